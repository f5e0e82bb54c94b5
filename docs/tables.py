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
import json
import math
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
FIG1 = "experiments/fig1/results"
sys.path[:0] = [str(ROOT / "experiments" / "fig1"), str(ROOT / "experiments")]  # the scripts' own table makers

from aggregate import (  # noqa: E402
    CLAIMS,
    claims,
    difference_table,
    machines_line,
    mean_ci,
    paired_difference,
    replace_between,
    summary_table,
    with_reference,
)
from value_of_looking import read_csv as read_looking  # noqa: E402
from value_of_looking import table as looking_table  # noqa: E402


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
    return spread_of(*mean_ci([float(v) for v in values]))


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


OLD_SHAPE = "--num-envs 16 --rollout-length 16 --lr-schedule constant"
"""The run shape and schedule of the defaults before 2026-12-06: ``$OLD`` in the tables' commands."""


def command_cell(row: dict) -> str:
    """The command (:data:`OLD_SHAPE` as ``$OLD``), the seeds of a row over seeds, and the row's note."""
    seeds = f", seeds {row['seeds']}" if row["sweep"] else ""
    note = f" ({row['note']})" if row["note"] else ""
    return f"`{row['command'].replace(OLD_SHAPE, '$OLD')}`{seeds}{note}"


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
    old = any(OLD_SHAPE in row["command"] for row in rows) and "command" in columns
    legend = f'`OLD="{OLD_SHAPE}"`, the defaults before 2026-12-06. ' if old else ""
    return markdown(header, cells) + "\n" + legend + provenance(rows)


V3 = "experiments/results/v3"


V3_AGAINST = ("meta_eps0.3", "meta_eps0.1")
"""The methods Figure 1 in room v3 is paired against: meta at each epsilon."""


def fig1_v3() -> str:
    """Figure 1 in room v3 and the machines that ran it, as ``aggregate.py --results experiments/results/v3`` prints
    them."""
    rows = read(f"{V3}/summary.csv")
    return summary_table(rows) + machines_line(rows)


def fig1_v3_ablations() -> str:
    """Room v3's ablations of Figure 1 after the runs of the config they change, the paired differences to it and the
    machines, as ``aggregate.py --ablations --against meta_eps0.3`` prints them."""
    rows = with_reference(read(f"{V3}/ablations.csv"), read(f"{V3}/summary.csv"))
    return summary_table(rows) + machines_line(rows) + "\n" + difference_table(rows, "meta_eps0.3")


V3_DEFAULT = "experiments/results/v3_400k"
"""The default command (``meta``) and ``--method fixed_forward`` over seeds 0-9, at the default budget."""
README_SEEDS = (range(5), range(5, 10))
"""The seeds of README's columns."""


def readme_results() -> str:
    """README's table: what the first command printed on seed 0 (``room_v3.csv``), and over seeds 0-4 and 5-9 the
    same command (``meta``) against its mover with the camera held forward, the fixed-camera baseline, their paired
    difference and random play."""
    printout = next(
        r for r in read("experiments/results/room_v3.csv") if (r["command"], r["seeds"]) == ("activeperc-train", "0")
    )
    columns = [[printout["success"], printout["camera_held"], "", "", printout["random"]]]
    held_rows = read(f"{V3_DEFAULT}/pan_vs_bearing.csv")
    for seeds in README_SEEDS:
        runs = [r for r in read(f"{V3_DEFAULT}/summary.csv") if r["fov"] == "60" and int(r["seed"]) in seeds]
        meta = [r for r in runs if r["method"] == "meta_eps0.3"]
        held = [r["success"] for r in held_rows if r["looker"] == "camera held" and run_seed(r["run"]) in seeds]
        _, mean, half = paired_difference(runs, "meta_eps0.3", 60)
        columns.append(
            [
                spread(r["final_success_rate"] for r in meta),
                spread(held),
                spread(r["final_success_rate"] for r in runs if r["method"] == "fixed_forward"),
                f"{mean:+.2f} ± {half:.2f}",
                spread(r["random_success_rate"] for r in meta),
            ]
        )
    names = [
        "`activeperc-train`: mover and looker",
        "its mover, camera held forward",
        "`--method fixed_forward`",
        "difference to `fixed_forward`, paired",
        "random play",
    ]
    frames = json.loads((ROOT / V3_DEFAULT / "sweep.json").read_text())["frames"]
    header = [f"room v3, 60°, {frames // 1000}k frames", "seed 0 (printed)", "seeds 0-4", "seeds 5-9"]
    return markdown(header, [[name, *cells] for name, *cells in zip(names, *columns, strict=True)])


def run_seed(run: str) -> int:
    """The seed of a run directory ``.../seedS``."""
    return int(run.rsplit("seed", 1)[1])


def v3_sweep(folder: str) -> str:
    """A room v3 sweep (``folder``) of ``meta --looker-credit best_look`` against ``fixed_forward``: results over
    seeds and the paired differences."""
    rows = read(f"{folder}/summary.csv")
    return summary_table(rows) + "\n" + difference_table(rows)


BUDGET = "experiments/results/budget.csv"


def fig1_budget() -> str:
    """What each Figure 1 method does with 1,000,000 frames (``experiments/fig1/budget.py``): each learner's
    updates and the frames they learn from."""
    rows = read(BUDGET)
    lines = [
        [
            f"`{r['method']}`",
            f"{int(r['frames_per_iteration']):,}",
            f"{int(r['mover_updates']):,}",
            f"{int(r['mover_frames']):,}",
            f"{int(r['looker_updates']):,}" if int(r["looker_updates"]) else "none",
            f"{int(r['looker_frames']):,}" if int(r["looker_updates"]) else "",
        ]
        for r in rows
    ]
    header = [
        "method",
        "frames an iteration",
        "mover updates",
        "frames they read",
        "looker updates",
        "frames they read",
    ]
    shape = {(r["num_envs"], r["rollout_length"]) for r in rows}
    note = "; ".join(f"{envs} rooms x {cycles} cycles a rollout" for envs, cycles in sorted(shape))
    return markdown(header, lines) + f"\nCommand: `python experiments/fig1/budget.py --csv {BUDGET}` ({note}).\n"


