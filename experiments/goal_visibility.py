"""How often is the red goal hidden from the robot's first-person view at its start pose?

For each seed the room is reset, the camera faces forward (pan 0, as at every start), and the
first-person image is rendered through the batched core. The goal counts as visible when at
least ``--min-pixels`` pixels are goal-red. The fraction of seeds in which it is NOT visible is
measured at each field of view, with the default config (``num_obstacles=3``) and with an
empty room (``num_obstacles=0``): the empty room separates the share due to the start heading
from the share due to the occluders. (The two rooms of a seed need not share a start: a draw whose
occluders do not fit is redrawn whole, so with occluders a seed often starts elsewhere.)

The looker could turn the camera before the robot moves, so the script also sweeps the pan
over ``k * pan_step`` (clipped to ``[-pan_range, +pan_range]``) with ``Simulator.look`` and
counts the starts in which the goal is hidden at every one of those pan angles.

For the empty room the pixel rule is also checked against geometry: the goal is in the field
of view when the horizontal angular extent of its box, seen from the camera, overlaps
``[-fov/2, +fov/2]``.

Run (under a minute on 2 CPU cores)::

    python experiments/goal_visibility.py --seeds 1000 --fovs 60 100 --csv runs/goal_visibility.csv

``--examples DIR`` also writes a few first-person views (4x enlarged PNGs) named with their
red-pixel counts, to inspect the rule by eye.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import numpy as np

import activeperc_env  # noqa: F401  (sets MUJOCO_GL=egl when headless, before mujoco is imported)
from activeperc_env import EnvConfig, Simulator, names
from activeperc_env.scripted import MIN_PIXELS, goal_pixels

BATCH = 250


def goal_pixel_counts(images: np.ndarray) -> np.ndarray:
    """Goal-red pixels (:func:`activeperc_env.scripted.goal_pixels`) per image of ``images`` (n, H, W, 3) uint8."""
    return goal_pixels(images).sum(axis=(1, 2))


def goal_in_view_cone(sim: Simulator, index: int) -> bool:
    """Whether any part of room ``index``'s goal box lies within the camera's horizontal FOV.

    Geometry only (occluders ignored): the bearings of the goal box's four vertical edges, seen
    from the camera, are compared with ``[-fov/2, +fov/2]`` around the camera's forward axis.
    """
    data = sim.physics_data(index)
    cam = sim.model.camera(names.EYE_CAMERA).id
    position = data.cam_xpos[cam, :2]
    forward = -data.cam_xmat[cam].reshape(3, 3)[:, 2]  # MuJoCo cameras look along -z
    yaw = math.atan2(forward[1], forward[0])
    gx, gy = sim.goal_xy(index)
    h = names.GOAL_HALF
    corners = np.array([[gx + sx * h, gy + sy * h] for sx in (-1, 1) for sy in (-1, 1)]) - position
    bearings = np.arctan2(corners[:, 1], corners[:, 0]) - yaw
    bearings = (bearings + np.pi) % (2 * np.pi) - np.pi
    half = math.radians(sim.config.fov) / 2
    return bool(bearings.max() > -half and bearings.min() < half)


def visible_at_some_pan(sim: Simulator, ids: np.ndarray, min_pixels: int = MIN_PIXELS) -> np.ndarray:
    """Sweep the camera of freshly reset rooms over every pan ``k * pan_step`` within the range.

    The base does not move (``look`` passes no time). The camera is left at ``-pan_range``.

    Returns:
        (len(ids),) bool: the goal covered at least ``min_pixels`` red pixels at some pan.
    """
    steps = math.ceil(sim.config.pan_range / sim.config.pan_step)
    seen = goal_pixel_counts(sim.render(ids)) >= min_pixels
    left = np.zeros(len(ids), dtype=np.int64)  # 0: pan left (+pan_step), 2: pan right
    for action, repeats in ((left, steps), (left + 2, 2 * steps)):
        for _ in range(repeats):
            sim.look(action, ids=ids)
            seen |= goal_pixel_counts(sim.render(ids)) >= min_pixels
    return seen


def measure(
    fov: float,
    num_obstacles: int,
    seeds: np.ndarray,
    min_pixels: int = MIN_PIXELS,
    batch: int = BATCH,
    geometry: bool = False,
    sweep: bool = True,
) -> dict:
    """Render every seed's start view and count the starts with the goal hidden.

    Args:
        fov: horizontal field of view, degrees.
        num_obstacles: occluders in the room (all other config fields at their defaults).
        seeds: the reset seeds, one room each.
        min_pixels: goal-red pixels needed to call the goal visible.
        batch: rooms rendered per ``Simulator.render`` call.
        geometry: also count the starts whose goal lies outside the view cone (see
            :func:`goal_in_view_cone`) and those where pixel rule and geometry disagree.
        sweep: also count the starts whose goal stays hidden at every pan angle (see
            :func:`visible_at_some_pan`).

    Returns:
        A dict with ``fov``, ``num_obstacles``, ``seeds``, ``hidden`` (count), ``fraction``,
        ``counts`` (per-seed red-pixel counts), with ``sweep`` ``hidden_every_pan``, and with
        ``geometry`` ``outside_cone`` and ``disagree``.
    """
    n = min(batch, len(seeds))
    sim = Simulator(EnvConfig(fov=fov, num_obstacles=num_obstacles), num_envs=n)
    counts = np.empty(len(seeds), dtype=np.int64)
    outside = np.zeros(len(seeds), dtype=bool)
    seen_somewhere = np.zeros(len(seeds), dtype=bool)
    try:
        for first in range(0, len(seeds), n):
            chunk = seeds[first : first + n]
            ids = np.arange(len(chunk))
            sim.reset(ids=ids, seeds=chunk)
            assert np.all(sim.pan(ids) == 0.0), "the camera should face forward at the start"
            counts[first : first + len(chunk)] = goal_pixel_counts(sim.render(ids))
            if geometry:
                outside[first : first + len(chunk)] = [not goal_in_view_cone(sim, int(i)) for i in ids]
            if sweep:
                seen_somewhere[first : first + len(chunk)] = visible_at_some_pan(sim, ids, min_pixels)
    finally:
        sim.close()
    hidden = counts < min_pixels
    result = {
        "fov": fov,
        "num_obstacles": num_obstacles,
        "seeds": len(seeds),
        "hidden": int(hidden.sum()),
        "fraction": float(hidden.mean()),
        "counts": counts,
    }
    if sweep:
        result["hidden_every_pan"] = int((~seen_somewhere).sum())
    if geometry:
        result["outside_cone"] = int(outside.sum())
        result["disagree"] = int((outside != hidden).sum())
    return result


def save_examples(fov: float, seeds: np.ndarray, directory: Path, min_pixels: int = MIN_PIXELS) -> None:
    """Write the start views of ``seeds`` with and without occluders, 4x enlarged, as PNGs."""
    import imageio.v3 as iio

    directory.mkdir(parents=True, exist_ok=True)
    for num_obstacles in (0, EnvConfig().num_obstacles):
        sim = Simulator(EnvConfig(fov=fov, num_obstacles=num_obstacles), num_envs=len(seeds))
        sim.reset(seeds=seeds)
        images = sim.render()
        counts = goal_pixel_counts(images)
        for seed, image, count in zip(seeds, images, counts, strict=True):
            tag = "visible" if count >= min_pixels else "hidden"
            big = image.repeat(4, axis=0).repeat(4, axis=1)
            iio.imwrite(directory / f"fov{fov:g}_obst{num_obstacles}_seed{seed}_{count}px_{tag}.png", big)
        iio.imwrite(directory / f"map_fov{fov:g}_obst{num_obstacles}_seed{seeds[0]}.png", sim.render_map(0))
        sim.close()


def main(argv: list[str] | None = None) -> list[dict]:
    """Parse the flags, measure, print a markdown table, and optionally write a CSV."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=1000, help="number of seeds, 0..N-1 (default 1000)")
    parser.add_argument("--fovs", type=float, nargs="+", default=[60.0, 100.0], help="horizontal FOVs, degrees")
    parser.add_argument("--min-pixels", type=int, default=MIN_PIXELS, help="red pixels that make the goal visible")
    parser.add_argument("--batch", type=int, default=BATCH, help="rooms per render call")
    parser.add_argument("--csv", type=Path, default=None, help="write the results to this CSV file")
    parser.add_argument("--examples", type=Path, default=None, help="write a few example PNGs to this folder")
    args = parser.parse_args(argv)
    for flag, value in (("--seeds", args.seeds), ("--min-pixels", args.min_pixels), ("--batch", args.batch)):
        if value < 1:
            parser.error(f"{flag} must be >= 1, got {value}")

    seeds = np.arange(args.seeds)
    default_obstacles = EnvConfig().num_obstacles
    rows = []
    for fov in args.fovs:
        rows.append(measure(fov, default_obstacles, seeds, args.min_pixels, args.batch))
        rows.append(measure(fov, 0, seeds, args.min_pixels, args.batch, geometry=True))
        if args.examples is not None:
            save_examples(fov, seeds[:6], args.examples, args.min_pixels)

    print(
        f"Goal NOT visible from the start pose, {args.seeds} seeds (visible = at least "
        f"{args.min_pixels} goal-red pixels)\n"
    )
    print(
        "| FOV (deg) | occluders | hidden, camera forward | hidden at every pan angle | "
        "geometry: goal outside the forward view cone |"
    )
    print("| ---: | ---: | ---: | ---: | ---: |")
    for row in rows:
        geometry = "-"
        if "outside_cone" in row:
            geometry = f"{_percent(row['outside_cone'], row['seeds'])} (pixel rule disagrees on {row['disagree']})"
        print(
            f"| {row['fov']:g} | {row['num_obstacles']} | {_percent(row['hidden'], row['seeds'])} "
            f"| {_percent(row['hidden_every_pan'], row['seeds'])} | {geometry} |"
        )

    if args.csv is not None:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with args.csv.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(
                [
                    "fov",
                    "num_obstacles",
                    "seeds",
                    "min_pixels",
                    "hidden_forward",
                    "fraction_hidden_forward",
                    "hidden_every_pan",
                    "outside_view_cone",
                    "disagree",
                ]
            )
            for row in rows:
                writer.writerow(
                    [
                        row["fov"],
                        row["num_obstacles"],
                        row["seeds"],
                        args.min_pixels,
                        row["hidden"],
                        f"{row['fraction']:.4f}",
                        row["hidden_every_pan"],
                        row.get("outside_cone", ""),
                        row.get("disagree", ""),
                    ]
                )
        print(f"\nwrote {args.csv}")
    return rows


def _percent(count: int, total: int) -> str:
    """``'62.9% (629/1000)'``."""
    return f"{count / total:.1%} ({count}/{total})"


if __name__ == "__main__":
    main(sys.argv[1:])
