"""The MuJoCo Warp backend: the rooms' physics and first-person views batched on a Warp device (a GPU, or the CPU).

``Simulator(config, num_envs, backend="warp", device="cuda")`` steps every room's physics with ``mujoco_warp`` and
draws the eye camera with its ray-traced batch renderer; the episode logic (layouts, reward, termination) is the
simulator's own, shared with the default backend. Needs the ``warp`` extra.
"""

from __future__ import annotations

import copy
import functools
import importlib.util
import logging
from collections.abc import Callable

import mujoco
import mujoco.batch
import numpy as np

from activeperc_env import names

BACKENDS = ("mujoco", "warp")
LAYER_OUTPUTS = {"depth": "depth", "segmentation": "seg"}  # a layer's name: the render context's name of it
LAYER_DTYPES = {"depth": np.float32, "segmentation": np.int32}
STEPPED = ("qpos", "qvel", "ctrl", "qacc_warmstart", "mocap_pos", "mocap_quat")
"""The fields of a room's state that a step reads, copied to the device before it."""
ADVANCED = ("qpos", "qvel", "qacc_warmstart")
"""The fields of :data:`STEPPED` that a step changes, copied back after it (the simulator alone sets the others)."""


def check_backend(backend: str, device: str) -> None:
    """``ValueError`` naming ``backend`` or ``device`` when this machine cannot run them."""
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r} is invalid: expected one of {BACKENDS}")
    if backend == "mujoco":
        if device != "cpu":
            raise ValueError(f"device={device!r} is invalid for backend='mujoco': it runs on the CPU ('cpu')")
        return
    if importlib.util.find_spec("mujoco_warp") is None:
        raise ValueError("backend='warp' needs MuJoCo Warp, which is not installed: pip install -e '.[warp]'")
    if not isinstance(device, str) or device.split(":")[0] not in ("cpu", "cuda"):
        raise ValueError(f"device={device!r} is invalid: expected 'cpu' or 'cuda' (or 'cuda:N')")
    if device.startswith("cuda"):
        warp, _ = _warp()
        index, gpus = device.partition(":")[2] or "0", warp.get_cuda_device_count()
        if not index.isdigit() or int(index) >= gpus:
            raise ValueError(f"device={device!r} is invalid: Warp sees {gpus} CUDA GPU(s) (device='cpu' runs, slowly)")


def _warp():
    """Warp and MuJoCo Warp, imported on first use."""
    import warp

    if warp.config.log_level == logging.INFO:  # Warp's default logs every kernel it loads; a choice of yours stays
        warp.config.log_level = logging.WARNING
    import mujoco_warp

    return warp, mujoco_warp


def replay(graphs: dict, key, device: str, work: Callable[[], None]) -> None:
    """Run ``work`` (launches of Warp kernels on fixed arrays) on ``device``: on a GPU as a CUDA graph, captured
    under ``key`` in ``graphs`` at its second run (the first loads its kernels) and replayed after, which saves
    launching every kernel from Python."""
    warp, _ = _warp()
    with warp.ScopedDevice(device):
        if not device.startswith("cuda") or key not in graphs:
            graphs.setdefault(key, None)
            work()
            return
        if graphs[key] is None:
            with warp.ScopedCapture(device=device) as capture:  # records the launches without running them
                work()
            graphs[key] = capture.graph
        warp.capture_launch(graphs[key])


@functools.cache
def _rgb_bytes_kernel():
    """The Warp kernel that unpacks the renderer's ABGR words of one camera into (world, y, x, rgb) bytes."""
    warp, _ = _warp()

    @warp.kernel
    def rgb_bytes(packed: warp.array2d(dtype=warp.uint32), first: int, out: warp.array4d(dtype=warp.uint8)):
        world, pixel = warp.tid()
        word = packed[world, first + pixel]
        y, x = pixel // out.shape[2], pixel % out.shape[2]
        out[world, y, x, 0] = warp.uint8((word >> warp.uint32(16)) & warp.uint32(0xFF))
        out[world, y, x, 1] = warp.uint8((word >> warp.uint32(8)) & warp.uint32(0xFF))
        out[world, y, x, 2] = warp.uint8(word & warp.uint32(0xFF))

    return rgb_bytes


def warp_model(model: mujoco.MjModel):
    """The scene on the current Warp device (MuJoCo Warp needs the midphase, which only speeds collisions up)."""
    _, mujoco_warp = _warp()

    model = copy.copy(model)
    model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_MIDPHASE)
    return mujoco_warp.put_model(model), model


