"""Re-evolve the shipped gaits for an uncertain robot and compare, on fresh robots, with the
gaits shipped before and with nominal evolution at equal evaluations (issue 29 §5).

For each model and seed (resumable: a finished run is kept, an interrupted one resumed):

* ``rand``: ``evolve --stamp-timed --randomize`` (K robots per generation from the default
  box, validation on 64 robots) at the shipped controller's GA budget (its ``ga`` field);
* ``nominal`` (unless ``--no-nominal``): ``evolve --stamp-timed`` on the nominal robot with K
  times the generations (ca2ddiff: K times the outer loops): about the same evaluations.

Then every best.json, and the shipped one, runs on ``--robots`` fresh robots of the default
box (seeded apart from every training and validation draw; the same robots for all) and on the
nominal robot, stamp-timed (the schedule model each was scored on). Printed: per model and
run the nominal distance, the mean over the robots, the 10th percentile, the validation mean;
the candidate to ship (the rand seed with the best validation mean) against the shipped gait
with the issue's targets: mean >= 1.3 x the shipped gait's, 10th percentile >= 50 % of its
own nominal distance, nominal >= 85 % of the shipped gait's. OUT/summary.json holds it all.

Usage: python bench/reship_randomized.py OUT [--models nnsin,...] [--seeds 1,2,3]
       [--samples 4] [--score mean|worst-quarter] [--robots 64] [--workers 2] [--no-nominal]
       [--measure-only] [--plain] [--pop P] [--gens G] [--ca2ddiff-gens L] [--coevol-gens C]
       [--no-shipped] [--baseline DIR] [--also NAME=C.json ...] [--builds]
``--builds`` plays each controller on its own build's timing (compiled into OUT/builds/), as
``bstool sensitivity BUILD`` does, instead of the schedule model evolution scored with.
``--also`` measures other controllers of a model beside them (e.g. a gait evolved on a box of
the user's own robot file, docs/results.md "evolved for the grippy corner").
With --plain and a budget it is the evolution comparison of docs/results.md ("Randomized
against nominal evolution"): every figure there is plain physics.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import targets_frontier  # bench/, beside this script

from bstool import fileio
from bstool.builtin import builtin_controller
from bstool.controllers import load_controller
from bstool.evolve import driver
from bstool.evolve.checkpoint import is_run
from bstool.experiments import sensitivity as sens
from bstool.robot.robotfile import Robot
from hil_mock.schedule_extract import build_schedule
from hil_mock.schedule_model import schedule_model

MODELS = ("nnsin", "nnsig", "ca1d", "ca2dsing", "ca2ddiff")
FRESH_SEED = 20261204  # the measuring robots: apart from every run's draws


def baseline(model: str, args: argparse.Namespace) -> Path:
    """The gait a re-ship is measured against and starts from: the shipped one, or --baseline's
    (tests/data/traced holds those shipped before the re-ship of 2026-12-07)."""
    if args.baseline is None:
        return builtin_controller(model)
    return args.baseline / f"{model}.json"


def budget(model: str, args: argparse.Namespace) -> dict[str, Any]:
    """The baseline gait's GA budget, or the one given (--pop, --gens, --coevol-gens)."""
    ga = load_controller(baseline(model, args)).ga or {}
    out = {k: ga[k] for k in ("pop", "gens", "coevol_gens", "pm")}
    for key in ("pop", "coevol_gens"):
        if getattr(args, key) is not None:
            out[key] = getattr(args, key)
    gens = args.ca2ddiff_gens if model == "ca2ddiff" else args.gens
    if gens is not None:
        out["gens"] = gens
    return out


def _timed(model: str, args: argparse.Namespace) -> dict[str, Any]:
    """evolve's keywords for the physics: stamp-timed on the schedule model, or plain."""
    if args.plain:
        return {}
    return {"stamp_timed": True, "schedule_model": _schedule(model, 0)}


