"""A 95 % bootstrap percentile interval, the same one everywhere bstool reports an interval.

Percentile rather than BCa: BCa's acceleration estimate is unstable on the few values a
campaign has per model (5 seeds). 9999 resamples from a fixed seed, so a report or a
sensitivity table is the same every time it is made.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

CONFIDENCE = 0.95
RESAMPLES = 9999
SEED = 0


def interval(data: tuple[np.ndarray, ...], statistic: Any) -> tuple[float, float]:
    """(low, high) of ``statistic`` (vectorized, with an ``axis`` keyword) over ``data``."""
    from scipy import stats

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a degenerate sample (all equal) is a point interval
        res = stats.bootstrap(
            data,
            statistic,
            n_resamples=RESAMPLES,
            confidence_level=CONFIDENCE,
            method="percentile",
            vectorized=True,
            random_state=np.random.default_rng(SEED),
        )
    ci = res.confidence_interval
    return float(ci.low), float(ci.high)