class WarpBatch(mujoco.batch.Batch):
    """A :class:`mujoco.batch.Batch` whose :meth:`step` runs on a Warp device: the rooms' state lives in the batch's
    rows as on the default backend (resets, copies and checkpoints work alike), a step copies the stepped fields
    (:data:`STEPPED`) to one ``mujoco_warp`` data of all rooms, steps every room and keeps the changed fields
    (:data:`ADVANCED`) of the rooms ``ids``."""

    def __init__(self, model: mujoco.MjModel, nsim: int, nthread: int = 0, device: str = "cpu"):
        warp, mujoco_warp = _warp()
        super().__init__(model, nsim, nthread=nthread)
        self.device = device
        with warp.ScopedDevice(device):
            self.warp_model, self.warp_host_model = warp_model(model)
            self._warp_data = mujoco_warp.make_data(self.warp_host_model, nworld=nsim)
        self._host_rows = {name: self.bind(name) for name in ("time", *STEPPED)}
        self._graphs = {}  # nstep -> the CUDA graph of that many steps (on a GPU)

    def step(self, ids=None, nstep: int = 1, stage=mujoco.mjtStage.mjSTAGE_NONE) -> None:
        """Advance the rooms ``ids`` (all when ``None``) by ``nstep`` physics steps; the others keep their state."""
        if stage != mujoco.mjtStage.mjSTAGE_NONE:
            raise ValueError(f"stage={stage!r} is invalid: the warp backend computes no stages after a step")
        warp, _ = _warp()
        ids = np.arange(self.nsim) if ids is None else np.asarray(ids)
        with warp.ScopedDevice(self.device):
            for name in STEPPED:
                getattr(self._warp_data, name).assign(self._host_rows[name].astype(np.float32))
            self.advance(nstep)
            for name in ADVANCED:
                self._host_rows[name][ids] = getattr(self._warp_data, name).numpy()[ids]
        self._host_rows["time"][ids] += nstep * self.model.opt.timestep

    def advance(self, nstep: int) -> None:
        """``nstep`` physics steps of every room's state on the device; the batch's rows are left as they were."""
        _, mujoco_warp = _warp()

        def steps() -> None:
            for _ in range(nstep):
                mujoco_warp.step(self.warp_model, self._warp_data)

        replay(self._graphs, nstep, self.device, steps)


