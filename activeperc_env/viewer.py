"""Rendering of the one-room adapters: the bird's-eye map, and MuJoCo's interactive viewer where a display exists."""

from __future__ import annotations

import warnings

import gymnasium

from activeperc_env.core import Simulator
from activeperc_env.gl import missing_display

RENDER_MODES = ["human", "rgb_array"]


def check_render_mode(mode: str | None, render_mode: str | None) -> None:
    """Refuse a ``mode`` given to ``render()`` other than ``None`` or the env's own ``render_mode``."""
    if mode is not None and mode != render_mode:
        raise ValueError(
            f"render({mode!r}) asks for another mode than the env's render_mode={render_mode!r}: the mode is chosen "
            "when the env is made (render_mode=...)"
        )


class OneRoomRendering:
    """Room 0 of ``self.sim`` as the PettingZoo and Gymnasium envs show it: its observation, ``render()`` and
    ``close()``."""

    sim: Simulator

    def _setup_rendering(self, render_mode: str | None) -> None:
        """Check and keep ``render_mode``; a ``'human'`` env gets its viewer (opened at the first render)."""
        if render_mode not in (None, *RENDER_MODES):
            raise ValueError(f"render_mode={render_mode!r} is invalid: expected None or one of {RENDER_MODES}")
        self.render_mode = render_mode
        self._viewer = HumanViewer() if render_mode == "human" else None

    def _observe(self) -> dict:
        """Room 0's observation as it is now (:meth:`Simulator.observe`): its first-person view, camera pan and
        range readings."""
        return {key: value[0] for key, value in self.sim.observe().items()}

    def render(self, mode: str | None = None):
        """``rgb_array``: the bird's-eye map (240x320x3 uint8); ``human``: MuJoCo's viewer (``None``). ``mode``, which
        some libraries pass (RLlib's PettingZoo wrappers), may only repeat the env's ``render_mode``."""
        check_render_mode(mode, self.render_mode)
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        self.sim.require_started("render()")
        if self.render_mode == "rgb_array":
            return self.sim.render_map(0)
        self._viewer.show(self.sim)
        return None

    def close(self):
        """Release the renderer and close the viewer."""
        if self._viewer is not None:
            self._viewer.close()
        self.sim.close()


class HumanViewer:
    """Shows room 0 of a simulator in MuJoCo's passive viewer; without a display it warns once and shows nothing."""

    def __init__(self):
        self._handle = None
        self._data = None
        self._headless = None  # why no window can open, once the first show() has looked

    def __getstate__(self) -> dict:
        """A copy of the env opens a window of its own at its first render: nothing of this one's is copied."""
        return {"_handle": None, "_data": None, "_headless": None}

    def show(self, sim: Simulator) -> None:
        """Draw the current state (opens the window on first use)."""
        if self._headless is None:
            self._headless = missing_display() or ""
            if self._headless:
                message = f"render_mode='human' needs a display; {self._headless}, so nothing is shown"
                warnings.warn(message, stacklevel=3)
        if self._headless:
            return
        import mujoco.viewer

        data = sim.physics_data(0)
        if self._handle is None:
            self._data = data
            self._handle = mujoco.viewer.launch_passive(sim.model, self._data)
        with self._handle.lock():
            self._data.qpos[:] = data.qpos
            self._data.mocap_pos[:] = data.mocap_pos
            mujoco.mj_forward(sim.model, self._data)  # the poses the viewer draws follow from qpos
        self._handle.sync()

    def close(self) -> None:
        """Close the window if one is open."""
        if self._handle is not None:
            self._handle.close()
            self._handle = None
