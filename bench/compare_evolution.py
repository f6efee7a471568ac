"""Plain GA vs ``--robust`` vs ``--coevolve-faults``, on the same model, seeds and budget.

For every seed, runs ``bstool evolve`` three times (plain, --robust MODE, --coevolve-faults)
and then measures each resulting best.json the same way, with physics at MAX_TRANS:

* the distance over the n leg rotations of its gait (``rotation_spread``): mean, min, max and
  (max − min)/mean;
* the single-failure mobility (``single_failures``, as ``bstool faults``): how many of the n·m
  single failures keep ≥ 80 % and 100 % of the healthy distance, and the mean M_D.

Prints one row per run and one mean row per variant. Run directories are kept under --out
(re-running with the same --out resumes / reuses finished runs).

Usage: nice python bench/compare_evolution.py --model nnsin --seeds 1 2 --pop 12 --gens 6 \\
       --transitions 20 --out /tmp/cmp
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bstool.cli import main as bstool_main
from bstool.controllers import load_controller
from bstool.experiments.mobility import distances_with, single_failures, summarize
from bstool.experiments.robustness import rotation_spread
from bstool.robot import RobotSpec
from bstool.sim.batch import BatchEvaluator

COLUMNS = (  # name, width, decimals (None: text)
    ("variant", 12, None),
    ("seed", 4, None),
    ("fitness", 8, 4),
    ("d_rot0", 7, 4),
    ("rot_mean", 8, 4),
    ("rot_min", 7, 4),
    ("rot_max", 7, 4),
    ("rot_range", 9, 2),
    ("keep80", 6, 1),
    ("keep100", 7, 1),
    ("mean_MD", 7, 1),
    ("fail_d", 6, 4),
    ("evolve_s", 8, 0),
)


def variants(args: argparse.Namespace) -> dict[str, list[str]]:
    """Each variant's extra ``bstool evolve`` flags. ``plain-equal`` is the plain GA given as
    many simulations as the 5-simulations-per-candidate variants (more generations)."""
    faults = ["--coevolve-faults", "--parasites", str(args.parasites)]
    faults += ["--parasite-k", args.parasite_k]
    equal = ["--gens", str(args.gens * (1 + args.parasites))]
    every = {
        "plain": [],
        "plain-equal": equal,
        f"robust-{args.robust}": ["--robust", args.robust],
        "coevolve": faults,
    }
    wanted = args.variants or ["plain", f"robust-{args.robust}", "coevolve"]
    unknown = [v for v in wanted if v not in every]
    if unknown:
        raise SystemExit(f"unknown variants {unknown}; choose from {sorted(every)}")
    return {name: every[name] for name in wanted}


def evolve(model: str, flags: list[str], seed: int, out: Path, args: argparse.Namespace) -> float:
    """Run (or resume, or reuse) one evolution; returns its wall time in seconds."""
    start = time.perf_counter()
    common = ["--quiet", "--workers", str(args.workers)]
    if (out / "checkpoint.npz").exists():
        argv = ["evolve", "--resume", str(out), *common]
    else:
        argv = ["evolve", model, "--out", str(out), "--seed", str(seed), "--pop", str(args.pop)]
        if "--gens" not in flags:
            argv += ["--gens", str(args.gens)]
        argv += ["--transitions", str(args.transitions), *flags, *common]
    if bstool_main(argv) != 0:
        raise SystemExit(f"bstool {' '.join(argv)} failed")
    return time.perf_counter() - start


def measure(best: Path, ev: BatchEvaluator, transitions: int) -> dict[str, float]:
    controller = load_controller(best)
    evaluate = distances_with(ev)
    spread = rotation_spread(controller, evaluate, transitions)
    faults = single_failures(controller, evaluate, transitions)
    return {
        "fitness": float(controller.fitness or math.nan),
        "d_rot0": spread.distances[0],
        "rot_mean": spread.mean,
        "rot_min": spread.min,
        "rot_max": spread.max,
        "rot_range": spread.relative_range,
        "keep80": faults.count_at_least(80.0),
        "keep100": faults.count_at_least(100.0),
        "mean_MD": summarize(faults.runs).get("mean", math.nan),
        # absolute: M_D is relative to the healthy distance, so a slow host scores high on it
        "fail_d": sum(r.distance for r in faults.runs) / len(faults.runs),
    }


def line(row: dict[str, object]) -> str:
    cells = []
    for name, width, decimals in COLUMNS:
        value = row.get(name, "")
        if decimals is None or isinstance(value, str):
            cells.append(f"{value!s:<{width}}" if name == "variant" else f"{value!s:>{width}}")
        else:
            cells.append(f"{float(value):>{width}.{decimals}f}")  # type: ignore[arg-type]
    return "  ".join(cells)


def header() -> str:
    return "  ".join(
        f"{name:<{width}}" if i == 0 else f"{name:>{width}}"
        for i, (name, width, _) in enumerate(COLUMNS)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="nnsin")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--pop", type=int, default=12)
    parser.add_argument("--gens", type=int, default=6)
    parser.add_argument("--transitions", type=int, default=20)
    parser.add_argument("--robust", choices=["mean", "worst"], default="mean")
    parser.add_argument("--parasites", type=int, default=4)
    parser.add_argument("--parasite-k", default="1..2")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--variants",
        nargs="+",
        help="subset of: plain, plain-equal (plain with 1 + parasites times the generations), "
        "robust-mean/robust-worst, coevolve (default: plain, robust, coevolve)",
    )
    parser.add_argument("--out", type=Path, default=None, help="keep run directories here")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="compare-evolution-"))
    print(f"# {' '.join(sys.argv)}")
    print(f"# model {args.model}, pop {args.pop}, gens {args.gens}, T {args.transitions}, "
          f"seeds {args.seeds}, runs in {out}")  # fmt: skip
    rows: list[dict[str, object]] = []
    spec = RobotSpec()
    with BatchEvaluator(spec, workers=args.workers) as ev:
        for seed in args.seeds:
            for name, flags in variants(args).items():
                run_dir = out / f"{name}-s{seed}"
                seconds = evolve(args.model, flags, seed, run_dir, args)
                row: dict[str, object] = {"variant": name, "seed": seed, "evolve_s": seconds}
                row.update(measure(run_dir / "best.json", ev, args.transitions))
                rows.append(row)
                print(line(row) if len(rows) > 1 else f"{header()}\n{line(row)}", flush=True)
    print("\n# mean over seeds")
    print(header())
    for name in variants(args):
        mine = [r for r in rows if r["variant"] == name]
        mean: dict[str, object] = {"variant": name, "seed": "all"}
        for col, _, _ in COLUMNS[2:]:
            mean[col] = float(np.nanmean([float(r[col]) for r in mine]))  # type: ignore[arg-type]
        print(line(mean))
    cells = spec.legs * spec.modules
    print(f"\n# fitness: what the GA maximised (plain: distance; robust: mean/min over rotations;"
          f" coevolve: mean of healthy + {args.parasites} parasite runs against the last"
          f" parasites). d_rot0: healthy distance as evolved; rot_*: distance over the"
          f" {spec.legs} leg rotations; rot_range = (max-min)/mean; keep80/keep100: of {cells}"
          f" single failures; mean_MD: mean M_D (%) over them; fail_d: mean distance (m) with"
          f" one module failed.")  # fmt: skip


if __name__ == "__main__":
    main()
