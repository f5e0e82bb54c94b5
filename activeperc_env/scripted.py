"""Scripted policies: baselines to run, a check that a room is solvable, and the instrument that measures what
looking is worth (``experiments/value_of_looking.py``).

Movers: :class:`VisionMover` (sees only what a learned mover sees: the image, the pan and the range sensor),
:class:`OracleMover` (reads the room's true state) and :class:`RandomMover`. Lookers: :class:`FixedLooker` (the
camera stays forward), :class:`ScanLooker` (sweeps until the goal is in view, then keeps it there),
:class:`TrackLooker` (the same without memory: pans at random until the goal is in view) and
:class:`RandomLooker`. :func:`play` runs a mover and a looker in a :class:`~activeperc_env.Simulator`.

Every policy acts on a batch of rooms: ``act(observation, ids)`` takes the observations of the rooms ``ids`` (the
dict :meth:`Simulator.observe` gives, leading dimension n) and returns n actions; given one room's observation (as
the PettingZoo and Gymnasium envs give it) it returns one int. ``reset(ids)`` starts new episodes in those rooms
(the policies that remember something forget it). :class:`OracleMover` also needs ``observation["state"]``
(:meth:`Simulator.state`, or ``env.state()`` of the PettingZoo envs).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from activeperc_env import names, sensors
from activeperc_env.config import EnvConfig
from activeperc_env.core import HOLD, LOOKER_ACTIONS, MOVER_ACTIONS, SUCCESS_DISTANCE, Simulator

TURN_LEFT, TURN_RIGHT, FORWARD = range(MOVER_ACTIONS)  # where the base slides: slide left, slide right, forward
PAN_LEFT, PAN_RIGHT = LOOKER_ACTIONS.index("pan_left"), LOOKER_ACTIONS.index("pan_right")
# The goal material is rgba (0.9, 0.05, 0.05). Under the scene's lights its pixels measure R in [103, 218] and
# G, B <= 12; no other material (grey walls, brown floor, green, yellow and blue occluders) comes close to this rule.
RED_MIN = 80
GREEN_BLUE_MAX = 50
MIN_PIXELS = 3  # a visible goal covers at least 4 pixels at 80x60
NEAR_FRACTION = 0.1  # a goal that covers this share of the view is a few tens of centimetres away
CORRIDOR_HALF = names.ROBOT_RADIUS + 0.04  # half the width of the way the base sweeps, with a margin
CORRIDOR_LENGTH = names.ROBOT_RADIUS + 0.3  # how far ahead the way must be clear for one forward move
LOOK_AHEAD = 0.8  # how much farther the way to the goal must be clear to head straight for it


def goal_pixels(images: np.ndarray) -> np.ndarray:
    """Which pixels of the views ``images`` (..., H, W, 3) uint8 show the goal: (..., H, W) bool."""
    r, g, b = (images[..., k].astype(np.int16) for k in range(3))
    return (r > RED_MIN) & (g < GREEN_BLUE_MAX) & (b < GREEN_BLUE_MAX)


def goal_in_view(images: np.ndarray, fov: float) -> tuple[np.ndarray, np.ndarray]:
    """Where the goal is in each view: its bearing from the camera's axis (radians, positive to the left; NaN when
    fewer than :data:`MIN_PIXELS` pixels show it) and its pixel count, each (n,)."""
    red = goal_pixels(images)
    counts = red.sum(axis=(1, 2))
    width = images.shape[2]
    columns = red.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = (columns * (np.arange(width) + 0.5)).sum(axis=1) / columns.sum(axis=1)
    offset = (centre - width / 2) / (width / 2)  # -1 at the left edge, +1 at the right
    bearing = -np.arctan(offset * math.tan(math.radians(fov) / 2))
    return np.where(counts >= MIN_PIXELS, bearing, np.nan), counts


def wrap(angle):
    """Angles in radians wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


