"""Timestep fidelity: do coarser physics steps rank and measure gaits like 1 ms does?

    python bench/timestep_fidelity.py [--timesteps 1,2,3,4] [--random 20] [--robots 4]
        [--seed 0] [--workers 2] [--quick] [--json FILE] [--quiet]

Issue 29 §4: may evolution run at 4 ms? Distances after 30 transitions (paper eq. 6,
``bstool.sim``) at each timestep, for the shipped controllers and ``--random`` random
controllers of each model (random chromosomes, as ``bstool.evolve.engine.new_run`` draws a
population; ca2ddiff pairs a random control with a random leg chromosome), on the nominal robot
and on ``--robots`` K random robots of the default box (``DEFAULT_BOX.samples``, the same K
robots for every controller: one generation of ``evolve --randomize``). The transition and
settle time stay the nominal robot's (0.475 s) at every timestep, so the step counts scale.

Against the finest timestep (1 ms), per model and overall:

* rho: Spearman rank correlation of the distances;
* d%: mean |difference| relative to the 1 ms distance, pooled: mean|d_h - d_1| / mean d_1
  (per-controller ratios explode for gaits that barely move); med%: the median of the
  per-controller |d_h - d_1| / d_1, for comparison;
* on the nominal robot, on each random robot (controller x robot pairs pooled), and for the
  mean over the K random robots per controller (what ``--randomize`` scores).

Also: the wall time of each timestep's batches, run in turn chunk by chunk in this process
(side by side), as a ratio to 2 ms; and a sensitivity floor: the same gaits at 1 ms on the
nominal robot with its friction changed by one part in a million (``--floor-eps``), which shows
how far a distance after 30 transitions moves for a change no measurement could see (contact
dynamics amplify it: ../shared/reference/mujoco.md). Decision rule (issue 29): a timestep may
be used by evolution if rho >= 0.95 and d% <= 3 % against 1 ms.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bstool.controllers import load_controller
from bstool.controllers.reference import MODELS
from bstool.evolve.problem import Problem
from bstool.robot import RobotSpec
from bstool.robot.uncertain import DEFAULT_BOX
from bstool.sim.batch import BatchEvaluator

TRANSITIONS = 30  # MAX_TRANS
CONTROLLERS = Path(__file__).resolve().parent.parent / "bstool" / "data" / "controllers"
RHO_MIN = 0.95  # issue 29's decision rule
DIFF_MAX = 3.0  # %
SETTINGS = ("nominal", "robots", "mean")
SETTING_TITLES = {
    "nominal": "nominal robot",
    "robots": "each random robot (controller x robot pairs)",
    "mean": "mean over the K random robots per controller (--randomize's score)",
}


@dataclasses.dataclass(frozen=True)
class Gait:
    model: str
    label: str  # "shipped" or "random<i>"
    states: np.ndarray  # (T+1, n, m)


def random_gaits(model: str, count: int, seed: int) -> list[Gait]:
    """``count`` random controllers of ``model``: uniform random chromosomes, decoded."""
    problem = Problem(model, transitions=TRANSITIONS)
    rng = np.random.default_rng([seed, 0, MODELS.index(model)])
    pops = {
        name: rng.integers(0, 2, (count, problem.length(name)), dtype=np.uint8)
        for name in problem.populations
    }
    if model == "ca2ddiff":  # row i of the controls with row i of the legs
        seqs = np.concatenate(
            [
                problem.sequences("control", pops["control"][i : i + 1], pops["leg"][i])
                for i in range(count)
            ]
        )
    else:
        seqs = problem.sequences("main", pops["main"])
    return [Gait(model, f"random{i}", np.asarray(s)) for i, s in enumerate(seqs)]


def shipped_gaits() -> list[Gait]:
    return [
        Gait(m, "shipped", load_controller(CONTROLLERS / f"{m}.json").states(TRANSITIONS))
        for m in MODELS
    ]


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    """Spearman's rho (scipy when installed; else Pearson of average ranks)."""
    try:
        from scipy.stats import spearmanr
    except ImportError:
        return float(np.corrcoef(_ranks(a), _ranks(b))[0, 1])
    return float(spearmanr(a, b).statistic)


