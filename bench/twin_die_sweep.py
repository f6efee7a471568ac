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
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from bstool.builtin import MODELS, builtin_controller
from bstool.compile import compile_controller
from bstool.controllers import load_controller
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    parser.add_argument("-T", "--transitions", type=int, default=30)
    parser.add_argument("--at", type=int, default=5, help="transition at which the module dies")
    parser.add_argument(
        "--power-up", action="store_true", help="dead from power-up (--fail) instead of --at"
    )
    args = parser.parse_args()
    T, at = args.transitions, args.at
    with tempfile.TemporaryDirectory() as tmp:
        for model in args.models:
            source = builtin_controller(model)
            ctrl = load_controller(source)
            out = Path(tmp) / model
            compile_controller(source, out)
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
