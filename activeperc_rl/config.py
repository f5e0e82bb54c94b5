"""The training configuration: one typed dataclass, every default defined here.

The CLI flags of ``activeperc-train`` are generated from these fields (and from
:class:`~activeperc_env.EnvConfig`'s, under ``env``), and YAML presets hold the same names::

    method: meta
    frames: 200000
    env:
      fov: 100
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Hashable
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from activeperc_env import EnvConfig
from activeperc_env.checks import is_seed
from activeperc_env.config import is_int, is_number, normalize_numbers, saved_room, with_field_docs
from activeperc_env.core import MAX_ENVS
from activeperc_env.warp_backend import BACKENDS
from activeperc_rl.atomic import atomic_path
from activeperc_rl.collection import COLLECTORS
from activeperc_rl.envs import MAX_FRAME_STACK
from activeperc_rl.losses import LOOKER_CREDITS
from activeperc_rl.methods import METHODS

DEVICES = ("auto", "cpu", "cuda")
MOVER_ROLLOUTS = ("d1", "all")
E1_LOOKS = ("greedy", "sample")
OPTIMIZERS = ("adam", "sgd")


@with_field_docs
@dataclass(frozen=True)
class TrainConfig:
    """Configuration of one training run; invalid values raise ``ValueError`` naming the field."""

    method: str = "meta"
    """The training method: 'meta' (the paper's meta-evaluation) or a baseline (a class of activeperc_rl.methods)."""
    frames: int = 300_000
    """Environment cycles to train for, counted over every room of every environment (E1 and E2 both)."""
    num_envs: int = 16
    """Rooms stepped together in each environment (E1 and E2 have this many each)."""
    rollout_length: int = 16
    """Cycles per room in one rollout: a rollout holds num_envs * rollout_length frames."""
    seed: int = 0
    """Seed of the models, of the exploration and of the training layouts."""
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
    gamma: float = 0.99
    """Discount factor of the mover's (and IA2C looker's) A2C."""
    gae_lambda: float = 0.95
    """GAE lambda of the A2C advantage."""
    lr: float = 7e-4
    """Adam learning rate of the mover's actor and critic (and of the joint agent)."""
    looker_lr: float = 3e-5
    """Adam learning rate of the looker (phi2 for 'meta', the looker's actor-critic for 'ia2c')."""
    entropy_coeff: float = 0.01
    """Weight of the entropy bonus in the mover's A2C loss (for the joint agent, of its move's entropy)."""
    looker_entropy_coeff: float = 0.0
    """Weight of the entropy bonus in the looker's loss (phi2's REINFORCE, the IA2C looker's A2C; the joint
    agent's look, given its move)."""
    critic_coeff: float = 0.5
    """Weight of the critic's loss in the A2C loss."""
    max_grad_norm: float = 0.5
    """Gradient-norm clip of every update."""
    epsilon: float = 0.3
    """'meta': probability of a uniformly random look in E2 (otherwise argmax of phi2); the paper uses 0.1 and 0.3."""
    alpha: float = 0.05
    """'meta': soft-update rate, phi1 <- alpha phi2 + (1 - alpha) phi1 (the paper's 0.05)."""
    shared_seeds: bool = True
    """'meta': E1 and E2 get the same layout streams (room i's k-th episode is the same layout in both)."""
    resample_d1: bool = True
    """'meta': sample D1 again after the soft update for the A2C step, as the paper does (3 rollouts per
    iteration); False reuses the first D1 (2 rollouts per iteration)."""
    looker_hold_prob: float = 0.95
    """Probability that an untrained looker holds the camera (phi1 and phi2, the IA2C looker, the joint agent's
    look); 1/3 makes every look equally likely."""
    e1_looks: str = "greedy"
    """'meta': how phi1 picks its looks in E1 and at test time: 'greedy' (its argmax) or 'sample' (drawn from its
    distribution)."""
    mover_rollouts: str = "all"
    """'meta': what the mover learns from: 'all' (the first D1 and D2, then the D1 sampled after the soft
    update) or 'd1' (the paper: that D1 only)."""
    looker_importance_weights: bool = False
    """'meta': weight each look's REINFORCE term by pi_phi2 / b, b the epsilon-greedy behaviour that drew it
    (the paper does not)."""
    looker_credit: str = "trajectory"
    """'meta': what each look of D2 is credited with: 'trajectory' (the paper: its trajectory's meta-evaluator),
    'look' (the value the look added, V(s') - V(s_bar)), 'every_look' (expected over the three looks' values) or
    'best_look' (phi2 learns which look's view the critic values most)."""
    looker_optimizer: str = "adam"
    """'meta': phi2's optimizer, 'adam' or 'sgd' (whose steps grow with the meta-evaluator's size)."""
    curriculum_fraction: float = 0.3
    """'curriculum': fraction of the frames spent pre-training the joint agent in a room without obstacles."""
    channels: tuple[int, ...] = (16, 32)
    """Output channels of the encoder's conv layers (kernels 8, 4, 3, ... with strides 4, 2, 1, ...)."""
    hidden_size: int = 256
    """Width of the encoder's output and of the heads' input."""
    bearing_bins: int = 0
    """Bins of the mover's bearing layout (0: none): its networks (and the joint agent's) lay the view's features
    out by bearing from the robot's heading, wherever the camera looks."""
    frame_stack: int = 1
    """Views of the latest cycles that every network reads, stacked on the image's channels (1: the current view
    only): a memory of where the goal was (make_env's frame_stack); needs bearing_bins 0."""
    success_window: int = 100
    """Finished episodes the logged success rate and mean return are averaged over."""
    checkpoint_every: float = 60.0
    """Seconds between checkpoints (one is also written as the run starts, at the end and on Ctrl-C, SIGTERM or
    SIGHUP)."""
    eval_episodes: int = 100
    """Held-out episodes evaluated at the end of training, for the learned, the camera-held and a random policy
    (0: none)."""
    env: EnvConfig = field(default_factory=EnvConfig)
    """The environment (the same for E1 and E2 and for evaluation)."""

    def __post_init__(self) -> None:
        if self.env is None or isinstance(self.env, dict):
            object.__setattr__(self, "env", EnvConfig.from_kwargs(**(self.env or {})))
        elif not isinstance(self.env, EnvConfig):
            raise ValueError(f"TrainConfig.env={self.env!r} is invalid: expected a mapping of environment options")
        if isinstance(self.channels, (list, tuple)):
            object.__setattr__(self, "channels", tuple(int(c) if is_int(c) else c for c in self.channels))
        normalize_numbers(self)
        checks = {
            "method": (self.method in METHODS, f"one of {METHODS}"),
            "frames": (is_int(self.frames) and self.frames >= 1, "an int >= 1"),
            "num_envs": (_int_in(self.num_envs, 1, MAX_ENVS), f"an int in 1 .. {MAX_ENVS}"),
            "rollout_length": (_int_in(self.rollout_length, 2, 2**20), "an int in 2 .. 1048576"),
            "seed": (is_seed(self.seed), "an int in [0, 2**63 - 1]"),
            "device": (self.device in DEVICES, f"one of {DEVICES}"),
            "torch_threads": (_int_in(self.torch_threads, 0, 4096), "an int in 0 .. 4096"),
            "learner_threads": (_int_in(self.learner_threads, 0, 4096), "an int in 0 .. 4096"),
            "portable": (isinstance(self.portable, bool), "true or false"),
            "collect_workers": (
                is_int(self.collect_workers) and is_int(self.num_envs) and 0 <= self.collect_workers <= self.num_envs,
                f"an int in 0 .. num_envs ({self.num_envs})",
            ),
            "collector": (self.collector in COLLECTORS, f"one of {COLLECTORS}"),
            "backend": (
                self.backend in BACKENDS and not (self.backend == "warp" and self.collect_workers),
                f"one of {BACKENDS} ('warp' steps its rooms in this process: collect_workers 0)",
            ),
            "ray_address": (
                isinstance(self.ray_address, str) and self.ray_address != "",
                "'local', 'auto' or HOST:PORT",
            ),
            "gamma": (is_number(self.gamma) and 0.0 <= self.gamma <= 1.0, "a number in [0, 1]"),
            "gae_lambda": (is_number(self.gae_lambda) and 0.0 <= self.gae_lambda <= 1.0, "a number in [0, 1]"),
            "lr": (_finite(self.lr) and self.lr > 0, "a finite number > 0"),
            "looker_lr": (_finite(self.looker_lr) and self.looker_lr > 0, "a finite number > 0"),
            "entropy_coeff": (_finite(self.entropy_coeff) and self.entropy_coeff >= 0, "a finite number >= 0"),
            "looker_entropy_coeff": (
                _finite(self.looker_entropy_coeff) and self.looker_entropy_coeff >= 0,
                "a finite number >= 0",
            ),
            "critic_coeff": (_finite(self.critic_coeff) and self.critic_coeff > 0, "a finite number > 0"),
            "max_grad_norm": (_finite(self.max_grad_norm) and self.max_grad_norm > 0, "a finite number > 0"),
            "epsilon": (is_number(self.epsilon) and 0.0 <= self.epsilon <= 1.0, "a probability in [0, 1]"),
            "shared_seeds": (isinstance(self.shared_seeds, bool), "true or false"),
            "resample_d1": (isinstance(self.resample_d1, bool), "true or false"),
            "looker_importance_weights": (isinstance(self.looker_importance_weights, bool), "true or false"),
            "alpha": (is_number(self.alpha) and 0.0 < self.alpha <= 1.0, "a number in (0, 1]"),
            "looker_hold_prob": (
                is_number(self.looker_hold_prob) and 0.0 < self.looker_hold_prob < 1.0,
                "a probability in (0, 1)",
            ),
            "e1_looks": (self.e1_looks in E1_LOOKS, f"one of {E1_LOOKS}"),
            "looker_credit": (self.looker_credit in LOOKER_CREDITS, f"one of {LOOKER_CREDITS}"),
            "looker_optimizer": (self.looker_optimizer in OPTIMIZERS, f"one of {OPTIMIZERS}"),
            "mover_rollouts": (self.mover_rollouts in MOVER_ROLLOUTS, f"one of {MOVER_ROLLOUTS}"),
            "curriculum_fraction": (
                is_number(self.curriculum_fraction) and 0.0 < self.curriculum_fraction < 1.0,
                "a number in (0, 1)",
            ),
            "channels": (
                isinstance(self.channels, tuple)
                and len(self.channels) >= 1
                and all(_int_in(c, 1, 4096) for c in self.channels),
                "one or more ints in 1 .. 4096",
            ),
            "hidden_size": (_int_in(self.hidden_size, 1, 2**16), "an int in 1 .. 65536"),
            "bearing_bins": (_int_in(self.bearing_bins, 0, 360), "an int in 0 .. 360"),
            "frame_stack": (
                _int_in(self.frame_stack, 1, MAX_FRAME_STACK) and (self.frame_stack == 1 or self.bearing_bins == 0),
                f"an int in 1 .. {MAX_FRAME_STACK}, 1 with bearing_bins (which lays out one view)",
            ),
            "success_window": (_int_in(self.success_window, 1, 2**31), "an int in 1 .. 2**31"),
            "checkpoint_every": (is_number(self.checkpoint_every) and self.checkpoint_every > 0, "seconds > 0"),
            "eval_episodes": (is_int(self.eval_episodes) and self.eval_episodes >= 0, "an int >= 0"),
        }
        for name, (ok, expected) in checks.items():
            if not ok:
                raise ValueError(f"TrainConfig.{name}={getattr(self, name)!r} is invalid: expected {expected}")

    @classmethod
    def from_dict(cls, values: dict) -> TrainConfig:
        """Build a config from a (YAML) mapping, naming any unknown key in a ``ValueError``."""
        if not isinstance(values, dict):
            raise ValueError(f"a training config must be a mapping of options, got {type(values).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            env_names = sorted(set(unknown) & {f.name for f in dataclasses.fields(EnvConfig)})
            hint = f"; {env_names} are environment options: put them under 'env:'" if env_names else ""
            raise ValueError(f"unknown training option(s) {unknown}{hint}; known options: {sorted(known)}")
        return cls(**values)

    @classmethod
    def from_saved(cls, values: dict) -> TrainConfig:
        """The config of a run saved in ``config.yaml`` or a checkpoint: as :meth:`from_dict`, but a saved room
        without ``version`` is v0 (runs saved before room v1 existed trained in v0)."""
        env = values.get("env") if isinstance(values, dict) else None
        if isinstance(env, dict):
            values = values | {"env": saved_room(env)}
        return cls.from_dict(values)

    def to_dict(self) -> dict:
        """The config as plain YAML-ready values (the env config nested under ``env``)."""
        values = dataclasses.asdict(self)
        values["channels"] = list(self.channels)
        return values

    def replace(self, **changes) -> TrainConfig:
        """A copy with ``changes`` applied; env fields may be given by name too (``fov=100``), and a new ``version``
        brings its own defaults for the options that were at the old version's."""
        env_fields = {f.name for f in dataclasses.fields(EnvConfig)}
        env_changes = {k: changes.pop(k) for k in list(changes) if k in env_fields}
        if env_changes.get("version", self.env.version) != self.env.version:
            # another room: the options still at the old version's defaults take the new one's
            for name, by_version in EnvConfig.VERSION_DEFAULTS.items():
                if name not in env_changes and getattr(self.env, name) == by_version[self.env.version]:
                    env_changes[name] = None
        if env_changes:
            changes["env"] = dataclasses.replace(self.env, **env_changes)
        values = self.to_dict() | changes
        return TrainConfig.from_dict(values)


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


def _int_in(value, low: int, high: int) -> bool:
    """Whether ``value`` is an int in ``low .. high`` (upper bounds keep absurd sizes from failing deep in torch)."""
    return is_int(value) and low <= value <= high


def save_yaml(config: TrainConfig, path: str | Path) -> None:
    """Write ``config`` as YAML (written to a temporary file first, then renamed over ``path``)."""
    with atomic_path(path) as temporary:
        temporary.write_text(yaml.safe_dump(config.to_dict(), sort_keys=False))


def _finite(value) -> bool:
    """Whether ``value`` is a real number other than infinity and NaN."""
    return is_number(value) and math.isfinite(value)


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