PRETRAINED = "experiments/results/pretrained.csv"


def pretrained() -> str:
    """The shipped policies' held-out success (``experiments/pretrained.py``), beside their runs' own evaluation."""
    rows = read(PRETRAINED)
    lines = [
        [
            f"`{r['policy']}`",
            f"`{r['trained_by']}`",
            f"{int(r['frames']):,}",
            f"{float(r['learned']):.2f} ({float(r['run_learned']):.2f})",
            f"{float(r['camera_held']):.2f}",
            f"{float(r['random']):.2f}",
        ]
        for r in rows
    ]
    header = ["policy", "trained by", "frames", "shipped (run)", "camera held forward", "random play"]
    episodes = {r["episodes"] for r in rows}
    return (
        markdown(header, lines)
        + f"\nHeld-out success on {'/'.join(sorted(episodes))} layouts (seed 0); in brackets, the run's float weights. "
        + f"Command: `{rows[0]['command']}`. "
        + provenance(rows)
    )


CLAIM_ROOMS = {"v3": f"{V3}/summary.csv", "v0": f"{FIG1}/summary.csv"}
"""The Figure 1 sweep of each room the paper's claims are judged in."""


def paper_claims() -> str:
    """Each of the paper's claims, its verdict in room v3 and in room v0 and the held-out success behind it, from each
    room's Figure 1 sweep (``aggregate.claims``)."""
    judged = [claims(read(path)) for path in CLAIM_ROOMS.values()]
    rows = [[claim, *(f"{room[i][1]}: {room[i][2]}" for room in judged)] for i, claim in enumerate(CLAIMS)]
    return markdown(["claim", "room v3, 1,000,000 frames", "room v0, 300,000 frames"], rows)


def portable_census() -> str:
    """What ``benchmarks/portable_bits.py --census`` counted under an emulated Haswell: per config and method, the
    distinct code addresses the run reached and those of instructions whose result the CPU model defines."""
    stored = json.loads((ROOT / "benchmarks/results/portable_bits.json").read_text())
    rows = []
    for config in ("portable", "unfused_adam"):
        for method, counts in stored[config]["emulated Haswell-v4"]["census"].items():
            defined = {k: v for k, v in counts.items() if k not in ("translated", "undecoded")}
            reached = ", ".join(f"`{name}` at {n}" for name, n in defined.items()) or "none"
            rows.append([f"`{config}`", method, f"{counts['translated']:,}", reached])
    return markdown(["config", "method", "distinct addresses reached", "CPU-defined instructions reached"], rows)


def portable_speed() -> str:
    """The table ``benchmarks/portable_speed.py`` printed into its committed output."""
    text = (ROOT / "benchmarks/results/cpu2/portable_speed.txt").read_text()
    return "".join(line + "\n" for line in text.splitlines() if line.startswith("|"))


def goal_visibility() -> str:
    """How often the goal is hidden at the start, as ``experiments/goal_visibility.py --csv`` wrote it."""

    def share(count: str, row: dict) -> str:
        return f"{int(count) / int(row['seeds']):.1%} ({count}/{row['seeds']})" if count else "-"

    rows = [
        [
            f"{float(r['fov']):g}",
            r["num_obstacles"] + (" (default)" if r["num_obstacles"] == "3" else ""),
            share(r["hidden_forward"], r),
            share(r["hidden_every_pan"], r),
            share(r["outside_view_cone"], r),
        ]
        for r in read("experiments/results/goal_visibility.csv")
    ]
    header = [
        "FOV (deg)",
        "occluders",
        "hidden, camera forward",
        "hidden at every pan angle",
        "geometry: goal outside the forward view cone",
    ]
    return markdown(header, rows)


BENCH = "benchmarks/results"
GOAL_COLUMNS = {  # (room, MiniWorld's llvmpipe setting): header
    ("v3", "LP_NUM_THREADS=0"): "v3 (the default room) against MiniWorld with our `LP_NUM_THREADS=0`",
    ("v3", "as it ships"): "v3 against MiniWorld as it ships",
    ("v3", "LP_NUM_THREADS=2"): "v3, ours and MiniWorld at `LP_NUM_THREADS=2`",
}
GOAL_SETTING = ("v3", "LP_NUM_THREADS=0")
"""The column the goals are judged in (bold): the default room, MiniWorld drawing as ours does."""


def runs_footer(rows: list[dict], lead: str = "Commands: ") -> str:
    """The commands of benchmark rows, each once, with the machines and dates it ran on and the outputs it printed,
    after ``lead``."""
    runs: dict[str, dict[tuple[str, str], dict[str, None]]] = {}
    for r in rows:
        outputs = runs.setdefault(r["command"], {}).setdefault((r["machine"], r["date"]), {})
        if r.get("output"):
            outputs[f"`{r['output']}`"] = None
    commands = [
        f"`{command}` "
        + " and ".join(
            f"({machine}, {date}" + "".join(f"; {o}" for o in outputs) + ")"
            for (machine, date), outputs in where.items()
        )
        for command, where in runs.items()
    ]
    return "\n" + lead + "; ".join(commands) + ".\n"


def times(value: str) -> str:
    """A ratio as the benchmarks print it: ``1.30x``."""
    return f"{float(value):.2f}x"


def goal_cell(row: dict | None) -> str:
    """A goal's ratio (bold in :data:`GOAL_SETTING`), its rounds, and the rates it is the ratio of."""
    if row is None:
        return "not run"
    ratio = times(row["ratio"])
    ratio = f"**{ratio}**" if (row["room"], row["peer"]) == GOAL_SETTING else ratio
    details = [", ".join(map(times, row["rounds"].split()))] if row["rounds"] else []
    if row["ours"]:
        against = f" against {int(row['miniworld']):,} steps/s" if row["miniworld"] else ""
        details.append(f"{int(row['ours']):,} {row['unit']}{against}")
    details += [row["note"]] if row["note"] else []
    return ratio + (f" ({'; '.join(details)})" if details else "")


