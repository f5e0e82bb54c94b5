"""What a run leaves on disk: the checkpoint (a method's networks, optimizers and rooms, for an exact resume) and the
metrics log, both safe against a kill.

``checkpoint.pt`` is written to a temporary file in the same directory, flushed to disk and
renamed over the old one (an atomic replace), so a kill at any moment leaves the previous
checkpoint whole. ``metrics.csv`` gets one flushed row per iteration; on resume the rows
written after the checkpoint (and a last row torn by a kill) are dropped, so ``frames`` stays monotone.
"""

from __future__ import annotations

import csv
import io
import pickle
import sys
import zipfile
from pathlib import Path

import torch
import yaml

from activeperc_rl.config import load_yaml
from activeperc_rl.method_base import Method
from activeperc_rl.recipe import TrainConfig, make_method
from activeperc_rl.runtime.atomic import atomic_path

CHECKPOINT = "checkpoint.pt"
METRICS = "metrics.csv"
CONFIG = "config.yaml"
EVAL = "eval.json"
METRIC_COLUMNS = ("frames", "iteration", "time_s", "fps", "success_rate", "mean_return", "episodes")


def save_checkpoint(path: str | Path, state: dict) -> None:
    """Write ``state`` with ``torch.save`` atomically (temporary file, fsync, rename). It is serialised in memory
    first and written with Python's own file I/O, so that a full disk raises ``OSError`` (torch's writer raises a
    ``RuntimeError`` of its own)."""
    buffer = io.BytesIO()
    torch.save(state, buffer)
    with atomic_path(path) as temporary:
        temporary.write_bytes(buffer.getbuffer())


def load_checkpoint(path: str | Path, config: TrainConfig | None = None) -> dict:
    """Read a checkpoint; with ``config``, check that the checkpoint was trained with it.

    Raises ``ValueError`` naming the file when it is missing, unreadable or damaged (:func:`read_saved`), or naming
    the options that differ from ``config`` (those in :data:`RESUMABLE` may differ).
    """
    return checked_checkpoint(read_saved(path), path, config)


