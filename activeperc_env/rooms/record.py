"""What a room is: :class:`Room`, the record each room version's module fills in."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from activeperc_env.robot import PlanarBase, WheeledBase


@dataclass(frozen=True)
class Room:
    """One room version: everything that makes it, read by the core, the adapters, the scripted policies and the
    docs. A new room is a new record (``activeperc_env/rooms/vK.py``) and one line in
    :data:`~activeperc_env.rooms.ROOMS`; an old room's record never changes what its episodes are."""

    version: int
    """The room's version, ``EnvConfig(version=...)``, and the ``-vK`` of its Gymnasium ids."""
    released: str
    """The date the room first shipped (ISO 8601)."""
    scene: Path
    """The scene's MJCF file: the room, the boxes and the robot (``activeperc_env/assets/``)."""
    physics_timestep: float
    """Seconds of one MuJoCo step; must equal the scene's ``<option timestep>``."""
    base: type[WheeledBase | PlanarBase]
    """The robot's base (:mod:`activeperc_env.robot`): how a reset places it and how a move drives it."""
    mover_actions: tuple[str, str, str]
    """What the mover's actions 0, 1 and 2 do."""
    shuffle_occluders: bool
    """Layout rule: the occluders trade places at random once placed, so that no box's colour tells where the goal
    lies (:func:`activeperc_env.layout.sample_layout`)."""
    defaults: dict[str, object]
    """The :class:`~activeperc_env.EnvConfig` options whose default is the room's own: a field left ``None`` takes
    its value from here."""
    summary: str
    """One line: what the room is (its version-history entry, as the env docstrings list it)."""
    changes: str
    """The rest of its version-history entry (Markdown): what changed from the room before, and why."""

    @property
    def name(self) -> str:
        """The PettingZoo envs' ``metadata["name"]`` of this room: ``activeperc_vK``."""
        return f"activeperc_v{self.version}"

    @property
    def turns(self) -> bool:
        """Whether the mover's moves turn the base (a base that slides keeps its start heading)."""
        return self.base.TURNS
