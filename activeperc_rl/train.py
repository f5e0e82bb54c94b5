"""The training loop: one function, top to bottom (:func:`train`).

A run directory holds ``config.yaml`` (the full config), ``metrics.csv`` (one row per iteration),
``tb/`` (TensorBoard), ``checkpoint.pt`` (atomic; when the run has started, every ``checkpoint_every``
seconds, at the end and on Ctrl-C, SIGTERM or SIGHUP) and, after a finished run, ``eval.json`` (the learned and
the random policy on held-out layouts). One process at a time trains into it (``activeperc_rl.runtime.rundir``).

Reproducibility: the same config on CPU gives the same run (networks, sampling and layouts are
seeded from ``seed``), and so does a run stopped and resumed: the checkpoint holds the networks, optimizers,
random-number state and where the collectors stand (:func:`~activeperc_rl.runtime.checkpoint.collection_state`).
A resume with another number of collection workers starts the rooms' episodes anew instead (seeded from
``seed`` and the frame count).
"""

from __future__ import annotations

import json
import math
import re
import signal
import sys
import time
from collections import deque
from contextlib import ExitStack, closing, contextmanager
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from activeperc_env.config import is_int
from activeperc_rl.collection import WorkerError
from activeperc_rl.envs import torch_device
from activeperc_rl.evaluate import evaluate
from activeperc_rl.method_base import Iteration
from activeperc_rl.methods import success_rate
from activeperc_rl.models import FixedLooker
from activeperc_rl.recipe import TrainConfig, make_method
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.allocator import keep_freed_memory
from activeperc_rl.runtime.atomic import atomic_path
from activeperc_rl.runtime.checkpoint import (
    CHECKPOINT,
    CONFIG,
    EVAL,
    METRIC_COLUMNS,
    METRICS,
    MetricsLog,
    collection_state,
    kept_rows,
    load_checkpoint,
    restore_collection,
    restore_method,
    save_checkpoint,
    save_yaml,
)
from activeperc_rl.runtime.rundir import check_fresh, claim_run_dir
from activeperc_rl.runtime.signals import on_stop_signals

# how the final evaluation names each policy it plays (the keys of eval.json)
EVAL_NAMES = {"learned": "learned", "camera_held": "learned, camera held forward", "random": "random"}


def train(
    config: TrainConfig, out: str | Path, resume: bool = False, progress: bool = True, stop_at: int | None = None
) -> dict:
    """Train ``config.method`` for ``config.run.frames`` frames into the run directory ``out``.

    For this whole process, torch runs on ``config.run.torch_threads`` threads and glibc's ``malloc`` keeps freed
    memory for reuse (:func:`~activeperc_rl.runtime.allocator.keep_freed_memory`).

    Args:
        config: the run's configuration.
        out: the run directory (created if needed).
        resume: continue the checkpoint in ``out`` up to ``config.run.frames`` (the other options must
            match the saved ones).
        progress: show a progress bar.
        stop_at: stop with the checkpoint saved (and no evaluation) once this many frames are trained; a resume
            goes on to ``config.run.frames`` as the run would have without the stop (the learning rates' schedule
            spans ``config.run.frames``).

    Returns:
        ``{"frames", "interrupted", "metrics"}`` and, after a finished run with ``eval_episodes > 0``,
        ``"eval"``: ``{"learned": ..., "random": ...}`` as :func:`~activeperc_rl.evaluate.evaluate` gives them.
    """
    out = Path(out)
    if config.run.portable:
        portable.require_pinned()
    if resume and not (out / CHECKPOINT).is_file():  # checked before claiming, which would create the directory
        raise ValueError(f"no checkpoint at {str(out / CHECKPOINT)!r}")
    if stop_at is not None and not (is_int(stop_at) and stop_at >= 1):
        raise ValueError(f"stop_at={stop_at!r} is invalid: expected an int >= 1 (frames)")
    device = torch_device(config.run.device)
    with claim_run_dir(out):
        if resume:
            state = load_checkpoint(out / CHECKPOINT, config)
            # a run overshoots its target by up to one iteration: resuming to that same target is fine
            target = TrainConfig.from_saved(state["config"]).run.frames
            if config.run.frames < state["frames"] and config.run.frames != target:
                raise ValueError(
                    f"frames={config.run.frames} is below the {state['frames']} frames the run in {str(out)!r} has "
                    f"trained: --frames is the total to train to, not an increment"
                )
            kept_rows(out / METRICS, state["frames"])  # a damaged log is refused before anything is written
        else:
            check_fresh(out)
            state = None
        verb = "resuming" if resume else "training"
        print(f"activeperc-train: {verb} {config.method} for {config.run.frames} frames -> {out}", flush=True)
        return _train(config, out, device, state, progress, min(config.run.frames, stop_at or config.run.frames))


