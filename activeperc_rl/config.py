"""The run's settings and the A2C settings, each a typed section of a training config, and how config files are read.

A section is a frozen dataclass with a one-line docstring under each field; its checks name the bad value.
:class:`~activeperc_rl.recipe.TrainConfig` puts the sections together (with the networks', the method's and the
room's), and ``activeperc-train``'s flags and the YAML presets are made from them::

    method: meta
    run:
      frames: 400000
    meta:
      epsilon: 0.1
    env:
      fov: 100
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Hashable
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import yaml

from activeperc_env.checks import is_seed
from activeperc_env.config import is_int, is_number, normalize_numbers, with_field_docs
from activeperc_env.core import MAX_ENVS
from activeperc_env.warp_backend import BACKENDS
from activeperc_rl.collection import COLLECTORS

DEVICES = ("auto", "cpu", "cuda")
LR_SCHEDULES = ("constant", "linear")


class Section:
    """A typed section of a training config (a frozen dataclass): :attr:`NAME` is its key in YAML, and
    :meth:`checks` says which values each field takes; a bad value raises ``ValueError`` naming it."""

    NAME: ClassVar[str]
    """The section's key in a YAML config (``run``, ``a2c``, ``network``, or the method's name)."""

    def __post_init__(self) -> None:
        normalize_numbers(self)
        for name, (ok, expected) in self.checks().items():
            if not ok:
                raise ValueError(f"{self.NAME}.{name}={getattr(self, name)!r} is invalid: expected {expected}")

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check: whether its value is valid, and what a valid one is."""
        return {}

    @classmethod
    def from_dict(cls, values) -> Section:
        """The section from a mapping of its options (``None``: the defaults); an unknown one raises ``ValueError``
        naming it and the known ones."""
        values = {} if values is None else values
        if not isinstance(values, dict):
            raise ValueError(f"'{cls.NAME}' must be a mapping of options, got {values!r}")
        known = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ValueError(f"unknown {cls.NAME} option(s) {unknown}; the {cls.NAME} options are {known}")
        return cls(**values)

    def to_dict(self) -> dict:
        """The section as plain YAML-ready values."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


@with_field_docs
@dataclass(frozen=True)
class RunConfig(Section):
    """The run's own settings: its budget and seed, where it runs, how it collects, checkpoints and evaluates."""

    NAME = "run"

    frames: int = 400_000
    """Environment cycles to train for, counted over every room of every environment (E1 and E2 both)."""
    seed: int = 0
    """Seed of the models, of the exploration and of the training layouts."""
    num_envs: int = 32
    """Rooms stepped together in each environment (E1 and E2 have this many each)."""
    rollout_length: int = 8
    """Cycles per room in one rollout: a rollout holds num_envs * rollout_length frames."""
    device: str = "auto"
    """Where the models run: 'cpu', 'cuda', or 'auto' (cuda when available)."""
    backend: str = "mujoco"
    """The rooms' physics and renderer: 'mujoco' (CPU physics, OpenGL views) or 'warp' (MuJoCo Warp, on the GPU
    when the models are; pip install -e '.[warp]')."""
    torch_threads: int = 1
    """Threads of torch's CPU ops while collecting (0: torch's default); 1 leaves the other cores to the physics
    and the renderer."""
    learner_threads: int = 0
    """Threads of torch's CPU ops during the updates (0: every CPU this process may use); a CPU run repeats
    exactly only with the same value."""
    portable: bool = False
    """Pin torch's CPU kernels (ATen's and oneDNN's at AVX2, MKL's on the branch every vendor runs alike) and the
    renderer (Mesa's softpipe, which compiles nothing for the CPU), and take torch's fused Adam step, so that a
    config and seed train the same run on other x86-64 CPUs with AVX2 (checked on an AMD EPYC against an emulated
    Intel Haswell)."""
    collect_workers: int = 0
    """Workers that step each environment's rooms (0: this process steps them); another number of workers
    trains another run."""
    collector: str = "process"
    """Where the collect_workers run: 'process' (this machine) or 'ray' (on ray_address; num_envs must split evenly
    over the workers)."""
    ray_address: str = "local"
    """The Ray cluster the 'ray' collector joins: 'local' (a Ray instance of the run's own), 'auto' (the one this
    machine is in) or the head's 'HOST:6379'."""
    success_window: int = 100
    """Finished episodes the logged success rate and mean return are averaged over."""
    checkpoint_every: float = 60.0
    """Seconds between checkpoints (one is also written as the run starts, at the end and on Ctrl-C, SIGTERM or
    SIGHUP)."""
    eval_episodes: int = 100
    """Held-out episodes evaluated at the end of training, for the learned, the camera-held and a random policy
    (0: none)."""

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        workers_ok = is_int(self.collect_workers) and is_int(self.num_envs) and 0 <= self.collect_workers
        return {
            "frames": (is_int(self.frames) and self.frames >= 1, "an int >= 1"),
            "seed": (is_seed(self.seed), "an int in [0, 2**63 - 1]"),
            "num_envs": (int_in(self.num_envs, 1, MAX_ENVS), f"an int in 1 .. {MAX_ENVS}"),
            "rollout_length": (int_in(self.rollout_length, 2, 2**20), "an int in 2 .. 1048576"),
            "device": (self.device in DEVICES, f"one of {DEVICES}"),
            "backend": (self.backend in BACKENDS, f"one of {BACKENDS}"),
            "torch_threads": (int_in(self.torch_threads, 0, 4096), "an int in 0 .. 4096"),
            "learner_threads": (int_in(self.learner_threads, 0, 4096), "an int in 0 .. 4096"),
            "portable": (isinstance(self.portable, bool), "true or false"),
            "collect_workers": (
                workers_ok and self.collect_workers <= self.num_envs,
                f"an int in 0 .. num_envs ({self.num_envs})",
            )
            if self.backend != "warp"
            else (self.collect_workers == 0, "0 with backend 'warp', which steps its rooms in this process"),
            "collector": (self.collector in COLLECTORS, f"one of {COLLECTORS}"),
            "ray_address": (
                isinstance(self.ray_address, str) and self.ray_address != "",
                "'local', 'auto' or HOST:PORT",
            ),
            "success_window": (int_in(self.success_window, 1, 2**31), "an int in 1 .. 2**31"),
            "checkpoint_every": (is_number(self.checkpoint_every) and self.checkpoint_every > 0, "seconds > 0"),
            "eval_episodes": (is_int(self.eval_episodes) and self.eval_episodes >= 0, "an int >= 0"),
        }