def evolve_one(out: Path, model: str, seed: int, kind: str, args: argparse.Namespace) -> Path:
    folder = out / f"{model}-{kind}-s{seed}"
    if (folder / "best.json").exists() and is_run(folder):
        state = driver.plan_resume(folder, {}).state
        if state.done:
            return folder
        schedule = {k: v for k, v in _timed(model, args).items() if k == "schedule_model"}
        driver.execute(driver.plan_resume(folder, {}), workers=args.workers, **schedule)
        return folder
    b = budget(model, args)
    gens = b["gens"] if kind == "rand" else b["gens"] * args.samples
    more: dict[str, Any] = {}
    if kind == "rand":
        more = {
            "randomize": True,
            "randomize_samples": args.samples,
            "randomize_score": args.score,
        }
    if args.init_shipped:
        more["init"] = baseline(model, args)
    start = time.perf_counter()
    driver.evolve(
        model,
        pop=b["pop"],
        gens=gens,
        coevol_gens=b["coevol_gens"],
        pm=b["pm"],
        seed=seed,
        out=folder,
        force=True,
        workers=args.workers,
        **_timed(model, args),
        **more,
    )
    fileio.write_json(folder / "wall.json", {"seconds": time.perf_counter() - start})
    return folder


_SCHEDULES: dict[str, Any] = {}


def _schedule(model: str, builds: int) -> Any:
    if model not in _SCHEDULES:
        _SCHEDULES[model] = schedule_model(model, builds=builds)
    return _SCHEDULES[model]


def measure(paths: dict[str, Path], model: str, args: argparse.Namespace) -> dict[str, Any]:
    """Every controller of ``paths`` on the same fresh robots (stamp-timed unless --plain)."""
    from bstool.evolve.fitness import PhysicsFitness, StampTimedFitness

    plan = sens.Design(
        Robot(), {}, Robot().box.samples(Robot().spec, args.robots, seed=[FRESH_SEED]), FRESH_SEED
    )
    ev: Any = None
    if args.plain:
        ev = PhysicsFitness(workers=args.workers).build()
    elif not args.builds:
        ev = StampTimedFitness(_schedule(model, 0), workers=args.workers).build()
    out = {}
    try:
        for name, path in paths.items():
            ctrl = load_controller(path)
            if args.builds:  # the controller's own build, not the schedule model
                if ev is not None:
                    ev.close()
                source = build_schedule(_compiled(path, model, name, args), ctrl.states(30))
                ev = StampTimedFitness(source, workers=args.workers).build()

            def run(seqs: list[Any], robots: list[Any], ev: Any = ev) -> list[float]:
                return [float(d) for d in ev(seqs, robot=robots)]

            t = sens.measure(name, ctrl.states(30), plan, run)
            out[name] = {
                "nominal": t.nominal,
                "mean": t.mean,
                "p10": t.p10,
                "worst": t.worst,
                "validation": ctrl.fitness if (ctrl.ga or {}).get("randomize") else None,
                "path": str(path),
            }
    finally:
        if ev is not None:
            ev.close()
    return out


def _also(text: str) -> tuple[str, Path, str]:
    """NAME=C.json of --also: the name, the file and its controller's model."""
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise SystemExit(f"--also {text!r}: expected NAME=C.json")
    return name, Path(path), load_controller(Path(path)).model