def _ranks(x: np.ndarray) -> np.ndarray:
    order = np.argsort(x, kind="stable")
    ranks = np.empty(len(x))
    ranks[order] = np.arange(len(x), dtype=float)
    for v in np.unique(x):  # ties share their average rank
        tie = x == v
        ranks[tie] = ranks[tie].mean()
    return ranks


def compare(fine: np.ndarray, coarse: np.ndarray) -> dict[str, float]:
    fine, coarse = fine.ravel(), coarse.ravel()
    diff = np.abs(coarse - fine)
    return {
        "rho": spearman(fine, coarse),
        "diff_pct": 100.0 * float(diff.mean() / fine.mean()),
        "median_pct": 100.0 * float(np.median(diff / np.maximum(fine, 1e-12))),
        "n": float(len(fine)),
    }


def simulate(
    gaits: list[Gait],
    robots: list[RobotSpec],
    timesteps: list[float],
    workers: int,
    chunk: int,
    floor_eps: float,
    quiet: bool,
) -> tuple[dict[float, np.ndarray], dict[float, float], np.ndarray]:
    """Distances (robot, gait) per timestep, seconds per timestep, and the distances at the
    finest timestep on the nominal robot with friction × (1 + floor_eps) (the floor)."""
    from tqdm import tqdm

    nominal = RobotSpec()
    tt = nominal.transition_time  # the nominal robot's, whatever the robot or timestep
    states = [g.states for g in gaits]
    dist = {h: np.empty((len(robots), len(gaits))) for h in timesteps}
    seconds = dict.fromkeys(timesteps, 0.0)
    total = len(robots) * len(gaits) * len(timesteps) + len(gaits)
    bar = tqdm(total=total, desc="evaluations", disable=quiet or not sys.stderr.isatty())

    def progress(k: int) -> None:
        bar.update(k)

    for r, robot in enumerate(robots):
        evs = {
            h: BatchEvaluator(
                dataclasses.replace(robot, timestep=h),
                workers=workers,
                transition_time=tt,
                settle_time=tt,
            )
            for h in timesteps
        }
        try:
            for c, start in enumerate(range(0, len(gaits), chunk)):
                part = states[start : start + chunk]
                # rotate the order per chunk so that no timestep always runs first
                order = timesteps[c % len(timesteps) :] + timesteps[: c % len(timesteps)]
                for h in order:
                    t0 = time.perf_counter()
                    res = evs[h].evaluate(part, progress)
                    seconds[h] += time.perf_counter() - t0
                    dist[h][r, start : start + len(part)] = [x.distance for x in res]
        finally:
            for ev in evs.values():
                ev.close()
    fine = min(timesteps)
    nudged = dataclasses.replace(
        robots[0], timestep=fine, friction=robots[0].friction * (1.0 + floor_eps)
    )
    with BatchEvaluator(nudged, workers=workers, transition_time=tt, settle_time=tt) as ev:
        floor = np.array([x.distance for x in ev.evaluate(states, progress)])
    bar.close()
    return dist, seconds, floor