class _Policy:
    """What every scripted policy shares: batched or single observations, per-room memory and random streams (room
    ``i`` draws from ``SeedSequence(seed, spawn_key=(i,))``, so a room acts alike whatever rooms play beside it)."""

    def __init__(self, config: EnvConfig | None = None, num_envs: int = 1, seed: int = 0):
        self.config = config if config is not None else EnvConfig()
        self.num_envs = num_envs
        self._rngs = [np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,))) for i in range(num_envs)]

    def _random(self, ids: np.ndarray) -> np.ndarray:
        """One uniform number in [0, 1) from the stream of each room of ``ids``."""
        return np.array([self._rngs[i].random() for i in ids])

    def reset(self, ids=None) -> None:
        """Start new episodes in the rooms ``ids`` (all when ``None``)."""

    def act(self, observation: dict, ids=None):
        """Actions for the rooms ``ids`` (all when ``None``) from their observations; one int for one room's."""
        single = np.ndim(observation["pan"]) == 1
        if single:
            observation = {key: np.asarray(value)[None] for key, value in observation.items()}
            ids = [0] if ids is None else ids
        ids = np.arange(len(observation["pan"])) if ids is None else np.atleast_1d(np.asarray(ids))
        actions = self._act(observation, ids)
        return int(actions[0]) if single else actions

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        raise NotImplementedError


def _steer(bearing: np.ndarray, forward_ok: np.ndarray, config: EnvConfig) -> np.ndarray:
    """The move that brings the heading toward ``bearing`` (radians, positive to the left): a turn while it lies
    beyond three quarters of one turn, else forward (where the way is clear; else a turn toward it). A base that
    slides without turning slides toward a bearing beyond 45 degrees instead, and sideways where forward is
    blocked."""
    if config.room.turns:
        tolerance = 0.75 * math.radians(config.turn_speed) / config.control_hz
    else:
        tolerance = math.pi / 4
    action = np.where(bearing > tolerance, TURN_LEFT, np.where(bearing < -tolerance, TURN_RIGHT, FORWARD))
    blocked = (action == FORWARD) & ~forward_ok
    return np.where(blocked, np.where(bearing >= 0, TURN_LEFT, TURN_RIGHT), action)


