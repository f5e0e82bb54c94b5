"""PettingZoo's own test suite, turn order, rewards and errors of the AEC and parallel envs."""

import functools
import types
import warnings

import numpy as np
import pytest
from conftest import goal_seeking_move
from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
    state_test,
)
from pettingzoo.utils import wrappers

import activeperc_env
from activeperc_env import LOOKER, MOVER
from activeperc_env.rooms import ROOMS


@pytest.mark.parametrize("version", ROOMS)
def test_api_test(version):
    api_test(activeperc_env.env(version=version), num_cycles=150)


@pytest.mark.parametrize("version", ROOMS)
def test_parallel_api_test(version):
    parallel_api_test(activeperc_env.parallel_env(version=version), num_cycles=150)


@pytest.mark.parametrize("version", ROOMS)
def test_seed_tests(version):
    seed_test(functools.partial(activeperc_env.env, version=version), num_cycles=60)
    parallel_seed_test(functools.partial(activeperc_env.parallel_env, version=version), num_cycles=60)


@pytest.mark.parametrize("version", ROOMS)
def test_max_cycles_test(version):
    room = types.SimpleNamespace(
        env=functools.partial(activeperc_env.env, version=version),
        parallel_env=functools.partial(activeperc_env.parallel_env, version=version),
    )
    max_cycles_test(room)


@pytest.mark.parametrize("version", ROOMS)
def test_render_test(version):
    render_test(lambda render_mode=None: activeperc_env.env(render_mode=render_mode, version=version))


@pytest.mark.parametrize("version", ROOMS)
def test_every_env_is_named_after_its_room(version):
    """The classes' metadata name the default room; each env names its own, as its record does."""
    assert activeperc_env.raw_env.metadata["name"] == activeperc_env.parallel_env.metadata["name"] == "activeperc_v3"
    assert activeperc_env.env().metadata["name"] == activeperc_env.parallel_env().metadata["name"] == "activeperc_v3"
    for make in (activeperc_env.env, activeperc_env.raw_env, activeperc_env.parallel_env):
        assert make(version=version).metadata["name"] == ROOMS[version].name == f"activeperc_v{version}"


def test_env_is_order_enforced_and_agents_alternate():
    env = activeperc_env.env(max_cycles=3)
    assert isinstance(env, wrappers.OrderEnforcingWrapper)
    env.reset(seed=0)
    parallel = activeperc_env.parallel_env()
    parallel.reset(seed=0)
    assert env.possible_agents == env.agents == parallel.possible_agents == parallel.agents == [MOVER, LOOKER]
    order = []
    for agent in env.agent_iter():
        order.append(agent)
        _, _, term, trunc, _ = env.last()
        env.step(None if term or trunc else 1)
    assert order == [MOVER, LOOKER] * 3 + [MOVER, LOOKER][: len(order) - 6]
    assert len(order) == 8


@pytest.mark.parametrize("looker_reward, shared", [("shared", True), ("none", False)])
def test_reward_arrives_after_the_move_and_is_shared_by_config(looker_reward, shared):
    env = activeperc_env.env(num_obstacles=0, looker_reward=looker_reward)
    env.reset(seed=3)
    sim = env.unwrapped.sim
    probe = activeperc_env.Simulator(sim.config)  # finds the scripted path, then the AEC env replays it
    probe.reset(seeds=[3])
    moves = []
    while not probe.done[0]:
        moves.append(goal_seeking_move(probe))
        probe.move([moves[-1]])
    assert len(moves) < sim.config.max_cycles, "the scripted mover should reach the goal"
    for move in moves[:-1]:
        env.step(move)
        env.step(1)
    env.step(moves[-1])
    _, reward, term, _, _ = env.last()
    expected = 1 - 0.2 * len(moves) / sim.config.max_cycles
    assert env.agent_selection == LOOKER
    assert reward == (expected if shared else 0.0)  # exactly: rewards are float64
    assert not term, "the episode ends at the end of the cycle"
    assert env.infos == {MOVER: {}, LOOKER: {}}
    env.step(1)
    assert env.terminations[MOVER] and env.terminations[LOOKER]
    assert env.last()[1] == pytest.approx(expected), "the mover's last() carries its reward"
    outcome = {"episode_success": True, "episode_return": expected}  # the mover's return, in both agents' info
    assert env.last()[4] == env.infos[LOOKER] == outcome
    parallel = activeperc_env.parallel_env(num_obstacles=0, looker_reward=looker_reward)
    parallel.reset(seed=3)
    for move in moves:
        _, rewards, terminations, _, infos = parallel.step({MOVER: move, LOOKER: 1})
        assert infos == ({MOVER: outcome, LOOKER: outcome} if terminations[MOVER] else {MOVER: {}, LOOKER: {}})
    assert terminations == {MOVER: True, LOOKER: True}
    assert rewards == {MOVER: expected, LOOKER: expected if shared else 0.0}


