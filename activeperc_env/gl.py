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
    "Stable-Baselines3 SubprocVecEnv(..., start_method='spawn'); for tools that take no start method (SuperSuit's "
    "concat_vec_envs_v1 with num_cpus > 0), call multiprocessing.set_start_method('spawn') at the start of the "
    "program."
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

# whether choose_backend set LP_NUM_THREADS (Mesa's llvmpipe then draws in the calling thread), or found it set
LLVMPIPE_THREADS_CHOSEN = False

# MUJOCO_GL's values on Linux, as MuJoCo reads them (_backend); any other fails at ``import mujoco``
RENDERING_OFF = ("disable", "disabled", "off", "false", "0")
LINUX_BACKENDS = ("", "egl", "osmesa", "glfw", "glx", "enable", "enabled", "on", "true", "1", *RENDERING_OFF)


def choose_backend() -> None:
    """Set ``MUJOCO_GL=egl`` when it is unset and no display can be opened (none named, or a stale ``DISPLAY``
    as over ssh without X forwarding); fail clearly when the library of the headless backend set or chosen is
    missing (``import mujoco`` would fail with an ``AttributeError`` of PyOpenGL's). Also set
    ``LP_NUM_THREADS=0`` when it is unset: Mesa's software renderer (llvmpipe) then draws in the calling thread,
    which renders our small views faster than its threads do (docs/performance.md); other drivers ignore it."""
    global LLVMPIPE_THREADS_CHOSEN
    if "LP_NUM_THREADS" not in os.environ:
        os.environ["LP_NUM_THREADS"] = "0"
        LLVMPIPE_THREADS_CHOSEN = True
    if sys.platform in ("darwin", "win32"):
        return
    backend = _backend()
    if backend not in LINUX_BACKENDS:  # MuJoCo's own error names the value, not what to use instead
        raise RuntimeError(
            f"MUJOCO_GL={os.environ['MUJOCO_GL']!r} is not one of MuJoCo's OpenGL backends: use egl (headless; "
            "chosen for you when MUJOCO_GL is unset and there is no display), osmesa (headless, slower), or glfw "
            "or glx (with a display)"
        )
    if not backend:
        if missing_display() is None:
            return
        backend = os.environ["MUJOCO_GL"] = "egl"
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    if backend == "egl" and ctypes.util.find_library("EGL") is None:
        raise ImportError(EGL_HELP)
    if backend == "osmesa" and ctypes.util.find_library("OSMesa") is None:
        raise ImportError(OSMESA_HELP)


def _backend() -> str:
    """``MUJOCO_GL`` as MuJoCo reads it: lower-cased and stripped, ``""`` when unset."""
    return os.environ.get("MUJOCO_GL", "").lower().strip()


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
    egl = sys.modules.get("mujoco.egl")
    if _forked_after_gl and egl is not None:
        # MuJoCo's exit handler terminates its EGL display and its contexts destroy themselves when collected: in a
        # fork, the driver's copied state hangs on that. Without a display MuJoCo skips every such EGL call.
        egl.EGL_DISPLAY = None


os.register_at_fork(after_in_child=_note_fork)


class Context:
    """A GL context of :func:`gl_context`, current in a thread only while a renderer draws: the renderer makes it
    current, draws, reads back and puts back what was current before (nothing, as a rule), so that it may be used
    from any thread, one at a time (EGL refuses a context that is current in another thread, and an env created in
    one thread is often stepped in another). With the other backends the context stays current in the thread that
    drew last."""

    def __init__(self, context):
        self.context = context  # MuJoCo's GLContext of the backend
        self._egl = _Egl(context) if type(context).__module__.startswith("mujoco.egl") else None

    def make_current(self):
        """Make the context current in the calling thread; returns what was current before, for :meth:`restore`.
        In a fork of a process that had rendered, raises ``RuntimeError`` (the driver would hang)."""
        if forked_after_gl():
            raise RuntimeError(FORK_HELP)
        if self._egl is None:
            self.context.make_current()
            return None
        return self._egl.make_current()

    def restore(self, previous) -> None:
        """Make current again what :meth:`make_current` found current (with EGL: nothing, or the context of a
        renderer whose draw the garbage collector interrupted to close this one)."""
        if self._egl is not None:
            self._egl.restore(previous)

    def usable(self) -> bool:
        """Whether the context can still be made current: not in a fork of a process that had rendered, nor with EGL
        once MuJoCo's exit handler has terminated the display (which destroyed every context on it)."""
        if forked_after_gl():
            return False
        return self._egl is None or sys.modules["mujoco.egl"].EGL_DISPLAY is not None

    def free(self) -> None:
        """Destroy the context."""
        self.context.free()


class _Egl:
    """Switching MuJoCo's EGL context straight through libEGL (PyOpenGL's wrapper checks for errors around every
    call, twice per render)."""

    DRAW, READ = 0x3059, 0x305A  # EGL_DRAW, EGL_READ

    def __init__(self, context):
        lib = ctypes.CDLL(ctypes.util.find_library("EGL"))
        lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
        lib.eglMakeCurrent.restype = ctypes.c_uint
        lib.eglGetCurrentContext.restype = ctypes.c_void_p
        lib.eglGetCurrentDisplay.restype = ctypes.c_void_p
        lib.eglGetCurrentSurface.argtypes = [ctypes.c_int]
        lib.eglGetCurrentSurface.restype = ctypes.c_void_p
        lib.eglGetError.restype = ctypes.c_int
        self._lib = lib
        previous = self._current()
        context.make_current()  # MuJoCo's own call, once, to learn its display and context handles
        self._display, self._context = lib.eglGetCurrentDisplay(), lib.eglGetCurrentContext()
        self.restore(previous)

    def _current(self) -> tuple | None:
        """The display, draw and read surfaces and context current in the calling thread; ``None`` when no context
        is (one call, the common case)."""
        lib = self._lib
        if not lib.eglGetCurrentContext():
            return None
        return (
            lib.eglGetCurrentDisplay(),
            lib.eglGetCurrentSurface(self.DRAW),
            lib.eglGetCurrentSurface(self.READ),
            lib.eglGetCurrentContext(),
        )

    def make_current(self) -> tuple | None:
        """Make the context current; returns the display, surfaces and context current before (``None``: no
        context, as a rule)."""
        previous = self._current()
        self._switch(self._display, None, None, self._context)
        return previous

    def restore(self, previous: tuple | None) -> None:
        """Make ``previous`` (from :meth:`make_current`) current again, or no context when there was none."""
        if previous is None:
            self._switch(self._display, None, None, None)
        else:
            self._switch(*previous)

    def _switch(self, display, draw, read, context) -> None:
        if not self._lib.eglMakeCurrent(display, draw, read, context):
            raise RuntimeError(f"eglMakeCurrent failed with EGL error 0x{self._lib.eglGetError():x}")


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
    backend = _backend()
    if backend in RENDERING_OFF:
        raise RuntimeError(
            f"MUJOCO_GL={os.environ['MUJOCO_GL']!r} turns MuJoCo's rendering off, and every observation here is an "
            "image: set MUJOCO_GL=egl, or leave it unset (EGL is chosen when there is no display)"
        )
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
