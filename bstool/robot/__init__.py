"""The brittle star robot: its description, the state→angle map, and its generated MJCF."""

from bstool.robot.mjcf import body_name, build_model, to_mjcf
from bstool.robot.spec import ANGLE_MAX, ANGLE_MIN, RobotSpec, state_to_angle

__all__ = [
    "ANGLE_MAX",
    "ANGLE_MIN",
    "RobotSpec",
    "body_name",
    "build_model",
    "state_to_angle",
    "to_mjcf",
]