def goals() -> str:
    """The 2-core goals: each goal in the default room against MiniWorld with its llvmpipe set as ours, as it ships and
    with both at two llvmpipe threads (rows of other rooms are left out)."""
    every = read(f"{BENCH}/cpu2/goals.csv")
    rows = [r for r in every if (r["room"], r["peer"]) in GOAL_COLUMNS]
    goals = dict.fromkeys(r["goal"] for r in every)
    cells = {(r["goal"], r["room"], r["peer"]): r for r in rows}
    lines = [[goal] + [goal_cell(cells.get((goal, *column))) for column in GOAL_COLUMNS] for goal in goals]
    return markdown(["goal (2 CPU cores)", *GOAL_COLUMNS.values()], lines) + runs_footer(rows)


def rooms_table(path: str) -> str:
    """Cycles/s of the TorchRL env by number of rooms (and against MiniWorld where it was timed)."""
    rows = read(path)
    lines = [["cycles/s (summed over rooms)"] + [f"{float(r['cycles_per_s']):,.0f}" for r in rows]]
    if rows[0]["miniworld_steps_per_s"]:
        peer = f"x MiniWorld ({float(rows[0]['miniworld_steps_per_s']):,.0f} steps/s)"
        lines.append([peer] + [f"{float(r['ratio']):.2f}" for r in rows])
    return markdown(["rooms N"] + [r["num_envs"] for r in rows], lines)


# the folders of benchmarks/results/h200/, each the code it measured
H200_RUNS = ("d7a6f27", "772515a", "7418c63", "21fc21d")


def h200_env() -> str:
    """Cycles/s of the TorchRL env on the H200 machine by number of rooms: the warp backend at the latest code, and the
    default backend."""
    runs = [("warp", H200_RUNS[-1], f"{H200_RUNS[-1]}/warp_env_scaling.csv")]
    runs.append(("mujoco (OpenGL on the GPU)", H200_RUNS[0], f"{H200_RUNS[0]}/opengl_env_scaling.csv"))
    lines = [
        [backend, f"`{code}`", f"{int(r['num_envs']):,}", f"{float(r['cycles_per_s']):,.0f}"]
        for backend, code, path in runs
        for r in read(f"{BENCH}/h200/{path}")
    ]
    return markdown(["backend", "code", "rooms", "cycles/s (summed over rooms)"], lines)


def h200_train() -> str:
    """`meta` training frames/s on the H200 machine by number of rooms: the warp backend at the latest code, and the
    default backend."""
    rows = [r for r in read(f"{BENCH}/h200/train.csv") if r["code"] == H200_RUNS[-1] or r["backend"] != "warp"]
    lines = [
        [
            r["backend"],
            f"`{r['code']}`",
            f"{int(r['rooms']):,}",
            f"{int(r['frames_per_s']):,}",
            f"{r['collect_percent']} %",
        ]
        for r in rows
    ]
    header = ["backend", "code", "rooms", "`meta` frames/s", "collection's share"]
    return markdown(header, lines) + runs_footer(rows)


def first_reached(points: dict, threshold: float) -> tuple | None:
    """The first of a curve's ``{frames: (minutes, success, half-width)}`` points whose mean success reaches
    ``threshold``, as ``(frames, point)``, or ``None``."""
    return next(((f, p) for f, p in points.items() if p[1] >= threshold), None)


def time_to_success() -> str:
    """Held-out success of the default command against training frames and minutes (``time_to_success.py``, the
    runs of :data:`TIME_TO_SUCCESS`): mean ± 95 % interval over the seeds every point has, per column, and where each
    threshold is first reached."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from time_to_success import THRESHOLDS, curve

    columns, commands = [], []
    for name, method, how in TIME_TO_SUCCESS:
        rows = [r for r in read(f"{BENCH}/cpu2/{name}") if r["method"] == method]
        seeds = sorted({r["seed"] for r in rows}, key=int)
        points = {frames: rest for frames, *rest in curve(rows, method)}
        columns.append((f"`{method}`, {count(len(seeds), 'seed')}, {how}", points))
        command = time_to_success_command(seeds, STEP, name, "" if method == "meta" else f"--method {method}")
        commands += [{"command": command} | r for r in rows]

    def cell(point) -> str:
        if point is None:
            return ""
        minutes, success, half = point
        return f"{spread_of(success, half)} ({minutes:.1f} min)"

    steps = sorted({step(frames) for _, points in columns for frames in points})
    nearest = [{step(f): p for f, p in points.items()} for _, points in columns]
    lines = [[f"{at:,}"] + [cell(points.get(at)) for points in nearest] for at in steps]
    for threshold in THRESHOLDS:
        firsts = []
        for _, points in columns:
            first = first_reached(points, threshold)
            firsts.append(f"{first[0]:,} frames, {first[1][0]:.1f} min" if first else "not reached")
        lines.append([f"first mean ≥ {threshold:.2f}", *firsts])
    return markdown(["frames"] + [label for label, _ in columns], lines) + runs_footer(commands)


DEFAULT_CURVES = "time_to_success_400k.csv"
"""The CSV of ``time_to_success.py`` that holds the default command's runs (and ``fixed_forward``'s beside them)."""
TIME_TO_SUCCESS = (  # (CSV, method, how its runs shared the machine)
    ("time_to_success_400k_alone.csv", "meta", "alone"),
    (DEFAULT_CURVES, "fixed_forward", "two at a time"),
)
"""The columns of :func:`time_to_success`: the default command's runs one at a time on both cores, beside
``fixed_forward``'s, two at a time, each on one core (``taskset``)."""
OLD_DEFAULT = f"--frames 600000 {OLD_SHAPE}"
"""The budget, run shape and schedule of the defaults before 2026-12-06."""
TWO_CORES = {"time_to_success.csv"}
"""The CSVs of ``time_to_success.py`` whose runs had both cores to themselves (the others ran two at a time)."""


