"""Offscreen MP4 of a run: physics exactly as Simulator.run, a frame every 1/fps seconds.

Call :func:`bstool.sim.gl.configure_headless_gl` before mujoco is first imported (the
``simulate`` command does); here a missing GL context becomes a clear error.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from bstool import fileio, outputs
from bstool.errors import InputError
from bstool.sim.simulator import SimResult, Simulator

#: scratch folders are named with the writer's pid, so the next run removes a killed run's
SCRATCH_PREFIX = "bstool-video-"
FPS = 25  # 40 ms per frame = 20 steps of 2 ms: frames fall exactly on physics steps
WIDTH, HEIGHT = 480, 272  # multiples of 16 for H.264


class VideoRecorder:
    """Offscreen frames of a MuJoCo model into an H.264 MP4, written atomically on success.

    >>> with VideoRecorder(model, "run.mp4") as rec:   # doctest: +SKIP
    ...     rec.frame(data)                            # once per 1/fps seconds of physics
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        path: str | os.PathLike[str],
        fps: int = FPS,
        size: tuple[int, int] = (WIDTH, HEIGHT),
    ) -> None:
        import imageio_ffmpeg

        self.path = path
        self.fps = fps
        self.frames = 0
        width, height = size
        try:
            self.renderer = mujoco.Renderer(model, height, width)
        except Exception as exc:  # GL context creation fails without a display or OSMesa
            raise InputError(
                f"cannot render offscreen: {exc}",
                hint="install libosmesa6 and set MUJOCO_GL=osmesa (bstool does this itself when "
                "no display is configured and mujoco is not yet imported)",
            ) from None
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance = 1.3
        self.camera.elevation = -35.0
        self.camera.azimuth = 90.0
        self.disc = model.body("disc").id
        # ffmpeg needs a file name: encode into a private temporary directory, then write the
        # target atomically with fileio (videos are a few MB).
        clean_stale_scratch()
        self._tmp = tempfile.TemporaryDirectory(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-")
        self._scratch = Path(self._tmp.name) / "run.mp4"
        self._writer = imageio_ffmpeg.write_frames(
            str(self._scratch),
            (width, height),
            fps=fps,
            codec="libx264",
            quality=7,
            macro_block_size=16,
            ffmpeg_log_level="error",
            output_params=["-movflags", "+faststart"],
        )
        self._writer.send(None)

    def steps_per_frame(self, model: mujoco.MjModel) -> int:
        return max(1, round(1.0 / (self.fps * model.opt.timestep)))

    def frame(self, data: mujoco.MjData) -> None:
        """Render the scene as it is in ``data``, the camera following the disc."""
        self.camera.lookat[:] = data.xpos[self.disc]
        self.renderer.update_scene(data, self.camera)
        self._writer.send(np.ascontiguousarray(self.renderer.render()))
        self.frames += 1

    def close(self, keep: bool = True) -> None:
        """Finish the file; write it to ``path`` only if ``keep`` (nothing half-written)."""
        try:
            self._writer.close()
            if keep:
                fileio.write_bytes(self.path, self._scratch.read_bytes())
        finally:
            self.renderer.close()
            self._tmp.cleanup()

    def __enter__(self) -> VideoRecorder:
        return self

    def __exit__(self, exc_type: object, *rest: object) -> None:
        self.close(keep=exc_type is None)


def clean_stale_scratch(folder: str | os.PathLike[str] | None = None) -> list[Path]:
    """Remove the scratch folders that killed video writers left in the temp folder."""
    root = Path(folder if folder is not None else tempfile.gettempdir())
    pattern = re.compile(rf"^{re.escape(SCRATCH_PREFIX)}(\d+)-")
    removed = []
    for entry in root.iterdir() if root.is_dir() else ():
        m = pattern.match(entry.name)
        if (
            m
            and entry.is_dir()
            and not entry.is_symlink()
            and not outputs.process_alive(int(m.group(1)))
        ):
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    return removed


def render_video(
    sim: Simulator,
    states: np.ndarray,
    path: str | os.PathLike[str],
    fps: int = FPS,
    size: tuple[int, int] = (WIDTH, HEIGHT),
    progress: Callable[[int], None] | None = None,
) -> SimResult:
    """Run ``states`` (validated) and write an H.264 MP4; returns the run's result."""
    data = mujoco.MjData(sim.model)
    with VideoRecorder(sim.model, path, fps, size) as rec:

        def frame(d: mujoco.MjData) -> None:
            rec.frame(d)
            if progress:
                progress(1)

        return sim.run_validated(
            states, data, on_chunk=frame, chunk_steps=rec.steps_per_frame(sim.model)
        )


def frame_count(sim: Simulator, transitions: int, fps: int = FPS) -> int:
    chunk = max(1, round(1.0 / (fps * sim.model.opt.timestep)))
    return sim.steps_for(transitions) // chunk
