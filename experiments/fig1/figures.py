"""Figure 1 (a)-(c): the bird's-eye map of a room and the robot's first-person views at 60 and 100 degrees.

The same layout (``--seed``) is reset once per field of view, so both views are taken from the same
state: the same robot pose, camera angle (forward, as at every start), goal and occluders. By default
the seed is the first from 0 whose goal is hidden from the forward view at 60 degrees and visible at
100, the situation the paper's figure illustrates (goal-red pixels counted as in
``experiments/goal_visibility.py``). The views are the images the agents get (80x60 by default), enlarged
without smoothing.

Writes ``docs/figures/fig1_map.png`` and ``docs/figures/fig1_obs.png`` (of the default room; ``--version`` another)::

    python experiments/fig1/figures.py
    python experiments/fig1/figures.py --seed 7 --version 0 --out /tmp/figures
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # goal_visibility.py is in experiments/

from goal_visibility import MIN_PIXELS, goal_pixel_counts  # noqa: E402

import activeperc_env  # noqa: E402, F401  (sets MUJOCO_GL=egl when headless, before mujoco is imported)
from activeperc_env import EnvConfig, Simulator  # noqa: E402
from activeperc_env.rooms import DEFAULT, ROOMS  # noqa: E402
from activeperc_rl.runtime.atomic import atomic_path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent.parent
FOVS = (60.0, 100.0)
SEARCH = 200  # seeds tried when looking for one whose goal only the wide view shows


def views(seed: int, fovs=FOVS, version: int = DEFAULT) -> tuple[np.ndarray, list[np.ndarray]]:
    """The map (narrowest fov's view cone) and one first-person view per fov, all from the start of layout ``seed``
    of room ``version``."""
    images, first_map = [], None
    for fov in fovs:
        sim = Simulator(EnvConfig(fov=fov, version=version))
        sim.reset(seeds=[seed])
        images.append(sim.render()[0])
        if first_map is None:
            first_map = sim.render_map(0)
        sim.close()
    return first_map, images


def revealing_seed(limit: int = SEARCH, version: int = DEFAULT) -> int:
    """The first seed whose goal is hidden from the forward view at 60 degrees and visible at 100 in room
    ``version``."""
    narrow, wide = (Simulator(EnvConfig(fov=fov, version=version), num_envs=limit) for fov in FOVS)
    seeds = list(range(limit))
    narrow.reset(seeds=seeds)
    wide.reset(seeds=seeds)
    hidden = goal_pixel_counts(narrow.render()) < MIN_PIXELS
    shown = goal_pixel_counts(wide.render()) >= MIN_PIXELS
    narrow.close()
    wide.close()
    found = np.flatnonzero(hidden & shown)
    if found.size == 0:
        raise ValueError(f"no seed below {limit} has its goal visible at 100 degrees only; pass --seed")
    return int(found[0])


def save_figures(seed: int, out: Path, version: int = DEFAULT) -> list[Path]:
    """Write ``fig1_map.png`` and ``fig1_obs.png`` of layout ``seed`` of room ``version`` into ``out``; returns
    their paths."""
    room_map, images = views(seed, version=version)
    out.mkdir(parents=True, exist_ok=True)
    figure, axis = plt.subplots(figsize=(6.4, 4.8))
    axis.imshow(room_map)
    title = f"(a) bird's-eye view, room v{version}, seed {seed}"
    axis.set_title(f"{title}\nred: goal; cone: {FOVS[0]:.0f} degree view; white: heading")
    axis.axis("off")
    paths = [out / "fig1_map.png", out / "fig1_obs.png"]
    _save(figure, paths[0])
    figure, axes = plt.subplots(1, len(FOVS), figsize=(4.2 * len(FOVS), 3.6))
    for axis, fov, image, letter in zip(axes, FOVS, images, "bcdefg", strict=False):
        axis.imshow(image, interpolation="nearest")
        axis.set_title(f"({letter}) field of view {fov:.0f} degrees ({image.shape[1]}x{image.shape[0]})")
        axis.axis("off")
    _save(figure, paths[1])
    return paths


def _save(figure, path: Path) -> None:
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png", dpi=100)
    plt.close(figure)


def main(argv: list[str] | None = None) -> int:
    """Command line; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, help="layout seed (default: the first that only 100 degrees reveals)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures", help="output folder")
    parser.add_argument("--version", type=int, choices=tuple(ROOMS), default=DEFAULT, help="the room (the default)")
    args = parser.parse_args(argv)
    if args.seed is not None and args.seed < 0:
        parser.error(f"--seed={args.seed} is invalid: expected an int >= 0")
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"--out {str(args.out)!r} is a file: give a folder")
    seed = revealing_seed(version=args.version) if args.seed is None else args.seed
    for path in save_figures(seed, args.out, args.version):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
