"""The environment's configuration: one typed dataclass, every default defined here."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import numbers
import textwrap
from dataclasses import dataclass
from typing import ClassVar

from activeperc_env.names import OCCLUDER_BODIES
from activeperc_env.rooms import DEFAULT, LEGACY_DEFAULT, ROOMS, Room

LOOKER_REWARDS = ("shared", "own_turn", "none")
LAYERS = ("depth", "segmentation")  # the optional image layers of the observation, each an EnvConfig flag
MAX_RANGE_RAYS = 64
MAX_CYCLES = 1_000_000  # an episode of more cycles (over 55 hours at 5 Hz) would, in practice, never end
ROOM_DEFAULTS = tuple(dict.fromkeys(name for room in ROOMS.values() for name in room.defaults))
"""The options whose default is each room's own (``None`` in :class:`EnvConfig` until it is built)."""


def field_docs(cls) -> dict[str, str]:
    """The docstring written under each field of the dataclass ``cls`` (or of the dataclass it inherits the field
    from), read from their source (Python keeps no attribute docstrings at run time)."""
    docs = {}
    for klass in reversed([k for k in cls.__mro__ if dataclasses.is_dataclass(k)]):
        body = ast.parse(textwrap.dedent(inspect.getsource(klass))).body[0].body
        for node, following in zip(body, body[1:], strict=False):
            is_doc = isinstance(following, ast.Expr) and isinstance(following.value, ast.Constant)
            if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and is_doc:
                docs[node.target.id] = " ".join(str(following.value.value).split())
    fields = {f.name for f in dataclasses.fields(cls)}
    return {name: doc for name, doc in docs.items() if name in fields}  # not the class's constants


def with_field_docs(cls):
    """Class decorator for a config dataclass: add an ``Attributes`` section to its docstring, each field with its
    default and the docstring under it, so that ``help()`` and IDEs show what each field means."""
    docs = field_docs(cls)
    lines = [cls.__doc__.rstrip(), "", "Attributes:"]
    for f in dataclasses.fields(cls):
        text = f"{f.name} ({f.type}, default {shown_default(cls, f)}): {docs.get(f.name, '')}"
        lines += textwrap.wrap(text, 100, initial_indent="    ", subsequent_indent="        ", break_on_hyphens=False)
    cls.__doc__ = "\n".join(lines) + "\n"
    return cls


def shown_default(cls, f: dataclasses.Field, as_flag: bool = False) -> str:
    """The default of field ``f`` of the config class ``cls`` as help texts show it (``repr``, or ``as_flag`` as one
    would type it: ``16 32``, ``shared``); where it is the room's own (:attr:`activeperc_env.rooms.Room.defaults`),
    each room's: ``30.0 (v3), 30.0 (v2), ...``, the default room's first."""
    if f.name in getattr(cls, "PER_ROOM", ()):
        order = [DEFAULT] + [v for v in sorted(ROOMS, reverse=True) if v != DEFAULT]
        return ", ".join(f"{ROOMS[v].defaults[f.name]!r} (v{v})" for v in order)
    default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    if not as_flag:
        return repr(default)
    return " ".join(map(str, default)) if isinstance(default, tuple) else str(default)


