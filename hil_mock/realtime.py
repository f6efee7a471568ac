"""Slot 0 on the token interpreter, paced to the wall clock (``serve --timing real``).

The preview runner (:class:`hil_mock.runners.InterpreterRunner`) runs 50 ms of virtual time and
emits what DEBUG printed at once: enough for a start-up announcement, but every byte then
arrives at the same moment. A real stamp keeps running and each DEBUG byte leaves when its
program gets there; :class:`RealtimeRunner` does that, so a host can time a program over the pty
(``bstool probe``, issue 13 §2): a thread runs the stamp ahead of the wall clock and emits every
DEBUG byte when its start bit is due (virtual time 0 = when slot 0 started), its clock (timing
scale, resonator) as the module's perturbations say. A SERIN with a timeout times out (nothing
is connected); the thread stops at END/STOP, a SERIN without timeout, a reset, or after
``seconds`` of running (a served stamp is not a robot: nothing needs it to run for ever).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from bstool.tokenizer import tokens as T
from hil_mock.eeprom import Eeprom

if TYPE_CHECKING:
    from hil_mock.stamp import Stamp
    from hil_mock.stamp.clock import StampClock

AHEAD_S = 0.05  # how far the interpreter may run ahead of the wall clock
CHUNK_NS = 20_000_000


def debug_chunks(stamp: Stamp, until_ns: int) -> Iterator[list[tuple[int, int, int]]]:
    """Run ``stamp`` alone (SERIN timeouts expire) until ``until_ns`` of virtual time or it
    stops, :data:`CHUNK_NS` at a time; yield after each chunk the (byte, start_ns, end_ns) of
    every byte it sent on DEBUG (pin 16) in it (often none)."""
    from hil_mock.stamp import Status
    from hil_mock.stamp.interpreter import StampIO

    sent: list[tuple[int, int, int]] = []

    class _DebugIO(StampIO):
        def serial_out(self, s: Stamp, pin: int, value: int, start_ns: int, mode: int) -> None:
            if pin == T.SERIAL_PIN:
                sent.append((value, start_ns, start_ns + s.clock.byte_ns(mode)))

    stamp.io = _DebugIO()
    while stamp.t < until_ns:
        if stamp.status is Status.RUNNING:
            stamp.run_until(min(stamp.t + CHUNK_NS, until_ns))
        elif stamp.status is Status.WAITING and stamp.wait and stamp.wait.deadline is not None:
            stamp.expire_wait()
            continue
        else:
            break
        yield list(sent)
        sent.clear()
    yield list(sent)


def debug_bytes(stamp: Stamp, until_ns: int) -> list[tuple[int, int, int]]:
    """Every DEBUG byte of ``stamp`` run alone up to ``until_ns`` (see :func:`debug_chunks`)."""
    return [b for chunk in debug_chunks(stamp, until_ns) for b in chunk]


class RealtimeRunner:
    """Runs slot 0 in real time in a thread; ``clock``/``start_s`` as InterpreterRunner's."""

    def __init__(
        self, seconds: float = 600.0, clock: StampClock | None = None, start_s: float = 0.0
    ) -> None:
        self.seconds = seconds
        self.clock = clock
        self.start_s = start_s
        self.starts = 0
        self.error: str | None = None
        self._stop = threading.Event()

    def start(self, eeprom: Eeprom, emit: Callable[[bytes], None]) -> None:
        self.stop()
        self.starts += 1
        self.error = None
        stop = self._stop = threading.Event()
        # a copy of the EEPROM as it is now: the next session may write it while this runs
        # (a WRITE of the program is not kept, unlike the preview's)
        image = [bytes(eeprom.slot(n)) for n in range(T.SLOTS)]
        thread = threading.Thread(
            target=self._run, args=(image, emit, stop), name="stamp realtime", daemon=True
        )
        thread.start()

    def stop(self) -> None:
        self._stop.set()  # never joined: stop() runs under the device's lock, emit takes it

    def _run(
        self, image: list[bytes], emit: Callable[[bytes], None], stop: threading.Event
    ) -> None:
        t0 = time.monotonic()
        try:
            from hil_mock.stamp.interpreter import Stamp

            stamp = Stamp(image, clock=self.clock)
            stamp.t = round(self.start_s * 1e9)
            until = stamp.t + round(self.seconds * 1e9)
            for chunk in debug_chunks(stamp, until):
                for value, start_ns, _end in chunk:
                    delay = t0 + start_ns / 1e9 - time.monotonic()
                    if (delay > 0 and stop.wait(delay)) or stop.is_set():
                        return
                    emit(bytes([value]))
                ahead = t0 + stamp.t / 1e9 - time.monotonic() - AHEAD_S
                if (ahead > 0 and stop.wait(ahead)) or stop.is_set():
                    return
        except Exception as exc:  # a foreign image: the stamp just sits there
            self.error = f"{type(exc).__name__}: {exc}"
