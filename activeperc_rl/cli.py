"""``activeperc-train``: command-line flags generated from the typed configs.

Every :class:`~activeperc_rl.config.TrainConfig` field and every
:class:`~activeperc_env.EnvConfig` field is a flag (``num_envs`` -> ``--num-envs``, booleans get
``--x/--no-x``), documented by the field's docstring. Precedence: defaults, then the YAML preset
given with ``--config``, then the flags. With ``--resume`` the run's own ``config.yaml`` is the
base and only the options in :data:`~activeperc_rl.checkpoint.RESUMABLE` may change.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from contextlib import suppress
from pathlib import Path

from activeperc_env import EnvConfig
from activeperc_env.arguments import ArgumentParser, add_config_flags
from activeperc_env.config import LOOKER_REWARDS
from activeperc_env.names import VERSIONS
from activeperc_env.warp_backend import BACKENDS
from activeperc_rl import portable
from activeperc_rl.checkpoint import CHECKPOINT, load_run_config
from activeperc_rl.collection import COLLECTORS, WorkerError
from activeperc_rl.config import (
    DEVICES,
    E1_LOOKS,
    MOVER_ROLLOUTS,
    OPTIMIZERS,
    TrainConfig,
    load_yaml,
)
from activeperc_rl.losses import LOOKER_CREDITS
from activeperc_rl.methods import METHOD_OPTIONS, METHODS, unused_options
from activeperc_rl.rundir import new_run_dir, remove_if_unused
from activeperc_rl.signals import stop_raises_interrupt

CHOICES = {
    "method": METHODS,
    "device": DEVICES,
    "collector": COLLECTORS,
    "backend": BACKENDS,
    "mover_rollouts": MOVER_ROLLOUTS,
    "e1_looks": E1_LOOKS,
    "looker_credit": LOOKER_CREDITS,
    "looker_optimizer": OPTIMIZERS,
    "looker_reward": LOOKER_REWARDS,
    "version": VERSIONS,
}
RUN_OPTIONS = ("out", "resume", "config", "no_progress")  # the flags that are not config fields


def build_parser() -> argparse.ArgumentParser:
    """The ``activeperc-train`` argument parser."""
    parser = ArgumentParser(
        prog="activeperc-train",
        description="Train the mover and the looker (the paper's meta-evaluation or a baseline) on the "
        "active-perception rooms. With no arguments: the meta method on the default preset.",
    )
    run = parser.add_argument_group("run")
    run.add_argument("--out", help="run directory (default: runs/METHOD-seedS-TIME)")
    run.add_argument("--resume", action="store_true", help="continue the run in --out up to --frames")
    run.add_argument("--config", metavar="PRESET.yaml", help="YAML preset of options (flags override it)")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_config_flags(parser.add_argument_group("training"), TrainConfig, CHOICES, skip=("env",))
    add_config_flags(parser.add_argument_group("environment"), EnvConfig, CHOICES)
    return parser


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """Merge defaults, the preset (or the resumed run's config) and the flags into a ``TrainConfig``."""
    env_names = {f.name for f in dataclasses.fields(EnvConfig)}
    flags = {k: v for k, v in vars(args).items() if k not in RUN_OPTIONS}
    if args.resume:
        if args.out is None:
            raise ValueError("--resume needs --out RUN_DIR")
        if args.config is not None:
            raise ValueError("--resume takes the run's own config.yaml; drop --config")
        return load_run_config(args.out).replace(**flags)
    values = load_yaml(args.config) if args.config is not None else {}
    env = values.pop("env", None)
    env = {} if env is None else env  # "env:" with nothing under it
    if not isinstance(env, dict):
        raise ValueError(f"'env' in {args.config!r} must be a mapping of environment options, got {env!r}")
    env = env | {k: v for k, v in flags.items() if k in env_names}
    values |= {k: v for k, v in flags.items() if k not in env_names}
    return TrainConfig.from_dict(values | {"env": env})


def unused_options_warning(args: argparse.Namespace, config: TrainConfig) -> str | None:
    """A line naming the options set by a flag or in the preset that the run's method does not read, or ``None``
    (also on ``--resume``, whose options are the run's own)."""
    if args.resume:
        return None
    preset = load_yaml(args.config) if args.config is not None else {}
    given = [k for k in vars(args) if k not in RUN_OPTIONS] + list(preset)
    unused = unused_options(config, dict.fromkeys(given))
    if not unused:
        return None
    named = ", ".join(f"{name} (read by {_listed(METHOD_OPTIONS[name])} only)" for name in unused)
    return f"activeperc-train: warning: method {config.method!r} does not use {named}"


def _listed(names) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return " and ".join(filter(None, [", ".join(names[:-1]), names[-1]]))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``activeperc-train``."""
    from activeperc_rl.train import TrainingError, train

    args = build_parser().parse_args(argv)
    # named: the default directory this command made, removed if the run never starts (with runs/ if it made that)
    out, named, made_parent = args.out, None, False
    try:
        # while the run starts or evaluates, SIGTERM and SIGHUP abort it as Ctrl-C does (training saves first)
        with stop_raises_interrupt():
            config = config_from_args(args)
            if config.portable and argv is None:
                portable.restart_pinned("activeperc-train")  # the same command, with torch's kernels pinned
            if warning := unused_options_warning(args, config):
                print(warning, file=sys.stderr)
            if out is None:
                stem = Path("runs") / f"{config.method}-seed{config.seed}-{time.strftime('%Y%m%d-%H%M%S')}"
                made_parent = not stem.parent.exists()
                out = named = str(new_run_dir(stem))
            train(config, out, resume=args.resume, progress=not args.no_progress)
            named = None
    except ValueError as error:
        print(f"activeperc-train: error: {error}", file=sys.stderr)
        return 2
    except (WorkerError, TrainingError, OSError) as error:  # a worker died; training diverged; the disk is full, ...
        print(f"activeperc-train: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # a second stop signal, or one while the run starts or evaluates
        saved = out is not None and (Path(out) / CHECKPOINT).is_file()
        hint = f"; its checkpoint is kept: continue with --resume --out {out}" if saved else ""
        print(f"\nactiveperc-train: interrupted{hint}", file=sys.stderr)
        return 130
    finally:
        if named is not None:
            remove_if_unused(named)
            if made_parent:
                with suppress(OSError):  # not empty: another run is in it, or this one's directory stayed
                    Path(named).parent.rmdir()
    return 0


if __name__ == "__main__":
    sys.exit(main())
