"""Runners for slot 0: the token interpreter, and stand-ins for tests.

:class:`AnnounceRunner` prints a fixed start-up line; :class:`ScanRunner` prints the
announcement found as plain ASCII inside slot 0 (test images carry it in their DATA), so what
is heard depends on what was really flashed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from bstool.wire import announce
from hil_mock.eeprom import Eeprom

if TYPE_CHECKING:
    from hil_mock.stamp.clock import StampClock


class AnnounceRunner:
    """Emits ``line`` each time slot 0 starts."""

    def __init__(self, line: bytes) -> None:
        self.line = line
        self.starts = 0

    def start(self, eeprom: Eeprom, emit: Callable[[bytes], None]) -> None:
        self.starts += 1
        emit(self.line)

    def stop(self) -> None:
        pass


class ScanRunner:
    """Emits the first ``bstool L<i>.M<j> <hash8>\\r`` found in slot 0, if any."""

    def __init__(self) -> None:
        self.starts = 0

    def start(self, eeprom: Eeprom, emit: Callable[[bytes], None]) -> None:
        self.starts += 1
        found = announce.find_raw(eeprom.slot(0))
        if found:
            emit(found)

    def stop(self) -> None:
        pass


class InterpreterRunner:
    """Runs slot 0 on the token interpreter (hil_mock.stamp) for ``seconds`` of virtual time
    and emits what the program sent on pin 16 (DEBUG): a bounded preview, enough for the
    start-up announcement. A program the interpreter cannot run emits nothing (see ``error``).
    ``clock`` and ``start_s`` are the module's perturbations (hil_mock/perturb.py): its timing
    factors, and when it starts after a reset (virtual time; the preview still covers
    ``seconds`` of running).
    """

    def __init__(
        self, seconds: float = 0.05, clock: StampClock | None = None, start_s: float = 0.0
    ) -> None:
        self.seconds = seconds
        self.starts = 0
        self.error: str | None = None
        self.clock = clock
        self.start_s = start_s

    def start(self, eeprom: Eeprom, emit: Callable[[bytes], None]) -> None:
        self.starts += 1
        self.error = None
        try:
            from hil_mock.stamp.interpreter import Stamp

            stamp = Stamp(eeprom, clock=self.clock)
            stamp.t = round(self.start_s * 1e9)
            stamp.run(self.seconds)
        except Exception as exc:  # a half-written or foreign image: the stamp just sits there
            self.error = f"{type(exc).__name__}: {exc}"
            return
        if stamp.debug:
            emit(bytes(stamp.debug))

    def stop(self) -> None:
        pass


def preview_runner() -> InterpreterRunner:
    """The runner for twins people flash by hand: slot 0 on the token interpreter."""
    return InterpreterRunner()
