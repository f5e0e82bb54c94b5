"""The Gymnasium single-agent views pass Gymnasium's checker and map actions as documented."""

import gymnasium
import numpy as np
import pytest
from conftest import goal_seeking_move
from gymnasium.utils.env_checker import check_env

import activeperc_env
from activeperc_env.rooms import DEFAULT, ROOMS


@pytest.mark.parametrize("env_id", [f"activeperc/{name}-v{v}" for v in ROOMS for name in ("Joint", "FixedForward")])
def test_check_env(env_id):
    env = gymnasium.make(env_id)
    check_env(env.unwrapped, skip_render_check=False)


def test_the_unversioned_ids_give_the_default_room_as_every_other_entry_point():
    """gymnasium.make without a version takes the newest room, which is the default room of every API."""
    assert DEFAULT == max(ROOMS)
    with pytest.warns(UserWarning, match=f"activeperc/Joint-v{DEFAULT}"):
        joint = gymnasium.make("activeperc/Joint")
    assert joint.unwrapped.config == activeperc_env.EnvConfig() == activeperc_env.env().unwrapped.config
    assert activeperc_env.parallel_env().config.version == activeperc_env.Simulator().config.version == DEFAULT


def test_joint_action_is_move_times_three_plus_look():
    env = gymnasium.make("activeperc/Joint-v1").unwrapped
    env.reset(seed=0)
    env.step(3 * 2 + 0)  # forward, pan left
    assert np.isclose(env.sim.pan()[0, 0], np.radians(env.config.pan_step))
    with pytest.raises(ValueError, match="joint agent.*Discrete\\(9\\)"):
        env.step(9)


def test_fixed_forward_never_pans():
    env = gymnasium.make("activeperc/FixedForward-v1", fov=100)
    obs, _ = env.reset(seed=1)
    for _ in range(10):
        obs, *_ = env.step(env.action_space.sample())
        assert obs["pan"][0] == 0.0
    assert env.unwrapped.config.fov == 100


def test_rgb_array_render_is_the_map_and_no_render_mode_warns():
    env = gymnasium.make("activeperc/Joint-v1", render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().shape == (240, 320, 3)
    plain = gymnasium.make("activeperc/Joint-v1")
    plain.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert plain.render() is None


def test_info_counts_cycles_and_render_fps_is_the_control_rate():
    env = gymnasium.make("activeperc/FixedForward-v1", control_hz=2.5)
    assert env.reset(seed=0)[1] == {"cycle": 0}
    assert env.step(2)[4] == {"cycle": 1}
    assert env.metadata["render_fps"] == 2.5
    assert activeperc_env.JointEnv.metadata["render_fps"] == activeperc_env.EnvConfig().control_hz


@pytest.mark.parametrize("drive", [True, False])
def test_the_last_steps_info_holds_the_episodes_outcome(drive):
    env = gymnasium.make("activeperc/FixedForward-v1", max_cycles=30, num_obstacles=0, goal_distance=2.5)
    env.reset(seed=0)
    summed, done = 0.0, False
    while not done:  # to the goal, or turning in place until max_cycles
        _, reward, terminated, truncated, info = env.step(goal_seeking_move(env.unwrapped.sim) if drive else 0)
        summed, done = summed + reward, terminated or truncated
        assert set(info) == ({"cycle", "episode_success", "episode_return"} if done else {"cycle"})
    assert info["episode_success"] == terminated == drive and info["episode_return"] == summed
    env.close()


def test_step_outside_an_episode_says_so():
    env = activeperc_env.gym_envs.JointEnv(max_cycles=2)  # unwrapped: no OrderEnforcing to catch it first
    with pytest.raises(RuntimeError, match=r"step\(\) before reset\(\)"):
        env.step(0)
    env.reset(seed=0)
    env.step(0)
    assert env.step(0)[3]  # truncated
    with pytest.raises(RuntimeError, match=r"step\(\) after the episode ended .*: call reset\(\)"):
        env.step(0)


def test_render_before_reset_says_so():
    env = activeperc_env.gym_envs.JointEnv(render_mode="rgb_array")
    with pytest.raises(RuntimeError, match=r"render\(\) before reset\(\)"):
        env.render()
    env.reset(seed=0)
    assert env.render().shape == (240, 320, 3)


def test_numpy_seeds_are_seeds():
    env = gymnasium.make("activeperc/Joint-v1")
    obs, _ = env.reset(seed=np.int64(5))
    assert env.unwrapped.np_random_seed == 5
    np.testing.assert_array_equal(obs["image"], gymnasium.make("activeperc/Joint-v1").reset(seed=5)[0]["image"])


def test_a_refused_seed_reseeds_nothing():
    env = gymnasium.make("activeperc/Joint-v1")
    env.reset(seed=3)
    before = env.unwrapped.np_random.bit_generator.state
    with pytest.raises(ValueError, match="seed=9223372036854775808 is invalid"):
        env.reset(seed=2**63)
    assert env.unwrapped.np_random.bit_generator.state == before
