"""Time to a looker that pays: held-out success against training frames and minutes, over seeds, beside the fixed
camera with the same options.

Each run trains in steps of ``--every`` frames (a resumed run is the run it would have been without the stop), and
each step's policy plays ``--episodes`` held-out layouts. Rows go into ``--csv`` as they finish, so a stopped
benchmark resumes where it was; the report prints, per method, the frames and training minutes (the runs' own
``time_s``: iterations only, not start-up or evaluation) at which the mean over seeds first reaches each threshold.
Training options after ``--`` are ``activeperc-train``'s flags::

    python benchmarks/time_to_success.py --seeds 0 1 2 3 4 --csv benchmarks/results/cpu2/time_to_success.csv
    python benchmarks/time_to_success.py --seeds 0 --every 100000 -- --frames 300000 --num-envs 32
    taskset -c 1 python benchmarks/time_to_success.py --seeds 3 4 --csv F  # beside --seeds 0 1 2 on core 0
    python benchmarks/time_to_success.py --no-train --csv benchmarks/results/cpu2/time_to_success.csv \\
        --figure docs/figures/time_to_success.png
"""

from __future__ import annotations

import argparse
import csv
import fcntl
import math
import os
import sys
import time
from pathlib import Path

import harness
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "experiments" / "fig1"))  # the sweeps' statistics
from aggregate import mean_ci  # noqa: E402

from activeperc_rl import cli
from activeperc_rl.evaluate import evaluate, load_policy
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.checkpoint import CHECKPOINT, METRICS

COLUMNS = ("method", "seed", "frames", "train_minutes", "success_rate", "mean_return", "episodes", "machine", "date")
THRESHOLDS = (0.5, 0.64, 0.75)
REFERENCE = "fixed_forward"


def train_to(config, out: Path, frames: int) -> dict:
    """Train the run in ``out`` (afresh, or on from its checkpoint) to ``frames`` of its ``config.run.frames``; its
    last row of metrics.csv. A stop signal (Ctrl-C, SIGTERM), after which training saves its checkpoint and returns
    early, stops the benchmark."""
    from activeperc_rl.train import train

    resume = (out / CHECKPOINT).is_file()
    train(config.replace(eval_episodes=0), out, resume=resume, progress=False, stop_at=frames)
    with open(out / METRICS, newline="") as file:
        last = list(csv.DictReader(file))[-1]
    if int(last["frames"]) < frames:
        raise SystemExit(
            f"time_to_success: stopped at {int(last['frames']):,} of {frames:,} frames in {out}; the same"
            " command goes on from there"
        )
    return last


def measured(config, out: Path, frames: int, episodes: int) -> dict:
    """One row of the CSV: the run in ``out`` trained to ``frames`` and scored on ``episodes`` held-out layouts."""
    last = train_to(config, out, frames)
    _, mover_policy, looker = load_policy(out)
    score = evaluate(config, mover_policy, looker, episodes)
    return {
        "method": config.method,
        "seed": config.run.seed,
        "frames": int(last["frames"]),  # the iteration that reached ``frames`` overshoots it
        "train_minutes": f"{float(last['time_s']) / 60:.2f}",
        "success_rate": score["success_rate"],
        "mean_return": f"{score['mean_return']:.4f}",
        "episodes": episodes,
        "machine": portable.machine(),
        "date": time.strftime("%Y-%m-%d"),
    }


def add_row(path: Path, row: dict) -> list[dict]:
    """Add ``row`` to the CSV at ``path`` and return all its rows as read back (text, as :func:`read_rows` gives
    them): under a lock on its folder, with the rows that other runs of the benchmark (other seeds, one core each)
    wrote there meanwhile."""
    path.parent.mkdir(parents=True, exist_ok=True)
    folder = os.open(path.parent, os.O_RDONLY)
    try:
        fcntl.flock(folder, fcntl.LOCK_EX)
        rows = read_rows(path) + [row]
        harness.write_csv(path, COLUMNS, [tuple(r[c] for c in COLUMNS) for r in rows])
        return read_rows(path)
    finally:
        os.close(folder)  # (and the lock with it)


