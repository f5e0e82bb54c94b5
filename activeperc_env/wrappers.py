"""PettingZoo wrappers of the rooms for other libraries: :func:`image_only`, each agent's camera image as its whole
observation, for wrappers and models that need a ``Box`` (SuperSuit's ``agent_indicator_v0`` and ``black_death_v3``,
Stable-Baselines3's ``CnnPolicy``)."""

from __future__ import annotations

from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper, BaseWrapper


def image_only(env: AECEnv | ParallelEnv) -> AECEnv | ParallelEnv:
    """``env`` (:func:`~activeperc_env.env`, :class:`~activeperc_env.raw_env` or :class:`~activeperc_env.parallel_env`)
    with each agent observing its ``"image"`` alone: ``Box(0, 255, (height, width, channels), uint8)``. The pan and
    the range readings are dropped; actions, rewards and episodes are the env's."""
    if isinstance(env, ParallelEnv):
        return _ParallelImageOnly(env)
    if isinstance(env, AECEnv):
        return _ImageOnly(env)
    raise TypeError(f"env={env!r} is invalid: expected a PettingZoo AEC or parallel env of activeperc_env")


class _Images:
    """The image space of each agent of ``self.env``, one object per agent as PettingZoo's API test asks."""

    def _image_spaces(self) -> None:
        spaces = {agent: self.env.observation_space(agent) for agent in self.env.possible_agents}
        if not all("image" in getattr(space, "spaces", {}) for space in spaces.values()):
            raise TypeError(f"{self.env!r} is invalid: its observations hold no 'image'")
        self.observation_spaces = {agent: space["image"] for agent, space in spaces.items()}

    def observation_space(self, agent: str):
        """``agent``'s image space."""
        return self.observation_spaces[agent]

    def render(self, *mode: str):
        """The env's ``render`` (RLlib passes the render mode, which may only repeat the env's own)."""
        return self.env.render(*mode)


class _ImageOnly(_Images, BaseWrapper):
    """An AEC env whose agents observe their image alone."""

    def __init__(self, env: AECEnv):
        super().__init__(env)
        self._image_spaces()

    def observe(self, agent: str):
        """``agent``'s image."""
        observation = self.env.observe(agent)
        return None if observation is None else observation["image"]


class _ParallelImageOnly(_Images, BaseParallelWrapper):
    """A parallel env whose agents observe their image alone."""

    def __init__(self, env: ParallelEnv):
        super().__init__(env)
        self._image_spaces()

    def reset(self, seed: int | None = None, options: dict | None = None):
        """The env's ``reset``, with images for observations."""
        observations, infos = self.env.reset(seed=seed, options=options)
        return {agent: obs["image"] for agent, obs in observations.items()}, infos

    def step(self, actions: dict):
        """The env's ``step``, with images for observations."""
        observations, *rest = self.env.step(actions)
        return {agent: obs["image"] for agent, obs in observations.items()}, *rest
