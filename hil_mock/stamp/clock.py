"""One stamp's own time keeping: how fast it executes and how far its resonator is off.

A :class:`StampClock` turns the nominal durations of the timing model (:mod:`.timing`) into
this stamp's durations on the shared virtual time line (integer ns):

* ``speed`` multiplies every instruction and fixed overhead of the timing model (the statement
  cost, RUN, the time between serial items): ``--timing-scale`` × ``--timing-spread`` × the
  resonator factor;
* ``resonator`` multiplies everything the stamp times by counting its clock: PAUSE, PULSOUT
  widths, SERIN timeouts, SEROUT pacing and the serial bit time (``--clock-spread``).

A factor > 1 is a slow stamp (every duration longer). With both factors 1 and no item time
every duration is exactly the timing model's, to the nanosecond.

The receive model (docs/twin.md, "Perturbations"): a UART samples each bit of an 8N1 frame in
the middle of its own bit time after the start edge, so bit k (0 = start, 9 = stop) is sampled
at (k + ½)·rx; the frame is read correctly while every sample stays inside the sender's bit k,
worst at the stop bit: 9·tx ≤ 9.5·rx < 10·tx, i.e. a total bit-time mismatch of ±5.3 %. The
stamp polls for the start edge in firmware and a real edge is not sharp, which eats into that
budget: :data:`UART_TOLERANCE` (an estimate) is the mismatch it accepts.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache

from bstool.timingfile import DEFAULT, TimingModel
from bstool.tokenizer import tokens as T

from . import timing

UART_TOLERANCE = 0.04
"""Largest |rx/tx − 1| at which a frame is still read: 4 %, an estimate between the 8N1
mid-bit limit (5.3 %) and the ±2 % per side that UART makers recommend; no BS2sx figure is
published (docs/twin.md)."""
STOP_SAMPLE_BITS = 9.5
"""Where the receiver samples the stop bit, in its own bit times after the start edge."""
CODE_BITS = T.SLOT_BYTES * 8


def frame_received(tx_bit_ns: float, rx_bit_ns: float, tolerance: float = UART_TOLERANCE) -> bool:
    """Whether a receiver with bit time ``rx_bit_ns`` reads a frame sent at ``tx_bit_ns``."""
    return abs(rx_bit_ns / tx_bit_ns - 1.0) <= tolerance


@lru_cache(maxsize=256)
def _table(speed: float, base_ns: int, per_bit_ns: int) -> tuple[int, ...]:
    """Statement cost by token bits (0..16384) at ``speed`` (shared by stamps of one speed)."""
    if speed == 1.0:
        return tuple(base_ns + per_bit_ns * b for b in range(CODE_BITS + 1))
    return tuple(round((base_ns + per_bit_ns * b) * speed) for b in range(CODE_BITS + 1))


@dataclass(frozen=True)
class StampClock:
    """Per-stamp timing factors (1.0 = the nominal timing model), the serial item time and the
    nominal timing model itself (issue 13 §2: a measured ``bstool.timing/1`` file's, passed in;
    default: the estimate of :mod:`.timing`)."""

    speed: float = 1.0
    resonator: float = 1.0
    item_ns: int | None = None
    """Nominal time between two SERIN/SEROUT items (× ``speed``); None: today's ideal serial
    timing (bytes back to back, the receiver listens again at the end of the stop bit)."""
    model: TimingModel = DEFAULT
    """The nominal coefficients (:func:`.timing.of`): statement cost, RUN, PAUSE, PULSOUT and
    SERIN-timeout units."""
    coefficients: timing.StampTiming = field(init=False, repr=False, compare=False)
    instruction: tuple[int, ...] = field(init=False, repr=False, compare=False)
    pause_ns: int = field(init=False, repr=False, compare=False)
    pulsout_ns: float = field(init=False, repr=False, compare=False)
    serin_unit_ns: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (self.speed > 0 and self.resonator > 0):
            raise ValueError("clock factors must be positive")
        r = self.resonator
        c = timing.of(self.model)
        object.__setattr__(self, "coefficients", c)
        object.__setattr__(self, "instruction", _table(float(self.speed), c.base_ns, c.per_bit_ns))
        object.__setattr__(self, "pause_ns", round(c.pause_ns * r))
        object.__setattr__(self, "pulsout_ns", c.pulsout_ns * r)
        object.__setattr__(self, "serin_unit_ns", c.serin_ns * r)

    @property
    def nominal(self) -> bool:
        """Factors 1 and ideal serial timing (the timing model may still be a measured one)."""
        return self.speed == 1.0 and self.resonator == 1.0 and self.item_ns is None

    def overhead_ns(self, nominal_ns: int) -> int:
        """A fixed overhead of the timing model on this stamp."""
        return nominal_ns if self.speed == 1.0 else round(nominal_ns * self.speed)

    @property
    def run_ns(self) -> int:
        """RUN into another slot, on top of its statement."""
        return self.overhead_ns(self.coefficients.run_ns)

    def with_model(self, model: TimingModel | None) -> StampClock:
        """This clock with another nominal timing model (None: the estimate)."""
        return replace(self, model=DEFAULT if model is None else model)

    def pulse_ns(self, units: int) -> int:
        return round(units * self.pulsout_ns)

    def timeout_ns(self, units: int) -> int:
        return round(units * self.serin_unit_ns)

    def bit_ns(self, mode: int) -> float:
        """One bit time at baudmode ``mode`` on this stamp's resonator."""
        return timing.byte_ns(mode) / timing.BITS_PER_BYTE * self.resonator

    def byte_ns(self, mode: int) -> int:
        """One 10-bit frame at ``mode`` on this stamp's resonator."""
        nominal = timing.byte_ns(mode)
        return nominal if self.resonator == 1.0 else round(nominal * self.resonator)

    def rx_done_ns(self, mode: int, tx_bit_ns: float | None = None) -> int:
        """From a received frame's start edge (sent at ``tx_bit_ns``, default this stamp's own
        bit time) until the stamp listens again or goes on. Ideal serial timing (no item
        time): at the end of the frame as sent. Stamp serial timing: the item time after the
        stop bit's mid-bit sample on the receiver's own clock."""
        if self.item_ns is None:
            own = self.byte_ns(mode)
            if tx_bit_ns is None or tx_bit_ns == self.bit_ns(mode):
                return own
            return round(timing.BITS_PER_BYTE * tx_bit_ns)
        return round(STOP_SAMPLE_BITS * self.bit_ns(mode)) + self.item_gap_ns

    @property
    def item_gap_ns(self) -> int:
        """SERIN: from the stop bit's sample to listening for the next item; SEROUT: from a
        stop bit's end to the next start bit (the stamp evaluates the next item)."""
        return 0 if self.item_ns is None else round(self.item_ns * self.speed)


NOMINAL = StampClock()
