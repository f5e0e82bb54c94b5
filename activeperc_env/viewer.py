"""``render_mode="human"``: MuJoCo's interactive viewer where a display exists."""

from __future__ import annotations

import os
import warnings

from activeperc_env.core import Simulator


class HumanViewer:
    """Shows room 0 of a simulator in MuJoCo's passive viewer; headless, warns once and shows nothing."""

    def __init__(self):
        self._handle = None
        self._data = None
        self._warned = False

    def show(self, sim: Simulator) -> None:
        """Draw the current state (opens the window on first use)."""
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            if not self._warned:
                warnings.warn("render_mode='human' needs a display; none found, so nothing is shown", stacklevel=3)
                self._warned = True
            return
        import mujoco.viewer

        data = sim.physics_data(0)
        if self._handle is None:
            self._data = data
            self._handle = mujoco.viewer.launch_passive(sim.model, self._data)
        with self._handle.lock():
            self._data.qpos[:] = data.qpos
            self._data.mocap_pos[:] = data.mocap_pos
        self._handle.sync()

    def close(self) -> None:
        """Close the window if one is open."""
        if self._handle is not None:
            self._handle.close()
            self._handle = None
