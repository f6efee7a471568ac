"""pyserial URL handlers of hil_mock: ``bstwin://NAME[?option=value&...]``.

``register()`` adds this package to ``serial.protocol_handler_packages`` (importing hil_mock
does it), after which ``serial.serial_for_url("bstwin://L2.M3")`` connects to the twin named
``L2.M3`` in this process, creating it on first use. Tests create twins with faults first:
``add_twin("m", ProgrammingDevice(faults=...))``. Options (docs/flash.md):

- ``timing=none|real|virtual`` line timing at the port's baud rate (default none);
- ``modem=0`` the port has no modem lines (DTR/BREAK raise, like a pty);
- ``model=BS2p40``, ``eeprom=PATH`` (persisted EEPROM) apply when the twin is created;
  slot 0 then runs on the token interpreter (a short preview: the start-up line).
"""

from __future__ import annotations

import threading

import serial

from hil_mock.progdevice import ProgrammingDevice

PACKAGE = "hil_mock.urlhandler"
_twins: dict[str, ProgrammingDevice] = {}
_lock = threading.Lock()


def register() -> None:
    """Make ``bstwin://`` known to ``serial.serial_for_url`` (idempotent)."""
    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)


def add_twin(name: str, device: ProgrammingDevice) -> ProgrammingDevice:
    """Put ``device`` at ``bstwin://name`` (replacing any twin of that name)."""
    with _lock:
        _twins[name] = device
    return device


def get_twin(name: str, **create: object) -> ProgrammingDevice:
    """The twin called ``name``; created with ``create`` options when new."""
    from hil_mock.eeprom import Eeprom
    from hil_mock.progdevice import default_runner
    from hil_mock.runners import preview_runner

    with _lock:
        if name not in _twins:
            path = create.pop("eeprom", None)
            eeprom = Eeprom(str(path)) if path else None
            if "runner" not in create:
                create["runner"] = default_runner() or preview_runner()
            _twins[name] = ProgrammingDevice(eeprom, **create)  # type: ignore[arg-type]
        return _twins[name]


def remove_twin(name: str) -> None:
    with _lock:
        _twins.pop(name, None)


def clear_twins() -> None:
    with _lock:
        _twins.clear()


register()
