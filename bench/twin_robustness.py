"""How today's link protocol fares on a twin as unkind as real stamps (issue 12 §1).

    python bench/twin_robustness.py [--models ca1d nnsin ...] [-T 12] [--seed 1] [--seeds N]
                                    [--quick]

Compiles each shipped controller (bstool/data/controllers/) once into a temporary folder, then
runs the twin without physics (``RobotTwin(perturb=...)``, i.e. ``bstool twin --no-physics``)
for every case: timing scale 0.5-3, timing spread ±20 %, clock spread ±2 %, start spread
0-3 s, the stamp serial item time, a single reset of a lead (0.0) and of a middle module (2.3)
for 0.1-0.8 s, 1 % byte noise (``--link-noise``) and combinations. Each module's states are
compared with the healthy reference ``controller.states(T)``, or for a reset with what the
record says happened (below). Prints one markdown table, a cell per model and case:
``exact/total`` (modules whose whole sequence equals the reference / modules), the mean
transition period (s) and the longest servo gap (ms; the reset module's own outage left out),
``!`` when some module stalled (made fewer than T transitions in the time limit). With
``--seeds N`` every case with random draws (spreads, noise) runs seeds seed..seed+N-1: the cell
sums the exact modules over the runs, averages the periods and takes the longest gap.
``--only TEXT`` keeps the cases whose name contains TEXT.
``--quick`` runs a smoke subset (two models, eight cases, T = 8); ``--noise-on-top`` adds every
case without noise once more with 1 % byte noise (the issue: "alone and combined, with 1 % byte
noise on top"). The resets of 0.1-0.8 s are shorter than the dead-limit (1.5 s, protocol/link.md):
the healthy reference. The long outages (2 and 3 s, at 2 s, after the first transitions) are
compared with what the record says happened (hil_mock/outage.py): healthy if the neighbours
waited, else ``controller.states(T, failed_at={c: T0}, rejoin={c: T2})`` (docs/controllers.md
"Rejoin").
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bstool.buildfile import Build
from bstool.builtin import MODELS, builtin_controller
from bstool.compile import compile_controller
from bstool.controllers import Controller, load_controller
from hil_mock.outage import compared_states, outage_reference, outages
from hil_mock.perturb import Perturbation, Reset
from hil_mock.robot import RobotTwin, load_build

RESET_AT_S = 2.0  # after the first transitions (the join; about 0.5 s unperturbed), before T = 12
LONG_AT_S = 2.0  # a long outage early enough that the module is back before T = 12
NOISE = 0.01


def cases(quick: bool, noise_on_top: bool = False) -> list[tuple[str, Perturbation, float]]:
    """(name, perturbation, link noise) in table order (with ``noise_on_top``, each case without
    noise is followed by itself with 1 % byte noise)."""
    table = _cases(quick)
    if not noise_on_top:
        return table
    out: list[tuple[str, Perturbation, float]] = []
    for name, p, noise in table:
        out.append((name, p, noise))
        if noise == 0 and name != "neutral":
            out.append((f"{name} + noise 1 %", p, NOISE))
    return out


def _cases(quick: bool) -> list[tuple[str, Perturbation, float]]:
    P = Perturbation

    def reset(module: str, off: float) -> P:
        return P(resets=(Reset(module, RESET_AT_S, off),))

    combo = P(timing_scale=1.5, timing_spread=0.1, clock_spread=0.01, start_spread=1.0,
              item_time_us=50.0)  # fmt: skip
    harsh = P(timing_scale=2.0, timing_spread=0.2, clock_spread=0.02, start_spread=3.0,
              item_time_us=100.0, resets=(Reset("2.3", RESET_AT_S, 0.4),))  # fmt: skip
    if quick:
        return [
            ("neutral", P(), 0.0),
            ("timing scale 3", P(timing_scale=3.0), 0.0),
            ("timing spread ±20 %", P(timing_spread=0.2), 0.0),
            ("clock spread ±2 %", P(clock_spread=0.02), 0.0),
            ("start spread 3 s", P(start_spread=3.0), 0.0),
            ("reset 0.0 for 0.4 s", reset("0.0", 0.4), 0.0),
            ("noise 1 %", P(), NOISE),
            ("combined + noise 1 %", combo, NOISE),
        ]
    out: list[tuple[str, Perturbation, float]] = [("neutral", P(), 0.0)]
    out += [(f"timing scale {f:g}", P(timing_scale=f), 0.0) for f in (0.5, 0.75, 1.5, 2.0, 3.0)]
    out += [(f"timing spread ±{p:.0%}", P(timing_spread=p), 0.0) for p in (0.05, 0.1, 0.2)]
    out += [(f"clock spread ±{p:.1%}", P(clock_spread=p), 0.0) for p in (0.005, 0.01, 0.02)]
    out += [(f"start spread {s:g} s", P(start_spread=s), 0.0) for s in (0.5, 1.0, 2.0, 3.0)]
    out += [(f"item time {u:g} us", P(item_time_us=u), 0.0) for u in (50.0, 150.0)]
    for module, where in (("0.0", "lead"), ("2.3", "middle")):
        out += [(f"reset {where} {module} for {off:g} s", reset(module, off), 0.0)
                for off in (0.1, 0.4, 0.8)]  # fmt: skip
    for module, where in (("0.0", "lead"), ("2.3", "middle")):
        out += [(f"long outage {where} {module} for {off:g} s",
                 P(resets=(Reset(module, LONG_AT_S, off),)), 0.0)
                for off in (2.0, 3.0)]  # fmt: skip
    out.append(("noise 1 %", P(), NOISE))
    out.append(("scale 2 + spread ±20 %", P(timing_scale=2.0, timing_spread=0.2), 0.0))
    out.append(("clock ±1 % + item 50 us", P(clock_spread=0.01, item_time_us=50.0), 0.0))
    out.append(("combined (1.5, ±10 %, ±1 %, 1 s, 50 us)", combo, 0.0))
    out.append(("combined + noise 1 %", combo, NOISE))
    out.append(("harsh (2, ±20 %, ±2 %, 3 s, 100 us, reset 2.3) + noise", harsh, NOISE))
    return out


def run_once(
    build: Build, ctrl: Controller, T: int, p: Perturbation, noise: float
) -> tuple[int, float, float, bool]:
    """(exact modules, mean period s, longest servo gap s, stalled) of one run."""
    twin = RobotTwin(build, noise=noise, seed=p.seed, physics=False, perturb=p)
    result = twin.run(T)
    outs = outages(twin)
    want = outage_reference(ctrl, T, outs)
    got = compared_states(result.states, want, outs)
    exact = sum(seq[: T + 1] == want[:, m.leg, m.module].tolist() for m, seq in got.items())
    outage = twin.perturb.reset_modules()
    gaps = [g for m, g in result.servo_gaps.items() if m not in outage]
    off = {o.module for o in outs if o.long and o.rejoin is None}  # still off: dead, not stalled
    stalled = [m for m in result.stalled if m not in off]
    return exact, result.period_stats()[0], max(gaps), bool(stalled)


def run_case(
    build: Build, ctrl: Controller, T: int, p: Perturbation, noise: float, seeds: list[int]
) -> str:
    """One table cell, over ``seeds`` if the case draws anything (else one run counts for
    all)."""
    drawn = noise > 0 or p.timing_spread > 0 or p.clock_spread > 0 or p.start_spread > 0
    runs = [
        run_once(build, ctrl, T, replace(p, seed=s), noise) for s in (seeds if drawn else seeds[:1])
    ]
    k = len(seeds) // len(runs)
    exact = k * sum(r[0] for r in runs)
    total = build.legs * build.modules * len(seeds)
    mean = float(np.mean([r[1] for r in runs]))
    gap = max(r[2] for r in runs)
    stalled = "!" if any(r[3] for r in runs) else ""
    return f"{exact}/{total}{stalled} · {mean:.3f} · {gap * 1000:.0f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    parser.add_argument("-T", "--transitions", type=int, default=None)
    parser.add_argument("--seed", type=int, default=1, help="seed of every draw and the noise")
    parser.add_argument("--seeds", type=int, default=1, help="runs per case with random draws")
    parser.add_argument("--quick", action="store_true", help="smoke subset")
    parser.add_argument(
        "--noise-on-top", action="store_true", help="every case again with 1 %% byte noise"
    )
    parser.add_argument("--only", default="", help="only the cases whose name contains this")
    args = parser.parse_args()
    models = args.models if not args.quick or args.models != list(MODELS) else ["ca1d", "nnsin"]
    T = args.transitions or (8 if args.quick else 12)
    table = [c for c in cases(args.quick, args.noise_on_top) if args.only in c[0]]
    cells: dict[tuple[str, str], str] = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for model in models:
            source = builtin_controller(model)
            out = Path(tmp) / model
            compile_controller(source, out)
            build = load_build(out)
            ctrl = load_controller(source)
            for name, p, noise in table:
                seeds = list(range(args.seed, args.seed + args.seeds))
                cells[model, name] = run_case(build, ctrl, T, p, noise, seeds)
                print(f"{model:9} {name:55} {cells[model, name]}", file=sys.stderr, flush=True)
    seeds = f"{args.seed}..{args.seed + args.seeds - 1}"
    print(f"\nT = {T}, seeds {seeds}; cell: exact modules/total · mean period s · longest "
          f"servo gap ms (! = stalled); {time.perf_counter() - start:.0f} s\n")  # fmt: skip
    print("| case | " + " | ".join(models) + " |")
    print("|---|" + "---|" * len(models))
    for name, _, _ in table:
        print(f"| {name} | " + " | ".join(cells[m, name] for m in models) + " |")


if __name__ == "__main__":
    main()
