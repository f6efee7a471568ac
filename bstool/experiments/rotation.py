"""Steering by swapping control parameters between legs (paper §5.2).

Leg i of the robot points along 2πi/n (anticlockwise, seen from above). Giving leg i the
parameters of leg i−R moves the whole gait R legs anticlockwise, which turns the heading by
+R·360°/n (exactly, while the model is n-fold symmetric). The rotation itself lives in
:mod:`bstool.controllers.rotation` (re-exported here).
"""

from __future__ import annotations

from dataclasses import dataclass

from bstool.controllers.rotation import rotate_controller, rotate_states
from bstool.experiments.paths import wrap_deg

__all__ = ["HeadingChoice", "choose_rotation", "rotate_controller", "rotate_states"]


@dataclass(frozen=True)
class HeadingChoice:
    legs: int  # rotation R in 0..n-1
    predicted: float  # heading after rotation, degrees
    residual: float  # wanted − predicted, degrees in (-180, 180]


def choose_rotation(base_heading: float, wanted: float, n: int) -> HeadingChoice:
    """The leg rotation that heads closest to ``wanted`` degrees, from a measured heading."""
    step = 360.0 / n
    best = min(range(n), key=lambda r: abs(wrap_deg(wanted - (base_heading + r * step))))
    predicted = wrap_deg(base_heading + best * step)
    return HeadingChoice(best, predicted, wrap_deg(wanted - predicted))
