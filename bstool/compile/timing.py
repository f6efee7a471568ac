"""Timing model of the serve loop on a BS2sx, for the manifest's estimates only: the nominal
period and the longest gap between servo pulses (protocol/link.md §6).

Model (docs/compile.md): every PBASIC statement costs :data:`STMT_MS` (a BS2sx runs about
10,000 instructions/s, bs2sx.md §1) plus its own time: PULSOUT its pulse, PAUSE its argument,
SEROUT 10 bit times per byte and the pace between bytes, SERIN its timeout when nothing comes,
RUN :data:`RUN_MS`. No constant of the programs is sized from these numbers: every wait of the
serve loop is a policy or a bound of the stamp's own behaviour (bstool.wire.link), and
correctness rests on the handshakes.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from bstool.timingfile import DEFAULT as DEFAULT_MODEL
from bstool.timingfile import TimingModel
from bstool.wire.link import ServeConstants, byte_ms

STMT_MS = 0.1
RUN_MS = 0.3
SERIN_UNIT_MS = 0.4  # BS2sx SERIN timeout unit
PULSOUT_UNIT_MS = 0.0008
HOLD_STMT_MS = 0.102
"""Mean time of a short statement (calibrated on the twin's interpreter model, 20 us + 2 us
per token bit; STMT_MS is the general upper estimate); kept for the timing file's ratio."""
PAD_PIN = 13
"""An unconnected pin (the probe program's delay pin)."""

TRY_STATEMENTS = 6
"""The statements of one try besides its PULSOUT, SEROUT and SERIN (frames, RANDOM, hdr = 0,
the IFs on the header, the jump)."""
TURNAROUND_STATEMENTS = 5
"""A slave from the end of a request's payload to its reply's SEROUT: the check, heard, the IFs
on the header, the pulse before the reply."""
END_STATEMENTS = 12
"""The end of a transition: the tick, the hold and got checks, prev, the rule's lookup."""
NN_MEETINGS = 3
"""NN: the meetings on a transition's critical path at one module: the upstream's REQ heard,
the downstream's TOOK and its REP (protocol/link.md §4.6)."""
GAP_STATEMENTS = 20
"""The statements between tries that the try counts above leave out (the tick bookkeeping every
16 rounds, jumps between wires); calibrated on the twin's interpreter (CA: 23-24 ms measured
against 22.7 ms without them)."""
NN_TAKE_STATEMENTS = 25
"""NN: a slave between a REQ's payload and the pulse before its TOOK: the stores, the NnTable
lookup and the relay set-up (GOSUB Take); calibrated on the twin (40 ms measured on the last
module of a leg)."""
NN_CHUNK = 3
"""NN: a REQ is sent in SEROUTs of this many bytes with a servo pulse between them."""


def transition_end_ms() -> float:
    """From the last try of a transition to the first of the next: the rule slot and back."""
    return 2 * RUN_MS + END_STATEMENTS * STMT_MS


def frame_ms(nbytes: int, k: ServeConstants) -> float:
    """One SEROUT of ``nbytes`` at the pace ``k.pace_ms``."""
    return nbytes * byte_ms() + max(0, nbytes - 1) * k.pace_ms


def _wait_ms(units: int, k: ServeConstants, jitter: float) -> float:
    return (units + jitter) * SERIN_UNIT_MS


