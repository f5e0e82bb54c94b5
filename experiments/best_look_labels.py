"""How a ``best_look`` run's looker followed its labels during training, from the run's ``metrics.csv``.

Run from the repository root::

    python experiments/best_look_labels.py runs/meta-seed0-TIME
    python experiments/best_look_labels.py RUN... --bin 200000 --csv labels.csv

For each run (a ``meta`` run with ``--looker-credit best_look`` or ``every_look``) it prints one row per bin of
``--bin`` frames (the frames logged first and last in it, its iterations) with the means over the bin's iterations
of: E1's pan rate, ``phi2``'s entropy, how often ``phi2``'s argmax was the critic's best look on D2's cycles
(``agreement``), and how often that best look was a pan left, a pan right or 'hold'. Labels spread evenly over the
three looks say the critic values them alike; an agreement near the share of the commonest label says ``phi2``
learned that label's frequency and little else.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from statistics import fmean

from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_rl.runtime.atomic import write_csv

COLUMNS = (
    "run",
    "frames",
    "iterations",
    "e1_pan_rate",
    "looker_entropy",
    "agreement",
    "best_left",
    "best_right",
    "best_hold",
)
SOURCES = {  # column: metrics.csv's column
    "e1_pan_rate": "e1_pan_rate",
    "looker_entropy": "looker_entropy",
    "agreement": "best_look_agreement",
    "best_left": "best_look_left",
    "best_right": "best_look_right",
}


def read_metrics(run: Path) -> list[dict]:
    """The rows of ``run``'s ``metrics.csv``, refusing a run that logged no best-look shares."""
    path = run / "metrics.csv"
    if not path.is_file():
        raise SystemExit(f"best_look_labels: {run} has no metrics.csv")
    with open(path, newline="") as file:
        rows = list(csv.DictReader(file))
    if not any(not math.isnan(float(row.get("best_look_agreement") or "nan")) for row in rows):
        raise SystemExit(f"best_look_labels: {path} has no best-look shares (not a meta run with a best_look credit)")
    return rows


def binned(run: Path, size: int) -> list[dict]:
    """One row per ``size`` frames of ``run``: the means of :data:`SOURCES` over the bin's iterations."""
    bins: dict[int, list[dict]] = {}
    for row in read_metrics(run):
        bins.setdefault(int(row["frames"]) // size, []).append(row)
    out = []
    for _, rows in sorted(bins.items()):
        # a row resumed from an older metrics.csv is blank in the shares' columns: nan, as the credits without them
        means = {column: fmean(float(row[source] or "nan") for row in rows) for column, source in SOURCES.items()}
        hold = 1 - means["best_left"] - means["best_right"]
        frames = f"{rows[0]['frames']}-{rows[-1]['frames']}"  # the first and last logged in the bin
        out.append({"run": str(run), "frames": frames, "iterations": len(rows)} | means | {"best_hold": hold})
    return out


def main(argv: list[str] | None = None) -> int:
    """Print (and with ``--csv`` write) every run's bins."""
    parser = ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="meta run directories (holding metrics.csv)")
    parser.add_argument("--bin", type=whole_number, default=100_000, help="frames per bin (100000)")
    parser.add_argument("--csv", type=Path, help="also write the rows here")
    args = parser.parse_args(argv)
    if args.bin < 1:
        parser.error(f"--bin must be >= 1, got {args.bin}")
    rows = [row for run in args.runs for row in binned(run, args.bin)]
    print(" | ".join(COLUMNS))
    for row in rows:
        print(" | ".join(cell(row[column], 2) for column in COLUMNS))
    if args.csv:
        write_csv(args.csv, COLUMNS, ({column: cell(row[column], 4) for column in COLUMNS} for row in rows))
    return 0


def cell(value: str | int | float, digits: int) -> str:
    """A row's value as text: a float with ``digits`` decimals."""
    return f"{value:.{digits}f}" if isinstance(value, float) else str(value)


if __name__ == "__main__":
    sys.exit(main())