def test_a_truncated_episode_ends_with_its_outcome_in_info():
    aec, parallel = activeperc_env.env(max_cycles=2), activeperc_env.parallel_env(max_cycles=2)
    aec.reset(seed=0)
    parallel.reset(seed=0)
    for _ in range(2):  # turning in place never reaches the goal
        aec.step(0)
        aec.step(1)
        *_, truncations, infos = parallel.step({MOVER: 0, LOOKER: 1})
    outcome = {"episode_success": False, "episode_return": 0.0}
    assert aec.truncations[MOVER] and aec.last()[4] == outcome
    assert truncations[MOVER] and infos == {MOVER: outcome, LOOKER: outcome}


def test_bad_action_names_agent_and_space():
    env = activeperc_env.env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="mover_0.*Discrete"):
        env.step(5)
    env.step(0)
    with pytest.raises(ValueError, match="looker_0.*Discrete"):
        env.step("pan")
    par = activeperc_env.parallel_env()
    par.reset(seed=0)
    with pytest.raises(ValueError, match="looker_0.*Discrete"):
        par.step({MOVER: 0, LOOKER: 3})
    with pytest.raises(ValueError, match="missing"):
        par.step({MOVER: 0})
    for actions in (None, [0, 1]):
        with pytest.raises(ValueError, match=r"expected a dict of actions of \['mover_0', 'looker_0'\]"):
            par.step(actions)


def test_unknown_agent_is_named():
    env = activeperc_env.env()
    with pytest.raises(ValueError, match="cat_0"):
        env.observation_space("cat_0")