def read_rows(path: Path) -> list[dict]:
    """The rows already measured (none when ``path`` does not exist)."""
    if not path.is_file():
        return []
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def curve(rows: list[dict], method: str) -> list[tuple[int, float, float, float]]:
    """``method``'s points measured on every seed it has: (frames, mean minutes, mean success, 95 % half-width, NaN
    for one seed)."""
    mine = [r for r in rows if r["method"] == method]
    seeds = {r["seed"] for r in mine}
    points = []
    for frames in sorted({int(r["frames"]) for r in mine}):
        at = [r for r in mine if int(r["frames"]) == frames]
        if {r["seed"] for r in at} != seeds:
            continue  # a point not every seed has reached yet
        success, half = mean_ci([float(r["success_rate"]) for r in at])
        minutes = sum(float(r["train_minutes"]) for r in at) / len(at)
        points.append((frames, minutes, success, half))  # half: NaN for one seed
    return points


def report(rows: list[dict], methods: list[str]) -> str:
    """Per method, where the mean held-out success over seeds first reaches each of :data:`THRESHOLDS`."""
    lines = []
    for method in methods:
        points = curve(rows, method)
        for threshold in THRESHOLDS:
            first = next((p for p in points if p[2] >= threshold), None)
            reached = f"{first[0]:,} frames, {first[1]:.1f} min of training" if first else "not reached"
            lines.append(f"{method}: mean held-out success {threshold:.2f}: {reached}")
        if points:
            frames, minutes, success, half = points[-1]
            spread = "one seed" if math.isnan(half) else f"± {half:.3f}"
            lines.append(f"{method}: at {frames:,} frames ({minutes:.1f} min): {success:.3f} ({spread})")
    return "\n".join(lines)


def plot(rows: list[dict], methods: list[str], path: Path) -> None:
    """Held-out success against frames and against training minutes, mean and 95 % band over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    for method in methods:
        points = curve(rows, method)
        if not points:
            continue
        frames, minutes, success, half = (np.array(column) for column in zip(*points, strict=True))
        for axis, x in zip(axes, (frames, minutes), strict=True):
            axis.plot(x, success, label=method)
            axis.fill_between(x, success - half, success + half, alpha=0.2)
    axes[0].set(xlabel="training frames", ylabel="held-out success")
    axes[1].set(xlabel="minutes of training")
    axes[0].legend()
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    parser.add_argument("--seeds", type=harness.at_least(int, "--seeds", 0), nargs="+", default=[0])
    parser.add_argument(
        "--every", type=harness.at_least(int, "--every", 1), default=50_000, help="frames between two scores"
    )
    parser.add_argument(
        "--episodes", type=harness.at_least(int, "--episodes", 1), default=100, help="held-out layouts a score plays"
    )
    parser.add_argument("--reference", default=REFERENCE, help="the method beside the config's ('none': alone)")
    parser.add_argument("--runs", type=Path, default=Path("runs/time_to_success"), help="run directories")
    parser.add_argument("--csv", type=Path, default=Path("runs/time_to_success/time_to_success.csv"))
    parser.add_argument("--figure", type=Path, help="the figure (default: beside the CSV, .png)")
    parser.add_argument("--no-train", action="store_true", help="report and draw what is measured, train nothing")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ours, train_flags = (argv[: argv.index("--")], argv[argv.index("--") + 1 :]) if "--" in argv else (argv, [])
    parser = build_parser()
    args = parser.parse_args(ours)
    try:
        config = cli.config_from_args(cli.build_parser().parse_args(train_flags))
    except ValueError as error:
        parser.error(str(error))
    methods = [config.method] + ([args.reference] if args.reference not in ("none", config.method) else [])
    figure = args.figure or args.csv.with_suffix(".png")
    harness.refuse_unwritable(parser, {"--csv": args.csv, "--figure": figure})
    rows = read_rows(args.csv)
    steps = list(range(args.every, config.run.frames, args.every)) + [config.run.frames]
    print(f"time_to_success: {methods}, seeds {args.seeds}, {steps[-1]:,} frames in steps of {args.every:,}")
    print(harness.machine_line(harness.machine_info()), flush=True)
    for method in [] if args.no_train else methods:
        for seed in args.seeds:
            run = config.replace(method=method, seed=seed)
            out = args.runs / method / f"seed{seed}"
            for frames in steps:
                mine = [int(r["frames"]) for r in rows if (r["method"], str(r["seed"])) == (method, str(seed))]
                if any(reached >= frames for reached in mine):
                    continue  # measured before, or passed by the iteration that reached the step before
                rows = add_row(args.csv, measured(run, out, frames, args.episodes))
                print(f"{method} seed {seed} at {frames:,} frames: {rows[-1]['success_rate']}", flush=True)
    print(report(rows, methods))
    plot(rows, methods, figure)
    print(f"wrote {figure}" if args.no_train else f"wrote {args.csv} and {figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
