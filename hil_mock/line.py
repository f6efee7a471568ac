"""A full-duplex 8N1 line between a host and a :class:`ProgrammingDevice`, with a clock.

Each byte occupies its direction of the wire for 10/baud seconds. ``timing``:

- ``"none"``: no wire time, everything arrives at once (fast tests);
- ``"real"``: wall-clock time; ``read`` sleeps until bytes have really "arrived";
- ``"virtual"``: a counter that only moves when the host waits for bytes or times out,
  so the line time of a session is exact and costs no sleeping (``now()`` reads it).

The device is driven at write time with the arrival timestamps, and its answers are queued
with theirs; the host sees them when its clock passes those times.
"""

from __future__ import annotations

import threading
import time
from collections import deque

from bstool.wire.programming import BITS_PER_BYTE
from hil_mock.progdevice import ProgrammingDevice

TIMINGS = ("none", "real", "virtual")


class Line:
    """The host end of a wire to one device. Thread-safe (runners may emit from threads)."""

    def __init__(self, device: ProgrammingDevice, *, timing: str = "none", baud: int = 9600):
        if timing not in TIMINGS:
            raise ValueError(f"timing must be one of {', '.join(TIMINGS)}, not {timing!r}")
        self.device = device
        self.timing = timing
        self.tau = BITS_PER_BYTE / baud if timing != "none" else 0.0
        self._cond = threading.Condition(threading.RLock())
        self._inbox: deque[tuple[float, int]] = deque()
        self._to_device_free = 0.0
        self._to_host_free = 0.0
        self._t0 = time.monotonic()
        self._vnow = 0.0
        self.closed = False
        device.attach(self._device_send, self.now)

    def now(self) -> float:
        if self.timing == "virtual":
            return self._vnow
        return time.monotonic() - self._t0

    # -- device -> host -------------------------------------------------------------------
    def _device_send(self, data: bytes, t: float, echo: bool) -> None:
        with self._cond:
            for b in data:
                # a hardware echo starts as the incoming byte starts: it lands with it
                start = max(t - self.tau if echo else t, self._to_host_free)
                self._to_host_free = start + self.tau
                self._inbox.append((self._to_host_free, b))
            self._cond.notify_all()

    # -- host side ------------------------------------------------------------------------
    def write(self, data: bytes) -> int:
        arrivals = []
        with self._cond:
            t = self.now()
            for b in data:
                start = max(t, self._to_device_free)
                self._to_device_free = start + self.tau
                arrivals.append((b, self._to_device_free))
        # outside our lock: the device calls back into _device_send under its own lock, and
        # a runner thread may do the same, so the lock order is always device -> line
        for b, at in arrivals:
            self.device.receive(b, at)
        return len(data)

    def read(self, size: int, timeout: float | None) -> bytes:
        """Up to ``size`` bytes that have arrived within ``timeout`` seconds (None = forever)."""
        out = bytearray()
        with self._cond:
            deadline = None if timeout is None else self.now() + timeout
            while len(out) < size and not self.closed:
                now = self.now()
                while self._inbox and self._inbox[0][0] <= now + 1e-9 and len(out) < size:
                    out.append(self._inbox.popleft()[1])
                if len(out) >= size or (deadline is not None and now >= deadline):
                    break
                due = self._inbox[0][0] if self._inbox else None
                if self.timing == "virtual":
                    if due is not None and (deadline is None or due <= deadline):
                        self._vnow = max(self._vnow, due)
                        continue
                    if deadline is not None:
                        self._vnow = max(self._vnow, deadline)
                        continue
                times = [x for x in (due, deadline) if x is not None]
                wake = min(times) if times else None
                self._cond.wait(None if wake is None else max(wake - now, 0.0))
        return bytes(out)

    def in_waiting(self) -> int:
        with self._cond:
            now = self.now()
            return sum(1 for t, _ in self._inbox if t <= now + 1e-9)

    def reset_input_buffer(self) -> None:
        """Drop what has arrived (virtual time: all queued, as the host waited to settle)."""
        with self._cond:
            if self.timing == "virtual":
                self._inbox.clear()
                return
            now = self.now()
            while self._inbox and self._inbox[0][0] <= now + 1e-9:
                self._inbox.popleft()

    def set_dtr(self, on: bool) -> None:
        self.device.set_dtr(on, self.now())

    def set_break(self, on: bool) -> None:
        self.device.set_break(on, self.now())

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()
