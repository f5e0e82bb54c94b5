"""The batched simulator core: N rooms, their physics, episode logic and rendering.

Every adapter (PettingZoo, Gymnasium, TorchRL) drives this one class, so the same episode seed gives
the same episode through every API (the TorchRL env draws each room's episode seeds from its base seed:
its ``episode_seeds`` are what to give the others). One cycle of the paper's section 2 is two calls:

1. ``move(u_m)``: the wheels are driven for one control period; reward, termination and
   truncation are computed; ``render()`` then gives ``s_bar``, the looker's observation.
2. ``look(u_c)``: the pan joint turns; no simulated time passes and the base does not move;
   ``render()`` then gives ``s'``, the mover's next observation.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass

import mujoco
import mujoco.batch
import numpy as np

from activeperc_env import names, sensors
from activeperc_env.checks import check_actions, check_seed
from activeperc_env.config import LAYERS, EnvConfig, is_int, physics_steps, saved_room
from activeperc_env.layout import sample_layout
from activeperc_env.render import TiledRenderer
from activeperc_env.warp_backend import WarpBatch, WarpRenderer, check_backend

MOVER_ACTIONS = 3  # the mover's actions in every room: 0 to the left, 1 to the right, 2 forward (the room names them)
LOOKER_ACTIONS = ("pan_left", "hold", "pan_right")
HOLD = LOOKER_ACTIONS.index("hold")  # the look that keeps the camera where it is
JOINT_ACTIONS = MOVER_ACTIONS * len(LOOKER_ACTIONS)  # one agent's joint action a = 3 u_m + u_c
SUCCESS_DISTANCE = names.GOAL_HALF + names.ROBOT_RADIUS + 0.1
MAX_ENVS = 2**16  # the most rooms one simulator holds
STATE_KEYS = ("config", "physics", "cycle", "done", "rngs")  # what every state of get_state holds
OUTCOME_KEYS = ("success", "episode_return")  # what get_state holds too; states saved before them lack them


@dataclass
class MoveResult:
    """What one move did to each simulation of the call, as (n,) arrays."""

    reward: np.ndarray
    """The mover's reward ``r(s, u_m)``: ``1 - 0.2 t / T`` on success, else 0 (float64)."""
    looker_reward: np.ndarray
    """The looker's reward for the same cycle: the mover's (``looker_reward`` 'shared' or 'own_turn'), or 0 ('none')."""
    terminated: np.ndarray
    """The robot reached the goal."""
    truncated: np.ndarray
    """The episode reached ``max_cycles`` without success."""
    success: np.ndarray
    """The robot reached the goal: the episode's outcome where it ended, False while it runs."""
    episode_return: np.ndarray
    """The mover's rewards summed over the episode, this move's included: its return where it ended (float64)."""

    def outcome(self, index: int = 0) -> dict:
        """Move ``index``'s outcome as the envs' ``info`` of an episode's last step: ``episode_success`` (bool) and
        ``episode_return`` (float)."""
        return {"episode_success": bool(self.success[index]), "episode_return": float(self.episode_return[index])}


def load_model(config: EnvConfig) -> mujoco.MjModel:
    """Compile the room's scene, set its camera to the configured field of view and hide the occluders left parked.

    Occluders beyond ``num_obstacles`` stand far outside the room, beyond every camera's far plane, so no view
    shows them; taking them out of the renderer's scene (a geom group no view draws) leaves every pixel as it
    was and saves their draw calls.
    """
    model = mujoco.MjModel.from_xml_path(str(config.room.scene))
    eye = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, names.EYE_CAMERA)
    model.cam_fovy[eye] = config.fovy
    for body in names.OCCLUDER_BODIES[config.num_obstacles :]:
        model.geom_group[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, body)] = names.HIDDEN_GROUP
    return model