@with_field_docs
@dataclass(frozen=True)
class A2CConfig(Section):
    """The mover's A2C (TorchRL's ``A2CLoss`` with GAE), which every method shares; also the joint agent's."""

    NAME = "a2c"

    lr: float = 7e-4
    """Adam learning rate of the mover's actor and critic (and of the joint agent)."""
    gamma: float = 0.99
    """Discount factor of the mover's (and IA2C looker's) A2C."""
    gae_lambda: float = 0.95
    """GAE lambda of the A2C advantage."""
    entropy_coeff: float = 0.01
    """Weight of the entropy bonus in the mover's A2C loss (for the joint agent, of its move's entropy)."""
    critic_coeff: float = 0.5
    """Weight of the critic's loss in the A2C loss."""
    max_grad_norm: float = 0.5
    """Gradient-norm clip of every update."""
    reuse_features: bool = True
    """The actor's and the critic's terms and GAE's values read one pass of their shared encoder per update (the same
    loss as TorchRL's A2CLoss to rounding, in half the time); false runs TorchRL's A2CLoss as it ships, as the runs
    saved before this option did."""
    lr_schedule: str = "linear"
    """How every learning rate of the run (the mover's, the looker's, the joint agent's) moves over run.frames:
    'constant', or 'linear' (from its value at the first frame down to 0 at the last)."""

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        return {
            "lr": (finite(self.lr) and self.lr > 0, "a finite number > 0"),
            "gamma": (is_number(self.gamma) and 0.0 <= self.gamma <= 1.0, "a number in [0, 1]"),
            "gae_lambda": (is_number(self.gae_lambda) and 0.0 <= self.gae_lambda <= 1.0, "a number in [0, 1]"),
            "entropy_coeff": (finite(self.entropy_coeff) and self.entropy_coeff >= 0, "a finite number >= 0"),
            "critic_coeff": (finite(self.critic_coeff) and self.critic_coeff > 0, "a finite number > 0"),
            "max_grad_norm": (finite(self.max_grad_norm) and self.max_grad_norm > 0, "a finite number > 0"),
            "reuse_features": (isinstance(self.reuse_features, bool), "true or false"),
            "lr_schedule": (self.lr_schedule in LR_SCHEDULES, f"one of {LR_SCHEDULES}"),
        }


def int_in(value, low: int, high: int) -> bool:
    """Whether ``value`` is an int in ``low .. high`` (upper bounds keep absurd sizes from failing deep in torch)."""
    return is_int(value) and low <= value <= high


def finite(value) -> bool:
    """Whether ``value`` is a real number other than infinity and NaN."""
    return is_number(value) and math.isfinite(value)


def load_yaml(path: str | Path) -> dict:
    """Read a YAML preset (a mapping); a missing, empty or non-UTF-8 file, invalid YAML, a key given twice or a
    non-mapping raises ``ValueError``.

    Numbers in exponent notation without a dot (``3e-5``, ``1E4``) are read as numbers, as YAML 1.2 and most
    users read them, not as the strings of PyYAML's YAML 1.1; a whole number in exponent notation (``2e6``) is
    an int, so that it fits int options such as ``frames``.
    """
    if str(path) == "":
        raise ValueError("config file '' is not a file name: give a YAML file")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"config file {str(path)!r} is a directory: give a YAML file")
    if not path.exists():
        raise ValueError(f"config file {str(path)!r} does not exist")
    if not path.is_file():
        raise ValueError(f"config file {str(path)!r} is not a regular file: give a YAML file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"config file {str(path)!r} is not UTF-8 text (byte {error.start})") from None
    try:
        values = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or " ".join(str(error).split())
        raise ValueError(f"config file {str(path)!r} is not valid YAML{where}: {problem}") from None
    if values is None:
        raise ValueError(f"config file {str(path)!r} holds no options (for the defaults, give no --config)")
    if not isinstance(values, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping of options")
    return values


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader, reading ``3e-5`` as a float and ``2e6`` as an int."""

    def construct_yaml_float(self, node):
        """A float, or an int when written in exponent notation with a whole value (``1e6``)."""
        value = super().construct_yaml_float(node)
        if "e" in str(node.value).lower() and math.isfinite(value) and value.is_integer():
            return int(value)
        return value

    def construct_mapping(self, node, deep=False):
        """A mapping; a key given twice raises ``yaml.constructor.ConstructorError`` at its second place."""
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, Hashable) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"option {key!r} is given twice", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


_Loader.add_constructor("tag:yaml.org,2002:float", _Loader.construct_yaml_float)
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)
