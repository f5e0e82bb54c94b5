"""Aggregate the Figure 1 sweep: learning curves over seeds and the table of final results.

Reads what ``sweep.py`` exported (``results/summary.csv`` and ``results/runs/*.csv``) and

- draws ``docs/figures/fig1_curves.png``: the training success rate and mean return (each a moving
  average over the last 100 finished episodes, as ``metrics.csv`` logs them, from the frame where 100
  episodes have finished) against frames, one
  column per field of view, the mean over seeds with a 95 % confidence band (Student's t over seeds,
  drawn within [0, 1]; no band with one seed); the dashed grey line is a random mover and looker on the
  held-out episodes, averaged over the seeds;
- writes the table of final held-out results into ``docs/results.md`` between the markers
  ``<!-- fig1-summary -->`` and ``<!-- /fig1-summary -->`` (and prints it).

``--ablations`` does the same for ``results/ablations.csv`` (figure ``fig1_ablations.png`` beside it; the table is
printed, and written only with ``--doc``, between the markers ``fig1-ablations``), with the runs of the config each
ablation changes (``meta_eps0.3`` at 60 degrees, from ``summary.csv``) drawn and listed first for reference. Run
from anywhere::

    python experiments/fig1/aggregate.py
    python experiments/fig1/aggregate.py --ablations

With ``--results DIR`` (another sweep's folder) the table is printed and the figure written into ``DIR``; the
committed document and figures change only with ``--doc`` and ``--figures``. It also prints each method's held-out
success minus ``fixed_forward``'s, paired by seed, or minus other methods' with ``--against METHOD...``.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))  # sweep.py sits next to this file

from sweep import HERE, METHODS, method_rank, read_summary  # noqa: E402

from activeperc_rl.runtime.atomic import atomic_path  # noqa: E402

ROOT = HERE.parent.parent
DOC = ROOT / "docs" / "results.md"
RESULTS = HERE / "results"  # the committed results, whose table and figures are docs/results.md's
GRID_POINTS = 100
FULL_WINDOW = 100  # curves start once this many training episodes have finished: metrics.csv averages the last 100
# Two-sided 95 % critical values of Student's t by degrees of freedom (standard statistical tables).
T95 = {
    1: 12.706,
    2: 4.303,
    3: 3.182,
    4: 2.776,
    5: 2.571,
    6: 2.447,
    7: 2.365,
    8: 2.306,
    9: 2.262,
    10: 2.228,
    15: 2.131,
    20: 2.086,
    30: 2.042,
}


def t95(dof: int) -> float:
    """The two-sided 95 % Student's t critical value for ``dof`` degrees of freedom.

    Between the table's rows (and beyond 30) it takes the row below, whose value is larger: conservative.
    """
    if dof < 1:
        raise ValueError(f"dof={dof} is invalid: expected an int >= 1")
    return T95[max(d for d in T95 if d <= dof)]


def ci_half_width(values: np.ndarray) -> np.ndarray:
    """Half-width of the 95 % confidence interval of the mean over axis 0 (the seeds); ``nan`` for one seed."""
    seeds = values.shape[0]
    if seeds == 1:
        return np.full(values.shape[1:], math.nan)
    return t95(seeds - 1) * values.std(axis=0, ddof=1) / math.sqrt(seeds)


def mean_ci(values) -> tuple[float, float]:
    """Mean and half-width of its 95 % confidence interval over the seeds (``nan`` half-width for one value)."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        raise ValueError("mean_ci needs at least one value")
    return float(values.mean()), float(ci_half_width(values))


