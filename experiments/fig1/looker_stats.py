"""What the looker did in training runs: E1's pan rate and phi2's entropy, read from each run's TensorBoard log.

The meta method logs, every iteration, ``meta/e1_pan_rate`` (the fraction of E1's cycles whose look was not
'hold': how often the deployed looker phi1 turns the camera) and ``looker/entropy`` (phi2's mean entropy on
E2's views; 1.10 is uniform over the three looks, 0 a deterministic look). This script prints, for each run
folder given, one row with the run's last logged frames and training success rate (``metrics.csv``), the
largest pan rate of the run, the smallest entropy, the pan rate and entropy averaged over the last ``--last``
iterations, and what phi2 looks like at the end (``phi2``): ``start`` when its entropy is within 0.03 of the
untrained phi2's (``looker_hold_prob`` of the run's ``config.yaml``: 0.23 nats for the default 0.95),
``hold`` or ``pan`` when it is near-deterministic (under 0.05 nats) and its greedy copy phi1 never or does
pan, ``mixed`` otherwise. Runs of other methods get empty looker columns.

``--csv`` also writes the rows, ``--doc`` writes them as a Markdown table between the markers ``<!-- NAME -->``
and ``<!-- /NAME -->`` (``--marker NAME``), and ``--from-csv`` reads the rows from such a CSV; with run folders
too, their rows are added to the CSV's (replacing a row of the same run) and all are sorted by run (from the
repository root)::

    python experiments/fig1/looker_stats.py experiments/fig1/runs/meta_eps0.?_fov*/seed* \
        --csv experiments/fig1/results/looker.csv
    python experiments/fig1/looker_stats.py --from-csv experiments/fig1/results/looker.csv --doc TABLE.md
    python experiments/fig1/looker_stats.py --from-csv experiments/fig1/results/looker.csv NEW_RUNS... \
        --csv experiments/fig1/results/looker.csv
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path
from statistics import fmean

sys.path.insert(0, str(Path(__file__).resolve().parent))  # aggregate.py sits next to this file

from aggregate import replace_between  # noqa: E402
from sweep import read_rows  # noqa: E402

from activeperc_rl.config import load_yaml  # noqa: E402
from activeperc_rl.recipe import TrainConfig  # noqa: E402
from activeperc_rl.runtime.atomic import atomic_path  # noqa: E402

COLUMNS = ("run", "frames", "success_rate", "max_pan_rate", "min_entropy", "pan_rate", "looker_entropy", "phi2")
DETERMINISTIC = 0.05  # an entropy under this (nats) is a near-deterministic look
UNCHANGED = 0.03  # an entropy this close to the untrained phi2's counts as unchanged


def start_entropy(hold_prob: float) -> float:
    """Entropy (nats) of an untrained looker: 'hold' with ``hold_prob``, each pan with half the rest."""
    pan = (1 - hold_prob) / 2
    return -(hold_prob * math.log(hold_prob) + 2 * pan * math.log(pan))


def read_scalars(tb_dir: Path, tags: tuple[str, ...]) -> dict[str, list[float]]:
    """The values of each of ``tags`` logged under ``tb_dir``, in step order (missing tags give empty lists)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(tb_dir), size_guidance={"scalars": 0})
    events.Reload()
    present = set(events.Tags()["scalars"])
    return {tag: [e.value for e in events.Scalars(tag)] if tag in present else [] for tag in tags}


def run_name(run_dir: Path) -> str:
    """The folder's name, with its config's for a sweep run (``meta_eps0.3_fov60/seed0``)."""
    run_dir = run_dir.resolve()
    return f"{run_dir.parent.name}/{run_dir.name}" if run_dir.name.startswith("seed") else run_dir.name


