"""Observation and action spaces shared by every adapter."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from activeperc_env.config import EnvConfig
from activeperc_env.core import LOOKER_ACTIONS, MOVER_ACTIONS


def observation_space(config: EnvConfig) -> spaces.Dict:
    """``Dict(image=Box(uint8, (H, W, 3)), pan=Box(float32, (1,)))``; pan in radians."""
    limit = math.radians(config.pan_range)
    return spaces.Dict(
        {
            "image": spaces.Box(0, 255, (config.height, config.width, 3), dtype=np.uint8),
            "pan": spaces.Box(-limit, limit, (1,), dtype=np.float32),
        }
    )


def mover_space() -> spaces.Discrete:
    """``Discrete(3)``: 0 turn left, 1 turn right, 2 forward."""
    return spaces.Discrete(len(MOVER_ACTIONS))


def looker_space() -> spaces.Discrete:
    """``Discrete(3)``: 0 pan left, 1 hold, 2 pan right."""
    return spaces.Discrete(len(LOOKER_ACTIONS))


def check_action(agent: str, action, space: spaces.Discrete) -> int:
    """Return ``action`` as an int, or raise ``ValueError`` naming the agent and its space."""
    scalar_array = isinstance(action, np.ndarray) and action.shape == () and np.issubdtype(action.dtype, np.integer)
    is_int = isinstance(action, (int, np.integer)) and not isinstance(action, (bool, np.bool_))
    if not (is_int or scalar_array):
        raise ValueError(f"action {action!r} of {agent} is not an int in its action space {space}")
    if not space.contains(int(action)):
        raise ValueError(f"action {action!r} of {agent} is outside its action space {space}")
    return int(action)