def analyse(
    gaits: list[Gait], dist: dict[float, np.ndarray], floor: np.ndarray, fine: float
) -> dict[str, Any]:
    """Figures per setting, group (model, "shipped", "all") and coarser timestep, against
    the timestep ``fine``."""
    groups: dict[str, np.ndarray] = {
        m: np.array([g.model == m for g in gaits])
        for m in MODELS
        if any(g.model == m for g in gaits)
    }
    groups["shipped"] = np.array([g.label == "shipped" for g in gaits])
    groups["all"] = np.ones(len(gaits), dtype=bool)
    out: dict[str, Any] = {s: {} for s in SETTINGS}
    out["floor"] = {}
    out["fine_cm"] = {}
    for name, mask in groups.items():
        views = {
            "nominal": lambda d, mask=mask: d[0, mask],
            "robots": lambda d, mask=mask: d[1:, mask],
            "mean": lambda d, mask=mask: d[1:, mask].mean(axis=0),
        }
        for setting, view in views.items():
            if setting != "nominal" and dist[fine].shape[0] < 2:
                continue
            out[setting][name] = {
                f"{h * 1e3:g}": compare(view(dist[fine]), view(dist[h])) for h in dist if h > fine
            }
        out["fine_cm"][name] = 100.0 * float(np.median(dist[fine][0, mask]))
        out["floor"][name] = compare(dist[fine][0, mask], floor[mask])
    return out


def verdict(figs: dict[str, Any], ms: str) -> dict[str, list[str]]:
    """Where timestep ``ms`` breaks the rule: per setting, the groups (models and "all") and
    why. The shipped row is left out: its 5 gaits are of 5 models, no ranking to keep."""
    out: dict[str, list[str]] = {}
    for setting in SETTINGS:
        out[setting] = []
        for group, by_ms in figs[setting].items():
            if group == "shipped":
                continue
            f, bad = by_ms[ms], []
            if f["rho"] < RHO_MIN:
                bad.append(f"rho {f['rho']:.3f}")
            if f["diff_pct"] > DIFF_MAX:
                bad.append(f"d {f['diff_pct']:.1f} %")
            if bad:
                out[setting].append(f"{group} ({', '.join(bad)})")
    return out


def print_overall(figs: dict[str, Any], fine_ms: str) -> None:
    """One line per setting: the "all" group against ``fine_ms``."""
    coarse = list(figs["nominal"]["all"])
    print(f"\noverall, against {fine_ms} ms (today's evolution timestep):")
    print(f"{'setting':<9}" + "".join(f" | {ms + ' ms rho':>9} {'d%':>5}" for ms in coarse))
    for setting in SETTINGS:
        if "all" in figs[setting]:
            cells = figs[setting]["all"]
            print(
                f"{setting:<9}"
                + "".join(
                    f" | {cells[ms]['rho']:>9.3f} {cells[ms]['diff_pct']:>5.1f}" for ms in coarse
                )
            )


