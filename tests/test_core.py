"""The batched core: one episode through every API, the paper's cycle, reward and reset."""

import re

import gymnasium
import numpy as np
import pytest
from conftest import assert_same_view, drive_to_goal, goal_seeking_move

import activeperc_env
from activeperc_env import LOOKER, MOVER, EnvConfig, Simulator
from activeperc_env.config import is_int
from activeperc_env.rooms import ROOMS

SEED = 7
CYCLES = 25


def _actions(n=CYCLES):
    rng = np.random.default_rng(123)
    return rng.integers(0, 3, size=(n, 2))


@pytest.mark.parametrize("version", ROOMS)
def test_same_seed_same_episode_through_every_api(version):
    actions = _actions()
    sim = Simulator(EnvConfig(version=version), num_envs=3)
    sim.reset(seeds=[SEED, SEED + 1, SEED])
    aec = activeperc_env.env(version=version)
    aec.reset(seed=SEED)
    par = activeperc_env.parallel_env(version=version)
    par_obs, _ = par.reset(seed=SEED)
    joint = gymnasium.make(f"activeperc/Joint-v{version}")
    joint_obs, _ = joint.reset(seed=SEED)
    first = sim.render()
    for obs in (aec.observe(MOVER), par_obs[MOVER], joint_obs):
        np.testing.assert_array_equal(obs["image"], first[0])
    assert_same_view(first[0], first[2])
    assert not np.array_equal(first[0], first[1]), "different seeds gave the same layout"

    for move, look in actions:
        sim.move(np.array([move] * 3))
        s_bar = sim.render()
        sim.look(np.array([look] * 3))
        s_next = sim.render()
        aec.step(int(move))
        np.testing.assert_array_equal(aec.observe(LOOKER)["image"], s_bar[0])
        aec.step(int(look))
        np.testing.assert_array_equal(aec.observe(MOVER)["image"], s_next[0])
        np.testing.assert_array_equal(aec.observe(MOVER)["pan"], sim.pan()[0])
        par_obs, *_ = par.step({MOVER: int(move), LOOKER: int(look)})
        np.testing.assert_array_equal(par_obs[MOVER]["image"], s_next[0])
        joint_obs, *_ = joint.step(int(3 * move + look))
        np.testing.assert_array_equal(joint_obs["image"], s_next[0])
        assert_same_view(s_next[0], s_next[2])  # same room, another tile of the buffer


def test_physics_is_identical_at_any_batch_size_and_thread_count():
    actions = _actions()
    one = Simulator(num_envs=1, nthread=1)
    many = Simulator(num_envs=8, nthread=2)
    one.reset(seeds=[SEED])
    many.reset(seeds=np.full(8, SEED))
    for move, _ in actions:
        one.move(np.array([move]))
        many.move(np.full(8, move))
    xy, heading, _ = one.pose(0)
    for i in range(8):
        xy_i, heading_i, _ = many.pose(i)
        np.testing.assert_array_equal(xy, xy_i)
        assert heading == heading_i


def test_looker_never_moves_the_base_and_mover_never_turns_the_camera():
    sim = Simulator(num_envs=4)
    sim.reset(seeds=np.arange(4))
    rng = np.random.default_rng(0)
    for _ in range(30):
        pans = sim.pan().copy()
        sim.move(rng.integers(0, 3, 4))
        np.testing.assert_array_equal(sim.pan(), pans)
        poses = [sim.pose(i)[:2] for i in range(4)]
        sim.look(rng.integers(0, 3, 4))
        for i in range(4):
            np.testing.assert_array_equal(sim.pose(i)[0], poses[i][0])
            assert sim.pose(i)[1] == poses[i][1]
        if sim.done.any():
            sim.reset(np.flatnonzero(sim.done))


def test_look_views_show_what_each_look_would_show_and_turn_nothing():
    sim = Simulator(EnvConfig(), num_envs=3, nthread=1)
    sim.reset(seeds=[1, 2, 3])
    sim.move(np.array([2, 0, 2]))
    sim.look(np.array([0, 1, 1]))
    sim.look(np.array([0, 1, 1]))
    sim.look(np.array([0, 1, 1]))
    sim.look(np.array([0, 1, 1]))  # room 0's camera at its left limit
    state = sim.get_state()
    views, pans = sim.look_views()
    assert views.shape == (3, 3, 60, 80, 3) and pans.shape == (3, 3, 1)
    assert np.array_equal(sim.get_state()["physics"], state["physics"])
    assert np.array_equal(views[:, 1], sim.render()) and np.array_equal(pans[:, 1], sim.pan())
    assert np.array_equal(views[0, 0], views[0, 1])  # a pan against the limit shows the view of a hold
    for look in (0, 2):
        other = Simulator(EnvConfig(), num_envs=3, nthread=1)
        other.set_state(state)
        other.look(np.full(3, look))
        assert np.array_equal(other.pan(), pans[:, look])
        assert_same_view(other.render(), views[:, look])
        other.close()
    sim.close()


