"""The paper's five control models, their state sequences, chromosomes and controller file."""

from bstool.controllers.controller import (
    FORMAT,
    Controller,
    controller_hash,
    dumps_controller,
    from_json,
    load_controller,
    make_controller,
    save_controller,
)
from bstool.controllers.reference import CA_MODELS, MODELS, NN_MODELS, nn_next_state

__all__ = [
    "CA_MODELS",
    "FORMAT",
    "MODELS",
    "NN_MODELS",
    "Controller",
    "controller_hash",
    "dumps_controller",
    "from_json",
    "load_controller",
    "make_controller",
    "nn_next_state",
    "save_controller",
]
