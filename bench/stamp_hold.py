"""Can the stamp-timed run skip part of the power-up hold? The error of doing so, measured.

A stamp-timed run spends its first seconds on the power-up: servos limp for ~25 ms, then
holding R^0 until the first transition (2.5-3.8 s with today's protocol, against the plain
simulator's 0.475 s settle). Per candidate, against the exact run (the twin's physics, to the
bit), this prints for random candidates of each model:

* ``nudge``: the exact run with the disc's height moved by --nudge m (default 1 um) at the
  first transition: the floor set by the physics' own sensitivity (no approximation can do
  better than a change of this size);
* ``cut H``: the hold before the first transition simulated for at most H s (later events
  and samples moved earlier by the rest).

and for each: how many candidates are within issue 13 §3's tolerance (distance within 2 % or
2 mm, path within 5 mm at each of the first 10 transitions), the distance errors and the rank
correlation of the distances. docs/twin.md, "Stamp-timed evaluation speed", has the numbers.

Usage: python bench/stamp_hold.py [--count 16] [--cuts 2.0,1.5] [--models nnsin,ca1d,nnsig]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from bstool.evolve.problem import Problem
from bstool.robot import RobotSpec
from bstool.sim import Simulator
from bstool.sim.simulator import SimResult
from bstool.sim.timed import PowerUpCache, StampSchedule
from hil_mock.schedule_model import schedule_model


def cut_hold(s: StampSchedule, hold: float, dt: float) -> StampSchedule:
    """``s`` with the still interval before its first transition cut to ``hold`` seconds."""
    pre = s.times < s.prefix_end
    last = float(s.times[pre].max()) if pre.any() else 0.0
    shift = math.floor(max(0.0, s.prefix_end - last - hold) / dt + 1e-9) * dt
    times = np.where(pre, s.times, s.times - shift)
    return StampSchedule(times, s.actuators, s.angles, s.samples - shift, s.actuator_count,
                         s.prefix_end - shift)  # fmt: skip


def nudged(sim: Simulator, s: StampSchedule, dz: float) -> SimResult:
    """The exact run with the disc moved up by ``dz`` at the first transition (the stored
    power-up's state edited: index 0 of the integration state is time, qpos follows)."""
    cache = PowerUpCache()
    sim.run_schedule(s, cache=cache)
    (key, (state, limp)) = next(iter(cache.table.items()))
    state = state.copy()
    state[1 + 2] += dz
    cache.table[key] = (state, limp)
    return sim.run_schedule(s, cache=cache)


def report(tag: str, exact: list[SimResult], other: list[SimResult]) -> None:
    d0 = np.array([r.distance for r in exact])
    d1 = np.array([r.distance for r in other])
    err = np.abs(d1 - d0)
    within = err <= np.maximum(0.02 * d0, 0.002)
    p10 = np.array([np.max(np.linalg.norm(a.path[:11] - b.path[:11], axis=1))
                    for a, b in zip(exact, other, strict=True)])  # fmt: skip
    ranks = [np.argsort(np.argsort(d)) for d in (d0, d1)]
    rho = float(np.corrcoef(*ranks)[0, 1])
    print(f"  {tag:10s} distance within 2 %/2 mm {within.sum():2d}/{len(d0)}, "
          f"path within 5 mm {np.sum(p10 < 0.005):2d}/{len(d0)}; |error| median "
          f"{np.median(err) * 1e3:.2f} mm, max {err.max() * 1e3:.2f} mm; rank correlation "
          f"{rho:.3f}", flush=True)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=16)
    ap.add_argument("--cuts", default="2.0,1.5")
    ap.add_argument("--models", default="nnsin,ca1d,nnsig")
    ap.add_argument("--nudge", type=float, default=1e-6)
    ap.add_argument("--transitions", type=int, default=30)
    args = ap.parse_args()
    sim = Simulator(RobotSpec())
    dt = sim.model.opt.timestep
    for model in args.models.split(","):
        fitted = schedule_model(model)
        problem = Problem(model, transitions=args.transitions)
        rng = np.random.default_rng(11)
        names = problem.populations
        bits = rng.integers(0, 2, (args.count, problem.length(names[0])), dtype=np.uint8)
        partner = None
        if len(names) > 1:
            partner = rng.integers(0, 2, problem.length(names[1]), dtype=np.uint8)
        schedules = [fitted.schedule(q) for q in problem.sequences(names[0], bits, partner)]
        exact = [sim.run_schedule(s) for s in schedules]
        hold = schedules[0].prefix_end
        print(f"{model}: {args.count} random candidates, power-up {hold:.2f} s, median distance "
              f"{np.median([r.distance for r in exact]) * 100:.1f} cm")  # fmt: skip
        report(f"nudge {args.nudge:g}", exact, [nudged(sim, s, args.nudge) for s in schedules])
        for h in (float(x) for x in args.cuts.split(",")):
            report(f"cut {h:g} s", exact, [sim.run_schedule(cut_hold(s, h, dt)) for s in schedules])


if __name__ == "__main__":
    main()
