"""Offscreen MP4 of a run: physics exactly as Simulator.run, a frame every 1/fps seconds.

Call :func:`bstool.sim.gl.configure_headless_gl` before mujoco is first imported (the
``simulate`` command does); here a missing GL context becomes a clear error.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from bstool import fileio
from bstool.errors import InputError
from bstool.sim.simulator import SimResult, Simulator

FPS = 25  # 40 ms per frame = 20 steps of 2 ms: frames fall exactly on physics steps
WIDTH, HEIGHT = 480, 272  # multiples of 16 for H.264


def render_video(
    sim: Simulator,
    states: np.ndarray,
    path: str | os.PathLike[str],
    fps: int = FPS,
    size: tuple[int, int] = (WIDTH, HEIGHT),
    progress: Callable[[int], None] | None = None,
) -> SimResult:
    """Run ``states`` (validated) and write an H.264 MP4; returns the run's result."""
    import imageio_ffmpeg

    width, height = size
    model = sim.model
    data = mujoco.MjData(model)
    chunk = max(1, round(1.0 / (fps * model.opt.timestep)))
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as exc:  # GL context creation fails without a display or OSMesa
        raise InputError(
            f"cannot render offscreen: {exc}",
            hint="install libosmesa6 and set MUJOCO_GL=osmesa (bstool does this itself when "
            "no display is configured and mujoco is not yet imported)",
        ) from None
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance = 1.3
    camera.elevation = -35.0
    camera.azimuth = 90.0
    disc = model.body("disc").id

    # ffmpeg needs a file name: encode into a private temporary directory, then write the
    # target atomically with fileio (videos are a few MB).
    try:
        with tempfile.TemporaryDirectory(prefix="bstool-video-") as tmp:
            scratch = Path(tmp) / "run.mp4"
            writer = imageio_ffmpeg.write_frames(
                str(scratch),
                (width, height),
                fps=fps,
                codec="libx264",
                quality=7,
                macro_block_size=16,
                ffmpeg_log_level="error",
                output_params=["-movflags", "+faststart"],
            )
            writer.send(None)

            def frame(d: mujoco.MjData) -> None:
                camera.lookat[:] = d.xpos[disc]
                renderer.update_scene(d, camera)
                writer.send(np.ascontiguousarray(renderer.render()))
                if progress:
                    progress(1)

            try:
                result = sim.run_validated(states, data, on_chunk=frame, chunk_steps=chunk)
            finally:
                writer.close()
            fileio.write_bytes(path, scratch.read_bytes())
    finally:
        renderer.close()
    return result


def frame_count(sim: Simulator, transitions: int, fps: int = FPS) -> int:
    chunk = max(1, round(1.0 / (fps * sim.model.opt.timestep)))
    return sim.steps_for(transitions) // chunk
