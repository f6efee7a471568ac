"""Evaluation speed of `bstool evolve`, with every ratio measured side by side in this run.

Prints, for a population of --pop candidates (default 100) of the default robot:

* evaluations/s through the evolve stack (chromosomes → state sequences → fitness cache →
  bstool.sim.batch), with 1 and 2 workers;
* the raw MuJoCo limit: the same control batch stepped with mj_step by the same number of
  threads, one MjData each, and no controller or simulator code around it; and the ratio;
* the 2-worker speed-up over 1 worker;
* the fraction of CA offspring whose physics was skipped (identical state sequence), from a
  GA run of --ga-gens generations on the toy fitness (selection dynamics only, no physics);
* the state-sequence generation rate (population sequences/s) for a CA and an NN model;
* ``--stamp-timed`` evaluation (``bstool evolve --stamp-timed``): evaluations/s beside the plain
  physics of the same population in the same rounds, their ratio, the seconds of physics each
  run needs (the twin's start-up and period against a 0.475 s settle and period), the
  schedule model's fitting time (one compile + twin run per representative, cached) and its
  schedule computation rate (schedules/s);
* the same population scored on the mean of --schedule-builds builds (``evolve
  --schedule-builds``; each build one more physics run per candidate).

Usage: python bench/evaluate.py [--pop 100] [--transitions 30] [--ga-gens 40] [--rounds 2]
       [--stamp-gens 4] [--stamp-models nnsin,nnsig,ca1d] [--schedule-builds 3]
"""

from __future__ import annotations

import argparse
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import mujoco
import numpy as np

from bstool.evolve.engine import GAParams, new_run, run
from bstool.evolve.fitness import FitnessCache, PhysicsFitness, StampTimedFitness, ToyEvaluator
from bstool.evolve.problem import Problem
from bstool.robot import RobotSpec
from bstool.sim import Simulator


def raw_rate(sim: Simulator, seqs: np.ndarray, workers: int) -> float:
    """Evaluations/s of bare mj_step over the same targets and step counts."""
    targets = [sim.angles(s) for s in seqs]
    datas = [mujoco.MjData(sim.model) for _ in range(workers)]
    lock = threading.Lock()
    cursor = [0]

    def worker(data: mujoco.MjData) -> None:
        model = sim.model
        while True:
            with lock:
                i = cursor[0]
                cursor[0] += 1
            if i >= len(targets):
                return
            ctrl = targets[i]
            mujoco.mj_resetData(model, data)
            data.ctrl[:] = ctrl[0]
            mujoco.mj_step(model, data, nstep=sim.settle_steps)
            for t in range(1, len(ctrl)):
                data.ctrl[:] = ctrl[t]
                mujoco.mj_step(model, data, nstep=sim.steps_per_transition)

    start = time.perf_counter()
    with ThreadPoolExecutor(workers) as pool:
        for f in [pool.submit(worker, d) for d in datas]:
            f.result()
    return len(targets) / (time.perf_counter() - start)


def stack_rate(problem: Problem, bits: np.ndarray, workers: int) -> float:
    """Evaluations/s through the evolve stack, every candidate new to the cache."""
    evaluator = PhysicsFitness(problem.legs, problem.modules, workers).build()
    evaluator([problem.sequences("main", bits[:1])[0]])  # warm the thread pool
    start = time.perf_counter()
    seqs = problem.sequences("main", bits)
    _, _, paid = FitnessCache().evaluate(seqs, evaluator)
    return paid / (time.perf_counter() - start)


def stamp_rate(problem: Problem, bits: np.ndarray, workers: int, schedules: object) -> float:
    """Evaluations/s of the stamp-timed evaluator (schedule model → run_schedule)."""
    evaluator = StampTimedFitness(schedules, problem.legs, problem.modules, workers).build()
    evaluator([problem.sequences("main", bits[:1])[0]])  # warm the thread pool
    start = time.perf_counter()
    seqs = problem.sequences("main", bits)
    _, _, paid = FitnessCache().evaluate(seqs, evaluator)
    return paid / (time.perf_counter() - start)


def schedule_rate(schedules: object, seqs: np.ndarray, seconds: float = 1.0) -> float:
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for s in seqs:
            schedules.schedule(s)  # type: ignore[attr-defined]
        count += len(seqs)
    return count / (time.perf_counter() - start)


def ga_rate_with(model: str, params: GAParams, factory: Any) -> tuple[float, Any]:
    """Paid evaluations/s of a GA run with physics (offspring keep their parents' R^0 as
    evolution's do); and the evaluator."""
    evaluator = factory.build()
    start = time.perf_counter()
    state = run(new_run(Problem(model, transitions=params.transitions), params), evaluator)
    rate = state.cache.evaluations / (time.perf_counter() - start)
    evaluator.close()
    return rate, evaluator


def ga_rate(model: str, params: GAParams, factory: Any) -> float:
    return ga_rate_with(model, params, factory)[0]