def _train(
    config: TrainConfig, out: Path, device: torch.device, state: dict | None, progress: bool, stop_at: int
) -> dict:
    """:func:`train` in the claimed run directory ``out``, from the checkpoint ``state`` or afresh (``None``)."""
    keep_freed_memory()  # the learner's large tensors reuse freed memory instead of faulting in fresh pages
    if config.run.torch_threads:
        torch.set_num_threads(config.run.torch_threads)
    torch.manual_seed(config.run.seed)
    run = _Run(config, out, device, state)
    with ExitStack() as stack:
        stack.callback(run.method.close)
        run.start()
        log = _Log(stack, run, progress)
        last_checkpoint = time.monotonic()
        with _interruptible() as interrupted:
            while run.frames < stop_at and not interrupted():
                start = time.perf_counter()
                step = run.iterate()
                log.write(step, run.advance(step, time.perf_counter() - start))
                if time.monotonic() - last_checkpoint >= config.run.checkpoint_every:
                    run.checkpoint()
                    last_checkpoint = time.monotonic()
            run.checkpoint()
            was_interrupted = interrupted()
    result = {"frames": run.frames, "interrupted": was_interrupted, "metrics": str(out / METRICS)}
    if was_interrupted:
        print(f"interrupted at {run.frames} frames; checkpoint saved in {out}; continue with --resume --out {out}")
        return result
    if run.frames < config.run.frames:
        print(f"activeperc-train: stopped at {run.frames} frames; continue with --resume --out {out}", flush=True)
        return result
    if config.run.eval_episodes:
        result["eval"] = run.evaluate(progress)
    print(f"activeperc-train: done, {run.frames} frames; the run is in {out}", flush=True)
    return result


