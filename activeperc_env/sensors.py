"""The range sensor of room v1: distances along horizontal rays from the base to the nearest wall or occluder.

The rays leave the base's centre at angles spread evenly from -90 to +90 degrees of its heading and stop at
``range_max``. They are cast in the plane, against the room's walls and the occluders' footprints (axis-aligned
squares, as every box in the room stands upright and unrotated), so a reading is exact and costs no physics. The
goal is not an obstacle to them: only the camera can find it.
"""

from __future__ import annotations

import numpy as np

from activeperc_env import names


def ray_angles(rays: int) -> np.ndarray:
    """The rays' angles relative to the heading, radians, right (-pi/2) to left (+pi/2); one ray looks ahead."""
    if rays == 1:
        return np.zeros(1)
    return np.linspace(-np.pi / 2, np.pi / 2, rays)


def cast(
    xy: np.ndarray, heading: np.ndarray, occluders: np.ndarray, angles: np.ndarray, range_max: float
) -> np.ndarray:
    """Distances from each base along each ray to the first wall or occluder, capped at ``range_max``.

    Args:
        xy: (n, 2) base positions, metres.
        heading: (n,) base yaw, radians.
        occluders: (n, k, 2) centres of the occluders in use.
        angles: (m,) ray angles relative to the heading (:func:`ray_angles`).
        range_max: the rays' length, metres.

    Returns:
        (n, m) float32 distances in [0, range_max] (0 for a ray that starts inside a box).
    """
    theta = heading[:, None] + angles[None, :]
    dx, dy = np.cos(theta), np.sin(theta)  # (n, m)
    x, y = xy[:, :1], xy[:, 1:2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_x, inv_y = 1.0 / dx, 1.0 / dy  # +-inf along an axis
        # the walls' inner faces: where the ray leaves the room's rectangle (never across an axis it runs along)
        to_x = np.where(dx == 0, np.inf, (np.copysign(names.ROOM_HALF_X, dx) - x) * inv_x)
        to_y = np.where(dy == 0, np.inf, (np.copysign(names.ROOM_HALF_Y, dy) - y) * inv_y)
        distance = np.fmin(np.fmin(to_x, to_y), range_max)
        # the slab test of every ray against every occluder's square at once: (n, k, m) entry and exit distances
        half = names.OCCLUDER_HALF[0]
        low = (occluders - half - xy[:, None])[..., None]  # (n, k, 2, 1): each square's near corner, from the base
        along_x, along_y = inv_x[:, None], inv_y[:, None]
        x1, x2 = low[:, :, 0] * along_x, (low[:, :, 0] + 2 * half) * along_x
        y1, y2 = low[:, :, 1] * along_y, (low[:, :, 1] + 2 * half) * along_y
        enter = np.fmax(np.fmax(np.fmin(x1, x2), np.fmin(y1, y2)), 0.0)
        leave = np.fmin(np.fmax(x1, x2), np.fmax(y1, y2))
        hits = np.where(leave >= enter, enter, np.inf)
        distance = np.fmin(distance, np.fmin.reduce(hits, axis=1, initial=np.inf))
    return np.clip(distance, 0.0, range_max).astype(np.float32)