def sequence_rate(model: str, pop: int, transitions: int, seconds: float = 1.0) -> float:
    problem = Problem(model, transitions=transitions)
    rng = np.random.default_rng(0)
    names = problem.populations
    bits = rng.integers(0, 2, (pop, problem.length(names[0])), dtype=np.uint8)
    partner = None
    if len(names) > 1:
        partner = rng.integers(0, 2, problem.length(names[1]), dtype=np.uint8)
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        problem.sequences(names[0], bits, partner)
        count += pop
    return count / (time.perf_counter() - start)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pop", type=int, default=100)
    ap.add_argument("--transitions", type=int, default=30)
    ap.add_argument("--ga-gens", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds, best kept")
    ap.add_argument("--stamp-gens", type=int, default=4, help="GA generations, stamp-timed")
    ap.add_argument(
        "--stamp-models",
        default="nnsin,nnsig,ca1d",
        help="models of the stamp-timed GA runs (comma-separated; '' = none)",
    )
    ap.add_argument(
        "--schedule-builds",
        type=int,
        default=3,
        help="also the population on an ensemble of K builds (evolve --schedule-builds; 0: no)",
    )
    args = ap.parse_args()

    problem = Problem("nnsin", transitions=args.transitions)
    bits = np.random.default_rng(1).integers(0, 2, (args.pop, 95), dtype=np.uint8)
    sim = Simulator(RobotSpec())
    seqs = problem.sequences("main", bits)
    steps = sim.steps_for(args.transitions)
    print(f"population {args.pop}, {args.transitions} transitions = {steps} mj_step per evaluation")
    rates = {}
    for workers in (1, 2):
        # alternate the two measurements and keep each one's best round, so a burst of load
        # from other processes does not land on one side only
        ours = raw = 0.0
        for _ in range(args.rounds):
            raw = max(raw, raw_rate(sim, seqs, workers))
            ours = max(ours, stack_rate(problem, bits, workers))
        rates[workers] = ours
        print(
            f"{workers} worker(s): {ours:7.2f} evaluations/s   raw MuJoCo {raw:7.2f}/s   "
            f"ratio {ours / raw:.3f}   ({1e6 / (raw * steps / workers):.1f} µs per mj_step)"
        )
    print(f"2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")

    from hil_mock.schedule_model import schedule_model  # the bench may use the twin

    start = time.perf_counter()
    schedules = schedule_model("nnsin")
    fit_s = time.perf_counter() - start
    sample = schedules.schedule(seqs[0])
    print(
        f"stamp-timed (nnsin schedule model, fitted in {fit_s:.1f} s): "
        f"{schedule_rate(schedules, seqs):.0f} schedules/s; physics per run "
        f"{sample.duration:.2f} s vs plain {steps * sim.model.opt.timestep:.2f} s"
    )
    for workers in (1, 2):
        plain = timed = 0.0
        for _ in range(args.rounds):
            plain = max(plain, stack_rate(problem, bits, workers))
            timed = max(timed, stamp_rate(problem, bits, workers, schedules))
        print(
            f"{workers} worker(s): stamp-timed {timed:7.2f} evaluations/s   plain {plain:7.2f}/s"
            f"   ratio {timed / plain:.3f}"
        )
    if args.schedule_builds:  # a candidate is K physics runs: expect about 1/K of the above
        ensemble = schedule_model("nnsin", builds=args.schedule_builds)
        plain = timed = 0.0
        for _ in range(args.rounds):
            plain = max(plain, stack_rate(problem, bits, 1))
            timed = max(timed, stamp_rate(problem, bits, 1, ensemble))
        print(
            f"1 worker, --schedule-builds {args.schedule_builds}: stamp-timed {timed:7.2f} "
            f"evaluations/s   plain {plain:7.2f}/s   ratio {timed / plain:.3f}"
        )

    for model in filter(None, args.stamp_models.split(",")):  # "" = no GA runs
        params = GAParams(pop=args.pop, gens=args.stamp_gens, transitions=args.transitions, seed=2)
        model_schedules = schedule_model(model)
        timed_rate = plain_rate = 0.0
        hits = ""
        for _ in range(args.rounds):
            plain_rate = max(plain_rate, ga_rate(model, params, PhysicsFitness(workers=1)))
            factory = StampTimedFitness(model_schedules, workers=1)
            rate, evaluator = ga_rate_with(model, params, factory)
            timed_rate = max(timed_rate, rate)
            cache = evaluator.runner.power_ups
            hits = f"power-ups restored {cache.hits}/{cache.hits + cache.misses}"
        print(
            f"{model} GA ({args.stamp_gens} generations of {args.pop}, 1 worker): stamp-timed "
            f"{timed_rate:.2f} evaluations/s, plain {plain_rate:.2f}/s, ratio "
            f"{timed_rate / plain_rate:.3f} ({hits})"
        )

    for model in ("ca1d", "ca2dsing"):
        params = GAParams(pop=args.pop, gens=args.ga_gens, transitions=args.transitions, seed=1)
        state = run(new_run(Problem(model, transitions=args.transitions), params), ToyEvaluator())
        s = state.stats()
        print(
            f"{model} GA ({args.ga_gens} generations, P_M {params.pm}, toy fitness): "
            f"{s['offspring_skipped']}/{s['offspring']} offspring skipped "
            f"({s['offspring_skipped'] / s['offspring']:.1%}), "
            f"{s['cache_hits']} cache hits incl. elites"
        )

    for model in ("ca1d", "ca2ddiff", "nnsin"):
        rate = sequence_rate(model, args.pop, args.transitions)
        print(f"state sequences {model:8s}: {rate:10.0f} sequences/s (population {args.pop})")


if __name__ == "__main__":
    main()