def run_row(run_dir: Path, last: int) -> dict:
    """One row of :data:`COLUMNS` for the run in ``run_dir``."""
    metrics = run_dir / "metrics.csv"
    if not metrics.is_file():
        raise ValueError(f"{str(run_dir)!r} is not a training run: it has no metrics.csv")
    with open(metrics, newline="") as f:
        logged = list(csv.DictReader(f))
    if not logged:
        raise ValueError(f"{str(run_dir)!r} has logged no iteration yet: its metrics.csv has no rows")
    if not (run_dir / "tb").is_dir():
        raise ValueError(f"{str(run_dir)!r} has no TensorBoard log (tb/), where the looker's statistics are")
    final = logged[-1]
    row = dict.fromkeys(COLUMNS, "")
    row |= {"run": run_name(run_dir), "frames": int(final["frames"]), "success_rate": float(final["success_rate"])}
    scalars = read_scalars(run_dir / "tb", ("meta/e1_pan_rate", "looker/entropy"))
    pans, entropies = scalars["meta/e1_pan_rate"], scalars["looker/entropy"]
    if pans and entropies:
        pan, entropy = fmean(pans[-last:]), fmean(entropies[-last:])
        hold_prob = TrainConfig.from_saved(load_yaml(run_dir / "config.yaml")).options.looker_hold_prob
        if abs(entropy - start_entropy(hold_prob)) <= UNCHANGED:
            phi2 = "start"
        elif entropy < DETERMINISTIC:
            phi2 = "hold" if pan == 0 else "pan"
        else:
            phi2 = "mixed"
        row |= {
            "max_pan_rate": round(max(pans), 4),
            "min_entropy": round(min(entropies), 4),
            "pan_rate": round(pan, 4),
            "looker_entropy": round(entropy, 4),
            "phi2": phi2,
        }
    return row


def markdown_table(rows: list[dict]) -> str:
    """The rows as a Markdown table (runs of other methods show dashes in the looker columns)."""
    lines = [
        "| run | frames | success | E1 pan rate, max / end | `phi2` entropy, min / end | `phi2` |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        pan = entropy = "-"
        if row["phi2"]:
            pan = f"{float(row['max_pan_rate']):.2f} / {float(row['pan_rate']):.2f}"
            entropy = f"{float(row['min_entropy']):.2f} / {float(row['looker_entropy']):.2f}"
        head = f"| {row['run']} | {int(row['frames']):,} | {float(row['success_rate']):.2f}"
        lines.append(f"{head} | {pan} | {entropy} | {row['phi2'] or '-'} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Print (and write as asked) one row per run folder and the rows of ``--from-csv``; 2 on bad input."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="*", type=Path, metavar="RUN_DIR", help="training run folders")
    parser.add_argument(
        "--from-csv", type=Path, help="read rows from a CSV this script wrote (the run folders' rows are added)"
    )
    parser.add_argument("--last", type=int, default=20, help="iterations averaged at the end of each run (20)")
    parser.add_argument("--csv", type=Path, help="also write the rows to this CSV file")
    parser.add_argument("--doc", type=Path, help="also write the Markdown table into this file, between the markers")
    parser.add_argument("--marker", default="looker-sweep", help="the markers' name: <!-- NAME --> (looker-sweep)")
    args = parser.parse_args(argv)
    if args.last < 1:
        parser.error(f"--last must be >= 1, got {args.last}")
    if not args.runs and not args.from_csv:
        parser.error("give run folders, --from-csv, or both")
    try:
        rows = [run_row(run, args.last) for run in args.runs]
        if args.from_csv:
            if not args.from_csv.is_file():
                raise ValueError(f"--from-csv {str(args.from_csv)!r} does not exist")
            merged = {row["run"]: row for row in read_rows(args.from_csv, COLUMNS[:3])}
            merged.update((row["run"], row) for row in rows)
            rows = sorted(merged.values(), key=lambda row: row["run"]) if args.runs else list(merged.values())
            if not rows:
                raise ValueError(f"--from-csv {str(args.from_csv)!r} holds no rows")
        doc = None
        if args.doc:
            if not args.doc.is_file():
                raise ValueError(f"--doc {str(args.doc)!r} does not exist")
            doc = replace_between(args.doc.read_text(), args.marker, markdown_table(rows))
    except ValueError as error:
        print(f"looker_stats: {error}", file=sys.stderr)
        return 2
    width = max(len(row["run"]) for row in rows)
    print(f"{'run':<{width}}  " + "  ".join(f"{c:>14}" for c in COLUMNS[1:]))
    for row in rows:
        print(f"{row['run']:<{width}}  " + "  ".join(f"{row[c]!s:>14}" for c in COLUMNS[1:]))
    if args.csv:
        with atomic_path(args.csv) as tmp, open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=COLUMNS)
            writer.writeheader()
            writer.writerows(rows)
    if doc is not None:
        with atomic_path(args.doc) as tmp:
            tmp.write_text(doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
