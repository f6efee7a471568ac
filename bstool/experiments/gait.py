"""Fig. 20 and §5.2's "clustering of states": how far a module's state moves per transition.

The paper saw NNsig's modules mostly stay or step to a neighbouring state (|S^{t+1} − S^t| ≤ 1)
and could say no such thing of NNsin. The leads are left out of the counts: every NN lead steps
by one (eq. 10) whatever the activation, so only the other modules tell the models apart.
"""

from __future__ import annotations

import numpy as np


def state_changes(states: np.ndarray, *, leads: bool = False) -> np.ndarray:
    """|S^{t+1} − S^t| of every module and transition (the leads only if ``leads``)."""
    seq = np.asarray(states, dtype=np.int64)
    if not leads:
        seq = seq[:, :, 1:]
    return np.abs(np.diff(seq, axis=0)).ravel()


def change_histogram(states: np.ndarray, k: int, *, leads: bool = False) -> np.ndarray:
    """How many module transitions moved by 0, 1, ..., k−1 states."""
    return np.bincount(state_changes(states, leads=leads), minlength=k)[:k]


def clustered_fraction(states: np.ndarray, *, leads: bool = False) -> float:
    """The fraction of module transitions that stay or move to a neighbouring state."""
    changes = state_changes(states, leads=leads)
    return float(np.mean(changes <= 1)) if changes.size else float("nan")
