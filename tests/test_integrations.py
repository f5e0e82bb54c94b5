"""Other RL libraries on our envs, as docs/env.md shows them: Tianshou's multi-agent DQN on the AEC env,
Stable-Baselines3's PPO through SuperSuit and RLlib's PPO on the image-only parallel env."""

import numpy as np
import pytest
import ray
import supersuit as ss
import torch
from conftest import EASY_ROOM
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.tune.registry import register_env
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from tianshou.algorithm import DQN, MultiAgentOffPolicyAlgorithm
from tianshou.algorithm.modelfree.dqn import DiscreteQLearningPolicy
from tianshou.algorithm.optim import AdamOptimizerFactory
from tianshou.data import Collector, VectorReplayBuffer
from tianshou.env import DummyVectorEnv
from tianshou.env.pettingzoo_env import PettingZooEnv
from tianshou.trainer import OffPolicyTrainerParams
from tianshou.utils.net.common import Net

import activeperc_env
from activeperc_env import LOOKER, MOVER


class FlatNet(Net):
    """Tianshou's MLP over the observation as one flat vector: image / 255, pan, range."""

    def forward(self, obs, state=None, info=None):
        image = np.asarray(obs.image, dtype=np.float32).reshape(len(obs.image), -1) / 255
        return super().forward(np.concatenate([image, obs.pan, obs.range], axis=1), state, info)


def train_with_tianshou(looker_reward: str) -> VectorReplayBuffer:
    """The docs' example (same calls) in EASY_ROOM, acting at random (eps 1); returns the collector's buffer."""

    def make_env():
        return PettingZooEnv(activeperc_env.env(looker_reward=looker_reward, **EASY_ROOM))

    env = make_env()
    inputs = sum(int(np.prod(space.shape)) for space in env.observation_space.values())
    dqns = [
        DQN(
            policy=DiscreteQLearningPolicy(
                model=FlatNet(state_shape=inputs, action_shape=3, hidden_sizes=[64]),
                action_space=env.action_space,
                eps_training=1.0,
            ),
            optim=AdamOptimizerFactory(lr=1e-3),
            target_update_freq=100,
        )
        for _ in env.agents
    ]
    algorithm = MultiAgentOffPolicyAlgorithm(algorithms=dqns, env=env)
    envs = DummyVectorEnv([make_env] * 2)
    envs.seed(0)
    collector = Collector(algorithm, envs, VectorReplayBuffer(10_000, len(envs)), exploration_noise=True)
    algorithm.run_training(
        OffPolicyTrainerParams(
            training_collector=collector,
            max_epochs=1,
            epoch_num_steps=400,
            collection_step_num_env_steps=20,
            update_step_num_gradient_steps_per_sample=0.1,
            batch_size=32,
            multi_agent_return_reduction=lambda returns: returns[:, 0],
            show_progress=False,
        )
    )
    return collector.buffer


def own_step_totals(buffer: VectorReplayBuffer) -> dict[str, float]:
    """Each agent's total reward over its own transitions (as MultiAgentOffPolicyAlgorithm hands them to that agent's
    DQN: its column of ``rew``) in each env's finished episodes."""
    agent_idx = {MOVER: 0, LOOKER: 1}  # PettingZooEnv's agent_idx: the order of possible_agents
    totals = dict.fromkeys(agent_idx, 0.0)
    for sub in buffer.buffers:
        batch = sub[np.arange(len(sub))]  # in time order: 10_000 steps never wrap around
        assert list(batch.obs.agent_id[:4]) == [MOVER, LOOKER, MOVER, LOOKER]
        finished = np.flatnonzero(batch.done)[-1] + 1  # the steps of finished episodes
        for agent, column in agent_idx.items():
            own = batch.obs.agent_id[:finished] == agent
            totals[agent] += float(batch.rew[:finished][own, column].sum())
    return totals


@pytest.mark.parametrize("looker_reward", ["own_turn", "shared"])
def test_tianshou_credits_the_looker_only_with_own_turn(looker_reward):
    np.random.seed(0)
    torch.manual_seed(0)
    totals = own_step_totals(train_with_tianshou(looker_reward))
    assert totals[MOVER] > 1.0, "random moves in the easy room should reach the goal in several episodes"
    if looker_reward == "own_turn":
        assert totals[LOOKER] == pytest.approx(totals[MOVER])
    else:  # the pitfall: the shared reward comes with the mover's step, and Tianshou credits it to the mover alone
        assert totals[LOOKER] == 0.0


def test_supersuits_box_only_wrappers_take_the_image_only_env():
    ss.black_death_v3(activeperc_env.image_only(activeperc_env.parallel_env(max_cycles=20)))
    ss.agent_indicator_v0(activeperc_env.image_only(activeperc_env.env(max_cycles=20)))


class RewardTotals(BaseCallback):
    """The rewards of each slot of the vectorised env, summed over the steps SB3 collected."""

    def __init__(self):
        super().__init__()
        self.totals = 0.0

    def _on_step(self) -> bool:
        self.totals = self.totals + self.locals["rewards"]
        return True


def test_stable_baselines3_with_supersuit_gives_both_agents_the_reward():
    """docs/env.md's example in EASY_ROOM: SB3's PPO steps one policy for both agents, and each agent's slot of the
    vectorised env receives every reward of its room."""
    room = activeperc_env.parallel_env(**EASY_ROOM)
    room.reset(seed=0)  # the copies' unseeded resets continue this stream: the same layouts in every run
    env = ss.agent_indicator_v0(activeperc_env.image_only(room))
    env = ss.pettingzoo_env_to_vec_env_v1(env)
    env = ss.concat_vec_envs_v1(env, 2, num_cpus=0, base_class="stable_baselines3")
    assert env.num_envs == 4 and env.observation_space.shape == (60, 80, 5)
    torch.manual_seed(0)
    model = PPO("CnnPolicy", env, n_steps=64, batch_size=64, n_epochs=1)
    totals = RewardTotals()
    model.learn(total_timesteps=256, callback=totals)
    mover, looker = totals.totals[0::2], totals.totals[1::2]  # slots alternate mover_0, looker_0 in each room
    assert mover.sum() > 1.0, "moves in the easy room should reach the goal in several episodes"
    assert np.allclose(mover, looker)


def test_rllib_trains_a_module_per_agent_and_both_receive_the_reward():
    """docs/env.md's RLlib example in EASY_ROOM: one PPO iteration on the float images, and the looker's episodes
    return what the mover's do."""
    register_env(
        "activeperc_easy",
        lambda options: ParallelPettingZooEnv(activeperc_env.image_only(activeperc_env.parallel_env(**options), True)),
    )
    config = (
        PPOConfig()
        .environment("activeperc_easy", env_config=EASY_ROOM)
        .multi_agent(policies={MOVER, LOOKER}, policy_mapping_fn=lambda agent_id, episode, **kwargs: agent_id)
        .rl_module(model_config=DefaultModelConfig(conv_filters=[[16, [8, 8], 4], [32, [4, 4], 2], [64, [4, 4], 2]]))
        .env_runners(num_env_runners=0)
        .training(train_batch_size_per_learner=256, minibatch_size=64, num_epochs=1)
        .debugging(seed=0)
    )
    ray.shutdown()  # an instance another test left running would refuse this one's settings
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        algo = config.build_algo()
        returns = algo.train()["env_runners"]["agent_episode_returns_mean"]
        algo.stop()
    finally:
        ray.shutdown()
    assert returns[MOVER] > 0.1, "moves in the easy room should reach the goal in several episodes"
    assert returns[LOOKER] == pytest.approx(returns[MOVER])
