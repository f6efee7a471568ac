"""Every module failing alone on the twin: do the compiled programs equal the reference?

    python bench/twin_die_sweep.py [--models nnsin ca1d ...] [-T 30] [--at 5 | --power-up]

For each model, compiles the shipped controller, then for each of the n·m modules runs the
twin (no physics) with that module dying at transition ``--at`` (``RobotTwin(die=...)``, i.e.
``bstool twin --die L.M@T``) and compares every module's states with
``controller.states(T, failed_at={module: at})``. Prints per model how many of the single
dying modules gave exactly the reference, the mean period of the live modules before the death
and after the switch-over (transitions at + 4 .. T, protocol/link.md §5), the slowest single
transition in between, the longest servo gap, and the first mismatch if any.

``--power-up`` instead kills each module from power-up (``bstool twin --fail L.M``) and
compares with ``controller.states(T, failed=[module])``; it prints the range of mean periods.

``--pairs`` (NN models) kills two modules of one leg one after the other: module a at ``--at``,
module b at ``--at2``, for every leg, both orders and every pair ``--gap`` apart along the leg
(default 1: neighbours; ``--gap 0``: every pair). Every module before the pair, the pair itself
and every other leg must equal ``controller.states(T, failed_at={a: at, b: at2})``; modules
after two *neighbours* that are both dead are the documented limit (docs/compile.md: they keep
the last upstream states they received) and must equal :func:`bstool.compile.emulate.run` with
the same deaths, the compiled tables run at the state level. Prints exact/total per model
(and how many of them also equal the reference outright) and the first mismatches.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from bstool.builtin import MODELS, builtin_controller
from bstool.compile import compile_controller, emulate
from bstool.compile.calibration import DEFAULT
from bstool.compile.plan import build_plans
from bstool.controllers import NN_MODELS, Controller, load_controller
from bstool.moduleid import ModuleId, all_modules
from hil_mock.robot import RobotTwin, TwinResult, load_build


def periods(result: TwinResult, dead: ModuleId, first: int, last: int) -> list[float]:
    """Mean period of the live modules for each transition index first..last-1."""
    out = []
    for i in range(first, last):
        ps = [p[i] for m, p in result.periods.items() if m != dead and i < len(p)]
        if ps:
            out.append(float(np.mean(ps)))
    return out


def pair_cases(legs: int, modules: int, gap: int) -> list[tuple[ModuleId, ModuleId]]:
    """(first to die, second to die) on every leg, both orders, ``gap`` apart (0: any)."""
    out = []
    for i in range(legs):
        for a in range(modules):
            for b in range(modules):
                if a != b and (gap == 0 or abs(a - b) == gap):
                    out.append((ModuleId(i, a), ModuleId(i, b)))
    return out


def pairs_sweep(model: str, build_dir: Path, T: int, at: int, at2: int, gap: int) -> None:
    """Two modules of a leg dying one after the other (``--pairs``)."""
    ctrl: Controller = load_controller(builtin_controller(model))
    build = load_build(build_dir)
    plans = build_plans(ctrl, DEFAULT, build.period, "0" * 8)
    cases = pair_cases(ctrl.legs, ctrl.modules, gap)
    exact = outright = 0
    bad: list[str] = []
    start = time.perf_counter()
    for first, second in cases:
        die = {first: at, second: at2}
        want = ctrl.states(T, failed_at=die)
        limit = emulate.run(plans, T, die=die)  # the documented limit after two dead neighbours
        lo, hi = sorted((first.module, second.module))
        after_pair = hi - lo == 1  # modules past two dead neighbours: the limit applies
        leg = first.leg
        for j in range(ctrl.modules):  # the limit may only differ after the pair
            if not (after_pair and j > hi):
                assert np.array_equal(limit[:, leg, j], want[:, leg, j]), (model, die, j)
        result = RobotTwin(build, die=die, physics=False).run(T)
        got = result.state_array(ctrl.legs, ctrl.modules, T)
        if np.array_equal(got, limit) and not result.stalled:
            exact += 1
            outright += int(np.array_equal(got, want))
            continue
        diff = [(t, f"{i}.{j}") for t, i, j in zip(*np.nonzero(got != limit), strict=True)]
        t0, who = min(diff) if diff else (0, "stalled")
        bad.append(f"{first}@{at},{second}@{at2}: {who} from {t0}")
    wall = time.perf_counter() - start
    apart = "any distance" if gap == 0 else f"{gap} apart"
    print(f"{model:9} pairs ({apart}) dying at {at} and {at2}: {exact}/{len(cases)} exact over "
          f"{T} transitions ({outright} equal to the reference outright); {wall:.0f} s",
          flush=True)  # fmt: skip
    for line in bad[:40]:
        print(f"    mismatch {line}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    parser.add_argument("-T", "--transitions", type=int, default=30)
    parser.add_argument("--at", type=int, default=5, help="transition at which the module dies")
    parser.add_argument(
        "--power-up", action="store_true", help="dead from power-up (--fail) instead of --at"
    )
    parser.add_argument(
        "--pairs", action="store_true", help="NN: two modules of a leg dying at --at and --at2"
    )
    parser.add_argument("--at2", type=int, default=10, help="--pairs: the second death")
    parser.add_argument(
        "--gap", type=int, default=1, help="--pairs: modules this far apart (0: every pair)"
    )
    args = parser.parse_args()
    T, at = args.transitions, args.at
    models = [m for m in args.models if m in NN_MODELS] if args.pairs else args.models
    with tempfile.TemporaryDirectory() as tmp:
        for model in models:
            source = builtin_controller(model)
            ctrl = load_controller(source)
            out = Path(tmp) / model
            compile_controller(source, out)
            if args.pairs:
                pairs_sweep(model, out, T, at, args.at2, args.gap)
                continue
            build = load_build(out)
            exact, before, after, worst, gaps, first_bad = 0, [], [], 0.0, [], None
            start = time.perf_counter()
            modules = all_modules(ctrl.legs, ctrl.modules)
            for dead in modules:
                if args.power_up:
                    result = RobotTwin(build, failed=[dead], physics=False).run(T)
                    want = ctrl.states(T, failed=[dead])
                else:
                    result = RobotTwin(build, die={dead: at}, physics=False).run(T)
                    want = ctrl.states(T, failed_at={dead: at})
                got = result.state_array(ctrl.legs, ctrl.modules, T)
                if np.array_equal(got, want) and not result.stalled:
                    exact += 1
                elif first_bad is None:
                    first_bad = dead
                gaps.append(max(result.servo_gaps.values()))
                if args.power_up:
                    before.append(result.period_stats()[0])
                    continue
                before += periods(result, dead, 1, at - 1)
                after += periods(result, dead, at + 4, T - 1)
                worst = max([worst, *periods(result, dead, at - 1, at + 4)])
            wall = time.perf_counter() - start
            if args.power_up:
                print(f"{model:9} dead from power-up: {exact}/{len(modules)} exact over {T} "
                      f"transitions; mean period {min(before):.4f}-{max(before):.4f} s; longest "
                      f"servo gap {max(gaps) * 1000:.1f} ms; first mismatch: "
                      f"{first_bad or 'none'}; {wall:.0f} s", flush=True)  # fmt: skip
                continue
            print(f"{model:9} dying at {at}: {exact}/{len(modules)} exact over {T} transitions; "
                  f"period before {np.mean(before):.4f} s, after the switch-over "
                  f"{np.mean(after):.4f} s (transitions {min(after):.4f}-{max(after):.4f}), "
                  f"slowest in between {worst:.3f} s; longest servo gap "
                  f"{max(gaps) * 1000:.1f} ms; first mismatch: {first_bad or 'none'}; "
                  f"{wall:.0f} s", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
