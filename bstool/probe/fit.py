"""Fit the timing model's coefficients to the probe's marker times, robustly.

A loop of ``n`` iterations between two markers lasts ``c + n·t`` (``c``: the markers' own
statements and byte, the FOR, the next loop's set-up). In each repeat the long loop minus the
short loop of a kind gives ``t`` with ``c`` cancelled; the kind's slope is the **median over
repeats**, so ⌊(R−1)/2⌋ markers delayed by any amount (a USB adapter's latency spike: each late
marker spoils one interval of two different kinds, never both loops of one kind) do not move it.
Its standard error is from the spread of the repeats (1.4826 × MAD × 1.2533 / √R, the median's).

From the slopes (µs per iteration):

* statement kinds (empty loop, an assignment, a long expression): ``t = s·base + b·per_bit``
  (s statements of b token bits in total), weighted least squares → ``base_us``,
  ``per_bit_us``; and ``instruction_time_ratio`` = Σ t / Σ t_model over those kinds, a
  one-parameter fit of "the default model × r";
* PAUSE, PULSOUT, SERIN-timeout kinds at two unit counts: the slope difference over the count
  difference → the unit;
* SEROUT of 3 and 1 bytes: the difference, less the 2 extra items' token bits, over 2 → the time
  of one SEROUT byte item.

RUN is not measured: the default × the instruction ratio, marked unmeasured (``sd`` None).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bstool.errors import DeviceError
from bstool.probe.program import INSTRUCTION_KINDS, ProbeProgram
from bstool.timingfile import DEFAULT, Coefficient, TimingModel

MEDIAN_SE = 1.2533  # standard error of a median / that of a mean (normal data)
MAD_SD = 1.4826


@dataclass(frozen=True)
class Slope:
    """Per-iteration time of one kind (µs) and its standard error."""

    value: float
    sd: float
    repeats: int
    values: tuple[float, ...]


def robust_slope(values: Sequence[float]) -> tuple[float, float]:
    """Median of ``values`` and its standard error from their MAD."""
    a = np.asarray(values, dtype=float)
    med = float(np.median(a))
    if len(a) < 2:
        return med, math.inf
    mad = float(np.median(np.abs(a - med)))
    return med, MAD_SD * mad * MEDIAN_SE / math.sqrt(len(a))


def intervals(
    program: ProbeProgram, times: Mapping[tuple[int, int], float]
) -> dict[tuple[int, int], float]:
    """Segment durations (s) by (repeat, marker) from marker arrival times by (repeat, marker)
    (a segment ends at the next marker of its repeat, the last one at the end marker)."""
    out: dict[tuple[int, int], float] = {}
    per = program.markers_per_repeat
    for r in range(program.repeats):
        for m in range(1, per):
            a, b = times.get((r, m)), times.get((r, m + 1))
            if a is not None and b is not None:
                out[(r, m)] = b - a
    return out


def slopes(program: ProbeProgram, spans: Mapping[tuple[int, int], float]) -> dict[str, Slope]:
    """Per-iteration time of every kind from the segment durations."""
    pairs: dict[str, list[tuple[int, int]]] = {}  # kind -> [(short marker, long marker)]
    by_kind: dict[str, list[tuple[int, int]]] = {}
    for s in program.segments:
        by_kind.setdefault(s.kind.name, []).append((s.marker, s.n))
    for name, segs in by_kind.items():
        (m_short, _), (m_long, _) = sorted(segs, key=lambda x: x[1])
        pairs[name] = [(m_short, m_long)]
    n_of = {s.marker: s.n for s in program.segments}
    out: dict[str, Slope] = {}
    for name, [(ms, ml)] in pairs.items():
        vals = []
        for r in range(program.repeats):
            a, b = spans.get((r, ms)), spans.get((r, ml))
            if a is not None and b is not None:
                vals.append((b - a) * 1e6 / (n_of[ml] - n_of[ms]))
        if not vals:
            raise DeviceError(
                f"probe: no complete measurement of the {name} loops (markers lost)",
                hint="check the cable and run bstool probe again",
            )
        value, sd = robust_slope(vals)
        out[name] = Slope(value, sd, len(vals), tuple(vals))
    return out


def _diff(a: Slope, b: Slope, per: float, less: float = 0.0) -> Coefficient:
    value = (a.value - b.value - less) / per
    return Coefficient(value, math.hypot(a.sd, b.sd) / abs(per))


def _unit(program: ProbeProgram, sl: Mapping[str, Slope], unit: str, scale: float) -> Coefficient:
    """One wait unit (µs / ``scale``) from the two kinds that wait ``unit`` at different counts."""
    low, high = sorted({s.kind for s in program.segments if s.kind.unit == unit},
                       key=lambda k: k.param)  # fmt: skip
    return _diff(sl[high.name], sl[low.name], (high.param - low.param) * scale)


def fit(program: ProbeProgram, spans: Mapping[tuple[int, int], float]) -> TimingModel:
    """The timing model measured by ``spans`` (segment durations, see :func:`intervals`)."""
    sl = slopes(program, spans)
    info = program.info
    names = list(INSTRUCTION_KINDS)
    y = np.array([sl[k].value for k in names])
    sd = np.array([max(sl[k].sd, 1e-9) for k in names])
    design = np.array([[info[k].statements, info[k].bits] for k in names], dtype=float)
    w = 1.0 / sd
    coef, *_ = np.linalg.lstsq(design * w[:, None], y * w, rcond=None)
    cov = np.linalg.pinv((design * w[:, None]).T @ (design * w[:, None]))
    base = Coefficient(float(coef[0]), float(math.sqrt(max(cov[0, 0], 0.0))))
    per_bit = Coefficient(float(coef[1]), float(math.sqrt(max(cov[1, 1], 0.0))))
    model_sum = sum(info[k].model_us for k in names)
    ratio = Coefficient(
        float(y.sum()) / model_sum, float(math.sqrt(float((sd**2).sum()))) / model_sum
    )
    pause = _unit(program, sl, "pause", 1000.0)
    pulsout = _unit(program, sl, "pulsout", 1.0)
    serin = _unit(program, sl, "serin", 1000.0)
    extra_bits = info["serout_3"].bits - info["serout_1"].bits
    item = _diff(sl["serout_3"], sl["serout_1"], 2, extra_bits * per_bit.value)
    return TimingModel(
        base_us=base,
        per_bit_us=per_bit,
        run_us=Coefficient(DEFAULT.run_us.value * ratio.value, None),
        pause_unit_ms=pause,
        pulsout_unit_us=pulsout,
        serin_unit_ms=serin,
        serout_item_us=item,
        instruction_time_ratio=ratio,
        source="probe",
        measurements={
            "repeats": program.repeats,
            "kinds": {
                k: {
                    "statements": info[k].statements,
                    "token_bits": info[k].bits,
                    "model_us": info[k].model_us,
                    "measured_us": s.value,
                    "sd_us": s.sd,
                    "per_repeat_us": list(s.values),
                }
                for k, s in sl.items()
            },
        },
    )
