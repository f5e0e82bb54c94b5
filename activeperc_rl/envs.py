"""TorchRL environment: the mover's batched env, with the looker inside its transition (one step is one cycle).

Its keys, looker and external modes, resets and seeding are in docs/training.md, "The TorchRL env".
"""

from __future__ import annotations

import inspect
import math

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from activeperc_env import LOOKER_ACTIONS, EnvConfig, Simulator
from activeperc_env.checks import check_actions
from activeperc_env.config import is_int
from activeperc_env.core import MOVER_ACTIONS
from activeperc_env.spaces import MAX_GEOM_ID

MOVER, LOOKER = "mover", "looker"


SPLITS = ("train", "eval")
MAX_FRAME_STACK = 16


def make_env(
    num_envs: int = 1,
    device="cpu",
    looker=None,
    seed: int | None = None,
    split: str = "train",
    first_room: int = 0,
    nthread: int = 0,
    look_views: bool = False,
    backend: str = "mujoco",
    frame_stack: int = 1,
    config: EnvConfig | None = None,
    **env_config,
):
    """Build the batched TorchRL env over one ``Simulator(num_envs)``.

    Args:
        num_envs: number of rooms (the env's ``batch_size`` is ``[num_envs]``).
        device: where observations, rewards and done flags live (images stay uint8).
        looker: the looker module (looker mode), or ``None`` for external mode (docs/training.md).
        seed: base seed of the rooms' layout streams (same as calling ``env.set_seed(seed)``);
            give E1 and E2 the same seed to give them the same reset sequence.
        split: ``"train"`` (even episode seeds) or ``"eval"`` (odd ones): the two never share a layout.
        first_room: index of this env's first room in a larger env whose rooms are split over several
            envs (worker processes): room ``i`` here gets the layouts of room ``first_room + i`` there.
        nthread: physics threads (0: every core this process may use).
        look_views: in looker mode, record what each look would have shown (see :class:`ActivePerceptionEnv`).
        backend: the rooms' physics and renderer: ``"mujoco"`` (CPU physics, OpenGL) or ``"warp"`` (MuJoCo Warp,
            on the GPU when ``device`` is one, else on Warp's CPU device).
        frame_stack: the latest cycles' views in each observation (1: the current view only; see
            :class:`ActivePerceptionEnv`).
        config: the room, as an :class:`~activeperc_env.EnvConfig`; or else
        **env_config: any :class:`~activeperc_env.EnvConfig` field (the others at their defaults).
    """
    if config is not None and env_config:
        raise ValueError(f"give the room as config or as EnvConfig fields, not both (got config and {env_config})")
    if config is not None and not isinstance(config, EnvConfig):
        raise TypeError(f"config={config!r} is invalid: expected an EnvConfig")
    env = ActivePerceptionEnv(
        config if config is not None else EnvConfig.from_kwargs(**env_config),
        num_envs=num_envs,
        device=device,
        looker=looker,
        nthread=nthread,
        split=split,
        first_room=first_room,
        look_views=look_views,
        backend=backend,
        frame_stack=frame_stack,
    )
    if seed is not None:
        env.set_seed(seed)
    return env


