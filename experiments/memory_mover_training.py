"""Does a mover with memory gain from a looker that looks? The A2C mover with a GRU, a scripted looker in the loop.

Run from the repository root::

    python experiments/memory_mover_training.py --looker fixed --version 2 --frames 300000
    python experiments/memory_mover_training.py --looker scan --version 2 --frames 300000

``scripted_looker_training.py`` found that a learned mover without memory gains nothing from a scripted looker that
sweeps or tracks, while the scripted vision mover, which remembers where it last saw the goal, does. This trains the
same A2C mover (``fixed_forward``'s networks and hyperparameters) with a GRU between its encoder and its heads
(TorchRL's ``GRUModule``; the env gets ``InitTracker`` and the GRU's state primer), with a scripted looker of
:data:`activeperc_env.scripted.LOOKERS` inside each cycle (``fixed``: the camera held forward), and prints one JSON
line: the held-out success with the same looker. A probe, not a method: one process, no checkpoints.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import torch
from scripted_looker_training import ScriptedLooker, probe_arguments, probe_config
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.envs import Compose, InitTracker, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import GRUModule, ProbabilisticActor, set_recurrent_mode
from torchrl.objectives import A2CLoss, ValueEstimators

from activeperc_env.arguments import whole_number
from activeperc_rl.envs import MOVER, make_env
from activeperc_rl.models import NUM_ACTIONS, make_encoder, observation_keys
from activeperc_rl.recipe import TrainConfig

MEMORY = (MOVER, "memory")


def memory_actor_critic(config: TrainConfig, memory_size: int):
    """The mover's actor and critic: one encoder and one GRU shared, a linear head each; and the GRU."""
    encoder = make_encoder(config.env, config.network.channels, config.network.hidden_size, config.network.bearing_bins)
    embed = TensorDictModule(encoder, in_keys=observation_keys(MOVER, encoder), out_keys=[(MOVER, "embed")])
    gru = GRUModule(
        input_size=config.network.hidden_size,
        hidden_size=memory_size,
        in_keys=[(MOVER, "embed"), (MOVER, "recurrent_state"), "is_init"],
        out_keys=[MEMORY, ("next", MOVER, "recurrent_state")],
    )
    logits = TensorDictModule(nn.Linear(memory_size, NUM_ACTIONS), in_keys=[MEMORY], out_keys=[(MOVER, "logits")])
    actor = ProbabilisticActor(
        TensorDictSequential(embed, gru, logits),
        in_keys={"logits": (MOVER, "logits")},
        out_keys=[(MOVER, "action")],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
        log_prob_key=(MOVER, "action_log_prob"),
    )
    value = TensorDictModule(nn.Linear(memory_size, 1), in_keys=[MEMORY], out_keys=["state_value"])
    return actor, TensorDictSequential(embed, gru, value), gru


def memory_env(config: TrainConfig, looker_name: str, gru: GRUModule, rooms: int, split: str):
    """The batched env with the scripted looker inside each cycle, the init flags and the GRU's state."""
    looker = ScriptedLooker(looker_name, config.env, rooms, config.run.seed)
    env = make_env(rooms, looker=looker, seed=config.run.seed, split=split, config=config.env)
    return TransformedEnv(env, Compose(InitTracker(), gru.make_tensordict_primer()))


def outcomes(rollout) -> tuple[list[bool], int]:
    """The successes of the episodes that ended in ``rollout``, and how many ended."""
    done = rollout.get(("next", "done")).reshape(-1)
    success = rollout.get(("next", MOVER, "episode_success")).reshape(-1)
    return success[done].tolist(), int(done.sum())


