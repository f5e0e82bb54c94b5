"""Write the docs' tables of results from the committed CSVs.

    python docs/tables.py            # rewrite every table between <!-- NAME --> and <!-- /NAME --> in docs/
    python docs/tables.py --check    # change nothing; exit 1 naming each table its CSV no longer gives

Each table's numbers live in a committed CSV, with the command, the machine and the date of each row where the
numbers were copied from what a run printed. Spreads over seeds (mean ± 95 % interval, Student's t) are computed
here from the sweeps' CSVs, as ``experiments/fig1/aggregate.py`` computes them.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
FIG1 = "experiments/fig1/results"
sys.path.insert(0, str(ROOT / "experiments" / "fig1"))  # the sweep's own table makers

from aggregate import mean_ci, replace_between, summary_table, with_reference  # noqa: E402
from looker_stats import markdown_table  # noqa: E402


def read(path: str) -> list[dict]:
    """The rows of the CSV at ``path`` (relative to the repository root)."""
    with open(ROOT / path, newline="") as file:
        return list(csv.DictReader(file))


def markdown(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table with a newline at its end."""
    lines = [header, ["---"] * len(header), *rows]
    return "".join("| " + " | ".join(line) + " |\n" for line in lines)


def spread(values) -> str:
    """``mean ± half-width`` of the 95 % interval over seeds, two digits."""
    return "{:.2f} ± {:.2f}".format(*mean_ci([float(v) for v in values]))


def seeds_of(text: str) -> list[str]:
    """``"0-4"`` as ``["0", "1", "2", "3", "4"]``."""
    first, last = text.split("-")
    return [str(seed) for seed in range(int(first), int(last) + 1)]


def sweep_outcome(row: dict) -> dict:
    """A row over seeds of a sweep: its held-out, random and final training success from the sweep's CSVs."""
    seeds = seeds_of(row["seeds"])
    runs = {r["seed"]: r for r in read(row["sweep"]) if f"{r['method']}_fov{r['fov']}" == row["sweep_run"]}
    runs = [runs[seed] for seed in seeds]
    curves = [read(f"{Path(row['sweep']).parent}/runs/{row['sweep_run']}_seed{seed}.csv") for seed in seeds]
    return row | {
        "success": spread(r["final_success_rate"] for r in runs),
        "random": spread(r["random_success_rate"] for r in runs),
        "train_success": spread(curve[-1]["success_rate"] for curve in curves),
    }


def command_cell(row: dict) -> str:
    """The command, the seeds of a row over seeds, and the row's note."""
    seeds = f", seeds {row['seeds']}" if row["sweep"] else ""
    note = f" ({row['note']})" if row["note"] else ""
    return f"`{row['command']}`{seeds}{note}"


def held_out_cell(row: dict) -> str:
    """Held-out success, against random's, and with the camera held forward where it was evaluated."""
    random = f" vs {row['random']}" if row["random"] else ""
    held = f" ({row['camera_held']} with the camera held forward)" if row["camera_held"] else ""
    return f"{row['success']}{random}{held}"


RUN_COLUMNS = {  # column name: (header, cell)
    "command": ("command", command_cell),
    "frames": ("frames", lambda row: f"{int(row['frames']):,}"),
    "episodes": ("held-out episodes", lambda row: row["episodes"]),
    "train": ("training success", lambda row: row["train_success"]),
    "held-out": ("held-out success", held_out_cell),
    "looked": ("what looked", lambda row: row["looked"]),
}


def provenance(rows: list[dict]) -> str:
    """Where and when the rows ran: ``Rows 1-2, 5: MACHINE, DATE; ...`` (``All rows: ...`` when one place)."""
    groups: dict[tuple[str, str], list[int]] = {}
    for number, row in enumerate(rows, 1):
        groups.setdefault((row["machine"], row["date"]), []).append(number)
    if len(groups) == 1:
        return "All rows: {}, {}.\n".format(*next(iter(groups)))
    parts = [
        f"row{'s' if len(numbers) > 1 else ''} {spans(numbers)}: {machine}, {date}"
        for (machine, date), numbers in groups.items()
    ]
    text = "; ".join(parts) + ".\n"
    return text[0].upper() + text[1:]


def spans(numbers: list[int]) -> str:
    """``[1, 2, 3, 5]`` as ``1-3, 5``."""
    runs: list[list[int]] = []
    for number in numbers:
        if runs and runs[-1][-1] == number - 1:
            runs[-1].append(number)
        else:
            runs.append([number])
    return ", ".join(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]) for run in runs)


def runs_table(name: str, columns: list[str]) -> str:
    """The table of ``experiments/results/NAME.csv``'s runs in ``columns``, then where and when they ran."""
    rows = [sweep_outcome(row) if row["sweep"] else row for row in read(f"experiments/results/{name}.csv")]
    header = [RUN_COLUMNS[column][0] for column in columns]
    cells = [[RUN_COLUMNS[column][1](row) for column in columns] for row in rows]
    return markdown(header, cells) + "\n" + provenance(rows)


def fig1_ablations() -> str:
    """The ablations of the Figure 1 sweep after the runs of the config they change (as aggregate.py writes it)."""
    return summary_table(with_reference(read(f"{FIG1}/ablations.csv"), read(f"{FIG1}/summary.csv")))


