"""What ``torch.compile`` buys the default recipe's networks, measured in one run: a network (encoder and head, the
default ``NetworkConfig``) timed eager and compiled in alternating rounds, at the two batches a `meta` iteration
passes through it: a collection step's forward pass (one view per room, no gradient) and an update's forward and
backward pass (E1's and E2's rollouts of every room together).

Run it from the repository root::

    python benchmarks/compile_speed.py                 # 3 rounds of 5 s per batch and mode, on torch's threads
    python benchmarks/compile_speed.py --threads 1 --rounds 5 --seconds 2
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import harness
import torch

from activeperc_rl.models import NUM_ACTIONS, Head
from activeperc_rl.recipe import TrainConfig


def network(config: TrainConfig) -> Head:
    """The mover's actor network of the recipe ``config``: its encoder and a 3-way head."""
    return Head(config.network.encoder(config.env), config.network.hidden_size, NUM_ACTIONS)


def views(config: TrainConfig, batch: int) -> tuple[torch.Tensor, ...]:
    """Random observations of ``batch`` rooms: images, pans and range readings."""
    env = config.env
    image = torch.randint(0, 256, (batch, env.height, env.width, 3), dtype=torch.uint8)
    return image, torch.rand(batch, 1), torch.rand(batch, env.range_rays)


def pass_of(model, inputs: tuple, backward: bool):
    """One pass of ``model`` on ``inputs``: a forward pass without gradients, or a forward and a backward pass."""

    def one() -> int:
        if backward:
            model(*inputs).sum().backward()
        else:
            with torch.no_grad():
                model(*inputs)
        return 1

    return one


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=harness.at_least(int, "rounds", 1), default=3, help="rounds (3)")
    parser.add_argument(
        "--seconds", type=harness.at_least(float, "seconds", 0, strict=True), default=5.0, help="timed s per pass (5)"
    )
    parser.add_argument("--threads", type=harness.at_least(int, "threads", 1), help="torch threads (torch's default)")
    args = parser.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    config = TrainConfig()
    eager = network(config)
    compiled = torch.compile(eager)
    rollouts = 2 * config.run.num_envs * config.run.rollout_length  # D1 and D2 of every room: meta's first update
    batches = {
        "collection step (forward)": (config.run.num_envs, False),
        "update (forward, backward)": (rollouts, True),
    }
    threads = f"torch {torch.__version__}, {torch.get_num_threads()} threads"
    print(f"{harness.machine_line(harness.machine_info())}; {threads}")
    for label, (batch, backward) in batches.items():
        inputs = views(config, batch)
        start = time.perf_counter()
        pass_of(compiled, inputs, backward)()  # compiles
        print(f"{label}, batch {batch}: compiled in {time.perf_counter() - start:.1f} s")
        ratios = []
        for _ in range(args.rounds):
            rates = {
                mode: harness.timed_rate(pass_of(model, inputs, backward), args.seconds, warmup=1.0)
                for mode, model in (("eager", eager), ("compiled", compiled))
            }
            ratios.append(rates["compiled"] / rates["eager"])
            print(f"  eager {1000 / rates['eager']:.1f} ms, compiled {1000 / rates['compiled']:.1f} ms a pass")
        spread = ", ".join(f"{r:.2f}x" for r in ratios)
        print(f"  compiled / eager passes a second: {statistics.median(ratios):.2f}x (rounds {spread})")


if __name__ == "__main__":
    sys.exit(main())