def read_curve(path: Path, frames: int) -> dict[str, np.ndarray]:
    """A run's exported curve as arrays, from the first row whose average spans ``FULL_WINDOW`` episodes.

    A run too short to finish that many episodes gives empty arrays; a missing or empty curve, or one that does
    not end at the run's ``frames`` (its summary row's: cut short, or another run's), is a ``ValueError``.
    """
    if not path.is_file():
        raise ValueError(f"{path} does not exist: sweep.py exports it when the run finishes (use the same --results)")
    with open(path, newline="") as file:
        rows = list(csv.DictReader(file))
    if not rows:
        raise ValueError(f"{path} has no rows")
    try:
        columns = {key: np.array([float(r[key]) for r in rows]) for key in rows[0]}
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: not a curve sweep.py wrote ({error})") from None
    if columns["frames"][-1] != frames:
        raise ValueError(
            f"{path} ends at {columns['frames'][-1]:.0f} frames, its row in the summary at {frames}: cut short or of "
            "another run (run sweep.py again to export it)"
        )
    valid = columns["episodes"] >= FULL_WINDOW
    return {key: values[valid] for key, values in columns.items()}


def group_runs(rows: list[dict]) -> dict[tuple[str, int], list[dict]]:
    """Summary rows grouped by (method, fov), in the paper's method order."""
    groups: dict[tuple[str, int], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["method"], int(row["fov"])), []).append(row)

    return {key: groups[key] for key in sorted(groups, key=lambda key: (method_rank(key[0]), *key))}


def check_one_budget(rows: list[dict]) -> None:
    """``ValueError`` naming each (method, fov) whose runs were trained to different frame counts."""
    mixed = []
    for (method, fov), runs in group_runs(rows).items():
        frames = sorted({int(r["frames"]) for r in runs})
        if len(frames) > 1:
            seeds = {f: [r["seed"] for r in runs if int(r["frames"]) == f] for f in frames}
            budgets = ", ".join(f"{f} frames (seeds {s})" for f, s in seeds.items())
            mixed.append(f"{method} at {fov} degrees: {budgets}")
    if mixed:
        raise ValueError(
            "runs of different budgets would be averaged together: "
            + "; ".join(mixed)
            + ". Give each budget its own folder (sweep.py --results DIR, then aggregate.py --results DIR)"
        )