RECIPE_OPTIONS = {  # column: (CSV of time_to_success.py, the method, the training flags)
    "constant, 16 x 16": ("time_to_success.csv", "meta", OLD_DEFAULT),
    "linear": ("time_to_success_lr_linear.csv", "meta", "--frames 600000 --num-envs 16 --rollout-length 16"),
    "linear, 32 x 8": ("time_to_success_lr_linear_32x8.csv", "meta", "--frames 600000"),
    "linear, 32 x 8, 400k (the default)": (DEFAULT_CURVES, "meta", ""),
}
"""The options of the recipe measured by ``time_to_success.py``, from the defaults before 2026-12-06 to today's."""
RECIPE_PAIRS = [
    ("linear", "constant, 16 x 16"),
    ("linear, 32 x 8", "linear"),
    ("linear, 32 x 8, 400k (the default)", "linear, 32 x 8"),
]
"""Each option beside the recipe it changes."""

MANY = "--num-envs 256 --rollout-length 8 --frames 1000000 --lr-schedule linear"
MANY_ROOMS = {  # as RECIPE_OPTIONS: benchmarks/gpu_learning.sh's first setting on the CPU, at two learning rates
    "256 x 8, lr 1.4e-3": ("time_to_success_256x8_lr0.0014.csv", "meta", f"{MANY} --lr 0.0014"),
    "256 x 8, lr 2.8e-3": ("time_to_success_256x8_lr0.0028.csv", "meta", f"{MANY} --lr 0.0028"),
}
"""The recipe for many rooms (a GPU's), tried first on the CPU: 256 rooms x 8 cycles a rollout, 2,048 frames an
update (32 x 8: 256)."""

LEVERS = {  # the flags added to the 400k recipe: its CSV of time_to_success.py (meta)
    "--looker-lr 0.001": "time_to_success_400k_looker_lr.csv",
    "--looker-steps 4": "time_to_success_400k_looker_steps.csv",
    "--mirror-looks": "time_to_success_400k_mirror.csv",
    "--epsilon 0.1": "time_to_success_400k_epsilon0.1.csv",
    "--e2-rooms 16": "time_to_success_400k_e2_rooms16.csv",
    "--e2-rooms 8": "time_to_success_400k_e2_rooms8.csv",
    "--looker-encoder own_bearing": "time_to_success_400k_looker_encoder_own_bearing.csv",
    "--looker-encoder mover": "time_to_success_400k_looker_encoder_mover.csv",
    "--alpha 1.0": "time_to_success_400k_alpha1.csv",
    "--lr 0.0014": "time_to_success_400k_lr0.0014.csv",
    "--mover-rollouts each": "time_to_success_400k_each.csv",
    "--num-envs 16": "time_to_success_400k_envs16.csv",
}
"""The default recipe with ``phi2`` stepped at a larger learning rate, or four times on each D2; with the looks valued
as in a mirror too; with fewer random looks in E2; with E2 in fewer rooms than E1, which gives the mover more updates
a frame; with ``phi2`` reading its view through the bearing layout, or through the mover's encoder; with ``phi1``
a copy of ``phi2`` at every soft update (no lag); and three that give the mover larger or more steps a frame: twice its
learning rate, one step on each rollout, half the rooms."""
LEVER_POINTS = (200_000, 400_000)
SWAP = "experiments/results/looker_swap.csv"

STEP = 100_000
"""The frames between two scores of the recipe tables' runs (``--every``): a point is named by the step it passed."""


def recipe_options() -> str:
    """The options of :data:`RECIPE_OPTIONS` (see :func:`recipe_table`)."""
    return recipe_table(RECIPE_OPTIONS, RECIPE_PAIRS)


def recipe_levers() -> str:
    """Each of :data:`LEVERS`: held-out success at :data:`LEVER_POINTS`, mean ± 95 % interval over its seeds, its
    paired difference to the 400k recipe at the last of them, and its CSV (one command for all, with each row's seeds,
    CSV and flags)."""
    base, method = DEFAULT_CURVES, "meta"
    names = {"": base} | LEVERS
    runs = {flags: [r for r in read(f"{BENCH}/cpu2/{name}") if r["method"] == method] for flags, name in names.items()}
    success = {
        flags: {(r["seed"], step(int(r["frames"]))): float(r["success_rate"]) for r in rows}
        for flags, rows in runs.items()
    }
    last = LEVER_POINTS[-1]
    lines, where = [], {}
    for flags, points in success.items():
        seeds = sorted({seed for seed, _ in points}, key=int)
        if seeds != [str(s) for s in range(len(seeds))]:
            raise ValueError(f"{names[flags]}: seeds {seeds}, not 0 to {len(seeds) - 1}")
        cells = [spread(points[seed, at] for seed in seeds) for at in LEVER_POINTS]
        paired = mean_ci([points[seed, last] - success[""][seed, last] for seed in seeds])
        name = f"`{flags}`" if flags else "none (the default)"
        difference = spread_of(*paired, "+.2f") if flags else ""
        lines.append([name, f"0-{seeds[-1]}", *cells, difference, f"`{names[flags]}`"])
        where.update({(r["machine"], r["date"]): None for r in runs[flags]})
    header = ["flags added", "seeds", *(f"{at:,} frames" for at in LEVER_POINTS), f"difference at {last:,}, by seed"]
    header.append("CSV")
    command = time_to_success_command(["SEEDS"], STEP, "CSV", "FLAGS")
    dates: dict[str, list[str]] = {}
    for machine, date in where:
        dates.setdefault(machine, []).append(date)
    machines = "; ".join(f"{machine}, {' and '.join(days)}" for machine, days in dates.items())
    return markdown(header, lines) + f"\nCommand: `{command}` ({machines}); one core each, two at a time.\n"


def many_rooms() -> str:
    """The runs of :data:`MANY_ROOMS` (see :func:`recipe_table`)."""
    return recipe_table(MANY_ROOMS, [])


