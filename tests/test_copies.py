"""Every env can be pickled and deep-copied, and a copy steps on exactly as the original (docs/env.md, "Copies")."""

import copy
import pickle
import re

import gymnasium
import numpy as np
import pytest

import activeperc_env
from activeperc_env import EnvConfig, Simulator
from activeperc_env.viewer import HumanViewer

COPIES = {"pickle": lambda env: pickle.loads(pickle.dumps(env)), "deepcopy": copy.deepcopy}


def same(a, b) -> bool:
    """Equal nested results (dicts, tuples, arrays, numbers), arrays compared exactly."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return np.array_equal(a, b)


@pytest.mark.parametrize("how", COPIES)
def test_a_copied_simulator_goes_on_as_the_original(how):
    sim = Simulator(EnvConfig(max_cycles=12), num_envs=3, nthread=2)
    sim.reset(seeds=[5, 6, 7])
    rng = np.random.default_rng(0)
    for _ in range(5):  # mid-episode, with views drawn
        sim.move(rng.integers(3, size=3))
        sim.look(rng.integers(3, size=3))
        sim.render()
    twin = COPIES[how](sim)
    for _ in range(40):  # past the ends of episodes: finished rooms draw new layouts from their streams
        moves, looks = rng.integers(3, size=3), rng.integers(3, size=3)
        steps = []
        for s in (sim, twin):
            finished = np.flatnonzero(s.done)
            if finished.size:
                s.reset(finished)
            result = s.move(moves)
            s_bar = s.render()
            s.look(looks)
            steps.append((vars(result), s_bar, s.render(), s.state(), s.cycle.copy()))
        assert same(*steps)
    assert same(sim.render_map(1), twin.render_map(1))
    sim.close()
    twin.close()


def play_parallel(env, actions):
    return [env.step(a) if env.agents else env.reset() for a in actions]


@pytest.mark.parametrize("how", COPIES)
def test_a_copied_parallel_env_goes_on_as_the_original(how):
    env = activeperc_env.parallel_env(render_mode="rgb_array", max_cycles=15)
    env.reset(seed=3)
    rng = np.random.default_rng(1)
    actions = [{"mover_0": int(m), "looker_0": int(c)} for m, c in rng.integers(3, size=(40, 2))]
    play_parallel(env, actions[:6])
    twin = COPIES[how](env)
    assert same(env.render(), twin.render()) and same(env.state(), twin.state())
    assert same(play_parallel(env, actions[6:]), play_parallel(twin, actions[6:]))


@pytest.mark.parametrize("how", COPIES)
def test_a_copied_aec_env_goes_on_as_the_original(how):
    env = activeperc_env.env(max_cycles=15)
    env.reset(seed=4)
    rng = np.random.default_rng(2)
    for _ in range(7):  # the looker's turn is next
        env.step(int(rng.integers(3)))
    twin = COPIES[how](env)
    for _ in range(30):
        action = int(rng.integers(3))
        lasts = []
        for e in (env, twin):
            if not e.agents:
                e.reset()
            lasts.append((e.agent_selection, e.last()))
            observation, _, terminated, truncated, _ = e.last()
            e.step(None if terminated or truncated else action)
        assert same(*lasts)


@pytest.mark.parametrize("how", COPIES)
def test_a_copied_gymnasium_env_goes_on_as_the_original(how):
    env = gymnasium.make("activeperc/Joint-v1", max_cycles=15)
    vec = gymnasium.make_vec("activeperc/Joint-v1", num_envs=3, max_cycles=15)
    env.reset(seed=0)
    vec.reset(seed=0)
    rng = np.random.default_rng(3)
    for _ in range(4):
        env.step(int(rng.integers(9)))
        vec.step(rng.integers(9, size=3))
    env_twin, vec_twin = COPIES[how](env), COPIES[how](vec)
    for _ in range(30):
        action, actions = int(rng.integers(9)), rng.integers(9, size=3)
        one = [e.step(action) for e in (env, env_twin)]
        many = [v.step(actions) for v in (vec, vec_twin)]
        assert same(*one) and same(*many)
        if one[0][2] or one[0][3]:
            assert same(env.reset(), env_twin.reset())


@pytest.mark.extras
def test_a_copied_torchrl_env_goes_on_as_the_original():
    import torch
    from torchrl.envs.utils import step_mdp

    from activeperc_rl.envs import LOOKER, MOVER, make_env
    from activeperc_rl.models import RandomPolicy

    env = make_env(num_envs=2, seed=7, max_cycles=10)
    torch.manual_seed(0)
    start = env.rollout(6, RandomPolicy((MOVER, LOOKER)), break_when_any_done=False)
    now = step_mdp(start[:, -1])  # the rooms go on from here, mid-episode: no reset
    twin = pickle.loads(pickle.dumps(env))
    assert same(twin.rooms_state(), env.rooms_state())
    rollouts = []
    for e in (env, twin):
        torch.manual_seed(1)
        policy = RandomPolicy((MOVER, LOOKER))
        rollouts.append(e.rollout(25, policy, auto_reset=False, tensordict=now.clone(), break_when_any_done=False))
    assert (rollouts[0] == rollouts[1]).all()
    assert not rollouts[0]["next", "done"][:, 0].any()  # the first steps continue the copied episodes
    assert rollouts[0]["next", "done"].any()  # and episodes ended and restarted within the rollout
    env.close()
    twin.close()


def test_a_copied_viewer_opens_a_window_of_its_own():
    viewer = HumanViewer()
    viewer._handle, viewer._headless = object(), ""  # as if its window were open
    twin = copy.deepcopy(viewer)
    assert twin._handle is None and twin._headless is None


def test_a_state_of_other_rooms_is_refused():
    two, three = Simulator(num_envs=2, nthread=1), Simulator(num_envs=3, nthread=1)
    with pytest.raises(ValueError, match="does not fit this simulator"):
        three.set_state(two.get_state())


def test_a_state_of_another_config_is_refused():
    empty, default = Simulator(EnvConfig(num_obstacles=0), nthread=1), Simulator(nthread=1)
    with pytest.raises(ValueError, match=r"another config \(differs in \['num_obstacles'\]\)"):
        default.set_state(empty.get_state())


def test_a_state_that_is_not_get_states_is_named():
    sim = Simulator(nthread=1)
    state = sim.get_state()
    del state["rngs"], state["done"]
    for bad, missing in (({}, "['config', 'physics', 'cycle', 'done', 'rngs']"), (state, "['done', 'rngs']")):
        with pytest.raises(ValueError, match=re.escape(f"a state without {missing} is not one of get_state()'s")):
            sim.set_state(bad)
