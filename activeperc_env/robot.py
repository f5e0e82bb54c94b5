"""The robot's bases: where one stands, how a reset places it and how a move drives it (each room's record names
its base: :mod:`activeperc_env.rooms`).

:class:`WheeledBase` rolls on two driven wheels (a free joint, wheel contacts with the floor). :class:`PlanarBase` is a
unicycle: velocity servos on two slides and a yaw hinge, nothing touching the floor. Both take the same three moves
(turn left, turn right, forward) and hold the same camera on a pan hinge. :class:`HolonomicBase` is the planar base
whose moves slide it left, right or forward, never turning it.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from activeperc_env import names

FORWARD = 2  # the mover's action "forward" in every room
_SLIDE_ANGLES = np.array([math.pi / 2, -math.pi / 2, 0.0])  # HolonomicBase's direction of each move, from the heading


def _address(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    return mujoco.mj_name2id(model, kind, name)


class WheeledBase:
    """A chassis on a free joint, driven by velocity servos on its two wheels (``forward_speed``: the wheels' rim
    speed in m/s; ``turn_speed``: degrees per second)."""

    TURNS = True
    """Whether the moves turn the base."""

    def __init__(self, model: mujoco.MjModel, forward_speed: float, turn_speed: float):
        self.root = int(model.jnt_qposadr[_address(model, mujoco.mjtObj.mjOBJ_JOINT, names.ROOT_JOINT)])
        self.wheels = [_address(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in (names.LEFT_WHEEL, names.RIGHT_WHEEL)]
        wheel = forward_speed / names.WHEEL_RADIUS
        turn = math.radians(turn_speed) * names.WHEEL_TRACK / 2 / names.WHEEL_RADIUS
        # wheel speed targets (left, right) in rad/s, one row per mover action
        self._targets = np.array([[-turn, turn], [turn, -turn], [wheel, wheel]])

    def place(self, qpos: np.ndarray, xy: np.ndarray, heading: float) -> None:
        """Put the base of one room (its ``qpos`` row) at ``xy``, facing ``heading``, on its wheels."""
        qpos[self.root : self.root + 3] = (*xy, names.WHEEL_RADIUS)
        half = heading / 2
        qpos[self.root + 3 : self.root + 7] = (math.cos(half), 0.0, 0.0, math.sin(half))

    def drive(self, ctrl: np.ndarray, qpos: np.ndarray, actions: np.ndarray) -> None:
        """Write the controls (rows of ``ctrl``) of the moves ``actions`` of the rooms whose ``qpos`` rows are given."""
        ctrl[:, self.wheels] = self._targets[actions]

    def xy(self, qpos: np.ndarray) -> np.ndarray:
        """(n, 2) positions of the bases of the ``qpos`` rows."""
        return qpos[:, self.root : self.root + 2]

    def heading(self, qpos: np.ndarray) -> np.ndarray:
        """(n,) yaw of the bases of the ``qpos`` rows, radians (not wrapped)."""
        # math.atan2 rounds alike on every CPU, numpy's arctan2 not (its AVX-512 kernel differs)
        quaternions = qpos[:, [self.root + 3, self.root + 6]]
        return np.array([2 * math.atan2(z, w) for w, z in quaternions], dtype=np.float64).reshape(len(qpos))


class PlanarBase:
    """A base on slides along x and y and a yaw hinge, each driven by a velocity servo (a unicycle: ``forward_speed``
    in m/s, ``turn_speed`` in degrees per second)."""

    TURNS = True
    """Whether the moves turn the base."""

    def __init__(self, model: mujoco.MjModel, forward_speed: float, turn_speed: float):
        joints = [_address(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names.BASE_JOINTS]
        self.x, self.y, self.yaw = (int(model.jnt_qposadr[j]) for j in joints)
        self.drives = [_address(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in names.BASE_DRIVES]
        self._speed = forward_speed
        turn = math.radians(turn_speed)
        self._yaw_rate = np.array([turn, -turn, 0.0])  # per mover action

    def place(self, qpos: np.ndarray, xy: np.ndarray, heading: float) -> None:
        """Put the base of one room (its ``qpos`` row) at ``xy``, facing ``heading``."""
        qpos[[self.x, self.y, self.yaw]] = (*xy, heading)

    def drive(self, ctrl: np.ndarray, qpos: np.ndarray, actions: np.ndarray) -> None:
        """Write the controls (rows of ``ctrl``) of the moves ``actions`` of the rooms whose ``qpos`` rows are given:
        'forward' drives along the heading the move starts from (a move turns or drives, never both)."""
        speed = np.where(actions == FORWARD, self._speed, 0.0)
        yaw = qpos[:, self.yaw]
        x, y, turn = self.drives
        ctrl[:, x], ctrl[:, y], ctrl[:, turn] = speed * np.cos(yaw), speed * np.sin(yaw), self._yaw_rate[actions]

    def xy(self, qpos: np.ndarray) -> np.ndarray:
        """(n, 2) positions of the bases of the ``qpos`` rows."""
        return qpos[:, [self.x, self.y]]

    def heading(self, qpos: np.ndarray) -> np.ndarray:
        """(n,) yaw of the bases of the ``qpos`` rows, radians (not wrapped)."""
        return qpos[:, self.yaw]


class HolonomicBase(PlanarBase):
    """The planar base, but its moves slide it left, right or forward without turning it: the body keeps its start
    heading, so only the camera can look to the side (``turn_speed`` is unused)."""

    TURNS = False

    def drive(self, ctrl: np.ndarray, qpos: np.ndarray, actions: np.ndarray) -> None:
        """Write the controls (rows of ``ctrl``) of the moves ``actions``: each drives at the forward speed along the
        heading turned by the move's angle (+90 degrees left, -90 right, 0 forward), the yaw held still."""
        direction = qpos[:, self.yaw] + _SLIDE_ANGLES[actions]
        x, y, turn = self.drives
        ctrl[:, x], ctrl[:, y], ctrl[:, turn] = self._speed * np.cos(direction), self._speed * np.sin(direction), 0.0
