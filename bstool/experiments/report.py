"""``bstool report``: one HTML page (PNGs beside it, no network needed) comparing controllers:
fitness curves, paths, fault tolerance, extrapolation and the numbers, plus report.json."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jinja2
import numpy as np

from bstool import fileio, outputs
from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.experiments import common, mobility
from bstool.experiments.extrapolate import reinit_states
from bstool.experiments.mobility import SingleFaults, single_failures
from bstool.experiments.paths import distance_curve, path_shape
from bstool.experiments.robustness import perturbation_spread, rotation_spread
from bstool.version import __version__

Progress = Callable[[str], None]
ScheduleFor = Callable[[Controller], Any]
"""The stamp-timed schedule model of a controller (a ``bstool.sim.timed.ScheduleModel``)."""


@dataclass
class Entry:
    name: str
    loaded: common.Loaded
    history: list[Any] | None


def find_entries(inputs: Sequence[str], robot: Any = None) -> list[Entry]:
    """Each input is an evolve run directory (best.json, history.csv) or a controller file;
    each runs on ``robot`` (``--robot``) if given, else on the robot it records."""
    from bstool.evolve.checkpoint import read_history

    entries: list[Entry] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            best = p / "best.json"
            if not best.exists():
                raise InputError(
                    f"{p} has no best.json", hint="give `bstool evolve --out` directories"
                )
            history = read_history(p / "history.csv") if (p / "history.csv").exists() else None
            entries.append(Entry(p.name, common.load(str(best), robot), history))
        elif p.exists():
            entries.append(Entry(p.stem, common.load(str(p), robot), None))
        else:
            raise InputError(f"no such run directory or controller file: {p}")
    labels = common.unique_labels([e.loaded.path for e in entries], [e.name for e in entries])
    for e, label in zip(entries, labels, strict=True):  # e.g. several runs/best.json
        e.name = label
    return entries


def build_report(
    inputs: Sequence[str],
    out_dir: str | os.PathLike[str],
    transitions: int = 30,
    extrapolate: int = 120,
    workers: int | None = None,
    progress: Progress | None = None,
    multi_samples: int = 0,
    multi_k: Sequence[int] = (1, 2, 3, 4, 5),
    force: bool = False,
    runs_done: Callable[[int], None] | None = None,
    runs_total: Callable[[int], None] | None = None,
    schedule_for: ScheduleFor | None = None,
    evaluation: str = "plain",
    robot: Any = None,
    sensitivity: tuple[int, int] | None = None,
) -> Path:
    """Run every experiment for every input and write ``out_dir/index.html`` (atomically: the
    whole directory appears at once). ``multi_samples`` > 0 adds the multiple-failure curves:
    that many random sets of K failed modules per K in ``multi_k`` (seed K, as `bstool faults`).

    ``out_dir`` must be new, empty, or an earlier report (else ``force``); it may never be or
    hold one of the inputs. ``runs_total(n)`` hears how many simulations are to come,
    ``runs_done(k)`` of every k finished. ``schedule_for`` (``bstool report --stamp-timed``)
    makes every run stamp-timed: each state sequence is played as the schedule model of its
    controller says a build would (``evaluation`` names it in the page and report.json); the
    perturbed starts stay on the plain simulator (a perturbed start has no schedule model).
    ``sensitivity`` (points, samples): ``bstool sensitivity``'s section, every controller on
    the same robots of the first one's uncertain ranges."""
    from bstool.experiments import plots
    from bstool.sim.batch import BatchEvaluator
    from bstool.sim.plot import plot_paths
    from bstool.sim.simulator import SimResult

    out = outputs.check_dir(
        out_dir, "report folder", force=force, ours=is_report, protect=tuple(inputs)
    )
    entries = find_entries(inputs, robot)
    if not entries:
        raise InputError("nothing to report", hint="give run directories or controller files")
    say = progress or (lambda _msg: None)
    design = None
    if sensitivity is not None:
        from bstool.experiments import sensitivity as sens
        from bstool.robot.robotfile import Robot

        chosen = entries[0].loaded.robot or Robot()
        design = sens.design(chosen, points=sensitivity[0], samples=sensitivity[1], seed=0)
    if runs_total:
        runs_total(sum(simulations(e.loaded.controller, transitions, extrapolate,
                                   multi_samples, multi_k) for e in entries)
                   + (0 if design is None else design.count * len(entries)))  # fmt: skip
    done = runs_done or (lambda _k: None)
    with outputs.staged_dir(out) as tmp:
        rows: list[dict[str, Any]] = []
        faults: dict[str, SingleFaults] = {}
        multi: dict[str, dict[int, list[mobility.FaultRun]]] = {}
        runs = []
        transfers: list[Any] = []
        for e in entries:
            c = e.loaded.controller
            with BatchEvaluator(e.loaded.spec, workers=workers) as ev:
                run = batch_runner(ev, None if schedule_for is None else schedule_for(c), runs_done)
                evaluate = mobility.distances_of(run)
                say(f"{e.name}: path and extrapolation")
                plain, reinit = run(
                    [c.states(extrapolate), reinit_states(c, extrapolate, transitions)]
                )
                if extrapolate >= transitions:  # the same states, so the same first T steps
                    base = SimResult(plain.path[: transitions + 1])
                else:
                    base = run([c.states(transitions)])[0]
                say(f"{e.name}: {c.legs * c.modules} single failures")
                f = single_failures(c, evaluate, transitions, base.distance)
                say(f"{e.name}: leg rotations and perturbed starts")
                spread = rotation_spread(c, evaluate, transitions)
                perturbed = perturbation_spread(c, e.loaded.spec, transitions, samples=3)
                done(1 + 3)
                transfer = None
                if design is not None:
                    say(f"{e.name}: {design.count} robots of the uncertain ranges")
                    schedule = None if schedule_for is None else schedule_for(c)
                    transfer = sens.measure(e.name, c.states(transitions), design,
                                            sens.on_batch(ev, schedule, done))  # fmt: skip
                    transfers.append(transfer)
                if multi_samples > 0:
                    say(f"{e.name}: {multi_samples} random sets of K failed modules per K")
                    multi[e.name] = {
                        k: mobility.random_failures(
                            c, evaluate, transitions, k, multi_samples, k, base.distance
                        )
                        for k in multi_k
                    }
            faults[e.name] = f
            runs.append((e.name, base))
            curves = {"plain": distance_curve(plain.path), "reinit": distance_curve(reinit.path)}
            ext_png = f"extrapolate-{len(rows)}.png"
            plots.plot_distance_curves(
                tmp / ext_png,
                {"plain": curves["plain"], f"re-init every {transitions}": curves["reinit"]},
                transitions,
                title=f"{e.name}: distance against transition",
            )
            md = np.array([r.mobility for r in f.runs], dtype=float)
            rows.append(
                {
                    "name": e.name,
                    "model": c.model,
                    "path": str(e.loaded.path),
                    "fitness": c.fitness,
                    "distance": base.distance,
                    "shape": path_shape(base.path).to_json(),
                    "faults": f.to_json(),
                    "mean_mobility": float(np.nanmean(md)) if md.size else 0.0,
                    "extrapolation": {k: v.tolist() for k, v in curves.items()},
                    "extrapolation_figure": ext_png,
                    "rotation": spread.to_json(),
                    "perturbation": perturbed.to_json(),
                    "multi_failures": {
                        str(k): mobility.summarize(v) for k, v in multi.get(e.name, {}).items()
                    },
                    "history": [vars(r) for r in e.history] if e.history else None,
                    "sensitivity": None if transfer is None else transfer.to_json(),
                }
            )
        say("figures")
        figures: dict[str, str | None] = {"paths": "paths.png", "faults": "faults.png"}
        plot_paths(tmp / "paths.png", runs, title="Disc paths")
        plots.plot_single_failures(tmp / "faults.png", faults)
        figures["multi"] = None
        if multi:
            plots.plot_multi_failures(tmp / "multi.png", multi)
            figures["multi"] = "multi.png"
        figures["sensitivity"] = None
        if design is not None and transfers:
            sens.plot(transfers, design, str(tmp / "sensitivity.png"))
            figures["sensitivity"] = "sensitivity.png"
        histories = {e.name: e.history for e in entries if e.history}
        figures["fitness"] = None
        if histories:
            plots.plot_fitness(tmp / "fitness.png", histories)
            figures["fitness"] = "fitness.png"
        models = _by_model(rows)
        context = {
            "title": "bstool report: brittle star controllers",
            "version": __version__,
            "evaluation": evaluation,
            "transitions": transitions,
            "extrapolate": extrapolate,
            "entries": rows,
            "multi_k": [str(k) for k in multi_k] if multi else [],
            "models": models,
            "figures": figures,
            "sensitivity": None
            if design is None
            else {
                "points": sensitivity[0] if sensitivity else None,
                "samples": len(design.joint),
                "seed": design.seed,
                "box": design.robot.box.describe(),
            },
        }
        fileio.write_text(tmp / "index.html", _render(context))
        fileio.write_json(tmp / "report.json", {k: v for k, v in context.items()})
    return out / "index.html"


