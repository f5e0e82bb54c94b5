"""``gymnasium.make_vec`` on our ids: N rooms in one batched core, the same episodes as Gymnasium's SyncVectorEnv."""

import gymnasium
import numpy as np
import pytest
from conftest import assert_same_view, goal_seeking_move
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import activeperc_env

IDS = ["activeperc/Joint-v1", "activeperc/FixedForward-v1", "activeperc/Joint-v0"]


def assert_same_observations(ours, theirs):
    """Same pan angles and ranges; same images up to the rasteriser's rounding (a room of ours is drawn in its own
    tile)."""
    assert set(ours) == set(theirs)
    assert {"image", "pan"} <= set(ours)
    for key in set(ours) - {"image"}:
        np.testing.assert_array_equal(ours[key], theirs[key])
    assert_same_view(ours["image"], theirs["image"])


def assert_same_infos(ours, theirs):
    assert set(ours) == set(theirs)
    for key, value in theirs.items():
        if key == "final_obs":
            for mine, other in zip(ours[key], value, strict=True):
                assert (mine is None) == (other is None)
                if other is not None:
                    assert_same_observations(
                        {k: v[None] for k, v in mine.items()}, {k: v[None] for k, v in other.items()}
                    )
        elif isinstance(value, dict):
            assert_same_infos(ours[key], value)
        else:
            np.testing.assert_array_equal(ours[key], value)
            assert ours[key].dtype == value.dtype


def actions_for(env_id, vec, rng):
    """Goal-seeking moves in the first rooms (so that episodes end in success too), random ones in the last."""
    sim = vec.unwrapped.sim
    moves = [goal_seeking_move(sim, i) for i in range(vec.num_envs - 1)] + [int(rng.integers(3))]
    moves = np.array(moves)
    if env_id == "activeperc/FixedForward-v1":
        return moves
    return 3 * moves + rng.integers(3, size=vec.num_envs)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("env_id", IDS)
def test_same_episodes_as_the_sync_vector_env(env_id, mode):
    config = {"max_cycles": 30, "num_obstacles": 0, "goal_distance": 2.5}  # the scripted rooms succeed in ~20
    ours = gymnasium.make_vec(env_id, num_envs=3, autoreset_mode=mode, **config)
    theirs = gymnasium.make_vec(
        env_id, num_envs=3, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **config
    )
    ours_class = activeperc_env.JointVectorEnv if "Joint" in env_id else activeperc_env.FixedForwardVectorEnv
    assert isinstance(ours, ours_class)
    assert isinstance(theirs, SyncVectorEnv)
    assert ours.single_observation_space == theirs.single_observation_space
    assert ours.single_action_space == theirs.single_action_space
    assert ours.observation_space == theirs.observation_space and ours.action_space == theirs.action_space
    assert ours.metadata["autoreset_mode"] == theirs.metadata["autoreset_mode"] == mode
    (obs, info), (obs2, info2) = ours.reset(seed=5), theirs.reset(seed=5)
    assert_same_observations(obs, obs2)
    assert_same_infos(info, info2)
    rng = np.random.default_rng(0)
    ended = {"terminated": 0, "truncated": 0}
    for _ in range(70):
        actions = actions_for(env_id, ours, rng)
        mine, other = ours.step(actions), theirs.step(actions)
        assert_same_observations(mine[0], other[0])
        for k in (1, 2, 3):
            np.testing.assert_array_equal(mine[k], other[k])
            assert mine[k].dtype == other[k].dtype
        assert_same_infos(mine[4], other[4])
        ended["terminated"] += int(mine[2].sum())
        ended["truncated"] += int(mine[3].sum())
    assert ended["terminated"] > 0 and ended["truncated"] > 0  # both ends and their autoresets were compared
    ours.close()
    theirs.close()


