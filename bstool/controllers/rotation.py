"""Leg rotation (paper §5.2): leg i takes what leg i−R ran, turning the gait R legs.

Leg i of the robot points along 2πi/n (anticlockwise, seen from above). Giving leg i the
parameters of leg i−R moves the whole gait R legs anticlockwise, which turns the heading by
+R·360°/n (exactly, while the model is n-fold symmetric). Used by robust evolution
(bstool.evolve.scoring) and by the steering experiments (bstool.experiments.rotation).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from bstool.controllers.controller import Controller


def rotate_controller(controller: Controller, legs: int) -> Controller:
    """A controller whose leg i runs what leg (i − legs) mod n ran.

    Per-leg parameters move (initial states; NN weights); the CA rules are the same for all
    cells of a kind, so they stay. Fitness is dropped: it was measured for the other heading.
    """
    n = controller.legs
    r = legs % n
    changes: dict[str, object] = {
        "initial_states": np.roll(controller.initial_states, r, axis=0),
        "fitness": None,
    }
    if controller.weights is not None:
        changes["weights"] = np.roll(controller.weights, r, axis=0)
    return dataclasses.replace(controller, **changes)  # type: ignore[arg-type]


def rotate_states(states: np.ndarray, legs: int) -> np.ndarray:
    """The same shift applied to a state sequence (T+1, n, m)."""
    return np.roll(states, legs % states.shape[1], axis=1)
