"""Every module dead alone on the twin: do the compiled programs still equal the reference?

    python bench/twin_dead_sweep.py [--models nnsin ca1d ...] [-T 25]

For each model, compiles the shipped controller, then for each of the n·m modules runs the
twin (no physics) with that module dead from power-up and compares every module's states
with ``controller.states(T, failed=[module])``. Prints per model how many of the single dead
modules gave exactly the reference, the range of mean periods, and the first mismatch if any.
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
from bstool.moduleid import all_modules
from hil_mock.robot import RobotTwin, load_build


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    parser.add_argument("-T", "--transitions", type=int, default=25)
    args = parser.parse_args()
    T = args.transitions
    with tempfile.TemporaryDirectory() as tmp:
        for model in args.models:
            source = builtin_controller(model)
            ctrl = load_controller(source)
            out = Path(tmp) / model
            compile_controller(source, out)
            build = load_build(out)
            exact, periods, first_bad = 0, [], None
            start = time.perf_counter()
            modules = all_modules(ctrl.legs, ctrl.modules)
            for dead in modules:
                result = RobotTwin(build, failed=[dead], physics=False).run(T)
                got = result.state_array(ctrl.legs, ctrl.modules, T)
                if np.array_equal(got, ctrl.states(T, failed=[dead])) and not result.stalled:
                    exact += 1
                elif first_bad is None:
                    first_bad = dead
                periods.append(result.period_stats()[0])
            wall = time.perf_counter() - start
            print(f"{model:9} dead alone: {exact}/{len(modules)} exact over {T} transitions; "
                  f"mean period {min(periods):.4f}-{max(periods):.4f} s; "
                  f"first mismatch: {first_bad or 'none'}; {wall:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
