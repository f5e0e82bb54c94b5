"""AgileRL's IPPO on our parallel env, as docs/env.md shows it. AgileRL pins tensordict==0.13.0 (the train extra
needs 0.14), so this file runs in a virtual environment of its own with the env alone (.ci/run's AgileRL step);
elsewhere it is skipped."""

import pytest

pytest.importorskip("agilerl", reason="AgileRL runs in a venv of its own: .ci/run's AgileRL step")

import gymnasium  # noqa: E402
import numpy as np  # noqa: E402
import supersuit as ss  # noqa: E402
import torch  # noqa: E402
from agilerl.algorithms import IPPO  # noqa: E402
from agilerl.training.train_multi_agent_on_policy import train_multi_agent_on_policy  # noqa: E402
from agilerl.vector.pz_async_vec_env import AsyncPettingZooVecEnv  # noqa: E402
from conftest import EASY_ROOM  # noqa: E402

import activeperc_env  # noqa: E402

NET_CONFIG = {
    "encoder_config": {"channel_size": [16, 32], "kernel_size": [8, 4], "stride_size": [4, 2]},
    "head_config": {"hidden_size": [64]},
}


def channels_first(env):
    """docs/env.md's wrapper: each agent's image alone, channels first (AgileRL 2.58's IPPO update raises on
    channels-last images: it scales the last observation, still channels last, by the space's bounds turned channels
    first)."""
    return ss.observation_lambda_v0(
        activeperc_env.image_only(env),
        lambda image, space: image.transpose(2, 0, 1),
        lambda space: gymnasium.spaces.Box(0, 255, (space.shape[2], *space.shape[:2]), np.uint8),
    )


def easy_room():
    """EASY_ROOM's parallel env as the AgileRL example wraps it."""
    return channels_first(activeperc_env.parallel_env(**EASY_ROOM))


class RecordingIPPO(IPPO):
    """IPPO that also sums the rewards of each agent in the rollouts handed to its update."""

    def learn(self, experiences):
        for agent_id, rewards in experiences[3].items():
            self.reward_totals[agent_id] = self.reward_totals.get(agent_id, 0.0) + float(np.nansum(rewards))
        return super().learn(experiences)


def test_agilerl_trains_both_agents_and_both_receive_the_reward():
    """docs/env.md's example in EASY_ROOM for 512 steps: IPPO updates a mover and a looker of their own, and the
    looker's rollouts carry every reward the mover's do."""
    env = AsyncPettingZooVecEnv([easy_room] * 2)
    env.reset(seed=0)
    torch.manual_seed(0)
    agent = RecordingIPPO(
        observation_spaces=[env.single_observation_space(agent_id) for agent_id in env.agents],
        action_spaces=[env.single_action_space(agent_id) for agent_id in env.agents],
        agent_ids=env.agents,
        net_config=NET_CONFIG,
        learn_step=128,
        batch_size=64,
        update_epochs=1,
    )
    agent.reward_totals = {}
    try:
        train_multi_agent_on_policy(env, "activeperc", "IPPO", [agent], max_steps=512, evo_steps=512, verbose=False)
    finally:
        env.close()
    assert sorted(agent.actors) == sorted([activeperc_env.MOVER, activeperc_env.LOOKER])
    mover, looker = agent.reward_totals[activeperc_env.MOVER], agent.reward_totals[activeperc_env.LOOKER]
    assert mover > 1.0, "moves in the easy room should reach the goal in several episodes"
    assert looker == pytest.approx(mover)
