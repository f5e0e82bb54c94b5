"""BenchMARL's IPPO on our parallel env, as docs/env.md shows it. BenchMARL needs torchrl<0.12, so this file runs in a
virtual environment of its own with the env alone (.ci/run's BenchMARL step); elsewhere it is skipped."""

import pytest

pytest.importorskip("benchmarl", reason="BenchMARL runs in a venv of its own: .ci/run's BenchMARL step")

from benchmarl.algorithms import IppoConfig  # noqa: E402
from benchmarl.environments.pettingzoo.common import PettingZooClass  # noqa: E402
from benchmarl.experiment import Experiment, ExperimentConfig  # noqa: E402
from benchmarl.experiment.callback import Callback  # noqa: E402
from benchmarl.models import CnnConfig  # noqa: E402
from conftest import EASY_ROOM  # noqa: E402
from torchrl.envs import PettingZooWrapper  # noqa: E402

import activeperc_env  # noqa: E402


class ActivePercTask(PettingZooClass):
    """docs/env.md's task: the room's parallel env through TorchRL's wrapper, the mover and the looker each a group."""

    def get_env_fun(self, num_envs, continuous_actions, seed, device):
        return lambda: PettingZooWrapper(
            activeperc_env.parallel_env(render_mode="rgb_array", **self.config),
            categorical_actions=True,
            seed=seed,
            device=device,
        )

    def supports_discrete_actions(self):
        return True

    def max_steps(self, env):
        return activeperc_env.EnvConfig(**self.config).max_cycles


class RewardTotals(Callback):
    """Each group's rewards summed over the batches BenchMARL collected to learn from."""

    def __init__(self):
        super().__init__()
        self.totals = {}

    def on_batch_collected(self, batch):
        for group in self.experiment.group_map:
            self.totals[group] = self.totals.get(group, 0.0) + float(batch["next", group, "reward"].sum())


def test_benchmarl_trains_both_agents_and_both_receive_the_reward(tmp_path):
    """docs/env.md's example in EASY_ROOM, two IPPO iterations of 200 frames: the mover and the looker are groups of
    their own, and the looker's batches carry every reward the mover's do."""
    config = ExperimentConfig.get_from_yaml()
    config.max_n_frames = 400
    config.on_policy_collected_frames_per_batch = 200
    config.on_policy_n_envs_per_worker = 2
    config.on_policy_minibatch_size = 50
    config.on_policy_n_minibatch_iters = 1
    config.evaluation = False
    config.loggers = []
    config.checkpoint_interval = 0
    config.create_json = False
    config.save_folder = str(tmp_path)
    model = CnnConfig.get_from_yaml()
    model.cnn_num_cells, model.cnn_kernel_sizes, model.cnn_strides, model.mlp_num_cells = [16, 32], [8, 4], [4, 2], [64]
    totals = RewardTotals()
    experiment = Experiment(
        task=ActivePercTask(name="room", config=EASY_ROOM),
        algorithm_config=IppoConfig.get_from_yaml(),
        model_config=model,
        critic_model_config=model,
        seed=0,
        config=config,
        callbacks=[totals],
    )
    assert experiment.group_map == {"mover": [activeperc_env.MOVER], "looker": [activeperc_env.LOOKER]}
    experiment.run()
    assert totals.totals["mover"] > 1.0, "moves in the easy room should reach the goal in several episodes"
    assert totals.totals["looker"] == pytest.approx(totals.totals["mover"])