def looker_swap() -> str:
    """The default's movers scored with lookers that mix ``phi1`` with the tracking looker
    (``experiments/looker_swap.py``): mean ± 95 % interval over the runs, and the paired difference to ``phi1``."""
    rows = read(SWAP)
    runs = list(dict.fromkeys(r["run"] for r in rows))
    success = {(r["run"], r["looker"]): float(r["success_rate"]) for r in rows}
    lines = []
    for looker in dict.fromkeys(r["looker"] for r in rows):
        paired = [success[run, looker] - success[run, "phi1"] for run in runs]
        own = spread(success[run, looker] for run in runs)
        lines.append([looker, own, spread_of(*mean_ci(paired), "+.2f") if looker != "phi1" else ""])
    command = f"python experiments/looker_swap.py {braced(runs)} --csv {SWAP}"
    header = ["looker", "held-out success", "difference to `phi1`, by run"]
    return markdown(header, lines) + runs_footer([{"command": command} | r for r in rows])


SWAP_FIG1 = ("experiments/results/looker_swap_fig1_v3.csv", "experiments/results/looker_swap_fig1_v3_seed2.csv")
"""One CSV a seed: looker_swap.py swaps the lookers of the runs it is given, so each call gets one seed's runs."""


def run_label(run: str) -> str:
    """A Figure 1 sweep's run directory (``RUNS/CONFIG_fovF/seedS``) as ``CONFIG seed S``."""
    config, seed = run.rstrip("/").split("/")[-2:]
    return f"{config.rsplit('_fov', 1)[0]} {seed.replace('seed', 'seed ')}"


def looker_swap_fig1() -> str:
    """Figure 1's movers, each with its own looker, the tracking looker and the lookers of the other runs of its seed
    (``experiments/looker_swap.py --lookers-of``): held-out success, one row a mover."""
    per_csv = {path: read(path) for path in SWAP_FIG1}
    rows = [row for path_rows in per_csv.values() for row in path_rows]
    runs = list(dict.fromkeys(r["run"] for r in rows))
    success = {(r["run"], r["looker"]): f"{float(r['success_rate']):.2f}" for r in rows}

    def others(run: str) -> str:
        swapped = [r for r in rows if r["run"] == run and r["looker"].startswith("looker of ")]
        return ", ".join(
            f"{run_label(r['looker'].removeprefix('looker of ')).split(' seed ')[0]} {success[run, r['looker']]}"
            for r in swapped
        )

    lines = [
        [run_label(run), success.get((run, "phi1"), ""), success.get((run, "track"), ""), others(run)] for run in runs
    ]
    episodes = "/".join(sorted({r["episodes"] for r in rows}))
    command = f"python experiments/looker_swap.py RUNS --lookers-of RUNS --episodes {episodes} --csv CSV"
    calls = "; ".join(
        f"`{braced(list(dict.fromkeys(r['run'] for r in path_rows)))}` into `{path}`"
        for path, path_rows in per_csv.items()
    )
    header = ["mover", "its own looker", "track looker", "the looker of its seed's run of"]
    footer = runs_footer([{"command": command} | r for r in rows], f"One seed's RUNS at a time: {calls}. Command: ")
    return markdown(header, lines) + footer


BEST_LOOK_FIG1 = "experiments/results/best_look_fig1_v3.csv"


def lookers_fig1(path: str, columns: dict[str, str], paired: dict[str, str]) -> str:
    """Figure 1's movers at 60 degrees with each looker of ``columns`` (``experiments/looker_swap.py``'s name: its
    header), from that script's CSV ``path``: mean ± 95 % interval over a method's runs; then, for each looker of
    ``paired``, its paired difference to the run's own looker."""
    rows = read(path)
    success = {(r["run"], r["looker"]): float(r["success_rate"]) for r in rows}
    by_method: dict[str, list[str]] = {}
    for run in dict.fromkeys(r["run"] for r in rows):
        by_method.setdefault(run_label(run).split(" seed ")[0], []).append(run)
    lines = []
    for method, runs in by_method.items():
        seeds = ", ".join(run_label(run).split(" seed ")[1] for run in runs)
        cells = [spread(success[run, looker] for run in runs) for looker in columns]
        for looker in paired:
            cells.append(spread_of(*mean_ci([success[run, looker] - success[run, "phi1"] for run in runs]), "+.2f"))
        lines.append([f"`{method}`", seeds, *cells])
    runs = list(dict.fromkeys(r["run"] for r in rows))
    episodes = "/".join(sorted({r["episodes"] for r in rows}))
    lookers = " ".join(f'"{name}"' if " " in name else name for name in columns)
    command = f"python experiments/looker_swap.py {braced(runs)} --lookers {lookers} --episodes {episodes} --csv {path}"
    header = ["mover", "seeds", *columns.values(), *paired.values()]
    return markdown(header, lines) + runs_footer([{"command": command} | r for r in rows])


def best_look_fig1() -> str:
    """Figure 1's movers with their own looker, their critic's best look (the label of meta's ``best_look`` credit,
    taken as the look) and the tracking looker."""
    columns = {"phi1": "its own looker", "critic's best look": "its critic's best look", "track": "track looker"}
    return lookers_fig1(BEST_LOOK_FIG1, columns, {"critic's best look": "best look − own, by run"})


SEARCH_FIG1 = "experiments/results/looker_search_fig1_v3.csv"


def looker_search_fig1() -> str:
    """Figure 1's movers with their own looker split into what it does while the goal is in its view and while it is
    not: each half kept, the other held, panned at random or replaced by the tracking looker."""
    columns = {
        "phi1": "its own looker",
        "phi1 in view, hold out of view": "own in view, hold out of view",
        "phi1 in view, random pan out of view": "own in view, random pans out of view",
        "track in view, phi1 out of view": "track in view, own out of view",
    }
    paired = {
        "phi1 in view, random pan out of view": "random out − own",
        "track in view, phi1 out of view": "track in − own",
    }
    return lookers_fig1(SEARCH_FIG1, columns, paired)