def test_reset_mask_and_disabled_autoreset():
    ours = gymnasium.make_vec("activeperc/FixedForward-v1", num_envs=3, max_cycles=2, autoreset_mode="Disabled")
    theirs = gymnasium.make_vec(
        "activeperc/FixedForward-v1",
        num_envs=3,
        max_cycles=2,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": AutoresetMode.DISABLED},
    )
    ours.reset(seed=[3, 4, 7])
    theirs.reset(seed=[3, 4, 7])
    ours.step(np.array([2, 2, 2]))
    theirs.step(np.array([2, 2, 2]))
    *_, truncated, _ = ours.step(np.array([0, 1, 2]))
    theirs.step(np.array([0, 1, 2]))
    assert truncated.all()
    with pytest.raises(RuntimeError, match=r"finished rooms \[0, 1, 2\].*reset_mask"):
        ours.step(np.array([2, 2, 2]))
    mask = np.array([True, False, True])
    seeds = [None, 5, 20]  # room 0 draws its next layout from the stream seeded with 3; room 1 is not reset
    (obs, info), (obs2, info2) = (
        ours.reset(seed=seeds, options={"reset_mask": mask}),
        theirs.reset(seed=seeds, options={"reset_mask": mask.copy()}),
    )
    room_0 = [ours.unwrapped.sim.pose(0)[0], theirs.envs[0].unwrapped.sim.pose(0)[0]]
    np.testing.assert_array_equal(*room_0)
    assert_same_observations(obs, obs2)
    assert_same_infos(info, info2)
    with pytest.raises(RuntimeError, match=r"finished rooms \[1\]"):  # room 1 was not reset
        ours.step(np.array([2, 2, 2]))
    ours.close()
    theirs.close()


def test_bad_input_is_named():
    vec = gymnasium.make_vec("activeperc/Joint-v1", num_envs=2)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"joint agent action 9 of room 1 is outside its action space Discrete\(9\)"):
        vec.step(np.array([0, 9]))
    with pytest.raises(ValueError, match=r"joint agent action\(s\) \[1\] invalid: expected 2 ints"):
        vec.step([1])
    with pytest.raises(ValueError, match=r"action\(s\) .*0\.5.* invalid"):
        vec.step(np.array([0.5, 1.0]))
    with pytest.raises(ValueError, match=r"seed=\[1\] is invalid"):
        vec.reset(seed=[1])
    first = vec.unwrapped.sim.state()
    with pytest.raises(ValueError, match=r"seed\[1\]=-1 is invalid"):
        vec.reset(seed=[1, -1])
    np.testing.assert_array_equal(vec.unwrapped.sim.state(), first)  # no room was reseeded
    with pytest.raises(ValueError, match=r"seed=9223372036854775807 is invalid: room i gets seed \+ i, so with 2"):
        vec.reset(seed=2**63 - 1)
    with pytest.raises(ValueError, match=r"seed=-1 is invalid: .* an int in \[0, 2\*\*63 - 2\]"):
        vec.reset(seed=np.int64(-1))
    np.testing.assert_array_equal(vec.unwrapped.sim.state(), first)
    vec.reset(seed=2**63 - 2)  # the largest: room 1 gets 2**63 - 1
    with pytest.raises(TypeError, match=r"reset_mask.*is invalid: expected a \(2,\) bool array"):
        vec.reset(options={"reset_mask": [True, False]})
    with pytest.raises(ValueError, match=r"reset_mask'\] has shape \(3,\)"):
        vec.reset(options={"reset_mask": np.ones(3, dtype=bool)})
    with pytest.raises(ValueError, match="marks no room"):
        vec.reset(options={"reset_mask": np.zeros(2, dtype=bool)})
    with pytest.raises(ValueError, match="nthread=-1 is invalid"):
        gymnasium.make_vec("activeperc/Joint-v1", num_envs=2, nthread=-1)
    with pytest.raises(ValueError, match="max_episode_steps=0 is invalid"):
        gymnasium.make_vec("activeperc/Joint-v1", num_envs=2, max_episode_steps=0)
    vec.close()
    with pytest.raises(ValueError, match="autoreset_mode='sometimes' is invalid"):
        activeperc_env.JointVectorEnv(num_envs=2, autoreset_mode="sometimes")
    with pytest.raises(ValueError, match="render_mode='human' is invalid for a vector env"):
        activeperc_env.JointVectorEnv(num_envs=2, render_mode="human")
    with pytest.raises(ValueError, match="num_envs=0 is invalid"):
        gymnasium.make_vec("activeperc/Joint-v1", num_envs=0)
    with pytest.raises(ValueError, match="fov=500"):
        gymnasium.make_vec("activeperc/Joint-v1", num_envs=2, fov=500)


def test_a_refused_vector_env_is_collected_without_an_error(monkeypatch):
    import gc
    import sys

    unraised = []
    monkeypatch.setattr(sys, "unraisablehook", unraised.append)
    with pytest.raises(ValueError, match="autoreset_mode='sometimes' is invalid"):
        activeperc_env.JointVectorEnv(num_envs=2, autoreset_mode="sometimes")
    gc.collect()  # gymnasium's VectorEnv.__del__ closes the half-built env
    assert [str(u.exc_value) for u in unraised] == []


