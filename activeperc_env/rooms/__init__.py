"""The rooms, one record per version (:class:`Room`): ``v0`` to ``v3``, each in its own module.

The core, the adapters, the scripted policies and the docs ask a room's record what it is (its scene, physics,
base, the mover's actions, layout rule, defaults and history); nothing outside this package compares version
numbers. A new room is a new module and one line in :data:`ROOMS`.
"""

from __future__ import annotations

import textwrap

from activeperc_env.rooms import v0, v1, v2, v3
from activeperc_env.rooms.record import Room

ROOMS: dict[int, Room] = {room.version: room for room in (v0.ROOM, v1.ROOM, v2.ROOM, v3.ROOM)}
"""Every room, by version."""
DEFAULT = 3
"""The default room's version: the one in which a learned looker pays."""
LEGACY_DEFAULT = 0
"""The room of a saved config that names none: configs were saved without ``version`` before room v1 existed."""


def mover_actions(version: int = DEFAULT) -> tuple[str, str, str]:
    """What the mover's actions 0, 1 and 2 do in room ``version`` (the default room's when not given)."""
    return ROOMS[version].mover_actions


def version_history(markdown: bool = False) -> str:
    """Every room's version-history entry, newest first: one line each for a docstring, or (``markdown``) the whole
    entries of docs/env.md, with their PettingZoo names and Gymnasium ids."""
    entries = []
    for version in sorted(ROOMS, reverse=True):
        record, default = ROOMS[version], ", the default" if version == DEFAULT else ""
        if not markdown:
            entries.append(f"v{version}{default}: {record.summary}")
            continue
        ids = f"`activeperc/Joint-v{version}`, `activeperc/FixedForward-v{version}`"
        head = f"- **v{version}** ({record.released}, `version={version}`{default}; PettingZoo name `{record.name}`, "
        entries.append(head + f"Gymnasium ids {ids}): {record.summary}")
        entries += [f"  {line}" for line in record.changes.splitlines() if line.strip()]  # inside the list item
    return "\n".join(entries)


def with_version_history(cls):
    """Class decorator for an env class: end its docstring with a ``Version History`` section made from the rooms'
    records (Gymnasium's and PettingZoo's env docstrings end with one)."""
    lines = []
    for entry in version_history().splitlines():
        lines += textwrap.wrap(entry, 112, initial_indent=" " * 8, subsequent_indent=" " * 8, break_on_hyphens=False)
    cls.__doc__ = cls.__doc__.rstrip() + "\n\n    Version History:\n" + "\n".join(lines) + "\n"
    return cls


__all__ = ["DEFAULT", "LEGACY_DEFAULT", "ROOMS", "Room", "mover_actions", "version_history", "with_version_history"]
