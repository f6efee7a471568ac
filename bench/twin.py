"""Speed of the robot twin: real-time factor of the 30-module twin with physics (virtual seconds
per wall second) and without, next to one interpreter alone (instructions/s), in one run.

    python bench/twin.py [--transitions 20] [--model nnsin]

Target (issue 7): the full robot at >= 5x real time on one core.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--transitions", type=int, default=20)
    ap.add_argument("--model", default="nnsin")
    args = ap.parse_args()

    from bstool.builtin import builtin_controller
    from bstool.compile import compile_controller
    from hil_mock.robot import GlobalSchedulerTwin, RobotTwin, load_build
    from hil_mock.stamp import Stamp, Status

    with tempfile.TemporaryDirectory() as tmp:
        build_dir = Path(tmp) / "build"
        compile_controller(builtin_controller(args.model), build_dir)
        build = load_build(build_dir)

        rows = []
        for label, cls, physics in (
            ("30 modules + MuJoCo", RobotTwin, True),
            ("30 modules, no physics", RobotTwin, False),
            ("no physics, global sched.", GlobalSchedulerTwin, False),
        ):
            twin = cls(build, physics=physics)
            t0 = time.perf_counter()
            run = twin.run(args.transitions)
            wall = time.perf_counter() - t0
            rows.append((label, run.virtual_seconds, wall, run.instructions))
        # one interpreter alone: the lead of leg 0 with nobody answering its links
        from bstool.moduleid import ModuleId

        images = build.images(ModuleId(0, 0))
        stamp = Stamp([images.get(n, bytes(2048)) for n in range(8)])
        t0 = time.perf_counter()
        while stamp.time < 20.0 and stamp.instructions < 2_000_000:
            if stamp.status is Status.WAITING:  # nobody answers: every SERIN times out
                stamp.expire_wait()
            elif stamp.run(seconds=20.0 - stamp.time) is not Status.WAITING:
                break
        alone = time.perf_counter() - t0

    print(f"model {args.model}, {args.transitions} transitions, period {build.period:.3f} s")
    for label, virtual, wall, instr in rows:
        print(
            f"{label:26} virtual {virtual:7.2f} s  wall {wall:6.2f} s  "
            f"real-time factor {virtual / wall:6.2f}x  ({instr / wall:,.0f} instructions/s)"
        )
    print(
        f"{'one interpreter alone':26} {stamp.instructions:,} instructions in {alone:.2f} s: "
        f"{stamp.instructions / alone:,.0f} instructions/s "
        f"({stamp.time / alone:.1f}x real time for that module)"
    )
    print(f"ratio physics/no-physics wall time: {rows[0][2] / rows[1][2]:.2f}")
    print(f"ratio global/local scheduler wall time (no physics): {rows[2][2] / rows[1][2]:.2f}")


if __name__ == "__main__":
    main()