def read_saved(path: str | Path, kind: str = "checkpoint", weights_only: bool | None = False):
    """What ``torch.save`` wrote to ``path``, read with torch's weights-only loader (``weights_only``), in full, or
    (``None``) weights-only unless the file holds more than tensors and plain values (a checkpoint's random states);
    ``ValueError`` naming the file (a ``kind``) when it is missing, unreadable or damaged (a part of it that does not
    match the CRC-32 checksum ``torch.save`` wrote for it)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no {kind} at {str(path)!r}")
    try:
        with zipfile.ZipFile(path) as archive:  # torch.save's archive: a CRC-32 checksum of every part
            damaged = archive.testzip()
        state = None if damaged else _torch_load(path, weights_only)
    except Exception as error:  # any unpickling failure means an unusable file
        raise ValueError(f"{kind} {str(path)!r} cannot be read: {error}") from error
    if damaged:
        raise ValueError(f"{kind} {str(path)!r} is damaged: its part {damaged!r} does not match its checksum")
    return state


def _torch_load(path: Path, weights_only: bool | None):
    """``torch.load`` on the CPU; ``weights_only=None`` tries the weights-only loader first."""
    if weights_only is None:
        try:
            return torch.load(path, map_location="cpu", weights_only=True)
        except pickle.UnpicklingError:  # more than tensors and plain values
            weights_only = False
    return torch.load(path, map_location="cpu", weights_only=weights_only)


def checked_checkpoint(state, path: str | Path, config: TrainConfig | None = None) -> dict:
    """``state``, read from ``path``, checked to be a checkpoint (trained with ``config`` when given); ``ValueError``
    naming the file when it is not, or naming the options that differ from ``config``."""
    if not isinstance(state, dict) or "config" not in state or "method" not in state:
        raise ValueError(f"{str(path)!r} is not an activeperc checkpoint")
    if config is not None:
        saved = TrainConfig.from_saved(state["config"])
        differ = config_differences(saved, config)
        if differ:
            raise ValueError(f"checkpoint {str(path)!r} does not match the config: {'; '.join(differ)}")
    return state


def restored_method(state: dict, path: str | Path, device: torch.device) -> tuple[TrainConfig, Method]:
    """The config of the checkpoint ``state`` (read from ``path``) and its method on ``device``, the networks and
    optimizers restored and the environments not started."""
    config = TrainConfig.from_saved(state["config"])
    method = make_method(config, device, start=False)
    restore_method(method, state, path)
    return config, method


def restore_method(method: Method, state: dict, path: str | Path) -> None:
    """Load the networks and optimizers of the checkpoint ``state`` (read from ``path``) into ``method``; each
    optimizer keeps the step its config asks for (a portable run takes torch's fused Adam step, whatever the
    checkpoint's optimizer took).

    Raises ``ValueError`` naming the file when they do not fit the method's networks.
    """
    saved = state["method"]
    if not isinstance(saved, dict) or not all(isinstance(saved.get(k), dict) for k in ("modules", "optimizers")):
        raise ValueError(f"checkpoint {str(path)!r} is unusable: it holds no networks and optimizers")
    if set(method.modules) != set(saved["modules"]):
        raise ValueError(
            f"checkpoint {str(path)!r} is unusable: its networks {sorted(saved['modules'])} do not match "
            f"{sorted(method.modules)}"
        )
    try:
        method.load_state_dict(saved)
    except ValueError as error:
        raise ValueError(f"checkpoint {str(path)!r} is unusable: {error}") from error
    for optimizer in method.optimizers.values():
        for group in optimizer.param_groups:  # the step the config asks for, not the saved one's
            if "fused" in group:
                group["fused"] = optimizer.defaults["fused"]


def collection_state(method: Method) -> list[dict]:
    """Where each of ``method``'s collectors' rooms stand between two rollouts
    (:meth:`~activeperc_rl.collection.Rollouts.state`): with :func:`restore_collection` after ``method.start()``, a
    resumed run with as many workers collects exactly what the uninterrupted run would have."""
    return [collector.state() for collector in method.collectors]


def restore_collection(method: Method, states: list[dict]) -> None:
    """Put ``method``'s collectors where :func:`collection_state` left them; ``ValueError`` when they do not fit."""
    if len(states) != len(method.collectors):
        raise ValueError(f"its {len(states)} collectors' state does not fit this run's {len(method.collectors)}")
    try:
        for collector, state in zip(method.collectors, states, strict=True):
            collector.load_state(state)
    except (KeyError, TypeError, RuntimeError, ValueError) as error:  # a damaged or hand-edited checkpoint
        raise ValueError(f"its collectors' state does not fit this run: {error}") from error


RESUMABLE = (
    "frames",
    "device",
    "torch_threads",
    "learner_threads",
    "collect_workers",
    "collector",
    "ray_address",
    "checkpoint_every",
    "eval_episodes",
)
"""Options of the run's settings that a resumed run may change; every other one must match the checkpoint's."""


def config_differences(saved: TrainConfig, config: TrainConfig) -> list[str]:
    """Human-readable ``section.name: saved -> new`` for every option that differs, except those in ``RESUMABLE``."""
    if saved.method != config.method:
        return [f"method: {saved.method!r} -> {config.method!r}"]
    old, new = saved.to_dict(), config.to_dict()
    differ = []
    for section, values in old.items():
        if section == "method":
            continue
        for name, value in values.items():
            if new[section][name] != value and not (section == "run" and name in RESUMABLE):
                differ.append(f"{section}.{name}: {value!r} -> {new[section][name]!r}")
    return differ


def kept_rows(path: Path, keep_until: int) -> list[dict]:
    """The rows of the metrics log ``path`` up to ``keep_until`` frames (none where there is no file); a torn last
    row (a kill mid-write) is dropped. A file that is not a metrics log, or a row before the last that does not
    parse, is a ``ValueError`` naming the file and line."""
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    if tuple(reader.fieldnames or ())[: len(METRIC_COLUMNS)] != METRIC_COLUMNS:
        raise ValueError(f"{str(path)!r} is not a metrics log: its header is {reader.fieldnames}")
    kept = []
    for number, row in enumerate(rows, start=2):
        whole = None not in row and None not in row.values() and row["frames"].isdigit()
        if not whole:
            if number == len(rows) + 1:
                break
            raise ValueError(f"{str(path)!r}, line {number}: not a metrics row: {row}")
        if int(row["frames"]) <= keep_until:
            kept.append(row)
    return kept


class MetricsLog:
    """``metrics.csv``: one row per iteration, flushed as it is written.

    Args:
        path: the CSV file.
        keep_until: on resume, the checkpoint's frame count: rows beyond it are dropped (the file is
            rewritten atomically; :func:`kept_rows`); ``None`` starts a new file.
        columns: the header: :data:`METRIC_COLUMNS` and the method's own columns after them. A resumed log
            with other method columns (an older run's) keeps its rows, blank where a column is new.
    """

    def __init__(self, path: str | Path, keep_until: int | None = None, columns: tuple[str, ...] = METRIC_COLUMNS):
        self.path = Path(path)
        self.columns = columns
        rows = kept_rows(self.path, keep_until) if keep_until is not None else []
        with atomic_path(self.path) as temporary, open(temporary, "w", newline="") as f:
            writer = csv.DictWriter(f, columns, extrasaction="ignore")
            writer.writeheader()
            writer.writerows(rows)
        self._file = open(self.path, "a", newline="")  # kept open for the run
        self._writer = csv.DictWriter(self._file, columns)

    def append(self, row: dict) -> None:
        """Write one row (keys: the log's columns; a missing one is left blank) and flush it."""
        self._writer.writerow(row)
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def save_yaml(config: TrainConfig, path: str | Path) -> None:
    """Write ``config`` as the run's ``config.yaml`` (written to a temporary file first, then renamed over ``path``)."""
    with atomic_path(path) as temporary:
        temporary.write_text(yaml.safe_dump(config.to_dict(), sort_keys=False))


def load_run_config(out: str | Path) -> TrainConfig:
    """The config saved in a run directory: its ``config.yaml`` or, in a run killed between its first checkpoint
    and that file or one whose file is damaged (said on stderr), the checkpoint's (``ValueError`` naming the directory
    when there is neither)."""
    path, checkpoint = Path(out) / CONFIG, Path(out) / CHECKPOINT
    if path.is_file():
        try:
            return TrainConfig.from_saved(load_yaml(path))
        except ValueError as error:
            if not checkpoint.is_file():
                raise
            print(f"activeperc-train: warning: {error}; the run's config is read from {checkpoint}", file=sys.stderr)
    if checkpoint.is_file():
        return TrainConfig.from_saved(load_checkpoint(checkpoint)["config"])
    raise ValueError(f"{str(out)!r} holds no run to resume (no {CONFIG})")
