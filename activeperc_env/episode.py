"""``activeperc-episode``: play one episode with random agents and save what it looked like.

Writes ``OUT/map.png`` (the bird's-eye map at the start, 320x240), ``OUT/views.png`` (the mover's
first-person views at the start and after each of the first 7 cycles, side by side, 2 white pixels apart) and
``OUT/episode.mp4`` (map beside first-person view, one frame at the start and one per cycle, at
``control_hz`` frames per second: simulated time), and prints the episode's length and return.
"""

from __future__ import annotations

import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from activeperc_env.arguments import ArgumentParser
from activeperc_env.checks import is_seed
from activeperc_env.config import EnvConfig
from activeperc_env.pettingzoo_env import LOOKER, MOVER, parallel_env
from activeperc_env.render import side_by_side

STRIP_CYCLES = 8
STRIP_GAP = 2  # white pixels between two views of views.png
OUTPUTS = ("map.png", "views.png", "episode.mp4")


def strip(views: list[np.ndarray]) -> np.ndarray:
    """The ``views`` side by side, :data:`STRIP_GAP` white pixels apart."""
    gap = np.full((views[0].shape[0], STRIP_GAP, 3), 255, dtype=np.uint8)
    return np.concatenate([part for view in views for part in (gap, view)][1:], axis=1)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = ArgumentParser(
        prog="activeperc-episode",
        description="Play one episode with random agents and write OUT/map.png, OUT/views.png (the first views) "
        "and OUT/episode.mp4 (map beside view, one frame per cycle).",
    )
    parser.add_argument("--out", type=Path, default=Path("runs/episode"), help="output folder (runs/episode)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the layout and of the random actions (0)")
    parser.add_argument(
        "--fov", type=float, default=EnvConfig.fov, help=f"horizontal field of view, degrees ({EnvConfig.fov:g})"
    )
    parser.add_argument(
        "--num-obstacles", type=int, default=EnvConfig.num_obstacles, help=f"occluders ({EnvConfig.num_obstacles})"
    )
    parser.add_argument("--no-video", action="store_true", help="skip episode.mp4")
    args = parser.parse_args(argv)
    if not is_seed(args.seed):
        parser.error(f"--seed={args.seed} is invalid: expected an int in [0, 2**63 - 1]")
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"--out {str(args.out)!r} is a file, not a folder")
    for name in OUTPUTS:
        if (args.out / name).is_dir():
            parser.error(f"{str(args.out / name)!r} is a folder: it cannot be written")
    try:
        env = parallel_env(render_mode="rgb_array", fov=args.fov, num_obstacles=args.num_obstacles)
    except ValueError as err:
        parser.error(str(err))
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        env.close()
        parser.error(f"--out {str(args.out)!r} cannot be made: {err.strerror}")
    rng = np.random.default_rng(args.seed)
    try:
        obs, _ = env.reset(seed=args.seed)
        start_map = env.render()
        frames = [side_by_side(start_map, obs[MOVER]["image"])]
        views = [obs[MOVER]["image"]]
        cycles = 0
        while env.agents:
            actions = {MOVER: int(rng.integers(3)), LOOKER: int(rng.integers(3))}
            obs, *_, infos = env.step(actions)
            cycles += 1
            if cycles < STRIP_CYCLES:
                views.append(obs[MOVER]["image"])
            frames.append(side_by_side(env.render(), obs[MOVER]["image"]))
    finally:
        env.close()
    iio.imwrite(args.out / "map.png", start_map)
    iio.imwrite(args.out / "views.png", strip(views))
    written = ["map.png", "views.png"]
    if not args.no_video:
        fps = env.config.control_hz  # the video plays in simulated time
        iio.imwrite(args.out / "episode.mp4", np.stack(frames), fps=fps, codec="libx264", macro_block_size=1)
        written.append("episode.mp4")
    outcome = "reached the goal" if infos[MOVER]["episode_success"] else "did not reach the goal"
    print(f"random agents {outcome} in {cycles} cycles, return {infos[MOVER]['episode_return']:.3f}")
    print(f"wrote {', '.join(str(args.out / name) for name in written)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