class VisionMover(_Policy):
    """A mover that sees what a learned mover sees: the goal's bearing from the red pixels and the pan, the
    obstacles from the range sensor (``range_rays`` > 0).

    With the goal in view it heads for it, going round an occluder in the way on the goal's side of it; without it,
    it explores: it drives on where the way is clear and now and then turns (each episode its own side). Its one
    memory: it never undoes its last turn at once (the readings flicker as the rays sweep over a box's edge).
    """

    def __init__(self, config: EnvConfig | None = None, num_envs: int = 1, seed: int = 0):
        super().__init__(config, num_envs, seed)
        if not self.config.range_rays:
            raise ValueError("VisionMover reads the range sensor: give the room range_rays > 0")
        self.angles = sensors.ray_angles(self.config.range_rays)
        self.explore_turn = np.zeros(num_envs, dtype=np.int64)
        self.last = np.full(num_envs, FORWARD)
        self.reset()

    def reset(self, ids=None) -> None:
        """Start new episodes in the rooms ``ids``: each draws the side it explores to."""
        ids = np.arange(self.num_envs) if ids is None else np.atleast_1d(ids)
        self.explore_turn[ids] = np.where(self._random(ids) < 0.5, TURN_LEFT, TURN_RIGHT)
        self.last[ids] = FORWARD

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        config, ranges = self.config, observation["range"]
        n = len(ranges)
        camera, counts = goal_in_view(observation["image"], config.fov)
        seen = ~np.isnan(camera)
        bearing = np.where(seen, wrap(observation["pan"][:, 0] + np.nan_to_num(camera)), 0.0)
        forward_ok = ~self._blocked(ranges, np.zeros(n), CORRIDOR_LENGTH)
        far = CORRIDOR_LENGTH + LOOK_AHEAD
        # the goal in view but an occluder in the way: pass it on the goal's side of its nearest point; turn that
        # way until the way ahead is clear, then drive
        obstacle = self._nearest_hit(ranges, bearing, far)
        detour = seen & self._blocked(ranges, bearing, far) & ~np.isnan(obstacle)
        side = np.where(bearing >= np.nan_to_num(obstacle), 1.0, -1.0)
        passes = forward_ok & (np.sign(-np.nan_to_num(obstacle)) == side)
        target = np.where(detour, np.where(passes, 0.0, side), bearing)
        action = _steer(target, forward_ok, config)
        near = seen & (counts > NEAR_FRACTION * config.width * config.height) & (np.abs(bearing) < math.radians(30))
        action = np.where(near, FORWARD, action)
        # the goal out of view: explore
        explore = np.where(self._random(ids) < 0.8, FORWARD, self.explore_turn[ids])
        left, right = ranges[:, len(self.angles) // 2 + 1 :].mean(1), ranges[:, : len(self.angles) // 2].mean(1)
        open_side = np.where(left > right, TURN_LEFT, TURN_RIGHT)
        explore = np.where((explore == FORWARD) & ~forward_ok, open_side, explore)
        action = np.where(seen, action, explore)
        last = self.last[ids]
        undoes = (action != FORWARD) & (last != FORWARD) & (action != last)
        action = np.where(undoes, np.where(forward_ok, FORWARD, last), action)
        self.last[ids] = action
        return action

    def _hits(self, ranges: np.ndarray, direction: np.ndarray):
        """The rays' hit points in the frame of ``direction`` (n,): x along it, y across; and which rays hit."""
        relative = self.angles[None, :] - direction[:, None]
        return ranges * np.cos(relative), ranges * np.sin(relative), ranges < self.config.range_max

    def _blocked(self, ranges: np.ndarray, direction: np.ndarray, length: float) -> np.ndarray:
        """Whether a hit lies in the way the base would sweep along ``direction`` within ``length``: (n,) bool."""
        x, y, hit = self._hits(ranges, direction)
        return (hit & (x > 0) & (x < length) & (np.abs(y) < CORRIDOR_HALF)).any(axis=1)

    def _nearest_hit(self, ranges: np.ndarray, direction: np.ndarray, length: float) -> np.ndarray:
        """The angle of the nearest hit in a slightly wider way along ``direction``; NaN where there is none."""
        x, y, hit = self._hits(ranges, direction)
        inside = hit & (x > 0) & (x < length) & (np.abs(y) < CORRIDOR_HALF + 0.1)
        distance = np.where(inside, ranges, np.inf)
        return np.where(np.isfinite(distance.min(axis=1)), self.angles[distance.argmin(axis=1)], np.nan)


class OracleMover(_Policy):
    """A mover that reads the room's true state (``observation["state"]``): it follows the shortest way to the goal
    around the occluders, on a 5-cm grid of the room planned once per layout."""

    CELL = 0.05

    def __init__(self, config: EnvConfig | None = None, num_envs: int = 1, seed: int = 0):
        super().__init__(config, num_envs, seed)
        c = self.CELL
        self.xs = np.arange(-names.ROOM_HALF_X + c / 2, names.ROOM_HALF_X, c)
        self.ys = np.arange(-names.ROOM_HALF_Y + c / 2, names.ROOM_HALF_Y, c)
        self._plans: dict[int, tuple[bytes, np.ndarray]] = {}  # room -> (its layout, distances to the goal)

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        state, k = observation["state"], self.config.num_obstacles
        bearing = np.zeros(len(state))
        for row, room in enumerate(ids):
            goal, occluders = state[row, 5:7], state[row, 7 : 7 + 2 * k].reshape(k, 2)
            layout = state[row, 5 : 7 + 2 * k].tobytes()
            if self._plans.get(int(room), (None,))[0] != layout:
                self._plans[int(room)] = (layout, self._distances(goal, occluders))
            xy = state[row, :2]
            to = self._waypoint(self._plans[int(room)][1], xy, goal) - xy
            bearing[row] = wrap(math.atan2(to[1], to[0]) - math.atan2(state[row, 3], state[row, 2]))
        return _steer(bearing, np.ones(len(state), dtype=bool), self.config)

    def _distances(self, goal: np.ndarray, occluders: np.ndarray) -> np.ndarray:
        """Path lengths (in cells) from every free cell to the goal, by Dijkstra on the 8-connected grid."""
        x, y = np.meshgrid(self.xs, self.ys, indexing="ij")
        margin = names.ROBOT_RADIUS + 0.05
        free = (np.abs(x) < names.ROOM_HALF_X - margin) & (np.abs(y) < names.ROOM_HALF_Y - margin)
        half = names.OCCLUDER_HALF[0] + margin
        for ox, oy in occluders:
            free &= ~((np.abs(x - ox) < half) & (np.abs(y - oy) < half))
        distance = np.full(x.shape, np.inf)
        start = np.hypot(x - goal[0], y - goal[1]) < SUCCESS_DISTANCE - 0.08
        distance[start] = 0.0
        heap = [(0.0, int(a), int(b)) for a, b in zip(*np.nonzero(start), strict=True)]
        steps = [(da, db, math.hypot(da, db)) for da in (-1, 0, 1) for db in (-1, 0, 1) if da or db]
        while heap:
            d, a, b = heapq.heappop(heap)
            if d > distance[a, b]:
                continue
            for da, db, w in steps:
                a2, b2 = a + da, b + db
                if 0 <= a2 < x.shape[0] and 0 <= b2 < x.shape[1] and free[a2, b2] and d + w < distance[a2, b2]:
                    distance[a2, b2] = d + w
                    heapq.heappush(heap, (d + w, a2, b2))
        return distance

    def _waypoint(self, distance: np.ndarray, xy: np.ndarray, goal: np.ndarray, cells: int = 8) -> np.ndarray:
        """The point ``cells`` grid steps down the path from ``xy`` (the goal once the path reaches it)."""
        a = int(np.clip(round((xy[0] - self.xs[0]) / self.CELL), 0, len(self.xs) - 1))
        b = int(np.clip(round((xy[1] - self.ys[0]) / self.CELL), 0, len(self.ys) - 1))
        if not np.isfinite(distance[a, b]):  # inside the margin around a box: start from the nearest free cell
            reachable = np.argwhere(np.isfinite(distance))
            a, b = reachable[np.argmin((reachable[:, 0] - a) ** 2 + (reachable[:, 1] - b) ** 2)]
        for _ in range(cells):
            if distance[a, b] == 0:
                return goal
            window = distance[max(a - 1, 0) : a + 2, max(b - 1, 0) : b + 2]
            da, db = np.unravel_index(np.argmin(window), window.shape)
            a, b = max(a - 1, 0) + da, max(b - 1, 0) + db
        return np.array([self.xs[a], self.ys[b]])


class RandomMover(_Policy):
    """Uniformly random moves."""

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        return (self._random(ids) * MOVER_ACTIONS).astype(np.int64)


class FixedLooker(_Policy):
    """Holds the camera where it is: forward, as it starts."""

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        return np.full(len(ids), HOLD)


class RandomLooker(_Policy):
    """Uniformly random looks."""

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        return (self._random(ids) * len(LOOKER_ACTIONS)).astype(np.int64)


class TrackLooker(_Policy):
    """Keeps the goal within half a pan step of the view's centre while it is in view; else pans left or right at
    random. Memoryless: a policy a learned looker can represent."""

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        camera, _ = goal_in_view(observation["image"], self.config.fov)
        search = np.where(self._random(ids) < 0.5, PAN_LEFT, PAN_RIGHT)
        return np.where(np.isnan(camera), search, _track(camera, self.config))


class ScanLooker(_Policy):
    """Sweeps the camera from one pan limit to the other until the goal is in view, then keeps it within half a pan
    step of the view's centre; when it loses the goal it sweeps on toward where it last saw it."""

    def __init__(self, config: EnvConfig | None = None, num_envs: int = 1, seed: int = 0):
        super().__init__(config, num_envs, seed)
        self.direction = np.ones(num_envs)  # +1 sweeps left, -1 right

    def reset(self, ids=None) -> None:
        """Start new episodes in the rooms ``ids``: each sweeps left first."""
        self.direction[np.arange(self.num_envs) if ids is None else ids] = 1.0

    def _act(self, observation: dict, ids: np.ndarray) -> np.ndarray:
        camera, _ = goal_in_view(observation["image"], self.config.fov)
        pan, limit = observation["pan"][:, 0], math.radians(self.config.pan_range)
        seen = ~np.isnan(camera)
        direction = np.where(seen, np.where(np.nan_to_num(camera) >= 0, 1.0, -1.0), self.direction[ids])
        direction = np.where(~seen & (pan >= limit - 1e-3), -1.0, direction)
        direction = np.where(~seen & (pan <= -limit + 1e-3), 1.0, direction)
        self.direction[ids] = direction
        return np.where(seen, _track(camera, self.config), np.where(direction > 0, PAN_LEFT, PAN_RIGHT))


def _track(camera: np.ndarray, config: EnvConfig) -> np.ndarray:
    """The looks that bring a goal seen at ``camera`` (bearing from the view's axis) within half a pan step."""
    half = math.radians(config.pan_step) / 2
    camera = np.nan_to_num(camera)
    return np.where(camera > half, PAN_LEFT, np.where(camera < -half, PAN_RIGHT, HOLD))


MOVERS = {"vision": VisionMover, "oracle": OracleMover, "random": RandomMover}
LOOKERS = {"fixed": FixedLooker, "scan": ScanLooker, "track": TrackLooker, "random": RandomLooker}


@dataclass
class Outcome:
    """How the episodes of :func:`play` ended, one entry per layout."""

    success: np.ndarray
    """(n,) bool: the robot reached the goal within ``max_cycles``."""
    cycles: np.ndarray
    """(n,) int: the episode's length in cycles."""


def play(config: EnvConfig, mover: str, looker: str, seeds, seed: int = 0, nthread: int = 0) -> Outcome:
    """One episode of the scripted ``mover`` and ``looker`` (names in :data:`MOVERS`, :data:`LOOKERS`) in each
    layout of ``seeds``, all rooms stepped together; ``seed`` seeds the policies' own randomness."""
    if mover not in MOVERS:
        raise ValueError(f"mover={mover!r} is invalid: expected one of {sorted(MOVERS)}")
    if looker not in LOOKERS:
        raise ValueError(f"looker={looker!r} is invalid: expected one of {sorted(LOOKERS)}")
    seeds = [int(s) for s in seeds]
    n = len(seeds)
    sim = Simulator(config, num_envs=n, nthread=nthread)
    movers, lookers = MOVERS[mover](config, n, seed), LOOKERS[looker](config, n, seed + 1)
    try:
        sim.reset(seeds=seeds)
        success = np.zeros(n, dtype=bool)
        running = np.arange(n)
        while running.size:
            observation = sim.observe(running) | {"state": sim.state(running)}
            result = sim.move(movers.act(observation, running), running)
            lookers_view = sim.observe(running)
            sim.look(lookers.act(lookers_view, running), running)
            success[running] |= result.terminated
            running = running[~(result.terminated | result.truncated)]
        return Outcome(success=success, cycles=sim.cycle.copy())
    finally:
        sim.close()
