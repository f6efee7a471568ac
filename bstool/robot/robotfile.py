"""The robot file (format ``bstool.robot/1``, TOML): a user's robot, for every command that
simulates, evolves or compiles.

Its keys are :class:`RobotSpec`'s fields in SI units (a missing key keeps its default); an
optional ``[uncertain]`` table gives the ranges evolution randomizes over and ``bstool
sensitivity`` sweeps (:mod:`bstool.robot.uncertain`). ``bstool robot`` prints the default file
with every key's unit and source. A run records its robot as values (:meth:`Robot.to_json`, in
best.json and in a build), and later commands use the recorded robot unless ``--robot`` is
given (:func:`resolve`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bstool.errors import InputError
from bstool.robot.spec import RobotSpec
from bstool.robot.uncertain import DEFAULT_BOX, Uncertainty, _did_you_mean, parse_uncertain

FORMAT = "bstool.robot/1"
#: sizes the rest of bstool assumes (the controllers' chromosomes, the 4-bit states, the
#: GA's options): a robot file may state them but not change them yet
FIXED_SIZES = {"legs": 5, "modules": 6, "states": 16}
_FIELDS = {f.name: f for f in dataclasses.fields(RobotSpec)}


@dataclass(frozen=True)
class Robot:
    """A robot as a user describes it: the nominal values and how uncertain they are."""

    spec: RobotSpec = dataclasses.field(default_factory=RobotSpec)
    uncertain: Uncertainty | None = None  # None: no [uncertain] table (the default box)
    source: str = "the default robot"  # for messages: a file, "recorded in best.json", ...

    @property
    def box(self) -> Uncertainty:
        """The ranges to randomize over: the file's, else the built-in default box."""
        return self.uncertain if self.uncertain is not None else DEFAULT_BOX

    @property
    def is_default(self) -> bool:
        return self.spec == RobotSpec() and self.uncertain is None

    def to_json(self) -> dict[str, Any]:
        """What a run or a build records: every value (not a path), and the ranges if given."""
        out: dict[str, Any] = {"format": FORMAT, **self.spec.to_dict()}
        if self.uncertain is not None:
            out["uncertain"] = self.uncertain.to_toml_table()
        return out

    def digest(self) -> str:
        text = json.dumps(self.to_json(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def differences(self, other: Robot) -> list[str]:
        """``name a -> b`` for each value that differs from ``other``'s (then the box)."""
        out = [
            f"{name} {getattr(other.spec, name)!r} -> {getattr(self.spec, name)!r}"
            for name in _FIELDS
            if getattr(self.spec, name) != getattr(other.spec, name)
        ]
        if self.box != other.box:
            out.append("the uncertain ranges")
        return out


def load(path: str | os.PathLike[str]) -> Robot:
    """Read and check a robot file; every mistake is an :class:`InputError` naming the file
    and the key."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(
            f"robot file not found: {p}", hint="write one with `bstool robot > my-robot.toml`"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read robot file {p}: {exc}") from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(
            f"{p}: malformed TOML: {exc}", hint="see `bstool robot` for a file that works"
        ) from None
    return parse(table, str(p))


def parse(table: Any, where: str) -> Robot:
    """A robot from a decoded file (or a recorded ``robot`` object); ``where`` names it."""
    if not isinstance(table, dict):
        raise InputError(f"{where}: a robot must be a table of key = value")
    fmt = table.get("format", FORMAT)
    if fmt != FORMAT:
        raise InputError(f"{where}: format must be {FORMAT!r}, got {fmt!r}")
    values: dict[str, Any] = {}
    for key, value in table.items():
        if key in ("format", "uncertain"):
            continue
        if key not in _FIELDS:
            raise InputError(f"{where}: unknown key {key!r}", hint=_did_you_mean(key))
        values[key] = _value(key, value, where)
    try:
        spec = RobotSpec(**values)
    except InputError as exc:  # pragma: no cover - every value was checked above
        raise InputError(f"{where}: {exc.message}") from None
    uncertain = None
    if "uncertain" in table:
        uncertain = parse_uncertain(table["uncertain"], spec, where)
    return Robot(spec, uncertain, where)


def _value(key: str, value: Any, where: str) -> Any:
    default = _FIELDS[key].default
    if isinstance(default, bool) or isinstance(value, bool):
        raise InputError(f"{where}: {key} must be a {type(default).__name__}, got {value!r}")
    if isinstance(default, str):
        if not isinstance(value, str):
            raise InputError(f"{where}: {key} must be a string, got {value!r}")
        if key == "lead_axis" and value not in ("vertical", "horizontal"):
            raise InputError(
                f'{where}: lead_axis must be "vertical" or "horizontal", got {value!r}'
            )
        return value
    if isinstance(default, int):
        if not isinstance(value, int):
            raise InputError(f"{where}: {key} must be an integer, got {value!r}")
        if key in FIXED_SIZES and value != FIXED_SIZES[key]:
            raise InputError(
                f"{where}: {key} = {value}: bstool evolves, simulates and compiles the robot of "
                f"the paper only ({FIXED_SIZES['legs']} legs of {FIXED_SIZES['modules']} modules, "
                f"{FIXED_SIZES['states']} states) so far",
                hint=f"remove {key}, or set it to {FIXED_SIZES[key]}",
            )
        return value
    if not isinstance(value, int | float):
        raise InputError(f"{where}: {key} must be a number (SI units), got {value!r}")
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise InputError(f"{where}: {key} must be a positive finite number, got {value!r}")
    return number


def from_record(obj: Any, where: str) -> Robot:
    """A robot recorded in a controller file or a build (``Robot.to_json``)."""
    return parse(obj, f"{where} (its recorded robot)")


def resolve(
    given: str | os.PathLike[str] | Robot | None, recorded: Any = None, *, what: str = ""
) -> tuple[Robot, str | None]:
    """The robot a command uses: ``--robot`` if given, else the one ``what`` recorded (a
    controller file or a build), else the default. The note (None if there is nothing to
    say) tells when ``--robot`` differs from the recorded robot."""
    record = None if recorded is None else from_record(recorded, what or "the input")
    base = record if record is not None else Robot()
    if given is None:
        return base, None
    robot = given if isinstance(given, Robot) else load(given)
    changes = robot.differences(base)
    if not changes:
        return robot, None
    source = f"the one {what} was evolved on" if record is not None else "the default robot"
    shown = ", ".join(changes[:4]) + (f" and {len(changes) - 4} more" if len(changes) > 4 else "")
    return robot, f"note: the robot of {robot.source} differs from {source}: {shown}"


# --- the default file -----------------------------------------------------------------------

#: unit and source of each key (docs/robot.md, "Choices where the paper is silent")
_NOTES = {
    "legs": ("", "n, the paper's robot (§2.1); fixed at 5 for now"),
    "modules": ("", "m per leg (§2.1); fixed at 6 for now"),
    "states": ("", "k per module, 16 angles in [-pi/3, pi/3] (§2.3); fixed at 16"),
    "lead_axis": ("", "hinge of the lead module: a hip yaw, the next one lifts (docs/robot.md)"),
    "disc_radius": ("m", "disc centre to a lead hinge: five 50 mm leads fit around"),
    "disc_height": ("m", "the disc's plates, wiring hub and battery pack"),
    "disc_mass": ("kg", "plates and wiring hub 0.15 + the 6 V NiMH pack 0.25"),
    "module_pitch": ("m", "hinge to hinge: a standard servo 41 x 20 x 36 mm + horn, bracket"),
    "module_length": ("m", "the module's body (5 mm shorter than the pitch)"),
    "module_width": ("m", "servo + bracket; the BS2SX-IC is 30 x 16 x 9 mm"),
    "module_height": ("m", "servo + bracket + carrier with the two touch sensors"),
    "module_mass": ("kg", "servo 0.040 + BS2sx and electronics 0.020 + bracket 0.030"),
    "servo_torque": ("N m", "stall torque of a standard analog servo at 6 V (4.1 kg cm)"),
    "servo_speed": ("s per 60 deg", "no-load speed at 6 V (0.16-0.19 s in listings)"),
    "servo_band": ("rad", "error that gives full torque (analog P loop: kp = torque / band)"),
    "servo_armature": ("kg m^2", "rotor inertia x gear ratio^2 (~30 ms time constant)"),
    "friction": ("", "sliding friction, aluminium/ABS on a hard floor"),
    "timestep": ("s", "physics step; 1 ms vs 2 ms rank correlation 0.97 (mujoco.md)"),
    "transition_margin": ("", "default transition time = margin x full-range travel time"),
}


def default_text() -> str:
    """The default robot file, every key commented with its unit and source, and the default
    [uncertain] box (which evolution and sensitivity use where a file has no such table)."""
    spec = RobotSpec()
    lines = [
        f"# bstool robot file ({FORMAT}): the robot bstool simulates, evolves for and compiles.",
        "# Every key is optional (a missing one keeps the default shown); SI units. Sources:",
        "# docs/robot.md. Use it with --robot FILE on simulate, evolve, compile, twin, ...",
        f'format = "{FORMAT}"',
        "",
    ]
    for name in _FIELDS:
        unit, why = _NOTES[name]
        value = getattr(spec, name)
        text = f'"{value}"' if isinstance(value, str) else repr(value)
        comment = f"{unit}: {why}" if unit else why
        lines.append(f"{name + ' = ' + text:<28} # {comment}")
    lines += [
        "",
        "# How far the real robot may be from these values: the ranges `bstool evolve",
        "# --randomize` draws robots from and `bstool sensitivity` sweeps (without this table",
        "# both use the default box, the one below). Each entry is `range = [low, high]`",
        "# (absolute, in the key's unit) or `scale = [low, high]` (factors of the value above),",
        '# drawn uniformly or with distribution = "log-uniform". Only physics may be uncertain:',
        "# friction, servo_* and the masses (a mass's inertia scales with it). Sources of the",
        '# default ranges: docs/robot.md, "Uncertain robot". (`bstool evolve --randomize-box',
        "# FILE` trains on another file's table instead, keeping this one for the reports.)",
        "[uncertain]",
    ]
    for r in DEFAULT_BOX.ranges:
        body = ", ".join(f"{k} = {_toml(v)}" for k, v in r.to_toml_value().items())
        lines.append(f"{r.name} = {{ {body} }}")
    return "\n".join(lines) + "\n"


def _toml(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(repr(float(v)) for v in value) + "]"
    return f'"{value}"' if isinstance(value, str) else repr(value)
