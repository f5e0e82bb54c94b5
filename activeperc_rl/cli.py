"""``activeperc-train``: command-line flags generated from the typed configs.

Every option of a :class:`~activeperc_rl.recipe.TrainConfig` section is a flag (``num_envs`` -> ``--num-envs``,
booleans get ``--x/--no-x``), documented by the field's docstring: the run's settings, A2C's, the networks', each
method's (a flag the chosen method does not read is an error) and the room's. Precedence: the defaults, then the
named ``--preset``, then the YAML file given with ``--config``, then the flags. With ``--resume`` the run's own
``config.yaml`` is the base and only the options in :data:`~activeperc_rl.runtime.checkpoint.RESUMABLE` may change.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from contextlib import suppress
from pathlib import Path

import yaml

from activeperc_env import EnvConfig
from activeperc_env.arguments import ArgumentParser, add_config_flags, add_field_flag
from activeperc_env.config import LOOKER_REWARDS, field_docs, shown_default
from activeperc_env.rooms import ROOMS
from activeperc_env.warp_backend import BACKENDS
from activeperc_rl.collection import COLLECTORS, WorkerError
from activeperc_rl.config import DEVICES, load_yaml
from activeperc_rl.losses import LOOKER_CREDITS
from activeperc_rl.methods import E1_LOOKS, METHOD_CLASSES, METHODS, MOVER_ROLLOUTS, OPTIMIZERS
from activeperc_rl.recipe import METHOD_OPTIONS, PRESETS, SECTIONS, TrainConfig, listed, merged, preset
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.checkpoint import CHECKPOINT, load_run_config
from activeperc_rl.runtime.rundir import new_run_dir, remove_if_unused
from activeperc_rl.runtime.signals import stop_raises_interrupt

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
    "version": tuple(ROOMS),
}
RUN_OPTIONS = ("out", "resume", "preset", "config", "print_config", "no_progress")  # the flags that are not options
GROUPS = {"run": "the run", "a2c": "A2C (every method's mover)", "network": "networks"}


def build_parser() -> argparse.ArgumentParser:
    """The ``activeperc-train`` argument parser."""
    parser = ArgumentParser(
        prog="activeperc-train",
        description="Train the mover and the looker (the paper's meta-evaluation or a baseline) in the active-"
        "perception rooms. With no arguments: meta with the recipe that works in the default room (v3), 400,000 "
        "frames, then the learned policy, the same mover with the camera held forward and random play on 100 "
        "held-out layouts.",
    )
    names = sorted(path.stem for path in PRESETS.glob("*.yaml"))
    command = parser.add_argument_group("command")
    command.add_argument("--out", help="run directory (default: runs/METHOD-seedS-TIME)")
    command.add_argument("--resume", action="store_true", help="continue the run in --out up to --frames")
    command.add_argument(
        "--preset",
        choices=names,
        help="a named preset (activeperc_rl/presets/): 'paper' is the "
        "paper's algorithm as written, 'pilot' the Figure 1 pilot's room and recipe",
    )
    command.add_argument(
        "--config", metavar="PRESET.yaml", help="YAML file of options (over --preset; flags override it)"
    )
    command.add_argument("--print-config", action="store_true", help="print the config as YAML and exit")
    command.add_argument("--no-progress", action="store_true", help="no progress bar")
    command.add_argument(
        "--method",
        choices=METHODS,
        default=argparse.SUPPRESS,
        help="the training method: 'meta' (the paper's meta-evaluation) or a baseline (default: meta)",
    )
    for name, cls in SECTIONS.items():
        add_config_flags(parser.add_argument_group(GROUPS[name]), cls, CHOICES)
    _add_method_flags(parser.add_argument_group("method options (each read only by the methods named)"))
    add_config_flags(parser.add_argument_group("room"), EnvConfig, CHOICES)
    return parser


def _add_method_flags(group) -> None:
    """One flag per method option, whichever methods have it; its help names them and each one's default."""
    for name, methods in METHOD_OPTIONS.items():
        docs = {method: field_docs(METHOD_CLASSES[method].Options)[name] for method in methods}
        if len(set(docs.values())) == 1:
            doc = f"{docs[methods[0]]} [{', '.join(methods)}]"
        else:
            doc = " ".join(f"[{method}] {text}" for method, text in docs.items())
        add_field_flag(group, _field(METHOD_CLASSES[methods[0]].Options, name), doc, method_default(name), CHOICES)


def method_default(name: str) -> str:
    """The default of the method option ``name`` as ``--help`` shows it: one value, or each method's where they
    differ (``3e-4 (meta), 3e-5 (ia2c)``)."""
    shown = {
        method: shown_default(METHOD_CLASSES[method].Options, _field(METHOD_CLASSES[method].Options, name), True)
        for method in METHOD_OPTIONS[name]
    }
    if len(set(shown.values())) == 1:
        return next(iter(shown.values()))
    return ", ".join(f"{value} ({method})" for method, value in shown.items())


def _field(cls, name: str) -> dataclasses.Field:
    """The field ``name`` of the dataclass ``cls``."""
    return next(f for f in dataclasses.fields(cls) if f.name == name)


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """Merge the defaults, the preset, the YAML file (or the resumed run's config) and the flags into a
    ``TrainConfig``."""
    flags = {k: v for k, v in vars(args).items() if k not in RUN_OPTIONS}
    if args.resume:
        if args.out is None:
            raise ValueError("--resume needs --out RUN_DIR")
        if args.config is not None or args.preset is not None:
            raise ValueError("--resume takes the run's own config.yaml; drop --config and --preset")
        return load_run_config(args.out).replace(**flags)
    values = preset(args.preset) if args.preset is not None else {}
    if args.config is not None:
        values = merged(values, load_yaml(args.config))
    method = flags.get("method", values.get("method", "meta"))
    own = {f.name for f in dataclasses.fields(METHOD_CLASSES.get(method, METHOD_CLASSES["meta"]).Options)}
    for name in flags:
        if name in METHOD_OPTIONS and name not in own:
            readers = listed(METHOD_OPTIONS[name])
            raise ValueError(
                f"--{name.replace('_', '-')} is not an option of method {method!r} (only of {readers}): drop it, "
                f"or train one of those with --method"
            )
    return TrainConfig.from_dict(values, flags)


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
            if args.print_config:
                print(yaml.safe_dump(config.to_dict(), sort_keys=False), end="")
                return 0
            if config.run.portable and argv is None:
                portable.restart_pinned("activeperc-train")  # the same command, with torch's kernels pinned
            if out is None:
                stem = Path("runs") / f"{config.method}-seed{config.run.seed}-{time.strftime('%Y%m%d-%H%M%S')}"
                made_parent = not stem.parent.exists()
                out = named = str(new_run_dir(stem))
            train(config, out, resume=args.resume, progress=not args.no_progress)
            named = None
    except ValueError as error:
        print(f"activeperc-train: error: {error}", file=sys.stderr)
        return 2
    except (WorkerError, TrainingError, OSError) as error:  # a worker died; training diverged; the disk is full, ...
        print(f"activeperc-train: error: {error}", file=sys.stderr)
        if isinstance(error, WorkerError) and argv is None:  # the command, not a caller of main()
            # with torch's shared-memory manager dead (a helper of the workers), freeing the tensors this process
            # shared would abort it at exit: the run's files are closed, so it exits without Python's clean-up
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(1)
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
