"""Running beyond MAX_TRANS (paper Fig. 19) and the paper's remedy: re-initialise every
MAX_TRANS transitions (§5.2, "reinitialize the state of the modules, and restart")."""

from __future__ import annotations

import numpy as np

from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.moduleid import ModuleId


def reinit_states(
    controller: Controller,
    transitions: int,
    every: int,
    failed: list[ModuleId] | None = None,
) -> np.ndarray:
    """R^0..R^every, then R^0..R^every again, ... cut to ``transitions`` + 1 frames.

    The robot keeps its place; only the module states restart: the transition after R^every
    goes to R^0 (the paper's "restart the state transitions from the beginning").
    """
    if every < 1:
        raise InputError(f"--reinit-every must be at least 1, got {every}")
    block = controller.states(every, failed=failed or [])  # every+1 frames: R^0..R^every
    reps = transitions // (every + 1) + 1
    frames = np.concatenate([block] * reps, axis=0)
    return frames[: transitions + 1]
