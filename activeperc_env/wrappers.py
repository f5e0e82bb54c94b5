"""PettingZoo wrappers of the rooms for other libraries: :func:`image_only`, each agent's camera image as its whole
observation, for wrappers and models that need a ``Box`` (SuperSuit's ``agent_indicator_v0`` and ``black_death_v3``,
Stable-Baselines3's ``CnnPolicy``)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper, BaseWrapper


def image_only(env: AECEnv | ParallelEnv, floats: bool = False) -> AECEnv | ParallelEnv:
    """``env`` (:func:`~activeperc_env.env`, :class:`~activeperc_env.raw_env` or :class:`~activeperc_env.parallel_env`)
    with each agent observing its ``"image"`` alone: ``Box(0, 255, (height, width, channels), uint8)``, or with
    ``floats`` ``Box(0, 1, ..., float32)`` for models that do not convert bytes themselves (RLlib's). The pan and the
    range readings are dropped; actions, rewards and episodes are the env's."""
    if not isinstance(floats, bool):
        raise TypeError(f"floats={floats!r} is invalid: expected True or False")
    if isinstance(env, ParallelEnv):
        return _ParallelImageOnly(env, floats)
    if isinstance(env, AECEnv):
        return _ImageOnly(env, floats)
    raise TypeError(f"env={env!r} is invalid: expected a PettingZoo AEC or parallel env of activeperc_env")


class _Images:
    """The image space of each agent of ``self.env`` (one object per agent, as PettingZoo's API test asks), and the
    image of an observation."""

    def _image_spaces(self, floats: bool) -> None:
        observed = {agent: self.env.observation_space(agent) for agent in self.env.possible_agents}
        if not all("image" in getattr(space, "spaces", {}) for space in observed.values()):
            raise TypeError(f"{self.env!r} is invalid: its observations hold no 'image'")
        self._floats = floats
        self.observation_spaces = {
            agent: spaces.Box(0.0, 1.0, space["image"].shape, np.float32) if floats else space["image"]
            for agent, space in observed.items()
        }

    def _image(self, observation: dict) -> np.ndarray:
        image = observation["image"]
        return image.astype(np.float32) / 255 if self._floats else image

    def observation_space(self, agent: str):
        """``agent``'s image space."""
        return self.observation_spaces[agent]

    def render(self, *mode: str):
        """The env's ``render`` (RLlib passes the render mode, which may only repeat the env's own)."""
        return self.env.render(*mode)


class _ImageOnly(_Images, BaseWrapper):
    """An AEC env whose agents observe their image alone."""

    def __init__(self, env: AECEnv, floats: bool):
        super().__init__(env)
        self._image_spaces(floats)

    def observe(self, agent: str):
        """``agent``'s image."""
        observation = self.env.observe(agent)
        return None if observation is None else self._image(observation)


class _ParallelImageOnly(_Images, BaseParallelWrapper):
    """A parallel env whose agents observe their image alone."""

    def __init__(self, env: ParallelEnv, floats: bool):
        super().__init__(env)
        self._image_spaces(floats)

    def reset(self, seed: int | None = None, options: dict | None = None):
        """The env's ``reset``, with images for observations."""
        observations, infos = self.env.reset(seed=seed, options=options)
        return {agent: self._image(obs) for agent, obs in observations.items()}, infos

    def step(self, actions: dict):
        """The env's ``step``, with images for observations."""
        observations, *rest = self.env.step(actions)
        return {agent: self._image(obs) for agent, obs in observations.items()}, *rest
