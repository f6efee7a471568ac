"""One run of a state sequence on the MuJoCo robot.

Run protocol (docs/robot.md): reset the data completely, set every servo target to R^0 and let
the robot settle for ``settle_time`` (from the flat pose); path[0] is the disc centre then.
Transition t = 1..T: set all targets to R^t's angles, step physics for ``transition_time``,
record the disc centre. Stepping uses ``mj_step(nstep=...)``, so Python runs once per
transition, not per physics step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from bstool.errors import InputError
from bstool.robot import RobotSpec, build_model, state_to_angle
from bstool.sim.states import validate_states
from bstool.sim.timed import PowerUpCache, StampSchedule, run_schedule


@dataclass(frozen=True, eq=False)
class SimResult:
    """Disc-centre path per transition (metres), displacement and distance (paper eq. 6)."""

    path: np.ndarray  # (T+1, 2)

    @property
    def displacement(self) -> tuple[float, float]:
        d = self.path[-1] - self.path[0]
        return float(d[0]), float(d[1])

    @property
    def distance(self) -> float:
        dx, dy = self.displacement
        return math.hypot(dx, dy)

    @property
    def transitions(self) -> int:
        return len(self.path) - 1

    def to_json(self) -> dict[str, Any]:
        return {
            "displacement": list(self.displacement),
            "distance": self.distance,
            "path": self.path.tolist(),
        }


class Simulator:
    """Plays state sequences on one robot model; one MjData, reset fully before each run.

    ``run`` uses the simulator's own MjData: one thread at a time. For parallel runs use
    ``bstool.sim.batch.BatchEvaluator`` (or ``run_validated`` with an MjData per thread).
    """

    def __init__(
        self,
        spec: RobotSpec | None = None,
        transition_time: float | None = None,
        settle_time: float | None = None,
    ) -> None:
        self.spec = spec or RobotSpec()
        self.transition_time = _positive(
            self.spec.transition_time if transition_time is None else transition_time,
            "transition time",
        )
        self.settle_time = _positive(
            self.transition_time if settle_time is None else settle_time, "settle time"
        )
        self.model = build_model(self.spec)
        self.data = mujoco.MjData(self.model)
        dt = self.model.opt.timestep
        self.steps_per_transition = max(1, round(self.transition_time / dt))
        self.settle_steps = max(1, round(self.settle_time / dt))
        self.angle_table = state_to_angle(np.arange(self.spec.states), self.spec.states)
        self._xy = slice(0, 2)  # the disc's free joint comes first in qpos

    def angles(self, states: np.ndarray) -> np.ndarray:
        """(T+1, n·m) servo targets in actuator order (leg-major, lead first)."""
        return np.ascontiguousarray(self.angle_table[states].reshape(len(states), -1))

    def run(self, states: Any) -> SimResult:
        """Play R^0..R^T (validated) and return the disc path."""
        return self.run_validated(validate_states(states, self.spec), self.data)

    def run_validated(
        self,
        states: np.ndarray,
        data: mujoco.MjData,
        on_chunk: Callable[[mujoco.MjData], None] | None = None,
        chunk_steps: int | None = None,
        *,
        model: mujoco.MjModel | None = None,
    ) -> SimResult:
        """Run on ``data`` (own MjData per thread). ``on_chunk`` is called every
        ``chunk_steps`` steps (video frames); physics is identical either way. ``model``: a
        copy of the simulator's model with another robot's physics (``bstool.robot.apply``);
        the step counts stay this simulator's (a robot's servo speed never changes the
        controller's period)."""
        model = self.model if model is None else model
        targets = self.angles(states)
        path = np.empty((len(states), 2))
        self.reset(data, model)
        step = _stepper(model, data, on_chunk, chunk_steps)
        data.ctrl[:] = targets[0]
        step(self.settle_steps)
        path[0] = data.qpos[self._xy]
        for t in range(1, len(states)):
            data.ctrl[:] = targets[t]
            step(self.steps_per_transition)
            path[t] = data.qpos[self._xy]
        return SimResult(path)

    def run_schedule(
        self,
        schedule: StampSchedule,
        data: mujoco.MjData | None = None,
        *,
        model: mujoco.MjModel | None = None,
        cache: PowerUpCache | None = None,
    ) -> SimResult:
        """Play timed servo commands (``bstool.sim.timed``: each module's targets at the
        instants its stamp sets them) instead of states; the path at the schedule's samples.
        ``model``/``data``: a worker thread's own (the model's gains change while limp);
        ``cache``: power-ups already simulated (the same path, fewer steps)."""
        return SimResult(
            run_schedule(self.model if model is None else model,
                         self.data if data is None else data, schedule, cache)
        )  # fmt: skip

    def reset(self, data: mujoco.MjData, model: mujoco.MjModel | None = None) -> None:
        """Back to the model's initial state: time, qpos, qvel, warm start, ctrl all cleared
        (``model``: a copy with another robot's physics; default the simulator's own)."""
        mujoco.mj_resetData(self.model if model is None else model, data)

    def steps_for(self, transitions: int) -> int:
        return self.settle_steps + transitions * self.steps_per_transition


def _stepper(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    on_chunk: Callable[[mujoco.MjData], None] | None,
    chunk_steps: int | None,
) -> Callable[[int], None]:
    if on_chunk is None or not chunk_steps:

        def step(n: int) -> None:
            mujoco.mj_step(model, data, nstep=n)

        return step

    pending = [0]  # steps since the last callback, carried across transitions

    def step_chunked(n: int) -> None:
        assert chunk_steps is not None and on_chunk is not None
        while n > 0:
            k = min(n, chunk_steps - pending[0])
            mujoco.mj_step(model, data, nstep=k)
            n -= k
            pending[0] += k
            if pending[0] == chunk_steps:
                pending[0] = 0
                on_chunk(data)

    return step_chunked


def _positive(value: float, what: str) -> float:
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{what} must be a positive number of seconds (got {value})")
    return float(value)
