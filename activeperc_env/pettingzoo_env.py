"""PettingZoo adapters: the AEC env (mover and looker take turns) and the parallel env.

A cycle is the mover's turn then the looker's turn. The mover's reward for its move is
given as soon as it moves (so the looker's ``last()`` sees it when ``looker_reward='shared'``; with
``'own_turn'`` the looker's share comes with its own step);
the episode ends at the end of the cycle in which the robot reached the goal or
``max_cycles`` ran out, after the looker's turn.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils import wrappers

from activeperc_env.config import EnvConfig
from activeperc_env.core import Simulator
from activeperc_env.rooms import DEFAULT, ROOMS, with_version_history
from activeperc_env.spaces import check_action, looker_space, mover_space, observation_space, state_space
from activeperc_env.viewer import RENDER_MODES, OneRoomRendering, check_render_mode

MOVER, LOOKER = "mover_0", "looker_0"


class _Adapter(OneRoomRendering):
    """What both PettingZoo envs share: spaces, seeding, rendering over one ``Simulator``."""

    # not "is_parallelizable": the AEC env's looker observes s_bar (after the move, before its look), so PettingZoo's
    # aec_to_parallel would give a game where the looker acts on another view than the mover; use parallel_env
    metadata = {"render_modes": RENDER_MODES, "name": ROOMS[DEFAULT].name}  # each env: its own room's

    def _setup(self, render_mode: str | None, config: dict) -> None:
        self._setup_rendering(render_mode)
        self.config = EnvConfig.from_kwargs(**config)
        self.metadata = {**self.metadata, "name": self.config.room.name, "render_fps": self.config.control_hz}
        self.sim = Simulator(self.config, num_envs=1, nthread=1)
        self.possible_agents = [MOVER, LOOKER]
        obs_space = observation_space(self.config)
        self.observation_spaces = {MOVER: obs_space, LOOKER: obs_space}
        self.action_spaces = {MOVER: mover_space(), LOOKER: looker_space()}
        self.state_space = state_space(self.config)
        # for wrappers that draw from env.unwrapped.np_random (SuperSuit's frame_skip_v0 with a range), as in
        # Gymnasium; reset(seed=s) seeds it. The room draws nothing from it: layouts come from the simulator.
        self.np_random = np.random.default_rng()

    def observation_space(self, agent):
        """The observation space of ``agent`` (the same object on every call)."""
        return self.observation_spaces[self._known(agent)]

    def action_space(self, agent):
        """The action space of ``agent`` (the same object on every call)."""
        return self.action_spaces[self._known(agent)]

    def state(self) -> np.ndarray:
        """The room's true state for centralised critics (:attr:`state_space`): robot x, y, cos and sin of the
        heading, pan, goal x, y, each occluder's x, y, and ``cycle / max_cycles``, as float32."""
        return self.sim.state()[0]  # before the first reset() it raises RuntimeError, naming state()

    def _reset_sim(self, seed: int | None) -> None:
        self.sim.reset(seeds=None if seed is None else [seed])
        if seed is not None:
            self.np_random = np.random.default_rng(int(seed))
        self.agents = list(self.possible_agents)

    def _known(self, agent):
        if agent not in self.possible_agents:
            raise ValueError(f"unknown agent {agent!r}: expected one of {self.possible_agents}")
        return agent


