"""A virtual stamp behind a pseudo-terminal: ``/dev/pts/N`` used like a USB-serial cable.

A pty has no modem lines, so the host cannot reset the stamp; the device is therefore put in
``reset_on_id`` mode (an identification byte starts a session, as if reset with a break).
Two threads pump bytes between the pty master and a :class:`~hil_mock.line.Line`, which
keeps the wire timing (``timing="real"`` paces the answers at the baud rate).
"""

from __future__ import annotations

import contextlib
import os
import pty
import select
import threading
import tty

from hil_mock.line import Line
from hil_mock.progdevice import ProgrammingDevice


class PtyEndpoint:
    """Serve ``device`` on a new pty; ``path`` is what the host opens."""

    def __init__(
        self, device: ProgrammingDevice, *, timing: str = "none", baud: int = 9600
    ) -> None:
        device.reset_on_id = True
        self.device = device
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)  # no echo or line editing by the tty layer itself
        self.path = os.ttyname(self._slave)
        self.line = Line(device, timing=timing, baud=baud)
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._pump_in, name=f"pty-in {self.path}", daemon=True),
            threading.Thread(target=self._pump_out, name=f"pty-out {self.path}", daemon=True),
        ]
        for t in self._threads:
            t.start()

    def _pump_in(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:
                continue  # no host has the slave open right now
            if data:
                self.line.write(data)

    def _pump_out(self) -> None:
        while not self._stop.is_set():
            data = self.line.read(1, 0.05)
            if not data:
                continue
            waiting = self.line.in_waiting()
            if waiting:
                data += self.line.read(waiting, 0)
            with contextlib.suppress(OSError):
                os.write(self._master, data)

    def close(self) -> None:
        self._stop.set()
        self.line.close()
        for t in self._threads:
            t.join(timeout=1)
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def __enter__(self) -> PtyEndpoint:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
