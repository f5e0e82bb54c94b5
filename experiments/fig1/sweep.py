"""Run the Figure 1 sweep: every method at both fields of view, several seeds, one frame budget.

Each (config, seed) is one ``activeperc-train`` run in its own process, in ``RUNS/CONFIG/seedS``
(checkpoints, TensorBoard, the full metrics.csv and the process's log ``train.log``). Configs are whole presets,
one folder per room: ``configs/ROOM/NAME_fovF.yaml`` (``configs/ROOM/ablations/`` with ``--ablations``), ``--room v3``
(the default room, the default) or ``--room v0`` (the paper-faithful room of the pilot); every run gets the same
``--frames``.

When a run has finished, its training curve is exported to ``RESULTS/runs/CONFIG_seedS.csv`` (frames, episodes
finished so far, success_rate, mean_return; at most 200 rows) and its row is merged into ``RESULTS/summary.csv``
(``RESULTS/ablations.csv`` for the ablations): the final checkpoint's evaluation on
``--eval-episodes`` held-out episodes, beside a uniformly random mover and looker on the same ones.

Resumable: run the same command again and finished runs are skipped, interrupted ones continue from
their checkpoint, and a larger ``--frames`` with a new ``--results`` folder continues finished runs to the new
budget. A run counts as finished when its ``eval.json`` is of its last logged frames (not of an earlier budget
it was continued from), of ``--frames`` or more, over ``--eval-episodes`` episodes. A results folder holds one
budget: its ``sweep.json`` pins ``--frames``, ``--eval-episodes``, the configs' folder and any options after ``--``
(and lists the CPUs that ran it: outside ``--portable``, runs repeat on the same kind of CPU only), and a sweep with
others is refused (so the committed pilot's rows are never replaced by another budget's, nor averaged with runs
of other options); a run directory continued to a larger budget is skipped by a sweep of a smaller one (its
runs of that budget are gone). Ctrl-C stops every run cleanly (each saves its checkpoint first; a second Ctrl-C
aborts them at once), and so do a SIGTERM and the SIGHUP of a closing terminal (a sweep started in the
background by a script ignores Ctrl-C, as any Python program does there: send SIGTERM). Two sweeps cannot run
on the same ``--runs`` folder at once (a lock file refuses the second).

Cores: the machine's CPUs are split into ``--jobs`` groups of ``--cores-per-job`` (default 1 core per
run, as many runs at once as cores) and each run is pinned to its group, so its physics threads and its
learner use that group only. Each run uses the GPU when one is present (``device: auto``).

Examples (from the repository root)::

    python experiments/fig1/sweep.py --seeds 0 1 2 3 4              # Figure 1 in the default room, 1,000,000 frames
    python experiments/fig1/sweep.py --room v0 --seeds 0 1 2 3 4    # the committed CPU pilot's runs (300,000 frames)
    python experiments/fig1/sweep.py --room v0 --frames 2000000 --seeds 0 1 2 --cores-per-job 2 \
        --results experiments/fig1/results/frames2m
    python experiments/fig1/sweep.py --only meta_eps0.3_fov60 --seeds 0 --runs /tmp/envs32 \
        --results /tmp/envs32/results -- --num-envs 32
    python experiments/fig1/sweep.py --room v0 --ablations --seeds 0 1 2

Arguments after ``--`` go to every ``activeperc-train`` call (a variant of the presets), a method's option to the runs
of the methods that have it only.
Then ``python experiments/fig1/aggregate.py --results RESULTS`` (the same folder) draws the curves and prints the
table; for the committed folder it updates docs/results.md and docs/figures.
"""

from __future__ import annotations

import argparse
import csv
import fcntl
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from activeperc_env.checks import is_seed
from activeperc_env.core import usable_cpus
from activeperc_rl import cli
from activeperc_rl.config import load_yaml
from activeperc_rl.recipe import METHOD_OPTIONS, TrainConfig
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.atomic import atomic_path
from activeperc_rl.runtime.checkpoint import CHECKPOINT, CONFIG, EVAL, METRICS, load_checkpoint
from activeperc_rl.runtime.rundir import run_files
from activeperc_rl.runtime.signals import stop_raises_interrupt