@with_version_history
class raw_env(_Adapter, AECEnv):  # PettingZoo's naming convention
    """The active-perception room as a PettingZoo AEC env.

    Description:
        A robot must reach a red box in a room where green, yellow and blue boxes hide it.
        ``mover_0`` drives the base; ``looker_0`` pans the camera. They act in turns: the mover
        moves (the base is driven for one control period), then the looker sees
        the result and turns the camera (no time passes), then the mover sees that view. For both
        agents acting on the same view use :class:`parallel_env`, not PettingZoo's ``aec_to_parallel``
        of this env (it refuses this env, which does not set ``is_parallelizable``: setting it would
        give a game where the looker acts on another view than the mover).

    Action Space:
        ``mover_0``: ``Discrete(3)`` 0 to the left, 1 to the right, 2 forward: slides in the default room
        (v3), turns in v0-v2 (:func:`activeperc_env.mover_actions`).
        ``looker_0``: ``Discrete(3)`` 0 pan left, 1 hold, 2 pan right (``pan_step`` degrees).

    Observation Space:
        ``Dict(image=Box(0, 255, (height, width, 3), uint8), pan=Box(float32, (1,)))``: the
        first-person camera image and the camera's pan angle (radians, relative to the
        heading); with a range sensor (v1-v3) also ``range=Box(0, range_max, (range_rays,), float32)``, the
        distances along the range sensor's rays (right to left) to the nearest wall or occluder (never the goal).
        The looker observes the state after the move, the mover after the look.

    Rewards:
        The mover gets ``1 - 0.2 * t / max_cycles`` in the cycle ``t`` in which it reaches the
        goal, else 0. The looker gets the same (``looker_reward='shared'``, at the mover's turn, or
        ``'own_turn'``, at its own) or 0 (``'none'``).

    Starting State:
        Seeded per episode: the robot on the west side, heading within 90 degrees of the
        goal's bearing, the goal on the east side, ``num_obstacles`` occluders in between,
        the camera facing forward.

    Episode End:
        Terminated at the end of the cycle in which the robot reaches the goal; truncated at
        the end of cycle ``max_cycles``. Then both agents' ``info`` holds the episode's outcome:
        ``episode_success`` (the robot reached the goal) and ``episode_return`` (the mover's return).

    Arguments:
        render_mode: None, 'rgb_array' or 'human'.
        **config: any :class:`EnvConfig` field (the room and its options).
    """

    def __init__(self, render_mode: str | None = None, **config):
        AECEnv.__init__(self)
        self._setup(render_mode, config)
        self.agents = []

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        """Start an episode; ``seed`` fixes its layout (later unseeded resets continue the stream); ``options`` are
        ignored."""
        self._reset_sim(seed)
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self.infos = {agent: {} for agent in self.agents}
        obs = self._observe()
        self._obs = {MOVER: obs, LOOKER: obs}
        self._pending = (False, False, {})  # the ends and outcome of the cycle's move, applied after the look
        self._looker_due = 0.0  # with looker_reward='own_turn': the looker's reward of the move, given after its look
        self.agent_selection = MOVER
        if self.render_mode == "human":
            self.render()

    def observe(self, agent):
        """The latest observation of ``agent`` (a copy: changing it changes nothing the env keeps)."""
        agent = self._known(agent)
        self.sim.require_started("observe()")
        return _copy(self._obs[agent])

    def last(self, observe: bool = True):
        """PettingZoo's ``last()``: the selected agent's observation, reward, termination, truncation and info."""
        self.sim.require_started("last()")
        return super().last(observe)

    def step(self, action) -> None:
        """Apply the selected agent's action (``None`` for an agent whose episode is over)."""
        if not self.agents:  # PettingZoo's order-enforcing wrapper (env()) warns and stops this call before here
            raise self.sim.outside_episode("step()")
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        action = check_action(agent, action, self.action_spaces[agent])
        self._cumulative_rewards[agent] = 0.0
        if agent == MOVER:
            result = self.sim.move(action)
            looker_reward = float(result.looker_reward[0])
            own_turn = self.config.looker_reward == "own_turn"
            self.rewards = {MOVER: float(result.reward[0]), LOOKER: 0.0 if own_turn else looker_reward}
            self._pending = (bool(result.terminated[0]), bool(result.truncated[0]), result.outcome())
            self._looker_due = looker_reward if own_turn else 0.0
            self._obs[LOOKER] = self._observe()
            self.agent_selection = LOOKER
        else:
            self.sim.look(action)
            self.rewards = {MOVER: 0.0, LOOKER: self._looker_due}
            self._obs[MOVER] = self._observe()
            terminated, truncated, outcome = self._pending
            self.terminations = dict.fromkeys(self.agents, terminated)
            self.truncations = dict.fromkeys(self.agents, truncated)
            if terminated or truncated:
                self.infos = {agent: dict(outcome) for agent in self.agents}
            self.agent_selection = MOVER
        self._accumulate_rewards()
        if self.render_mode == "human":
            self.render()


class parallel_env(_Adapter, ParallelEnv):  # PettingZoo's naming convention
    """The active-perception room as a PettingZoo parallel env.

    Both agents act on the same observation; the look is applied after the move, and both
    then observe the result. Spaces, rewards, episode end and arguments are those of
    :class:`raw_env`.
    """

    def __init__(self, render_mode: str | None = None, **config):
        self._setup(render_mode, config)
        self.agents = []

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode; returns ``(observations, infos)`` (``options`` are ignored)."""
        self._reset_sim(seed)
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return {agent: _copy(obs) for agent in self.agents}, {agent: {} for agent in self.agents}

    def step(self, actions: dict):
        """One cycle: the mover's action, then the looker's; returns PettingZoo's five dicts."""
        if not self.agents:
            raise self.sim.outside_episode("step()")
        if not isinstance(actions, Mapping):
            raise ValueError(f"actions={actions!r} is invalid: expected a dict of actions of {self.agents}")
        unknown = sorted(set(actions) - set(self.agents))
        missing = sorted(set(self.agents) - set(actions))
        if unknown or missing:
            raise ValueError(f"actions must name exactly {self.agents}; unknown {unknown}, missing {missing}")
        move = check_action(MOVER, actions[MOVER], self.action_spaces[MOVER])
        look = check_action(LOOKER, actions[LOOKER], self.action_spaces[LOOKER])
        result = self.sim.move(np.array([move]))
        self.sim.look(np.array([look]))
        obs = self._observe()
        rewards = {MOVER: float(result.reward[0]), LOOKER: float(result.looker_reward[0])}
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        agents = self.agents
        info = result.outcome() if terminated or truncated else {}
        if terminated or truncated:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return (
            {agent: _copy(obs) for agent in agents},
            rewards,
            dict.fromkeys(agents, terminated),
            dict.fromkeys(agents, truncated),
            {agent: dict(info) for agent in agents},
        )


def _copy(obs: dict) -> dict:
    """An observation of its own, so that one agent's (or one call's) changes reach no other."""
    return {key: value.copy() for key, value in obs.items()}


class _OrderEnforcing(wrappers.OrderEnforcingWrapper):
    """PettingZoo's order-enforcing wrapper whose ``render`` passes on the mode some libraries give (RLlib's), and
    whose ``last`` and ``step`` after a reset go straight to the env (PettingZoo's reach every attribute through two
    ``__getattr__``: a tenth of a cycle)."""

    def last(self, observe: bool = True):
        """The env's ``last()``; before a reset, PettingZoo's error."""
        return self.env.last(observe) if self._has_reset else super().last(observe)

    def step(self, action) -> None:
        """The env's ``step()``; before a reset or after the episode, PettingZoo's error or warning."""
        if self._has_reset and self.env.agents:
            self._has_updated = True
            self.env.step(action)
        else:
            super().step(action)

    def render(self, mode: str | None = None):
        """The env's ``render`` (``mode`` may only repeat its ``render_mode``)."""
        check_render_mode(mode, self.unwrapped.render_mode)
        return super().render()


def env(render_mode: str | None = None, **config):
    """The AEC env wrapped in PettingZoo's order-enforcing wrapper (the usual entry point)."""
    return _OrderEnforcing(raw_env(render_mode=render_mode, **config))
