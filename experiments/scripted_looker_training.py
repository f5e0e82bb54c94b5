"""Does a learned mover gain from a looker that looks? The mover trained by A2C with a scripted looker in the loop.

Run from the repository root::

    python experiments/scripted_looker_training.py --looker track --frames 300000 --seed 0
    python experiments/scripted_looker_training.py --looker fixed --frames 300000 --seed 0   # Fixed_Forward
    python experiments/scripted_looker_training.py --looker scan --version 2 --bearing-bins 30
    python experiments/scripted_looker_training.py --looker scan --bearing-bins 30 --recipe default --frames 400000

The mover is ``fixed_forward``'s (the TrainConfig defaults, A2C on the default room), but its environment runs a
scripted looker of :data:`activeperc_env.scripted.LOOKERS` inside each cycle (``fixed``: the camera held forward,
which is the Fixed_Forward baseline). After ``--frames`` frames the mover is evaluated with the same looker on
``--episodes`` held-out layouts (as ``activeperc-eval`` does) and one JSON line is printed. A gain over ``fixed`` is
what a learned looker could add for this mover; scripted policies alone (``value_of_looking.py``) say what looking
is worth to a mover that reads the goal's bearing off the image by design. ``--version`` picks the room and
``--bearing-bins`` the mover's bearing layout (``TrainConfig.bearing_bins``).
"""

from __future__ import annotations

import json
import sys
import time

import torch
from torch import nn

from activeperc_env import EnvConfig, scripted
from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_env.rooms import ROOMS
from activeperc_rl.evaluate import MAX_ROOMS, evaluate
from activeperc_rl.methods import FixedForward
from activeperc_rl.recipe import TrainConfig, make_method


class ScriptedLooker(nn.Module):
    """A scripted looker as the TorchRL env's looker module: reads ``("looker", "observation")`` and writes
    ``("looker", "action")``."""

    def __init__(self, name: str, config, num_envs: int, seed: int = 0):
        super().__init__()
        self.policy = scripted.LOOKERS[name](config, num_envs, seed)

    def forward(self, tensordict):
        """Write the scripted looks of every room into ``tensordict``."""
        views = {key: tensordict.get(("looker", "observation", key)).cpu().numpy() for key in ("image", "pan")}
        action = torch.as_tensor(self.policy.act(views), dtype=torch.int64, device=tensordict.device)
        tensordict.set(("looker", "action"), action)
        return tensordict


class MoverWithScriptedLooker(FixedForward):
    """``fixed_forward``'s mover and A2C, with a scripted looker in the loop."""

    looker_name = "track"

    def start(self) -> None:
        """Build the environment, with the scripted looker in the loop."""
        looker = ScriptedLooker(self.looker_name, self.env, self.run.num_envs, self.run.seed)
        self.collector = self._collector(self.actor, looker=looker)

    def policy(self):
        """The mover, and a fresh scripted looker for the evaluation's rooms."""
        return self.actor, ScriptedLooker(self.looker_name, self.env, MAX_ROOMS, self.run.seed)


def probe_arguments(prog: str, description: str, looker: str) -> ArgumentParser:
    """The arguments of a probe with a scripted looker in the loop (``looker``: the default looker)."""
    parser = ArgumentParser(prog=prog, description=description)
    parser.add_argument("--looker", choices=sorted(scripted.LOOKERS), default=looker, help=f"the looker ({looker})")
    parser.add_argument("--frames", type=whole_number, default=300_000, help="training frames (300000)")
    parser.add_argument("--seed", type=whole_number, default=0, help="seed of the run (0)")
    parser.add_argument("--episodes", type=whole_number, default=200, help="held-out episodes (200)")
    parser.add_argument("--version", type=int, choices=ROOMS, default=EnvConfig().version, help="room version")
    parser.add_argument("--bearing-bins", type=whole_number, default=0, help="the mover's bearing layout (0: none)")
    parser.add_argument(
        "--recipe",
        choices=("probe", "default"),
        default="probe",
        help="run shape and learning rate schedule: the committed probes' (16 rooms x 16 cycles, constant; the"
        " default) or activeperc-train's defaults",
    )
    return parser


def probe_config(args) -> TrainConfig:
    """``fixed_forward``'s config with the probe's budget, seed, room and bearing layout, at the run shape and learning
    rate schedule of ``--recipe``: its committed results' (16 rooms x 16 cycles, constant) or today's defaults."""
    shape = dict(num_envs=16, rollout_length=16, lr_schedule="constant") if args.recipe == "probe" else {}
    return TrainConfig.from_options(
        method="fixed_forward",
        frames=args.frames,
        **shape,
        seed=args.seed,
        bearing_bins=args.bearing_bins,
        env={"version": args.version},
    )


def main(argv: list[str] | None = None) -> int:
    """Train, evaluate, print one JSON line."""
    parser = probe_arguments("scripted_looker_training.py", __doc__.split("\n\n")[0], "track")
    args = parser.parse_args(argv)
    if args.frames < 1 or args.episodes < 1:
        parser.error("--frames and --episodes must be >= 1")
    config = probe_config(args)
    torch.manual_seed(config.run.seed)
    torch.set_num_threads(config.run.torch_threads)
    cls = FixedForward if args.looker == "fixed" else MoverWithScriptedLooker
    MoverWithScriptedLooker.looker_name = args.looker
    method = make_method(config, torch.device("cpu"), cls=cls)
    start, frames = time.perf_counter(), 0
    try:
        while frames < config.run.frames:
            frames += method.iterate().frames
        mover, looker = method.policy()
        result = evaluate(config, mover, looker, episodes=args.episodes, seed=0)
    finally:
        method.close()
    minutes = round((time.perf_counter() - start) / 60, 1)
    run = {
        "looker": args.looker,
        "version": args.version,
        "bearing_bins": args.bearing_bins,
        "recipe": args.recipe,
        "frames": frames,
    }
    print(json.dumps(run | {"seed": args.seed, "eval": result, "minutes": minutes}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