VIEW_FIG1 = "experiments/results/pan_vs_bearing_fig1_v3.csv"


def looker_view_fig1() -> str:
    """Where Figure 1's lookers at 60 degrees point the camera (``experiments/pan_vs_bearing.py``), one row a run: its
    held-out success, pan rate and how often the goal is in the mover's view, ahead (inside the forward field of view)
    and to the side."""
    rows = sorted((r for r in read(VIEW_FIG1) if r["looker"] == "learned"), key=lambda r: run_label(r["run"]))
    columns = ("success", "pan_rate", "goal_in_view", "in_view_inside_fov", "in_view_outside_fov")
    lines = [[run_label(r["run"]), *(f"{float(r[column]):.2f}" for column in columns)] for r in rows]
    episodes = "/".join(sorted({r["episodes"] for r in rows}))
    command = f"python experiments/pan_vs_bearing.py RUN --episodes {episodes} --csv {VIEW_FIG1}"
    runs = braced(sorted({r["run"] for r in rows}))
    header = ["run (60 degrees)", "held-out success", "pan rate", "goal in view", "goal ahead: in view", "to the side"]
    return markdown(header, lines) + runs_footer([{"command": command} | r for r in rows], f"Each RUN of `{runs}`: ")


LOOK_VALUES_FIG1 = "experiments/results/look_values_fig1_v3.csv"
LOOK_VALUE_COLUMNS = (
    "gain_left", "gain_right", "best_left", "best_right", "greedy_left", "greedy_hold", "greedy_right",
)  # fmt: skip


def look_values_fig1() -> str:
    """What ``meta``'s critic says each look is worth and what its ``phi2`` picks (``experiments/look_values.py``), by
    where the goal is in the looker's view: the means over the runs of the groups' shares of the looks, the critic's
    gain of each pan over holding, its labels (the best look) and ``phi2``'s greedy looks."""
    rows = read(LOOK_VALUES_FIG1)
    runs = list(dict.fromkeys(r["run"] for r in rows))
    totals = {run: sum(int(r["looks"]) for r in rows if r["run"] == run) for run in runs}
    for r in rows:
        r["share"] = int(r["looks"]) / totals[r["run"]]
        r["best_hold"] = 1 - float(r["best_left"]) - float(r["best_right"])
    lines = []
    for group in dict.fromkeys(r["goal_in_s_bar"] for r in rows):
        of = [r for r in rows if r["goal_in_s_bar"] == group]
        mean = {key: sum(float(r[key]) for r in of) / len(of) for key in (*LOOK_VALUE_COLUMNS, "share", "best_hold")}
        labels, greedy = ([mean[f"{what}_{u}"] for u in ("left", "hold", "right")] for what in ("best", "greedy"))
        gains = f"{mean['gain_left']:+.3f} / {mean['gain_right']:+.3f}"
        shares = (" / ".join(f"{x:.2f}" for x in values) for values in (labels, greedy))
        lines.append([group, f"{mean['share']:.2f}", gains, *shares])
    seeds = ", ".join(run_label(run).split(" seed ")[1] for run in runs)
    header = [f"goal in the looker's view (`meta_eps0.3`, seeds {seeds})", "share of looks"]
    header += ["Q(left) − Q(hold) / Q(right) − Q(hold)", "best look: left / hold / right", "`phi2`'s argmax: same"]
    command = f"python experiments/look_values.py RUN --csv {LOOK_VALUES_FIG1}"
    lead = f"Each RUN of `{braced(runs)}`: "
    return markdown(header, lines) + runs_footer([{"command": command} | r for r in rows], lead)


REFIT_FIG1 = "experiments/results/looker_refit_fig1_v3.csv"
REFIT_MEMORY_FIG1 = "experiments/results/looker_refit_memory_fig1_v3.csv"


def looker_refit_fig1(path: str = REFIT_FIG1, shown: tuple[str, ...] = ()) -> str:
    """``meta``'s movers of Figure 1 with ``phi2``, ``phi1``, copies of ``phi2`` refitted on fresh labels and untrained
    lookers fitted on them (``experiments/looker_refit.py --episodes``; ``shown``: only these lookers, by name
    prefix): agreement with the labels on held-out cycles and held-out success, mean ± 95 % interval over the runs,
    and the paired difference of success to ``phi1``'s."""
    rows = read(path)
    runs = list(dict.fromkeys(r["run"] for r in rows))
    lookers = list(dict.fromkeys((r["looker"], r["steps"], r["lr"]) for r in rows))
    by = {(r["run"], r["looker"], r["steps"], r["lr"]): r for r in rows}
    lines = []
    for looker in (looker for looker in lookers if not shown or looker[0].startswith(shown)):
        name, steps, lr = looker
        if name.startswith("fresh"):  # "fresh, 4 views": an untrained looker fitted on the same labels
            label = f"untrained, {name.split(', ')[1]}, {steps} steps"
        else:
            label = f"`{name}` refitted, {steps} steps at {lr}" if int(steps) else f"`{name}`"
        of = [by[(run, *looker)] for run in runs]
        paired = [
            float(r["success_rate"]) - float(by[run, "phi1", "0", ""]["success_rate"])
            for r, run in zip(of, runs, strict=True)
        ]
        difference = spread_of(*mean_ci(paired), "+.2f") if looker != ("phi1", "0", "") else ""
        lines.append([label, spread(r["agreement"] for r in of), spread(r["success_rate"] for r in of), difference])
    seeds = ", ".join(run_label(run).split(" seed ")[1] for run in runs)
    episodes = "/".join(sorted({r["episodes"] for r in rows}))
    frames = sorted({int(r["looker"].split(", ")[1].split()[0]) for r in rows if r["looker"].startswith("fresh")})
    options = f" --fresh-frames {' '.join(map(str, frames))}" if frames else ""
    rates = sorted({r["lr"] for r in rows if r["lr"]}, key=float)
    options += f" --lr {' '.join(rates)}" if rates != ["0.0003", "0.001"] else ""
    command = f"python experiments/looker_refit.py {braced(runs)}{options} --episodes {episodes} --csv {path}"
    header = [f"looker (`meta_eps0.3`, 60 degrees, seeds {seeds})", "agreement with its labels", "held-out success"]
    header.append("success − `phi1`'s, by run")
    return markdown(header, lines) + runs_footer([{"command": command} | r for r in rows])


