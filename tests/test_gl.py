"""The headless backend choice: EGL when no display can be opened, a clear error when EGL is missing."""

import os
import subprocess
import sys

import pytest

from activeperc_env import gl

RENDER_ONE_VIEW = """
import os
import activeperc_env
env = activeperc_env.env()
env.reset(seed=0)
print(os.environ.get("MUJOCO_GL"), int(env.last()[0]["image"].max()))
"""


def test_a_stale_display_falls_back_to_egl():
    """DISPLAY set but unreachable (ssh without X forwarding, a container): MuJoCo's default glfw context would
    fail with an obscure FatalError; the import picks EGL instead and the env renders."""
    environment = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    environment |= {"DISPLAY": ":987", "WAYLAND_DISPLAY": ""}
    out = subprocess.run(
        [sys.executable, "-c", RENDER_ONE_VIEW], env=environment, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    backend, brightest = out.stdout.split()
    assert backend == "egl" and int(brightest) > 0


CLOSE_AFTER_MUJOCOS_EXIT_HANDLER = """
import activeperc_env
import mujoco.egl
env = activeperc_env.env()
env.reset(seed=0)
env.last()
mujoco.egl._terminate_display()  # what MuJoCo's exit handler does, before a library's own exit handler closes envs
env.close()
print("closed")
"""


def test_an_env_closed_after_mujoco_terminated_the_egl_display_closes_quietly():
    """Exit handlers run last-registered first, so one registered before the first render (Ray's, a user's) closes
    its envs after MuJoCo's has terminated the EGL display; their contexts went with it, and closing says nothing."""
    environment = os.environ | {"MUJOCO_GL": "egl"}
    out = subprocess.run(
        [sys.executable, "-c", CLOSE_AFTER_MUJOCOS_EXIT_HANDLER],
        env=environment,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0 and out.stdout == "closed\n", out.stderr
    assert "Exception" not in out.stderr and "Traceback" not in out.stderr, out.stderr


def test_without_a_display_or_egl_the_import_says_what_to_install(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(gl.ctypes.util, "find_library", lambda name: None)
    with pytest.raises(ImportError, match="apt-get install libegl1 libgl1-mesa-dri"):
        gl.choose_backend()


def test_a_usable_display_or_a_chosen_backend_is_left_alone(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "missing_display", lambda: None)
    gl.choose_backend()
    assert "MUJOCO_GL" not in os.environ
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.setattr(gl, "missing_display", lambda: "none found")
    monkeypatch.setattr(gl.ctypes.util, "find_library", lambda name: f"lib{name}.so")  # as where OSMesa is installed
    gl.choose_backend()
    assert os.environ["MUJOCO_GL"] == "osmesa"


@pytest.mark.parametrize(
    ("backend", "library", "install"), [("egl", "EGL", "libegl1"), ("osmesa", "OSMesa", "libosmesa6")]
)
def test_a_headless_backend_set_without_its_library_says_what_to_install(monkeypatch, backend, library, install):
    """``import mujoco`` itself would fail with an AttributeError from deep inside PyOpenGL."""
    monkeypatch.setenv("MUJOCO_GL", backend)
    monkeypatch.setattr(gl.ctypes.util, "find_library", lambda name: None if name == library else "lib.so")
    with pytest.raises(ImportError, match=f"apt-get install {install}"):
        gl.choose_backend()


def test_a_window_backend_without_a_display_says_to_use_egl(monkeypatch):
    """MuJoCo would fail at its first context with 'an OpenGL platform library has not been loaded'."""
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match=r"MUJOCO_GL='glfw' .* no display here .*: set MUJOCO_GL=egl"):
        gl.gl_context(8, 8)


def test_egl_without_mesas_drivers_says_what_to_install(monkeypatch):
    import mujoco.egl

    def no_device(width, height):
        raise ImportError("Cannot initialize a EGL device display.")

    monkeypatch.setenv("MUJOCO_GL", "egl")
    monkeypatch.setattr(mujoco.egl, "GLContext", no_device)
    with pytest.raises(ImportError, match="Cannot initialize a EGL device display. .*apt-get install libgl1-mesa-dri"):
        gl.gl_context(8, 8)


def test_an_unknown_backend_names_the_ones_to_use(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "EGl2")
    with pytest.raises(RuntimeError, match="MUJOCO_GL='EGl2' is not one of MuJoCo's OpenGL backends: use egl"):
        gl.choose_backend()
    monkeypatch.setenv("MUJOCO_GL", " EGL ")  # MuJoCo reads it lower-cased and stripped
    monkeypatch.setattr(gl.ctypes.util, "find_library", lambda name: f"lib{name}.so")
    gl.choose_backend()


@pytest.mark.parametrize("value", ["disable", "off", "0"])
def test_rendering_turned_off_says_to_use_egl(monkeypatch, value):
    """MuJoCo then has no context to make; the window-system error that came instead blamed a missing display."""
    monkeypatch.setenv("MUJOCO_GL", value)
    gl.choose_backend()  # physics without rendering is MuJoCo's business; our first view is ours
    with pytest.raises(RuntimeError, match=f"MUJOCO_GL='{value}' turns MuJoCo's rendering off.*set MUJOCO_GL=egl"):
        gl.gl_context(8, 8)
