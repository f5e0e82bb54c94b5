"""Offscreen rendering of many simulations: first-person views drawn as tiles of one buffer.

One GL context and one ``MjrContext`` serve every view. Each view is drawn into its own tile
(viewport) of the offscreen buffer and the whole buffer is read back once per batch, which is
far cheaper than one read-back per view. Shadows, reflections, skybox and multisampling are
off: they cost most of the frame time and carry nothing the agents need.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager

import mujoco
import numpy as np

from activeperc_env import names
from activeperc_env.gl import gl_context

MAX_BUFFER = 4096  # largest offscreen side we ask of the GL driver
MAP_SIZE = (320, 240)  # width, height of the bird's-eye map
CONE_LENGTH = 1.2  # metres of view cone drawn on the map
HEADING_LENGTH = 0.5  # metres of the line that shows the base's heading on the map


class TiledRenderer:
    """Renders first-person views of many simulations and bird's-eye maps of one.

    Args:
        model: the compiled scene (its offscreen buffer size is set here).
        width, height: size of one first-person view in pixels.
        max_views: the views the offscreen buffer is sized for: one pass draws them all as tiles, up to a
            buffer of ``MAX_BUFFER`` pixels a side; a ``render`` call with more views takes several passes.
        fov: horizontal field of view of the robot's camera in degrees, for the maps' view cone.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, max_views: int, fov: float):
        self.width, self.height, self.fov = width, height, fov
        self.cols = max(1, min(max_views, MAX_BUFFER // width))
        self.rows = max(1, min(math.ceil(max_views / self.cols), MAX_BUFFER // height))
        # the buffer holds the tiles alone: llvmpipe draws a view that fills its buffer (one room's) a tenth faster
        buf_w, buf_h = self.cols * width, self.rows * height
        self._model = model
        self._gl = None
        self._gl = gl_context(buf_w, buf_h)
        with self._current():
            self._ctx = _offscreen_context(model, buf_w, buf_h)
        self._map_ctx: mujoco.MjrContext | None = None  # the maps' buffer, made at the first map
        self._scene = mujoco.MjvScene(model, maxgeom=200)
        for flag in (
            mujoco.mjtRndFlag.mjRND_SHADOW,
            mujoco.mjtRndFlag.mjRND_REFLECTION,
            mujoco.mjtRndFlag.mjRND_SKYBOX,
        ):
            self._scene.flags[flag] = 0
        self._data = mujoco.MjData(model)
        self._eye_opt = mujoco.MjvOption()
        self._eye_opt.geomgroup[names.ROBOT_GROUP] = 0
        self._map_opt = mujoco.MjvOption()
        self._eye = _fixed_camera(model, names.EYE_CAMERA)
        self._map = _fixed_camera(model, names.MAP_CAMERA)
        self._pixels = np.empty(buf_h * buf_w * 3, dtype=np.uint8)  # read-back buffer
        self._tile_pixels = np.empty((height, width, 3), dtype=np.uint8)  # read-back buffer of tile 0 alone
        # where each tile lies in the buffer (tiles fill rows from the bottom left), and the areas read back by the
        # last tile they hold
        self._tile_rects = [
            mujoco.MjrRect(col * width, row * height, width, height)
            for row in range(self.rows)
            for col in range(self.cols)
        ]
        self._areas: dict[int, mujoco.MjrRect] = {}

    @property
    def views_per_pass(self) -> int:
        """Views drawn before one read-back: view ``k`` of a call lands in tile ``k % views_per_pass``."""
        return self.cols * self.rows

    def render(self, qpos: np.ndarray, mocap_pos: np.ndarray, tiles: np.ndarray | None = None) -> np.ndarray:
        """First-person views of the simulations whose states are given.

        Args:
            qpos: (n, nq) joint positions.
            mocap_pos: (n, nmocap, 3) positions of the goal and occluders.
            tiles: optional (n,) distinct tiles (below ``views_per_pass``) to draw the views in, all in one
                pass; by default view ``k`` is drawn in tile ``k % views_per_pass``. The rasteriser rounds
                edges and shades a little differently in another tile (pixels one level darker or lighter, rarely
                an edge pixel of another colour), so the tile is part of what a view looks like.

        Returns:
            (n, height, width, 3) uint8 images, top row first.
        """
        n = len(qpos)
        out = np.empty((n, self.height, self.width, 3), dtype=np.uint8)
        if tiles is not None and n:
            tiles = np.asarray(tiles, dtype=np.int64)
            if tiles.shape != (n,) or tiles.min() < 0 or tiles.max() >= self.views_per_pass or len(set(tiles)) != n:
                raise ValueError(
                    f"tiles {tiles.tolist()} invalid: expected {n} distinct tiles in 0 .. {self.views_per_pass - 1}"
                )
        previous = self._gl.make_current()  # as _current() does, without a generator's cost (twice a cycle)
        try:
            if n == 1 and (tiles is None or tiles[0] == 0):  # an env's one view: read into ``out`` straight
                self._draw_tiles(qpos, mocap_pos, (0,))
                mujoco.mjr_readPixels(self._tile_pixels, None, self._tile_rects[0], self._ctx)
                out[0] = self._tile_pixels[::-1]
                return out
            for views, drawn in self._passes(n, tiles):
                self._draw_tiles(qpos[views], mocap_pos[views], drawn)
                out[views] = self._read_rgb(drawn)
        finally:
            self._gl.restore(previous)
        return out

    def _passes(self, n: int, tiles: np.ndarray | None) -> Iterator[tuple[slice | np.ndarray, list[int]]]:
        """The passes that draw ``n`` views: which views (an index of them) each draws, in which tiles. In the given
        ``tiles``, all in one pass; by default view ``k`` in tile ``k % views_per_pass``."""
        if tiles is not None:
            if n:
                yield slice(None), tiles.tolist()
            return
        for first in range(0, n, self.views_per_pass):
            count = min(self.views_per_pass, n - first)
            yield slice(first, first + count), list(range(count))

    @contextmanager
    def _current(self) -> Iterator[None]:
        """This renderer's GL context, current in the calling thread for the block; after it, what was current
        before (as a rule nothing: the next call may come from another thread, as for an env created in one
        thread and stepped in another; or another renderer's, when the garbage collector closed this one in the
        middle of that renderer's draw)."""
        previous = self._gl.make_current()
        try:
            yield
        finally:
            self._gl.restore(previous)

    def _draw_tiles(self, qpos, mocap_pos, tiles: list[int], after_each=None) -> list:
        """Draw the views of the states given, view ``k`` in tile ``tiles[k]`` of the buffer; return what
        ``after_each()`` gave after each view (nothing without it)."""
        kept = []
        for q, mocap, tile in zip(qpos, mocap_pos, tiles, strict=True):
            self._pose(q, mocap)
            mujoco.mjv_updateScene(
                self._model,
                self._data,
                self._eye_opt,
                None,
                self._eye,
                mujoco.mjtCatBit.mjCAT_ALL,
                self._scene,
            )
            mujoco.mjr_render(self._tile_rects[tile], self._scene, self._ctx)
            if after_each is not None:
                kept.append(after_each())
        return kept

    def _read_rgb(self, tiles: list[int]) -> np.ndarray:
        """The colours of ``tiles``, read back at once: (len(tiles), height, width, 3) uint8."""
        area = self._area(tiles)
        pixels = self._pixels[: area.height * area.width * 3].reshape(area.height, area.width, 3)
        mujoco.mjr_readPixels(pixels, None, area, self._ctx)
        return self._of_tiles(pixels, area, tiles)

    def _area(self, tiles: list[int]) -> mujoco.MjrRect:
        """The part of the buffer that holds ``tiles``: whole rows of tiles from the bottom left."""
        top = max(tiles)
        if top not in self._areas:
            used_rows = top // self.cols + 1
            used_cols = self.cols if used_rows > 1 else top + 1
            self._areas[top] = mujoco.MjrRect(0, 0, used_cols * self.width, used_rows * self.height)
        return self._areas[top]

    def _of_tiles(self, pixels: np.ndarray, area: mujoco.MjrRect, tiles: list[int]) -> np.ndarray:
        """The views of ``tiles`` in ``pixels`` (an ``area`` read back, (height, width, ...)): (len(tiles), height,
        width, ...), top row first."""
        # GL rows run bottom-up: tile (row, col) starts at pixel row row * height from the bottom
        rows, cols, rest = area.height // self.height, area.width // self.width, pixels.shape[2:]
        grid = pixels.reshape(rows, self.height, cols, self.width, *rest)[:, ::-1]
        return grid.swapaxes(1, 2).reshape(-1, self.height, self.width, *rest)[tiles]

    def render_layers(self, qpos: np.ndarray, mocap_pos: np.ndarray, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The layers ``names`` (``"depth"``: :meth:`render_depth`, ``"segmentation"``: :meth:`render_segmentation`)
        of the views of the simulations given, a pass each."""
        return {name: getattr(self, f"render_{name}")(qpos, mocap_pos) for name in names}

    def render_depth(self, qpos: np.ndarray, mocap_pos: np.ndarray) -> np.ndarray:
        """Depth of the first-person views of the simulations given: (n, height, width) float32, the distance in
        metres along the camera's axis to what each pixel shows, 0 where nothing is seen."""
        extent = self._model.stat.extent
        near, far = self._model.vis.map.znear * extent, self._model.vis.map.zfar * extent
        buffer = self._layers(qpos, mocap_pos, segmentation=False)  # OpenGL's depth in [0, 1], not linear
        depth = near / (1.0 - buffer * (1.0 - near / far))
        return np.where(buffer < 1.0, depth, 0.0).astype(np.float32)  # the far plane: nothing seen

    def render_segmentation(self, qpos: np.ndarray, mocap_pos: np.ndarray) -> np.ndarray:
        """What each pixel of the first-person views of the simulations given shows: (n, height, width) int32 ids
        of the model's geoms, -1 where no geom is seen."""
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
        self._scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
        try:
            return self._layers(qpos, mocap_pos, segmentation=True)
        finally:
            self._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 0
            self._scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 0

    def _layers(self, qpos: np.ndarray, mocap_pos: np.ndarray, segmentation: bool) -> np.ndarray:
        """Draw the views and read back, per pixel, the depth buffer or (``segmentation``) the geom seen."""
        n = len(qpos)
        out = np.empty((n, self.height, self.width), dtype=np.int32 if segmentation else np.float32)
        with self._current():
            for views, tiles in self._passes(n, None):
                if segmentation:
                    # each view's geom ids by the colour code its scene drew them in
                    geoms = self._draw_tiles(qpos[views], mocap_pos[views], tiles, self._geoms_by_code)
                    rgb = self._read_rgb(tiles).astype(np.int64)
                    codes = rgb[..., 0] | rgb[..., 1] << 8 | rgb[..., 2] << 16  # the scene's geom index + 1
                    codes = np.minimum(codes, self._scene.maxgeom + 1)
                    out[views] = np.stack([table[code] for table, code in zip(geoms, codes, strict=True)])
                else:
                    self._draw_tiles(qpos[views], mocap_pos[views], tiles)
                    area = self._area(tiles)
                    depth = np.empty((area.height, area.width), dtype=np.float32)
                    mujoco.mjr_readPixels(None, depth, area, self._ctx)
                    out[views] = self._of_tiles(depth, area, tiles)
        return out

    def _geoms_by_code(self) -> np.ndarray:
        """For each colour code of the scene's segmentation (its geom index + 1; 0: nothing), the model geom it
        shows, -1 for none; codes past the scene's geoms map to -1 too."""
        table = np.full(self._scene.maxgeom + 2, -1, dtype=np.int32)
        for geom in self._scene.geoms[: self._scene.ngeom]:
            if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM and geom.segid >= 0:
                table[geom.segid + 1] = geom.objid
        return table

    def render_map(self, qpos: np.ndarray, mocap_pos: np.ndarray) -> np.ndarray:
        """Bird's-eye map of one simulation, with the camera's view cone (orange) and the base's heading (a white
        line from its centre) drawn in.

        Args:
            qpos: (nq,) joint positions.
            mocap_pos: (nmocap, 3) positions of the goal and occluders.

        Returns:
            (240, 320, 3) uint8 image, north (+y) up.
        """
        self._pose(qpos, mocap_pos)
        mujoco.mjv_updateScene(
            self._model,
            self._data,
            self._map_opt,
            None,
            self._map,
            mujoco.mjtCatBit.mjCAT_ALL,
            self._scene,
        )
        self._add_view_cone()
        self._add_heading()
        width, height = MAP_SIZE
        rect = mujoco.MjrRect(0, 0, width, height)
        pixels = np.empty((height, width, 3), dtype=np.uint8)
        with self._current():
            if self._map_ctx is None:
                self._map_ctx = _offscreen_context(self._model, width, height)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._map_ctx)
            try:
                mujoco.mjr_render(rect, self._scene, self._map_ctx)
                mujoco.mjr_readPixels(pixels, None, rect, self._map_ctx)
            finally:
                mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        return pixels[::-1].copy()

    def close(self) -> None:
        """Release the GL resources (none where the context is no longer usable: in a fork of a rendering process,
        what it inherited is left alone; at exit, after MuJoCo terminated the EGL display, they are gone with it)."""
        if self._gl is None:
            return
        if self._gl.usable():
            # missing when the constructor failed after the GL context
            contexts = [c for c in (getattr(self, "_ctx", None), getattr(self, "_map_ctx", None)) if c is not None]
            if contexts:
                # MuJoCo frees the GL objects by their names in whatever context is current: make it ours, or
                # another renderer's framebuffer and textures of the same names are deleted and it draws wrong views
                with self._current():
                    for context in contexts:
                        context.free()
            self._gl.free()
        self._gl = None

    def _pose(self, qpos: np.ndarray, mocap_pos: np.ndarray) -> None:
        """Load one simulation's positions and compute the poses the renderer reads."""
        self._data.qpos[:] = qpos
        self._data.mocap_pos[:] = mocap_pos
        mujoco.mj_kinematics(self._model, self._data)
        mujoco.mj_camlight(self._model, self._data)

    def _add_view_cone(self) -> None:
        """Append two orange lines from the camera along the edges of its horizontal field of view."""
        cam_id = self._eye.fixedcamid
        origin = self._data.cam_xpos[cam_id].copy()
        forward = -self._data.cam_xmat[cam_id].reshape(3, 3)[:, 2]
        yaw = math.atan2(forward[1], forward[0])
        for edge in (-0.5, 0.5):
            angle = yaw + math.radians(self.fov) * edge
            tip = origin + CONE_LENGTH * np.array([math.cos(angle), math.sin(angle), 0.0])
            self._add_line(origin, tip, (1.0, 0.55, 0.0))

    def _add_heading(self) -> None:
        """Append a white line from the base's centre along its heading (the cone shows heading plus pan)."""
        base = self._model.body(names.BASE_BODY).id
        origin = self._data.xpos[base] + np.array([0.0, 0.0, 0.1])  # above the chassis, so that it is drawn on top
        forward = self._data.xmat[base].reshape(3, 3)[:, 0] * np.array([1.0, 1.0, 0.0])
        self._add_line(origin, origin + HEADING_LENGTH * forward / max(np.linalg.norm(forward), 1e-9), (1.0, 1.0, 1.0))

    def _add_line(self, start: np.ndarray, end: np.ndarray, rgb: tuple[float, float, float]) -> None:
        """Append a 3-pixel line from ``start`` to ``end`` to the scene (nothing when the scene is full)."""
        if self._scene.ngeom >= self._scene.maxgeom:
            return
        geom = self._scene.geoms[self._scene.ngeom]
        mujoco.mjv_initGeom(
            geom,
            mujoco.mjtGeom.mjGEOM_LINE,
            np.zeros(3),
            np.zeros(3),
            np.zeros(9),
            np.array([*rgb, 1.0], dtype=np.float32),
        )
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, 3.0, start, end)
        self._scene.ngeom += 1

    def __del__(self):
        if not sys.is_finalizing():  # at interpreter exit the GL library may be gone; the contexts die with the process
            self.close()


def side_by_side(map_image: np.ndarray, view: np.ndarray) -> np.ndarray:
    """A video frame: the bird's-eye map with the first-person view on its right, the view scaled up by a whole
    factor to at most the map's height (a taller view stays as it is), on black, with even sides (as H.264 needs)."""
    scale = max(1, map_image.shape[0] // view.shape[0])
    big = view.repeat(scale, axis=0).repeat(scale, axis=1)
    height = max(map_image.shape[0], big.shape[0])
    width = map_image.shape[1] + big.shape[1]
    canvas = np.zeros((height + height % 2, width + width % 2, 3), dtype=np.uint8)
    canvas[: map_image.shape[0], : map_image.shape[1]] = map_image
    canvas[: big.shape[0], map_image.shape[1] : width] = big
    return canvas


def _offscreen_context(model: mujoco.MjModel, width: int, height: int) -> mujoco.MjrContext:
    """A MuJoCo render context of ``model`` in the current GL context, drawing into an offscreen buffer of ``width``
    x ``height`` pixels (the model's own buffer size is left as it was)."""
    visual = model.vis.global_
    size = visual.offwidth, visual.offheight
    visual.offwidth, visual.offheight = width, height
    try:
        context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
    finally:
        visual.offwidth, visual.offheight = size
    mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
    return context


def _fixed_camera(model: mujoco.MjModel, name: str) -> mujoco.MjvCamera:
    """An ``MjvCamera`` that looks through the model's named camera."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
    cam.fixedcamid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
    return cam