@pytest.mark.parametrize("display, why", [(None, "none found"), (":99", "display ':99' could not be opened")])
def test_rgb_array_map_and_headless_human(monkeypatch, display, why):
    """Without a display, or with one that cannot be reached (a stale DISPLAY), 'human' warns once and goes on."""
    env = activeperc_env.env(render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if display is None:
        monkeypatch.delenv("DISPLAY", raising=False)
    else:
        monkeypatch.setenv("DISPLAY", display)
    human = activeperc_env.env(render_mode="human")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        human.reset(seed=0)
        assert human.render() is None
        human.step(0)
    messages = [str(w.message) for w in caught if "needs a display" in str(w.message)]
    assert len(messages) == 1 and why in messages[0]


def test_the_human_viewer_follows_the_robot(monkeypatch):
    """MuJoCo's passive viewer draws the poses of the data it was given: each frame must recompute them from the
    copied qpos (a viewer that only copied qpos showed the first pose for ever). A stand-in for the window."""
    import contextlib

    import mujoco.viewer

    from activeperc_env import viewer

    class Window:
        syncs = 0

        def lock(self):
            return contextlib.nullcontext()

        def sync(self):
            Window.syncs += 1

        def close(self):
            pass

    monkeypatch.setattr(viewer, "missing_display", lambda: None)
    monkeypatch.setattr(mujoco.viewer, "launch_passive", lambda model, data: Window())
    env = activeperc_env.parallel_env(render_mode="human")
    env.reset(seed=0)
    shown = env._viewer._data
    start = shown.xpos.copy()
    for _ in range(4):
        env.step({MOVER: 2, LOOKER: 1})
    assert Window.syncs == 5
    robot = env.unwrapped.sim.physics_data(0)
    mujoco.mj_kinematics(env.unwrapped.sim.model, robot)
    assert np.abs(shown.xpos - start).max() > 0.1 and np.allclose(shown.xpos, robot.xpos)
    env.close()


def test_observations_are_the_callers_own():
    """Changing an observation in place (a user's preprocessing) changes neither the other agent's nor a later one."""
    aec = activeperc_env.env()
    aec.reset(seed=3)
    first = aec.last()[0]
    kept = first["image"].copy()
    first["image"][:] = 0
    first["pan"][:] = 9.0
    assert np.array_equal(aec.observe(MOVER)["image"], kept) and aec.observe(MOVER)["pan"][0] == 0.0
    assert np.array_equal(aec.observe(LOOKER)["image"], kept)

    par = activeperc_env.parallel_env()
    for observations in (par.reset(seed=3)[0], par.step({MOVER: 2, LOOKER: 0})[0]):
        mover, looker = observations[MOVER], observations[LOOKER]
        assert np.array_equal(mover["image"], looker["image"]) and mover["pan"] == looker["pan"]
        before = looker["image"].copy()
        mover["image"][:] = 0
        mover["pan"][:] = 9.0
        assert np.array_equal(looker["image"], before) and looker["pan"][0] != 9.0


@pytest.mark.parametrize("version", ROOMS)
def test_state_test_passes_without_warnings(version):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        state_test(activeperc_env.env(version=version), activeperc_env.parallel_env(version=version), num_cycles=150)


@pytest.mark.parametrize("num_obstacles", [0, 3, 6])
def test_state_is_the_true_layout_and_the_same_in_both_envs(num_obstacles):
    aec = activeperc_env.env(num_obstacles=num_obstacles, max_cycles=40, pan_range=60)
    par = activeperc_env.parallel_env(num_obstacles=num_obstacles, max_cycles=40, pan_range=60)
    aec.reset(seed=4)
    par.reset(seed=4)
    assert aec.state_space == par.state_space and aec.state_space.shape == (8 + 2 * num_obstacles,)
    sim = aec.unwrapped.sim
    rng = np.random.default_rng(0)
    for cycle in range(1, 13):
        move, look = goal_seeking_move(sim), int(rng.integers(3))
        aec.step(move)
        aec.step(look)
        par.step({MOVER: move, LOOKER: look})
        state = aec.state()
        assert state.dtype == np.float32 and aec.state_space.contains(state)
        np.testing.assert_array_equal(state, par.state())
        xy, heading, pan = sim.pose()
        expected = [*xy, np.cos(heading), np.sin(heading), pan, *sim.goal_xy(), *sim.occluders_xy().ravel(), cycle / 40]
        np.testing.assert_allclose(state, np.array(expected, dtype=np.float32), rtol=0, atol=1e-6)
    assert abs(state[4]) > 0  # the random looks turned the camera


def test_state_and_step_before_reset_say_so():
    env = activeperc_env.parallel_env()
    with pytest.raises(RuntimeError, match=r"state\(\) before reset\(\)"):
        env.state()
    with pytest.raises(RuntimeError, match=r"step\(\) before reset\(\)"):
        env.step({MOVER: 0, LOOKER: 1})
    env.reset(seed=0)
    env.state()
    with pytest.raises(RuntimeError, match=r"state\(\) before reset\(\)"):
        activeperc_env.raw_env().state()


@pytest.mark.parametrize("make", [activeperc_env.raw_env, activeperc_env.parallel_env])
def test_render_last_and_observe_before_reset_say_so(make):
    env = make(render_mode="rgb_array")
    calls = {"render": env.render}
    if make is activeperc_env.raw_env:
        calls |= {"last": env.last, "observe": lambda: env.observe(MOVER)}
    for name, call in calls.items():
        with pytest.raises(RuntimeError, match=rf"{name}\(\) before reset\(\): call reset\(\) first"):
            call()
    env.reset(seed=0)
    assert all(call() is not None for call in calls.values())


def test_a_raw_aec_step_outside_an_episode_says_so():
    env = activeperc_env.raw_env(max_cycles=1)
    with pytest.raises(RuntimeError, match=r"step\(\) before reset\(\)"):
        env.step(0)
    env.reset(seed=0)
    for action in (0, 1, None, None):  # one cycle, then each agent steps None once
        env.step(action)
    assert env.agents == []
    with pytest.raises(RuntimeError, match=r"step\(\) after the episode ended"):
        env.step(0)


def test_the_aec_env_is_not_converted_to_another_game():
    """In the AEC env the looker acts on s_bar, so aec_to_parallel (which needs is_parallelizable) must refuse it:
    converted, the looker would act on the view before its own last look. parallel_to_aec keeps the game."""
    from pettingzoo.utils.conversions import aec_to_parallel, parallel_to_aec

    with pytest.raises(AssertionError, match="is_parallelizable"):
        aec_to_parallel(activeperc_env.raw_env())
    aec = parallel_to_aec(activeperc_env.parallel_env())
    api_test(aec, num_cycles=20)


@pytest.mark.extras
def test_supersuit_frame_skip_draws_from_np_random_seeded_by_reset():
    """SuperSuit's parallel frame_skip_v0 with a range draws its skips from env.unwrapped.np_random."""
    import supersuit as ss

    def play(seed):
        env = ss.frame_skip_v0(activeperc_env.parallel_env(max_cycles=30), (1, 3))
        env.reset(seed=seed)
        steps, goal = 0, env.unwrapped.sim.goal_xy()
        while env.agents:
            env.step({"mover_0": 2, "looker_0": 1})
            steps += 1
        return steps, goal.tolist()

    first = play(0)
    assert first == play(0) and 10 <= first[0] < 30  # skips of 1 to 3 cycles, the same for the same seed
    plain = activeperc_env.parallel_env()
    plain.reset(seed=0)
    assert plain.unwrapped.sim.goal_xy().tolist() == first[1]  # the room draws nothing from np_random


@pytest.mark.parametrize("make", [activeperc_env.env, activeperc_env.parallel_env])
def test_render_takes_the_mode_some_libraries_pass(make):
    """RLlib's PettingZoo wrappers call ``render(render_mode)``: the env's own mode is accepted, another refused."""
    env = make(render_mode="rgb_array")
    env.reset(seed=0)
    assert np.array_equal(env.render("rgb_array"), env.render())
    with pytest.raises(ValueError, match="render\\('human'\\) asks for another mode than the env's render_mode='rgb_"):
        env.render("human")


@pytest.mark.parametrize("looker_reward, looker_share", [("shared", 0.0), ("own_turn", 1.0), ("none", 0.0)])
def test_own_turn_gives_the_looker_its_reward_with_its_own_step(looker_reward, looker_share):
    """Tianshou reads ``rewards`` after each step and credits the agent that stepped: with 'own_turn' the looker's
    steps carry the shared reward (with 'shared' it came with the mover's step); ``last()`` totals stay the same."""
    env = activeperc_env.env(num_obstacles=0, looker_reward=looker_reward)
    env.reset(seed=3)
    sim = env.unwrapped.sim
    own_steps = {MOVER: 0.0, LOOKER: 0.0}  # what each agent's own steps returned, as Tianshou sees them
    by_last = {MOVER: 0.0, LOOKER: 0.0}  # what last() gave each agent, as PettingZoo's loop sees them
    for agent in env.agent_iter():
        _, reward, term, trunc, _ = env.last()
        by_last[agent] += reward
        if term or trunc:
            env.step(None)
            continue
        env.step(goal_seeking_move(sim) if agent == MOVER else 1)
        own_steps[agent] += env.unwrapped.rewards[agent]
    assert by_last[MOVER] > 0.5, "the scripted mover should reach the goal"
    assert by_last[LOOKER] == (0.0 if looker_reward == "none" else by_last[MOVER])
    assert own_steps == {MOVER: by_last[MOVER], LOOKER: looker_share * by_last[MOVER]}


def test_image_only_envs_pass_pettingzoo_api_tests_and_observe_the_image():
    aec = activeperc_env.image_only(activeperc_env.env(max_cycles=20))
    api_test(aec, num_cycles=30)
    parallel = activeperc_env.image_only(activeperc_env.parallel_env(max_cycles=20))
    parallel_api_test(parallel, num_cycles=30)
    plain = activeperc_env.parallel_env(max_cycles=20)
    images, _ = parallel.reset(seed=3)
    full, _ = plain.reset(seed=3)
    for agent in plain.agents:
        assert np.array_equal(images[agent], full[agent]["image"])
    floats = activeperc_env.image_only(activeperc_env.parallel_env(max_cycles=20), floats=True)
    scaled, _ = floats.reset(seed=3)
    assert floats.observation_space(MOVER).dtype == np.float32 and floats.observation_space(MOVER).contains(
        scaled[MOVER]
    )
    assert np.array_equal(scaled[MOVER], full[MOVER]["image"].astype(np.float32) / 255)
    with pytest.raises(TypeError, match="expected a PettingZoo AEC or parallel env"):
        activeperc_env.image_only(object())
