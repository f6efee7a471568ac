"""Opening the port a stamp hangs on: device paths, pyserial URLs and ``auto``.

Every failure to open becomes a :class:`~bstool.flash.errors.PortError` with a hint (which
group grants access, what holds the port). URL schemes are pyserial's plug-ins: the twin's
``bstwin://`` works once hil_mock is imported (it registers its handler package).
"""

from __future__ import annotations

import errno
import grp
import os
from collections.abc import Callable

import serial
from serial.tools import list_ports

from bstool.flash.errors import PortError
from bstool.wire.programming import BAUD

#: URL schemes whose pyserial classes have no modem lines (DTR/BREAK are silently ignored).
NO_MODEM_SCHEMES = ("socket", "loop")


def scheme(port: str) -> str | None:
    """The URL scheme of ``port`` (``"socket"``...), or None for a device path."""
    return port.split("://", 1)[0].lower() if "://" in port else None


def usb_serial_ports() -> list[str]:
    """Device paths of the USB-serial adapters present (the ones with a USB vendor id)."""
    return sorted(p.device for p in list_ports.comports() if p.vid is not None)


def resolve_auto(choose: Callable[[list[str]], str] | None = None) -> str:
    """Pick the one USB-serial port; with several, ask ``choose`` (or fail listing them)."""
    ports = usb_serial_ports()
    if len(ports) == 1:
        return ports[0]
    if not ports:
        raise PortError(
            "--port auto: no USB-serial port found",
            hint="plug in the programming cable, or give the port: --port /dev/ttyUSB0",
        )
    if choose is None:
        raise PortError(
            f"--port auto: {len(ports)} USB-serial ports found ({', '.join(ports)})",
            hint="choose one with --port PATH",
        )
    return choose(ports)


def _group_of(path: str) -> str | None:
    try:
        return grp.getgrgid(os.stat(path).st_gid).gr_name
    except (OSError, KeyError):
        return None


def open_port(port: str, *, baud: int = BAUD, timeout: float = 0.25) -> serial.Serial:
    """Open ``port`` (path or pyserial URL) at 8N1 with exclusive access for device paths."""
    kind = scheme(port)
    try:
        if kind is None:  # a device path: refuse to share it with another program
            return serial.serial_for_url(
                port, baudrate=baud, timeout=timeout, write_timeout=5.0, exclusive=True
            )
        return serial.serial_for_url(port, baudrate=baud, timeout=timeout, write_timeout=5.0)
    except ValueError as exc:  # unknown URL scheme or bad option
        raise PortError(
            f"{port}: not a usable port ({exc})",
            hint="give a device path (/dev/ttyUSB0), a pyserial URL (socket://host:port) or auto",
        ) from None
    except serial.SerialException as exc:
        raise _port_error(port, exc) from None


def _port_error(port: str, exc: serial.SerialException) -> PortError:
    code = exc.errno
    if code == errno.ENOENT or (code is None and not os.path.exists(port) and "://" not in port):
        return PortError(
            f"port {port} does not exist",
            hint="check the cable is plugged in; list ports: python -m serial.tools.list_ports",
        )
    if code == errno.EACCES:
        group = _group_of(port)
        who = f"the '{group}' group" if group else "the group that owns it"
        return PortError(
            f"no permission to open {port}",
            hint=f"add yourself to {who} (sudo usermod -aG {group or 'dialout'} $USER), "
            "then log in again",
        )
    if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "lock" in str(exc).lower():
        return PortError(
            f"port {port} is busy: another program has it open",
            hint="close the other terminal/IDE using it (see: fuser -v " + port + ")",
        )
    return PortError(f"cannot open {port}: {exc}", hint="check the port name and the cable")
