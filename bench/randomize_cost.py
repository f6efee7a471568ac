"""What randomized physics costs (issue 29 §4), every ratio measured side by side in one run.

1. One randomized sample against one evaluation of the same robot: P state sequences on R
   robots of the default box, run on models compiled from each robot's spec (the reference),
   on the nominal model with each robot written in once per call (``evolve --randomize``) and
   with a different robot for every run (``bstool sensitivity``, validation). Target: a
   randomized sample costs at most 1.05 x the evaluation it stands for. Also printed: those
   robots' physics against the nominal robot's (a softer or grippier robot steps slower).
2. A whole GA run: ``evolve --randomize --randomize-samples K`` against a nominal run of the
   same population and generations (the same seed), with the evaluations each paid.
   ``--timestep`` runs the randomized one at another physics step (the nominal one stays at
   the robot's), the timestep fidelity study's question (docs/robot.md).

Rounds alternate (nominal, randomized, ...) and the best of each is kept, so a busy machine
spoils both alike.

Usage: python bench/randomize_cost.py [--pop 24] [--robots 4] [--transitions 30] [--workers 2]
       [--rounds 3] [--gens 3] [--samples 4] [--model nnsin] [--timestep S] [--skip-run]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

import numpy as np

from bstool.evolve.driver import evolve
from bstool.evolve.problem import Problem
from bstool.robot import RobotSpec
from bstool.robot.uncertain import DEFAULT_BOX
from bstool.sim.batch import BatchEvaluator


def timed(fn: Any) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def sample_cost(args: argparse.Namespace) -> None:
    """Applied physics against models built from each robot's spec: the same robots, the same
    physics, so the ratio is what applying costs; and the random robots' own physics cost
    against the nominal robot's (a property of the physics, not of bstool)."""
    problem = Problem(args.model, transitions=args.transitions)
    rng = np.random.default_rng(1)
    bits = rng.integers(0, 2, (args.pop, problem.length("main")), dtype=np.uint8)
    seqs = list(problem.sequences("main", bits))
    nominal = RobotSpec()
    period = nominal.transition_time
    robots = DEFAULT_BOX.samples(nominal, args.robots, seed=[7])
    best = {"nominal": np.inf, "built": np.inf, "applied": np.inf, "per run": np.inf}
    mixed = [robots[i % len(robots)] for i in range(len(seqs))]

    def built() -> None:  # one model compiled from each robot's spec: the reference
        for r in robots:
            with BatchEvaluator(r, workers=args.workers, transition_time=period) as one:
                one.evaluate(seqs)

    with BatchEvaluator(nominal, workers=args.workers) as ev:
        ev.evaluate(seqs[:2])  # warm the pool
        ev.evaluate(seqs[:2], robot=robots[0])  # and the worker model copies

        def nominal_runs() -> None:
            for _r in robots:
                ev.evaluate(seqs)

        def applied() -> None:  # evolve --randomize: one robot a call
            for r in robots:
                ev.evaluate(seqs, robot=r)

        def per_run() -> None:  # sensitivity, validation: a robot for every run
            for _r in robots:
                ev.evaluate(seqs, robot=mixed)

        for _ in range(args.rounds):
            for name, fn in (("nominal", nominal_runs), ("built", built), ("applied", applied),
                             ("per run", per_run)):  # fmt: skip
                best[name] = min(best[name], timed(fn))
    runs = len(seqs) * len(robots)
    print(f"1. {args.pop} {args.model} sequences x {len(robots)} robots of the default box x "
          f"{args.transitions} transitions, {args.workers} workers, best of {args.rounds} "
          "alternating rounds")  # fmt: skip
    labels = {
        "nominal": "nominal robot",
        "built": "models built from the robots' specs",
        "applied": "robots applied, one a call",
        "per run": "robots applied, one per run",
    }
    for name, seconds in best.items():
        print(f"   {labels[name]:<38} {seconds:7.2f} s  {runs / seconds:6.2f} runs/s")
    worst = max(best["applied"], best["per run"]) / best["built"]
    print(
        f"   a randomized sample / the same robot built from its spec: {worst:.3f} (target <= 1.05)"
    )
    print(
        f"   the random robots' physics / the nominal robot's: "
        f"{best['built'] / best['nominal']:.3f} (contacts and stiffness differ; not bstool's)"
    )


def run_cost(args: argparse.Namespace) -> None:
    common = dict(pop=args.pop, gens=args.gens, transitions=args.transitions, seed=3,
                  workers=args.workers)  # fmt: skip
    robot = None
    if args.timestep:
        from bstool.robot.robotfile import Robot

        robot = Robot(dataclasses.replace(RobotSpec(), timestep=args.timestep))
    best = {"nominal": np.inf, "randomized": np.inf}
    paid = {}
    for _ in range(args.rounds):
        start = time.perf_counter()
        plain = evolve(args.model, **common)  # type: ignore[arg-type]
        best["nominal"] = min(best["nominal"], time.perf_counter() - start)
        start = time.perf_counter()
        rand = evolve(args.model, randomize=True, randomize_samples=args.samples, robot=robot,
                      **common)  # type: ignore[arg-type]  # fmt: skip
        best["randomized"] = min(best["randomized"], time.perf_counter() - start)
        paid = {"nominal": plain.stats["evaluations"], "randomized": rand.stats["evaluations"]}
    step = f" at a {args.timestep * 1000:g} ms step" if args.timestep else ""
    print(f"2. evolve {args.model} --pop {args.pop} --gens {args.gens} (best of {args.rounds})")
    print(f"   nominal              {best['nominal']:7.2f} s  {paid['nominal']} evaluations")
    print(f"   --randomize K={args.samples}{step}  {best['randomized']:7.2f} s  "
          f"{paid['randomized']} evaluations (validation included)")  # fmt: skip
    print(
        f"   randomized / nominal run: {best['randomized'] / best['nominal']:.2f} "
        "(target <= 2.5 with K = 4)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="nnsin")
    ap.add_argument("--pop", type=int, default=24)
    ap.add_argument("--transitions", type=int, default=30)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--gens", type=int, default=3, help="GA generations of part 2")
    ap.add_argument("--samples", type=int, default=4, help="K of part 2")
    ap.add_argument("--robots", type=int, default=4, help="robots of part 1")
    ap.add_argument("--timestep", type=float, default=None, help="part 2's randomized step (s)")
    ap.add_argument("--skip-run", action="store_true", help="only part 1")
    args = ap.parse_args()
    sample_cost(args)
    if not args.skip_run:
        run_cost(args)


if __name__ == "__main__":
    main()
