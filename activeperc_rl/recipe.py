"""A whole training recipe, :class:`TrainConfig`: the method and its options, the run, A2C, the networks and the
room; the named presets; and how a recipe is read from YAML, from flags and from a saved run.

The defaults are the recipe that works in the default room (room v3, ``meta`` with the ``best_look`` credit and
the mover's bearing layout, 400,000 frames of 32 rooms x 8 cycles, learning rates falling linearly). The paper's
algorithm as written is the preset ``paper``, and the Figure 1 pilot's room and recipe the preset ``pilot``
(``activeperc-train --preset paper``; files in ``activeperc_rl/presets/``). In YAML each section is a mapping; a
preset may hold the options of several methods (a run reads its own method's)::

    method: meta
    run: {frames: 1000000, seed: 3}
    meta: {epsilon: 0.1}
    env: {fov: 100}
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import torch

from activeperc_env import EnvConfig
from activeperc_env.config import saved_room
from activeperc_env.rooms import ROOMS
from activeperc_rl.config import A2CConfig, RunConfig, Section, load_yaml
from activeperc_rl.method_base import Method
from activeperc_rl.methods import METHOD_CLASSES, METHODS
from activeperc_rl.models import NetworkConfig, stacked_views

SECTIONS: dict[str, type[Section]] = {cls.NAME: cls for cls in (RunConfig, A2CConfig, NetworkConfig)}
"""The sections every method reads, by their key in YAML (the method's own and ``env`` come beside them)."""
ENV = "env"
PRESETS = Path(__file__).resolve().parent / "presets"
"""The named presets: ``NAME.yaml`` each (``activeperc-train --preset NAME``)."""
LEGACY_DEFAULTS = {
    "frames": 300_000,
    "num_envs": 16,
    "rollout_length": 16,
    "looker_lr": 3e-5,
    "looker_credit": "trajectory",
    "bearing_bins": 0,
    "reuse_features": False,
    "lr_schedule": "constant",
}
"""The defaults, before 2026-12-05, of the options whose default has changed since: a run saved then (a flat
``config.yaml``) that lacks one of them was trained with this value."""
ADDED_OPTIONS = {"a2c": {"reuse_features": False, "lr_schedule": "constant"}}
"""The options added since runs were saved by section, each with the value that a saved run lacking it ran with."""


def _option_owners() -> dict[str, str]:
    """Each option of the shared sections and of the room, by name: the key of its section."""
    owners = {f.name: name for name, cls in SECTIONS.items() for f in dataclasses.fields(cls)}
    return owners | {f.name: ENV for f in dataclasses.fields(EnvConfig)}


def _option_readers() -> dict[str, tuple[str, ...]]:
    """Each method option by name: the methods that have it, in :data:`~activeperc_rl.methods.METHODS`' order."""
    names = dict.fromkeys(f.name for cls in METHOD_CLASSES.values() for f in dataclasses.fields(cls.Options))
    return {
        name: tuple(m for m, cls in METHOD_CLASSES.items() if name in {f.name for f in dataclasses.fields(cls.Options)})
        for name in names
    }


OPTION_SECTIONS = _option_owners()
"""The section (``run``, ``a2c``, ``network`` or ``env``) of every option that is not a method's own."""
METHOD_OPTIONS = _option_readers()
"""Each method option by name: the methods that have it."""


@dataclass(frozen=True)
class TrainConfig:
    """A training recipe: the method and its options, the run's settings, A2C's, the networks' and the room.

    Each part is a typed config (a mapping of its options, or ``None`` for its defaults, is taken too): ``options``
    is the method's own (:attr:`activeperc_rl.methods.Meta.Options` and so on), the others are shared.
    :meth:`from_options` builds one from flat option names (``TrainConfig.from_options(frames=10_000, fov=100)``).
    """

    method: str = "meta"
    """The training method: 'meta' (the paper's meta-evaluation) or a baseline (:mod:`activeperc_rl.methods`)."""
    options: Section | None = None
    """The method's options (its ``Options``; ``None``: their defaults)."""
    run: RunConfig = field(default_factory=RunConfig)
    """The run's own settings (:class:`~activeperc_rl.config.RunConfig`)."""
    a2c: A2CConfig = field(default_factory=A2CConfig)
    """The mover's A2C (:class:`~activeperc_rl.config.A2CConfig`)."""
    network: NetworkConfig = field(default_factory=NetworkConfig)
    """The networks (:class:`~activeperc_rl.models.NetworkConfig`)."""
    env: EnvConfig = field(default_factory=EnvConfig)
    """The room (the same for every environment of the run and for evaluation)."""

    def __post_init__(self) -> None:
        if self.method not in METHOD_CLASSES:
            raise ValueError(f"method={self.method!r} is invalid: expected one of {METHODS}")
        options_class = METHOD_CLASSES[self.method].Options
        parts = {"options": options_class} | SECTIONS
        for name, cls in parts.items():
            value = getattr(self, name)
            if value is None or isinstance(value, dict):
                object.__setattr__(self, name, cls.from_dict(value))
            elif isinstance(value, Section) and not isinstance(value, cls):
                raise ValueError(
                    f"TrainConfig.{name}={value!r} is invalid: method {self.method!r} takes {cls.__name__}"
                )
            elif not isinstance(value, cls):
                raise ValueError(f"'{cls.NAME}' must be a mapping of options, got {value!r}")
        if self.env is None or isinstance(self.env, dict):
            object.__setattr__(self, ENV, EnvConfig.from_kwargs(**(self.env or {})))
        elif not isinstance(self.env, EnvConfig):
            raise ValueError(f"TrainConfig.env={self.env!r} is invalid: expected a mapping of environment options")
        e2_rooms, workers = getattr(self.options, "e2_rooms", 0), self.run.collect_workers
        if 0 < e2_rooms < workers:
            raise ValueError(
                f"meta.e2_rooms={e2_rooms} is invalid: expected 0 or at least run.collect_workers={workers} (each of "
                "E2's workers steps one room or more)"
            )

    @classmethod
    def from_options(cls, **options) -> TrainConfig:
        """The defaults with ``options`` given by name, as the flags name them (``method``, ``frames``, ``epsilon``,
        ``fov``, ...; ``env`` may also be an :class:`EnvConfig` or a mapping of room options): see :meth:`replace`."""
        env = options.pop(ENV, None)
        return cls(method=options.pop("method", "meta"), env=env).replace(**options)

    @classmethod
    def from_dict(cls, values: dict, flags: dict | None = None) -> TrainConfig:
        """A config from a nested mapping (a YAML preset: ``method``, the sections, the method's section, ``env``),
        then ``flags`` (flat option names: :meth:`replace`) on top; the room's flags join its mapping before the room
        is built, so that a ``version`` flag brings that room's defaults. A preset may hold several methods'
        sections; the run reads its own. Every value is checked as written, also where a flag replaces it: an unknown
        key or a bad value raises ``ValueError`` naming it."""
        if not isinstance(values, dict):
            raise ValueError(f"a training config must be a mapping of options, got {type(values).__name__}")
        flags = dict(flags or {})
        method = flags.pop("method", values.get("method", "meta"))
        known = {"method", ENV, *SECTIONS, *METHODS}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown key(s) {unknown} in the config{_where(unknown)}; its keys are {sorted(known)}")
        room = {name: flags.pop(name) for name in list(flags) if OPTION_SECTIONS.get(name) == ENV}
        env = {} if values.get(ENV) is None else values[ENV]  # "env:" with nothing under it: the room's defaults
        if not isinstance(env, dict):
            raise ValueError(f"'{ENV}' must be a mapping of room options, got {env!r}")
        for name in sorted(set(values) & set(METHODS) - {method}):  # other methods' sections, checked as written
            METHOD_CLASSES[name].Options.from_dict(values[name])
        if room:
            EnvConfig.from_kwargs(**env)  # the room as written, before the flags change it
        parts = {name: values.get(name) for name in SECTIONS}
        config = cls(method=method, options=values.get(method), env=env | room, **parts)
        return config.replace(**flags) if flags else config

    @classmethod
    def from_saved(cls, values: dict) -> TrainConfig:
        """The config of a run saved in ``config.yaml`` or a checkpoint. A run saved before the sections existed (its
        options flat, 2026-12-05 and earlier) is read with the defaults of its day for the options it lacks
        (:data:`LEGACY_DEFAULTS`; a room without ``version`` is v0), and the options its method did not read are
        dropped."""
        if not isinstance(values, dict):
            raise ValueError(f"a saved training config must be a mapping of options, got {type(values).__name__}")
        if not isinstance(values.get(ENV), dict):
            return cls.from_dict(values)
        values = values | {ENV: saved_room(values[ENV])}
        if any(name in values for name in SECTIONS):
            saved = {name: values.get(name) or {} for name in ADDED_OPTIONS}
            added = {
                name: options | saved[name] for name, options in ADDED_OPTIONS.items() if isinstance(saved[name], dict)
            }
            return cls.from_dict(values | added)
        flat = LEGACY_DEFAULTS | {key: value for key, value in values.items() if key != ENV}
        method = flat.pop("method", "meta")
        if method not in METHOD_CLASSES:
            raise ValueError(f"method={method!r} is invalid: expected one of {METHODS}")
        own = {f.name for f in dataclasses.fields(METHOD_CLASSES[method].Options)}
        flat = {key: value for key, value in flat.items() if key not in METHOD_OPTIONS or key in own}
        return cls(method=method, env=values[ENV]).replace(**flat)

    @property
    def stacked_views(self) -> int:
        """Views of the latest cycles in each observation of the run's envs
        (:func:`~activeperc_rl.models.stacked_views`)."""
        return stacked_views(self.network, self.options)

    def to_dict(self) -> dict:
        """The config as plain YAML-ready values: ``method``, then each section (the method's under its name)."""
        sections = {name: getattr(self, name).to_dict() for name in SECTIONS}
        return {
            "method": self.method,
            **sections,
            self.method: self.options.to_dict(),
            ENV: dataclasses.asdict(self.env),
        }

    def replace(self, **changes) -> TrainConfig:
        """A copy with ``changes`` given by option name (``frames=10_000``, ``epsilon=0.1``, ``fov=100``); a new
        ``method`` starts from its own options' defaults, and a new ``version`` brings the room's own defaults for
        the options that were at the old room's. An option that no section has, or that the method does not read,
        raises ``ValueError`` naming it."""
        method = changes.pop("method", self.method)
        if method not in METHOD_CLASSES:
            raise ValueError(f"method={method!r} is invalid: expected one of {METHODS}")
        own = {f.name for f in dataclasses.fields(METHOD_CLASSES[method].Options)}
        grouped: dict[str, dict] = {}
        for name, value in changes.items():
            if name in own:
                grouped.setdefault("options", {})[name] = value
            elif name in OPTION_SECTIONS:
                grouped.setdefault(OPTION_SECTIONS[name], {})[name] = value
            elif name in METHOD_OPTIONS:
                readers = listed(METHOD_OPTIONS[name])
                raise ValueError(f"method {method!r} does not read {name} (an option of {readers} only)")
            else:
                raise ValueError(f"unknown training option {name!r}")
        options = self.options if method == self.method else METHOD_CLASSES[method].Options()
        parts = {"options": options} | {name: getattr(self, name) for name in SECTIONS}
        for name, values in grouped.items():
            if name != ENV:
                parts[name] = dataclasses.replace(parts[name], **values)
        return TrainConfig(method=method, env=_new_room(self.env, grouped.get(ENV, {})), **parts)


def _new_room(env: EnvConfig, changes: dict) -> EnvConfig:
    """``env`` with ``changes``; where they change the room's version, the options still at the old room's defaults
    take the new room's."""
    if not changes:
        return env
    if "version" in changes and ROOMS.get(changes["version"]) not in (None, env.room):  # another room
        old = env.room.defaults
        changes = {name: None for name, value in old.items() if getattr(env, name) == value} | changes
    return dataclasses.replace(env, **changes)


def _where(keys: list[str]) -> str:
    """Where options given at a config's top level belong: ``; put 'frames' under 'run:'``."""
    places = [f"{key!r} under '{OPTION_SECTIONS[key]}:'" for key in keys if key in OPTION_SECTIONS]
    places += [
        f"{key!r} under its method's section ('{listed(METHOD_OPTIONS[key])}:')"
        for key in keys
        if key in METHOD_OPTIONS
    ]
    return f"; put {', '.join(places)}" if places else ""


def listed(names) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    names = list(names)
    return " and ".join(filter(None, [", ".join(names[:-1]), names[-1]]))


def preset(name: str) -> dict:
    """The named preset ``name`` (a file of :data:`PRESETS`) as a nested mapping; ``ValueError`` naming the known
    ones for another name."""
    names = sorted(path.stem for path in PRESETS.glob("*.yaml"))
    if name not in names:
        raise ValueError(f"preset {name!r} does not exist: the presets are {names}")
    return load_yaml(PRESETS / f"{name}.yaml")


def merged(base: dict, top: dict) -> dict:
    """The nested config mapping ``base`` with ``top``'s options over it, section by section."""
    out = dict(base)
    for key, value in top.items():
        both = isinstance(value, dict) and isinstance(out.get(key), dict)
        out[key] = {**out[key], **value} if both else value
    return out


def make_method(
    config: TrainConfig, device: torch.device, start: bool = True, cls: type[Method] | None = None
) -> Method:
    """Build the configured method's networks and optimizers, and (``start``) its environments and collectors;
    ``cls``: a subclass of the method's class to build instead (an experiment's variant)."""
    parts = {name: getattr(config, name) for name in SECTIONS}
    method = (cls or METHOD_CLASSES[config.method])(config.options, env=config.env, device=device, **parts)
    if start:
        try:
            method.start()
        except BaseException:
            method.close()  # the collectors it had started
            raise
    return method