def batch_runner(
    ev: Any, schedule_model: Any, progress: Callable[[int], None] | None
) -> Callable[[Sequence[np.ndarray]], list[Any]]:
    """State sequences → SimResults: plain, or stamp-timed with ``schedule_model``."""
    if schedule_model is None:
        return lambda seqs: list(ev.evaluate(list(seqs), progress=progress))
    return lambda seqs: list(
        ev.evaluate_schedules([schedule_model.schedule(s) for s in seqs], progress=progress)
    )


MARKER = b'<meta name="generator" content="bstool report'
_REPORT_FILE = re.compile(r"^(index\.html|report\.json|tables\.md|[\w.-]+\.png)$")


def is_report(folder: Path) -> bool:
    """A folder this command wrote: its index.html carries the marker and nothing else is
    there but the report's own files (so replacing it loses nothing of the user's)."""
    index = folder / "index.html"
    try:
        with open(index, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    names = [p.name for p in folder.iterdir()]
    return MARKER in head and all(_REPORT_FILE.match(n) for n in names)


def simulations(
    c: Controller, transitions: int, extrapolate: int, multi_samples: int, multi_k: Sequence[int]
) -> int:
    """How many runs :func:`build_report` makes for one controller (the progress bar's total)."""
    cells = c.legs * c.modules
    runs = 2 + (extrapolate < transitions) + cells + c.legs + 4  # ... rotations, perturbed
    if multi_samples > 0:
        runs += sum(min(multi_samples, math.comb(cells, k)) for k in multi_k)
    return runs


def _by_model(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    out = []
    for model in sorted({r["model"] for r in rows}):
        mine = [r for r in rows if r["model"] == model]
        out.append(
            {
                "model": model,
                "runs": len(mine),
                "mean_distance": float(np.mean([r["distance"] for r in mine])),
                "best_distance": float(np.max([r["distance"] for r in mine])),
                "mean_keep_80": float(np.mean([r["faults"]["keep_80"] for r in mine])),
            }
        )
    return out


def _render(context: dict[str, Any]) -> str:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("bstool", "data"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
    )
    return env.get_template("report.html.j2").render(**context)
