"""Gymnasium vector envs over one batched ``Simulator``: what ``gymnasium.make_vec`` gives for our ids.

``gymnasium.make_vec("activeperc/Joint-v1", num_envs=N)`` steps N rooms in one ``mujoco.batch.Batch`` and draws
their views as tiles of one offscreen buffer, instead of N single-room envs (N GL contexts, one read-back per
view) in Gymnasium's ``SyncVectorEnv``. Episodes are those of ``SyncVectorEnv`` over the single-room envs: the
same seeds (``reset(seed=s)`` gives room ``i`` the seed ``s + i``), the same autoreset, rewards, ends and infos.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from activeperc_env.checks import check_actions, check_seed
from activeperc_env.config import EnvConfig, is_int
from activeperc_env.core import HOLD, JOINT_ACTIONS, MoveResult, Simulator, split_joint
from activeperc_env.spaces import mover_space, observation_space


class _SingleAgentVectorEnv(VectorEnv):
    """N rooms of a single-agent view; subclasses map the agent's actions to moves and looks.

    Args:
        num_envs: the number of rooms N.
        render_mode: ``None`` or ``"rgb_array"`` (``render()`` gives every room's bird's-eye map).
        autoreset_mode: Gymnasium's ``AutoresetMode`` (or its value): ``NEXT_STEP`` (the default, as in
            ``SyncVectorEnv``), ``SAME_STEP`` (``info["final_obs"]`` and ``info["final_info"]`` hold what the
            finished rooms ended with) or ``DISABLED`` (reset finished rooms with ``options={"reset_mask": m}``).
        nthread: physics threads (0 uses every core).
        max_episode_steps: what ``gymnasium.make(..., max_episode_steps=k)`` does with its ``TimeLimit``: an
            episode is also truncated after ``k`` steps (``max_cycles`` stays the env's own end and the reward's T).
        disable_env_checker: accepted as ``gymnasium.make`` accepts it; a vector env has no checker to disable.
        **config: fields of :class:`activeperc_env.EnvConfig`.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": EnvConfig.control_hz}  # each env: its own

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        nthread: int = 0,
        max_episode_steps: int | None = None,
        disable_env_checker: bool = False,
        **config,
    ):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode={render_mode!r} is invalid for a vector env: expected None or 'rgb_array' "
                "('human' shows one room: use gymnasium.make)"
            )
        try:
            autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            modes = [mode.value for mode in AutoresetMode]
            raise ValueError(f"autoreset_mode={autoreset_mode!r} is invalid: expected one of {modes}") from None
        if max_episode_steps is not None and (not is_int(max_episode_steps) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps={max_episode_steps!r} is invalid: expected None or an int >= 1")
        self.max_episode_steps = max_episode_steps
        self.config = EnvConfig.from_kwargs(**config)
        self.sim = Simulator(self.config, num_envs=num_envs, nthread=nthread)
        self.num_envs = self.sim.num_envs
        self.render_mode = render_mode
        self.autoreset_mode = autoreset_mode
        self.metadata = {**self.metadata, "render_fps": self.config.control_hz, "autoreset_mode": autoreset_mode}
        self.single_observation_space = observation_space(self.config)
        self.single_action_space = self._agent_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._ended = np.zeros(self.num_envs, dtype=bool)  # rooms whose episode ended at the last step

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Start episodes in every room, or in those of ``options["reset_mask"]``.

        Args:
            seed: ``None`` (each room draws its layout from its own stream), an int ``s`` (room ``i`` gets
                ``s + i``, as in ``SyncVectorEnv``) or one int or ``None`` per room.
            options: ``{"reset_mask": (N,) bool array}`` resets only the rooms marked ``True``; as Gymnasium's
                vector envs do, the mask is taken out of ``options``.
        """
        if isinstance(seed, np.ndarray) and seed.ndim == 0:  # one seed as a 0-d array
            seed = seed.item()
        seeds = self._seeds(seed)
        mask = self._reset_mask(options)
        if not self.sim.started().all() and not mask.all():
            raise ResetNeeded("the first reset() must start every room: options['reset_mask'] is for later resets")
        super().reset(seed=int(seed) if is_int(seed) else None)
        ids = np.flatnonzero(mask)
        seeded = np.array([seeds[i] is not None for i in ids], dtype=bool)
        if seeded.any():
            self.sim.reset(ids[seeded], seeds=[seeds[i] for i in ids[seeded]])
        if not seeded.all():
            self.sim.reset(ids[~seeded])
        self._ended[mask] = False
        return self._observe(), {"cycle": np.zeros(self.num_envs, dtype=np.int64), "_cycle": mask.copy()}

    def step(self, actions):
        """One cycle in every room: the move, then the look; Gymnasium's five batched values.

        Under ``NEXT_STEP`` a room whose episode ended at the previous step is reset instead (reward 0,
        not terminated, not truncated, ``info["cycle"]`` 0), as ``SyncVectorEnv`` does.
        """
        if not self.sim.started().all():
            raise ResetNeeded("step() before reset(): call reset() first")
        actions = check_actions(actions, self.num_envs, int(self.single_action_space.n), self.AGENT, scalar=False)
        moves, looks = self._split(actions)
        if self.autoreset_mode == AutoresetMode.DISABLED and self._ended.any():
            raise RuntimeError(
                f"step() on the finished rooms {np.flatnonzero(self._ended).tolist()} with autoreset_mode DISABLED: "
                "reset them first with reset(options={'reset_mask': mask})"
            )
        restart = self._ended if self.autoreset_mode == AutoresetMode.NEXT_STEP else np.zeros_like(self._ended)
        play = np.flatnonzero(~restart)
        rewards = np.zeros(self.num_envs, dtype=np.float64)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        outcomes = {}
        if play.size:
            result = self.sim.move(moves[play], ids=play)
            self.sim.look(looks[play], ids=play)
            rewards[play], terminated[play], truncated[play] = result.reward, result.terminated, result.truncated
            outcomes = self._outcomes(play, result)
            if self.max_episode_steps is not None:
                truncated[play] |= self.sim.cycle[play] >= self.max_episode_steps
        if restart.any():
            self.sim.reset(np.flatnonzero(restart))
        self._ended = terminated | truncated
        infos = outcomes
        if self.autoreset_mode == AutoresetMode.SAME_STEP and self._ended.any():
            infos = self._final(np.flatnonzero(self._ended), outcomes)
            self.sim.reset(np.flatnonzero(self._ended))
        infos.update({"cycle": self.sim.cycle.copy(), "_cycle": np.ones(self.num_envs, dtype=bool)})
        return self._observe(), rewards, terminated, truncated, infos

    def render(self) -> tuple[np.ndarray, ...] | None:
        """``rgb_array``: one (240, 320, 3) bird's-eye map per room, as ``SyncVectorEnv`` gives; else ``None``."""
        if self.render_mode != "rgb_array":
            return None
        if not self.sim.started().all():
            raise ResetNeeded("render() before reset(): call reset() first")
        return tuple(self.sim.render_map(i) for i in range(self.num_envs))

    def close_extras(self, **kwargs) -> None:
        """Release the renderer (none where the constructor refused its arguments before building it)."""
        if "sim" in self.__dict__:
            self.sim.close()

    def _observe(self) -> dict:
        return self.sim.observe()

    def _outcomes(self, rooms: np.ndarray, result: MoveResult) -> dict:
        """``episode_success`` and ``episode_return`` of the rooms (of ``rooms``) whose episode the move ``result``
        ended, with their masks, as ``SyncVectorEnv`` gathers the one-room envs' infos."""
        over = result.terminated | result.truncated
        if not over.any():
            return {}
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[rooms[over]] = True
        success = np.zeros(self.num_envs, dtype=bool)
        success[rooms[over]] = result.success[over]
        returns = np.zeros(self.num_envs, dtype=np.float64)
        returns[rooms[over]] = result.episode_return[over]
        return {
            "episode_success": success,
            "_episode_success": mask,
            "episode_return": returns,
            "_episode_return": mask.copy(),
        }

    def _final(self, ended: np.ndarray, outcomes: dict) -> dict:
        """``SAME_STEP``'s ``final_obs`` and ``final_info`` (with the ``outcomes`` of the episodes the rooms ended) of
        the rooms ``ended``, before they are reset."""
        observation = self.sim.observe()  # every room drawn in its own tile, as after
        final_obs = np.full(self.num_envs, None, dtype=object)
        for i in ended:
            final_obs[i] = {key: value[i] for key, value in observation.items()}
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[ended] = True
        cycles = np.where(mask, self.sim.cycle, 0)
        return {
            "final_obs": final_obs,
            "_final_obs": mask,
            "final_info": {"cycle": cycles, "_cycle": mask.copy()} | outcomes,
            "_final_info": mask.copy(),
        }

    def _seeds(self, seed) -> list[int | None]:
        """One seed or ``None`` per room, checked before any room is reseeded."""
        if seed is None:
            return [None] * self.num_envs
        if is_int(seed):
            first = check_seed(seed, rooms=self.num_envs)
            return [first + i for i in range(self.num_envs)]
        if not isinstance(seed, (list, tuple, np.ndarray)) or len(seed) != self.num_envs:
            raise ValueError(
                f"seed={seed!r} is invalid: expected None, an int or a list of {self.num_envs} ints or None"
            )
        return [None if s is None else check_seed(s, f"seed[{room}]") for room, s in enumerate(seed)]

    def _reset_mask(self, options: dict | None) -> np.ndarray:
        """``options["reset_mask"]`` taken out of ``options`` and checked (as ``SyncVectorEnv`` does), or all rooms."""
        if options is not None and not isinstance(options, dict):
            raise TypeError(f"options={options!r} is invalid: expected None or a dict")
        mask = options.pop("reset_mask", None) if options is not None else None
        if mask is None:
            return np.ones(self.num_envs, dtype=bool)
        if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
            raise TypeError(f"options['reset_mask']={mask!r} is invalid: expected a ({self.num_envs},) bool array")
        if mask.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] has shape {mask.shape}: expected ({self.num_envs},)")
        if not mask.any():
            raise ValueError("options['reset_mask'] marks no room: expected at least one True")
        return mask

    AGENT = ""
    """What errors call the agent that acts."""

    def _agent_space(self) -> gym.spaces.Discrete:
        raise NotImplementedError

    def _split(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError


class JointVectorEnv(_SingleAgentVectorEnv):
    """N rooms of ``activeperc/Joint-v1``: actions ``3 * u_m + u_c``, one ``Discrete(9)`` per room."""

    AGENT = "joint agent"

    def _agent_space(self) -> gym.spaces.Discrete:
        return gym.spaces.Discrete(JOINT_ACTIONS)

    def _split(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return split_joint(actions)


class FixedForwardVectorEnv(_SingleAgentVectorEnv):
    """N rooms of ``activeperc/FixedForward-v1``: the mover's action per room, the camera held forward."""

    AGENT = "mover"

    def _agent_space(self) -> gym.spaces.Discrete:
        return mover_space()

    def _split(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return actions, np.full_like(actions, HOLD)
