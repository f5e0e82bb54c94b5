"""Observation and action spaces shared by every adapter."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from activeperc_env.checks import check_actions
from activeperc_env.config import EnvConfig
from activeperc_env.core import LOOKER_ACTIONS, MOVER_ACTIONS
from activeperc_env.names import ROOM_HALF_X, ROOM_HALF_Y

MAX_GEOM_ID = 255  # the segmentation space's bound on geom ids (the rooms have fewer than 32 geoms)


def observation_space(config: EnvConfig) -> spaces.Dict:
    """``Dict(image=Box(uint8, (H, W, 3)), pan=Box(float32, (1,)))``, pan in radians, and with a range sensor
    (``range_rays`` > 0) ``range=Box(float32, (range_rays,))`` in metres, right to left; with ``depth``,
    ``depth=Box(float32, (H, W))`` in metres, and with ``segmentation``, ``segmentation=Box(int32, (H, W))`` geom
    ids (-1: none)."""
    limit = math.radians(config.pan_range)
    keys = {
        "image": spaces.Box(0, 255, (config.height, config.width, 3), dtype=np.uint8),
        "pan": spaces.Box(-limit, limit, (1,), dtype=np.float32),
    }
    if config.range_rays:
        keys["range"] = spaces.Box(0.0, config.range_max, (config.range_rays,), dtype=np.float32)
    if config.depth:
        keys["depth"] = spaces.Box(0.0, np.inf, (config.height, config.width), dtype=np.float32)
    if config.segmentation:
        keys["segmentation"] = spaces.Box(-1, MAX_GEOM_ID, (config.height, config.width), dtype=np.int32)
    return spaces.Dict(keys)


def state_space(config: EnvConfig) -> spaces.Box:
    """``Box(float32, (8 + 2 * num_obstacles,))``: the layout of :meth:`activeperc_env.Simulator.state`.

    Robot x, y; cos and sin of its heading; pan; goal x, y; each occluder's x, y; ``cycle / max_cycles``.
    Positions lie inside the room (x in [-3, 3], y in [-2, 2] metres), the pan within ``pan_range``.
    """
    limit = math.radians(config.pan_range)
    room = [ROOM_HALF_X, ROOM_HALF_Y]
    high = np.array(room + [1.0, 1.0, limit] + room * (1 + config.num_obstacles) + [1.0], dtype=np.float32)
    low = -high
    low[-1] = 0.0
    return spaces.Box(low, high, dtype=np.float32)


def mover_space() -> spaces.Discrete:
    """``Discrete(3)``: 0 to the left, 1 to the right, 2 forward (turns or slides: the room's ``mover_actions``)."""
    return spaces.Discrete(MOVER_ACTIONS)


def looker_space() -> spaces.Discrete:
    """``Discrete(3)``: 0 pan left, 1 hold, 2 pan right."""
    return spaces.Discrete(len(LOOKER_ACTIONS))


def check_action(agent: str, action, space: spaces.Discrete) -> int:
    """``action`` as an int, or ``ValueError`` naming the agent and its space (``checks.check_actions``)."""
    return int(check_actions(action, 1, int(space.n), agent, scalar=True)[0])