def train(config: TrainConfig, looker_name: str, memory_size: int):
    """A2C of the memory mover for ``config.run.frames`` frames, printing its training success every 50,000 frames;
    returns the actor and its GRU."""
    actor, critic, gru = memory_actor_critic(config, memory_size)
    loss = A2CLoss(
        actor,
        critic,
        entropy_coeff=config.a2c.entropy_coeff,
        critic_coeff=config.a2c.critic_coeff,
        loss_critic_type="l2",
        functional=False,
    )
    loss.set_keys(
        reward=(MOVER, "reward"),
        action=(MOVER, "action"),
        sample_log_prob=(MOVER, "action_log_prob"),
        value="state_value",
    )
    loss.make_value_estimator(
        ValueEstimators.GAE, gamma=config.a2c.gamma, lmbda=config.a2c.gae_lambda, deactivate_vmap=True
    )
    params = list(dict.fromkeys([*actor.parameters(), *critic.parameters()]))
    optimizer = torch.optim.Adam(params, lr=config.a2c.lr, eps=1e-5)
    env = memory_env(config, looker_name, gru, config.run.num_envs, "train")
    batch = config.run.num_envs * config.run.rollout_length
    collector = Collector(env, actor, frames_per_batch=batch, total_frames=-1)
    window: list[bool] = []
    frames = 0
    try:
        for rollout in collector:
            rollout = rollout.reshape(config.run.num_envs, config.run.rollout_length)
            with set_recurrent_mode(True):
                with torch.no_grad():
                    loss.value_estimator(rollout)
                losses = loss(rollout)
                total = losses["loss_objective"] + losses["loss_critic"] + losses["loss_entropy"]
                optimizer.zero_grad(set_to_none=True)
                total.backward()
                torch.nn.utils.clip_grad_norm_(params, config.a2c.max_grad_norm)
                optimizer.step()
            collector.update_policy_weights_()
            window = (window + outcomes(rollout)[0])[-config.run.success_window :]
            frames += rollout.numel()
            if frames // 50_000 != (frames - rollout.numel()) // 50_000:
                print(json.dumps({"frames": frames, "train_success": float(np.mean(window or [0]))}), flush=True)
            if frames >= config.run.frames:
                break
    finally:
        collector.shutdown()
    return actor, gru


def held_out(config: TrainConfig, looker_name: str, actor, gru: GRUModule, episodes: int) -> float:
    """Held-out success of the mover with the scripted looker, its actions sampled as ``activeperc-eval`` does."""
    rooms = min(episodes, 16)
    env = memory_env(config, looker_name, gru, rooms, "eval")
    successes: list[bool] = []
    try:
        with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM), torch.random.fork_rng():
            torch.manual_seed(0)
            td = env.reset()
            while len(successes) < episodes:
                td = actor(td)
                td, following = env.step_and_maybe_reset(td)
                done = td.get(("next", "done")).reshape(-1)
                successes += td.get(("next", MOVER, "episode_success")).reshape(-1)[done].tolist()
                td = following
    finally:
        env.close()
    return float(np.mean(successes[:episodes]))


def main(argv: list[str] | None = None) -> int:
    """Train, evaluate, print one JSON line."""
    parser = probe_arguments("memory_mover_training.py", __doc__.split("\n\n")[0], "scan")
    parser.add_argument("--memory", type=whole_number, default=128, help="the GRU's hidden size (128)")
    args = parser.parse_args(argv)
    if args.frames < 1 or args.episodes < 1 or args.memory < 1:
        parser.error("--frames, --episodes and --memory must be >= 1")
    config = probe_config(args)
    torch.manual_seed(config.run.seed)
    torch.set_num_threads(config.run.torch_threads)
    start = time.perf_counter()
    actor, gru = train(config, args.looker, args.memory)
    success = held_out(config, args.looker, actor, gru, args.episodes)
    run = {"looker": args.looker, "version": args.version, "bearing_bins": args.bearing_bins, "memory": args.memory}
    minutes = round((time.perf_counter() - start) / 60, 1)
    print(json.dumps(run | {"frames": args.frames, "seed": args.seed, "success": success, "minutes": minutes}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