def print_tables(figs: dict[str, Any], coarse: list[str], fine_ms: str, floor_eps: float) -> None:
    head = f"{'group':<9} {'n':>4} {'d1 cm':>6}"
    for ms in coarse:
        head += f" | {ms + ' ms rho':>9} {'d%':>5} {'med%':>5}"
    for setting in SETTINGS:
        if not figs[setting]:
            continue
        print(f"\n{SETTING_TITLES[setting]}: {', '.join(coarse)} ms against {fine_ms} ms")
        print(head)
        for group, by_ms in figs[setting].items():
            n = int(next(iter(by_ms.values()))["n"])
            line = f"{group:<9} {n:>4} {figs['fine_cm'][group]:>6.1f}"
            for ms in coarse:
                f = by_ms[ms]
                line += f" | {f['rho']:>9.3f} {f['diff_pct']:>5.1f} {f['median_pct']:>5.1f}"
            print(line)
    print(f"\nsensitivity floor: {fine_ms} ms, nominal robot, friction x (1 + {floor_eps:g})")
    print(f"{'group':<9} {'n':>4} {'rho':>9} {'d%':>5} {'med%':>5}")
    for group, f in figs["floor"].items():
        print(
            f"{group:<9} {int(f['n']):>4} {f['rho']:>9.3f} {f['diff_pct']:>5.1f} "
            f"{f['median_pct']:>5.1f}"
        )
    print("(d1 cm: median distance at the fine timestep on the nominal robot)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--timesteps", default="1,2,3,4", help="ms, comma-separated; finest first")
    ap.add_argument("--random", type=int, help="random controllers per model (20)")
    ap.add_argument("--robots", type=int, help="K random robots of the default box (4)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--chunk", type=int, default=16, help="gaits per side-by-side round")
    ap.add_argument(
        "--floor-eps", type=float, default=1e-6, help="relative friction nudge of the floor"
    )
    ap.add_argument("--quick", action="store_true", help="defaults 3 random per model, 2 robots")
    ap.add_argument("--json", type=Path, help="also write the figures and raw distances here")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()
    quick, full = (3, 2), (20, 4)
    defaults = quick if args.quick else full
    args.random = defaults[0] if args.random is None else args.random
    args.robots = defaults[1] if args.robots is None else args.robots
    timesteps = sorted(float(x) / 1e3 for x in args.timesteps.split(","))
    if len(timesteps) < 2 or args.random < 1 or args.robots < 0:
        ap.error("need two timesteps or more, --random >= 1, --robots >= 0")

    nominal = RobotSpec()
    gaits = shipped_gaits() + [g for m in MODELS for g in random_gaits(m, args.random, args.seed)]
    robots = [nominal, *DEFAULT_BOX.samples(nominal, args.robots, seed=[args.seed, 1])]
    print(
        f"timestep fidelity {datetime.date.today()}: {len(gaits)} gaits (5 shipped + "
        f"{args.random} random x {len(MODELS)} models), nominal robot + {args.robots} random "
        f"robots (default box, seed {args.seed}), {TRANSITIONS} transitions of "
        f"{nominal.transition_time:.3f} s, workers {args.workers}"
    )
    for h in timesteps:
        steps = max(1, round(nominal.transition_time / h))
        print(f"  {h * 1e3:g} ms: {steps} steps per transition = {steps * h:.3f} s")

    t0 = time.perf_counter()
    dist, seconds, floor = simulate(
        gaits, robots, timesteps, args.workers, args.chunk, args.floor_eps, args.quiet
    )
    fine_ms = f"{timesteps[0] * 1e3:g}"
    coarse = [f"{h * 1e3:g}" for h in timesteps[1:]]
    figs = analyse(gaits, dist, floor, timesteps[0])
    print_tables(figs, coarse, fine_ms, args.floor_eps)

    print("\nwall time of the same batches, run in turn in this process:")
    ref = 0.002 if 0.002 in seconds else timesteps[0]
    for h in timesteps:
        print(
            f"  {h * 1e3:g} ms: {seconds[h]:7.1f} s = {seconds[h] / seconds[ref]:.2f} x "
            f"{ref * 1e3:g} ms"
        )
    print(f"total {time.perf_counter() - t0:.0f} s")

    if 0.002 in dist and timesteps[0] < 0.002 < timesteps[-1]:
        print_overall(analyse(gaits, dist, floor, 0.002), "2")

    print(f"\nrule: rho >= {RHO_MIN} and d% <= {DIFF_MAX:g} % against {fine_ms} ms, for every")
    print("model and overall (failures listed):")
    verdicts = {}
    for ms in coarse:
        fails = verdict(figs, ms)
        ok = not any(fails.values())
        verdicts[ms] = {"pass": ok, "failures": fails}
        print(f"  {ms} ms: {'PASS' if ok else 'FAIL'}")
        for setting, where in fails.items():
            if figs.get(setting):
                print(f"    {setting:<8} {'; '.join(where) if where else 'pass'}")

    if args.json:
        from bstool import fileio

        fileio.write_json(
            args.json,
            {
                "date": str(datetime.date.today()),
                "args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
                "gaits": [[g.model, g.label] for g in gaits],
                "robots": [r.to_dict() for r in robots],
                "distances_m": {f"{h * 1e3:g}": d.tolist() for h, d in dist.items()},
                "floor_m": floor.tolist(),
                "seconds": {f"{h * 1e3:g}": s for h, s in seconds.items()},
                "figures": figs,
                "verdicts": verdicts,
            },
        )


if __name__ == "__main__":
    main()
