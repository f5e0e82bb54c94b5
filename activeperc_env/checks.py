"""The checks of seeds and actions that every API runs: one place, one wording of their errors."""

from __future__ import annotations

import numpy as np

from activeperc_env.config import is_int

MAX_SEED = 2**63 - 1
"""The largest seed a room takes (seeds travel as int64 through the batched APIs)."""


def is_seed(value, rooms: int = 1) -> bool:
    """Whether ``value`` is a seed for ``rooms`` rooms that get ``value + i`` each: an int in [0, 2**63 - rooms]."""
    return is_int(value) and 0 <= value <= MAX_SEED - (rooms - 1)


def check_seed(seed, name: str = "seed", rooms: int = 1) -> int:
    """``seed`` as an int; ``ValueError`` calling it ``name`` unless :func:`is_seed` (``rooms``: see there)."""
    if isinstance(seed, np.generic) or (isinstance(seed, np.ndarray) and seed.ndim == 0):
        seed = seed.item()
    if not is_seed(seed, rooms):
        why = f"room i gets seed + i, so with {rooms} rooms it must be " if rooms > 1 else "expected "
        raise ValueError(f"{name}={seed!r} is invalid: {why}an int in [0, 2**63 - {rooms}]")
    return int(seed)


def check_actions(
    actions, count: int, n: int, agent: str, meanings: tuple[str, ...] = (), scalar: bool | None = None
) -> np.ndarray:
    """``actions`` as ``count`` int64 indices; ``ValueError`` naming ``agent`` and its action space ``Discrete(n)``
    (with the ``meanings`` of its actions) unless they are one int of it per room. ``scalar``: True takes one int
    only (one agent's step), False an array of ``count`` only (a vector env's), None either when ``count`` is 1."""
    if (
        count == 1
        and scalar is not False
        and (type(actions) is int or isinstance(actions, np.integer))
        and 0 <= actions < n
    ):
        return np.array([actions], dtype=np.int64)  # one agent's step, the common case, without numpy's checks
    array = np.asarray(actions)
    if array.shape == () and count == 1 and scalar is not False:
        array = array.reshape(1)
    elif scalar:
        array = None  # one agent's step takes an int, not an array of one
    if array is None or array.shape != (count,) or not (np.issubdtype(array.dtype, np.integer) or array.size == 0):
        expected = "an int" if count == 1 and scalar is not False else f"{count} ints"
        raise ValueError(
            f"{agent} action(s) {actions!r} invalid: expected {expected} in its action space {_space(n, meanings)}"
        )
    outside = np.flatnonzero((array < 0) | (array >= n))
    if outside.size:
        room = f" of room {outside[0]}" if count > 1 else ""
        raise ValueError(
            f"{agent} action {array[outside[0]].item()!r}{room} is outside its action space {_space(n, meanings)}"
        )
    return array.astype(np.int64)


def _space(n: int, meanings: tuple[str, ...]) -> str:
    """An action space as the errors name it: ``Discrete(3) ('left', 'hold', 'right')``."""
    return " ".join(filter(None, [f"Discrete({n})", str(meanings) if meanings else ""]))