def master_try_ms(pulse_ms: float, tx: int, rx: int, k: ServeConstants, *, nn: bool) -> float:
    """A master's try that is answered: its pulse, its request, the slave's turnaround (its
    pulse before the reply) and the reply."""
    chunks = -(-(1 + tx) // NN_CHUNK) if nn else 1
    return (
        chunks * pulse_ms
        + frame_ms(1 + tx, k)
        + (chunks - 1) * STMT_MS
        + TURNAROUND_STATEMENTS * STMT_MS
        + pulse_ms
        + frame_ms(1 + rx, k)
        + TRY_STATEMENTS * STMT_MS
    )


def master_miss_ms(
    pulse_ms: float, tx: int, k: ServeConstants, *, nn: bool, jitter: float
) -> float:
    """A master's try that nobody answers: its request and the whole reply wait."""
    chunks = -(-(1 + tx) // NN_CHUNK) if nn else 1
    return (
        chunks * pulse_ms
        + frame_ms(1 + tx, k)
        + _wait_ms(k.reply_wait, k, jitter)
        + TRY_STATEMENTS * STMT_MS
    )


def listen_ms(pulse_ms: float, k: ServeConstants, *, jitter: float) -> float:
    """A slave's try that hears nothing: its pulse and the whole listen."""
    return pulse_ms + _wait_ms(k.listen, k, jitter) + TRY_STATEMENTS * STMT_MS


def slave_receive_gap_ms(rx: int, k: ServeConstants, *, nn: bool) -> float:
    """A slave's longest time between its try's pulse and the pulse before its reply: a request
    starting at the end of the longest listen, received whole (the payload at the pace)."""
    take = NN_TAKE_STATEMENTS if nn else 0
    return (
        _wait_ms(k.listen, k, k.jitter_units)
        + frame_ms(1 + rx, k)
        + (TRY_STATEMENTS + TURNAROUND_STATEMENTS + 2 * rx + take + GAP_STATEMENTS) * STMT_MS
    )


def master_gap_ms(pulse_ms: float, tx: int, rx: int, k: ServeConstants, *, nn: bool) -> float:
    """A master's longest time between two pulses: the longest chunk of its request, then the
    longest reply wait with a reply starting at its end, and the next try's statements."""
    del pulse_ms  # the gap runs from the end of a pulse to the start of the next
    first = min(1 + tx, NN_CHUNK) if nn else 1 + tx
    return (
        frame_ms(first, k)
        + _wait_ms(k.reply_wait, k, k.jitter_units)
        + frame_ms(1 + rx, k)
        + (2 * TRY_STATEMENTS + GAP_STATEMENTS) * STMT_MS
    )


# ---- issue 13 §2: a measured timing file (bstool.timingfile, bstool probe) ------------------
_active = DEFAULT_MODEL
_ESTIMATE = {"STMT_MS": STMT_MS, "HOLD_STMT_MS": HOLD_STMT_MS, "RUN_MS": RUN_MS,
             "PULSOUT_UNIT_MS": PULSOUT_UNIT_MS, "SERIN_UNIT_MS": SERIN_UNIT_MS}  # fmt: skip


def coefficients() -> TimingModel:
    """The timing model the estimates use now: the default, or the one of :func:`measured`."""
    return _active


@contextmanager
def measured(model: TimingModel | None) -> Iterator[None]:
    """Estimate with ``model`` inside the block: statements (STMT_MS, HOLD_STMT_MS) × its
    instruction time ratio, its RUN overhead, PULSOUT and SERIN-timeout units. Not thread-safe
    (compile runs on one thread)."""
    global _active, STMT_MS, HOLD_STMT_MS, RUN_MS, PULSOUT_UNIT_MS, SERIN_UNIT_MS
    if model is None:
        yield
        return
    r = model.instruction_time_ratio.value
    _active = model
    STMT_MS = _ESTIMATE["STMT_MS"] * r
    HOLD_STMT_MS = _ESTIMATE["HOLD_STMT_MS"] * r
    RUN_MS = model.run_us.value / 1000
    PULSOUT_UNIT_MS = model.pulsout_unit_us.value / 1000
    SERIN_UNIT_MS = model.serin_unit_ms.value
    try:
        yield
    finally:
        _active = DEFAULT_MODEL
        STMT_MS, HOLD_STMT_MS, RUN_MS = (
            _ESTIMATE[k] for k in ("STMT_MS", "HOLD_STMT_MS", "RUN_MS")
        )
        PULSOUT_UNIT_MS, SERIN_UNIT_MS = _ESTIMATE["PULSOUT_UNIT_MS"], _ESTIMATE["SERIN_UNIT_MS"]