@with_field_docs
@dataclass(frozen=True)
class EnvConfig:
    """Configuration of the active-perception room; invalid values raise ``ValueError``.

    A field that defaults to ``None`` takes its room's default (:attr:`activeperc_env.rooms.Room.defaults`) when it
    is built.
    """

    PER_ROOM: ClassVar[tuple[str, ...]] = ROOM_DEFAULTS
    """The fields whose default is each room's own."""

    fov: float = 60.0
    """Horizontal field of view of the robot's camera, in degrees (the paper uses 60 and 100)."""
    width: int = 80
    """Width of the first-person image, in pixels."""
    height: int = 60
    """Height of the first-person image, in pixels."""
    num_obstacles: int = 3
    """Occluder boxes placed between the start and the goal (0 to 6; 0 gives an empty room)."""
    heading_spread: float | None = None
    """The robot starts facing within this many degrees of the goal's bearing (180: any way at all)."""
    goal_distance: float | None = None
    """Distance along the room (x) between the robot's start and the goal, in metres (2.5 to 4.6; the room is 6 m
    long)."""
    max_cycles: int | None = None
    """Cycles (one move and one look each) before the episode is truncated."""
    pan_range: float = 120.0
    """The camera pans within [-pan_range, +pan_range] degrees of the robot's heading."""
    pan_step: float = 30.0
    """Degrees the camera turns for one 'pan left' or 'pan right' action."""
    control_hz: float = 5.0
    """Mover decisions per simulated second; a period must be a whole number of the version's physics steps
    (50 / k Hz in v1-v3, 200 / k Hz in v0)."""
    forward_speed: float = 0.75
    """Speed of the 'forward' action, in m/s (in v0 the wheels' rim speed)."""
    turn_speed: float | None = None
    """Yaw rate of 'turn left' and 'turn right', in degrees per second (v3's base slides and never turns: it takes
    only its default)."""
    range_rays: int | None = None
    """Rays of the range sensor (the observation's 'range'; 0: none), spread evenly from -90 to +90 degrees of the
    heading; they meet walls and occluders, never the goal."""
    range_max: float = 2.0
    """Distance at which the range sensor's rays stop, in metres: a ray that meets nothing reads range_max."""
    depth: bool = False
    """Add 'depth' to the observation: (height, width) float32, the distance in metres along the camera's axis to
    what each pixel shows (0 where nothing is seen)."""
    segmentation: bool = False
    """Add 'segmentation' to the observation: (height, width) int32, the id of the model's geom each pixel shows
    (-1 where none is seen)."""
    looker_reward: str = "shared"
    """'shared': the looker receives the mover's reward; 'own_turn': the same, but given at the looker's own turn in
    the AEC env (for libraries that credit each agent with the reward of its own step, as Tianshou does); 'none':
    the looker's reward is always 0."""
    version: int = DEFAULT
    """The room (:mod:`activeperc_env.rooms`): 3, where the base slides and never turns, so only the camera sees to
    the side; 2 and 1, where the base turns; or 0, the paper-faithful room of the Figure 1 pilot."""

    def __post_init__(self) -> None:
        if not (is_int(self.version) and self.version in ROOMS):  # first: the other defaults depend on it
            raise ValueError(f"EnvConfig.version={self.version!r} is invalid: expected one of {tuple(ROOMS)}")
        for name, value in ROOMS[int(self.version)].defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)
        normalize_numbers(self)
        timestep = self.room.physics_timestep
        checks = {
            "fov": is_number(self.fov) and 0.0 < self.fov < 180.0,
            "width": is_int(self.width) and 8 <= self.width <= 1024,
            "height": is_int(self.height) and 8 <= self.height <= 1024,
            "num_obstacles": is_int(self.num_obstacles) and 0 <= self.num_obstacles <= len(OCCLUDER_BODIES),
            "heading_spread": is_number(self.heading_spread) and 0.0 <= self.heading_spread <= 180.0,
            "goal_distance": is_number(self.goal_distance) and 2.5 <= self.goal_distance <= 4.6,
            "max_cycles": is_int(self.max_cycles) and 1 <= self.max_cycles <= MAX_CYCLES,
            "pan_range": is_number(self.pan_range) and 0.0 <= self.pan_range <= 180.0,
            "pan_step": is_number(self.pan_step) and 0.0 < self.pan_step <= 180.0,
            "control_hz": is_number(self.control_hz)
            and 0.5 <= self.control_hz <= 1 / timestep
            and _whole_steps(self.control_hz, timestep),
            "forward_speed": is_number(self.forward_speed) and 0.0 < self.forward_speed <= 3.0,
            "turn_speed": is_number(self.turn_speed)
            and 0.0 < self.turn_speed <= 720.0
            and (self.room.turns or self.turn_speed == self.room.defaults["turn_speed"]),
            "range_rays": is_int(self.range_rays) and 0 <= self.range_rays <= MAX_RANGE_RAYS,
            "range_max": is_number(self.range_max) and 0.2 <= self.range_max <= 10.0,
            "depth": isinstance(self.depth, bool),
            "segmentation": isinstance(self.segmentation, bool),
            "looker_reward": isinstance(self.looker_reward, str) and self.looker_reward in LOOKER_REWARDS,
        }
        allowed = {
            "fov": "a number of degrees in (0, 180)",
            "width": "an int in [8, 1024]",
            "height": "an int in [8, 1024]",
            "num_obstacles": f"an int in [0, {len(OCCLUDER_BODIES)}]",
            "heading_spread": "degrees in [0, 180]",
            "goal_distance": "metres in [2.5, 4.6]",
            "max_cycles": f"an int in [1, {MAX_CYCLES:,}]",
            "pan_range": "degrees in [0, 180]",
            "pan_step": "degrees in (0, 180]",
            "control_hz": f"a rate in [0.5, {1 / timestep:g}] Hz whose period is a whole number of the v{self.version} "
            f"room's {timestep * 1000:g} ms physics steps ({1 / timestep:g} / k Hz, e.g. {_rates(timestep)})",
            "forward_speed": "m/s in (0, 3]",
            "turn_speed": "degrees per second in (0, 720]"
            if self.room.turns
            else f"its default, {self.room.defaults['turn_speed']:g}: the v{self.version} room's base never turns",
            "range_rays": f"an int in [0, {MAX_RANGE_RAYS}]",
            "range_max": "metres in [0.2, 10]",
            "depth": "True or False",
            "segmentation": "True or False",
            "looker_reward": f"one of {LOOKER_REWARDS}",
        }
        for field, ok in checks.items():
            if not ok:
                raise ValueError(f"EnvConfig.{field}={getattr(self, field)!r} is invalid: expected {allowed[field]}")

    @classmethod
    def from_kwargs(cls, hint: str = "", /, **kwargs) -> EnvConfig:
        """Build a config from keyword arguments; an unknown one raises :class:`UnknownOptionError` naming it,
        worded as Python words an unexpected keyword argument, ``hint`` after it."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(kwargs) - known)
        if unknown:
            names = ", ".join(repr(name) for name in unknown)
            what = "arguments {}: not env options" if len(unknown) > 1 else "argument {}: not an env option"
            raise UnknownOptionError(f"unexpected keyword {what.format(names)}{hint}; known options: {sorted(known)}")
        return cls(**kwargs)

    @property
    def room(self) -> Room:
        """The record of the room this config builds (:mod:`activeperc_env.rooms`)."""
        return ROOMS[self.version]

    @property
    def fovy(self) -> float:
        """MuJoCo's vertical field of view (degrees) for the horizontal ``fov`` and the aspect."""
        half = math.radians(self.fov) / 2
        return math.degrees(2 * math.atan(math.tan(half) * self.height / self.width))


