"""How much a view drawn in another tile of the offscreen buffer differs from a one-room env's view of the same state.

Many rooms are drawn as tiles of one buffer (``Simulator(num_envs=N)``, ``make_vec``, ``make_env``); a one-room
env draws its view in the first tile. The rasteriser rounds a triangle's edges at another position of the buffer
a little differently, so a view may differ from the one-room view of the same state in a few pixels. This
script puts all ``--rooms`` rooms of one simulator in the same state (same seed, same random moves and looks),
replays the same episode in a one-room simulator, and compares every room's view ``s'`` with the one-room
view, cycle by cycle. It prints how many views differ at all, in how many pixels, and how many pixels differ
by more than one level of shade (an edge pixel that takes the colour of the surface beside it).

    python experiments/tile_shading.py [--episodes 5] [--cycles 60] [--rooms 16] [--version V]
"""

from __future__ import annotations

import argparse

import numpy as np

from activeperc_env import EnvConfig, Simulator
from activeperc_env.rooms import DEFAULT, ROOMS


def main() -> None:
    """Print the differences between the tiles' views and the one-room views of the same states."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--cycles", type=int, default=60)
    parser.add_argument("--rooms", type=int, default=16)
    parser.add_argument("--version", type=int, choices=tuple(ROOMS), default=DEFAULT, help="the room (the default)")
    args = parser.parse_args()
    for flag, value in (("--episodes", args.episodes), ("--cycles", args.cycles), ("--rooms", args.rooms)):
        if value < 1:
            parser.error(f"{flag} must be >= 1, got {value}")

    config, n = EnvConfig(version=args.version), args.rooms
    many, one = Simulator(config, num_envs=n), Simulator(config, num_envs=1)
    rng = np.random.default_rng(0)
    differing, beyond_one = [], []  # per view compared: pixels that differ at all, by more than one level
    for episode in range(args.episodes):
        many.reset(seeds=[episode] * n)
        one.reset(seeds=[episode])
        for _ in range(args.cycles):
            move, look = rng.integers(3), rng.integers(3)
            result = many.move(np.full(n, move))
            one.move(np.array([move]))
            if result.terminated[0] or result.truncated[0]:
                break
            many.look(np.full(n, look))
            one.look(np.array([look]))
            diff = np.abs(many.render().astype(int) - one.render().astype(int)).max(axis=-1)  # (n, h, w)
            differing.append((diff > 0).sum(axis=(1, 2)))
            beyond_one.append((diff > 1).sum(axis=(1, 2)))
    differing, beyond_one = np.concatenate(differing), np.concatenate(beyond_one)
    pixels = config.width * config.height
    views = differing.size
    print(f"{views} views ({n} tiles, {views // n} states, {config.width}x{config.height} pixels) against one room's")
    print(f"views that differ at all: {np.mean(differing > 0):.1%}")
    print(
        f"pixels that differ, per view: mean {differing.mean() / pixels:.2%}, 99th percentile "
        f"{np.quantile(differing, 0.99) / pixels:.2%}, max {differing.max() / pixels:.2%} ({differing.max()} pixels)"
    )
    print(
        f"pixels that differ by more than one level: in {np.mean(beyond_one > 0):.2%} of the views, "
        f"at most {beyond_one.max()} in one view, {beyond_one.sum()} in all"
    )


if __name__ == "__main__":
    main()
