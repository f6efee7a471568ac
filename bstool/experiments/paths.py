"""Shape of a disc path: distance per transition, lateral deviation and sway (paper §5.2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def distance_curve(path: np.ndarray) -> np.ndarray:
    """Euclidean distance from the start after each transition (eq. 6 at every t)."""
    p = np.asarray(path, dtype=float)
    return np.hypot(p[:, 0] - p[0, 0], p[:, 1] - p[0, 1])


def heading_deg(path: np.ndarray) -> float:
    """Direction of the start-to-end displacement, degrees anticlockwise from +x."""
    d = np.asarray(path[-1], dtype=float) - np.asarray(path[0], dtype=float)
    return math.degrees(math.atan2(d[1], d[0]))


def wrap_deg(angle: float) -> float:
    """An angle in degrees folded into (-180, 180]."""
    a = math.fmod(angle, 360.0)
    if a <= -180.0:
        a += 360.0
    elif a > 180.0:
        a -= 360.0
    return a


@dataclass(frozen=True)
class PathShape:
    distance: float  # start to end, metres
    length: float  # along the path, metres
    max_deviation: float  # largest distance of a point from the start-to-end line, metres
    rms_deviation: float  # root mean square of those distances
    sway: float  # mean side-to-side step: mean |change of signed deviation| per transition
    heading: float  # degrees

    def to_json(self) -> dict[str, float]:
        return {k: float(v) for k, v in self.__dict__.items()}


def path_shape(path: np.ndarray) -> PathShape:
    """Lateral deviation from the straight start-to-end line, and sway.

    The deviation of a point is its signed perpendicular distance from that line; sway is how
    far the disc moves sideways per transition on average (the side-to-side motion of §5.2).
    """
    p = np.asarray(path, dtype=float) - np.asarray(path[0], dtype=float)
    end = p[-1]
    dist = float(np.hypot(*end))
    steps = np.diff(p, axis=0)
    length = float(np.hypot(steps[:, 0], steps[:, 1]).sum()) if len(steps) else 0.0
    if dist > 0:
        normal = np.array([-end[1], end[0]]) / dist
        signed = p @ normal
    else:
        signed = np.hypot(p[:, 0], p[:, 1])
    sway = float(np.abs(np.diff(signed)).mean()) if len(signed) > 1 else 0.0
    return PathShape(
        distance=dist,
        length=length,
        max_deviation=float(np.abs(signed).max()),
        rms_deviation=float(np.sqrt(np.mean(signed**2))),
        sway=sway,
        heading=heading_deg(path) if dist > 0 else 0.0,
    )