HERE = Path(__file__).resolve().parent
CONFIGS = HERE / "configs"
ROOMS = {"v3": (HERE.parent / "results" / "v3", 1_000_000), "v0": (HERE / "results", 300_000)}
"""Each room's folder of presets (``configs/ROOM``): its results folder and frame budget (room v3's runs of the
defaults before 2026-12-06 are in ``experiments/results/v3_bearing``)."""
METHODS = ("meta_eps0.1", "meta_eps0.3", "fixed_forward", "joint", "ia2c", "curriculum")
"""The paper's methods, in the order the sweep runs and the figures list them."""
SUMMARY_COLUMNS = (
    "method",
    "fov",
    "seed",
    "frames",
    "final_success_rate",
    "final_return",
    "random_success_rate",
    "random_return",
    "train_minutes",
    "machine",
)
"""Columns of a summary row; ``machine`` (:func:`~activeperc_rl.runtime.portable.machine` of the sweep that exported
the run) is empty in rows exported before it was recorded."""
NUMBERS = SUMMARY_COLUMNS[1:-1]
"""The summary columns that hold numbers (every one required)."""
CURVE_COLUMNS = ("frames", "episodes", "success_rate", "mean_return")
"""Columns of an exported curve; ``episodes`` counts the training episodes finished so far."""
CURVE_ROWS = 200
SETTINGS = "sweep.json"
"""The file of a results folder that pins the settings its rows were made with (:func:`check_settings`)."""
POLL_S = 1.0


@dataclass(frozen=True)
class Task:
    """One run of the sweep: a config file and a seed."""

    config: Path
    seed: int

    @property
    def name(self) -> str:
        """The config's name, ``METHOD_fovF`` (the run's folder name)."""
        return self.config.stem

    @property
    def method(self) -> str:
        """The method's name in the results (``meta_eps0.1``, ``fixed_forward``, an ablation's name, ...)."""
        return self.name.rsplit("_fov", 1)[0]

    @property
    def fov(self) -> int:
        """The horizontal field of view in the config's name."""
        return int(self.name.rsplit("_fov", 1)[1])

    @property
    def label(self) -> str:
        """``CONFIG_seedS``, the run's name in the results."""
        return f"{self.name}_seed{self.seed}"

    def run_dir(self, runs: Path) -> Path:
        """Where the run's files go."""
        return runs / self.name / f"seed{self.seed}"


def find_configs(ablations: bool = False, only: list[str] | None = None, root: Path = CONFIGS / "v3") -> list[Path]:
    """The sweep's config files in the room folder ``root``, in the paper's method order and field of view 60 before
    100.

    ``only`` keeps the configs with those names (``ValueError`` naming any that does not exist).
    """
    folder = root / "ablations" if ablations else root
    paths = [p for p in folder.glob("*.yaml") if "_fov" in p.stem]
    if not paths:
        raise ValueError(f"no NAME_fovF.yaml config in {str(folder)!r}")

    def order(path: Path) -> tuple:
        task = Task(path, 0)
        return method_rank(task.method), task.fov, task.name

    paths.sort(key=order)
    if only:
        names = {p.stem: p for p in paths}
        missing = sorted(set(only) - set(names))
        if missing:
            elsewhere = root if ablations else root / "ablations"
            hint = ""
            if all((elsewhere / f"{name}.yaml").is_file() for name in missing):
                hint = " (Figure 1's configs: drop --ablations)" if ablations else " (ablations: add --ablations)"
            raise ValueError(f"--only {missing}: no such config; known: {sorted(names)}{hint}")
        paths = [p for p in paths if p.stem in only]
    return paths


def is_finished(run_dir: Path, frames: int, eval_episodes: int) -> bool:
    """Whether the run's final evaluation (``eval.json``) is of its last logged frames, ``frames`` or more of
    them, over ``eval_episodes`` episodes (not a stale one of a budget the run was continued from since)."""
    path = run_dir / EVAL
    if not path.is_file():
        return False
    try:
        evaluation = json.loads(path.read_text())
        evaluated = int(evaluation["frames"])
        episodes = evaluation["learned"]["episodes"]
    except (ValueError, KeyError, TypeError) as error:
        raise ValueError(
            f"{path} is not an evaluation activeperc-train wrote ({error!r}): delete it to evaluate the run again"
        ) from None
    return evaluated >= frames and evaluated == last_logged_frames(run_dir) and episodes == eval_episodes


