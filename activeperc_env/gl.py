"""Choose MuJoCo's OpenGL backend before ``mujoco`` is imported: EGL when no display exists."""

from __future__ import annotations

import ctypes.util
import os
import sys

EGL_HELP = (
    "activeperc renders headless through EGL, but libEGL was not found. Install it, e.g. "
    "'apt-get install libegl1 libgl1-mesa-dri' on Debian/Ubuntu, or set MUJOCO_GL to a "
    "backend that works on this machine (glfw with a display, osmesa)."
)


def choose_backend() -> None:
    """Set ``MUJOCO_GL=egl`` when it is unset and there is no display; fail clearly without EGL."""
    if os.environ.get("MUJOCO_GL") or sys.platform in ("darwin", "win32"):
        return
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    if ctypes.util.find_library("EGL") is None:
        raise ImportError(EGL_HELP)
    os.environ["MUJOCO_GL"] = "egl"
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def gl_context(width: int, height: int):
    """An offscreen GL context of the backend ``MUJOCO_GL`` names, whatever was imported first.

    ``mujoco`` binds ``mujoco.GLContext`` when it is imported; if that happened before
    :func:`choose_backend` ran, this still returns a context of the chosen backend.
    """
    backend = os.environ.get("MUJOCO_GL", "").lower()
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco import GLContext
    return GLContext(width, height)
