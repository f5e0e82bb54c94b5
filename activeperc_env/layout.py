"""Random room layouts: the robot's start, the goal, and occluders placed between them."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from activeperc_env.names import (
    GOAL_HALF,
    OCCLUDER_HALF,
    ROBOT_RADIUS,
    ROOM_HALF_X,
    ROOM_HALF_Y,
)

X_JITTER = 0.3  # start and goal x are drawn within this of -+goal_distance / 2
SIDE_Y = ROOM_HALF_Y - 0.5
LINE_OFFSET = 0.45  # the first occluder's centre is within this of the start-goal line
SIDE_OFFSET = (1.0, 1.6)  # the others' centres are this far to either side of it
SIDES = (-1.0, 1.0)  # which side of the line
# whole-layout draws before giving up: the hardest config (6 occluders, goal_distance 2.5) fits 13 of 700 draws
# (tests/test_scene.py): all of 1,000 draws then fail about once in 10**8 resets, which long runs with many rooms
# approach; all of 10,000 practically never, at no cost where a draw fits
MAX_TRIES = 10_000
PLACE_TRIES = 50  # spots tried for one occluder before the draw starts over


@dataclass(frozen=True)
class Layout:
    """One episode's layout, in metres and radians (world frame, room centred at the origin)."""

    start_xy: np.ndarray
    """(2,) the robot's start position."""
    heading: float
    """The robot's start heading (yaw)."""
    goal_xy: np.ndarray
    """(2,) centre of the red goal box."""
    occluders_xy: np.ndarray
    """(num_obstacles, 2) centres of the occluder boxes."""


def sample_layout(
    rng: np.random.Generator,
    num_obstacles: int,
    goal_distance: float,
    heading_spread: float = math.pi / 2,
    shuffle: bool = False,
) -> Layout:
    """Draw a layout: start on the west side, goal on the east side, occluders on the way.

    The start heading lies within ``heading_spread`` radians of the goal's bearing. With ``shuffle`` the occluders
    trade places at random once placed (room v2), so that no box's colour tells where the goal lies.

    The start's x is drawn within ``X_JITTER`` of ``-goal_distance / 2`` and the goal's within
    ``X_JITTER`` of ``+goal_distance / 2``; both y anywhere but 0.5 m from the side walls.

    Occluders stand 35-65 % of the way from start to goal (25-75 % for a fourth to sixth), the
    first within ``LINE_OFFSET`` of the line between them, so the goal is hidden from most starts,
    the others ``SIDE_OFFSET`` to either side of it, so they hide the goal from views to the side
    and leave a way round the first. A draw whose occluders do not fit is redrawn whole from the same
    stream, so a seed fixes the layout.
    """
    for _ in range(MAX_TRIES):
        layout = _draw(rng, num_obstacles, goal_distance, heading_spread)
        if layout is not None:
            if shuffle:
                return dataclasses.replace(layout, occluders_xy=layout.occluders_xy[rng.permutation(num_obstacles)])
            return layout
    raise RuntimeError(f"no layout with {num_obstacles} occluders fitted in {MAX_TRIES} draws")


def _draw(rng: np.random.Generator, num_obstacles: int, goal_distance: float, heading_spread: float) -> Layout | None:
    """One attempt at a layout; ``None`` when an occluder finds no free spot. It computes in plain floats: the same
    operations as on numpy's small arrays, in the same order, round alike and cost less."""
    half = goal_distance / 2
    start = (rng.uniform(-half - X_JITTER, -half + X_JITTER), rng.uniform(-SIDE_Y, SIDE_Y))
    goal = (rng.uniform(half - X_JITTER, half + X_JITTER), rng.uniform(-SIDE_Y, SIDE_Y))
    line = (goal[0] - start[0], goal[1] - start[1])
    bearing = math.atan2(line[1], line[0])  # the math module's, not numpy's: see _distance
    heading = bearing + rng.uniform(-heading_spread, heading_spread)
    length = _distance(goal, start)
    normal = (-line[1] / length, line[0] / length)
    occluders: list[tuple[float, float]] = []
    for i in range(num_obstacles):
        along = (0.35, 0.65) if i < 3 else (0.25, 0.75)  # a fourth to sixth box needs more room
        for _ in range(PLACE_TRIES):
            fraction = rng.uniform(*along)
            if i == 0:
                offset = rng.uniform(-LINE_OFFSET, LINE_OFFSET)
            else:
                offset = SIDES[rng.integers(0, 2)] * rng.uniform(*SIDE_OFFSET)  # rng.choice(SIDES)'s draw, faster
            xy = tuple(start[a] + fraction * line[a] + offset * normal[a] for a in (0, 1))
            if _fits(xy, start, goal, occluders):
                occluders.append(xy)
                break
        else:
            return None
    return Layout(
        start_xy=np.array(start),
        heading=float(heading),
        goal_xy=np.array(goal),
        occluders_xy=np.array(occluders, dtype=float).reshape(num_obstacles, 2),
    )


def _fits(xy: tuple, start: tuple, goal: tuple, others: list[tuple]) -> bool:
    """Whether an occluder at ``xy`` stays in the room and clear of start, goal and the others."""
    half = OCCLUDER_HALF[0]
    if abs(xy[0]) > ROOM_HALF_X - half - 0.05 or abs(xy[1]) > ROOM_HALF_Y - half - 0.05:
        return False
    clearance = half * math.sqrt(2) + 0.1
    if _distance(xy, start) < clearance + ROBOT_RADIUS + 0.2:
        return False
    if _distance(xy, goal) < clearance + GOAL_HALF * math.sqrt(2) + 0.3:
        return False
    return all(_distance(xy, o) > 2 * half + 0.25 for o in others)


def _distance(a, b) -> float:
    """The distance between two points, the same to the last bit on every CPU (numpy's ``linalg.norm`` and
    ``arctan2`` pick SIMD kernels by CPU and round differently on some)."""
    dx, dy = float(a[0] - b[0]), float(a[1] - b[1])
    return math.sqrt(dx * dx + dy * dy)
