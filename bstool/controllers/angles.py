"""State ↔ angle for the controllers: θ(s) = −π/3 + s·(2π/3)/(k−1), nearest state with ties up.

The same floats as ``bstool.robot.state_to_angle`` (same expression; tested equal), kept here
so the controllers (and the tables the compiler derives from them) do not depend on the robot.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

K = 16
"""The paper's number of states per module (4-bit genes)."""

ANGLE_MIN = -math.pi / 3
ANGLE_MAX = math.pi / 3

TIE_EPS = 1e-9
"""An angle within this many radians of a half step counts as an exact tie (→ higher state)."""


def state_to_angle(s: int, k: int = K) -> float:
    """Angle in radians of state ``s`` (0..k−1)."""
    return ANGLE_MIN + s * ((ANGLE_MAX - ANGLE_MIN) / (k - 1))


def angle_table(k: int = K) -> npt.NDArray[np.float64]:
    """Angles of states 0..k−1, computed by :func:`state_to_angle` (identical floats)."""
    return np.array([state_to_angle(s, k) for s in range(k)], dtype=np.float64)


def angle_to_state(phi: float, k: int = K) -> int:
    """Nearest state to angle ``phi``; exact ties (within :data:`TIE_EPS`) go to the higher state.

    Values outside [−π/3, π/3] clamp to 0 or k−1.
    """
    step = (ANGLE_MAX - ANGLE_MIN) / (k - 1)
    lo = math.floor((phi - ANGLE_MIN) / step)
    mid = ANGLE_MIN + (lo + 0.5) * step
    s = lo + 1 if phi >= mid - TIE_EPS else lo
    return min(max(s, 0), k - 1)


def angles_to_states(phi: npt.NDArray[np.float64], k: int = K) -> npt.NDArray[np.int64]:
    """Vectorised :func:`angle_to_state` (the same operations, element by element)."""
    step = (ANGLE_MAX - ANGLE_MIN) / (k - 1)
    lo = np.floor((phi - ANGLE_MIN) / step)
    mid = ANGLE_MIN + (lo + 0.5) * step
    s = np.where(phi >= mid - TIE_EPS, lo + 1, lo).astype(np.int64)
    return np.clip(s, 0, k - 1)
