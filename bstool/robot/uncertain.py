"""How far a real robot may be from the nominal one: a range per physics parameter, and seeded
draws of whole robots from them (docs/robot.md "Uncertain robot").

A range is absolute (``range = [low, high]``, in the parameter's unit) or relative to the
nominal value (``scale = [low, high]``, a factor), drawn uniformly or log-uniformly. Only the
physics of a compiled model can vary (``bstool.robot.apply.PHYSICS_FIELDS``): geometry needs a
model of its own.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bstool.errors import InputError
from bstool.robot.apply import PHYSICS_FIELDS
from bstool.robot.spec import RobotSpec

DISTRIBUTIONS = ("uniform", "log-uniform")


@dataclass(frozen=True)
class ParamRange:
    """One parameter's uncertainty: values in [low, high] (× nominal when ``relative``)."""

    name: str
    low: float
    high: float
    relative: bool = False  # scale = [low, high]: factors of the nominal value
    distribution: str = "uniform"

    def bounds(self, nominal: RobotSpec) -> tuple[float, float]:
        """The absolute interval for the robot ``nominal``."""
        if not self.relative:
            return self.low, self.high
        value = float(getattr(nominal, self.name))
        return self.low * value, self.high * value

    def draw(self, nominal: RobotSpec, u: float) -> float:
        """The value at quantile ``u`` in [0, 1) of the distribution."""
        lo, hi = self.bounds(nominal)
        if self.distribution == "log-uniform":
            return float(math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))))
        return float(lo + u * (hi - lo))

    def points(self, nominal: RobotSpec, count: int) -> list[float]:
        """``count`` values evenly spread over the range (in log for log-uniform), ends
        included: the one-at-a-time sweep of ``bstool sensitivity``."""
        if count == 1:
            return [self.draw(nominal, 0.5)]
        return [self.draw(nominal, i / (count - 1)) for i in range(count)]

    def to_toml_value(self) -> dict[str, Any]:
        out: dict[str, Any] = {("scale" if self.relative else "range"): [self.low, self.high]}
        if self.distribution != "uniform":
            out["distribution"] = self.distribution
        return out

    def describe(self) -> str:
        kind = "×" if self.relative else ""
        law = "log-uniform " if self.distribution == "log-uniform" else ""
        return f"{self.name} {law}{kind}{self.low:g}–{kind}{self.high:g}"


