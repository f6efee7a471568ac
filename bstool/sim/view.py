"""MuJoCo's interactive viewer, playing a run in real time (needs a display)."""

from __future__ import annotations

import time

import mujoco
import numpy as np

from bstool.errors import InputError
from bstool.sim.gl import has_display
from bstool.sim.simulator import Simulator


def require_display() -> None:
    if not has_display():
        raise InputError(
            "--view needs a display, but none is configured (DISPLAY and WAYLAND_DISPLAY are"
            " not set)",
            hint="render offscreen instead with --video FILE.mp4, or run where a display exists",
        )
    _check_glfw()


def view_run(sim: Simulator, states: np.ndarray) -> None:
    """Open the passive viewer and play ``states``; returns when the window is closed."""
    import mujoco.viewer

    require_display()
    data = mujoco.MjData(sim.model)
    chunk = max(1, round(1 / (60 * sim.model.opt.timestep)))  # ~60 redraws per second
    try:
        viewer = mujoco.viewer.launch_passive(sim.model, data)
    except Exception as exc:
        raise InputError(
            f"cannot open the MuJoCo viewer: {exc}", hint="use --video FILE.mp4 instead"
        ) from None
    with viewer:
        start = time.perf_counter()

        def sync(d: mujoco.MjData) -> None:
            if not viewer.is_running():
                raise _Closed
            ahead = d.time - (time.perf_counter() - start)
            if ahead > 0:
                time.sleep(ahead)
            viewer.sync()

        try:
            sim.run_validated(states, data, on_chunk=sync, chunk_steps=chunk)
        except _Closed:
            return
        while viewer.is_running():
            time.sleep(0.05)


def _check_glfw() -> None:
    """The viewer exits the process when GLFW cannot start: find out first, quietly."""
    import os
    import warnings

    try:
        import glfw

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ok = bool(glfw.init())
    except Exception:
        ok = False
    if not ok:
        where = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        raise InputError(
            f"--view cannot open the display {where!r} (GLFW failed to initialise)",
            hint="check the display (X forwarding, xhost), or render with --video FILE.mp4",
        )


class _Closed(Exception):
    """The user closed the viewer window."""
