"""Simulator throughput next to raw MuJoCo stepping on the same model (ratios, one run).

    python bench/simulator.py [--population 16] [--transitions 30]

1. One run (Simulator.run on random gaits): transitions/s and MuJoCo steps/s, against raw
   stepping of the same controls (reset, set ctrl, mj_step(nstep) per transition) and a bare
   Python loop of single mj_step calls.
2. Batches: evaluations/s of BatchEvaluator with 1 and 2 threads against raw stepping with the
   same number of threads (one MjData each), and sequential vs thread pool vs mujoco.rollout.
"""

from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Callable

import mujoco
import numpy as np

from bstool.sim import BatchEvaluator, Simulator


def interleaved(repeat: int, fns: dict[str, Callable[[], object]]) -> dict[str, float]:
    """Best time of each function over ``repeat`` rounds, run in turn (A B C A B C ...), so
    that load from other processes hits every variant alike."""
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeat):
        for name, fn in fns.items():
            t = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - t)
    return best


def raw_run(sim: Simulator, targets: np.ndarray, data: mujoco.MjData) -> None:
    """The same physics as Simulator.run with nothing else around it."""
    mujoco.mj_resetData(sim.model, data)
    data.ctrl[:] = targets[0]
    mujoco.mj_step(sim.model, data, nstep=sim.settle_steps)
    for t in range(1, len(targets)):
        data.ctrl[:] = targets[t]
        mujoco.mj_step(sim.model, data, nstep=sim.steps_per_transition)


def raw_threads(sim: Simulator, all_targets: list[np.ndarray], workers: int) -> None:
    datas = [mujoco.MjData(sim.model) for _ in range(workers)]
    lock = threading.Lock()
    nxt = [0]

    def work(data: mujoco.MjData) -> None:
        while True:
            with lock:
                i = nxt[0]
                nxt[0] += 1
            if i >= len(all_targets):
                return
            raw_run(sim, all_targets[i], data)

    threads = [threading.Thread(target=work, args=(d,)) for d in datas]
    for th in threads:
        th.start()
    for th in threads:
        th.join()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--population", type=int, default=16)
    ap.add_argument("--transitions", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()

    sim = Simulator()
    rng = np.random.default_rng(0)
    pop = [rng.integers(0, 16, (args.transitions + 1, 5, 6)) for _ in range(args.population)]
    targets = [sim.angles(s) for s in pop]
    steps = sim.steps_for(args.transitions)
    n_pop = len(pop)
    print(
        f"model: {sim.model.nbody - 1} bodies, {sim.model.nu} actuators, timestep "
        f"{sim.model.opt.timestep * 1000:g} ms; transition {sim.transition_time:g} s ="
        f" {sim.steps_per_transition} steps, settle {sim.settle_steps} steps;"
        f" {args.transitions} transitions = {steps} steps per evaluation"
    )

    # 1. one run at a time --------------------------------------------------------------
    data = mujoco.MjData(sim.model)

    def loop_single() -> None:
        for tg in targets:
            mujoco.mj_resetData(sim.model, data)
            for t in range(len(tg)):
                data.ctrl[:] = tg[t]
                for _ in range(sim.settle_steps if t == 0 else sim.steps_per_transition):
                    mujoco.mj_step(sim.model, data)

    one = interleaved(
        args.repeat,
        {
            "Simulator.run": lambda: [sim.run(s) for s in pop],
            "raw mj_step(nstep)": lambda: [raw_run(sim, tg, data) for tg in targets],
            "raw mj_step loop": loop_single,
        },
    )
    total_steps = steps * n_pop
    total_trans = args.transitions * n_pop
    print("\n[one run at a time, 1 thread]")
    for label, t in one.items():
        print(
            f"  {label:20s} {total_trans / t:8.1f} transitions/s {total_steps / t:9.0f} steps/s"
            f"  ({t / total_steps * 1e6:.1f} µs/step)"
        )
    t_sim = one["Simulator.run"]
    print(f"  ratio Simulator / raw nstep: {one['raw mj_step(nstep)'] / t_sim:.3f}")
    print(f"  ratio Simulator / raw loop:  {one['raw mj_step loop'] / t_sim:.3f}")

    # 2. batches --------------------------------------------------------------------------
    print(f"\n[batches of {n_pop} evaluations]")
    evs = {
        "threads1": BatchEvaluator(workers=1, method="threads"),
        "threads2": BatchEvaluator(workers=2, method="threads"),
        "rollout2": BatchEvaluator(workers=2, method="rollout"),
        "sequential": BatchEvaluator(workers=1, method="sequential"),
    }
    fns: dict[str, Callable[[], object]] = {
        name: (lambda ev=ev: ev.evaluate(pop)) for name, ev in evs.items()
    }
    fns["raw1"] = lambda: raw_threads(sim, targets, 1)
    fns["raw2"] = lambda: raw_threads(sim, targets, 2)
    bt = interleaved(args.repeat, fns)
    for ev in evs.values():
        ev.close()
    rate = {k: n_pop / v for k, v in bt.items()}
    for w in (1, 2):
        print(
            f"  {w} thread(s): BatchEvaluator {rate[f'threads{w}']:6.2f} eval/s,"
            f" raw stepping {rate[f'raw{w}']:6.2f} eval/s,"
            f" ratio {rate[f'threads{w}'] / rate[f'raw{w}']:.3f}"
        )
    print(f"  2 threads over 1 thread: {rate['threads2'] / rate['threads1']:.2f}x")
    print(f"  sequential           {rate['sequential']:6.2f} eval/s")
    print(f"  thread pool (2)      {rate['threads2']:6.2f} eval/s")
    print(f"  mujoco.rollout (2)   {rate['rollout2']:6.2f} eval/s")


if __name__ == "__main__":
    main()