@dataclass(frozen=True)
class Uncertainty:
    """The ranges of a robot file's ``[uncertain]`` table (or the default box)."""

    ranges: tuple[ParamRange, ...]

    def __post_init__(self) -> None:
        order = {name: i for i, name in enumerate(PHYSICS_FIELDS)}
        object.__setattr__(self, "ranges", tuple(sorted(self.ranges, key=lambda r: order[r.name])))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.ranges)

    def sample(self, nominal: RobotSpec, rng: np.random.Generator) -> RobotSpec:
        """One robot: every uncertain parameter drawn (in PHYSICS_FIELDS order)."""
        values: dict[str, Any] = {r.name: r.draw(nominal, float(rng.random())) for r in self.ranges}
        return dataclasses.replace(nominal, **values)

    def samples(self, nominal: RobotSpec, count: int, seed: Sequence[int] | int) -> list[RobotSpec]:
        """``count`` robots drawn from ``np.random.default_rng(seed)``: the same seed gives the
        same robots for every controller (common random numbers)."""
        rng = np.random.default_rng(seed)
        return [self.sample(nominal, rng) for _ in range(count)]

    def to_toml_table(self) -> dict[str, dict[str, Any]]:
        return {r.name: r.to_toml_value() for r in self.ranges}

    def describe(self) -> str:
        return "; ".join(r.describe() for r in self.ranges)

    def digest(self) -> str:
        text = json.dumps(self.to_toml_table(), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


#: The built-in box where a robot file has no [uncertain] table (docs/robot.md, "Uncertain
#: robot", gives the source of each range).
DEFAULT_BOX = Uncertainty(
    (
        ParamRange("friction", 0.3, 1.0, distribution="log-uniform"),
        ParamRange("servo_torque", 0.7, 1.15, relative=True),
        ParamRange("servo_speed", 0.85, 1.25, relative=True),
        ParamRange("servo_band", 0.8, 1.25, relative=True),
        ParamRange("module_mass", 0.85, 1.2, relative=True),
        ParamRange("disc_mass", 0.85, 1.2, relative=True),
    )
)


def parse_uncertain(
    table: Any, nominal: RobotSpec, where: str, *, section: str = "uncertain"
) -> Uncertainty:
    """The ``[uncertain]`` table of a robot file, checked against the nominal robot."""
    if not isinstance(table, Mapping):
        raise InputError(f"{where}: [{section}] must be a table of parameter = {{ ... }}")
    ranges = []
    for name, value in table.items():
        key = f"{section}.{name}"
        if name not in PHYSICS_FIELDS:
            known = [f.name for f in dataclasses.fields(RobotSpec)]
            if name in known:
                raise InputError(
                    f"{where}: {key}: {name} cannot be uncertain (it changes the robot's "
                    "geometry or size, which a randomized run keeps fixed)",
                    hint="uncertain may be: " + ", ".join(PHYSICS_FIELDS),
                )
            raise InputError(f"{where}: unknown parameter {key}", hint=_did_you_mean(name))
        ranges.append(_parse_range(name, value, nominal, where, key))
    return Uncertainty(tuple(ranges))


def _parse_range(name: str, value: Any, nominal: RobotSpec, where: str, key: str) -> ParamRange:
    example = (
        f"{name} = {{ scale = [0.8, 1.2] }} or "
        f'{{ range = [0.3, 1.0], distribution = "log-uniform" }}'
    )
    if not isinstance(value, Mapping):
        raise InputError(f"{where}: {key} must be a table", hint=example)
    unknown = set(value) - {"range", "scale", "distribution"}
    if unknown:
        bad = sorted(unknown)[0]
        close = difflib.get_close_matches(bad, ["range", "scale", "distribution"], n=1)
        raise InputError(
            f"{where}: unknown key {key}.{bad}",
            hint=f"did you mean {close[0]}?" if close else "use range, scale and distribution",
        )
    kinds = [k for k in ("range", "scale") if k in value]
    if len(kinds) != 1:
        raise InputError(
            f"{where}: {key} needs exactly one of range (absolute) or scale (× nominal)",
            hint=example,
        )
    kind = kinds[0]
    pair = value[kind]
    if (
        not isinstance(pair, list)
        or len(pair) != 2
        or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in pair)
    ):
        raise InputError(f"{where}: {key}.{kind} must be [low, high] (two numbers)", hint=example)
    low, high = float(pair[0]), float(pair[1])
    if not (math.isfinite(low) and math.isfinite(high)):
        raise InputError(f"{where}: {key}.{kind} must be finite, got {pair}")
    if low > high:
        raise InputError(
            f"{where}: {key}.{kind}: the low end {low:g} is above the high end {high:g}"
        )
    law = value.get("distribution", "uniform")
    if law not in DISTRIBUTIONS:
        raise InputError(
            f"{where}: {key}.distribution must be one of {', '.join(DISTRIBUTIONS)}, got {law!r}"
        )
    result = ParamRange(name, low, high, relative=kind == "scale", distribution=str(law))
    lo, _hi = result.bounds(nominal)
    if not lo > 0:
        raise InputError(
            f"{where}: {key}.{kind} {pair} leaves {name} at {lo:g}: it must stay positive",
            hint="every physics parameter must be > 0 over its whole range",
        )
    return result


def _did_you_mean(name: str, choices: Iterable[str] | None = None) -> str:
    names = (
        list(choices) if choices is not None else [f.name for f in dataclasses.fields(RobotSpec)]
    )
    close = difflib.get_close_matches(name, names, n=1)
    return f"did you mean {close[0]}?" if close else "the keys are: " + ", ".join(names)
