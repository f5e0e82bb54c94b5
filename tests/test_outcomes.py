"""A dense reward: nothing downstream assumes that the room pays only on success.

The core's reward gets a shaping term every cycle, so that "success = return > 0" and "return = last reward" are
both wrong; the PettingZoo, Gymnasium and TorchRL envs, evaluation and training must report the core's success and
the sum of the rewards.
"""

import csv
import json
from collections import defaultdict

import gymnasium
import numpy as np
import pytest
import torch

import activeperc_env.core
from activeperc_env import LOOKER, MOVER, EnvConfig, Simulator
from activeperc_rl.envs import make_env
from activeperc_rl.evaluate import evaluate
from activeperc_rl.methods import finished_episodes
from activeperc_rl.recipe import TrainConfig, make_method
from activeperc_rl.train import train

SHAPING = 0.01  # paid every cycle, on top of the room's own reward
ROOM = EnvConfig(num_obstacles=0, goal_distance=2.5, max_cycles=12)
TINY = dict(num_envs=4, rollout_length=12, channels=(8,), hidden_size=32, env=ROOM)


@pytest.fixture
def ended(monkeypatch) -> dict:
    """A dense room (:data:`SHAPING` each cycle; the goal counts as reached from 2.5 m, so that random movers reach
    it about half the time). Returns the episodes the core ends, per simulator in the order they first moved:
    ``(room, the sum of its rewards, whether it reached the goal)``."""
    reward, move = Simulator._reward, Simulator.move
    episodes, running = {}, defaultdict(float)

    def dense(self, success, cycles):
        return reward(self, success, cycles) + SHAPING

    def recording(self, actions, ids=None):
        result = move(self, actions, ids)
        rooms = range(self.num_envs) if ids is None else ids
        ends = zip(rooms, result.reward, result.terminated, result.truncated, strict=True)
        for room, paid, terminated, truncated in ends:
            running[self, int(room)] += paid
            if terminated or truncated:  # terminated: the robot reached the goal
                summed = running.pop((self, int(room)))
                episodes.setdefault(self, []).append((int(room), summed, bool(terminated)))
        return result

    monkeypatch.setattr(activeperc_env.core, "SUCCESS_DISTANCE", 2.5)
    monkeypatch.setattr(Simulator, "_reward", dense)
    monkeypatch.setattr(Simulator, "move", recording)
    return episodes


def outcomes(episodes) -> list[tuple[float, bool]]:
    """``(return as float32, success)`` of ``episodes``, sorted: the same episodes in any order give the same list."""
    return sorted((float(np.float32(summed)), success) for _, summed, success in episodes)


def assert_mixed(episodes) -> None:
    """Some of ``episodes`` reached the goal and some did not, and every return is above 0."""
    successes = [success for *_, success in episodes]
    assert any(successes) and not all(successes)
    assert all(summed > 0 for _, summed, _ in episodes)  # "return > 0" would call every one a success


def test_the_pettingzoo_and_gymnasium_infos_report_the_cores_outcomes(ended):
    parallel = activeperc_env.parallel_env(**vars(ROOM))
    joint = gymnasium.make("activeperc/Joint-v1", **vars(ROOM))
    rng = np.random.default_rng(0)
    for seed in range(8):
        parallel.reset(seed=seed)
        summed = 0.0
        while parallel.agents:
            actions = {MOVER: int(rng.integers(3)), LOOKER: int(rng.integers(3))}
            _, rewards, terminations, _, infos = parallel.step(actions)
            summed += rewards[MOVER]
        assert infos[MOVER] == infos[LOOKER] == {"episode_success": terminations[MOVER], "episode_return": summed}
        joint.reset(seed=seed)
        summed, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, info = joint.step(int(rng.integers(9)))
            summed, done = summed + reward, terminated or truncated
        assert (info["episode_success"], info["episode_return"]) == (terminated, summed)
    parallel.close()
    joint.close()
    assert_mixed([episode for episodes in ended.values() for episode in episodes])


def test_the_torchrl_env_reports_the_cores_outcomes(ended):
    env = make_env(4, seed=0, nthread=1, config=ROOM)
    generator = torch.Generator().manual_seed(0)

    def policy(td):
        td.set(("mover", "action"), torch.randint(3, (4,), generator=generator))
        return td.set(("looker", "action"), torch.randint(3, (4,), generator=generator))

    rollout = env.rollout(40, policy, break_when_any_done=False)
    env.close()
    returns, successes = finished_episodes(rollout)
    assert_mixed(ended[env.sim])
    assert sorted(zip(returns, successes, strict=True)) == outcomes(ended[env.sim])


def test_evaluation_reports_the_cores_outcomes(ended):
    result = evaluate(TrainConfig.from_options(env=ROOM), episodes=8, seed=0)
    (sim,) = ended
    first = [next(episode for episode in ended[sim] if episode[0] == room) for room in range(8)]  # each room's quota
    assert_mixed(first)
    assert result["success_rate"] == np.mean([success for *_, success in first])
    assert result["mean_return"] == pytest.approx(np.mean([summed for _, summed, _ in first]), rel=1e-6)


def test_training_logs_and_eval_json_report_the_cores_outcomes(ended, tmp_path):
    config = TrainConfig.from_options(method="fixed_forward", frames=300, eval_episodes=4, success_window=1000, **TINY)
    train(config, tmp_path / "run", progress=False)
    with open(tmp_path / "run" / "metrics.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    training, learned, random = ended.values()
    assert_mixed(training)
    assert sum(int(row["episodes"]) for row in rows) == len(training)
    logged = rows[-1]  # its window holds every training episode
    assert float(logged["success_rate"]) == pytest.approx(np.mean([won for *_, won in training]), abs=1e-4)
    assert float(logged["mean_return"]) == pytest.approx(np.mean([summed for _, summed, _ in training]), abs=1e-4)
    evaluated = json.loads((tmp_path / "run" / "eval.json").read_text())
    for name, episodes in (("learned", learned), ("random", random)):
        first = [next(episode for episode in episodes if episode[0] == room) for room in range(4)]
        assert evaluated[name]["success_rate"] == np.mean([won for *_, won in first])
        assert evaluated[name]["mean_return"] == pytest.approx(np.mean([summed for _, summed, _ in first]), rel=1e-6)


def test_the_meta_iterations_outcomes_and_e2_success_rate_are_the_cores(ended):
    method = make_method(TrainConfig.from_options(method="meta", **TINY), torch.device("cpu"))
    try:
        step = method.iterate()
        e1, e2 = ended[method.e1.env.sim], ended[method.e2.env.sim]
    finally:
        method.close()
    assert_mixed(e1 + e2)
    assert sorted(zip(step.returns, step.successes, strict=True)) == outcomes(e1)  # both D1 rollouts
    assert step.losses["meta/e2_success_rate"] == pytest.approx(np.mean([won for *_, won in e2]))
