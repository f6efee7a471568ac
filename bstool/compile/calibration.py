"""Servo calibration: state → pulse width (PULSOUT units of 0.8 µs) per module.

pulse_us(s) = centre_us + direction · us_per_rad · θ(s), clamped to [min_us, max_us], where
θ(s) is the robot's state angle. Defaults (docs/compile.md): a standard analog servo, 1.5 ms
centre, 90° per 1000 µs (= 636.6 µs/rad), so the paper's ±60° is 833–2167 µs; limits 800 and
2200 µs. A file (``--calibration servos.json``, format ``bstool.servos/1``) overrides any field
for all modules (``"default"``) or one module (``"modules": {"2.3": {...}}``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields, replace
from typing import Any

from bstool import fileio
from bstool.controllers.angles import state_to_angle
from bstool.errors import BuildError, InputError
from bstool.moduleid import ModuleId, parse_module

FORMAT = "bstool.servos/1"
PULSOUT_UNIT_US = 0.8  # BS2sx PULSOUT unit (bs2sx.md §2)
HARD_MIN_US = 500.0
HARD_MAX_US = 2500.0
_HINT = (
    'expected {"format": "bstool.servos/1", "default": {...}, "modules": {"L.M": {...}}} with '
    "fields centre_us, us_per_rad, direction (1 or -1), min_us, max_us; see docs/compile.md"
)


@dataclass(frozen=True)
class Servo:
    centre_us: float = 1500.0
    us_per_rad: float = 1000.0 / (math.pi / 2)
    direction: int = 1
    min_us: float = 800.0
    max_us: float = 2200.0

    def pulse_us(self, state: int, k: int = 16) -> float:
        us = self.centre_us + self.direction * self.us_per_rad * state_to_angle(state, k)
        return min(max(us, self.min_us), self.max_us)

    def pulses(self, k: int = 16) -> list[int]:
        """PULSOUT argument for each state (0.8 µs units, rounded to nearest)."""
        return [round(self.pulse_us(s, k) / PULSOUT_UNIT_US) for s in range(k)]

    def clipped(self, k: int = 16) -> list[int]:
        """States whose angle the limits cut off."""
        out = []
        for s in range(k):
            us = self.centre_us + self.direction * self.us_per_rad * state_to_angle(s, k)
            if not self.min_us <= us <= self.max_us:
                out.append(s)
        return out


@dataclass(frozen=True)
class Calibration:
    default: Servo
    modules: dict[ModuleId, Servo]

    def servo(self, mid: ModuleId) -> Servo:
        return self.modules.get(mid, self.default)


DEFAULT = Calibration(Servo(), {})


def _bad(source: str, where: str, what: str) -> BuildError:
    return BuildError(f"invalid calibration {source}: {where}: {what}", hint=_HINT)


def _servo(base: Servo, obj: Any, source: str, where: str) -> Servo:
    if not isinstance(obj, dict):
        raise _bad(source, where, "expected an object of servo fields")
    names = {f.name for f in fields(Servo)}
    changes: dict[str, Any] = {}
    for key, value in obj.items():
        if key not in names:
            raise _bad(
                source, f"{where}.{key}", f"unknown field (known: {', '.join(sorted(names))})"
            )
        if key == "direction":
            if value not in (1, -1) or isinstance(value, bool):
                raise _bad(source, f"{where}.direction", f"expected 1 or -1, got {value!r}")
            changes[key] = int(value)
            continue
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise _bad(source, f"{where}.{key}", f"expected a number, got {value!r}")
        changes[key] = float(value)
    servo = replace(base, **changes)
    if servo.us_per_rad <= 0:
        raise _bad(source, f"{where}.us_per_rad", f"must be > 0, got {servo.us_per_rad}")
    if not HARD_MIN_US <= servo.min_us < servo.max_us <= HARD_MAX_US:
        raise _bad(
            source,
            where,
            f"need {HARD_MIN_US:g} <= min_us < max_us <= {HARD_MAX_US:g} µs, "
            f"got {servo.min_us:g}..{servo.max_us:g}",
        )
    if not servo.min_us <= servo.centre_us <= servo.max_us:
        raise _bad(source, f"{where}.centre_us", f"{servo.centre_us:g} µs is outside the limits")
    return servo


def parse_calibration(obj: Any, source: str, legs: int, modules: int) -> Calibration:
    """Validate a decoded calibration object against a robot of ``legs`` × ``modules``."""
    if not isinstance(obj, dict):
        raise _bad(source, "top level", "expected a JSON object")
    if obj.get("format") != FORMAT:
        raise _bad(source, "format", f"expected {FORMAT!r}, got {obj.get('format')!r}")
    for key in obj:
        if key not in ("format", "default", "modules", "legs", "modules_per_leg"):
            raise _bad(source, key, "unknown field")
    for key, size in (("legs", legs), ("modules_per_leg", modules)):
        if key in obj and obj[key] != size:
            raise BuildError(
                f"calibration {source} is for a robot with {key} = {obj[key]}, but the "
                f"controller has {size}",
                hint="use the calibration file of this robot, or a controller evolved for it",
            )
    default = _servo(Servo(), obj.get("default", {}), source, "default")
    per_module: dict[ModuleId, Servo] = {}
    entries = obj.get("modules", {})
    if not isinstance(entries, dict):
        raise _bad(source, "modules", 'expected an object keyed by module, e.g. "2.3"')
    for key, value in entries.items():
        try:
            mid = parse_module(str(key), legs, modules)
        except InputError as exc:
            raise InputError(
                f"calibration {source}: {exc.message}",
                hint=f"this robot has legs 0..{legs - 1} and modules 0..{modules - 1}",
            ) from None
        per_module[mid] = _servo(default, value, source, f"modules.{key}")
    return Calibration(default, per_module)


def load_calibration(path: str | os.PathLike[str], legs: int, modules: int) -> Calibration:
    return parse_calibration(fileio.read_json(path, "calibration file"), str(path), legs, modules)