def test_step_or_render_before_reset_is_refused():
    vec = gymnasium.make_vec("activeperc/Joint-v1", num_envs=2, render_mode="rgb_array")
    with pytest.raises(gymnasium.error.ResetNeeded, match="step\\(\\) before reset"):
        vec.step(np.array([0, 1]))
    with pytest.raises(gymnasium.error.ResetNeeded, match="render\\(\\) before reset"):
        vec.render()
    with pytest.raises(gymnasium.error.ResetNeeded, match="first reset\\(\\) must start every room"):
        vec.reset(options={"reset_mask": np.array([True, False])})
    vec.reset(seed=np.int64(3))  # a numpy int is a seed too
    reference = activeperc_env.Simulator(activeperc_env.EnvConfig(version=1), num_envs=2)
    reference.reset(seeds=[3, 4])
    np.testing.assert_array_equal(vec.unwrapped.sim.state(), reference.state())
    vec.close()


def test_max_episode_steps_truncates_as_gymnasium_make_does():
    kwargs = {"num_envs": 2, "max_episode_steps": 3, "disable_env_checker": True, "max_cycles": 5}
    ours = gymnasium.make_vec("activeperc/FixedForward-v1", **kwargs)
    theirs = gymnasium.make_vec("activeperc/FixedForward-v1", vectorization_mode="sync", **kwargs)
    ours.reset(seed=0)
    theirs.reset(seed=0)
    truncated = []
    for _ in range(8):
        mine, other = ours.step(np.array([0, 1])), theirs.step(np.array([0, 1]))
        for k in (1, 2, 3):
            np.testing.assert_array_equal(mine[k], other[k])
        assert_same_infos(mine[4], other[4])
        truncated.append(bool(mine[3].all()))
    assert truncated == [False, False, True, False, False, False, True, False]  # step 4 and 8 restart the rooms
    ours.close()
    theirs.close()


def test_observations_are_the_callers_own_and_render_gives_every_map():
    vec = gymnasium.make_vec("activeperc/Joint-v1", num_envs=2, render_mode="rgb_array", fov=100)
    obs, _ = vec.reset(seed=0)
    kept = obs["image"].copy()
    obs["image"][:] = 0
    after, *_ = vec.step(np.array([4, 4]))  # forward, hold: the views change
    assert after["image"].any() and not np.array_equal(after["image"], kept)
    maps = vec.render()
    assert len(maps) == 2 and all(m.shape == (240, 320, 3) and m.dtype == np.uint8 for m in maps)
    assert not np.array_equal(maps[0], maps[1])  # two layouts
    assert vec.unwrapped.config.fov == 100 and vec.metadata["render_fps"] == vec.unwrapped.config.control_hz
    vec.close()


def test_gymnasium_vector_wrappers_count_episodes():
    vec = gymnasium.wrappers.vector.RecordEpisodeStatistics(
        gymnasium.make_vec("activeperc/FixedForward-v1", num_envs=2, max_cycles=3)
    )
    vec.reset(seed=0)
    for _ in range(3):
        *_, info = vec.step(np.array([0, 1]))
    assert info["_episode"].all()
    np.testing.assert_array_equal(info["episode"]["l"], [3, 3])
    np.testing.assert_array_equal(info["episode"]["r"], [0.0, 0.0])
    vec.close()


@pytest.mark.extras
def test_torchrl_gym_wrapper_runs_it_with_autoreset_disabled():
    import torch
    from torchrl.envs import GymWrapper
    from torchrl.envs.utils import check_env_specs

    vec = gymnasium.make_vec("activeperc/FixedForward-v1", num_envs=3, max_cycles=4, autoreset_mode="Disabled")
    env = GymWrapper(vec)
    check_env_specs(env, seed=0)
    data = env.rollout(10, break_when_any_done=False)  # TorchRL resets the finished rooms through reset_mask
    done = data["next", "done"].squeeze(-1)
    assert torch.equal(done, (torch.arange(10) % 4 == 3).expand(3, 10))
    assert data["image"].shape == (3, 10, 60, 80, 3)
    env.close()


def test_odd_reset_arguments_are_taken_or_named():
    env = gymnasium.make_vec("activeperc/Joint-v1", num_envs=2)
    zero_d, _ = env.reset(seed=np.array(3))  # one seed as a 0-d array, as the one-room envs take it
    plain, _ = env.reset(seed=3)
    assert np.array_equal(zero_d["image"], plain["image"])
    with pytest.raises(TypeError, match="options='x' is invalid: expected None or a dict"):
        env.reset(options="x")
    env.close()
