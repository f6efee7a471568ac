"""How far apart the modules of a robot switch their servos: the serve loop's phase skew.

For each model, the shipped controller and a few random ones are compiled (default period)
and run on the twin without physics; a transition's *skew* is the latest minus the earliest
module's first pulse of it, over the whole robot and within one leg. Prints the skew at
transitions 10 and T, the mean period, per build and as the median per model.

    python bench/phase_skew.py [-T 30] [--random 2] [--models ca1d,ca2dsing]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bstool import buildfile
from bstool.api import builtin_controller
from bstool.compile.build import compile_loaded
from bstool.controllers import MODELS
from hil_mock.schedule_model import random_controller, transition_instants


def skews(instants: np.ndarray, legs: int) -> tuple[np.ndarray, np.ndarray]:
    """Per transition 1..T: the robot's skew and the largest within-leg skew (s)."""
    starts = instants[:, 1:-1]  # (A, T)
    robot = starts.max(axis=0) - starts.min(axis=0)
    per_leg = starts.reshape(legs, -1, starts.shape[1])
    leg = (per_leg.max(axis=1) - per_leg.min(axis=1)).max(axis=0)
    return robot, leg


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-T", "--transitions", type=int, default=30)
    ap.add_argument("--random", type=int, default=2, help="random controllers per model")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--period", type=float, default=None)
    args = ap.parse_args()
    T = args.transitions
    mid = min(10, T)
    print(f"{'build':<16} {'skew@' + str(mid):>8} {'skew@' + str(T):>8} {'leg@' + str(T):>7} "
          f"{'period':>7}  (s)")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="bstool-skew-") as tmp:
        for model in args.models.split(","):
            rows = []
            ctrls = [("shipped", builtin_controller(model))]
            ctrls += [(f"random{s}", random_controller(model, 100 + s)) for s in range(args.random)]
            for name, ctrl in ctrls:
                out = Path(tmp) / f"{model}-{name}"
                t0 = time.perf_counter()
                res = compile_loaded(ctrl, out, period=args.period)
                build = buildfile.Build(out, res.manifest)
                inst, _ = transition_instants(build, T)
                robot, leg = skews(inst, build.legs)
                base = inst[:, 1:-1].mean(axis=0)
                period = float(np.diff(base[1:]).mean())
                rows.append((robot[mid - 1], robot[T - 1], leg[T - 1], period))
                print(f"{model + ' ' + name:<16} {robot[mid - 1]:8.3f} {robot[T - 1]:8.3f} "
                      f"{leg[T - 1]:7.3f} {period:7.3f}  [{time.perf_counter() - t0:.0f} s]",
                      flush=True)  # fmt: skip
            med = [statistics.median(c) for c in zip(*rows, strict=True)]
            print(f"{model + ' median':<16} {med[0]:8.3f} {med[1]:8.3f} {med[2]:7.3f} "
                  f"{med[3]:7.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