class Simulator:
    """N independent rooms stepped together; all game logic lives here.

    Args:
        config: the environment configuration (defaults when ``None``).
        num_envs: number of rooms N.
        nthread: physics threads (``mujoco.batch.Batch``); 0 uses every core.
        backend: ``"mujoco"`` (MuJoCo's CPU physics and OpenGL views) or ``"warp"`` (MuJoCo Warp's physics and
            batch renderer on ``device``: :mod:`activeperc_env.warp_backend`).
        device: where the ``"warp"`` backend runs: ``"cuda"`` (``"cuda:N"``) or ``"cpu"`` (slow, for tests).

    Every room must be reset before it is stepped, looked at or observed: before its first :meth:`reset` it holds
    no episode, and those calls raise ``RuntimeError``.
    """

    def __init__(
        self,
        config: EnvConfig | None = None,
        num_envs: int = 1,
        nthread: int = 0,
        backend: str = "mujoco",
        device: str = "cpu",
    ):
        if config is not None and not isinstance(config, EnvConfig):
            raise TypeError(f"config={config!r} is invalid: expected an EnvConfig (EnvConfig(**options)) or None")
        if not is_int(num_envs) or not 1 <= num_envs <= MAX_ENVS:
            raise ValueError(f"num_envs={num_envs!r} is invalid: expected an int in 1 .. {MAX_ENVS}")
        if not is_int(nthread) or nthread < 0:
            raise ValueError(f"nthread={nthread!r} is invalid: expected an int >= 0 (0: every core)")
        check_backend(backend, device)
        self.backend, self.device = backend, device
        self.config = config if config is not None else EnvConfig()
        self.num_envs = num_envs = int(num_envs)
        self.model = load_model(self.config)
        self.substeps = physics_steps(self.config)
        nthread = min(nthread or usable_cpus(), num_envs)
        if backend == "warp":
            self._batch = WarpBatch(self.model, num_envs, nthread=nthread, device=device)
        else:
            self._batch = mujoco.batch.Batch(self.model, num_envs, nthread=nthread)
        self._qpos = self._batch.bind("qpos")
        self._qvel = self._batch.bind("qvel")
        self._ctrl = self._batch.bind("ctrl")
        self._mocap_pos = self._batch.bind("mocap_pos")
        self._ids = _Ids(self.model)
        self._base = self.config.room.base(self.model, self.config.forward_speed, self.config.turn_speed)
        self._ray_angles = sensors.ray_angles(self.config.range_rays)
        # the latest range readings of every room, and which are still those of the base's pose (a look leaves them)
        self._ranges = np.zeros((num_envs, self.config.range_rays), dtype=np.float32)
        self._ranged = np.zeros(num_envs, dtype=bool)
        self._occluders_used = list(self._ids.occluders[: self.config.num_obstacles])  # their rows of mocap_pos
        self._layers_on = tuple(name for name in LAYERS if getattr(self.config, name))  # observed besides the image
        self._renderer: TiledRenderer | WarpRenderer | None = None
        self._views: np.ndarray | None = None  # the latest first-person view of every room
        # the tile of the offscreen buffer each view in _views was drawn in; -1 once the room has changed
        self._tiles = np.full(num_envs, -1)
        self.cycle = np.zeros(num_envs, dtype=np.int64)
        self.done = np.ones(num_envs, dtype=bool)
        self.success = np.zeros(num_envs, dtype=bool)  # whether each room's episode reached the goal
        self.episode_return = np.zeros(num_envs)  # the mover's rewards summed over each room's episode
        self._all_started = False  # whether every room has had its first reset (see require_started)
        self._rngs = [np.random.default_rng() for _ in range(num_envs)]
        self._pan_deltas = math.radians(self.config.pan_step) * np.array([1.0, 0.0, -1.0])
        self._pan_limit = math.radians(self.config.pan_range)

    # ----------------------------------------------------------------- state and copies
    def get_state(self) -> dict:
        """Everything the rooms' future depends on, as plain data: the config, MuJoCo's state rows of every room
        (solver warm start included), the cycle counters, which rooms are done, their episodes' outcomes so far, and
        each room's random stream. With :meth:`set_state` on a simulator of the same config and ``num_envs``, it steps
        on exactly as this one."""
        return {
            "config": dataclasses.asdict(self.config),
            "physics": self._batch.state.copy(),
            "cycle": self.cycle.copy(),
            "done": self.done.copy(),
            "success": self.success.copy(),
            "episode_return": self.episode_return.copy(),
            "rngs": [rng.bit_generator.state for rng in self._rngs],
        }

    def set_state(self, state: dict) -> None:
        """Restore what :meth:`get_state` returned; ``ValueError`` when it is of another config or number of rooms."""
        missing = [key for key in STATE_KEYS if key not in state] if isinstance(state, dict) else list(STATE_KEYS)
        if missing:
            raise ValueError(f"a state without {missing} is not one of get_state()'s")
        ours = dataclasses.asdict(self.config)
        theirs = saved_room(state["config"])
        if theirs != ours:
            differ = sorted(k for k in ours.keys() | theirs.keys() if theirs.get(k) != ours.get(k))
            raise ValueError(f"a state of rooms of another config (differs in {differ}) does not fit this simulator")
        physics = np.asarray(state["physics"])
        per_room = {np.shape(state[key]) for key in ("cycle", "done", *OUTCOME_KEYS) if key in state}
        per_room.add((len(state["rngs"]),))
        if physics.shape != self._batch.state.shape or per_room != {(self.num_envs,)}:
            raise ValueError(
                f"a state of physics rows {physics.shape} and {len(state['rngs'])} rooms does not fit this simulator "
                f"({self._batch.state.shape}, {self.num_envs} rooms)"
            )
        self._batch.state[:] = physics
        self.cycle[:] = state["cycle"]
        self.done[:] = state["done"]
        # a state saved before outcomes were kept: its rooms paid only at the goal, which ends an episode, so a
        # running room had no success and a return of 0
        self.success[:] = state.get("success", False)
        self.episode_return[:] = state.get("episode_return", 0.0)
        for rng, saved in zip(self._rngs, state["rngs"], strict=True):
            rng.bit_generator.state = saved
        self._tiles[:] = -1  # every view is drawn anew
        self._ranged[:] = False
        self._all_started = bool(self.started().all())

    def __getstate__(self) -> dict:
        """For pickle and ``copy.deepcopy``: :meth:`get_state` and the size of the batch; the GL renderer is not
        copied, the copy makes its own at its first render (the same pixels)."""
        return {
            "num_envs": self.num_envs,
            "nthread": self._batch.nthread,
            "backend": self.backend,
            "device": self.device,
            **self.get_state(),
        }

    def __setstate__(self, state: dict) -> None:
        """Build the simulator anew and restore the rooms' state."""
        config = EnvConfig(**saved_room(state["config"]))
        backend = {key: state[key] for key in ("backend", "device") if key in state}
        self.__init__(config, state["num_envs"], state["nthread"], **backend)
        self.set_state(state)

    # ----------------------------------------------------------------- episode control
    def reset(self, ids=None, seeds=None) -> None:
        """Start new episodes in the rooms ``ids`` (all when ``None``).

        Args:
            ids: the rooms to reset (all when ``None``), distinct and increasing.
            seeds: ``None``, or one seed per reset room (an int is broadcast), each an int in
                [0, 2**63 - 1]: a room given a seed restarts its random stream from it. Without seeds
                the rooms draw their layouts from their streams.
        """
        ids = self._as_ids(ids, changed=True)
        if seeds is not None:
            for i, seed in zip(ids, _check_seeds(seeds, ids), strict=True):
                self._rngs[i] = np.random.default_rng(seed)
        self._batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        n_obs = self.config.num_obstacles
        for i in ids:
            layout = sample_layout(
                self._rngs[i],
                n_obs,
                self.config.goal_distance,
                math.radians(self.config.heading_spread),
                shuffle=self.config.room.shuffle_occluders,
            )
            qpos = self._qpos[i]
            self._base.place(qpos, layout.start_xy, layout.heading)
            mocap = self._mocap_pos[i]
            mocap[self._ids.goal] = (*layout.goal_xy, names.GOAL_HALF)
            for k, m in enumerate(self._ids.occluders):
                if k < n_obs:
                    mocap[m] = (*layout.occluders_xy[k], names.OCCLUDER_HALF[2])
                else:
                    mocap[m] = (names.PARK_X + 2 * k, 0.0, names.OCCLUDER_HALF[2])
        self._ctrl[ids] = 0.0
        self.cycle[ids] = 0
        self.done[ids] = False
        self.success[ids] = False
        self.episode_return[ids] = 0.0
        self._tiles[ids] = -1
        self._ranged[ids] = False
        self._all_started = self._all_started or bool(self.started().all())

    def started(self, ids=None) -> np.ndarray:
        """Whether each room of ``ids`` (all when ``None``) has been reset at least once: (n,) bool."""
        ids = self._as_ids(ids)
        return ~(self.done[ids] & (self.cycle[ids] == 0))  # an episode that ended has cycles

    def require_started(self, call: str, ids=None) -> None:
        """Raise ``RuntimeError`` naming ``call`` (e.g. ``"render()"``) when a room of ``ids`` was never reset."""
        if self._all_started:
            return
        ids = self._as_ids(ids)
        never = ids[~self.started(ids)]
        if never.size:
            rooms = f" of rooms {never.tolist()}" if self.num_envs > 1 else ""
            raise RuntimeError(f"{call} before reset(){rooms}: call reset() first")

    def move(self, actions, ids=None) -> MoveResult:
        """The mover's half of a cycle: drive the wheels for one control period.

        Args:
            actions: (n,) ints: 0 to the left, 1 to the right, 2 forward (the room's ``mover_actions``: turns where
                the base turns, slides where it slides).
            ids: the rooms that move (all when ``None``), distinct and increasing; none of them may be done.
        """
        ids = self._as_ids(ids, changed=True)
        actions = check_actions(actions, len(ids), MOVER_ACTIONS, "mover", self.config.room.mover_actions)
        self.require_started("move()", ids)
        rows = self._rows(ids)
        if self.done[rows].any():
            raise RuntimeError(f"move() on finished episodes {ids[self.done[ids]].tolist()}: reset them first")
        ctrl = self._ctrl[ids]
        self._base.drive(ctrl, self._qpos[rows], actions)
        self._ctrl[rows] = ctrl
        self._batch.step(None if isinstance(rows, slice) else ids, nstep=self.substeps)
        self._tiles[rows] = -1
        self._ranged[rows] = False
        # a stiff servo holds the pan joint while the base moves; its residual error (about
        # 1e-5 rad) would accumulate over an episode, so the joint returns to its command
        self._qpos[rows, self._ids.pan] = self._ctrl[rows, self._ids.pan_ctrl]
        self._qvel[rows, self._ids.pan_dof] = 0.0
        self.cycle[rows] += 1
        cycle = self.cycle[ids]
        to_goal = self._base.xy(self._qpos[rows]) - self._mocap_pos[rows, self._ids.goal, :2]
        success = np.sqrt(np.add.reduce(to_goal * to_goal, axis=1)) < SUCCESS_DISTANCE  # np.linalg.norm's sum
        reward = self._reward(success, cycle)
        truncated = ~success & (cycle >= self.config.max_cycles)
        self.done[rows] = success | truncated
        self.success[rows] = success
        self.episode_return[rows] += reward
        looker_reward = np.zeros_like(reward) if self.config.looker_reward == "none" else reward.copy()
        return MoveResult(
            reward=reward,
            looker_reward=looker_reward,
            terminated=success,
            truncated=truncated,
            success=success.copy(),
            episode_return=self.episode_return[ids],
        )

    def _reward(self, success: np.ndarray, cycles: np.ndarray) -> np.ndarray:
        """The mover's reward for moves that ended cycles ``cycles``: ``1 - 0.2 t / T`` where they reached the goal,
        else 0 (float64)."""
        frac = cycles / self.config.max_cycles
        return np.where(success, 1.0 - 0.2 * frac, 0.0)

    def outside_episode(self, call: str, index: int = 0) -> RuntimeError:
        """The error for ``call`` (e.g. ``"step()"``) made on room ``index`` outside an episode: before its first
        reset, or after its episode ended (an episode ends in a move, so its cycle count is then above 0)."""
        when = "after the episode ended (terminated or truncated)" if self.cycle[index] else "before reset()"
        return RuntimeError(f"{call} {when}: call reset()")

    def look(self, actions, ids=None) -> None:
        """The looker's half of a cycle: turn the camera; no time passes, the base stays put.

        Args:
            actions: (n,) ints in {0: pan left, 1: hold, 2: pan right}.
            ids: the rooms whose camera turns (all when ``None``), distinct and increasing.
        """
        ids = self._as_ids(ids, changed=True)
        actions = check_actions(actions, len(ids), len(LOOKER_ACTIONS), "looker", LOOKER_ACTIONS)
        self.require_started("look()", ids)
        rows = self._rows(ids)
        before = self._qpos[rows, self._ids.pan]
        pan = np.minimum(np.maximum(before + self._pan_deltas[actions], -self._pan_limit), self._pan_limit)  # a clip
        pan = pan.astype(np.float32)
        self._tiles[ids[pan != before]] = -1  # a hold, or a pan against the limit, leaves the view as it was
        self._qpos[rows, self._ids.pan] = pan
        self._qvel[rows, self._ids.pan_dof] = 0.0
        self._ctrl[rows, self._ids.pan_ctrl] = pan

    def look_views(self, ids=None) -> tuple[np.ndarray, np.ndarray]:
        """What each look would show the rooms ``ids`` (all when ``None``), the camera left where it is: the views
        (n, 3, height, width, 3) uint8 and pans (n, 3, 1) float32 after 'pan left', 'hold' and 'pan right'. A look
        that would not turn the camera (a hold, a pan against the limit) shows the current view."""
        ids = self._as_ids(ids)
        current = self.render(ids)
        before = self._qpos[ids, self._ids.pan]
        pans = np.clip(before[:, None] + self._pan_deltas, -self._pan_limit, self._pan_limit).astype(np.float32)
        views = np.repeat(current[:, None], len(LOOKER_ACTIONS), axis=1)
        turned = pans != before[:, None]
        if turned.any():
            rooms = np.nonzero(turned)[0]
            qpos = self._qpos[ids[rooms]].copy()
            qpos[:, self._ids.pan] = pans[turned]
            views[turned] = self.renderer.render(qpos, self._mocap_pos[ids[rooms]])
        return views, pans[..., None]

    # ----------------------------------------------------------------- observations
    def render(self, ids=None, out: np.ndarray | None = None) -> np.ndarray:
        """First-person camera images of the rooms ``ids``: (n, height, width, 3) uint8.

        Only the rooms that changed since their view was drawn (in the tile of the offscreen buffer this
        call draws them in) are drawn again; the others get their last view, the very pixels a new render
        would give. A look that leaves the camera where it was ('hold', or a pan against the limit) changes
        nothing, so in a cycle the looker's view ``s_bar`` is drawn for every room and the mover's ``s'``
        only for the rooms whose camera turned.
        """
        every = ids is None
        ids = self._as_ids(ids)
        self.require_started("render()", ids)
        per_pass = self.renderer.views_per_pass
        # where each view is drawn in the offscreen buffer; every room: the rows, in one pass where they fit
        every = every and self.num_envs <= per_pass
        rows, tiles = (slice(None), ids) if every else (ids, np.arange(len(ids)) % per_pass)
        if self._views is None:
            cfg = self.config
            self._views = np.zeros((self.num_envs, cfg.height, cfg.width, 3), dtype=np.uint8)
        # the rasteriser rounds a view a little differently in another tile: a view is reused only where
        # it was drawn in the tile this call would draw it in, and a stale one is drawn again in that tile
        stale = self._tiles[rows] != tiles
        if stale.any():
            if stale.all() or len(ids) > per_pass or len(np.unique(ids)) < len(ids):
                self._views[rows] = self.renderer.render(self._qpos[rows], self._mocap_pos[rows])
                self._tiles[ids] = tiles
            else:
                redraw = ids[stale]
                views = self.renderer.render(self._qpos[redraw], self._mocap_pos[redraw], tiles=tiles[stale])
                self._views[redraw] = views
                self._tiles[redraw] = tiles[stale]
        if out is None:
            return self._views[rows].copy()  # callers may keep or change it
        out[...] = self._views[rows]
        return out

    def device_views(self, ids=None):
        """First-person camera images of the rooms ``ids`` (all when ``None``; at most ``num_envs``) drawn anew where
        the warp backend runs and left there: an (n, height, width, 3) uint8 Warp array, which ``torch.from_dlpack``
        reads in place, lent until the renderer's next pass (any render, look or layer of this simulator: copy what
        you keep). The same pixels as :meth:`render`; the default backend draws on the host and has none
        (``ValueError``)."""
        if self.backend != "warp":
            raise ValueError(f"device_views() needs backend='warp'; backend={self.backend!r} draws with render()")
        ids = self._as_ids(ids)
        self.require_started("device_views()", ids)
        return self.renderer.device_views(self._qpos[ids], self._mocap_pos[ids])

    def observe(self, ids=None, device_images: bool = False) -> dict:
        """The rooms' observations as every API gives them: ``image`` (:meth:`render`; with ``device_images``, the
        views :meth:`device_views` lends), ``pan`` (:meth:`pan`) and, with a range sensor (``range_rays`` > 0),
        ``range`` (:meth:`ranges`); with ``depth`` and ``segmentation`` set in the config, ``depth``
        (:meth:`render_depth`) and ``segmentation`` (:meth:`render_segmentation`)."""
        others = {"pan": self.pan(ids)}
        if self.config.range_rays:
            others["range"] = self.ranges(ids)
        if self._layers_on:
            others |= self._layers(self._layers_on, ids)
        image = self.device_views(ids) if device_images else self.render(ids)  # last: a pass after it would redraw
        return {"image": image, **others}

    def render_depth(self, ids=None) -> np.ndarray:
        """Depth of the camera images of the rooms ``ids``: (n, height, width) float32, the distance in metres along
        the camera's axis to what each pixel shows, 0 where nothing is seen; needs ``EnvConfig(depth=True)``."""
        return self._layers(("depth",), ids)["depth"]

    def render_segmentation(self, ids=None) -> np.ndarray:
        """What each pixel of the camera images of the rooms ``ids`` shows: (n, height, width) int32 ids of the
        model's geoms (``mujoco.mj_id2name(sim.model, mujoco.mjtObj.mjOBJ_GEOM, id)``), -1 where none is seen; needs
        ``EnvConfig(segmentation=True)``."""
        return self._layers(("segmentation",), ids)["segmentation"]

    def _layers(self, names: tuple[str, ...], ids) -> dict[str, np.ndarray]:
        """The renderer's layers ``names`` of the rooms ``ids``, drawn anew."""
        for name in names:
            if not getattr(self.config, name):
                raise ValueError(f"render_{name}() needs EnvConfig({name}=True); this room has {name}=False")
        ids = self._as_ids(ids)
        self.require_started(" and ".join(f"render_{name}()" for name in names), ids)
        return self.renderer.render_layers(self._qpos[ids], self._mocap_pos[ids], names)

    def ranges(self, ids=None) -> np.ndarray:
        """The range sensor's readings (:mod:`activeperc_env.sensors`): (n, range_rays) float32 metres, right first."""
        ids = self._as_ids(ids)
        self.require_started("ranges()", ids)
        stale = ids[~self._ranged[ids]]
        if stale.size:
            qpos, mocap = self._qpos[stale], self._mocap_pos[stale]
            occluders = mocap[:, self._occluders_used, :2]
            self._ranges[stale] = sensors.cast(
                self._base.xy(qpos), self._base.heading(qpos), occluders, self._ray_angles, self.config.range_max
            )
            self._ranged[stale] = True
        return self._ranges[ids]  # a copy

    def pan(self, ids=None) -> np.ndarray:
        """The camera's pan angle relative to the robot's heading, radians: (n, 1) float32."""
        ids = self._as_ids(ids)
        self.require_started("pan()", ids)
        return self._qpos[ids, self._ids.pan : self._ids.pan + 1].astype(np.float32)

    def state(self, ids=None) -> np.ndarray:
        """The rooms' true state, for centralised critics: (n, 8 + 2 * num_obstacles) float32.

        Per room: the robot's x and y (metres, room centred at the origin), the cosine and sine of its heading,
        the camera's pan (radians), the goal's x and y, each occluder's x and y, and ``cycle / max_cycles``.
        Its bounds are :func:`activeperc_env.spaces.state_space`.
        """
        ids = self._as_ids(ids)
        self.require_started("state()", ids)
        qpos, mocap = self._qpos[ids], self._mocap_pos[ids]
        heading = self._base.heading(qpos)
        occluders = mocap[:, self._occluders_used, :2].reshape(len(ids), -1)
        columns = [
            self._base.xy(qpos),
            np.cos(heading)[:, None],
            np.sin(heading)[:, None],
            qpos[:, self._ids.pan : self._ids.pan + 1],
            mocap[:, self._ids.goal, :2],
            occluders,
            (self.cycle[ids] / self.config.max_cycles)[:, None],
        ]
        return np.concatenate(columns, axis=1).astype(np.float32)

    def render_map(self, index: int = 0) -> np.ndarray:
        """Bird's-eye map of room ``index`` with the camera's view cone: (240, 320, 3) uint8."""
        index = self._as_index(index)
        self.require_started("render_map()", index)
        return self.renderer.render_map(self._qpos[index], self._mocap_pos[index])

    def pose(self, index: int = 0) -> tuple[np.ndarray, float, float]:
        """Robot position (x, y), heading and camera pan of room ``index``, for scripts and tests."""
        index = self._as_index(index)
        self.require_started("pose()", index)
        q = self._qpos[index : index + 1]
        heading = float(self._base.heading(q)[0])
        return self._base.xy(q)[0].copy(), math.atan2(math.sin(heading), math.cos(heading)), float(q[0, self._ids.pan])

    def goal_xy(self, index: int = 0) -> np.ndarray:
        """Centre (x, y) of room ``index``'s goal box."""
        index = self._as_index(index)
        self.require_started("goal_xy()", index)
        return self._mocap_pos[index][self._ids.goal, :2].copy()

    def occluders_xy(self, index: int = 0) -> np.ndarray:
        """Centres (k, 2) of room ``index``'s occluder boxes in use."""
        index = self._as_index(index)
        self.require_started("occluders_xy()", index)
        mocap = self._mocap_pos[index]
        return mocap[list(self._ids.occluders[: self.config.num_obstacles]), :2].copy()

    def physics_data(self, index: int = 0) -> mujoco.MjData:
        """An ``MjData`` holding room ``index``'s full state (for MuJoCo's viewer and tools)."""
        data = self._batch.get_data(self._as_index(index))
        mujoco.mj_forward(self.model, data)
        return data

    @property
    def renderer(self) -> TiledRenderer | WarpRenderer:
        """The renderer, created on first use so that physics-only users need no GL."""
        if self._renderer is None and self.backend == "warp":
            cfg = self.config
            self._renderer = WarpRenderer(
                self._batch, cfg.width, cfg.height, self.num_envs, cfg.fov, cfg.depth, cfg.segmentation
            )
        if self._renderer is None:
            self._renderer = TiledRenderer(
                self.model, self.config.width, self.config.height, self.num_envs, self.config.fov
            )
        return self._renderer

    def close(self) -> None:
        """Release the renderer's GL context."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def _as_ids(self, ids, changed: bool = False) -> np.ndarray:
        """``ids`` as an int64 array (all rooms when ``None``); ``ValueError`` unless they are ints of rooms (a bool
        mask is not taken: ``np.flatnonzero(mask)`` gives its rooms), and for a call that ``changed`` the rooms,
        distinct and increasing."""
        if ids is None:
            return np.arange(self.num_envs)
        arr = np.atleast_1d(np.asarray(ids))
        if arr.ndim != 1 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
            raise ValueError(
                f"room ids {ids!r} are invalid: expected ints in 0 .. {self.num_envs - 1} "
                "(for a bool mask, pass np.flatnonzero(mask))"
            )
        if arr.size and (arr.min() < 0 or arr.max() >= self.num_envs):
            raise ValueError(f"room ids {arr.tolist()} out of range for num_envs={self.num_envs}")
        if changed and (np.diff(arr) <= 0).any():
            raise ValueError(f"room ids {arr.tolist()} are invalid: expected distinct rooms in increasing order")
        return arr.astype(np.int64)

    def _rows(self, ids: np.ndarray) -> np.ndarray | slice:
        """The rows of the per-room arrays of the distinct, increasing rooms ``ids``: all of them as a slice (which
        indexes without copies) where they are every room."""
        return slice(None) if len(ids) == self.num_envs else ids

    def _as_index(self, index) -> int:
        """``index`` as the int of one room; ``ValueError`` unless it is one (negative indices are not taken)."""
        if not (is_int(index) and 0 <= index < self.num_envs):
            raise ValueError(f"room index {index!r} is invalid: expected an int in 0 .. {self.num_envs - 1}")
        return int(index)


class _Ids:
    """Addresses of the camera's and the room's named elements in ``qpos``, ``qvel``, ``ctrl`` and ``mocap_pos``,
    looked up once (the base's are its own: :mod:`activeperc_env.robot`)."""

    def __init__(self, model: mujoco.MjModel):
        def joint(name):
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)

        def mocap(body):
            return model.body_mocapid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)]

        def actuator(name):
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)

        self.pan = int(model.jnt_qposadr[joint(names.PAN_JOINT)])
        self.pan_dof = int(model.jnt_dofadr[joint(names.PAN_JOINT)])
        self.pan_ctrl = actuator(names.PAN_ACTUATOR)
        self.goal = int(mocap(names.GOAL_BODY))
        self.occluders = tuple(int(mocap(b)) for b in names.OCCLUDER_BODIES)


def _check_seeds(seeds, ids: np.ndarray) -> list[int]:
    """One seed per room of ``ids`` (an int is broadcast), each a seed (``checks.check_seed``); else ``ValueError``."""
    if isinstance(seeds, np.ndarray) and seeds.ndim == 0:
        seeds = seeds.item()
    if is_int(seeds):
        seeds = [seeds] * len(ids)
    if not isinstance(seeds, (list, tuple, np.ndarray)) or len(seeds) != len(ids):
        raise ValueError(f"seeds={seeds!r} invalid: expected an int or {len(ids)} ints, one per reset room")
    return [check_seed(seed, f"seeds[{k}]" if len(seeds) > 1 else "seed") for k, seed in enumerate(seeds)]


def split_joint(action):
    """``(u_m, u_c)`` of joint actions ``a = 3 u_m + u_c`` (an int or a numpy array of them)."""
    return divmod(action, len(LOOKER_ACTIONS))


def usable_cpus() -> int:
    """CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
