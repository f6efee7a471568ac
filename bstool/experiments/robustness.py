"""The reality gap in simulation: how much a controller's distance depends on luck.

Contact-rich locomotion is chaotic. Two runs that are physically the same experiment — the gait
shifted by one leg (the model is n-fold symmetric), or a start perturbed far below anything
measurable — can end tens of percent apart after 30 transitions. These functions measure that
spread for a controller.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from bstool.controllers import Controller
from bstool.experiments.mobility import Evaluate
from bstool.experiments.rotation import rotate_controller
from bstool.robot import RobotSpec
from bstool.sim.simulator import Simulator

PERTURBATION_RAD = 1e-6  # joint-angle noise at the start: far below any servo's resolution


@dataclass(frozen=True)
class Spread:
    distances: tuple[float, ...]

    @property
    def mean(self) -> float:
        return float(np.mean(self.distances))

    @property
    def min(self) -> float:
        return float(np.min(self.distances))

    @property
    def max(self) -> float:
        return float(np.max(self.distances))

    @property
    def relative_range(self) -> float:
        """(max − min) / mean: 0 for a perfectly repeatable controller."""
        return (self.max - self.min) / self.mean if self.mean > 0 else 0.0

    def to_json(self) -> dict[str, object]:
        return {
            "distances": list(self.distances),
            "mean": self.mean,
            "min": self.min,
            "max": self.max,
            "relative_range": self.relative_range,
        }


def rotation_spread(controller: Controller, evaluate: Evaluate, transitions: int) -> Spread:
    """Distance of the same gait run from each of the n legs (rotation 0..n−1)."""
    sequences = [
        rotate_controller(controller, r).states(transitions) for r in range(controller.legs)
    ]
    return Spread(tuple(evaluate(sequences)))


class PerturbedSimulator(Simulator):
    """A simulator whose every run starts with the joint angles nudged by tiny random noise
    (seeded; a new draw per run)."""

    def __init__(
        self, spec: RobotSpec | None = None, scale: float = PERTURBATION_RAD, seed: int = 0
    ) -> None:
        super().__init__(spec)
        self.scale = scale
        self.rng = np.random.default_rng(seed)

    def reset(self, data: mujoco.MjData, model: mujoco.MjModel | None = None) -> None:
        model = self.model if model is None else model
        super().reset(data, model)
        hinges = slice(7, model.nq)  # after the disc's free joint (3 position + 4 quat)
        data.qpos[hinges] += self.rng.normal(0.0, self.scale, model.nq - 7)
        mujoco.mj_forward(model, data)


def perturbation_spread(
    controller: Controller,
    spec: RobotSpec,
    transitions: int,
    samples: int = 5,
    seed: int = 0,
    scale: float = PERTURBATION_RAD,
) -> Spread:
    """Distance over ``samples`` runs from starts perturbed by ``scale`` radians (plus the
    unperturbed run first)."""
    states = controller.states(transitions)
    plain = Simulator(spec).run(states).distance
    sim = PerturbedSimulator(spec, scale, seed)
    return Spread((plain, *(sim.run(states).distance for _ in range(samples))))
