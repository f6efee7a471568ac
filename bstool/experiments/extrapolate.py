"""Running beyond MAX_TRANS (paper Fig. 19) and the paper's remedy: re-initialise every
MAX_TRANS transitions (§5.2, "reinitialize the state of the modules, and restart")."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np

from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.robot import RobotSpec
from bstool.sim.simulator import SimResult, Simulator
from bstool.sim.states import validate_states


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


def run_with_progress(
    spec: RobotSpec,
    sequences: Sequence[np.ndarray],
    advance: Callable[[int], None] | None = None,
    total: Callable[[int], None] | None = None,
) -> list[SimResult]:
    """Run each sequence on its own thread, calling ``advance(1)`` after every simulated
    transition (``total(n)`` first, with the number of calls to come)."""
    sim = Simulator(spec)
    chunk = sim.steps_per_transition
    arrays = [validate_states(s, sim.spec) for s in sequences]
    datas = [sim.data] + [mujoco.MjData(sim.model) for _ in arrays[1:]]
    if total:
        total(sum(sim.steps_for(len(a) - 1) // chunk for a in arrays))

    def tick(_data: mujoco.MjData) -> None:
        if advance:
            advance(1)

    with ThreadPoolExecutor(max(1, len(arrays)), thread_name_prefix="bstool-ext") as pool:
        futures = [
            pool.submit(sim.run_validated, a, d, on_chunk=tick, chunk_steps=chunk)
            for a, d in zip(arrays, datas, strict=True)
        ]
        return [f.result() for f in futures]
