"""Choose MuJoCo's OpenGL backend before ``mujoco`` is imported: EGL when no usable display exists."""

from __future__ import annotations

import ctypes.util
import os
import sys
import warnings

FORK_HELP = (
    "this process was forked from one that had already rendered, and the GL driver's state does not survive a "
    "fork: making a GL context here would hang. Start the process with the 'spawn' method instead, e.g. "
    "multiprocessing.get_context('spawn'), or for Gymnasium's async vector env "
    "gymnasium.make_vec(..., vectorization_mode='async', vector_kwargs={'context': 'spawn'}), or for "
    "Stable-Baselines3 SubprocVecEnv(..., start_method='spawn')."
)
EGL_HELP = (
    "activeperc renders headless through EGL, but libEGL was not found. Install it, e.g. "
    "'apt-get install libegl1 libgl1-mesa-dri' on Debian/Ubuntu, or set MUJOCO_GL to a "
    "backend that works on this machine (glfw with a display, osmesa)."
)
OSMESA_HELP = (
    "MUJOCO_GL=osmesa renders through Mesa's OSMesa, but libOSMesa was not found. Install it, e.g. "
    "'apt-get install libosmesa6' on Debian/Ubuntu, or use MUJOCO_GL=egl (faster)."
)
MESA_DRIVER_HELP = (
    "Without a GPU, EGL renders through Mesa, whose drivers are a package of their own: install them, e.g. "
    "'apt-get install libgl1-mesa-dri' on Debian/Ubuntu."
)


def choose_backend() -> None:
    """Set ``MUJOCO_GL=egl`` when it is unset and no display can be opened (none named, or a stale ``DISPLAY``
    as over ssh without X forwarding); fail clearly when the library of the headless backend set or chosen is
    missing (``import mujoco`` would fail with an ``AttributeError`` of PyOpenGL's)."""
    if sys.platform in ("darwin", "win32"):
        return
    backend = os.environ.get("MUJOCO_GL", "").lower().strip()
    if not backend:
        if missing_display() is None:
            return
        backend = os.environ["MUJOCO_GL"] = "egl"
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    if backend == "egl" and ctypes.util.find_library("EGL") is None:
        raise ImportError(EGL_HELP)
    if backend == "osmesa" and ctypes.util.find_library("OSMesa") is None:
        raise ImportError(OSMESA_HELP)


def missing_display() -> str | None:
    """Why no window can open here (no display named, or the named one cannot be reached), or ``None``."""
    display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    if not display:
        return "none found (DISPLAY and WAYLAND_DISPLAY are unset)"
    import glfw  # what MuJoCo opens windows and its default GL contexts with

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", glfw.GLFWError)
        if not glfw.init():  # a no-op returning True when glfw is already initialised
            return f"display {display!r} could not be opened"
    return None


_made_contexts = False  # this process, or one it was forked from, has made a GL context
_forked_after_gl = False  # ... and this process is such a fork


def _note_fork() -> None:
    global _forked_after_gl
    _forked_after_gl = _made_contexts


os.register_at_fork(after_in_child=_note_fork)


class Context:
    """A GL context of :func:`gl_context`, current in a thread only while a renderer draws: the renderer makes it
    current, draws, reads back and releases it, so that it may be used from any thread, one at a time (EGL refuses
    a context that is current in another thread, and an env created in one thread is often stepped in another).
    With EGL both switches go straight to libEGL (PyOpenGL's wrapper took 5 us a call); with the other backends
    the context stays current in the thread that drew last."""

    def __init__(self, context):
        self.context = context  # MuJoCo's GLContext of the backend
        self._switch = _egl_switch(context) if type(context).__module__.startswith("mujoco.egl") else None

    def make_current(self) -> None:
        """Make the context current in the calling thread."""
        if self._switch is None:
            self.context.make_current()
        else:
            self._switch(True)

    def release(self) -> None:
        """Leave no context current in the calling thread (EGL; a no-op with the other backends)."""
        if self._switch is not None:
            self._switch(False)

    def free(self) -> None:
        """Destroy the context."""
        self.context.free()


def _egl_switch(context):
    """``switch(on)``: make MuJoCo's EGL ``context`` current in the calling thread (``on``), or none; raises
    ``RuntimeError`` with EGL's error code when EGL refuses."""
    from mujoco import egl

    lib = ctypes.CDLL(ctypes.util.find_library("EGL"))
    lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
    lib.eglMakeCurrent.restype = ctypes.c_uint
    lib.eglGetError.restype = ctypes.c_int
    display, ours = ctypes.c_void_p(egl.EGL_DISPLAY.address), ctypes.c_void_p(context._context.address)

    def switch(on: bool) -> None:
        if not lib.eglMakeCurrent(display, None, None, ours if on else None):
            raise RuntimeError(f"eglMakeCurrent failed with EGL error 0x{lib.eglGetError():x}")

    return switch


def forked_after_gl() -> bool:
    """Whether this process was forked from one that had made a GL context: its copy of the driver's state must not
    be used (making or freeing a context in it may hang)."""
    return _forked_after_gl


def gl_context(width: int, height: int) -> Context:
    """An offscreen GL context of the backend ``MUJOCO_GL`` names, whatever was imported first.

    ``mujoco`` binds ``mujoco.GLContext`` when it is imported; if that happened before
    :func:`choose_backend` ran, this still returns a context of the chosen backend. In a process
    forked from one that had made a context (where the driver would hang), raises ``RuntimeError``.
    """
    global _made_contexts
    if forked_after_gl():
        raise RuntimeError(FORK_HELP)
    backend = os.environ.get("MUJOCO_GL", "").lower().strip()
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        if sys.platform == "linux" and (reason := missing_display()):
            raise RuntimeError(
                f"MUJOCO_GL={backend!r} renders through a window system, and there is no display here ({reason}): "
                "set MUJOCO_GL=egl, or leave it unset, to render headless"
            )
        from mujoco import GLContext
    try:
        context = GLContext(width, height)
    except ImportError as error:  # mujoco.egl's "Cannot initialize a EGL device display": no driver behind libEGL
        if backend != "egl":
            raise
        raise ImportError(f"{error} {MESA_DRIVER_HELP}") from error
    _made_contexts = True
    return Context(context)
