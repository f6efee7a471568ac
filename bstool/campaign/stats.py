"""Statistics over a campaign's seeds: a mean with its 95 % bootstrap interval, a two-sided
Mann–Whitney U test between two models, and the verdict rules of docs/campaign.md.

Seeds are few (5 in the paper's plan), so: the interval is the bootstrap percentile interval
(BCa's acceleration estimate is unstable with 5 values), 9999 resamples from a fixed seed (the
report is the same every time), and the test is the exact U test when there are no ties.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bstool.experiments.bootstrap import CONFIDENCE as CONFIDENCE  # re-exported: the report
from bstool.experiments.bootstrap import RESAMPLES as RESAMPLES
from bstool.experiments.bootstrap import SEED as SEED
from bstool.experiments.bootstrap import interval as _bootstrap

ALPHA = 0.05

HOLDS = "holds"
FAILS = "does not hold"
UNCLEAR = "cannot be told apart"


def _values(values: Sequence[float | None]) -> np.ndarray:
    arr = np.array([np.nan if v is None else v for v in values], dtype=float)
    return arr[np.isfinite(arr)]


@dataclass(frozen=True)
class Interval:
    """A mean over ``n`` runs and its 95 % bootstrap interval (None below 2 runs)."""

    mean: float | None
    low: float | None
    high: float | None
    n: int

    def to_json(self) -> dict[str, Any]:
        return {"mean": self.mean, "low": self.low, "high": self.high, "n": self.n}

    def text(self, scale: float = 1.0, digits: int = 1) -> str:
        if self.mean is None:
            return "—"
        m = f"{self.mean * scale:.{digits}f}"
        if self.low is None or self.high is None:
            return f"{m} (n = {self.n})"
        return f"{m} [{self.low * scale:.{digits}f}, {self.high * scale:.{digits}f}]"


def _mean(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis)


def _mean_difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis) - np.mean(y, axis=axis)


def mean_interval(values: Sequence[float | None]) -> Interval:
    """The mean of ``values`` (None and non-finite ones left out) with its 95 % interval."""
    v = _values(values)
    if v.size == 0:
        return Interval(None, None, None, 0)
    if v.size < 2:
        return Interval(float(v.mean()), None, None, int(v.size))
    if np.all(v == v[0]):
        return Interval(float(v[0]), float(v[0]), float(v[0]), int(v.size))
    low, high = _bootstrap((v,), _mean)
    return Interval(float(v.mean()), low, high, int(v.size))


def difference_interval(a: Sequence[float | None], b: Sequence[float | None]) -> Interval:
    """mean(a) − mean(b), the two resampled independently, with its 95 % interval."""
    x, y = _values(a), _values(b)
    if x.size == 0 or y.size == 0:
        return Interval(None, None, None, 0)
    diff = float(x.mean() - y.mean())
    if x.size < 2 or y.size < 2:
        return Interval(diff, None, None, int(min(x.size, y.size)))
    if np.all(x == x[0]) and np.all(y == y[0]):
        return Interval(diff, diff, diff, int(min(x.size, y.size)))
    low, high = _bootstrap((x, y), _mean_difference)
    return Interval(diff, low, high, int(min(x.size, y.size)))


@dataclass(frozen=True)
class Test:
    """A two-sided Mann–Whitney U test of a against b; ``direction`` +1 when a tends to be
    larger (U above its mean n_a·n_b/2), −1 when smaller, 0 when neither."""

    u: float
    p: float
    n_a: int
    n_b: int

    @property
    def direction(self) -> int:
        centre = self.n_a * self.n_b / 2
        return 0 if self.u == centre else (1 if self.u > centre else -1)

    def to_json(self) -> dict[str, Any]:
        return {"u": self.u, "p": self.p, "n_a": self.n_a, "n_b": self.n_b}


def mann_whitney(a: Sequence[float | None], b: Sequence[float | None]) -> Test | None:
    """The test, or None when either side has no value (or the p-value is undefined)."""
    from scipy import stats

    x, y = _values(a), _values(b)
    if x.size == 0 or y.size == 0:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = stats.mannwhitneyu(x, y, alternative="two-sided")
    p = float(res.pvalue)
    if not math.isfinite(p):
        return None
    return Test(float(res.statistic), p, int(x.size), int(y.size))


def greater(test: Test | None) -> str:
    """ "a is larger than b": holds when p < 0.05 with a larger, does not hold when p < 0.05
    with a smaller, cannot be told apart otherwise."""
    if test is None or test.p >= ALPHA or test.direction == 0:
        return UNCLEAR
    return HOLDS if test.direction > 0 else FAILS


def smaller(test: Test | None) -> str:
    """ "a is smaller than b" (the rule of :func:`greater`, the other way)."""
    flipped = greater(test)
    return {HOLDS: FAILS, FAILS: HOLDS}.get(flipped, UNCLEAR)


def similar(test: Test | None, difference: Interval, margin: float) -> str:
    """ "a is comparable to b": holds when the 95 % interval of mean(a) − mean(b) lies within
    ±margin, does not hold when the test finds them different (p < 0.05), cannot be told
    apart otherwise."""
    if test is not None and test.p < ALPHA:
        return FAILS
    if difference.low is None or difference.high is None:
        return UNCLEAR
    return HOLDS if -margin <= difference.low and difference.high <= margin else UNCLEAR


def positive(interval: Interval) -> str:
    """ "the mean is above 0": holds when the whole 95 % interval is, does not hold when it is
    wholly below 0, cannot be told apart otherwise."""
    if interval.low is None or interval.high is None:
        return UNCLEAR
    if interval.low > 0:
        return HOLDS
    return FAILS if interval.high < 0 else UNCLEAR


def negative(interval: Interval) -> str:
    flipped = positive(interval)
    return {HOLDS: FAILS, FAILS: HOLDS}.get(flipped, UNCLEAR)


def matches(interval: Interval, value: float) -> str:
    """ "the paper's figure is ``value``": holds when it lies within our 95 % interval, does
    not hold when outside it, cannot be told apart without an interval."""
    if interval.low is None or interval.high is None:
        return UNCLEAR
    return HOLDS if interval.low <= value <= interval.high else FAILS


def combined(verdicts: Sequence[str]) -> str:
    """A claim made of several comparisons: holds when every one holds, does not hold when
    any does not, cannot be told apart otherwise."""
    if not verdicts:
        return UNCLEAR
    if any(v == FAILS for v in verdicts):
        return FAILS
    return HOLDS if all(v == HOLDS for v in verdicts) else UNCLEAR
