"""Where a run's looker points the camera: its pan against the goal's bearing, over held-out episodes.

Run from the repository root::

    python experiments/pan_vs_bearing.py RUN
    python experiments/pan_vs_bearing.py RUN --episodes 200 --figure docs/figures/pan_vs_bearing.png \
        --csv experiments/results/pan_vs_bearing.csv

The run's mover plays ``--episodes`` held-out episodes (those of the run's final evaluation: ``--seed`` is the run's
seed unless given) twice: with the run's own looker and with the camera held forward. After every cycle it records
the goal's bearing from the robot's heading, the camera's pan, whether the cycle's look panned, and whether the
goal showed in the mover's view. The figure
has the learned looker's pan against the goal's bearing (a tracking camera lies on the diagonal, a held one on
the zero line) and, for both lookers, how often the goal is in view at each bearing. Printed (and ``--csv``):
per looker, the held-out success rate, the pan rate (looks that are not 'hold') and the share of cycles with the
goal in view, overall and with the goal inside and outside the forward camera's field of view.
"""

from __future__ import annotations

import csv
import datetime
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from activeperc_env.arguments import ArgumentParser, whole_number  # noqa: E402
from activeperc_env.core import HOLD  # noqa: E402
from activeperc_env.scripted import goal_in_view, wrap  # noqa: E402
from activeperc_rl.envs import LOOKER, MOVER, latest_view  # noqa: E402
from activeperc_rl.evaluate import evaluate, load_policy  # noqa: E402
from activeperc_rl.models import FixedLooker  # noqa: E402
from activeperc_rl.runtime import portable  # noqa: E402
from activeperc_rl.runtime.atomic import atomic_path, write_csv  # noqa: E402

COLUMNS = (
    "run", "looker", "episodes", "success", "pan_rate", "goal_in_view", "in_view_inside_fov", "in_view_outside_fov",
    "cycles", "machine", "date",
)  # fmt: skip
BEARING_BINS = np.linspace(-180, 180, 25)


def bearing_and_pan(sim) -> tuple[np.ndarray, np.ndarray]:
    """The goal's bearing from each room's robot heading and the camera's pan, degrees (positive to the left), from
    the rooms' true state (``Simulator.state``: x, y, cos and sin of the heading, pan, the goal's x and y, ...)."""
    state = sim.state().astype(np.float64)
    heading = np.arctan2(state[:, 3], state[:, 2])
    bearing = wrap(np.arctan2(state[:, 6] - state[:, 1], state[:, 5] - state[:, 0]) - heading)
    return np.degrees(bearing), np.degrees(state[:, 4])


def play(config, mover_policy, looker, episodes: int, seed: int) -> dict:
    """Play ``episodes`` held-out episodes as ``activeperc-eval`` does; per cycle: ``bearing``, ``pan`` (degrees),
    ``looked``, ``seen``; and the episodes' ``success_rate`` and their number, ``episodes``."""
    cycles = {"bearing": [], "pan": [], "looked": [], "seen": []}

    def record(env, td, counted):
        images = latest_view(td.get(("next", MOVER, "observation", "image"))).numpy()
        bearing, pan = bearing_and_pan(env.sim)
        cycles["bearing"].append(bearing[counted])
        cycles["pan"].append(pan[counted])
        cycles["looked"].append((td.get(("next", LOOKER, "action")).reshape(-1).numpy() != HOLD)[counted])
        cycles["seen"].append(~np.isnan(goal_in_view(images, config.env.fov)[0])[counted])

    outcome = evaluate(config, mover_policy, looker, episodes, seed, on_cycle=record)
    return {key: np.concatenate(values) for key, values in cycles.items()} | outcome


def summary(run: str, looker: str, record: dict[str, np.ndarray], fov: float) -> dict:
    """One row of :data:`COLUMNS` for a looker's record."""
    outside = np.abs(record["bearing"]) > fov / 2
    return {
        "run": run,
        "looker": looker,
        "episodes": record["episodes"],
        "success": f"{record['success_rate']:.3f}",
        "pan_rate": f"{record['looked'].mean():.3f}",
        "goal_in_view": f"{record['seen'].mean():.3f}",
        "in_view_inside_fov": f"{record['seen'][~outside].mean():.3f}",
        "in_view_outside_fov": f"{record['seen'][outside].mean():.3f}",
        "cycles": len(record["seen"]),
        "machine": portable.machine(),
        "date": datetime.date.today().isoformat(),
    }


