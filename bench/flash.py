"""Upload time of one full slot (128 records) against the twin emulating a 9600-baud line.

Prints the measured time as a ratio to the line's physical limit, bytes x 10 bits / 9600 baud
(bytes = everything the host sends: identification, slot, 128 x 18 record bytes, end byte).
Target: ratio <= 1.15 (docs/flash.md). Run: python bench/flash.py [--repeat N]
"""

from __future__ import annotations

import argparse
import random
import time

import hil_mock  # noqa: F401  (registers bstwin://)
from bstool.flash import Programmer, Timing
from bstool.flash.port import open_port
from bstool.wire import programming as P
from hil_mock.progdevice import ProgrammingDevice
from hil_mock.ptyendpoint import PtyEndpoint
from hil_mock.urlhandler import add_twin, remove_twin

_rng = random.Random(1)
IMAGE = bytes(_rng.randrange(256) for _ in range(P.SLOT_SIZE))
RECORDS = P.records_for_image(IMAGE, list(range(P.BLOCKS)))


def one_upload(port: str, device: ProgrammingDevice) -> tuple[float, int, float | None]:
    """(wall seconds, bytes sent, virtual line seconds or None) of one session."""
    ser = open_port(port, timeout=0.25)
    prog = Programmer(ser, timing=Timing())
    line = getattr(ser, "_line", None)
    v0 = line.now() if line is not None else 0.0
    t0 = time.perf_counter()
    result = prog.upload_slot(0, RECORDS)
    wall = time.perf_counter() - t0
    virtual = line.now() - v0 if line is not None and line.timing == "virtual" else None
    ser.close()
    assert device.eeprom.slot(0) == IMAGE, "image differs"
    return wall, result.bytes_sent, virtual


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    print(f"one full slot: {len(RECORDS)} records; line limit = bytes x 10 / 9600 s")
    print(f"{'endpoint':<28} {'bytes':>6} {'seconds':>8} {'limit s':>8} {'ratio':>6}")
    rows = []
    for timing in ("real", "virtual"):
        for _ in range(args.repeat):
            device = add_twin("bench", ProgrammingDevice())
            wall, n, virtual = one_upload(f"bstwin://bench?timing={timing}", device)
            remove_twin("bench")
            seconds = virtual if virtual is not None else wall
            rows.append((f"bstwin:// ({timing} time)", n, seconds))
    for _ in range(args.repeat):
        device = ProgrammingDevice()
        with PtyEndpoint(device, timing="real") as ep:
            wall, n, _ = one_upload(ep.path, device)
        rows.append(("pty (real time)", n, wall))
    for name, n, seconds in rows:
        limit = P.line_limit_seconds(n)
        print(f"{name:<28} {n:>6} {seconds:>8.3f} {limit:>8.3f} {seconds / limit:>6.3f}")
    best_real = min(
        s / P.line_limit_seconds(n) for name, n, s in rows if "bstwin" in name and "real" in name
    )
    print(f"bstwin real-time ratio (best of {args.repeat}): {best_real:.3f}  (target <= 1.15)")


if __name__ == "__main__":
    main()
