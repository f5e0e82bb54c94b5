"""Other RL libraries on our envs: Tianshou's multi-agent DQN on the AEC env, as docs/env.md shows it."""

import numpy as np
import pytest
import torch
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

# an empty room where the goal lies straight ahead, two forward moves away: random moves reach it often
EASY_ROOM = dict(
    num_obstacles=0, goal_distance=2.5, heading_spread=0.0, forward_speed=3.0, control_hz=2.5, max_cycles=10
)


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