def test_pan_moves_by_step_and_stays_in_range():
    config = EnvConfig(pan_step=30, pan_range=60)
    sim = Simulator(config)
    sim.reset(seeds=[0])
    sim.look([0])
    assert np.isclose(sim.pan()[0, 0], np.radians(30), atol=1e-6)
    for _ in range(5):
        sim.look([0])
    assert np.isclose(sim.pan()[0, 0], np.radians(60), atol=1e-6)
    sim.look([1])
    assert np.isclose(sim.pan()[0, 0], np.radians(60), atol=1e-6)
    for _ in range(6):
        sim.look([2])
    assert np.isclose(sim.pan()[0, 0], -np.radians(60), atol=1e-6)


def test_scripted_controller_reaches_goal_and_reward_matches_formula():
    config = EnvConfig(num_obstacles=0)
    sim = Simulator(config, num_envs=1)
    for seed in range(5):
        sim.reset(seeds=[seed])
        rewards = drive_to_goal(sim)
        cycle, reward = rewards[-1]
        assert sim.done[0]
        assert cycle < config.max_cycles / 2, "a good policy should need well under half of max_cycles"
        assert reward == 1 - 0.2 * cycle / config.max_cycles  # exactly, in float64
        assert all(r == 0.0 for _, r in rewards[:-1])


def test_truncation_at_max_cycles_with_zero_reward():
    sim = Simulator(EnvConfig(max_cycles=5))
    sim.reset(seeds=[0])
    for t in range(5):
        result = sim.move([0])  # turning in place never reaches the goal
        assert result.reward[0] == 0.0
        assert result.truncated[0] == (t == 4)
        assert not result.terminated[0]
    with pytest.raises(RuntimeError, match="reset"):
        sim.move([0])


def test_a_move_reports_its_episodes_outcome_and_a_reset_clears_it():
    room = EnvConfig(max_cycles=30, num_obstacles=0, goal_distance=2.5, version=1)  # a base that turns in place
    sim = Simulator(room, num_envs=2, nthread=1)
    sim.reset(seeds=[0, 1])
    summed = np.zeros(2)
    while not sim.done.all():  # room 0 drives to the goal, room 1 turns in place until max_cycles
        running = np.flatnonzero(~sim.done)
        result = sim.move(np.array([goal_seeking_move(sim, 0), 0])[running], ids=running)
        summed[running] += result.reward
        np.testing.assert_array_equal(result.episode_return, summed[running])
        np.testing.assert_array_equal(result.success, result.terminated)
    assert sim.success.tolist() == [True, False] and summed[0] > 0 == summed[1]
    np.testing.assert_array_equal(sim.episode_return, summed)
    copy = Simulator(sim.config, num_envs=2, nthread=1)
    copy.set_state(sim.get_state())
    assert copy.success.tolist() == [True, False] and copy.episode_return.tolist() == summed.tolist()
    old = {key: value for key, value in sim.get_state().items() if key not in ("success", "episode_return")}
    copy.set_state(old)  # a state saved before outcomes were kept
    assert not copy.success.any() and not copy.episode_return.any()
    sim.reset(ids=[0])
    assert sim.success.tolist() == [False, False] and sim.episode_return.tolist() == [0.0, summed[1]]


def test_partial_reset_leaves_other_rooms_alone():
    sim = Simulator(num_envs=3)
    sim.reset(seeds=[1, 2, 3])
    sim.move([2, 2, 2])
    before = [sim.pose(i) for i in range(3)]
    sim.reset(ids=[1], seeds=[9])
    assert sim.cycle.tolist() == [1, 0, 1]
    for i in (0, 2):
        np.testing.assert_array_equal(sim.pose(i)[0], before[i][0])
    other = Simulator(num_envs=1)
    other.reset(seeds=[9])
    np.testing.assert_array_equal(sim.render(ids=[1]), other.render())


def test_unseeded_resets_continue_the_seeded_stream():
    a, b = Simulator(), Simulator()
    a.reset(seeds=[5])
    b.reset(seeds=[5])
    a.reset()
    b.reset()
    np.testing.assert_array_equal(a.goal_xy(), b.goal_xy())
    c = Simulator()
    c.reset(seeds=[5])
    assert not np.array_equal(a.goal_xy(), c.goal_xy())


