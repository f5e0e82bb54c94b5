"""How closely the MuJoCo Warp backend follows the default one: trajectories, episode ends, the goal in view, and
the views' depth and segmentation.

python experiments/warp_agreement.py                 # 16 rooms, 300 random cycles each, rooms v1 and v2
python experiments/warp_agreement.py --device cuda   # the warp backend on the GPU
"""

from __future__ import annotations

import argparse

import numpy as np

from activeperc_env import EnvConfig, Simulator


def red(views: np.ndarray) -> np.ndarray:
    """Where the views show the red goal: (n, height, width) bool."""
    v = views.astype(int)
    return (v[..., 0] > 120) & (v[..., 1] < 80) & (v[..., 2] < 80)


def compare(version: int, rooms: int, cycles: int, device: str, seed: int) -> dict:
    """Both backends through the same random cycles (rooms restarted together when either ends)."""
    config = EnvConfig(version=version, depth=True, segmentation=True)
    ours = Simulator(config, num_envs=rooms, nthread=1)
    warp = Simulator(config, num_envs=rooms, nthread=1, backend="warp", device=device)
    for sim in (ours, warp):
        sim.reset(seeds=list(range(seed, seed + rooms)))
    rng = np.random.default_rng(seed)
    apart = intersection = union = 0
    position, pixels, depth, same_geom = [], [], [], []
    for _ in range(cycles):
        moves, looks = rng.integers(0, 3, (2, rooms))
        for sim in (ours, warp):
            sim.move(moves)
            sim.look(looks)
        apart += int((ours.done != warp.done).sum())
        position.append(np.abs(ours.state()[:, :2] - warp.state()[:, :2]).max(axis=1))
        views, warp_views = ours.render(), warp.render()
        pixels.append(np.abs(views.astype(int) - warp_views.astype(int)).mean())
        layers, warp_layers = ours.observe(), warp.observe()
        both = (layers["depth"] > 0) & (warp_layers["depth"] > 0)
        depth.append(np.abs(layers["depth"] - warp_layers["depth"])[both])
        same_geom.append((layers["segmentation"] == warp_layers["segmentation"]).mean())
        seen, warp_seen = red(views), red(warp_views)
        intersection += int((seen & warp_seen).sum())
        union += int((seen | warp_seen).sum())
        ended = np.flatnonzero(ours.done | warp.done)
        if ended.size:
            ours.reset(ended)
            warp.reset(ended)
    position = np.concatenate(position)
    return {
        "room-cycles": rooms * cycles,
        "position median (m)": f"{np.median(position):.1e}",
        "position 99 % (m)": f"{np.quantile(position, 0.99):.1e}",
        "position max (m)": f"{position.max():.1e}",
        "episodes ended apart": apart,
        "goal-mask IoU": f"{intersection / union:.3f}" if union else "goal never in view",
        "mean pixel difference (levels)": f"{np.mean(pixels):.2f}",
        "depth 99 % (m)": f"{np.quantile(np.concatenate(depth), 0.99):.1e}",
        "same geom (pixels)": f"{np.mean(same_geom):.4f}",
    }


def main(argv: list[str] | None = None) -> None:
    """Command line: one table row per room version."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rooms", type=int, default=16, help="rooms of each backend (16)")
    parser.add_argument("--cycles", type=int, default=300, help="random cycles (300)")
    parser.add_argument("--versions", type=int, nargs="+", default=[1, 2], help="room versions (1 2)")
    parser.add_argument("--device", default="cpu", help="where the warp backend runs: cpu or cuda (cpu)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the layouts and the random actions (0)")
    args = parser.parse_args(argv)
    if args.rooms < 1 or args.cycles < 1:
        parser.error(f"--rooms {args.rooms} and --cycles {args.cycles} must be at least 1")
    rows = {version: compare(version, args.rooms, args.cycles, args.device, args.seed) for version in args.versions}
    columns = list(next(iter(rows.values())))
    print("| room | " + " | ".join(columns) + " |")
    print("| --- " * (len(columns) + 1) + "|")
    for version, row in rows.items():
        print(f"| v{version} | " + " | ".join(str(row[c]) for c in columns) + " |")


if __name__ == "__main__":
    main()
