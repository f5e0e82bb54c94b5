"""Where one first-person view's time goes, and what culling the boxes out of sight before the draw would save.

The parts: GL context, state, scene, draw calls, read-back; it reads the renderer's private members.

Run it from the repository root::

    python benchmarks/view_profile.py                # 2,000 views
    python benchmarks/view_profile.py --views 500 --json
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time

import harness
import numpy as np

PARTS = (  # of one view, as TiledRenderer.render draws it in its own pass
    "context",  # the GL context made current before the view and released after it (so any thread may step an env)
    "pose",  # the room's state loaded into the renderer's MjData (mj_kinematics, mj_camlight)
    "cull",  # the test of which boxes are in view (numpy; culled views only)
    "scene",  # mjv_updateScene: the list of geoms to draw
    "draw",  # mjr_render: the GL draw calls (llvmpipe queues the work)
    "read",  # mjr_readPixels: the read-back, which waits for llvmpipe to finish drawing
)
WARM_UP = 20  # untimed views drawn each way first: a new context's first draw compiles llvmpipe's shaders
MODES = ("whole", "culled")
CULL_MARGIN = 0.01  # metres: a box counts as out of sight only this far beyond a frustum plane


class Frustum:
    """The eye camera's view volume in its own frame, as five planes (four sides and the near plane).

    A box is out of sight when it lies wholly beyond one of the planes, by more than ``CULL_MARGIN``; a box that
    reaches into the view is never dropped (a box beyond no single plane may still be out of sight: it is kept).
    """

    def __init__(self, model, camera: int, width: int, height: int):
        tan_v = math.tan(math.radians(model.cam_fovy[camera]) / 2)
        tan_h = tan_v * width / height  # the horizontal half-angle: the vertical one stretched by the aspect
        znear = model.vis.map.znear * model.stat.extent
        # outward normals in the camera frame (x right, y up, the camera looks along -z) and offsets
        sides = np.array([[1.0, 0.0, tan_h], [-1.0, 0.0, tan_h], [0.0, 1.0, tan_v], [0.0, -1.0, tan_v]])
        self.normals = np.vstack([sides / np.linalg.norm(sides, axis=1, keepdims=True), [0.0, 0.0, 1.0]])
        self.offsets = np.array([0.0, 0.0, 0.0, 0.0, znear])
        self.camera = camera

    def visible(self, data, boxes: np.ndarray, half_sizes: np.ndarray) -> np.ndarray:
        """Which of ``boxes`` (geom ids, box geoms with ``half_sizes``) reach into the view in ``data``'s pose."""
        rotation = data.cam_xmat[self.camera].reshape(3, 3)
        centres = (data.geom_xpos[boxes] - data.cam_xpos[self.camera]) @ rotation
        axes = data.geom_xmat[boxes].reshape(-1, 3, 3).transpose(0, 2, 1) @ rotation  # box axes, camera frame
        beyond = centres @ self.normals.T + self.offsets  # distance of each centre beyond each plane
        reach = (np.abs(axes @ self.normals.T) * half_sizes[:, :, None]).sum(axis=1)  # half extent along normals
        return ~(beyond - reach > CULL_MARGIN).any(axis=1)


