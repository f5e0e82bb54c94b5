"""``activeperc-episode``: play one episode with random agents and save what it looked like.

Writes ``OUT/map.png`` (the bird's-eye map at the start), ``OUT/views.png`` (the mover's
first-person views of the first cycles) and ``OUT/episode.mp4`` (map beside first-person
view, every cycle), and prints the episode's length and return.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from activeperc_env.config import EnvConfig
from activeperc_env.pettingzoo_env import LOOKER, MOVER, parallel_env
from activeperc_env.render import side_by_side

STRIP_CYCLES = 8


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = argparse.ArgumentParser(prog="activeperc-episode", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/episode"), help="output folder")
    parser.add_argument("--seed", type=int, default=0, help="layout and action seed")
    parser.add_argument("--fov", type=float, default=EnvConfig.fov, help="horizontal field of view, degrees")
    parser.add_argument("--num-obstacles", type=int, default=EnvConfig.num_obstacles)
    parser.add_argument("--no-video", action="store_true", help="skip episode.mp4")
    args = parser.parse_args(argv)
    try:
        env = parallel_env(render_mode="rgb_array", fov=args.fov, num_obstacles=args.num_obstacles)
    except ValueError as err:
        parser.error(str(err))
    rng = np.random.default_rng(args.seed)
    obs, _ = env.reset(seed=args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    start_map = env.render()
    frames = [side_by_side(start_map, obs[MOVER]["image"])]
    strip = [obs[MOVER]["image"]]
    total, cycles = 0.0, 0
    while env.agents:
        actions = {MOVER: int(rng.integers(3)), LOOKER: int(rng.integers(3))}
        obs, rewards, *_ = env.step(actions)
        total += rewards[MOVER]
        cycles += 1
        if cycles < STRIP_CYCLES:
            strip.append(obs[MOVER]["image"])
        frames.append(side_by_side(env.render(), obs[MOVER]["image"]))
    env.close()
    iio.imwrite(args.out / "map.png", start_map)
    iio.imwrite(args.out / "views.png", np.concatenate(strip, axis=1))
    written = ["map.png", "views.png"]
    if not args.no_video:
        fps = env.config.control_hz  # the video plays in simulated time
        iio.imwrite(args.out / "episode.mp4", np.stack(frames), fps=fps, codec="libx264", macro_block_size=1)
        written.append("episode.mp4")
    outcome = "reached the goal" if total > 0 else "did not reach the goal"
    print(f"random agents {outcome} in {cycles} cycles, return {total:.3f}")
    print(f"wrote {', '.join(str(args.out / name) for name in written)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
