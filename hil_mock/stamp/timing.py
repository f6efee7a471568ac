"""The virtual clock's model of BS2sx execution time, in integer nanoseconds.

Sources and reasoning (docs/twin.md, "Timing model"):

* The BS2sx runs about 10,000 instructions/s (bs2sx.md §1, CMP/FAQ), i.e. about 100 us for a
  typical instruction. Its interpreter fetches every token bit from the serial EEPROM, so an
  instruction's time grows with its length in bits. Model: ``BASE + PER_BIT × bits`` with a
  typical 40-bit statement (``x = x + 1`` is 44) at 100 us. An estimate, not a measurement.
* PAUSE, PULSOUT, SERIN timeouts and serial bytes take their real durations on top: PAUSE in
  1 ms units, PULSOUT in 0.8 us units, SERIN timeout in 0.4 ms units (bs2sx.md §2); one serial
  byte is 10 bit times (start, 8 data, stop; 7E1 is also 10) at the baudmode's bit rate
  2.5 MHz / ((mode & $FFF) + 20) (bs2sx.md §2), i.e. exactly 4000 × ((mode & $FFF) + 20) ns.
* RUN costs ~300 us (bs2sx.md §1). WRITE waits for the EEPROM write cycle: 5 ms, the maximum
  of 24LC16-class serial EEPROMs (assumption: the stamp polls until the write completes).
"""

from __future__ import annotations

from dataclasses import dataclass

from bstool.timingfile import TimingModel
from bstool.tokenizer import tokens as T

BASE_NS = 20_000
PER_BIT_NS = 2_000
RUN_NS = 300_000
EEPROM_WRITE_NS = 5_000_000
PAUSE_UNIT_NS = int(T.PAUSE_UNIT_MS * 1_000_000)
PULSOUT_UNIT_NS = round(T.PULSOUT_UNIT_US * 1_000)
SERIN_TIMEOUT_UNIT_NS = round(T.SERIN_TIMEOUT_UNIT_MS * 1_000_000)
BITS_PER_BYTE = 10
_NS_PER_CLOCK = 1_000_000_000 // T.BAUD_CLOCK  # 400 ns per baud-clock tick


def instruction_ns(bits: int) -> int:
    """Execution time of a statement of ``bits`` token bits (waits excluded)."""
    return BASE_NS + PER_BIT_NS * bits


def byte_ns(mode: int) -> int:
    """Time of one serial byte (10 bit times) at a BS2sx baudmode."""
    return BITS_PER_BYTE * _NS_PER_CLOCK * ((mode & 0x0FFF) + T.BAUD_OFFSET)


# ---- issue 13 §2: measured coefficients (a bstool.timing/1 file) replace the estimate ------


@dataclass(frozen=True)
class StampTiming:
    """The nominal coefficients a :class:`~hil_mock.stamp.clock.StampClock` scales, in integer
    ns (defaults: the estimate above); :func:`of` makes them from a measured timing model."""

    base_ns: int = BASE_NS
    per_bit_ns: int = PER_BIT_NS
    run_ns: int = RUN_NS
    pause_ns: int = PAUSE_UNIT_NS
    pulsout_ns: int = PULSOUT_UNIT_NS
    serin_ns: int = SERIN_TIMEOUT_UNIT_NS

    def instruction_ns(self, bits: int) -> int:
        return self.base_ns + self.per_bit_ns * bits


ESTIMATE = StampTiming()


def of(model: TimingModel | None) -> StampTiming:
    """The twin's coefficients of ``model`` (None or the default model: :data:`ESTIMATE`): the
    statement cost ``base + per_bit x token bits``, RUN, and the PAUSE, PULSOUT and SERIN-timeout
    units. Serial bit times stay the baudmode's (the file's SEROUT item time is reported, not
    applied: a stamp's UART follows its resonator, which the units already carry)."""
    if model is None:
        return ESTIMATE
    return StampTiming(
        round(model.base_us.value * 1000),
        round(model.per_bit_us.value * 1000),
        round(model.run_us.value * 1000),
        round(model.pause_unit_ms.value * 1_000_000),
        round(model.pulsout_unit_us.value * 1000),
        round(model.serin_unit_ms.value * 1_000_000),
    )