def continued_past(run_dir: Path, frames: int) -> int | None:
    """The ``frames`` the run in ``run_dir`` was last asked to train to (its ``config.yaml``) when that is more than
    ``frames``: the directory no longer holds the run of ``frames``, which a sweep of ``frames`` must skip. ``None``
    otherwise, and without a checkpoint (no run, or one killed before its first checkpoint, started afresh)."""
    path = run_dir / CONFIG
    if not (run_dir / CHECKPOINT).is_file() or not path.is_file():
        return None
    try:
        budget = TrainConfig.from_saved(load_yaml(path)).run.frames
    except (ValueError, KeyError, TypeError) as error:
        raise ValueError(f"{path} is not a run's config ({error}): move the run directory away") from None
    return budget if budget > frames else None


def check_settings(results: Path, settings: dict, write: bool) -> None:
    """``ValueError`` when ``results`` holds rows made with other settings (its :data:`SETTINGS` file): a results
    folder holds one budget, one evaluation and one set of options, so that its rows may be averaged. A folder
    without the file gets it (``write``)."""
    path = results / SETTINGS
    if path.is_file():
        try:
            pinned = json.loads(path.read_text())
        except ValueError as error:
            raise ValueError(f"{path} is damaged ({error}); it holds the settings of the folder's rows") from None
        differ = [
            f"{key} {pinned.get(key)!r} there, {value!r} here"
            for key, value in settings.items()
            if pinned.get(key) != value
        ]
        if differ:
            raise ValueError(
                f"{results} holds results of other settings ({'; '.join(differ)}): give these runs a --results "
                "folder of their own (the run directories are continued in place)"
            )
    elif write:
        results.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as temporary:
            temporary.write_text(json.dumps(settings, indent=2) + "\n")


def record_machine(results: Path) -> None:
    """Add this machine (:func:`~activeperc_rl.runtime.portable.machine`) to the ``machines`` that made the folder's
    rows, in its :data:`SETTINGS` file: runs outside portable mode repeat on the same kind of CPU only."""
    path, machine = results / SETTINGS, portable.machine()
    settings = json.loads(path.read_text())
    if machine not in settings.setdefault("machines", []):
        settings["machines"].append(machine)
        with atomic_path(path) as temporary:
            temporary.write_text(json.dumps(settings, indent=2) + "\n")


def last_logged_frames(run_dir: Path) -> int | None:
    """The frames of the last whole row of the run's ``metrics.csv`` (``None`` without one)."""
    path = run_dir / METRICS
    if not path.is_file():
        return None
    with open(path, newline="") as file:
        rows = [row for row in csv.DictReader(file) if (row.get("frames") or "").isdigit()]
    return int(rows[-1]["frames"]) if rows else None


def method_rank(method: str) -> int:
    """Position of ``method`` in :data:`METHODS` (other names, such as the ablations', come after)."""
    return METHODS.index(method) if method in METHODS else len(METHODS)


def train_command(task: Task, run_dir: Path, frames: int, eval_episodes: int, extra: list[str]) -> list[str]:
    """The ``activeperc-train`` call of a task: a resume when the run has a checkpoint, else a fresh run.

    A checkpoint already past ``frames`` (a run that overshot its budget within its last iteration and stopped
    before its evaluation) is resumed to its own frames, which evaluates it where it stands (the trainer refuses a
    total below what it has trained).
    """
    checkpoint = run_dir / CHECKPOINT
    if checkpoint.is_file():
        trained = int(load_checkpoint(checkpoint)["frames"])
        command = [sys.executable, "-m", "activeperc_rl.cli", "--out", str(run_dir), "--resume"]
        command += ["--frames", str(max(frames, trained))]
    else:
        command = [sys.executable, "-m", "activeperc_rl.cli", "--out", str(run_dir), "--frames", str(frames)]
        command += ["--config", str(task.config), "--seed", str(task.seed)]
    return command + ["--eval-episodes", str(eval_episodes), "--no-progress", *read_by(task.config, extra)]


def read_by(config: Path, extra: list[str]) -> list[str]:
    """The options after ``--`` that the run of the preset ``config`` reads: a method's option goes to the runs of
    the methods that have it only (``activeperc-train`` refuses a flag its method does not read)."""
    method = TrainConfig.from_dict(load_yaml(config)).method
    actions = {flag: action for action in cli.build_parser()._actions for flag in action.option_strings}
    kept, i = [], 0
    while i < len(extra):
        flag = extra[i].split("=", 1)[0]
        action = actions.get(flag)
        takes = 0 if action is None or action.nargs == 0 or "=" in extra[i] else 1
        readers = METHOD_OPTIONS.get(action.dest, (method,)) if action is not None else (method,)
        if method in readers:
            kept += extra[i : i + 1 + takes]
        i += 1 + takes
    return kept


