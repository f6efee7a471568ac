"""Host side of the BS2sx programming protocol (protocol/programming.md) and ``bstool flash``.

Library use::

    from bstool.flash import load_target, flash_module
    target = load_target("build/", module="2.3")
    report = flash_module("/dev/ttyUSB0", target.modules[0], progress=print)
    print(report.summary())

Everything raises :class:`bstool.errors.DeviceError` subclasses (``bstool.flash.errors``).
"""

from __future__ import annotations

from bstool.flash.errors import (
    AnnouncementError,
    EchoMismatchError,
    FlashInterrupted,
    FlashTimeoutError,
    NoEchoError,
    NoReplyError,
    PortError,
    RecordRefusedError,
    WrongStampError,
)
from bstool.flash.flasher import ModuleReport, WalkResult, flash_all, flash_module, read_ports_file
from bstool.flash.port import open_port, resolve_auto
from bstool.flash.session import FAST, Programmer, Progress, SlotResult, Timing
from bstool.flash.target import ModulePlan, SlotPlan, Target, load_target

__all__ = [
    "FAST",
    "AnnouncementError",
    "EchoMismatchError",
    "FlashInterrupted",
    "FlashTimeoutError",
    "ModulePlan",
    "ModuleReport",
    "NoEchoError",
    "NoReplyError",
    "PortError",
    "Programmer",
    "Progress",
    "RecordRefusedError",
    "SlotPlan",
    "SlotResult",
    "Target",
    "Timing",
    "WalkResult",
    "WrongStampError",
    "flash_all",
    "flash_module",
    "load_target",
    "open_port",
    "read_ports_file",
    "resolve_auto",
]