def random_states(count: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` (qpos, mocap_pos) pairs of one room under random moves and looks, new episodes as they end."""
    from activeperc_env import Simulator

    sim = Simulator(num_envs=1)
    sim.reset(seeds=[seed])
    rng = np.random.default_rng(seed)
    states = []
    for _ in range(count):
        states.append((sim._qpos[0].copy(), sim._mocap_pos[0].copy()))
        sim.move(rng.integers(0, 3, 1))
        sim.look(rng.integers(0, 3, 1))
        if sim.done[0]:
            sim.reset()
    sim.close()
    return states


def profile(views: int, seed: int) -> dict:
    """Time every part of :data:`PARTS` for ``views`` views of random play, each drawn whole and culled (the boxes,
    walls, goal and occluders, that lie wholly outside the camera's frustum moved to a geom group the view does not
    draw, as per-view culling would do), each way first in half the views; compare their pixels."""
    import mujoco

    from activeperc_env import Simulator, names

    states = random_states(views, seed)
    sim = Simulator(num_envs=1)
    renderer = sim.renderer
    model, data, scene = renderer._model, renderer._data, renderer._scene
    groups = model.geom_group.copy()
    boxes = np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_BOX) & (groups != names.ROBOT_GROUP))
    boxes = boxes[groups[boxes] != names.HIDDEN_GROUP]  # the parked occluders are never drawn
    half_sizes = model.geom_size[boxes]
    frustum = Frustum(model, renderer._eye.fixedcamid, renderer.width, renderer.height)
    rect = mujoco.MjrRect(0, 0, renderer.width, renderer.height)

    def draw(index: int, cull: bool, out: np.ndarray, spent: dict, drawn: list) -> None:
        start = time.perf_counter()
        previous = renderer._gl.make_current()
        made_current = time.perf_counter()
        renderer._pose(*states[index])
        marks = [made_current, time.perf_counter()]
        if cull:
            visible = frustum.visible(data, boxes, half_sizes)
            model.geom_group[boxes] = np.where(visible, groups[boxes], names.HIDDEN_GROUP)
            drawn.append(int(visible.sum()))
        marks.append(time.perf_counter())
        mujoco.mjv_updateScene(model, data, renderer._eye_opt, None, renderer._eye, mujoco.mjtCatBit.mjCAT_ALL, scene)
        marks.append(time.perf_counter())
        mujoco.mjr_render(rect, scene, renderer._ctx)
        marks.append(time.perf_counter())
        mujoco.mjr_readPixels(out, None, rect, renderer._ctx)
        read = time.perf_counter()
        renderer._gl.restore(previous)
        marks.append(read)
        spent["context"] += made_current - start + time.perf_counter() - read
        model.geom_group[:] = groups
        for part, (begin, end) in zip(PARTS[1:], itertools.pairwise(marks), strict=True):
            spent[part] += end - begin

    result = {"views": views, "boxes": len(boxes)}
    spent = {mode: dict.fromkeys(PARTS, 0.0) for mode in MODES}
    drawn: list[int] = []
    out = {mode: np.empty((renderer.height, renderer.width, 3), dtype=np.uint8) for mode in MODES}
    try:
        for index in range(min(WARM_UP, views)):
            for mode in MODES:
                draw(index, mode == "culled", out[mode], dict.fromkeys(PARTS, 0.0), [])
        for index in range(views):
            for mode in MODES if index % 2 == 0 else MODES[::-1]:  # each mode first in half the views
                draw(index, mode == "culled", out[mode], spent[mode], drawn)
            if not np.array_equal(out["whole"], out["culled"]):
                result.setdefault("first_differing_view", index)
    finally:
        model.geom_group[:] = groups
        sim.close()
    for mode in MODES:
        result[mode] = {part: 1e6 * seconds / views for part, seconds in spent[mode].items()}  # microseconds a view
    result["boxes_drawn_when_culled"] = float(np.mean(drawn))
    result["same_pixels"] = "first_differing_view" not in result
    return result


def main(argv: list[str] | None = None) -> dict:
    """Parse the flags, profile the views and print the report; return it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--views", type=harness.at_least(int, "views", 1), default=2000, help="views of random play to draw (2000)"
    )
    parser.add_argument(
        "--seed", type=harness.at_least(int, "seed", 0), default=0, help="seed of the episodes and random actions (0)"
    )
    parser.add_argument("--json", action="store_true", help="also print one JSON object with every figure")
    args = parser.parse_args(argv)

    import activeperc_env  # noqa: F401 (chooses the GL backend, e.g. MUJOCO_GL=egl)

    result = profile(args.views, args.seed)
    print(f"activeperc: one first-person view, {args.views} views of random play, microseconds per view")
    print(f"{'':8}" + "".join(f"{part:>9}" for part in PARTS) + f"{'total':>9}")
    for mode in MODES:
        times = result[mode]
        print(f"{mode:8}" + "".join(f"{times[part]:9.1f}" for part in PARTS) + f"{sum(times.values()):9.1f}")
    saved = sum(result["whole"].values()) - sum(result["culled"].values())
    print(
        f"culling drew {result['boxes_drawn_when_culled']:.2f} of the {result['boxes']} boxes a view on average,"
        f" saved {saved:.1f} us a view in all, and gave "
        + (
            "the same pixels in every view"
            if result["same_pixels"]
            else f"DIFFERENT pixels (first in view {result['first_differing_view']})"
        )
    )
    if args.json:
        print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
