"""The evolved controllers shipped with bstool (bstool/data/controllers/<model>.json, with the
history.csv of the run that made each): the built-in defaults of simulate, demo and the tests."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from bstool.errors import InputError

MODELS = ("nnsin", "nnsig", "ca1d", "ca2dsing", "ca2ddiff")
DEFAULT_MODEL = "nnsin"  # the paper's best traveller (§4.3)


def builtin_controller(model: str = DEFAULT_MODEL) -> Path:
    """Path of the shipped evolved controller of ``model``."""
    path = Path(str(resources.files("bstool") / "data" / "controllers" / f"{model}.json"))
    if model not in MODELS or not path.is_file():
        raise InputError(f"no built-in controller for {model!r}", hint=f"pick one of {MODELS}")
    return path


def builtin_history(model: str = DEFAULT_MODEL) -> Path:
    """The history.csv of the evolution run that produced the built-in controller."""
    return builtin_controller(model).with_suffix(".history.csv")
