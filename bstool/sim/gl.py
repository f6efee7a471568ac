"""Choosing MuJoCo's OpenGL backend before mujoco is imported (offscreen video, viewer).

MuJoCo reads MUJOCO_GL once, when ``mujoco`` is first imported. This module must not import
mujoco itself.
"""

from __future__ import annotations

import os
import sys


def has_display() -> bool:
    """True when an X11 or Wayland display is configured for this process."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def configure_headless_gl() -> str:
    """Select OSMesa (CPU rendering) unless a GL backend is already configured or a display
    exists. Returns the backend mujoco will use ("glfw" stands for the default)."""
    if "MUJOCO_GL" not in os.environ and not has_display():
        os.environ["MUJOCO_GL"] = "osmesa"
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
    return os.environ.get("MUJOCO_GL", "glfw") or "glfw"


def mujoco_already_imported() -> bool:
    return "mujoco" in sys.modules
