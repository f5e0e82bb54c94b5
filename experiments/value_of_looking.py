"""What looking is worth in a room: every scripted mover and looker on the same held-out layouts.

Run from the repository root::

    python experiments/value_of_looking.py                        # 400 layouts, FOV 60 and 100, the default room
    python experiments/value_of_looking.py --layouts 200 --fov 60 --csv runs/vol.csv --version 0 --range-rays 13

Each mover of :data:`activeperc_env.scripted.MOVERS` (the vision mover sees what a learned mover sees; the oracle
reads the true state; random moves at random) plays with each looker of :data:`~activeperc_env.scripted.LOOKERS`
(fixed: the camera stays forward; scan and track: look for the goal, then keep it in view; random) one episode in
each of ``--layouts`` layouts, the same layouts for every pair: the episode seeds 1, 3, 5, ... (odd, as the
training CLI's held-out layouts; the policies' own randomness is seeded with ``--seed``). The oracle and the random
mover never read the image, so their rows are the same for every looker; random moves with random looks are uniform
random play. For each pair and field of view it prints and writes (``--csv``) the success rate with its 95 % Wilson
interval and the mean length of the successful episodes, then the gain of each looker over the fixed camera for
the vision mover. Every env option is a flag (``--turn-speed 90``, ``--version 0``, ...).
"""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

from activeperc_env import EnvConfig
from activeperc_env.arguments import ArgumentParser, add_config_flags, whole_number
from activeperc_env.rooms import ROOMS
from activeperc_env.scripted import LOOKERS, MOVERS, play

# every (mover, looker) pair, in table order
PAIRS = [(mover, looker) for mover in MOVERS for looker in LOOKERS]
COLUMNS = ("mover", "looker", "fov", "layouts", "success", "ci_low", "ci_high", "mean_cycles")
Z95 = 1.959964


def wilson(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95 % with the default ``z``)."""
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def measure(config: EnvConfig, layouts: int, seed: int = 0, pairs=PAIRS) -> list[dict]:
    """One row per (mover, looker) of ``pairs`` in ``config``'s room, over the first ``layouts`` held-out layouts."""
    seeds = 2 * np.arange(layouts) + 1
    rows = []
    for mover, looker in pairs:
        outcome = play(config, mover, looker, seeds, seed=seed)
        wins = int(outcome.success.sum())
        low, high = wilson(wins, layouts)
        cycles = float(outcome.cycles[outcome.success].mean()) if wins else math.nan
        rows.append(
            {
                "mover": mover,
                "looker": looker,
                "fov": config.fov,
                "layouts": layouts,
                "success": wins / layouts,
                "ci_low": low,
                "ci_high": high,
                "mean_cycles": cycles,
            }
        )
    return rows


def table(rows: list[dict]) -> str:
    """The markdown table docs/env.md shows: success [95 % interval] and mean cycles of each pair at each FOV."""
    fovs = sorted({row["fov"] for row in rows})
    header = "| mover | looker | " + " | ".join(f"FOV {fov:g}: success [95 % CI], cycles" for fov in fovs) + " |"
    lines = [header, "| --- | --- | " + " | ".join("---" for _ in fovs) + " |"]
    for mover, looker in dict.fromkeys((row["mover"], row["looker"]) for row in rows):
        cells = []
        for fov in fovs:
            row = next(r for r in rows if (r["mover"], r["looker"], r["fov"]) == (mover, looker, fov))
            cycles = "-" if math.isnan(row["mean_cycles"]) else f"{row['mean_cycles']:.0f}"
            cells.append(f"{row['success']:.2f} [{row['ci_low']:.2f}, {row['ci_high']:.2f}], {cycles}")
        lines.append(f"| {mover} | {looker} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def gains(rows: list[dict]) -> str:
    """For the vision mover: each looker's success minus the fixed camera's, and whether the intervals are apart."""
    lines = []
    for fov in sorted({row["fov"] for row in rows}):

        def of(looker, fov=fov):
            return next(r for r in rows if (r["mover"], r["looker"], r["fov"]) == ("vision", looker, fov))

        lookers = [r["looker"] for r in rows if (r["mover"], r["fov"]) == ("vision", fov)]
        if "fixed" not in lookers:
            continue
        fixed = of("fixed")
        for looker in lookers:
            if looker == "fixed":
                continue
            row = of(looker)
            apart = row["ci_low"] > fixed["ci_high"] or row["ci_high"] < fixed["ci_low"]
            lines.append(
                f"FOV {fov:g}: vision mover, {looker} looker vs fixed camera: {row['success'] - fixed['success']:+.3f}"
                f" ({'intervals apart' if apart else 'intervals overlap'})"
            )
    return "\n".join(lines)


def read_csv(path: Path) -> list[dict]:
    """The rows of a CSV that :func:`write_csv` wrote, numbers as numbers."""
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        row["layouts"] = int(row["layouts"])
        for key in ("fov", "success", "ci_low", "ci_high", "mean_cycles"):
            row[key] = float(row[key])
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    """The rows as a CSV file with :data:`COLUMNS`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.4f}" if isinstance(v, float) and k != "fov" else v) for k, v in row.items()})


def main(argv: list[str] | None = None) -> int:
    """Parse the flags, play every pair, print the table and the gains, and write the CSV."""
    parser = ArgumentParser(prog="value_of_looking.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--layouts", type=whole_number, default=400, help="held-out layouts per pair (400)")
    parser.add_argument("--fov", type=float, nargs="+", default=[60.0, 100.0], help="fields of view (60 100)")
    parser.add_argument("--seed", type=whole_number, default=0, help="seed of the policies' randomness (0)")
    parser.add_argument(
        "--pairs", nargs="+", metavar="MOVER:LOOKER", help="only these pairs, e.g. vision:fixed vision:scan (all)"
    )
    parser.add_argument("--csv", type=Path, help="write the rows to this CSV file")
    add_config_flags(parser.add_argument_group("environment"), EnvConfig, {"version": tuple(ROOMS)}, skip=("fov",))
    args = parser.parse_args(argv)
    if args.layouts < 1:
        parser.error(f"--layouts={args.layouts} is invalid: expected an int >= 1")
    pairs = PAIRS
    if args.pairs is not None:
        pairs = [tuple(pair.split(":", 1)) for pair in args.pairs]
        bad = [p for p, pair in zip(args.pairs, pairs, strict=True) if pair not in PAIRS]
        if bad:
            known = f"{sorted(MOVERS)} x {list(LOOKERS)}"
            parser.error(f"--pairs {' '.join(bad)} invalid: expected MOVER:LOOKER of {known}")
    options = {k: v for k, v in vars(args).items() if k not in ("layouts", "fov", "seed", "pairs", "csv")}
    try:
        configs = [EnvConfig(fov=fov, **options) for fov in args.fov]
    except ValueError as error:
        parser.error(str(error))
    start = time.perf_counter()
    rows = [row for config in configs for row in measure(config, args.layouts, args.seed, pairs)]
    shown = {k: v for k, v in vars(configs[0]).items() if k != "fov"}
    print(f"value of looking: {args.layouts} held-out layouts (episode seeds 1, 3, ...), room {shown}\n")
    print(table(rows))
    print()
    print(gains(rows))
    print(f"\n({time.perf_counter() - start:.0f} s)")
    if args.csv is not None:
        write_csv(rows, args.csv)
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
