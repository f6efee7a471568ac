"""Speed of the BS2sx token interpreter alone: instructions per wall second, and virtual seconds
per wall second, on the tokenizer vectors' images (Parallax's tokens), in one run.

    python bench/interpreter.py [--seconds 2]

Target (issue 7): >= 50,000 instructions/s per core (the real BS2sx runs ~10,000/s).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

VECTORS = Path(__file__).resolve().parents[2] / "shared" / "vectors" / "tokenizer"
CASES = [
    ("flow_goto_gosub", "GOSUB/RETURN/IF/assignments, endless"),
    ("if_single_compare", "IF compares and arithmetic, endless"),
    ("robot_ca_module", "robot module alone: PULSOUT/PAUSE/SEROUT/SERIN timeouts/READ"),
    ("multi_robot_rules", "robot module alone with RUN between 3 slots"),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0, help="wall seconds per case")
    args = ap.parse_args()

    from hil_mock.stamp import SimpleEeprom, Stamp, Status
    from hil_mock.stamp.codegen import load_program

    print(f"{'case':20} {'instructions/s':>15} {'virtual s/wall s':>17}  what")
    for name, what in CASES:
        folder = VECTORS / name
        images = [p.read_bytes() for p in sorted(folder.glob("slot*.eeprom"))]
        t0 = time.perf_counter()
        for img in images:
            load_program(img)
        decode = time.perf_counter() - t0
        stamp = Stamp(SimpleEeprom(images), name=name)
        t0 = time.perf_counter()
        wall = 0.0
        while wall < args.seconds:
            for _ in range(1000):
                if stamp.status is Status.WAITING:
                    stamp.expire_wait()  # alone: every SERIN times out
                stamp.run_until(stamp.t + 50_000_000, max_steps=20_000)
            wall = time.perf_counter() - t0
        print(
            f"{name:20} {stamp.instructions / wall:15,.0f} {stamp.time / wall:17,.1f}  {what}"
            f" (decode+translate {decode * 1e3:.1f} ms)"
        )


if __name__ == "__main__":
    main()