class ActivePerceptionEnv(EnvBase):
    """The active-perception rooms as one batched TorchRL env whose step is one full cycle.

    Args:
        config: the environment configuration.
        num_envs: number of rooms.
        device: device of the output tensors.
        looker: the looker module, or ``None`` (external mode).
        nthread: physics threads of the simulator (0: every core).
        split: ``"train"`` or ``"eval"``: the parity of the episode seeds.
        first_room: index of the first room in the seeding of a larger env split over several (see :func:`make_env`).
        look_views: in looker mode, also record under ``("looker", "look_views")`` the ``"image"`` (3, H, W, 3) and
            ``"pan"`` (3, 1) that 'pan left', 'hold' and 'pan right' would have given the mover in each cycle
            (:meth:`~activeperc_env.Simulator.look_views`): the views meta's credit for every look values, which the
            looker reads too.
        backend: the simulator's backend (:func:`make_env`).
        frame_stack: the views of the latest ``frame_stack`` cycles in every observation: its ``image`` stacks them
            on the channels, ``(*batch, H, W, 3 * frame_stack)`` oldest first, and its ``pan`` holds their pans,
            ``(*batch, frame_stack)``; the looker's views and ``look_views`` end with the view they show. A room's
            first observation repeats its start view. The range stays the current reading.
    """

    def __init__(
        self,
        config: EnvConfig,
        num_envs: int = 1,
        device="cpu",
        looker=None,
        nthread: int = 0,
        split: str = "train",
        first_room: int = 0,
        look_views: bool = False,
        backend: str = "mujoco",
        frame_stack: int = 1,
    ):
        if split not in SPLITS:
            raise ValueError(f"split={split!r} is invalid: expected one of {SPLITS}")
        if not is_int(num_envs) or num_envs < 1:
            raise ValueError(f"num_envs={num_envs!r} is invalid: expected an int >= 1")
        if not is_int(first_room) or first_room < 0:
            raise ValueError(f"first_room={first_room!r} is invalid: expected an int >= 0")
        if not is_int(frame_stack) or not 1 <= frame_stack <= MAX_FRAME_STACK:
            raise ValueError(f"frame_stack={frame_stack!r} is invalid: expected an int in 1 .. {MAX_FRAME_STACK}")
        num_envs, first_room = int(num_envs), int(first_room)
        self.frame_stack = int(frame_stack)
        super().__init__(device=torch_device(device), batch_size=[num_envs])
        self.first_room = first_room
        self.split = split
        self.look_views = bool(look_views)
        self.config = config
        self.num_envs = num_envs
        on_gpu = self.device is not None and self.device.type == "cuda"
        warp_device = str(self.device) if backend == "warp" and on_gpu else "cpu"
        self.sim = Simulator(config, num_envs=num_envs, nthread=nthread, backend=backend, device=warp_device)
        self._device_images = backend == "warp"  # the views are drawn where the env's tensors live: read them there
        self.episode_seeds = np.zeros(num_envs, dtype=np.int64)
        # how each room's latest step ended it: a room left out of a partial step reports these again
        self._terminated = np.zeros(num_envs, dtype=bool)
        self._truncated = np.zeros(num_envs, dtype=bool)
        self._seed_rngs = [np.random.default_rng() for _ in range(num_envs)]
        past = self.frame_stack - 1  # each room's views of the cycles before, oldest first
        self._past_images = torch.zeros(
            (num_envs, config.height, config.width, 3 * past), dtype=torch.uint8, device=self.device
        )
        self._past_pans = torch.zeros((num_envs, past), dtype=torch.float32, device=self.device)
        self._looker = None
        self._looker_spec = Composite(shape=self.batch_size, device=self.device)
        self._make_specs()
        self.set_looker(looker)
        self.is_closed = False

    # ------------------------------------------------------------------ specs
    def _make_specs(self) -> None:
        n, cfg = self.batch_size, self.config
        limit = math.radians(cfg.pan_range)
        k = self.frame_stack
        self._obs_spec = Composite(
            image=Bounded(0, 255, (*n, cfg.height, cfg.width, 3 * k), dtype=torch.uint8, device=self.device),
            pan=Bounded(-limit, limit, (*n, k), dtype=torch.float32, device=self.device),
            shape=n,
            device=self.device,
        )
        if cfg.range_rays:
            self._obs_spec["range"] = Bounded(
                0.0, cfg.range_max, (*n, cfg.range_rays), dtype=torch.float32, device=self.device
            )
        if cfg.depth:
            self._obs_spec["depth"] = Unbounded((*n, cfg.height, cfg.width), dtype=torch.float32, device=self.device)
        if cfg.segmentation:
            self._obs_spec["segmentation"] = Bounded(
                -1, MAX_GEOM_ID, (*n, cfg.height, cfg.width), dtype=torch.int32, device=self.device
            )
        self._outcome_spec = Composite(
            episode_success=Categorical(2, (*n, 1), dtype=torch.bool, device=self.device),
            episode_return=Unbounded((*n, 1), dtype=torch.float32, device=self.device),
            shape=n,
            device=self.device,
        )
        reward = Unbounded((*n, 1), dtype=torch.float32, device=self.device)
        self.full_reward_spec = Composite(
            {MOVER: Composite(reward=reward, shape=n), LOOKER: Composite(reward=reward.clone(), shape=n)},
            shape=n,
            device=self.device,
        )
        flag = Categorical(2, (*n, 1), dtype=torch.bool, device=self.device)
        self.full_done_spec = Composite(
            done=flag, terminated=flag.clone(), truncated=flag.clone(), shape=n, device=self.device
        )

    def _action_spec(self, agent: str) -> Composite:
        actions = MOVER_ACTIONS if agent == MOVER else len(LOOKER_ACTIONS)
        action = Categorical(actions, self.batch_size, dtype=torch.int64, device=self.device)
        return Composite(action=action, shape=self.batch_size, device=self.device)

    def _update_specs(self) -> None:
        n = self.batch_size
        actions = {MOVER: self._action_spec(MOVER)}
        observations = {MOVER: Composite(observation=self._obs_spec.clone(), shape=n)}
        observations[MOVER].update(self._outcome_spec.clone())
        if self._looker is None:
            actions[LOOKER] = self._action_spec(LOOKER)
        else:
            observations[LOOKER] = self._looker_spec.clone()
        self.full_action_spec = Composite(actions, shape=n, device=self.device)
        self.full_observation_spec = Composite(observations, shape=n, device=self.device)
        self.empty_cache()

    # ------------------------------------------------------------------ looker
    @property
    def looker(self):
        """The looker module run inside each step, or ``None`` (external mode)."""
        return self._looker

    def set_looker(self, module) -> None:
        """Put ``module`` in the loop (``None``: external mode); the specs are rebuilt.

        The module is dry-run once on zeros (under a forked torch RNG, so seeding is unaffected)
        to find the entries it writes; they must all lie under ``"looker"``. A ``TransformedEnv`` around
        this env keeps its own copy of the specs: call ``empty_cache()`` on it after this (or set the looker
        before wrapping).
        """
        if module is None:
            self._looker = None
            self._update_specs()
            return
        n = self.batch_size
        spec = Composite(observation=self._obs_spec.clone(), shape=n, device=self.device)
        if self.look_views:
            image, pan = self._obs_spec["image"], self._obs_spec["pan"]
            looks = len(LOOKER_ACTIONS)
            spec["look_views"] = Composite(
                image=Bounded(0, 255, (*n, looks, *image.shape[1:]), dtype=torch.uint8, device=self.device),
                pan=Bounded(pan.space.low.min(), pan.space.high.max(), (*n, looks, *pan.shape[1:]), device=self.device),
                shape=n,
                device=self.device,
            )
        fake = TensorDict({LOOKER: spec.zero()}, batch_size=n, device=self.device)  # what the looker reads
        devices = [self.device] if self.device is not None and self.device.type == "cuda" else []
        with torch.no_grad(), torch.random.fork_rng(devices=devices):
            out = module(fake.clone())
        out = fake if out is None else out
        new = set(out.keys(True, True)) - set(fake.keys(True, True))
        outside = sorted(str(k) for k in new if not (isinstance(k, tuple) and k[0] == LOOKER))
        if outside or (LOOKER, "action") not in new:
            raise ValueError(
                f"the looker module must write ({LOOKER!r}, 'action') and only entries under {LOOKER!r}; "
                f"it wrote {sorted(map(str, new))}"
            )
        for key in sorted(new, key=str):
            value = out.get(key)
            if key == (LOOKER, "action"):
                _check_looker_action(value, n[0])
                spec[key[1:]] = Categorical(len(LOOKER_ACTIONS), value.shape, dtype=value.dtype, device=self.device)
            else:
                spec[key[1:]] = Unbounded(value.shape, dtype=value.dtype, device=self.device)
        self._looker = module
        self._looker_spec = spec
        self._update_specs()

    # ------------------------------------------------------------------ EnvBase API
    def _reset(self, tensordict: TensorDictBase | None = None, seed: int | None = None, **kwargs) -> TensorDictBase:
        unknown = sorted(set(kwargs) - {"set_state", "rooms_state"})  # set_state: TorchRL's own keyword
        if unknown:
            raise TypeError(f"reset() got unknown keyword argument(s) {unknown}; it takes seed= and rooms_state=")
        if seed is not None:
            self._set_seed(seed)
        mask = None if tensordict is None else tensordict.get("_reset", None)
        if kwargs.get("rooms_state") is not None:
            if mask is not None:
                raise ValueError("reset(rooms_state=...) resumes every room: it takes no '_reset' mask")
            return self._resume(kwargs["rooms_state"])
        if mask is None:
            ids = np.arange(self.num_envs)
        else:
            ids = mask.reshape(self.num_envs).nonzero().squeeze(-1).cpu().numpy()
        observation = self._obs_spec.zero()
        if len(ids):
            parity = SPLITS.index(self.split)
            seeds = np.array([2 * self._seed_rngs[i].integers(2**62) + parity for i in ids], dtype=np.int64)
            self.sim.reset(ids, seeds)
            self.episode_seeds[ids] = seeds
            self._terminated[ids] = self._truncated[ids] = False
            start = self._current(ids)
            index = torch.from_numpy(ids).to(self._past_pans.device)
            self._past_images[index] = start["image"].repeat(1, 1, 1, self.frame_stack - 1)
            self._past_pans[index] = start["pan"].repeat(1, self.frame_stack - 1)
            for key, value in self._stacked(start, index).items():
                observation[key][index] = value
        return self._reset_output(observation)

    def _reset_output(self, observation: TensorDictBase) -> TensorDict:
        """What a reset returns: the mover's ``observation``, the rooms' outcomes and the looker's placeholders."""
        out = TensorDict({MOVER: {"observation": observation}}, batch_size=self.batch_size, device=self.device)
        out.update({MOVER: self._outcomes()})
        if self._looker is not None:
            out.set(LOOKER, self._looker_spec.zero())
        return out

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        n = self.num_envs
        # TorchRL's partial steps (rollout(break_when_all_done=True)): only the rooms of the "_step" mask act; the
        # others keep their state and report a zero reward and their done flags
        mask = tensordict.get("_step", None)
        ids = np.arange(n) if mask is None else mask.reshape(n).nonzero().squeeze(-1).cpu().numpy()
        moves = _to_numpy(tensordict.get((MOVER, "action")), n, MOVER)[ids]
        if self._looker is None:  # checked before the move: a bad look leaves the rooms as they were
            looks = _to_numpy(tensordict.get((LOOKER, "action")), n, LOOKER)[ids]
            looks = check_actions(looks, len(ids), len(LOOKER_ACTIONS), LOOKER, LOOKER_ACTIONS)
        result = self.sim.move(moves, ids)
        out = TensorDict(batch_size=self.batch_size, device=self.device)
        if self._looker is None:
            self.sim.look(looks, ids)
        else:
            record = TensorDict({LOOKER: {"observation": self._observe()}}, batch_size=self.batch_size)
            if self.look_views:  # drawn before the look: a looker may pick by them
                image, pan = self._stacked_look_views()
                views = TensorDict({"image": image, "pan": pan}, batch_size=self.batch_size)
                record.set((LOOKER, "look_views"), views)
            with torch.no_grad():
                written = self._looker(record)
            record = (record if written is None else written).get(LOOKER)
            if self.look_views:
                record.set("look_views", views)
            self.sim.look(_to_numpy(record.get("action"), n, LOOKER)[ids], ids)
            out.set(LOOKER, record.select(*self._looker_spec.keys(True, True)))
        observation = self._observe()
        self._remember(observation, ids)
        out.set((MOVER, "observation"), observation)
        out.update({MOVER: self._outcomes()})
        for agent, reward in ((MOVER, result.reward), (LOOKER, result.looker_reward)):
            rewards = np.zeros(n, dtype=np.float32)
            rewards[ids] = reward
            out.set((agent, "reward"), torch.from_numpy(rewards).reshape(n, 1).to(self.device))
        self._terminated[ids], self._truncated[ids] = result.terminated, result.truncated
        terminated = torch.from_numpy(self._terminated.copy()).reshape(n, 1).to(self.device)
        truncated = torch.from_numpy(self._truncated.copy()).reshape(n, 1).to(self.device)
        out.set("terminated", terminated)
        out.set("truncated", truncated)
        out.set("done", terminated | truncated)
        return out

    def _set_seed(self, seed: int | None) -> None:
        """Give room ``i`` the episode-seed stream ``SeedSequence(seed, spawn_key=(first_room + i,))``."""
        if seed is not None and not (is_int(seed) and seed >= 0):  # any entropy SeedSequence takes, not a room seed
            raise ValueError(f"seed={seed!r} is invalid: expected None or an int >= 0")
        self._seed_rngs = [
            np.random.default_rng(
                None if seed is None else np.random.SeedSequence(seed, spawn_key=(self.first_room + i,))
            )
            for i in range(self.num_envs)
        ]

    def rooms_state(self) -> dict:
        """The rooms' state (the simulator's :meth:`~activeperc_env.Simulator.get_state`, the episode seeds and
        their streams, how each room's last step ended), as plain arrays: with :meth:`load_rooms_state` an env of
        the same config and ``num_envs`` goes on exactly as this one (what a resumed training run needs)."""
        return {
            "sim": self.sim.get_state(),
            "episode_seeds": self.episode_seeds.copy(),
            "seed_rngs": [rng.bit_generator.state for rng in self._seed_rngs],
            "terminated": self._terminated.copy(),
            "truncated": self._truncated.copy(),
            "past_images": self._past_images.to("cpu", copy=True).numpy(),
            "past_pans": self._past_pans.to("cpu", copy=True).numpy(),
        }

    def load_rooms_state(self, state: dict) -> None:
        """Restore what :meth:`rooms_state` returned; ``ValueError`` when it is of another number of rooms or frame
        stack (and the env is left as it was)."""
        for key in ("episode_seeds", "terminated", "truncated"):
            if np.shape(state[key]) != (self.num_envs,):
                raise ValueError(f"its {key} of shape {np.shape(state[key])} do not fit {self.num_envs} rooms")
        # states saved before frame stacks existed hold none (their envs stacked none)
        pasts = {key: getattr(self, f"_{key}") for key in ("past_images", "past_pans")} if self.frame_stack > 1 else {}
        for key, past in pasts.items():
            if np.shape(state[key]) != tuple(past.shape):
                raise ValueError(f"its {key} of shape {np.shape(state[key])} do not fit this env's frame stack")
        self.sim.set_state(state["sim"])
        self.episode_seeds[:] = state["episode_seeds"]
        for rng, saved in zip(self._seed_rngs, state["seed_rngs"], strict=True):
            rng.bit_generator.state = saved
        self._terminated[:] = state["terminated"]
        self._truncated[:] = state["truncated"]
        for key, past in pasts.items():
            past[:] = torch.as_tensor(np.asarray(state[key])).to(past.device)

    def random_state(self) -> torch.Tensor:
        """The torch random state of the process this env steps in: in a collector's worker, the stream its policy
        and looker draw from."""
        return torch.get_rng_state()

    def set_random_state(self, state: torch.Tensor) -> None:
        """Restore what :meth:`random_state` returned."""
        torch.set_rng_state(state)

    def _resume(self, state: dict) -> TensorDictBase:
        """Load ``state`` (:meth:`rooms_state`) and return the rooms' observation as a reset does, starting no
        episode: ``reset(rooms_state=...)``, how a collector resumes where a checkpoint left its rooms."""
        self.load_rooms_state(state)
        return self._reset_output(self._observe())

    def close(self, *, raise_if_closed: bool = True) -> None:
        """Release the simulator's renderer."""
        self.sim.close()
        super().close(raise_if_closed=raise_if_closed)

    def _outcomes(self) -> TensorDict:
        """Every room's ``episode_success`` and ``episode_return`` (the simulator's) on ``device``."""
        outcomes = {"episode_success": self.sim.success, "episode_return": self.sim.episode_return.astype(np.float32)}
        values = {key: torch.from_numpy(value.copy()).reshape(self.num_envs, 1) for key, value in outcomes.items()}
        return TensorDict(values, batch_size=self.batch_size).to(self.device)

    def _observe(self) -> TensorDict:
        """The current observation of every room (:meth:`~activeperc_env.Simulator.observe`), after the room's past
        views when it stacks frames, on ``device``."""
        observation = self._stacked(self._current(), slice(None))
        return TensorDict(observation, batch_size=self.batch_size, device=self.device)

    def _current(self, ids: np.ndarray | None = None) -> dict[str, torch.Tensor]:
        """The simulator's observation of the rooms ``ids`` (all when ``None``) as tensors on ``device``: the warp
        backend's views copied where they were drawn, the rest from the host."""
        observation = self.sim.observe(ids, device_images=self._device_images)
        return {
            key: (torch.from_numpy(value) if isinstance(value, np.ndarray) else _copied(value)).to(self.device)
            for key, value in observation.items()
        }

    def _stacked(self, observation: dict[str, torch.Tensor], index) -> dict[str, torch.Tensor]:
        """The ``observation`` of the rooms at ``index`` (a slice or a tensor of rooms) with their past views before
        its image and pan."""
        if self.frame_stack == 1:
            return observation
        past = {"image": self._past_images[index], "pan": self._past_pans[index]}
        return observation | {key: _after(value, observation[key]) for key, value in past.items()}

    def _stacked_look_views(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The simulator's :meth:`~activeperc_env.Simulator.look_views` of every room on ``device``, each after the
        room's past views: images ``(n, 3, H, W, 3 * frame_stack)`` and pans ``(n, 3, frame_stack)``."""
        views, pans = (torch.from_numpy(value).to(self.device) for value in self.sim.look_views())
        if self.frame_stack == 1:
            return views, pans
        return _after(self._past_images[:, None], views), _after(self._past_pans[:, None], pans)

    def _remember(self, observation: TensorDict, ids: np.ndarray) -> None:
        """Keep the latest views of the rooms ``ids`` (every room's stacked ``observation`` at a cycle's end) as their
        past views."""
        if self.frame_stack == 1 or not len(ids):
            return
        index = torch.from_numpy(ids).to(self._past_pans.device)
        self._past_images[index] = observation["image"][index, ..., 3:]
        self._past_pans[index] = observation["pan"][index, 1:]


# TorchRL's metaclass shows the constructor as (*args, **kwargs) to help() and IDEs: give them its real arguments
_init = inspect.signature(ActivePerceptionEnv.__init__)
ActivePerceptionEnv.__signature__ = _init.replace(parameters=list(_init.parameters.values())[1:])


def _check_looker_action(action: torch.Tensor, n: int) -> None:
    if action.is_floating_point() or action.is_complex() or action.shape not in ((n,), (n, 1)):
        raise ValueError(
            f"the looker module wrote ('looker', 'action') of shape {tuple(action.shape)} and dtype "
            f"{action.dtype}: expected integers of shape ({n},) or ({n}, 1) in Discrete(3) {LOOKER_ACTIONS}"
        )


def _after(past: torch.Tensor, current: torch.Tensor) -> torch.Tensor:
    """``past`` (repeated over ``current``'s axes where it has length 1) before ``current`` on the last axis."""
    return torch.cat([past.expand(*current.shape[:-1], past.shape[-1]), current], dim=-1)


def _copied(views) -> torch.Tensor:
    """A tensor copy of views that lie on the warp backend's device (any DLPack array), made where they lie."""
    return torch.from_dlpack(views).clone()


def latest_view(image):
    """The latest view of observation images (``(..., H, W, 3 * frame_stack)``, a frame stack's last three channels;
    the image itself without one)."""
    return image[..., -3:]


def torch_device(device) -> torch.device | None:
    """``device`` (a name such as ``"cpu"`` or ``"cuda:0"``, ``"auto"``: cuda when torch sees a GPU, or a
    ``torch.device``) as a ``torch.device``, ``None`` (TorchRL's env without a device) as it is; ``ValueError``
    naming it when torch knows no such device or it is a GPU that torch does not see."""
    if device is None:
        return None
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        resolved = torch.device(device)
    except (RuntimeError, TypeError) as error:
        raise ValueError(f"device={device!r} is invalid: {error}") from None
    if resolved.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device={device!r} is invalid: torch sees no CUDA device")
    return resolved


def _to_numpy(action: torch.Tensor | None, n: int, agent: str) -> np.ndarray:
    if action is None:
        raise KeyError(f"({agent!r}, 'action') missing from the input tensordict")
    if action.numel() != n:
        raise ValueError(
            f"({agent!r}, 'action') of shape {tuple(action.shape)} is invalid: expected {n} action indices, "
            f"shape ({n},) or ({n}, 1) (one-hot actions are not taken)"
        )
    return action.detach().reshape(n).cpu().numpy()