def _compiled(path: Path, model: str, name: str, args: argparse.Namespace) -> Any:
    """``bstool compile`` of ``path`` in OUT/builds/MODEL-NAME (kept: compiled once)."""
    from bstool import buildfile
    from bstool.cli import main as cli

    folder = args.out / "builds" / f"{model}-{name}"
    made = (folder / "manifest.json").is_file()
    if not made and cli(["compile", str(path), "-o", str(folder), "-q", "--force"]) != 0:
        raise SystemExit(f"could not compile {path}")
    return buildfile.load(str(folder))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--samples", type=int, default=4, help="K of --randomize")
    ap.add_argument(
        "--score", default="mean", choices=("mean", "worst-quarter"), help="--randomize-score"
    )
    ap.add_argument("--robots", type=int, default=64, help="fresh robots to measure on")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-nominal", action="store_true", help="skip nominal evolution")
    ap.add_argument("--measure-only", action="store_true", help="no evolution, measure runs")
    ap.add_argument("--plain", action="store_true", help="plain physics, not --stamp-timed")
    ap.add_argument("--pop", type=int, default=None, help="instead of the shipped budget's")
    ap.add_argument("--gens", type=int, default=None, help="instead of the shipped budget's")
    ap.add_argument("--ca2ddiff-gens", type=int, default=None, help="ca2ddiff outer loops")
    ap.add_argument("--coevol-gens", type=int, default=None, help="ca2ddiff co-evolution gens")
    ap.add_argument("--no-shipped", action="store_true", help="do not measure the shipped gait")
    ap.add_argument(
        "--init-shipped",
        action="store_true",
        help="start every run from the baseline gait (evolve --init; see --baseline)",
    )
    ap.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="folder of <model>.json to compare with and start from (default: the shipped)",
    )
    ap.add_argument(
        "--builds",
        action="store_true",
        help="measure each controller on its own build's timing (bstool sensitivity BUILD), "
        "not the schedule model",
    )
    ap.add_argument(
        "--also",
        action="append",
        default=[],
        metavar="NAME=C.json",
        help="also measure this controller (its model's rows); repeatable",
    )
    args = ap.parse_args()
    if args.builds and args.plain:
        ap.error("--builds plays stamp-timed physics; drop --plain")
    also = [_also(text) for text in args.also]
    args.out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",")]
    kinds = ["rand"] if args.no_nominal else ["rand", "nominal"]
    summary_file = args.out / ("summary-builds.json" if args.builds else "summary.json")
    old = summary_file
    summary: dict[str, Any] = fileio.read_json(old) if old.exists() else {}  # other models kept
    for model in args.models.split(","):
        paths: dict[str, Path] = {} if args.no_shipped else {"shipped": baseline(model, args)}
        for seed in seeds:
            for kind in kinds:
                folder = args.out / f"{model}-{kind}-s{seed}"
                if not args.measure_only:
                    evolve_one(args.out, model, seed, kind, args)
                if (folder / "best.json").exists():
                    paths[f"{kind}-s{seed}"] = folder / "best.json"
        paths.update({name: path for name, path, m in also if m == model})
        figures = measure(paths, model, args)
        rand = {k: v for k, v in figures.items() if k.startswith("rand")}
        pick = max(rand, key=lambda k: rand[k]["validation"] or 0.0) if rand else None
        old = figures.get("shipped")
        verdict = {}
        if pick is not None and old is not None:
            r = targets_frontier.ratios(figures[pick], old)  # issue 29 §5's targets, once
            verdict = {
                "candidate": pick,
                "mean_ratio": r["mean"],
                "p10_of_nominal": r["p10"],
                "nominal_ratio": r["nominal"],
                "targets_met": all(targets_frontier.met(r)),
            }
        summary[model] = {"runs": figures, "verdict": verdict}
        fileio.write_json(summary_file, summary)
        how = "plain" if args.plain else "stamp-timed"
        how += ", each on its own build" if args.builds else ""
        print(f"\n{model}: {how}, {args.robots} fresh robots of the default box (cm)")
        print(f"  {'run':<14}{'nominal':>9}{'mean':>8}{'p10':>8}{'worst':>8}{'validation':>12}")
        for name, f in figures.items():
            val = "" if f["validation"] is None else f"{f['validation'] * 100:.2f}"
            print(
                f"  {name:<14}{f['nominal'] * 100:9.2f}{f['mean'] * 100:8.2f}"
                f"{f['p10'] * 100:8.2f}{f['worst'] * 100:8.2f}{val:>12}"
            )
        for kind in kinds:
            means = [f["mean"] for n, f in figures.items() if n.startswith(kind)]
            if means:
                print(f"  {kind} over {len(means)} seeds: mean {np.mean(means) * 100:.2f} cm")
        if verdict:
            print(
                f"  candidate {verdict['candidate']}: mean x{verdict['mean_ratio']:.2f} of the "
                f"shipped (target 1.3), p10 {verdict['p10_of_nominal']:.0%} of its nominal "
                f"(target 50 %), nominal x{verdict['nominal_ratio']:.2f} (target 0.85): "
                f"{'met' if verdict['targets_met'] else 'NOT met'}"
            )


if __name__ == "__main__":
    main()
