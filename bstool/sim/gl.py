"""Choosing MuJoCo's OpenGL backend before mujoco is imported (offscreen video, viewer).

MuJoCo reads MUJOCO_GL once, when ``mujoco`` is first imported. This module must not import
mujoco itself.
"""

from __future__ import annotations

import ctypes.util
import os
import sys

from bstool.errors import InputError


def has_display() -> bool:
    """True when an X11 or Wayland display is configured for this process."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def osmesa_present() -> bool:
    """The OSMesa library can be found (by name, or loaded where no ldconfig can list it)."""
    if ctypes.util.find_library("OSMesa") is not None:
        return True
    for name in ("libOSMesa.so", "libOSMesa.so.8", "libOSMesa.so.6"):
        try:
            ctypes.CDLL(name)
        except OSError:
            continue
        return True
    return False


def configure_headless_gl() -> str:
    """Select OSMesa (CPU rendering) unless a GL backend is already configured or a display
    exists. Returns the backend mujoco will use ("glfw" stands for the default)."""
    if "MUJOCO_GL" not in os.environ and not has_display():
        if not osmesa_present():  # else a ctypes traceback from PyOpenGL
            raise InputError(
                "offscreen rendering needs the OSMesa library (libOSMesa), which is not "
                "installed, and there is no display",
                hint="install it (Debian/Ubuntu: apt-get install libosmesa6), or set "
                "MUJOCO_GL=egl where EGL works",
            )
        os.environ["MUJOCO_GL"] = "osmesa"
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
    return os.environ.get("MUJOCO_GL", "glfw") or "glfw"


def mujoco_already_imported() -> bool:
    return "mujoco" in sys.modules