def in_view_by_bearing(record: dict[str, np.ndarray]) -> np.ndarray:
    """The share of cycles with the goal in view in each bin of :data:`BEARING_BINS` (NaN for an empty bin)."""
    index = np.clip(np.digitize(record["bearing"], BEARING_BINS) - 1, 0, len(BEARING_BINS) - 2)
    counts = np.bincount(index, minlength=len(BEARING_BINS) - 1)
    seen = np.bincount(index, weights=record["seen"], minlength=len(BEARING_BINS) - 1)
    with np.errstate(invalid="ignore"):
        return seen / counts


def plot(learned: dict, held: dict, config, title: str, path: Path) -> None:
    """Pan against bearing for the learned looker; the goal in view by bearing for both lookers."""
    limit = config.env.pan_range
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    pan_bins = np.linspace(-limit, limit, int(round(2 * limit / config.env.pan_step)) * 2 + 2)
    left.hist2d(learned["bearing"], learned["pan"], bins=[BEARING_BINS, pan_bins], cmap="Greys", cmin=1)
    line = np.linspace(-limit, limit, 2)
    left.plot(line, line, color="tab:red", lw=1, label="camera on the goal")
    left.axhline(0, color="tab:blue", lw=1, ls="--", label="camera held forward")
    left.set(xlabel="goal's bearing from the heading (degrees)", ylabel="camera pan (degrees)", xlim=(-180, 180))
    left.set_title("learned looker: pan against the goal's bearing (cycles)", fontsize=10)
    left.legend(loc="upper left", fontsize=8)
    centres = (BEARING_BINS[:-1] + BEARING_BINS[1:]) / 2
    for name, record, colour in (("learned looker", learned, "tab:red"), ("camera held", held, "tab:blue")):
        right.plot(centres, in_view_by_bearing(record), color=colour, marker=".", label=name)
    right.axvspan(-config.env.fov / 2, config.env.fov / 2, color="0.9", label="forward field of view")
    right.set(xlabel="goal's bearing from the heading (degrees)", ylabel="share of cycles", xlim=(-180, 180))
    right.set(ylim=(0, 1))
    right.set_title("the goal in the mover's view", fontsize=10)
    right.legend(loc="upper left", fontsize=8)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=110, format="png")
    plt.close(figure)


def main(argv: list[str] | None = None) -> int:
    """Play both lookers, print their rows, draw the figure."""
    parser = ArgumentParser(prog="pan_vs_bearing.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="a run directory (holding checkpoint.pt) of a method with a looker")
    parser.add_argument("--episodes", type=whole_number, default=200, help="held-out episodes per looker (200)")
    parser.add_argument(
        "--seed", type=whole_number, help="seed of the layouts and the sampling (default: the run's, as its eval.json)"
    )
    parser.add_argument("--figure", type=Path, help="write the figure here (PNG)")
    parser.add_argument("--csv", type=Path, help="add the two rows to this CSV (replacing the run's rows)")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes={args.episodes} must be >= 1")
    try:
        config, mover_policy, looker = load_policy(args.run)
    except ValueError as error:
        parser.error(str(error))
    if looker is None:
        parser.error(f"{args.run!r} is a run of {config.method!r}, whose policy writes the look itself")
    seed = config.run.seed if args.seed is None else args.seed
    records = {
        name: play(config, mover_policy, module, args.episodes, seed)
        for name, module in (("learned", looker), ("camera held", FixedLooker()))
    }
    rows = [summary(args.run, name, record, config.env.fov) for name, record in records.items()]
    print(" | ".join(COLUMNS))
    for row in rows:
        print(" | ".join(str(row[c]) for c in COLUMNS))
    if args.figure:
        title = f"{args.run}: room v{config.env.version}, FOV {config.env.fov:g}, {args.episodes} held-out episodes"
        plot(records["learned"], records["camera held"], config, title, args.figure)
        print(f"wrote {args.figure}")
    if args.csv:
        write_rows(args.csv, rows)
        print(f"wrote {args.csv}")
    return 0


def write_rows(path: Path, rows: list[dict], columns=COLUMNS) -> None:
    """Add ``rows`` (of one run) to the CSV at ``path``, replacing the rows of the same run (atomic rewrite)."""
    kept = []
    if path.is_file():
        with open(path, newline="") as file:
            kept = [row for row in csv.DictReader(file) if row["run"] != rows[0]["run"]]
    write_csv(path, list(columns), kept + rows)


if __name__ == "__main__":
    raise SystemExit(main())
