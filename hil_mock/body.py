"""The twin's body: each module's servo as a MuJoCo actuator of ``bstool simulate``'s robot.

A PULSOUT on the servo pin sets its target angle through the module's calibration (the inverse
of the build's state → pulse table). A servo that gets no pulse for :data:`LIMP_AFTER_S` goes
limp (no torque) until the next pulse.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bstool.buildfile import Build, Module
from bstool.moduleid import ModuleId
from hil_mock.stamp import Stamp
from hil_mock.twin_result import NS


def robot_spec(build: Build) -> RobotSpec:
    """The robot a build was compiled for: the robot file's values it recorded
    (``robot_values``), else the manifest's size with the default physics."""
    from bstool.robot import RobotSpec
    from bstool.robot.robotfile import from_record

    if build.manifest.robot_values is not None:
        return from_record(build.manifest.robot_values, str(build.root)).spec
    robot = build.manifest.robot
    return RobotSpec(legs=robot.legs, modules=robot.modules, states=robot.states)


def with_robot(build: Build, robot: Robot) -> Build:
    """``build`` run on another robot (``bstool twin --robot``): its programs, that robot's
    physics (and timestep) for the twin and the reference simulators."""
    import dataclasses

    manifest = dataclasses.replace(build.manifest, robot_values=robot.to_json())
    return dataclasses.replace(build, manifest=manifest)


if TYPE_CHECKING:
    from bstool.robot import RobotSpec
    from bstool.robot.robotfile import Robot
    from bstool.sim.simulator import Simulator

LIMP_AFTER_S = 0.06
"""An analog hobby servo holds its position for a frame or two after the last pulse, then stops
driving; 60 ms (3 frames of 20 ms) is the threshold used here."""


@dataclass
class ServoTrack:
    """One module's servo as the twin sees it."""

    actuator: int
    pin: int
    widths: np.ndarray  # PULSOUT units, sorted ascending
    angles: np.ndarray  # radians for those widths
    target: float
    last_pulse_ns: int = -(10**15)
    longest_gap_ns: int = 0
    pulses: int = 0
    limp: bool = False
    # its own module lost power since its last pulse (--reset): the next gap is an outage
    powered_off: bool = False
    longest_outage_ns: int = 0  # the longest time without pulses across its own power-offs

    def angle_of(self, units: int) -> float:
        return float(np.interp(units, self.widths, self.angles))


class Body:
    """The physics half of :class:`hil_mock.robot.RobotTwin` (a mixin: it shares its state)."""

    build: Build
    sim: Simulator | None
    dt_ns: int
    t_ns: int
    servos: dict[ModuleId, ServoTrack]
    stamps: dict[ModuleId, Stamp]
    _gain: Any
    _bias: Any

    def _init_physics(self, physics: bool) -> None:
        self.sim = None
        if not physics:  # the robot's step still sets the chunk the stamps run in
            self.dt_ns = round(robot_spec(self.build).timestep * NS)
            return
        from bstool.sim.simulator import Simulator

        self.sim = Simulator(robot_spec(self.build))
        self.sim.reset(self.sim.data)
        self.dt_ns = round(self.sim.model.opt.timestep * NS)
        self._gain = self.sim.model.actuator_gainprm.copy()
        self._bias = self.sim.model.actuator_biasprm.copy()

    def _servo(self, mid: ModuleId, info: Module) -> ServoTrack:
        from bstool.robot import state_to_angle

        widths = np.array(info.servo.pulsout, dtype=float)
        k = len(widths)
        angles = np.array([state_to_angle(s, k) for s in range(k)])
        order = np.argsort(widths, kind="stable")
        servo_pin = info.servo_pin
        r0 = int(info.initial_state)
        actuator = mid.leg * self.build.modules + mid.module
        return ServoTrack(actuator, servo_pin, widths[order], angles[order], float(angles[r0]))

    def _servo_drive(self) -> list[tuple[ServoTrack, bool]]:
        """Every servo with whether it is limp in the chunk starting now (no pulse for more
        than :data:`LIMP_AFTER_S`; failed, dead or unpowered modules keep their own flag).
        What :meth:`_apply_servos` applies, and what ``hil_mock.schedule_extract`` records."""
        limp_after = int(LIMP_AFTER_S * NS)
        out = []
        for mid, servo in self.servos.items():
            if mid in self.stamps:
                servo.limp = self.t_ns - servo.last_pulse_ns > limp_after
            out.append((servo, servo.limp))
        return out

    def _drive_hook(self, drive: list[tuple[ServoTrack, bool]]) -> None:
        """Called with every chunk's drive before it is applied (``schedule_extract``)."""

    def _apply_servos(self) -> None:
        drive = self._servo_drive()
        self._drive_hook(drive)
        if self.sim is None:
            return
        model, data = self.sim.model, self.sim.data
        for servo, limp in drive:
            a = servo.actuator
            if limp:
                model.actuator_gainprm[a] = 0.0
                model.actuator_biasprm[a] = 0.0
            else:
                model.actuator_gainprm[a] = self._gain[a]
                model.actuator_biasprm[a] = self._bias[a]
                data.ctrl[a] = servo.target

    def _disc_xy(self) -> tuple[float, float]:
        assert self.sim is not None
        q = self.sim.data.qpos
        return (float(q[0]), float(q[1]))
