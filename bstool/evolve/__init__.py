"""Evolution of the controllers: the paper's GA, §3.4 co-evolution, checkpoints, Dask backend.

Entry points (loaded on first use)::

    from bstool.evolve import evolve
    result = evolve("nnsin", pop=20, gens=10, seed=1, out="run", on_generation=print)

See docs/api.md and docs/evolution.md.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bstool.evolve.driver import (
        EvolveInterrupted,
        EvolveResult,
        Generation,
        evolve,
        resume,
    )
    from bstool.evolve.engine import GAParams, HistoryRow

_WHERE = {
    "evolve": "bstool.evolve.driver",
    "resume": "bstool.evolve.driver",
    "EvolveResult": "bstool.evolve.driver",
    "EvolveInterrupted": "bstool.evolve.driver",
    "Generation": "bstool.evolve.driver",
    "GAParams": "bstool.evolve.engine",
    "HistoryRow": "bstool.evolve.engine",
}

__all__ = [
    "EvolveInterrupted",
    "EvolveResult",
    "GAParams",
    "Generation",
    "HistoryRow",
    "evolve",
    "resume",
]


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'bstool.evolve' has no attribute {name!r}")