def test_rooms_never_seeded_draw_layouts_of_their_own():
    """Without a seed, every room of every simulator starts from fresh entropy, as Gymnasium's envs do."""
    a, b = Simulator(num_envs=3), Simulator(num_envs=3)
    a.reset()
    b.reset()
    goals = [tuple(sim.goal_xy(i)) for sim in (a, b) for i in range(3)]
    assert len(set(goals)) == 6


@pytest.mark.parametrize("bad", [3, -1, [0, 1], 1.5, "left", True])
def test_bad_actions_name_the_agent_and_its_space(bad):
    sim = Simulator()
    sim.reset(seeds=[0])
    with pytest.raises(ValueError, match=r"mover.*Discrete\(3\)"):
        sim.move(np.array(bad) if not isinstance(bad, str) else bad)
    with pytest.raises(ValueError, match=r"looker.*Discrete\(3\)"):
        sim.look(np.array(bad) if not isinstance(bad, str) else bad)


def test_bad_num_envs_nthread_config_and_ids_are_named():
    for num_envs in (0, 2**16 + 1, 2**63):
        with pytest.raises(ValueError, match=f"num_envs={num_envs} is invalid: expected an int in 1 .. 65536"):
            Simulator(num_envs=num_envs)
    for nthread in (-1, 1.5, None):
        with pytest.raises(ValueError, match=f"nthread={nthread}"):
            Simulator(num_envs=2, nthread=nthread)
    with pytest.raises(TypeError, match=r"config=\{'fov': 100\} is invalid: expected an EnvConfig"):
        Simulator({"fov": 100})
    sim = Simulator(num_envs=2)
    with pytest.raises(ValueError, match=r"\[5\]"):
        sim.reset(ids=[5])


def test_room_ids_and_indices_are_ints_of_rooms_and_a_refused_call_changes_nothing():
    sim = Simulator(num_envs=3)
    sim.reset(seeds=[0, 1, 2])
    before = sim.get_state()
    for ids in (np.array([False, True, True]), [0.5], "0", [[0, 1]], slice(0, 2)):  # a mask; floats; ...
        with pytest.raises(ValueError, match="room ids .* are invalid: expected ints in 0 .. 2"):
            sim.look([0, 0], ids=ids)
    for call in (lambda: sim.reset(ids=[1, 1], seeds=[7, 8]), lambda: sim.move([0, 0], ids=[2, 0])):
        with pytest.raises(ValueError, match="expected distinct rooms in increasing order"):
            call()
    with pytest.raises(ValueError, match="distinct rooms"):
        sim.look([0, 0], ids=[1, 1])
    assert sim.render([2, 0, 2]).shape[0] == 3  # reading calls take any rooms in any order
    after = sim.get_state()
    assert all(np.array_equal(before[key], after[key]) for key in ("physics", "cycle", "done"))
    assert after["rngs"] == before["rngs"]  # the refused reset did not reseed room 1
    for index in (-1, 3, True, 1.0, None):
        for call in (sim.render_map, sim.pose, sim.goal_xy, sim.occluders_xy, sim.physics_data):
            with pytest.raises(ValueError, match=f"room index {index!r} is invalid"):
                call(index)
    with pytest.raises(RuntimeError, match=r"pose\(\) before reset"):
        Simulator().pose()
    sim.reset(ids=[1], seeds=np.array(7))  # a 0-d array is one seed
    alone = Simulator()
    alone.reset(seeds=[7])
    assert np.array_equal(sim.state([1]), alone.state())


@pytest.mark.parametrize("seed", [1.7, True, -1, 2**63, "0"])
def test_bad_seeds_are_named_by_every_api(seed):
    match = re.escape(repr(seed))
    with pytest.raises(ValueError, match=match):
        Simulator().reset(seeds=[seed])
    for env in (activeperc_env.env(), activeperc_env.parallel_env()):
        with pytest.raises(ValueError, match=match):
            env.reset(seed=seed)
    if is_int(seed) and seed >= 0:  # Gymnasium refuses the others itself
        with pytest.raises(ValueError, match=match):
            gymnasium.make("activeperc/Joint-v1").reset(seed=seed)
    with pytest.raises(ValueError, match=r"2 ints, one per reset room"):
        Simulator(num_envs=2).reset(seeds=[0, 1, 2])


