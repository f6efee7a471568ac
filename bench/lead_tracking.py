"""How well each module follows its servo target: the leads against the other modules, on the
nominal robot and on the stickiest, weakest corner of the default box (friction 1.0, servo
torque x0.7), plain physics, 30 transitions. Behind docs/results.md's reading of why no NN gait
keeps its distance there: an NN lead must follow eq. 10's fixed cycle (S_0 + 1 mod 16), which
evolution cannot change.

Printed per gait and robot: the disc's distance; the leads' and the other modules' mean
|target - angle| at the end of each transition (degrees); and the leads' travel, the mean over
the 5 leads of (the range of angles reached) / (the range commanded).

Usage: python bench/lead_tracking.py [C.json ...]   (default: the five shipped gaits)
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import mujoco
import numpy as np

from bstool.builtin import builtin_controller
from bstool.controllers import load_controller
from bstool.robot import RobotSpec
from bstool.sim.simulator import Simulator

MODELS = ("nnsin", "nnsig", "ca1d", "ca2dsing", "ca2ddiff")
TRANSITIONS = 30


def tracking(sim: Simulator, states: np.ndarray) -> dict[str, float]:
    """Distance, tracking errors and the leads' travel of one run."""
    model, data = sim.model, mujoco.MjData(sim.model)
    # a sample at every transition's end needs the settle to be whole transitions
    assert sim.settle_steps % sim.steps_per_transition == 0
    # actuator k drives joint trnid[k, 0]; its angle is qpos[jnt_qposadr[joint]]
    qadr = model.jnt_qposadr[model.actuator_trnid[:, 0]]
    seen: list[np.ndarray] = []
    result = sim.run_validated(
        states, data, on_chunk=lambda d: seen.append(d.qpos[qadr].copy()),
        chunk_steps=sim.steps_per_transition,
    )  # fmt: skip
    # the settle's samples first, then one at the end of each transition: keep those
    angles = np.array(seen[-(len(states) - 1) :])
    targets = sim.angles(states)[1:]
    err = np.degrees(np.abs(targets - angles))
    modules = sim.spec.modules
    lead = np.zeros(targets.shape[1], dtype=bool)
    lead[::modules] = True  # leg-major, lead first
    commanded = np.ptp(targets[:, lead], axis=0)
    reached = np.ptp(angles[:, lead], axis=0)
    moved = commanded > 0  # a lead commanded to stay has no fraction to give
    travel = reached[moved] / commanded[moved]
    return {
        "distance": result.distance * 100,
        "lead_err": float(err[:, lead].mean()),
        "other_err": float(err[:, ~lead].mean()),
        "lead_travel": float(travel.mean()) if travel.size else float("nan"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("controllers", nargs="*", type=Path)
    args = ap.parse_args()
    paths = args.controllers or [builtin_controller(m) for m in MODELS]
    nominal = RobotSpec()
    corner = dataclasses.replace(nominal, friction=1.0, servo_torque=nominal.servo_torque * 0.7)
    sims = {"nominal": Simulator(nominal), "friction 1.0, torque x0.7": Simulator(corner)}
    print(f"{'gait':<24}{'robot':<28}{'cm':>7}{'lead err':>10}{'other err':>11}{'lead travel':>13}")
    for path in paths:
        ctrl = load_controller(path)
        states = ctrl.states(TRANSITIONS)
        name = f"{ctrl.model} ({Path(path).parent.name})"
        for robot, sim in sims.items():
            t = tracking(sim, states)
            print(
                f"{name:<24}{robot:<28}{t['distance']:7.1f}{t['lead_err']:9.1f}°"
                f"{t['other_err']:10.1f}°{t['lead_travel']:12.0%}"
            )


if __name__ == "__main__":
    main()
