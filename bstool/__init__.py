"""bstool: from evolved brittle-star controllers to code running on BS2sx modules.

The Python API is :mod:`bstool.api` (docs/api.md); its names are also reachable here, loaded on
first use so that ``import bstool`` stays cheap. ``evolve``, ``compile`` and ``flash`` are the
names of bstool's subpackages, so call them as ``bstool.api.evolve`` etc. (or
``bstool.evolve.evolve``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from bstool.version import __version__

if TYPE_CHECKING:
    from bstool import api
    from bstool.api import (
        EvolveInterrupted,
        EvolveResult,
        Generation,
        builtin_controller,
        evaluate,
        load_controller,
        load_states,
        resume,
        simulate,
        states,
        tokenize,
        tokenize_text,
    )

__all__ = [
    "EvolveInterrupted",
    "EvolveResult",
    "Generation",
    "__version__",
    "api",
    "builtin_controller",
    "evaluate",
    "load_controller",
    "load_states",
    "resume",
    "simulate",
    "states",
    "tokenize",
    "tokenize_text",
]


def __getattr__(name: str) -> Any:
    """``bstool.api`` and the API's names, imported on first use."""
    if name == "api" or name in __all__:
        api = importlib.import_module("bstool.api")
        return api if name == "api" else getattr(api, name)
    raise AttributeError(f"module 'bstool' has no attribute {name!r}")