def braced(paths: list[str]) -> str:
    """``paths`` as one shell word, the part where they differ in braces (``runs/seed{0,1,2}``,
    ``runs/{meta,ia2c}/seed1``); one path as it is."""
    if len(paths) < 2:
        return " ".join(paths)
    prefix = os.path.commonprefix(paths)
    shortest = min(len(path) for path in paths) - len(prefix)
    suffix = os.path.commonprefix([path[::-1] for path in paths])[::-1][-shortest:] if shortest else ""
    middles = ",".join(path[len(prefix) : len(path) - len(suffix)] for path in paths)
    return f"{prefix}{{{middles}}}{suffix}"


def time_to_success_command(seeds: list[str], every: int, name: str, flags: str) -> str:
    """The ``time_to_success.py`` command that measured ``meta``'s (or ``flags``' method's) runs of ``seeds`` into the
    CSV ``name`` of ``benchmarks/results/cpu2`` (the runs of today's defaults were made with these defaults as
    flags: ``--frames 400000 --lr-schedule linear --num-envs 32 --rollout-length 8``)."""
    command = (
        f"python benchmarks/time_to_success.py --seeds {' '.join(seeds)} --every {every} --reference none"
        f" --csv {BENCH}/cpu2/{name}"
    )
    return command + (f" -- {flags}" if flags else "")


def recipe_table(options: dict[str, tuple[str, str, str]], pairs: list[tuple[str, str]]) -> str:
    """Held-out success against training frames for each of ``options``, mean ± 95 % interval over seeds (with the
    mean minutes of training of the runs made one core each), the paired differences by seed of ``pairs``, and the
    frames and minutes at which each first reaches a threshold."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from time_to_success import THRESHOLDS, curve

    rows = {}
    for label, (name, method, _) in options.items():
        rows[label] = [r for r in read(f"{BENCH}/cpu2/{name}") if r["method"] == method]
    one_core = [label for label, (name, _, _) in options.items() if name not in TWO_CORES]
    curves = {label: {f: rest for f, *rest in curve(rows[label], options[label][1])} for label in options}
    points = {label: {step(f): p for f, p in curves[label].items()} for label in options}
    success = {
        label: {(r["seed"], step(int(r["frames"]))): float(r["success_rate"]) for r in rows[label]} for label in rows
    }

    def cell(label: str, at: int) -> str:
        if at not in points[label]:
            return ""
        minutes, mean, half = points[label][at]
        return spread_of(mean, half) + (f" ({minutes:.1f} min)" if label in one_core else "")

    def paired(label: str, other: str, at: int) -> str:
        seeds = [seed for seed, where in success[label] if where == at and (seed, at) in success[other]]
        if not seeds:
            return ""
        mean, half = mean_ci([success[label][s, at] - success[other][s, at] for s in seeds])
        return spread_of(mean, half, "+.2f") + (f" ({count(len(seeds), 'seed')})" if len(seeds) < 5 else "")

    lines = []
    for at in sorted(set().union(*(set(p) for p in points.values()))):
        cells = [cell(label, at) for label in options]
        lines.append([f"{at:,}", *cells, *(paired(label, other, at) for label, other in pairs)])
    for threshold in THRESHOLDS:
        firsts = []
        for label in options:
            first = first_reached(curves[label], threshold)
            if first is None:
                firsts.append("not reached")
            else:
                firsts.append(f"{first[0]:,} frames" + (f", {first[1][0]:.1f} min" if label in one_core else ""))
        lines.append([f"first mean ≥ {threshold:.2f}", *firsts, *([""] * len(pairs))])
    seeds = {label: len({r["seed"] for r in rows[label]}) for label in options}
    names = [label + (f" ({count(seeds[label], 'seed')})" if seeds[label] < 5 else "") for label in options]
    header = ["frames (first past)", *names, *(f"{label} − {other}, by seed" for label, other in pairs)]
    commands = []
    for label in options:
        name, _, flags = options[label]
        seeds = sorted({r["seed"] for r in rows[label]})
        every = step(min(int(r["frames"]) for r in rows[label]))  # the first score's step
        command = time_to_success_command(seeds, every, name, flags)
        commands += [{"command": command} | r for r in rows[label]]
    footer = runs_footer(commands).removesuffix(".\n")
    alone = "".join(f"; {label}: one run at a time on both cores" for label in options if label not in one_core)
    rest = "the others two at a time" if alone else "two runs at a time"
    return markdown(header, lines) + footer + alone + f"; {rest}, each on one core (`taskset`).\n"


def spread_of(mean: float, half: float, form: str = ".2f") -> str:
    """``mean ± half`` (the mean alone where one value gave no interval)."""
    return f"{mean:{form}}" + ("" if math.isnan(half) else f" ± {half:.2f}")


def count(n: int, noun: str) -> str:
    """``1 seed``, ``2 seeds``."""
    return f"{n} {noun}" + ("s" if n != 1 else "")


def step(frames: int) -> int:
    """The step of :data:`STEP` frames that a score at ``frames`` (the first iteration past it) stands for."""
    return frames // STEP * STEP


def speed_of_variants(report_name: str, variants: dict[str, str]) -> str:
    """Training frames/s of each method in the ``train_speed.py --out`` report ``report_name`` as each of two
    ``variants`` ran it (the suffix of its label in the report: its options, or ``""``: as the recipe has it, each
    with its name in the table), in the same rounds, the first's gain over the second by round; then where an
    iteration goes, in milliseconds."""
    report = json.loads((ROOT / BENCH / "cpu2" / report_name).read_text())
    runs = report["methods"]
    methods = [label for label in runs if "[" not in label]
    lines = []
    for label in methods:
        pair = [runs[label + suffix] for suffix in variants]
        gains = [a / b for a, b in zip(*(r["frames_per_s_rounds"] for r in pair), strict=True)]
        rates = [f"{r['frames_per_s']:,.0f}" for r in pair]
        lines.append([f"`{label}`", *rates, ", ".join(f"{g:.2f}x" for g in gains)])
    speed = markdown(["method", *(f"frames/s, {name}" for name in variants.values()), "gain, by round"], lines)

    def per_iteration(result: dict, seconds: float) -> str:
        return f"{1e3 * seconds / result['iterations']:.0f}"

    parts = [
        (PART_NAMES[part], lambda r, part=part: r["parts_s"][part]) for part in next(iter(runs.values()))["parts_s"]
    ]
    parts += [
        ("collection, the rest (TorchRL, tensordict, sampling)", lambda r: r["collect_s"] - sum(r["parts_s"].values())),
        ("learning (losses, backward passes, optimizers)", lambda r: r["learn_s"]),
        ("the iteration", lambda r: r["seconds"]),
    ]
    columns = [(f"`{label}`, {name}", runs[label + suffix]) for label in methods for suffix, name in variants.items()]
    rows = [[name] + [per_iteration(r, get(r)) for _, r in columns] for name, get in parts]
    machine = f"{report['machine']['usable_cpus']}-core {report['cpu']}"
    footer = runs_footer([{"command": report["command"], "machine": machine, "date": report["date"]}])
    return speed + "\n" + markdown(["ms per iteration", *(name for name, _ in columns)], rows) + footer


PART_NAMES = {
    "move": "physics",
    "look": "the looks",
    "reset": "resets",
    "render": "renders",
    "look_views": "the looks' views (E2, for `best_look`)",
    "forward": "network forward passes in collection",
}


def train_flags() -> str:
    """``activeperc-train``'s flags as its ``--help`` gives them: each flag, its default and its meaning."""
    from activeperc_rl.cli import build_parser

    rows = []
    for action in build_parser()._actions:
        if action.dest == "help":
            continue
        meaning, given, default = action.help.replace("%%", "%").partition(" (default: ")
        default = f"`{default.removesuffix(')')}`" if given else "off" if action.nargs == 0 else "none"
        rows.append([", ".join(f"`{flag}`" for flag in action.option_strings), default, meaning])
    return markdown(["flag", "default", "meaning"], rows)