def test_rooms_never_reset_are_refused_by_name():
    sim = Simulator(num_envs=3)
    for call in (lambda: sim.move([0, 0, 0]), lambda: sim.look([0, 0, 0]), sim.render, sim.pan, sim.state):
        with pytest.raises(RuntimeError, match=r"before reset\(\) of rooms \[0, 1, 2\]: call reset\(\)"):
            call()
    with pytest.raises(RuntimeError, match=r"render_map\(\) before reset\(\) of rooms \[2\]"):
        sim.render_map(2)
    sim.reset([0, 1], seeds=[0, 1])
    sim.render([0, 1])
    with pytest.raises(RuntimeError, match=r"render\(\) before reset\(\) of rooms \[2\]"):
        sim.render()
    sim.reset([2])
    assert sim.started().all()
    sim.move([2, 2, 2])
    copy = Simulator(num_envs=3)
    copy.set_state(sim.get_state())
    copy.render()  # a restored state carries which rooms have started
    with pytest.raises(RuntimeError, match=r"^move\(\) before reset\(\): call reset\(\) first$"):
        Simulator().move([0])


def test_occluders_in_use_and_parked():
    sim = Simulator(EnvConfig(num_obstacles=2))
    sim.reset(seeds=[0])
    occluders = sim.occluders_xy()
    assert occluders.shape == (2, 2)
    assert (np.abs(occluders[:, 0]) < 3).all() and (np.abs(occluders[:, 1]) < 2).all()


def test_empty_id_list_is_a_no_op():
    sim = Simulator(num_envs=2)
    sim.reset(seeds=[0, 1])
    assert sim.render(ids=[]).shape == (0, 60, 80, 3)
    assert sim.pan(ids=[]).shape == (0, 1)
    assert sim.move([], ids=[]).reward.shape == (0,)


def _count_drawn_views(sim):
    """Wrap ``sim.renderer.render`` to count the views it draws; returns the list of counts per call."""
    calls, draw = [], sim.renderer.render

    def counting(qpos, mocap_pos, tiles=None):
        calls.append(len(qpos))
        return draw(qpos, mocap_pos, tiles)

    sim.renderer.render = counting
    return calls


def test_views_are_drawn_again_only_for_the_rooms_that_changed():
    sim = Simulator(EnvConfig(), num_envs=3)
    sim.reset(seeds=[1, 2, 3])
    calls = _count_drawn_views(sim)
    first = sim.render()
    assert calls == [3]
    sim.look([1, 1, 1])  # every looker holds: nothing changed
    assert np.array_equal(sim.render(), first) and calls == [3]
    sim.look([1, 0, 1])  # one camera turns
    sim.render()
    assert calls == [3, 1]
    sim.move([2, 2, 2])
    sim.render()
    assert calls == [3, 1, 3]
    sim.render([2])  # room 2 alone goes to the buffer's first tile, not its own: drawn again there
    sim.render([2])
    sim.render()  # and back in its own tile
    assert calls == [3, 1, 3, 1, 1]
    image = sim.render()
    image[:] = 0  # the caller's copy
    assert sim.render().any()
    with pytest.raises(ValueError, match="tiles"):
        sim.renderer.render(np.zeros((2, sim.model.nq)), np.zeros((2, sim.model.nmocap, 3)), tiles=[0, 0])


def test_reused_views_are_the_pixels_of_a_new_render():
    sim = Simulator(EnvConfig(pan_range=60), num_envs=4)
    sim.reset(seeds=[5, 6, 7, 8])
    rng = np.random.default_rng(0)
    for _ in range(30):  # holds, pans, pans against the limit, moves
        if rng.random() < 0.5:
            sim.move(rng.integers(0, 3, 4))
        else:
            sim.look(rng.choice([0, 1, 1, 1, 2], 4))
        data = [sim.physics_data(i) for i in range(4)]
        fresh = sim.renderer.render(np.stack([d.qpos for d in data]), np.stack([d.mocap_pos for d in data]))
        assert np.array_equal(sim.render(), fresh)
        if sim.done.any():
            sim.reset(np.flatnonzero(sim.done))


def test_render_into_a_given_array():
    sim = Simulator(num_envs=3)
    sim.reset(seeds=[1, 2, 3])
    out = np.zeros((2, 60, 80, 3), dtype=np.uint8)
    assert sim.render([2, 0], out=out) is out
    assert out.any()
    everything = sim.render()  # rooms 2 and 0 drawn again, in their own tiles
    assert_same_view(out[0], everything[2])
    assert_same_view(out[1], everything[0])