def export_run(task: Task, run_dir: Path, results: Path) -> dict:
    """Write the run's compact training curve into ``results/runs/`` and return its summary row."""
    with open(run_dir / METRICS, newline="") as file:
        rows = list(csv.DictReader(file))
    if not rows:
        raise ValueError(f"{run_dir / METRICS} has no rows")
    seen = np.cumsum([int(r["episodes"]) for r in rows])
    for row, count in zip(rows, seen, strict=True):
        row["episodes"] = int(count)
    keep = np.unique(np.linspace(0, len(rows) - 1, min(CURVE_ROWS, len(rows))).round().astype(int))
    curve = results / "runs" / f"{task.label}.csv"
    curve.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(curve) as temporary, open(temporary, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(CURVE_COLUMNS)
        writer.writerows([rows[i][c] for c in CURVE_COLUMNS] for i in keep)
    evaluation = json.loads((run_dir / EVAL).read_text())
    return {
        "method": task.method,
        "fov": task.fov,
        "seed": task.seed,
        "frames": evaluation["frames"],
        "final_success_rate": round(evaluation["learned"]["success_rate"], 4),
        "final_return": round(evaluation["learned"]["mean_return"], 4),
        "random_success_rate": round(evaluation["random"]["success_rate"], 4),
        "random_return": round(evaluation["random"]["mean_return"], 4),
        "train_minutes": round(float(rows[-1]["time_s"]) / 60, 1),
        "machine": portable.machine(),
    }


def read_summary(path: Path) -> list[dict]:
    """The rows of a summary CSV (empty when the file does not exist); see :func:`read_rows`. A value that is not
    a number where one belongs is a ``ValueError`` naming the file and line."""
    rows = read_rows(path, SUMMARY_COLUMNS[:1] + NUMBERS)
    for line, row in enumerate(rows, start=2):
        try:
            for column in NUMBERS:
                (int if column in ("fov", "seed", "frames") else float)(row[column])
        except ValueError as error:
            raise ValueError(f"{path}, line {line}: {error}") from None
    return rows


def read_rows(path: Path, required: tuple[str, ...]) -> list[dict]:
    """The rows of a CSV this folder's scripts wrote (empty when the file does not exist).

    ``ValueError`` naming the file when its header lacks a ``required`` column, or naming the line of a row
    with too few or too many values or an empty ``required`` one (a file cut short, or edited by hand).
    """
    if not path.is_file():
        return []
    with open(path, newline="") as file:
        reader = csv.DictReader(file)
        rows = list(reader)
    missing = [c for c in required if c not in (reader.fieldnames or ())]
    if missing:
        raise ValueError(f"{path} has no column {missing}: not a file these scripts wrote")
    for line, row in enumerate(rows, start=2):
        if None in row or None in row.values() or not all(row[c] for c in required):
            raise ValueError(f"{path}, line {line}: a row with missing or extra values: {row}")
    return rows


def merge_summary(path: Path, new_rows: list[dict]) -> None:
    """Replace the rows of ``path`` that share (method, fov, seed) with ``new_rows`` (atomic rewrite)."""
    rows = {(r["method"], str(r["fov"]), str(r["seed"])): r for r in read_summary(path)}
    rows |= {(r["method"], str(r["fov"]), str(r["seed"])): r for r in new_rows}

    def order(key):
        method, fov, seed = key
        return method_rank(method), method, int(fov), int(seed)

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temporary, open(temporary, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=SUMMARY_COLUMNS, restval="")
        writer.writeheader()
        writer.writerows(rows[key] for key in sorted(rows, key=order))


def core_groups(jobs: int | None, cores_per_job: int) -> list[list[int] | None]:
    """One CPU set per concurrent run (``None``: no pinning, when the runs would not fit the CPUs)."""
    if cores_per_job < 1:
        raise ValueError(f"--cores-per-job={cores_per_job} is invalid: expected an int >= 1")
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else list(range(usable_cpus()))
    jobs = jobs if jobs is not None else max(1, len(cpus) // cores_per_job)
    if jobs < 1:
        raise ValueError(f"--jobs={jobs} is invalid: expected an int >= 1")
    if jobs * cores_per_job > len(cpus) or not hasattr(os, "sched_setaffinity"):
        return [None] * jobs
    return [cpus[i * cores_per_job : (i + 1) * cores_per_job] for i in range(jobs)]


def run_sweep(
    tasks: list[Task],
    frames: int,
    runs: Path,
    summary: Path,
    eval_episodes: int = 100,
    groups: list[list[int] | None] | None = None,
    extra: list[str] | None = None,
) -> int:
    """Run every unfinished task, ``len(groups)`` at a time, exporting each as it finishes.

    Returns 0 when every task finished, 1 when some failed (their logs are named), 130 on Ctrl-C.
    """
    groups = groups or [None]
    extra = extra or []
    results = summary.parent
    pending, done_rows, elsewhere = [], [], []
    for task in tasks:
        budget = continued_past(task.run_dir(runs), frames)
        if budget is not None:
            elsewhere.append(task)
            print(
                f"sweep: skip {task.label}: its run directory was continued to {budget} frames, so it no longer "
                f"holds the run of {frames} (a budget's runs need their own --runs)",
                flush=True,
            )
        elif is_finished(task.run_dir(runs), frames, eval_episodes):
            done_rows.append(export_run(task, task.run_dir(runs), results))
        else:
            pending.append(task)
    if done_rows:
        merge_summary(summary, done_rows)
    print(
        f"sweep: {len(tasks)} runs of {frames} frames: {len(done_rows)} done, {len(pending)} to run "
        f"({len(groups)} at a time)",
        flush=True,
    )
    running: dict[int, tuple[subprocess.Popen, Task, float]] = {}
    free = list(range(len(groups)))
    failed = []
    try:
        while pending or running:
            while pending and free:
                slot, task = free.pop(0), pending.pop(0)
                running[slot] = (_start(task, runs, frames, eval_episodes, groups[slot], extra), task, time.time())
                print(f"sweep: start {task.label}" + (f" on CPUs {groups[slot]}" if groups[slot] else ""), flush=True)
            time.sleep(POLL_S)
            for slot, (process, task, started) in list(running.items()):
                if process.poll() is None:
                    continue
                del running[slot]
                free.append(slot)
                run_dir = task.run_dir(runs)
                minutes = (time.time() - started) / 60
                if process.returncode == 0 and is_finished(run_dir, frames, eval_episodes):
                    row = export_run(task, run_dir, results)
                    merge_summary(summary, [row])
                    print(
                        f"sweep: done {task.label} in {minutes:.1f} min: success {row['final_success_rate']} "
                        f"(random {row['random_success_rate']})",
                        flush=True,
                    )
                else:
                    failed.append(task)
                    print(
                        f"sweep: FAILED {task.label} (exit {process.returncode}); see {run_dir / 'train.log'}",
                        flush=True,
                    )
    except KeyboardInterrupt:
        print("\nsweep: Ctrl-C: every run saves its checkpoint and stops; run the same command to continue", flush=True)
        _stop([process for process, _, _ in running.values()])
        return 130
    except Exception:  # a results file it cannot update, say: no run is left going unwatched
        print("sweep: stopping the runs (each saves its checkpoint) after this error:", flush=True)
        _stop([process for process, _, _ in running.values()])
        raise
    if failed or elsewhere:
        left = [t.label for t in failed + elsewhere]
        print(f"sweep: {len(left)} run(s) failed or skipped: {', '.join(left)}", flush=True)
        return 1
    print(f"sweep: all {len(tasks)} runs done; rows in {summary}", flush=True)
    return 0


def _stop(processes: list[subprocess.Popen]) -> None:
    """Pass a stop on to the runs (as SIGTERM: they may have been started ignoring SIGINT, as our own process may
    have been) and wait for them; a second stop is passed on too (the runs then abort at once, their last
    checkpoints whole)."""
    for process in processes:
        process.send_signal(signal.SIGTERM)
    while any(process.poll() is None for process in processes):
        try:
            for process in processes:
                process.wait()
        except KeyboardInterrupt:
            print("\nsweep: stopped again: the runs abort now, without a new checkpoint", flush=True)
            for process in processes:
                if process.poll() is None:
                    process.send_signal(signal.SIGTERM)


def _start(task: Task, runs: Path, frames: int, eval_episodes: int, cpus, extra) -> subprocess.Popen:
    """Start a task's training process (its own session, so a terminal's Ctrl-C reaches it only through us)."""
    run_dir = task.run_dir(runs)
    run_dir.mkdir(parents=True, exist_ok=True)
    command = train_command(task, run_dir, frames, eval_episodes, extra)
    log = open(run_dir / "train.log", "a")  # the child writes to its own copy; ours is closed below
    if "--resume" not in command:  # a run killed as it started leaves files a fresh run refuses to overwrite
        stale = run_files(run_dir)
        for name in stale:
            (run_dir / name).unlink()
        if stale:
            log.write(f"# removed {', '.join(stale)} of a run killed before its first checkpoint\n")
    log.write(f"$ {' '.join(command)}\n")
    log.flush()
    pin = (lambda: os.sched_setaffinity(0, cpus)) if cpus else None
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=pin)
    log.close()
    return process


def main(argv: list[str] | None = None) -> int:
    """Command line of the sweep; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--room", choices=ROOMS, default="v3", help="the room's presets, configs/ROOM (default v3)")
    parser.add_argument("--frames", type=int, help="frame budget of every run (default: the room's, v3 1000000)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="seeds of every config (default 0 1 2)")
    parser.add_argument("--only", nargs="+", metavar="CONFIG", help="run only these configs (names without .yaml)")
    parser.add_argument("--ablations", action="store_true", help="run configs/ablations/ instead of Figure 1's")
    parser.add_argument("--jobs", type=int, help="runs at once (default: CPUs // cores-per-job)")
    parser.add_argument("--cores-per-job", type=int, default=1, help="CPUs each run is pinned to (default 1)")
    parser.add_argument("--eval-episodes", type=int, default=100, help="held-out episodes of the final evaluation")
    parser.add_argument("--runs", type=Path, help="run directories (default fig1/runs/ROOM)")
    parser.add_argument("--results", type=Path, help="exported results (default: the room's committed folder)")
    parser.add_argument("--dry-run", action="store_true", help="print the runs and their state, run nothing")
    args = parser.parse_args(argv)
    results, frames = ROOMS[args.room]
    args.frames = frames if args.frames is None else args.frames
    args.results = results if args.results is None else args.results
    args.runs = HERE / "runs" / args.room if args.runs is None else args.runs
    try:
        if args.frames < 1 or args.eval_episodes < 1:
            raise ValueError(f"--frames={args.frames} and --eval-episodes={args.eval_episodes} must be >= 1")
        if not all(is_seed(seed) for seed in args.seeds):
            raise ValueError(f"--seeds {args.seeds}: seeds must be in [0, 2**63 - 1]")
        twice = sorted({seed for seed in args.seeds if args.seeds.count(seed) > 1})
        if twice:
            raise ValueError(f"--seeds {args.seeds}: {twice} given more than once")
        configs = find_configs(args.ablations, args.only, CONFIGS / args.room)
        groups = core_groups(args.jobs, args.cores_per_job)
        if groups[0] is None and args.cores_per_job > 1:
            print(
                f"sweep: {len(groups)} runs of {args.cores_per_job} cores do not fit this machine's CPUs: "
                "the runs are not pinned",
                flush=True,
            )
        tasks = [Task(config, seed) for seed in args.seeds for config in configs]
        summary = args.results / ("ablations.csv" if args.ablations else "summary.csv")
        folder = str((CONFIGS / args.room).relative_to(HERE.parent.parent))
        settings = {"frames": args.frames, "eval_episodes": args.eval_episodes, "configs": folder, "options": extra}
        read_summary(summary)  # a damaged file is named now, not when the first run has finished
        check_settings(args.results, settings, write=not args.dry_run)
        if args.dry_run:
            for task in tasks:
                run_dir = task.run_dir(args.runs)
                budget = continued_past(run_dir, args.frames)
                if budget is not None:
                    print(f"{task.label}: skipped: its run directory was continued to {budget} frames")
                    continue
                state = "done" if is_finished(run_dir, args.frames, args.eval_episodes) else "to run"
                command = train_command(task, run_dir, args.frames, args.eval_episodes, extra)
                print(f"{task.label}: {state}: {' '.join(command)}")
            return 0
        record_machine(args.results)
    except ValueError as error:
        parser.error(str(error))
    args.runs.mkdir(parents=True, exist_ok=True)
    with open(args.runs / ".sweep.lock", "w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            parser.error(f"another sweep.py is running on {str(args.runs)!r}; wait for it or stop it first")
        with stop_raises_interrupt():  # a kill or a closing terminal stops the runs as Ctrl-C does
            try:
                return run_sweep(tasks, args.frames, args.runs, summary, args.eval_episodes, groups, extra)
            except ValueError as error:  # a damaged run or results file (any runs going were stopped first)
                print(f"sweep: error: {error}", file=sys.stderr, flush=True)
                return 2


if __name__ == "__main__":
    sys.exit(main())
