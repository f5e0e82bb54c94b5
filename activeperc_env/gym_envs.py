"""Gymnasium single-agent views of the room: the Joint agent and the Fixed-forward mover."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from activeperc_env.config import EnvConfig
from activeperc_env.core import HOLD, JOINT_ACTIONS, Simulator, split_joint
from activeperc_env.rooms import with_version_history
from activeperc_env.spaces import check_action, mover_space, observation_space
from activeperc_env.viewer import RENDER_MODES, OneRoomRendering


class _SingleAgentEnv(OneRoomRendering, gym.Env):
    """One agent over a one-room ``Simulator``; subclasses map its action to a move and a look."""

    metadata = {"render_modes": RENDER_MODES, "render_fps": EnvConfig.control_hz}  # each env: its own

    def __init__(self, render_mode: str | None = None, **config):
        self._setup_rendering(render_mode)
        hint = (
            " (an option of the rooms stepped together by gymnasium.make_vec's default mode; with "
            "vectorization_mode 'sync' or 'async' pass vector_kwargs={'autoreset_mode': ...})"
            if "autoreset_mode" in config
            else ""
        )
        self.config = EnvConfig.from_kwargs(hint, **config)
        self.metadata = {**self.metadata, "render_fps": self.config.control_hz}
        self.sim = Simulator(self.config, num_envs=1, nthread=1)
        self.observation_space = observation_space(self.config)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode; ``seed`` fixes the layout, as in the PettingZoo envs (``options`` are ignored)."""
        self.sim.reset(seeds=None if seed is None else [seed])  # first: it checks the seed
        super().reset(seed=None if seed is None else int(seed))  # Gymnasium takes Python ints only
        if self.render_mode == "human":
            self.render()
        return self._observe(), {"cycle": 0}

    def step(self, action):
        """One cycle: the move, then the look; returns Gymnasium's five values."""
        if self.sim.done[0]:
            raise self.sim.outside_episode("step()")
        move, look = self._split(action)
        result = self.sim.move(np.array([move]))
        self.sim.look(np.array([look]))
        if self.render_mode == "human":
            self.render()
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        info = {"cycle": int(self.sim.cycle[0])} | (result.outcome() if terminated or truncated else {})
        return self._observe(), float(result.reward[0]), terminated, truncated, info

    def _split(self, action) -> tuple[int, int]:
        raise NotImplementedError


@with_version_history
class JointEnv(_SingleAgentEnv):
    """One agent that both moves and looks: ``Discrete(9)``, action ``3 * u_m + u_c`` (``activeperc/Joint-v3``).

    Description:
        The paper's Joint baseline (and the Curriculum baseline's agent): the room of
        :class:`activeperc_env.pettingzoo_env.raw_env` with one agent choosing both the move and the look
        of each cycle. The look is applied after the move.

    Action Space:
        ``Discrete(9)``: ``3 * u_m + u_c`` with ``u_m`` the move (0 left, 1 right, 2 forward: slides in v3,
        turns in v0-v2) and ``u_c`` the look (0 pan left, 1 hold, 2 pan right).

    Observation Space:
        ``Dict(image=Box(0, 255, (height, width, 3), uint8), pan=Box(float32, (1,)))``: the view after the
        look and the camera's pan (radians, relative to the heading); in v1-v3 also ``range`` (as in
        :class:`~activeperc_env.pettingzoo_env.raw_env`).

    Rewards:
        ``1 - 0.2 * t / max_cycles`` in the cycle ``t`` in which the robot reaches the goal, else 0.

    Starting State:
        As :class:`~activeperc_env.pettingzoo_env.raw_env`: a seeded layout, the camera facing forward.

    Episode End:
        Terminated when the robot reaches the goal; truncated after ``max_cycles`` cycles. The last step's
        ``info`` adds ``episode_success`` (the robot reached the goal) and ``episode_return`` (the sum of the rewards).

    Arguments:
        render_mode: None, 'rgb_array' or 'human'.
        **config: any :class:`EnvConfig` field (the room and its options).
    """

    def __init__(self, render_mode: str | None = None, **config):
        super().__init__(render_mode, **config)
        self.action_space = gym.spaces.Discrete(JOINT_ACTIONS)

    def _split(self, action) -> tuple[int, int]:
        return split_joint(check_action("joint agent", action, self.action_space))


@with_version_history
class FixedForwardEnv(_SingleAgentEnv):
    """The mover alone, its camera fixed forward (``activeperc/FixedForward-v3``).

    Description:
        The paper's Fixed_Forward baseline: the room of :class:`activeperc_env.pettingzoo_env.raw_env`
        with the looker always holding, so the camera never leaves the robot's heading.

    Action Space:
        ``Discrete(3)``: 0 to the left, 1 to the right, 2 forward (slides in v3, turns in v0-v2).

    Observation Space:
        As :class:`JointEnv`'s; ``pan`` is always 0.

    Rewards:
        ``1 - 0.2 * t / max_cycles`` in the cycle ``t`` in which the robot reaches the goal, else 0.

    Starting State:
        As :class:`~activeperc_env.pettingzoo_env.raw_env`: a seeded layout, the camera facing forward.

    Episode End:
        Terminated when the robot reaches the goal; truncated after ``max_cycles`` cycles. The last step's
        ``info`` adds ``episode_success`` (the robot reached the goal) and ``episode_return`` (the sum of the rewards).

    Arguments:
        render_mode: None, 'rgb_array' or 'human'.
        **config: any :class:`EnvConfig` field (the room and its options).
    """

    def __init__(self, render_mode: str | None = None, **config):
        super().__init__(render_mode, **config)
        self.action_space = mover_space()

    def _split(self, action) -> tuple[int, int]:
        return check_action("mover", action, self.action_space), HOLD
