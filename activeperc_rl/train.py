"""The training loop: one function, top to bottom (:func:`train`).

A run directory holds ``config.yaml`` (the full config), ``metrics.csv`` (one row per iteration),
``tb/`` (TensorBoard), ``checkpoint.pt`` (atomic; every ``checkpoint_every`` seconds, at the end
and on Ctrl-C) and, after a finished run, ``eval.json`` (the learned and the random policy on
held-out layouts).

Reproducibility: the same config on CPU gives the same run (networks, sampling and layouts are
seeded from ``seed``). A resumed run continues the networks, optimizers and random-number state,
but its rooms restart with fresh layouts (seeded from ``seed`` and the frame count), so it is not
bit-identical to an uninterrupted run.
"""

from __future__ import annotations

import json
import math
import signal
import threading
import time
from collections import deque
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from activeperc_rl.allocator import keep_freed_memory
from activeperc_rl.atomic import atomic_path
from activeperc_rl.checkpoint import (
    CHECKPOINT,
    CONFIG,
    METRICS,
    MetricsLog,
    load_checkpoint,
    save_checkpoint,
)
from activeperc_rl.config import TrainConfig, load_yaml, resolve_device, save_yaml
from activeperc_rl.evaluate import evaluate
from activeperc_rl.methods import make_method


def train(config: TrainConfig, out: str | Path, resume: bool = False, progress: bool = True) -> dict:
    """Train ``config.method`` for ``config.frames`` frames into the run directory ``out``.

    For this whole process, torch runs on ``config.torch_threads`` threads and glibc's ``malloc`` keeps freed
    memory for reuse (:func:`~activeperc_rl.allocator.keep_freed_memory`).

    Args:
        config: the run's configuration.
        out: the run directory (created if needed).
        resume: continue the checkpoint in ``out`` up to ``config.frames`` (the other options must
            match the saved ones).
        progress: show a progress bar.

    Returns:
        ``{"frames", "interrupted", "metrics"}`` and, after a finished run with ``eval_episodes > 0``,
        ``"eval"``: ``{"learned": ..., "random": ...}`` as :func:`~activeperc_rl.evaluate.evaluate` gives them.
    """
    out = Path(out)
    state = None
    if resume:
        state = load_checkpoint(out / CHECKPOINT, config)
        # a run overshoots its target by up to one iteration: resuming to that same target is fine
        if config.frames < state["frames"] and config.frames != state["config"]["frames"]:
            raise ValueError(
                f"frames={config.frames} is below the {state['frames']} frames the run in {str(out)!r} has trained: "
                f"--frames is the total to train to, not an increment"
            )
    elif (out / CHECKPOINT).exists():
        raise ValueError(f"{str(out)!r} already holds a run: pass --resume to continue it, or choose another --out")
    device = resolve_device(config.device)
    out.mkdir(parents=True, exist_ok=True)
    save_yaml(config, out / CONFIG)

    keep_freed_memory()  # the learner's large tensors reuse freed memory instead of faulting in fresh pages
    if config.torch_threads:
        torch.set_num_threads(config.torch_threads)
    torch.manual_seed(config.seed)
    method = make_method(config, device, start=False)
    frames, iteration, elapsed = 0, 0, 0.0
    window = deque(maxlen=config.success_window)
    if state is not None:
        method.load_state_dict(state["method"])
        frames, iteration, elapsed = state["frames"], state["iteration"], state["time_s"]
        window.extend(state["window"])
        torch.set_rng_state(state["torch_rng"])
        method.env_seed = int(np.random.SeedSequence([config.seed, frames]).generate_state(1)[0])
    method.start()

    metrics = MetricsLog(out / METRICS, keep_until=frames if state is not None else None)
    from torch.utils.tensorboard import SummaryWriter

    # scalars are logged against frames: drop those written after the checkpoint
    writer = SummaryWriter(str(out / "tb"), purge_step=frames + 1 if state is not None else None)

    def checkpoint() -> None:
        save_checkpoint(
            out / CHECKPOINT,
            {
                "method": method.state_dict(),
                "config": config.to_dict(),
                "frames": frames,
                "iteration": iteration,
                "time_s": elapsed,
                "window": list(window),
                "torch_rng": torch.get_rng_state(),
            },
        )

    bar = tqdm(total=config.frames, initial=frames, unit="frame", disable=not progress, dynamic_ncols=True)
    last_checkpoint = time.monotonic()
    try:
        with _interruptible() as interrupted:
            while frames < config.frames and not interrupted():
                start = time.perf_counter()
                step = method.iterate()
                seconds = time.perf_counter() - start
                frames, iteration, elapsed = frames + step.frames, iteration + 1, elapsed + seconds
                window.extend(step.returns)
                success = float(np.mean([r > 0 for r in window])) if window else math.nan
                mean_return = float(np.mean(window)) if window else math.nan
                row = {
                    "frames": frames,
                    "iteration": iteration,
                    "time_s": round(elapsed, 3),
                    "fps": round(step.frames / seconds, 1),
                    "success_rate": round(success, 4),
                    "mean_return": round(mean_return, 4),
                    "episodes": len(step.returns),
                }
                metrics.append(row)
                for key in ("fps", "success_rate", "mean_return"):
                    writer.add_scalar(f"train/{key}", row[key], frames)
                for key, value in step.losses.items():
                    writer.add_scalar(key, value, frames)
                bar.update(step.frames)
                bar.set_postfix(fps=f"{row['fps']:.0f}", success=f"{success:.2f}", ret=f"{mean_return:.3f}")
                if time.monotonic() - last_checkpoint >= config.checkpoint_every:
                    checkpoint()
                    last_checkpoint = time.monotonic()
            checkpoint()
            was_interrupted = interrupted()
    finally:
        bar.close()
        writer.close()
        metrics.close()
        method.close()

    result = {"frames": frames, "interrupted": was_interrupted, "metrics": str(out / METRICS)}
    if was_interrupted:
        print(f"interrupted at {frames} frames; checkpoint saved in {out}; continue with --resume --out {out}")
        return result
    if config.eval_episodes:
        mover_policy, looker = method.policy()
        result["eval"] = {
            "learned": evaluate(config, mover_policy, looker, config.eval_episodes, config.seed, device),
            "random": evaluate(config, None, None, config.eval_episodes, config.seed, device),
        }
        _write_json(out / "eval.json", result["eval"] | {"frames": frames, "eval_seed": config.seed})
        for name, values in result["eval"].items():
            print(
                f"{name:>8}: success rate {values['success_rate']:.3f}, mean return {values['mean_return']:.3f} "
                f"({values['episodes']} held-out episodes)"
            )
    return result


def load_run_config(out: str | Path) -> TrainConfig:
    """The config saved in a run directory (``ValueError`` naming the directory when there is none)."""
    path = Path(out) / CONFIG
    if not path.is_file():
        raise ValueError(f"{str(out)!r} holds no run to resume (no {CONFIG})")
    return TrainConfig.from_dict(load_yaml(path))


@contextmanager
def _interruptible():
    """Turn the first Ctrl-C (SIGINT) into a flag the loop polls; a second one interrupts at once."""
    flag = {"set": False}
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return

    def handler(signum, frame):
        if flag["set"]:
            raise KeyboardInterrupt
        flag["set"] = True
        print("\nCtrl-C: finishing this iteration, then saving a checkpoint (Ctrl-C again to abort)", flush=True)

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: flag["set"]
    finally:
        signal.signal(signal.SIGINT, previous)


def _write_json(path: Path, values: dict) -> None:
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps(values, indent=2) + "\n")
