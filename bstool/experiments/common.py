"""What the experiment commands share: loading a controller with its robot, and an evaluator."""

from __future__ import annotations

from dataclasses import dataclass

from bstool.controllers import Controller, load_controller
from bstool.robot import RobotSpec


@dataclass
class Loaded:
    path: str
    controller: Controller
    spec: RobotSpec

    @property
    def name(self) -> str:
        from pathlib import Path

        p = Path(self.path)
        return p.parent.name if p.name == "best.json" else p.stem


def load(path: str) -> Loaded:
    controller = load_controller(path)
    spec = RobotSpec(legs=controller.legs, modules=controller.modules, states=controller.k)
    return Loaded(path, controller, spec)


def default_transitions(controller: Controller, given: int | None) -> int:
    """-T if given, else the controller's MAX_TRANS, else the paper's 30."""
    if given is not None:
        return given
    return controller.max_trans or 30