def seed_band(curves: list[dict[str, np.ndarray]], key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames, mean and 95 % half-width over seeds of one curve column, on a grid every curve covers."""
    start = max(c["frames"][0] for c in curves)
    stop = min(c["frames"][-1] for c in curves)
    grid = np.linspace(start, stop, GRID_POINTS)
    values = np.stack([np.interp(grid, c["frames"], c[key]) for c in curves])
    return grid, values.mean(axis=0), ci_half_width(values)


def plot_curves(rows: list[dict], curves_dir: Path, out: Path) -> None:
    """Draw the training curves of every (method, fov) in ``rows`` into ``out`` (one column per fov)."""
    groups = group_runs(rows)
    fovs = sorted({fov for _, fov in groups})
    figure, axes = plt.subplots(2, len(fovs), figsize=(6 * len(fovs), 7.5), squeeze=False, sharex=True)
    colors = dict(zip(dict.fromkeys(m for m, _ in groups), plt.cm.tab10.colors, strict=False))
    for column, fov in enumerate(fovs):
        for (method, group_fov), runs in groups.items():
            if group_fov != fov:
                continue
            curves = [read_curve(curves_dir / f"{method}_fov{fov}_seed{r['seed']}.csv", int(r["frames"])) for r in runs]
            curves = [c for c in curves if c["frames"].size]  # runs too short to fill the window have no curve
            if not curves:
                continue
            for row_index, key in enumerate(("success_rate", "mean_return")):
                grid, mean, half = seed_band(curves, key)
                axis = axes[row_index, column]
                seeds = f"{len(curves)} seed" + ("s" if len(curves) > 1 else "")
                axis.plot(grid, mean, color=colors[method], label=f"{method} ({seeds})")
                # both quantities lie in [0, 1]: the band is drawn within it
                low, high = np.clip(mean - half, 0, 1), np.clip(mean + half, 0, 1)
                axis.fill_between(grid, low, high, color=colors[method], alpha=0.2)
        # the random policy's result depends on the seed only (not on the method): one value per seed
        random_rows = {r["seed"]: r for runs in groups.values() for r in runs if int(r["fov"]) == fov}
        for row_index, key in enumerate(("random_success_rate", "random_return")):
            level = np.mean([float(r[key]) for r in random_rows.values()])
            axes[row_index, column].axhline(level, color="grey", linestyle="--", label="random (held-out)")
        axes[0, column].set_title(f"horizontal field of view {fov} degrees")
        axes[0, column].set_ylabel("success rate (last 100 episodes)")
        axes[1, column].set_ylabel("mean return (last 100 episodes)")
        axes[1, column].set_xlabel("environment frames (E1 and E2 both for meta)")
        axes[0, column].legend(fontsize=8)  # each field of view its own: a config may have more seeds in one
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as temporary:
        figure.savefig(temporary, format="png", dpi=100)
    plt.close(figure)


def with_reference(ablations: list[dict], summary: list[dict]) -> list[dict]:
    """``ablations`` preceded by the runs of ``summary`` they change one option of.

    Ablation ``METHOD_CHANGE`` at a field of view changes the main config ``METHOD`` at that field of view (the
    longest such method name wins): its rows with the ablations' seeds come first.
    """
    main = {r["method"] for r in summary}
    bases = set()
    for row in ablations:
        prefixes = [m for m in main if row["method"].startswith(m + "_")]
        if prefixes:
            bases.add((max(prefixes, key=len), row["fov"]))
    seeds = {r["seed"] for r in ablations}
    return [r for r in summary if (r["method"], r["fov"]) in bases and r["seed"] in seeds] + ablations


def summary_table(rows: list[dict]) -> str:
    """The Markdown table of final held-out results: mean and 95 % interval over seeds per (method, fov)."""

    def cell(values, digits=3):
        mean, half = mean_ci([float(v) for v in values])
        return f"{mean:.{digits}f}" if math.isnan(half) else f"{mean:.{digits}f} ± {half:.{digits}f}"

    lines = [
        "| fov | method | seeds | frames | held-out success | held-out return | random success | train min |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (method, fov), runs in sorted(group_runs(rows).items(), key=lambda item: item[0][1]):
        lines.append(
            f"| {fov} | {method} | {','.join(str(r['seed']) for r in runs)} | {runs[0]['frames']} | "
            f"{cell(r['final_success_rate'] for r in runs)} | {cell(r['final_return'] for r in runs)} | "
            f"{cell(r['random_success_rate'] for r in runs)} | {cell((r['train_minutes'] for r in runs), 1)} |"
        )
    return "\n".join(lines) + "\n"


def machines_line(rows: list[dict]) -> str:
    """A line naming the CPUs that made the runs, with their seeds and number of runs (outside ``--portable`` a run
    repeats on its own kind of CPU only); empty when no row records one."""
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(row.get("machine") or "not recorded", []).append(row)
    if set(groups) == {"not recorded"}:
        return ""
    parts = []
    for machine, runs in sorted(groups.items()):
        seeds = ",".join(sorted({str(r["seed"]) for r in runs}, key=int))
        parts.append(f"{machine}: seeds {seeds} ({len(runs)} run{'s' if len(runs) > 1 else ''})")
    return "\nMachines: " + "; ".join(parts) + ".\n"


def paired_difference(rows: list[dict], method: str, fov: int, reference: str = "fixed_forward") -> tuple:
    """The seeds that ``method`` and ``reference`` both ran at ``fov`` (in ``rows``' order), and the mean and 95 %
    half-width over them of ``method``'s held-out success minus ``reference``'s (no seeds: NaN and NaN)."""
    success = {(r["method"], int(r["fov"]), int(r["seed"])): float(r["final_success_rate"]) for r in rows}
    seeds = [s for m, f, s in success if (m, f) == (method, fov) and (reference, fov, s) in success]
    if not seeds:
        return seeds, math.nan, math.nan
    return seeds, *mean_ci([success[method, fov, s] - success[reference, fov, s] for s in seeds])


def difference_table(rows: list[dict], *references: str) -> str:
    """The Markdown table of each method's held-out success minus each of ``references``' (default fixed_forward) at
    the same field of view, paired by seed: mean ± 95 % half-width over the seeds both ran (named where fewer than the
    method's), one column a reference; empty when no method shares a seed with any of them."""
    references = references or ("fixed_forward",)
    groups = group_runs(rows)
    lines = []
    for method, fov in sorted(groups, key=lambda key: key[1]):
        own = [int(r["seed"]) for r in groups[method, fov]]
        cells = []
        for reference in references:
            seeds, mean, half = paired_difference(rows, method, fov, reference)
            if method == reference or not seeds:
                cells.append("")
                continue
            cell = f"{mean:+.3f}" + ("" if math.isnan(half) else f" ± {half:.3f}")
            cells.append(cell + (f" (seeds {','.join(map(str, seeds))})" if len(seeds) < len(own) else ""))
        if any(cells):
            lines.append(f"| {fov} | {method} | {','.join(map(str, own))} | {' | '.join(cells)} |")
    if not lines:
        return ""
    columns = " | ".join(f"held-out success minus {reference}'s, same seed" for reference in references)
    return f"| fov | method | seeds | {columns} |\n|---|---|---|{'---|' * len(references)}\n" + "\n".join(lines) + "\n"


def replace_between(text: str, marker: str, content: str) -> str:
    """``text`` with what lies between ``<!-- marker -->`` and ``<!-- /marker -->`` replaced by ``content``."""
    start, end = f"<!-- {marker} -->\n", f"<!-- /{marker} -->"
    if start not in text or end not in text:
        raise ValueError(f"the markers {start.strip()} and {end} are missing")
    head, rest = text.split(start, 1)
    return head + start + content + end + rest.split(end, 1)[1]


CLAIMS = (
    "1. At 100 degrees some baselines obtain large returns",
    "2. At 100 degrees `meta` with epsilon 0.1 is best",
    "3. At 60 degrees every method's return drops",
    "4. At 60 degrees `meta` with epsilon 0.3 is best",
    "(implied) `meta`'s looker learns to look and beats the fixed camera",
)
"""The paper's claims on Figure 1 (section 4), judged by :func:`claims`."""
BASELINES = ("fixed_forward", "joint", "ia2c", "curriculum")
LARGE = 0.5
"""The held-out success claim 1 counts as a large return (the paper gives no number)."""
DROP = 0.01
"""The least fall of held-out return from 100 to 60 degrees that claim 3 counts as a drop."""


def claims(rows: list[dict]) -> list[tuple[str, str, str]]:
    """Each of :data:`CLAIMS` with its verdict in the Figure 1 sweep ``rows`` (every method at 60 and 100 degrees)
    and the numbers behind it (means over each method's seeds; paired differences over the seeds both ran)."""
    runs = group_runs(rows)
    success = {key: mean_ci([float(r["final_success_rate"]) for r in group])[0] for key, group in runs.items()}
    returns = {key: mean_ci([float(r["final_return"]) for r in group])[0] for key, group in runs.items()}
    methods = list(dict.fromkeys(method for method, _ in runs))

    def names(listed, joint: str = "and") -> str:
        quoted = [f"`{m}`" for m in listed]
        return ", ".join(quoted[:-1]) + f" {joint} {quoted[-1]}" if len(quoted) > 1 else "".join(quoted)

    def ranked(fov: int, among) -> tuple[str, str]:
        order = sorted(((success[m, fov], m) for m in among if (m, fov) in success), reverse=True)
        return order[0][1], ", ".join(f"`{m}` {value:.3f}" for value, m in order)

    def paired(method: str, fov: int, reference: str) -> tuple[float, float]:
        return paired_difference(rows, method, fov, reference)[1:]

    large = [m for m in BASELINES if success.get((m, 100), 0.0) >= LARGE]
    present = [m for m in BASELINES if (m, 100) in success]
    first = f"reproduced by {names(large)} only" if large and large != present else _reproduced(bool(large))
    best100, at100 = ranked(100, methods)
    eps = paired("meta_eps0.1", 100, "meta_eps0.3")
    dropped = [m for m in methods if returns[m, 100] - returns[m, 60] > DROP]
    kept = [m for m in methods if m not in dropped]
    third = f"for {names(dropped)}; not for {names(kept, 'or')}" if dropped and kept else _reproduced(not kept)
    falls = ", ".join(f"`{m}` {returns[m, 100]:.3f} to {returns[m, 60]:.3f}" for m in methods)
    best60, at60 = ranked(60, methods)
    looker = {fov: paired("meta_eps0.3", fov, "fixed_forward") for fov in (60, 100)}
    implied = all(mean - half > 0 for mean, half in looker.values())
    lead = f"`meta_eps0.3` minus `fixed_forward`, paired: {_pm(*looker[60])} at 60 degrees, {_pm(*looker[100])} at 100"
    return [
        (CLAIMS[0], first, f"{ranked(100, BASELINES)[1]} (large: held-out success {LARGE} or more)"),
        (CLAIMS[1], _reproduced(best100 == "meta_eps0.1"), f"{at100}; `meta_eps0.1` minus `meta_eps0.3` {_pm(*eps)}"),
        (CLAIMS[2], third, f"held-out return from 100 to 60 degrees (a drop: more than {DROP}): {falls}"),
        (CLAIMS[3], _reproduced(best60 == "meta_eps0.3"), at60),
        (CLAIMS[4], _reproduced(implied), lead),
    ]


def _reproduced(held: bool) -> str:
    return "reproduced" if held else "not reproduced"


def _pm(mean: float, half: float) -> str:
    return f"{mean:+.3f}" if math.isnan(half) else f"{mean:+.3f} ± {half:.3f}"


def main(argv: list[str] | None = None) -> int:
    """Command line; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ablations", action="store_true", help="the ablations instead of Figure 1's runs")
    parser.add_argument("--results", type=Path, default=RESULTS, help="sweep.py's --results (default fig1/results)")
    parser.add_argument(
        "--figures", type=Path, help="where the figure goes (default: docs/figures for fig1/results, else --results)"
    )
    parser.add_argument(
        "--doc",
        type=Path,
        help="the document whose table is updated (default: docs/results.md for "
        "fig1/results; for another --results none, the table is only printed)",
    )
    parser.add_argument(
        "--against",
        nargs="+",
        metavar="METHOD",
        help="the methods whose held-out success the paired differences subtract, a column each (default "
        "fixed_forward, where it ran)",
    )
    args = parser.parse_args(argv)
    committed = args.results.resolve() == RESULTS.resolve()
    into_docs = committed and not args.ablations  # room v0's ablations live in the design notes, as prose
    figures = args.figures or (ROOT / "docs" / "figures" if into_docs else args.results)
    doc = args.doc or (DOC if into_docs else None)
    name = "ablations" if args.ablations else "summary"
    try:
        rows = read_summary(args.results / f"{name}.csv")
        if not rows:
            raise ValueError(f"no results in {args.results / f'{name}.csv'}: run sweep.py first")
        if args.ablations:
            rows = with_reference(rows, read_summary(args.results / "summary.csv"))
        check_one_budget(rows)
        methods = sorted({r["method"] for r in rows})
        for method in args.against or ():
            if method not in methods:
                raise ValueError(f"--against {method!r}: no runs of that method here; these ran: {methods}")
        table = summary_table(rows) + machines_line(rows)
        marker = "fig1-ablations" if args.ablations else "fig1-summary"
        if doc is not None:
            if not doc.is_file():
                raise ValueError(f"--doc {str(doc)!r} does not exist")
            try:
                text = replace_between(doc.read_text(), marker, table)
            except ValueError as error:
                raise ValueError(f"--doc {str(doc)!r}: {error}") from None
        figure = figures / ("fig1_ablations.png" if args.ablations else "fig1_curves.png")
        plot_curves(rows, args.results / "runs", figure)
    except ValueError as error:
        parser.error(str(error))
    print(table, end="")
    differences = difference_table(rows, *(args.against or ()))
    if differences:
        print("\n" + differences, end="")
    if not args.ablations and set(group_runs(rows)) >= {(m, fov) for m in METHODS for fov in (60, 100)}:
        print("\nThe paper's claims:")
        for claim, verdict, numbers in claims(rows):
            print(f"- {claim}: {verdict}: {numbers}")
    if doc is None:
        print(f"wrote {figure}")
        return 0
    with atomic_path(doc) as temporary:
        temporary.write_text(text)
    print(f"wrote {figure} and the table in {doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
