"""When each module's servo moves: a build run on the twin without physics, recorded.

:func:`extract_schedule` runs every module's program on the twin's interpreter, its timing
model and link protocol, exactly as ``bstool twin`` does (power-up and join, the serve loop, rule
look-ups, RUN dispatch, one servo pulse every ~23 ms), but without MuJoCo. At every 10 ms chunk
it records what the twin would apply to each actuator (:meth:`hil_mock.body.Body._servo_drive`:
the last pulse's target, or limp after 60 ms without one), and the instant of each path point
(the chunk in which the reference module started transition t + 1). The result is a
:class:`bstool.sim.timed.StampSchedule`; ``Simulator.run_schedule`` plays it and reproduces the
twin's path to the bit (the same physics, fed the same controls at the same steps).
Nothing here knows the protocol's timing: it is whatever the build's programs do.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from bstool.buildfile import Build
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.sim.timed import BuildSchedule, StampSchedule
from bstool.timingfile import TimingModel
from hil_mock.body import ServoTrack, robot_spec
from hil_mock.perturb import Perturbation
from hil_mock.robot import RobotTwin
from hil_mock.twin_result import NS, TwinResult

if TYPE_CHECKING:
    from bstool.sim.simulator import SimResult, Simulator


class Recorder(RobotTwin):
    """A twin that writes down the servo commands it applies (``physics=False``: without
    MuJoCo, the default here)."""

    def __init__(self, build: Build, *, physics: bool = False, **kwargs: Any) -> None:
        self.events: list[tuple[float, int, float]] = []
        self.samples: list[float] = []
        self._applied: dict[int, float] = {}
        self._seen = 1  # the reference's first record is R^0, not a path point
        super().__init__(build, physics=physics, **kwargs)

    def _drive_hook(self, drive: list[tuple[ServoTrack, bool]]) -> None:
        t = self.t_ns / NS
        for servo, limp in drive:
            command = math.nan if limp else servo.target
            before = self._applied.get(servo.actuator)
            if before is None or not _same(before, command):
                self._applied[servo.actuator] = command
                self.events.append((t, servo.actuator, command))
        if self.reference is not None:
            n = len(self.records[self.reference].states)
            while self._seen < n:
                self.samples.append(t)
                self._seen += 1

    def schedule(self, transitions: int) -> StampSchedule:
        """The recorded schedule up to path point ``transitions`` (the run must have reached
        the reference's transition T + 1)."""
        samples = self.samples[: transitions + 1]
        if not samples:
            raise InputError(
                f"{self.build.root}: the twin made no transition, so there is no path",
                hint="run `bstool twin` on the build to see which module stalled",
            )
        end = samples[-1]  # the playback needs nothing after the last sample
        events = [e for e in self.events if e[0] <= end]
        return StampSchedule.from_events(
            events, samples=samples, actuator_count=self.build.legs * self.build.modules
        )


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


def extract_schedule(
    build: Build,
    transitions: int,
    *,
    failed: Iterable[ModuleId | str] = (),
    die: Mapping[ModuleId, int] | None = None,
    limp_failed: bool = False,
    cut: Iterable[tuple[ModuleId, ModuleId]] = (),
    noise: float = 0.0,
    seed: int = 0,
    perturb: Perturbation | None = None,
    timeout_s: float | None = None,
    timing: TimingModel | None = None,
) -> tuple[StampSchedule, TwinResult]:
    """The schedule of ``transitions`` transitions of ``build`` (and what the twin observed:
    states, periods). The options are :class:`~hil_mock.robot.RobotTwin`'s; with the same
    options the twin's physics run sees exactly these commands."""
    if transitions < 1:
        raise InputError(f"transitions must be >= 1, got {transitions}")
    twin = Recorder(
        build,
        failed=failed,
        die=die,
        limp_failed=limp_failed,
        cut=cut,
        noise=noise,
        seed=seed,
        perturb=perturb,
        timing=timing,
    )
    # one more: path[T] is taken when the reference starts transition T + 1
    result = twin.run(transitions + 1, timeout_s=timeout_s)
    schedule = twin.schedule(transitions)
    return schedule, result


def build_schedule(build: Build, states: Any) -> BuildSchedule:
    """``build``'s own schedule for ``states`` (its controller's, ``len(states) - 1``
    transitions), as a schedule source: what ``bstool sensitivity BUILD`` plays on each robot."""
    schedule, _ = extract_schedule(build, len(states) - 1)
    return BuildSchedule(schedule, states)


def stamp_timed_simulator(build: Build) -> Simulator:
    """The MuJoCo robot of ``build`` (the twin's own: same spec, same physics)."""
    from bstool.sim.simulator import Simulator

    return Simulator(robot_spec(build))


def simulate_build(
    build: Build, transitions: int, **options: Any
) -> tuple[SimResult, StampSchedule, TwinResult]:
    """``bstool simulate --build``: the build's schedule (:func:`extract_schedule`, same
    ``options``) played by the simulator; the path, the schedule and the twin's record."""
    schedule, result = extract_schedule(build, transitions, **options)
    return stamp_timed_simulator(build).run_schedule(schedule), schedule, result