class UnknownOptionError(TypeError, ValueError):
    """An env option that :class:`EnvConfig` does not have: a ``TypeError`` as for any unexpected keyword argument
    (tools such as TorchRL's ``GymEnv`` drop an argument the env refuses that way), and a ``ValueError`` as for
    any other bad option."""


def saved_room(values: dict) -> dict:
    """The options of a room config as saved (a state, a run): one saved before room v1 existed has no ``version``
    and is of v0's rooms."""
    return {"version": LEGACY_DEFAULT} | values


def physics_steps(config: EnvConfig) -> int:
    """MuJoCo steps in one control period of ``config`` (the nearest whole number)."""
    return _steps(config.control_hz, config.room.physics_timestep)


def _steps(control_hz: float, timestep: float) -> int:
    return max(1, round(1.0 / (control_hz * timestep)))


def _whole_steps(control_hz: float, timestep: float) -> bool:
    """Whether one control period of ``control_hz`` is a whole number of ``timestep`` physics steps (to 0.1 % of a
    step)."""
    return abs(1.0 / (control_hz * timestep) - _steps(control_hz, timestep)) < 1e-3


def _rates(timestep: float) -> str:
    """Some control rates a physics step of ``timestep`` seconds admits, as text: '50, 25, 12.5, 10, 5, ...'."""
    return ", ".join(f"{1 / (k * timestep):g}" for k in (1, 2, 4, 5, 10, 20, 25, 50))


def is_int(value) -> bool:
    """Whether ``value`` is an integer (Python's or numpy's), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_number(value) -> bool:
    """Whether ``value`` is a real number (Python's or numpy's), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def normalize_numbers(config) -> None:
    """Turn the numbers in a frozen config dataclass's ``int`` and ``float`` fields (numpy's too) into Python ints
    and floats, in place, so that the config compares, prints and saves as plain values; anything else is left
    for the config's checks to reject."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        kind = f.type.removesuffix(" | None")
        if kind == "int" and is_int(value):
            object.__setattr__(config, f.name, int(value))
        elif kind == "float" and is_number(value):
            object.__setattr__(config, f.name, float(value))
