"""Simulating the robot: one run (:class:`Simulator`), batches on threads (``bstool.sim.batch``).

Names are loaded lazily so that ``bstool.sim.gl`` can pick MuJoCo's GL backend before anything
imports mujoco (MuJoCo reads MUJOCO_GL once, at import).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bstool.sim.batch import BatchEvaluator, evaluate_batch
    from bstool.sim.simulator import SimResult, Simulator
    from bstool.sim.states import (
        hold_failed,
        load_states_file,
        states_from_json,
        validate_states,
    )

_WHERE = {
    "SimResult": "bstool.sim.simulator",
    "Simulator": "bstool.sim.simulator",
    "BatchEvaluator": "bstool.sim.batch",
    "evaluate_batch": "bstool.sim.batch",
    "hold_failed": "bstool.sim.states",
    "load_states_file": "bstool.sim.states",
    "states_from_json": "bstool.sim.states",
    "validate_states": "bstool.sim.states",
}

__all__ = [
    "BatchEvaluator",
    "SimResult",
    "Simulator",
    "evaluate_batch",
    "hold_failed",
    "load_states_file",
    "states_from_json",
    "validate_states",
]


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'bstool.sim' has no attribute {name!r}")
