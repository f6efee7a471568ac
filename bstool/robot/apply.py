"""Give a compiled MuJoCo model another robot's physics without writing or compiling MJCF.

A randomized evaluation runs the same geometry with other friction, masses and servo numbers
(docs/robot.md "Uncertain robot"). Compiling MJCF per sample costs ~20 ms and a model per
thread; writing the few fields that a :class:`RobotSpec`'s physics reach costs microseconds:

- friction: the sliding friction of every geom (a contact mixes both geoms' values, MuJoCo's
  default ``max``, so setting both bodies of every contact is setting all geoms);
- module and disc mass: each body's mass, and its inertia scaled with it (the shapes do not
  change), then ``mj_setConst`` recomputes what the compiler derives from them;
- servo torque, speed and band: the position actuator's gain and bias together (kp, −kp), its
  force range, and the joint damping (back-EMF slope = torque / no-load speed);
- servo armature: every hinge's armature.

Geometry, sizes, ``legs``/``modules``/``states`` and the timestep are not physics of a compiled
model: :func:`check_applicable` refuses a robot that changes them (build a model instead).
``tests/test_robot_apply.py`` checks that a model changed this way walks the same path as one
built from the spec.
"""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING

import numpy as np

from bstool.errors import InputError
from bstool.robot.mjcf import body_name
from bstool.robot.spec import RobotSpec

if TYPE_CHECKING:
    import mujoco

#: the RobotSpec fields :func:`apply_physics` writes into a compiled model
PHYSICS_FIELDS = (
    "friction",
    "servo_torque",
    "servo_speed",
    "servo_band",
    "servo_armature",
    "module_mass",
    "disc_mass",
)
#: fields that only the spec's own derived numbers read (not the model): free to differ
FREE_FIELDS = ("transition_margin",)


def check_applicable(base: RobotSpec, robot: RobotSpec) -> None:
    """Refuse a ``robot`` whose difference from ``base`` is more than physics."""
    changed = [
        f.name
        for f in fields(RobotSpec)
        if f.name not in PHYSICS_FIELDS
        and f.name not in FREE_FIELDS
        and getattr(base, f.name) != getattr(robot, f.name)
    ]
    if changed:
        raise InputError(
            f"{', '.join(changed)} cannot vary between samples of one robot: they change its "
            "geometry or size, not its physics",
            hint="give them one value in the robot file, outside [uncertain]",
        )


def apply_physics(
    model: mujoco.MjModel, robot: RobotSpec, *, base: RobotSpec, base_model: mujoco.MjModel
) -> None:
    """Write ``robot``'s physics into ``model``, a copy of ``base_model`` (compiled from
    ``base``; it is only read). Stateless: each call starts from ``base_model``'s masses and
    inertias, so applying robot after robot never drifts, and applying ``base`` restores it."""
    import mujoco

    check_applicable(base, robot)
    model.geom_friction[:, 0] = robot.friction
    disc = mujoco.mj_name2id(base_model, mujoco.mjtObj.mjOBJ_BODY, "disc")
    # the disc is n parts of disc_mass / n, summed as the compiler sums its geoms
    parts = [robot.disc_mass / base.legs] * base.legs
    masses = {disc: (sum(parts[1:], parts[0]), robot.disc_mass / base.disc_mass)}
    for i in range(base.legs):
        for j in range(base.modules):  # one capsule each: its mass is the body's
            body = mujoco.mj_name2id(base_model, mujoco.mjtObj.mjOBJ_BODY, body_name(i, j))
            masses[body] = (robot.module_mass, robot.module_mass / base.module_mass)
    for body, (mass, ratio) in masses.items():
        if ratio == 1.0:  # the compiled values, to the bit
            model.body_mass[body] = base_model.body_mass[body]
            model.body_inertia[body] = base_model.body_inertia[body]
        else:  # the same shapes: inertia scales with the mass
            model.body_mass[body] = mass
            model.body_inertia[body] = base_model.body_inertia[body] * ratio
    kp = robot.servo_kp
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 1] = -kp
    model.actuator_forcerange[:] = np.array([-robot.servo_torque, robot.servo_torque])
    hinges = base_model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
    dofs = base_model.jnt_dofadr[hinges]
    model.dof_damping[dofs] = robot.servo_damping
    model.dof_armature[dofs] = robot.servo_armature
    mujoco.mj_setConst(model, mujoco.MjData(model))