class _Run:
    """One run in its claimed directory: the method, how far it has trained, and its checkpoint."""

    def __init__(self, config: TrainConfig, out: Path, device: torch.device, state: dict | None):
        self.config, self.out, self.device, self.state = config, out, device, state
        self.method = make_method(config, device, start=False)
        self.frames, self.iteration, self.elapsed = 0, 0, 0.0
        self.window = deque(maxlen=config.run.success_window)  # (return, success) of the last finished episodes
        # an exact resume puts the rooms where the checkpoint left them; without their state (another number of
        # collection workers, or a checkpoint from before it was saved) the rooms start new episodes from a
        # stream of their own
        self.exact = (
            state is not None
            and state.get("collection") is not None
            and "env_seed" in state
            and state.get("collect_workers", 0) == config.run.collect_workers
        )
        if state is not None:
            restore_method(self.method, state, out / CHECKPOINT)
            self.frames, self.iteration, self.elapsed = state["frames"], state["iteration"], state["time_s"]
            self.window.extend(map(_episode, state["window"]))
            self.method.env_seed = state["env_seed"] if self.exact else _fresh_env_seed(config, self.frames)
        self.saved_frames = self.frames  # the frames of the checkpoint on disk

    def start(self) -> None:
        """Build the collectors (the rooms where the checkpoint left them, on an exact resume) and write the run's
        first files: a fresh run's checkpoint and config.yaml, a resumed run's config.yaml."""
        config, out, state = self.config, self.out, self.state
        self.method.start()
        if self.exact:
            try:
                restore_collection(self.method, state["collection"])
            except ValueError as error:  # e.g. another MuJoCo whose state rows differ, or a damaged checkpoint
                print(
                    f"activeperc-train: warning: the rooms' state in {out / CHECKPOINT} does not fit this run "
                    f"({error}); they start new episodes, so this resume is not the uninterrupted run",
                    file=sys.stderr,
                )
                self.method.close()
                self.method.env_seed = _fresh_env_seed(config, self.frames)
                self.method.start()
        if state is not None:
            torch.set_rng_state(state["torch_rng"])  # after start(), which may draw from it
        # nothing is written before the run has started; from then on the directory holds a checkpoint
        if state is not None:
            save_yaml(config, out / CONFIG)
            if self.frames < config.run.frames:
                _retire_eval(out)
            return
        try:  # the first checkpoint, then config.yaml: a run directory never holds a config without one
            self.checkpoint()
            save_yaml(config, out / CONFIG)
        except BaseException:  # stopped (or failed) before it started: leave nothing of the run behind
            for name in (CONFIG, CHECKPOINT):
                (out / name).unlink(missing_ok=True)
            raise

    def checkpoint(self) -> None:
        """Save the networks, the optimizers, the counters, the random state and the rooms' state."""
        try:
            collection = collection_state(self.method)
        except WorkerError:  # a worker died since the last iteration: the next one says so; save what we have
            collection = None
        save_checkpoint(
            self.out / CHECKPOINT,
            {
                "method": self.method.state_dict(),
                "config": self.config.to_dict(),
                "frames": self.frames,
                "iteration": self.iteration,
                "time_s": self.elapsed,
                "window": list(self.window),
                "torch_rng": torch.get_rng_state(),
                "env_seed": self.method.env_seed,
                "collection": collection,
                "collect_workers": self.config.run.collect_workers,
            },
        )
        self.saved_frames = self.frames

    def iterate(self) -> Iteration:
        """One iteration of the method; a dead worker or diverged learning is an error naming what is kept."""
        kept = f"the checkpoint at {self.saved_frames} frames is kept"
        where = f"iteration {self.iteration + 1} ({self.frames} frames)"
        self.method.schedule_learning_rates(self.frames)
        try:
            step = self.method.iterate()
        except WorkerError as error:
            raise WorkerError(f"{error}; {kept}: continue with --resume --out {self.out}") from None
        except (ValueError, RuntimeError) as error:  # e.g. sampling from NaN logits: the learning diverged
            broken = self.method.non_finite()
            if not (isinstance(error, ValueError) or broken or _mentions_non_finite(error)):
                raise
            why = f"the weights of {broken} are not finite" if broken else " ".join(str(error).split())
            raise TrainingError(f"training failed at {where}: {why}; {kept} in {self.out}") from error
        if broken := self.method.non_finite():
            raise TrainingError(
                f"training diverged at {where}: the weights of {broken} are not finite; {kept} in {self.out}"
            )
        return step

    def advance(self, step: Iteration, seconds: float) -> dict:
        """Count ``step`` (which took ``seconds``) in; its row of ``metrics.csv``."""
        self.frames, self.iteration, self.elapsed = (
            self.frames + step.frames,
            self.iteration + 1,
            self.elapsed + seconds,
        )
        self.window.extend(zip(step.returns, step.successes, strict=True))
        success = success_rate([won for _, won in self.window])
        mean_return = float(np.mean([ret for ret, _ in self.window])) if self.window else math.nan
        return {
            "frames": self.frames,
            "iteration": self.iteration,
            "time_s": round(self.elapsed, 3),
            "fps": round(step.frames / seconds, 1),
            "success_rate": round(success, 4),
            "mean_return": round(mean_return, 4),
            "episodes": len(step.returns),
        } | {column: round(step.losses.get(key, math.nan), 5) for key, column in self.method.LOGGED.items()}

    def evaluate(self, progress: bool) -> dict:
        """The learned and a random policy on held-out layouts, printed and written to ``eval.json``; where a looker
        module turns the camera, also the learned mover with the camera held forward (``"camera_held"``): what the
        learned looker adds."""
        mover_policy, looker = self.method.policy()
        run = self.config.run
        held_out = dict(episodes=run.eval_episodes, seed=run.seed, device=self.device, progress=progress)
        result = {"learned": evaluate(self.config, mover_policy, looker, **held_out)}
        if looker is not None:
            result["camera_held"] = evaluate(self.config, mover_policy, FixedLooker(), **held_out)
        result["random"] = evaluate(self.config, None, None, **held_out)
        record = {
            "frames": self.frames,
            "eval_seed": self.config.run.seed,
            "torch_cpu_capability": portable.cpu_capability(),
        }
        _write_json(self.out / EVAL, result | record)
        for name, values in result.items():
            rate, mean_return, episodes = values["success_rate"], values["mean_return"], values["episodes"]
            print(
                f"{EVAL_NAMES[name]:>28}: success rate {rate:.3f}, mean return {mean_return:.3f} "
                f"({episodes} held-out episodes)"
            )
        return result


