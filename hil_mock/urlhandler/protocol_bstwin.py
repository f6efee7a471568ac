"""``bstwin://NAME?...``: a pyserial port wired to an in-process virtual BS2sx."""

from __future__ import annotations

import errno
import urllib.parse
from typing import Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from hil_mock.line import TIMINGS, Line
from hil_mock.urlhandler import get_twin


class Serial(SerialBase):
    """A pyserial port whose other end is a :class:`hil_mock.progdevice.ProgrammingDevice`."""

    BAUDRATES = (300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._line: Line | None = None
        self._modem = True
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        name, timing, modem, create = _parse(str(self.port))
        device = get_twin(name, **create)
        self._modem = modem
        if not modem:  # the host cannot reset it: let an identification byte do it
            device.reset_on_id = True
        self._line = Line(device, timing=timing, baud=int(self.baudrate or 9600))
        self.is_open = True
        if self._modem:  # like a real port: opening asserts DTR (holds the stamp in reset)
            self._line.set_dtr(self.dtr)
            self._line.set_break(self.break_condition)

    def close(self) -> None:
        if self.is_open and self._line is not None:
            if self._modem:
                self._line.set_break(False)
                self._line.set_dtr(False)  # HUPCL: closing releases the reset
            self._line.close()
        self.is_open = False
        super().close()

    def _reconfigure_port(self) -> None:
        pass

    def _need(self) -> Line:
        if not self.is_open or self._line is None:
            raise PortNotOpenError()
        return self._line

    @property
    def in_waiting(self) -> int:
        return self._need().in_waiting()

    def read(self, size: int = 1) -> bytes:
        return self._need().read(size, self.timeout)

    def write(self, data: Any) -> int:
        return self._need().write(bytes(data))

    def reset_input_buffer(self) -> None:
        self._need().reset_input_buffer()

    def reset_output_buffer(self) -> None:
        self._need()

    @property
    def out_waiting(self) -> int:
        return 0

    def _no_modem(self) -> None:
        raise SerialException(errno.ENOTTY, "bstwin port opened with modem=0 has no modem lines")

    def _update_dtr_state(self) -> None:
        if self.is_open:
            if not self._modem:
                self._no_modem()
            self._need().set_dtr(self.dtr)

    def _update_break_state(self) -> None:
        if self.is_open:
            if not self._modem:
                self._no_modem()
            self._need().set_break(self.break_condition)

    def _update_rts_state(self) -> None:
        if self.is_open and not self._modem:
            self._no_modem()

    @property
    def cts(self) -> bool:
        return False

    @property
    def dsr(self) -> bool:
        return False

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return False


def _parse(url: str) -> tuple[str, str, bool, dict[str, object]]:
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "bstwin":
        raise SerialException(f"expected bstwin://NAME[?options], got {url!r}")
    name = (parts.netloc + parts.path).strip("/")
    if not name:
        raise SerialException(f"{url}: the twin needs a name, e.g. bstwin://L0.M0")
    timing, modem = "none", True
    create: dict[str, object] = {}
    for key, values in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items():
        value = values[-1]
        if key == "timing":
            if value not in TIMINGS:
                raise SerialException(f"{url}: timing must be one of {', '.join(TIMINGS)}")
            timing = value
        elif key == "modem":
            modem = value not in ("0", "no", "false")
        elif key == "model":
            create["model"] = value
        elif key == "eeprom":
            create["eeprom"] = value
        else:
            raise SerialException(f"{url}: unknown option {key!r}")
    return name, timing, modem, create
