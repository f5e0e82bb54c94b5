"""Which look an untrained looker's argmax picks, over views of random play: why lookers start by holding.

For each seed, a looker actor is built with PyTorch's default initialisation (``--hold-prob 0``, the
default) or with :func:`activeperc_rl.models.start_holding`, and its argmax is taken on the looker's
views of ``--rooms`` rooms played for ``--cycles`` cycles by a uniformly random mover and looker. It
prints how many views pick each look. E2 in the meta method looks by this argmax (with probability
``1 - epsilon``), so a look that wins in nearly every view pins E2's camera at a pan limit.

    python experiments/untrained_looker.py [--seeds 5] [--rooms 16] [--cycles 20] [--hold-prob P]
"""

from __future__ import annotations

import argparse

import torch

from activeperc_rl.envs import LOOKER, MOVER, make_env
from activeperc_rl.models import RandomPolicy, make_actor, make_encoder, start_holding
from activeperc_rl.recipe import TrainConfig

LOOKS = ("pan left", "hold", "pan right")


def main() -> None:
    """Print, for each seed, how many views of random play pick each look."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--rooms", type=int, default=16)
    parser.add_argument("--cycles", type=int, default=20)
    parser.add_argument("--hold-prob", type=float, default=0.0, help="0: PyTorch's default init")
    args = parser.parse_args()
    for flag, value in (("--seeds", args.seeds), ("--rooms", args.rooms), ("--cycles", args.cycles)):
        if value < 1:
            parser.error(f"{flag} must be >= 1, got {value}")
    if not 0.0 <= args.hold_prob < 1.0:
        parser.error(f"--hold-prob must be in [0, 1), got {args.hold_prob}")

    config = TrainConfig.from_options(version=1)  # the room the untrained looker was measured in (docs/training.md)
    network = config.network
    torch.manual_seed(0)  # the random play
    env = make_env(args.rooms, seed=0, looker=RandomPolicy((LOOKER,)))
    views = env.rollout(args.cycles, RandomPolicy((MOVER,)), break_when_any_done=False)
    env.close()
    views = views.select((LOOKER, "observation")).reshape(-1)
    print(f"argmax of an untrained looker over {views.numel()} views ({', '.join(LOOKS)}):")
    for seed in range(args.seeds):
        torch.manual_seed(seed)
        actor = make_actor(make_encoder(config.env, network.channels, network.hidden_size), network.hidden_size, LOOKER)
        if args.hold_prob:
            start_holding(actor, args.hold_prob)
        with torch.no_grad():
            greedy = actor[0](views.clone()).get((LOOKER, "logits")).argmax(-1)
        print(f"  seed {seed}: {torch.bincount(greedy, minlength=len(LOOKS)).tolist()}")


if __name__ == "__main__":
    main()
