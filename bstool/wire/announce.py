"""The start-up announcement: ``bstool L<leg>.M<module> <hash8>`` and CR, sent with DEBUG.

Every compiled module program sends it first (templates/pbasic/_start.j2 gets the text from
:func:`line`); ``bstool flash`` and the twin parse it with :func:`find` to check which program
runs where. This module is the one place its format is written.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from bstool.moduleid import ModuleId

PIN = 16
"""DEBUG's pin: the programming port's SOUT."""
BAUD = 9600
BAUDMODE = 240
"""SERIN/SEROUT's baudmode for the programming port at 9600 baud, true polarity (bs2sx.md)."""
END = "\r"
PREFIX = "bstool"


def generic(hash8: str = "<hash8>") -> str:
    """The announcement with the module left open, for people (WIRING.md, the manifest)."""
    return f"{PREFIX} L<leg>.M<module> {hash8}"


DESCRIPTION = generic() + f"\\r on DEBUG (pin {PIN}, {BAUD} baud)"
"""How the build manifest describes the announcement (its ``announcement`` field)."""

_PATTERN = re.compile(rb"bstool L(\d+)\.M(\d+) ([0-9a-fA-F]{8})\r")


@dataclass(frozen=True)
class Announcement:
    """One heard announcement: which module the program says it is, and its controller."""

    module: ModuleId
    hash8: str  # lower-case hex

    @property
    def text(self) -> str:
        return line(self.module, self.hash8)


def line(module: ModuleId, hash8: str) -> str:
    """The announcement's text without the final CR, e.g. ``bstool L2.M3 3fa9c0d1``."""
    return f"{PREFIX} {module.label} {hash8}"


def encode(module: ModuleId, hash8: str) -> bytes:
    """The bytes on the wire, CR included."""
    return (line(module, hash8) + END).encode("ascii")


def find(data: bytes) -> Announcement | None:
    """The first complete announcement in ``data`` (bytes heard on DEBUG), or None."""
    found = _PATTERN.search(data)
    if found is None:
        return None
    mid = ModuleId(int(found.group(1)), int(found.group(2)))
    return Announcement(mid, found.group(3).decode("ascii").lower())


def find_raw(data: bytes) -> bytes | None:
    """The first complete announcement in ``data`` as the bytes sent (CR included), or None."""
    found = _PATTERN.search(data)
    return found.group(0) if found else None


def first_line(debug: bytes) -> str:
    """What a program printed on DEBUG up to its first CR (the twin's announcement check)."""
    return debug.decode("ascii", "replace").split(END)[0]
