"""Room v1's range sensor: exact distances to walls and occluders, blind to the goal, in every API's observation."""

import math

import mujoco
import numpy as np
import pytest

import activeperc_env
from activeperc_env import EnvConfig, Simulator, names, sensors
from activeperc_env.rooms import DEFAULT
from activeperc_env.spaces import observation_space


def mujoco_ranges(sim, index):
    """The same rays cast by MuJoCo's ``mj_ray`` at 0.5 m height: above the goal (0.4 m tall), below the occluders'
    and the walls' tops, against the room's geoms (group 0) only."""
    data = sim.physics_data(index)
    xy, heading, _ = sim.pose(index)
    group = np.array([1, 0, 0, 0, 0, 0], dtype=np.uint8)
    out = []
    for angle in sensors.ray_angles(sim.config.range_rays):
        direction = np.array([math.cos(heading + angle), math.sin(heading + angle), 0.0])
        geom = np.array([-1], dtype=np.int32)
        distance = mujoco.mj_ray(sim.model, data, np.array([*xy, 0.5]), direction, group, 1, -1, geom)
        out.append(sim.config.range_max if distance < 0 else min(distance, sim.config.range_max))
    return np.array(out)


@pytest.mark.parametrize("num_obstacles", [0, 3, 6])
def test_ranges_are_mujocos_own_ray_casts(num_obstacles):
    config = EnvConfig(num_obstacles=num_obstacles, goal_distance=4.6, range_max=5.0)
    sim = Simulator(config, num_envs=8)
    sim.reset(seeds=np.arange(8))
    rng = np.random.default_rng(0)
    for _ in range(40):
        sim.move(rng.choice(3, size=8, p=[0.3, 0.3, 0.4]))
        ranges = sim.ranges()
        for i in range(8):
            np.testing.assert_allclose(ranges[i], mujoco_ranges(sim, i), atol=1e-5)
        if sim.done.any():
            sim.reset(np.flatnonzero(sim.done))


def test_rays_run_right_to_left_and_one_ray_looks_ahead():
    np.testing.assert_allclose(sensors.ray_angles(3), [-math.pi / 2, 0.0, math.pi / 2])
    np.testing.assert_allclose(sensors.ray_angles(1), [0.0])
    # a base 1 m from the east wall, facing it: straight ahead reads 1, to the sides the north and south walls
    sim = Simulator(EnvConfig(num_obstacles=0, range_rays=3, range_max=5.0))
    sim.reset(seeds=[0])
    sim._base.place(sim._qpos[0], np.array([2.0, 0.5]), 0.0)
    np.testing.assert_allclose(sim.ranges()[0], [2.5, 1.0, 1.5], atol=1e-6)


def test_the_goal_is_not_an_obstacle_to_the_rays():
    sim = Simulator(EnvConfig(num_obstacles=0, range_rays=1, range_max=5.0))
    sim.reset(seeds=[0])
    goal = sim.goal_xy()
    sim._base.place(sim._qpos[0], goal - [1.0, 0.0], 0.0)  # 1 m west of the goal, facing it and the east wall
    assert sim.ranges()[0, 0] == pytest.approx(names.ROOM_HALF_X - (goal[0] - 1.0), abs=1e-6)


def test_ranges_stop_at_range_max_and_a_room_without_rays_has_no_range():
    sim = Simulator(EnvConfig(num_obstacles=0, range_max=0.5))
    sim.reset(seeds=[0])
    assert sim.ranges().max() == pytest.approx(0.5)
    bare = EnvConfig(range_rays=0)
    sim = Simulator(bare)
    sim.reset(seeds=[0])
    assert set(sim.observe()) == {"image", "pan"} and "range" not in observation_space(bare).spaces
    assert set(observation_space(EnvConfig()).spaces) == {"image", "pan", "range"}


def test_every_api_observes_the_same_ranges():
    import gymnasium

    sim = Simulator()
    sim.reset(seeds=[5])
    par = activeperc_env.parallel_env()
    obs, _ = par.reset(seed=5)
    joint = gymnasium.make(f"activeperc/Joint-v{DEFAULT}")
    joint_obs, _ = joint.reset(seed=5)
    for move, look in [(2, 0), (2, 1), (0, 2), (2, 2)]:
        sim.move([move])
        sim.look([look])
        obs, *_ = par.step({activeperc_env.MOVER: move, activeperc_env.LOOKER: look})
        joint_obs, *_ = joint.step(3 * move + look)
        for theirs in (obs[activeperc_env.MOVER]["range"], joint_obs["range"]):
            np.testing.assert_array_equal(theirs, sim.ranges()[0])
    assert par.observation_space(activeperc_env.MOVER)["range"].contains(obs[activeperc_env.MOVER]["range"])