def method_options() -> str:
    """Which method reads each method option, from the methods' option classes."""
    from activeperc_rl.methods import METHODS
    from activeperc_rl.recipe import METHOD_OPTIONS

    rows = [
        [f"`--{option.replace('_', '-')}`"] + ["yes" if method in readers else "" for method in METHODS]
        for option, readers in METHOD_OPTIONS.items()
    ]
    return markdown(["flag", *(f"`{method}`" for method in METHODS)], rows)


def value_of_looking(name: str) -> str:
    """``experiments/results/NAME.csv``'s scripted pairs; the oracle and random movers, which never read the image,
    with the fixed camera only (their rows are the same with every looker)."""
    rows = read_looking(ROOT / f"experiments/results/{name}.csv")
    return looking_table([r for r in rows if r["mover"] == "vision" or r["looker"] == "fixed"]) + "\n"


def version_history() -> str:
    """The rooms' version history, from their records (activeperc_env/rooms/)."""
    from activeperc_env.rooms import version_history

    return version_history(markdown=True) + "\n"


SECTIONS = {  # marker: (document in docs/, the function that makes its table)
    "version-history": ("env.md", version_history),
    "train-flags": ("training.md", train_flags),
    "method-options": ("training.md", method_options),
    "goal-visibility": ("results.md", goal_visibility),
    "value-of-looking-v3": ("results.md", lambda: value_of_looking("value_of_looking_v3")),
    "fig1-v3": ("results.md", fig1_v3),
    "fig1-v3-vs-meta": ("results.md", lambda: difference_table(read(f"{V3}/summary.csv"), *V3_AGAINST)),
    "readme-results": ("../README.md", readme_results),
    "room-v3-default": ("results.md", lambda: v3_sweep(V3_DEFAULT)),
    "fig1-budget": ("results.md", fig1_budget),
    "pretrained": ("training.md", pretrained),
    "room-v3": ("results.md", lambda: runs_table("room_v3", ["command", "held-out"])),
    "paper-claims": ("results.md", paper_claims),
    "portable-census": ("training.md", portable_census),
    "portable-speed": ("performance.md", portable_speed),
    "fig1-summary": ("results.md", lambda: summary_table(read(f"{FIG1}/summary.csv"))),
    "fig1-v3-ablations": ("results.md", fig1_v3_ablations),
    "goals": ("performance.md", goals),
    "time-to-success": ("performance.md", time_to_success),
    "recipe-options": ("performance.md", recipe_options),
    "looker-swap": ("performance.md", looker_swap),
    "looker-swap-fig1": ("results.md", looker_swap_fig1),
    "best-look-fig1": ("results.md", best_look_fig1),
    "looker-search-fig1": ("results.md", looker_search_fig1),
    "looker-view-fig1": ("results.md", looker_view_fig1),
    "look-values-fig1": ("results.md", look_values_fig1),
    "looker-refit-fig1": ("results.md", looker_refit_fig1),
    "looker-memory-fig1": ("results.md", lambda: looker_refit_fig1(REFIT_MEMORY_FIG1, ("phi1", "fresh"))),
    "recipe-levers": ("performance.md", recipe_levers),
    "many-rooms": ("performance.md", many_rooms),
    "default-speed": (
        "performance.md",
        lambda: speed_of_variants(
            "train_speed_v3.json", {"": "`reuse_features`", " [reuse_features=False]": "TorchRL's `A2CLoss`"}
        ),
    ),
    "env-scaling": ("performance.md", lambda: rooms_table(f"{BENCH}/env_scaling.csv")),
    "h200-warp-env": ("performance.md", h200_env),
    "h200-warp-train": ("performance.md", h200_train),
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
