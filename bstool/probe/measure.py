"""``bstool probe``: flash the measurement program to one stamp and time what it sends back.

The host keeps the port open after the upload (the stamp starts slot 0 at the end of the
session), waits for the program's header line, then stamps each marker byte with
``time.monotonic()`` as it is read, one byte per read (markers are tens of ms apart, so a read
never holds two). Markers carry their segment number: a lost or garbled byte drops the two
intervals around it instead of shifting the rest. The fit (:mod:`bstool.probe.fit`) takes care
of the host's timestamp jitter.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

from bstool.errors import DeviceError
from bstool.flash import ModulePlan, SlotPlan, Timing, flash_module, open_port
from bstool.flash.errors import FlashInterrupted, PortError
from bstool.probe import fit
from bstool.probe.program import END_MARKER, HEADER, ProbeProgram, build
from bstool.timingfile import TimingModel, stamped

HEADER_WAIT_S = 3.0  # after the upload, until the program's first line
SLOW_FACTOR = 4.0  # a stamp this much slower than the model still gets its markers
NOT_RUNNING_HINT = (
    "the stamp took the program but does not run it: check it is a BS2sx powered by a steady "
    "supply, that nothing holds its ATN/reset line, and run bstool probe again"
)


@dataclass
class ProbeResult:
    model: TimingModel
    program: ProbeProgram
    port: str
    markers: int
    lost: int
    seconds: float  # wall time of the measurement (after the upload)


def plan_for(program: ProbeProgram) -> ModulePlan:
    image = program.image
    return ModulePlan(None, [SlotPlan(0, list(image.records), bytes(image.eeprom))])


def _wait_header(ser: serial.Serial, port: str) -> None:
    want = HEADER.encode() + b"\r"
    buf = b""
    deadline = time.monotonic() + HEADER_WAIT_S
    while time.monotonic() < deadline:
        ser.timeout = max(0.01, min(0.1, deadline - time.monotonic()))
        chunk = ser.read(1)
        if chunk:
            buf = (buf + chunk)[-64:]
            if buf.endswith(want):
                return
    heard = f" (heard {buf[-20:]!r})" if buf else " (nothing heard)"
    raise DeviceError(
        f"the stamp on {port} took the probe program but did not start it within "
        f"{HEADER_WAIT_S:g} s{heard}",
        hint=NOT_RUNNING_HINT,
    )


def read_markers(
    ser: serial.Serial,
    program: ProbeProgram,
    *,
    port: str,
    clock: Callable[[], float] = time.monotonic,
    on_marker: Callable[[], None] | None = None,
) -> tuple[dict[tuple[int, int], float], int]:
    """Marker arrival times by (repeat, marker number); and how many were lost or garbled."""
    per = program.markers_per_repeat
    total = program.repeats * per
    longest = max(s.n * program.info[s.kind.name].model_us for s in program.segments) / 1e6
    wait = 1.0 + SLOW_FACTOR * longest
    times: dict[tuple[int, int], float] = {}
    index = 0  # position in the expected marker sequence
    lost = 0
    ser.timeout = wait
    while index < total:
        data = ser.read(1)
        t = clock()
        if not data:
            hint = NOT_RUNNING_HINT if index == 0 else "check the cable and power, then try again"
            if port.startswith("bstwin://"):
                hint = (
                    "a bstwin:// stamp runs a 50 ms preview: probe a served twin instead "
                    "(python -m hil_mock serve --timing real runs its stamps in real time)"
                )
            raise DeviceError(
                f"the probe program on {port} stopped sending after {index} of {total} markers "
                f"(nothing for {wait:.1f} s)",
                hint=hint,
            )
        value = data[0]
        r, m = divmod(index, per)
        expected = m + 1 if m + 1 < per else END_MARKER
        if value == expected:
            times[(r, m + 1)] = t
            index += 1
        elif 1 <= value < per and value > m + 1:  # markers of this repeat were lost
            lost += value - (m + 1)
            index = r * per + value - 1
            times[(r, value)] = t
            index += 1
        elif value == END_MARKER:  # the rest of this repeat was lost
            lost += per - 1 - m
            times[(r, per)] = t
            index = (r + 1) * per
        elif value == 1 and m > 0:  # the end marker of repeat r - 1... and more were lost
            lost += per - m
            index = (r + 1) * per
            times[(r + 1, 1)] = t
            index += 1
        else:
            lost += 1  # a garbled byte: skipped
            continue
        if on_marker:
            on_marker()
    return times, lost


def probe(
    port: str,
    *,
    quick: bool = False,
    repeats: int | None = None,
    timing: Timing | None = None,
    log: Callable[[str], None] | None = None,
    on_marker: Callable[[int], None] | None = None,
) -> ProbeResult:
    """Measure the stamp on ``port``; ``on_marker(total)`` is called for every marker heard
    (``total`` = how many are expected, for a progress bar)."""
    program = build(quick=quick, repeats=repeats)
    timing = timing or Timing()
    ser = open_port(port, timeout=timing.reply)
    total = program.repeats * program.markers_per_repeat
    try:
        flash_module(ser, plan_for(program), timing=timing, log=log, listen=False)
        start = time.monotonic()
        _wait_header(ser, port)
        times, lost = read_markers(
            ser, program, port=port, on_marker=(lambda: on_marker(total)) if on_marker else None
        )
        seconds = time.monotonic() - start
    except (OSError, serial.SerialException) as exc:
        raise PortError(
            f"the port {port} failed during the probe ({exc})",
            hint="check the USB cable/adapter, then run bstool probe again",
        ) from None
    except KeyboardInterrupt:
        raise FlashInterrupted(
            f"interrupted: the probe on {port} was not finished",
            hint="run bstool probe again (the stamp now holds the probe program: flash the "
            "module's own program afterwards)",
        ) from None
    finally:
        ser.close()
    model = fit.fit(program, fit.intervals(program, times))
    model = stamped(model, f"probe {port}")
    model.measurements.update(
        {"markers": len(times), "lost": lost, "seconds": round(seconds, 3), "quick": quick}
    )
    return ProbeResult(model, program, port, len(times), lost, seconds)