def h100_long() -> str:
    """The two longer H100 runs: held-out results and what ``phi2`` ended as."""
    looker = {r["run"].split("/")[0]: r["phi2"] for r in read(f"{FIG1}/h100_long/looker.csv")}
    rows = [
        [
            f"`{r['method']}`, {r['fov']} degrees",
            f"{int(r['frames']):,}",
            f"{float(r['final_success_rate']):.2f}",
            f"{float(r['final_return']):.3f}",
            f"{float(r['random_success_rate']):.2f}",
            looker[f"{r['method']}_fov{r['fov']}"] or "-",
        ]
        for r in read(f"{FIG1}/h100_long/summary.csv")
    ]
    return markdown(["run", "frames", "held-out success", "held-out return", "random success", "`phi2`"], rows)


def importance_weights() -> str:
    """The three runs whose ``phi2`` settled on 'hold', with the paper's gradient and with importance weights."""
    paper = looker_outcomes(f"{FIG1}/summary.csv", f"{FIG1}/looker.csv")
    weighted = looker_outcomes(f"{FIG1}/importance_weights/summary.csv", f"{FIG1}/importance_weights/looker.csv")
    rows = []
    for seed, after in weighted.items():
        before = paper[seed]
        rows.append(
            [f"seed {seed}, the paper's gradient / weighted"]
            + [
                f"{before[key]} {joint} {after[key]}"
                for key, joint in (("held_out", "/"), ("training", "/"), ("entropy", "→"), ("phi2", "→"))
            ]
        )
    header = [
        "run (`meta_eps0.3`, 100 degrees)",
        "held-out success",
        "training success",
        "`phi2` entropy, min / end",
        "`phi2`",
    ]
    return markdown(header, rows)


def looker_outcomes(summary: str, looker: str) -> dict[str, dict]:
    """``meta_eps0.3`` at 100 degrees by seed: held-out and training success, ``phi2``'s entropy and end."""
    held_out = {r["seed"]: r for r in read(summary) if r["method"] == "meta_eps0.3" and r["fov"] == "100"}
    outcomes = {}
    for row in read(looker):
        run, seed = row["run"].split("/seed")
        if run == "meta_eps0.3_fov100":
            outcomes[seed] = {
                "held_out": f"{float(held_out[seed]['final_success_rate']):.2f}",
                "training": f"{float(row['success_rate']):.2f}",
                "entropy": f"{float(row['min_entropy']):.2f} / {float(row['looker_entropy']):.2f}",
                "phi2": row["phi2"],
            }
    return outcomes


SECTIONS = {  # marker: (document in docs/, the function that makes its table)
    "room-v1": ("training.md", lambda: runs_table("room_v1", ["command", "episodes", "held-out", "looked"])),
    "room-v1-baselines": (
        "training.md",
        lambda: runs_table("room_v1_baselines", ["command", "held-out", "looked"]),
    ),
    "room-v2": ("training.md", lambda: runs_table("room_v2", ["command", "episodes", "held-out", "looked"])),
    "memory-mover": ("training.md", lambda: runs_table("memory_mover", ["command", "episodes", "held-out", "looked"])),
    "room-v0": ("training.md", lambda: runs_table("room_v0", ["command", "frames", "train", "held-out"])),
    "fig1-summary": ("reproduction.md", lambda: summary_table(read(f"{FIG1}/summary.csv"))),
    "fig1-ablations": ("reproduction.md", fig1_ablations),
    "looker-sweep": ("reproduction.md", lambda: markdown_table(read(f"{FIG1}/looker.csv"))),
    "looker-probe": ("reproduction.md", lambda: markdown_table(read(f"{FIG1}/looker_probe.csv"))),
    "looker-ablations": ("reproduction.md", lambda: markdown_table(read(f"{FIG1}/looker_ablations.csv"))),
    "h100-long": ("reproduction.md", h100_long),
    "importance-weights": ("reproduction.md", importance_weights),
}


def made(docs: Path = DOCS) -> dict[Path, str]:
    """The text of each document with generated tables, every table made anew from its CSV."""
    texts: dict[Path, str] = {}
    for marker, (name, make) in SECTIONS.items():
        path = docs / name
        texts[path] = replace_between(texts.get(path) or path.read_text(), marker, make())
    return texts


def stale(docs: Path = DOCS) -> list[str]:
    """The markers whose table in ``docs`` differs from what its CSV gives."""
    names = []
    for marker, (name, make) in SECTIONS.items():
        text = (docs / name).read_text()
        try:
            if replace_between(text, marker, make()) != text:
                names.append(marker)
        except ValueError as error:  # the document lost the table's markers
            raise ValueError(f"docs/{name}: {error}") from None
    return names


def main(argv: list[str] | None = None) -> int:
    """Command line; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if a table is out of date")
    args = parser.parse_args(argv)
    try:
        names = stale()
    except ValueError as error:  # a document lost a table's markers
        parser.error(str(error))
    if args.check:
        for marker in names:
            print(f"docs/{SECTIONS[marker][0]}: the table '{marker}' is out of date: run python docs/tables.py")
        return 1 if names else 0
    for path, text in made().items():
        if text != path.read_text():
            path.write_text(text)
            print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
