"""THE timing file format (``bstool.timing/1``): a stamp's measured timing coefficients.

``bstool probe`` writes it; ``bstool compile --timing F``, ``bstool twin --timing F`` and
``python -m hil_mock serve --timing-model F`` read it. :class:`TimingModel` holds every
coefficient of the timing model (docs/probe.md) with its standard error; the default instance is
today's estimate (docs/twin.md, "Timing model"): a statement costs ``base + per_bit × token
bits``, RUN a fixed overhead, PAUSE/PULSOUT/SERIN timeouts their units, a SEROUT item its byte.

File::

    {"format": "bstool.timing/1",
     "source": "probe /dev/ttyUSB0", "created": "2026-12-01T20:00:00Z", "bstool_version": "...",
     "coefficients": {"base_us": {"value": 36.1, "sd": 0.4}, ...},   # every name in COEFFICIENTS
     "instruction_time_ratio": {"value": 1.80, "sd": 0.004},
     "measurements": {...}}                                          # optional, free-form

``sd`` is one standard error, ``null`` for a coefficient that was not measured (the estimate).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, fields, replace
from typing import Any

from bstool import fileio
from bstool.errors import InputError

FORMAT = "bstool.timing/1"
TYPICAL_BITS = 40
"""Token bits of a typical statement (``x = x + 1`` is 44): the instruction time ratio compares
statements of this length."""
RELOAD = "measure the stamp again with bstool probe, or fix the file"


@dataclass(frozen=True)
class Coefficient:
    """A coefficient and its standard error (None: not measured, the model's estimate)."""

    value: float
    sd: float | None = None

    def to_json(self) -> dict[str, float | None]:
        return {"value": self.value, "sd": self.sd}


@dataclass(frozen=True)
class TimingModel:
    """The coefficients of the timing model (defaults: the estimate of docs/twin.md)."""

    base_us: Coefficient = Coefficient(20.0)
    """Every statement: this much, plus ``per_bit_us`` per token bit."""
    per_bit_us: Coefficient = Coefficient(2.0)
    run_us: Coefficient = Coefficient(300.0)
    """RUN into another slot, on top of its statement."""
    pause_unit_ms: Coefficient = Coefficient(1.0)
    """One unit of PAUSE (and SEROUT pace)."""
    pulsout_unit_us: Coefficient = Coefficient(0.8)
    serin_unit_ms: Coefficient = Coefficient(0.4)
    """One unit of a SERIN timeout."""
    serout_item_us: Coefficient = Coefficient(1040.0)
    """One more byte item of a SEROUT at 9600 baud (mode 240): 10 bit times plus any gap."""
    instruction_time_ratio: Coefficient = Coefficient(1.0)
    """Measured statement time / the default model's (1.0 = the model), fitted directly."""
    source: str = "default"
    created: str | None = None
    bstool_version: str | None = None
    measurements: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def measured(self) -> bool:
        return self.source != "default"

    def statement_us(self, bits: int) -> float:
        """One statement of ``bits`` token bits (waits excluded)."""
        return self.base_us.value + self.per_bit_us.value * bits

    def coefficients(self) -> dict[str, Coefficient]:
        return {name: getattr(self, name) for name in COEFFICIENTS}


COEFFICIENTS = tuple(f.name for f in fields(TimingModel) if f.type in ("Coefficient", Coefficient))
DEFAULT = TimingModel()
_COEFF_NAMES = tuple(n for n in COEFFICIENTS if n != "instruction_time_ratio")
_LIMITS = {  # plausible bounds (a stamp 5x off the estimate either way, a clock 20 % off)
    "base_us": (0.0, 500.0),
    "per_bit_us": (0.0, 50.0),
    "run_us": (0.0, 5000.0),
    "pause_unit_ms": (0.8, 1.2),
    "pulsout_unit_us": (0.64, 0.96),
    "serin_unit_ms": (0.32, 0.48),
    "serout_item_us": (500.0, 5000.0),
    "instruction_time_ratio": (0.2, 5.0),
}


def to_json(model: TimingModel) -> dict[str, Any]:
    out: dict[str, Any] = {
        "format": FORMAT,
        "source": model.source,
        "created": model.created,
        "bstool_version": model.bstool_version,
        "coefficients": {n: getattr(model, n).to_json() for n in _COEFF_NAMES},
        "instruction_time_ratio": model.instruction_time_ratio.to_json(),
    }
    if model.measurements:
        out["measurements"] = model.measurements
    return out


def dump(model: TimingModel, path: str | os.PathLike[str]) -> None:
    """Write ``model`` atomically (never a half-written file)."""
    fileio.write_json(path, to_json(model))


def _number(obj: Any, where: str, *, allow_none: bool = False) -> float | None:
    if obj is None and allow_none:
        return None
    if isinstance(obj, bool) or not isinstance(obj, int | float) or not math.isfinite(obj):
        raise InputError(f"{where} must be a finite number, not {obj!r}", hint=RELOAD)
    return float(obj)


def _coefficient(obj: Any, where: str, name: str) -> Coefficient:
    if not isinstance(obj, dict) or "value" not in obj:
        raise InputError(f'{where} must be an object {{"value": X, "sd": S}}', hint=RELOAD)
    extra = sorted(set(obj) - {"value", "sd"})
    if extra:
        raise InputError(f"{where}: unknown field {extra[0]!r}", hint=RELOAD)
    value = _number(obj["value"], f"{where}.value")
    assert value is not None
    sd = _number(obj.get("sd"), f"{where}.sd", allow_none=True)
    lo, hi = _LIMITS[name]
    if not lo <= value <= hi:
        raise InputError(
            f"{where}.value {value:g} is outside the plausible range {lo:g}..{hi:g}", hint=RELOAD
        )
    if sd is not None and sd < 0:
        raise InputError(f"{where}.sd must be >= 0, not {sd:g}", hint=RELOAD)
    return Coefficient(value, sd)


def _text(obj: Any, where: str) -> str | None:
    if obj is not None and not isinstance(obj, str):
        raise InputError(f"{where} must be a string, not {obj!r}", hint=RELOAD)
    return obj


def from_json(obj: Any, file: str | os.PathLike[str] = "timing file") -> TimingModel:
    """Check every field; an :class:`InputError` names the file and the field."""
    f = str(file)
    if not isinstance(obj, dict):
        raise InputError(f"{f}: a timing file is a JSON object", hint=RELOAD)
    if obj.get("format") != FORMAT:
        raise InputError(
            f"{f}: format is {obj.get('format')!r}, not {FORMAT!r}: not a timing file",
            hint="give the file bstool probe wrote (-o stamp-timing.json)",
        )
    known = {"format", "source", "created", "bstool_version", "coefficients",
             "instruction_time_ratio", "measurements"}  # fmt: skip
    extra = sorted(set(obj) - known)
    if extra:
        raise InputError(f"{f}: unknown field {extra[0]!r}", hint=RELOAD)
    coeffs = obj.get("coefficients")
    if not isinstance(coeffs, dict):
        raise InputError(f"{f}: coefficients must be an object", hint=RELOAD)
    missing = [n for n in _COEFF_NAMES if n not in coeffs]
    if missing:
        raise InputError(f"{f}: coefficients.{missing[0]} is missing", hint=RELOAD)
    unknown = sorted(set(coeffs) - set(_COEFF_NAMES))
    if unknown:
        raise InputError(f"{f}: unknown coefficient {unknown[0]!r}", hint=RELOAD)
    values = {n: _coefficient(coeffs[n], f"{f}: coefficients.{n}", n) for n in _COEFF_NAMES}
    if "instruction_time_ratio" not in obj:
        raise InputError(f"{f}: instruction_time_ratio is missing", hint=RELOAD)
    values["instruction_time_ratio"] = _coefficient(
        obj["instruction_time_ratio"], f"{f}: instruction_time_ratio", "instruction_time_ratio"
    )
    measurements = obj.get("measurements", {})
    if not isinstance(measurements, dict):
        raise InputError(f"{f}: measurements must be an object", hint=RELOAD)
    source = _text(obj.get("source"), f"{f}: source") or "default"
    return TimingModel(
        **values,
        source=source,
        created=_text(obj.get("created"), f"{f}: created"),
        bstool_version=_text(obj.get("bstool_version"), f"{f}: bstool_version"),
        measurements=measurements,
    )


def load(path: str | os.PathLike[str]) -> TimingModel:
    """Read a ``bstool.timing/1`` file (missing, malformed or wrong: :class:`InputError`)."""
    return from_json(fileio.read_json(path, "timing file"), path)


def stamped(model: TimingModel, source: str) -> TimingModel:
    """``model`` marked as measured now by ``source`` (with this bstool's version)."""
    from bstool.version import __version__

    created = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    return replace(model, source=source, created=created, bstool_version=__version__)
