"""Shared helpers for the test suite."""

import math

import numpy as np

import activeperc_env  # noqa: F401  (chooses the headless GL backend before mujoco renders)


def goal_seeking_move(sim, index: int = 0) -> int:
    """A scripted mover that knows where the goal is: turn towards it, then drive forward."""
    xy, heading, _ = sim.pose(index)
    to_goal = sim.goal_xy(index) - xy
    error = math.atan2(to_goal[1], to_goal[0]) - heading
    error = math.atan2(math.sin(error), math.cos(error))
    if abs(error) < math.radians(12):
        return 2
    return 0 if error > 0 else 1


def drive_to_goal(sim, index: int = 0, max_cycles: int = 200):
    """Run the scripted mover in room ``index``; the (cycle, reward) pairs until the episode ends."""
    rewards = []
    for _ in range(max_cycles):
        result = sim.move(np.array([goal_seeking_move(sim, index)]), ids=[index])
        rewards.append((int(sim.cycle[index]), float(result.reward[0])))
        if result.terminated[0] or result.truncated[0]:
            break
    return rewards


def assert_same_view(a, b):
    """Equal up to the rasteriser's rounding: a view drawn at another framebuffer offset may
    shift a few pixels' shade by one level, never more."""
    diff = np.abs(a.astype(int) - b.astype(int))
    assert diff.max() <= 1
    assert (diff > 0).mean() < 1e-3
