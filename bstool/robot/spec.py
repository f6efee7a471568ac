"""The robot description: size, geometry, masses, servo and physics, with documented defaults.

Every number is explained in docs/robot.md (source or reasoning). The MJCF model is generated
from this object only (bstool.robot.mjcf), so a spec fully determines the simulated robot.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any, Literal

from bstool.errors import InputError

ANGLE_MIN = -math.pi / 3
ANGLE_MAX = math.pi / 3


@dataclass(frozen=True)
class RobotSpec:
    """An n-legged brittle star robot of m one-hinge modules per leg, k states per module."""

    legs: int = 5  # n
    modules: int = 6  # m, module 0 = lead (at the disc)
    states: int = 16  # k

    # Axis of the lead module's hinge; the others alternate along the leg.
    lead_axis: Literal["vertical", "horizontal"] = "vertical"

    # Geometry (metres) and masses (kg).
    disc_radius: float = 0.080  # disc centre -> lead hinge
    disc_height: float = 0.045
    disc_mass: float = 0.400  # frame and hub 0.15 + the 6 V NiMH pack 0.25
    module_pitch: float = 0.075  # hinge to hinge along the leg
    module_length: float = 0.070  # the module's box (shorter than the pitch: 5 mm gap)
    module_width: float = 0.050
    module_height: float = 0.045
    module_mass: float = 0.090  # servo 0.040 + electronics 0.020 + bracket 0.030

    # Servo (Futaba S5301: standard-size analog servo, taken at 6 V from the NiMH pack).
    servo_torque: float = 0.40  # N·m, stall torque (4.1 kg·cm)
    servo_speed: float = 0.19  # s per 60° at no load
    servo_band: float = 0.10  # rad of error that gives full torque (proportional band)
    servo_armature: float = 0.002  # kg·m², motor rotor inertia reflected through the gears

    # Contact and physics.
    friction: float = 0.4  # sliding friction, aluminium/ABS on a hard floor
    timestep: float = 0.002  # s
    transition_margin: float = 1.25  # default transition time = margin × full-range travel time

    def __post_init__(self) -> None:
        problems = []
        if self.legs < 1:
            problems.append(f"legs must be >= 1 (got {self.legs})")
        if self.modules < 1:
            problems.append(f"modules must be >= 1 (got {self.modules})")
        if self.states < 2:
            problems.append(f"states must be >= 2 (got {self.states})")
        if self.lead_axis not in ("vertical", "horizontal"):
            problems.append(
                f"lead_axis must be 'vertical' or 'horizontal' (got {self.lead_axis!r})"
            )
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float) and not (math.isfinite(value) and value > 0):
                problems.append(f"{f.name} must be a positive number (got {value})")
        if problems:
            raise InputError("bad robot spec: " + "; ".join(problems))

    # Derived servo constants -------------------------------------------------------------
    @property
    def servo_no_load_speed(self) -> float:
        """rad/s: 60° in ``servo_speed`` seconds."""
        return (math.pi / 3) / self.servo_speed

    @property
    def servo_kp(self) -> float:
        """N·m/rad: full torque at ``servo_band`` of error, like an analog servo's P loop."""
        return self.servo_torque / self.servo_band

    @property
    def servo_damping(self) -> float:
        """N·m·s/rad: DC-motor back-EMF slope, so speed falls linearly to 0 at stall torque."""
        return self.servo_torque / self.servo_no_load_speed

    @property
    def transition_time(self) -> float:
        """Default seconds per transition: long enough to cross the full range [-π/3, π/3]."""
        full_range = (ANGLE_MAX - ANGLE_MIN) / self.servo_no_load_speed
        return self.transition_margin * full_range

    @property
    def actuators(self) -> int:
        return self.legs * self.modules

    def axis_of(self, module: int) -> Literal["vertical", "horizontal"]:
        """Hinge axis of module ``module`` (0 = lead): alternating, starting with lead_axis."""
        other: Literal["vertical", "horizontal"] = (
            "horizontal" if self.lead_axis == "vertical" else "vertical"
        )
        return self.lead_axis if module % 2 == 0 else other

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def state_to_angle(s: Any, k: int = 16) -> Any:
    """θ(s) = −π/3 + s·(2π/3)/(k−1) in radians; works on ints and numpy arrays alike."""
    return ANGLE_MIN + s * ((ANGLE_MAX - ANGLE_MIN) / (k - 1))