class WarpRenderer:
    """First-person views of many rooms drawn by MuJoCo Warp's batch renderer; maps by the OpenGL renderer.

    Args:
        batch: the rooms' physics, whose scene on the device the renderer shares.
        width, height: size of one view in pixels.
        max_views: the views one call draws at most in one pass (more take several).
        fov: horizontal field of view in degrees (for the maps' view cone).
        depth, segmentation: whether each pass also draws the views' depth and geom ids (for
            :meth:`render_layers`).
    """

    def __init__(
        self,
        batch: WarpBatch,
        width: int,
        height: int,
        max_views: int,
        fov: float,
        depth: bool = False,
        segmentation: bool = False,
    ):
        warp, mujoco_warp = _warp()
        self.width, self.height, self.fov, self.device = width, height, fov, batch.device
        self.views_per_pass = max_views
        self._mj_model = model = batch.model
        self._map_renderer = None
        self._model, host_model = batch.warp_model, batch.warp_host_model
        eye = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, names.EYE_CAMERA)
        with warp.ScopedDevice(self.device):
            self._data = mujoco_warp.make_data(host_model, nworld=max_views)
            self._context = mujoco_warp.create_render_context(
                host_model,
                nworld=max_views,
                cam_res=(width, height),
                render_rgb=True,
                render_depth=depth,
                render_seg=segmentation,
                cam_active=[camera == eye for camera in range(model.ncam)],
                enabled_geom_groups=[0, 1],  # the eye does not see the robot's own geoms (group 2)
            )
            self._rgb = warp.zeros((max_views, height, width, 3), dtype=warp.uint8)
        # the views' bytes on the host: one page-locked buffer that a GPU's pass is copied into, reused by every pass;
        # on Warp's CPU device the very array
        self._host_rgb = warp.empty_like(self._rgb, device="cpu", pinned=True) if batch.device != "cpu" else self._rgb
        self._first_pixel = int(self._context.rgb_adr.numpy()[0])  # the eye's pixels in the renderer's rows
        drawn = {"depth": depth, "segmentation": segmentation}
        self._layer_rows = {}  # each layer drawn: the render context's rows of it, and the eye's pixels in them
        for name in (name for name, wanted in drawn.items() if wanted):
            first = int(getattr(self._context, f"{LAYER_OUTPUTS[name]}_adr").numpy()[0])
            rows = getattr(self._context, f"{LAYER_OUTPUTS[name]}_data")
            self._layer_rows[name] = rows, slice(first, first + width * height)
        self._graphs = {}  # the CUDA graph of a pass (on a GPU)
        self._lent = False  # whether device_views lent the views of the last pass

    def render(self, qpos: np.ndarray, mocap_pos: np.ndarray, tiles: np.ndarray | None = None) -> np.ndarray:
        """First-person views of the rooms whose states are given: (n, height, width, 3) uint8 (``tiles`` is
        the OpenGL renderer's and changes nothing here)."""
        out = np.empty((len(qpos), self.height, self.width, 3), dtype=np.uint8)
        for first in range(0, len(qpos), self.views_per_pass):
            last = min(len(qpos), first + self.views_per_pass)
            self._draw(qpos[first:last], mocap_pos[first:last], out[first:last])
        return out

    def _draw(self, qpos: np.ndarray, mocap_pos: np.ndarray, out: np.ndarray) -> None:
        """Up to ``views_per_pass`` views in one pass of the renderer, into ``out``."""
        warp, _ = _warp()
        with warp.ScopedDevice(self.device):
            self._load_and_draw(qpos, mocap_pos)
            out[...] = self.views_on_host(len(qpos))

    def device_views(self, qpos: np.ndarray, mocap_pos: np.ndarray):
        """First-person views of up to ``views_per_pass`` rooms whose states are given, left on the device: an (n,
        height, width, 3) uint8 Warp array of the renderer's own buffer, which the next pass overwrites (it first
        waits for the device to finish what was asked of these views: a copy ``torch.from_dlpack`` read, say)."""
        warp, _ = _warp()
        if len(qpos) > self.views_per_pass:
            raise ValueError(f"{len(qpos)} views are more than one pass draws ({self.views_per_pass})")
        if not len(qpos):
            return self._rgb[:0]
        with warp.ScopedDevice(self.device):
            self._load_and_draw(qpos, mocap_pos)
        self._lent = True
        return self._rgb[: len(qpos)]

    def _load_and_draw(self, qpos: np.ndarray, mocap_pos: np.ndarray) -> None:
        """Put up to ``views_per_pass`` rooms' states in the renderer's worlds (the unused ones repeat the last) and
        draw them."""
        warp, _ = _warp()
        if self._lent:  # work on any stream may still read the views device_views lent
            warp.synchronize_device(self.device)
            self._lent = False
        if len(qpos) < self.views_per_pass:
            rows = np.minimum(np.arange(self.views_per_pass), len(qpos) - 1)
            qpos, mocap_pos = qpos[rows], mocap_pos[rows]
        self._data.qpos.assign(qpos.astype(np.float32))
        self._data.mocap_pos.assign(mocap_pos.astype(np.float32))
        self.draw()

    def views_on_host(self, n: int) -> np.ndarray:
        """The bytes of the first ``n`` views of the last pass, as a host array that the next pass overwrites."""
        warp, _ = _warp()
        if self._host_rgb is not self._rgb:
            warp.copy(self._host_rgb, self._rgb, count=n * self.height * self.width * 3)
            warp.synchronize_device(self.device)  # a copy to page-locked memory returns before it is done
        return self._host_rgb.numpy()[:n]

    def draw(self) -> None:
        """Draw the views of every world of the renderer's data on the device, as bytes (:meth:`render` reads them)."""
        replay(self._graphs, "pass", self.device, self._pass)

    def _pass(self) -> None:
        """The kernels of :meth:`draw`."""
        warp, mujoco_warp = _warp()
        mujoco_warp.kinematics(self._model, self._data)
        mujoco_warp.camlight(self._model, self._data)
        mujoco_warp.refit_bvh(self._model, self._data, self._context)
        mujoco_warp.render(self._model, self._data, self._context)
        words = self.width * self.height
        warp.launch(
            _rgb_bytes_kernel(),
            dim=(self.views_per_pass, words),
            inputs=[self._context.rgb_data, self._first_pixel],
            outputs=[self._rgb],
        )

    def render_layers(self, qpos: np.ndarray, mocap_pos: np.ndarray, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The layers ``names`` (``"depth"``, ``"segmentation"``) of the views of the rooms given, from the same passes:
        depth (n, height, width) float32, metres along the camera's axis, 0 where nothing is seen; segmentation
        (n, height, width) int32 geom ids, -1 where no geom is seen."""
        warp, _ = _warp()
        for name in names:
            if name not in self._layer_rows:
                raise ValueError(f"this renderer draws no {name}: make it with {name}=True")
        outputs = {name: self._layer_rows[name] for name in names}
        n = len(qpos)
        out = {name: np.empty((n, self.height, self.width), dtype=LAYER_DTYPES[name]) for name in names}
        for start in range(0, n, self.views_per_pass):
            stop = min(n, start + self.views_per_pass)
            with warp.ScopedDevice(self.device):
                self._load_and_draw(qpos[start:stop], mocap_pos[start:stop])
                for name, (data, columns) in outputs.items():
                    values = data[: stop - start].numpy()[:, columns]
                    if name == "segmentation":  # (object id, object type) pairs: geoms' ids, -1 for anything else
                        values = np.where(values[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), values[..., 0], -1)
                    out[name][start:stop] = values.reshape(-1, self.height, self.width)
        return out

    def render_map(self, qpos: np.ndarray, mocap_pos: np.ndarray) -> np.ndarray:
        """Bird's-eye map of one room, drawn by the OpenGL renderer (:meth:`TiledRenderer.render_map`)."""
        from activeperc_env.render import TiledRenderer

        if self._map_renderer is None:
            self._map_renderer = TiledRenderer(self._mj_model, self.width, self.height, 1, self.fov)
        return self._map_renderer.render_map(qpos, mocap_pos)

    def close(self) -> None:
        """Release the maps' GL context (the Warp arrays go with the renderer)."""
        if self._map_renderer is not None:
            self._map_renderer.close()
            self._map_renderer = None