class _Log:
    """Where a run's iterations are logged: ``metrics.csv``, TensorBoard and the progress bar, opened in ``stack``
    (which closes them)."""

    def __init__(self, stack: ExitStack, run: _Run, progress: bool):
        resumed = run.state is not None
        columns = METRIC_COLUMNS + tuple(run.method.LOGGED.values())
        self.metrics = stack.enter_context(
            closing(MetricsLog(run.out / METRICS, keep_until=run.frames if resumed else None, columns=columns))
        )
        from torch.utils.tensorboard import SummaryWriter

        # scalars are logged against frames: drop those written after the checkpoint
        purge = run.frames + 1 if resumed else None
        self.writer = stack.enter_context(SummaryWriter(str(run.out / "tb"), purge_step=purge))
        self.bar = stack.enter_context(
            tqdm(
                total=run.config.run.frames, initial=run.frames, unit="frame", disable=not progress, dynamic_ncols=True
            )
        )

    def write(self, step: Iteration, row: dict) -> None:
        """Log ``step``'s ``row`` in the CSV, its scalars in TensorBoard, and move the bar on."""
        self.metrics.append(row)
        for key in ("fps", "success_rate", "mean_return"):
            self.writer.add_scalar(f"train/{key}", row[key], row["frames"])
        for key, value in step.losses.items():
            self.writer.add_scalar(key, value, row["frames"])
        self.bar.total = max(self.bar.total, row["frames"])  # the last iteration may pass the budget: the bar ends full
        self.bar.update(step.frames)
        self.bar.set_postfix(
            fps=f"{row['fps']:.0f}", success=f"{row['success_rate']:.2f}", ret=f"{row['mean_return']:.3f}"
        )


def _mentions_non_finite(error: Exception) -> bool:
    """Whether torch's ``error`` is about NaN or infinite values (as when a distribution samples from NaN logits)."""
    return re.search(r"\b(nan|inf)\b", str(error), flags=re.IGNORECASE) is not None


class TrainingError(RuntimeError):
    """Training failed after it had started (not a bad option): the message says where and what is kept."""


def _episode(saved) -> tuple[float, bool]:
    """A checkpoint window's ``(return, success)``; a bare return is from a checkpoint saved before successes were
    kept, whose rooms paid only on success."""
    return (float(saved), saved > 0) if isinstance(saved, float) else (float(saved[0]), bool(saved[1]))


def _fresh_env_seed(config: TrainConfig, frames: int) -> int:
    """The layout streams' base seed of a resume that cannot put the rooms where they were: from the seed and
    the frames, so that the resumed rooms do not replay the episodes the run started with."""
    return int(np.random.SeedSequence([config.run.seed, frames]).generate_state(1)[0])


@contextmanager
def _interruptible():
    """Turn the first stop signal (:func:`~activeperc_rl.runtime.signals.stop_signals`: Ctrl-C, SIGTERM, SIGHUP) into a
    flag the loop polls; a second one interrupts at once. After a SIGHUP, what would go to the terminal goes to
    ``/dev/null``."""
    flag = {"set": False}

    def stop(signum: int) -> None:
        if flag["set"]:
            raise KeyboardInterrupt
        flag["set"] = True
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        print(f"\n{name}: finishing this iteration, then saving a checkpoint ({name} again to abort)", flush=True)

    with on_stop_signals(stop):
        yield lambda: flag["set"]


def _retire_eval(out: Path) -> None:
    """Move the run's ``eval.json`` to ``eval_FRAMES.json`` (FRAMES: the frames it evaluated) before the run trains
    further, so that ``eval.json`` never describes another checkpoint than the one beside it; says so on stderr."""
    path = out / EVAL
    try:
        evaluated = json.loads(path.read_text()).get("frames")
    except FileNotFoundError:
        return
    except (ValueError, AttributeError):  # damaged, or not ours: still not of the checkpoint to come
        evaluated = None
    if not is_int(evaluated):
        evaluated = "earlier"
    kept = path.replace(out / f"eval_{evaluated}.json")
    print(f"activeperc-train: {EVAL} is of the run at {evaluated} frames; kept as {kept.name}", file=sys.stderr)


def _write_json(path: Path, values: dict) -> None:
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps(values, indent=2) + "\n")
