"""Module addresses "L.M": leg L (from 0) and module M along the leg (0 = lead, at the disc)."""

from __future__ import annotations

import re
from typing import NamedTuple

from bstool.errors import InputError

_PATTERN = re.compile(r"^\s*L?(\d+)\s*\.\s*M?(\d+)\s*$", re.IGNORECASE)


class ModuleId(NamedTuple):
    leg: int
    module: int

    def __str__(self) -> str:
        return f"{self.leg}.{self.module}"

    @property
    def label(self) -> str:
        """Human label used in messages and announcements, e.g. ``L2.M3``."""
        return f"L{self.leg}.M{self.module}"


def parse_module(text: str, legs: int | None = None, modules: int | None = None) -> ModuleId:
    """Parse ``"2.3"`` (or ``"L2.M3"``); check it against the robot's size when given."""
    match = _PATTERN.match(text)
    if not match:
        raise InputError(
            f"bad module address {text!r}: expected L.M, e.g. 2.3 (leg 2, module 3; 0 = lead)"
        )
    mid = ModuleId(int(match.group(1)), int(match.group(2)))
    if legs is not None and not mid.leg < legs:
        raise InputError(f"unknown module {text}: leg {mid.leg} is not in 0..{legs - 1}")
    if modules is not None and not mid.module < modules:
        raise InputError(f"unknown module {text}: module {mid.module} is not in 0..{modules - 1}")
    return mid


def all_modules(legs: int, modules: int) -> list[ModuleId]:
    """Every module in the canonical order: leg by leg, lead first."""
    return [ModuleId(i, j) for i in range(legs) for j in range(modules)]


def parse_failure_time(
    text: str, legs: int | None = None, modules: int | None = None, option: str = "--die"
) -> tuple[ModuleId, int]:
    """Parse ``"2.3@7"``: module 2.3 fails at transition 7 (it shows S^7, then holds it)."""
    where, sep, when = text.partition("@")
    if not sep or not when.strip().isdigit():
        what = {
            "--rejoin": "comes back at",
            "--held-by": "held at",
            "--rejoin-with": "comes back with its state of",
        }.get(option, "fails after")
        raise InputError(
            f"bad {option} {text!r}: expected L.M@T, e.g. 2.3@7 (module 2.3 {what} "
            "transition 7; T is a whole number >= 0)"
        )
    return parse_module(where, legs, modules), int(when)
