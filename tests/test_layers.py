"""Depth and segmentation observations: each pixel's value is what MuJoCo's own ray along that pixel meets, on both
backends; they reach every API's observations only when asked for."""

import math

import mujoco
import numpy as np
import pytest

import activeperc_env
from activeperc_env import EnvConfig, Simulator, names
from activeperc_env.spaces import MAX_GEOM_ID

BACKENDS = [
    ("mujoco", "cpu"),
    pytest.param("warp", "cpu", marks=pytest.mark.skipif("not warp_installed()", reason="no warp extra")),
    pytest.param("warp", "cuda", marks=pytest.mark.skipif("not warp_installed() or gpus() == 0", reason="no GPU")),
]


def warp_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("mujoco_warp") is not None


def gpus() -> int:
    """CUDA GPUs Warp sees."""
    import warp

    return warp.get_cuda_device_count()


def rays(sim: Simulator, room: int, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For the pixels (k, 2) of room ``room``'s view (row, column): the planar distance to what MuJoCo's ``mj_ray``
    through each pixel's centre meets, and the geom it meets (-1: none)."""
    cfg, data = sim.config, sim.physics_data(room)
    camera = sim.model.camera(names.EYE_CAMERA).id
    half_x, half_y = math.tan(math.radians(cfg.fov) / 2), math.tan(math.radians(cfg.fovy) / 2)
    groups = np.array(mujoco.MjvOption().geomgroup, dtype=np.uint8)  # the groups a view draws (0-2) ...
    groups[names.ROBOT_GROUP] = 0  # ... but the robot's own
    depth, geoms = np.zeros(len(pixels)), np.full(len(pixels), -1)
    for k, (row, col) in enumerate(pixels):
        local = np.array(
            [((col + 0.5) / cfg.width * 2 - 1) * half_x, (1 - (row + 0.5) / cfg.height * 2) * half_y, -1.0]
        )
        direction = data.cam_xmat[camera].reshape(3, 3) @ local
        hit = np.array([-1], dtype=np.int32)
        distance = mujoco.mj_ray(sim.model, data, data.cam_xpos[camera], direction, groups, 1, -1, hit)
        if hit[0] >= 0:
            depth[k], geoms[k] = distance, hit[0]  # distance in units of ``direction``, whose depth is 1
    return depth, geoms


@pytest.mark.parametrize(("backend", "device"), BACKENDS)
def test_each_pixel_shows_what_mujocos_ray_through_it_meets(backend, device):
    config = EnvConfig(depth=True, segmentation=True)
    sim = Simulator(config, num_envs=4, nthread=1, backend=backend, device=device)
    sim.reset(seeds=[0, 1, 2, 3])
    rng = np.random.default_rng(0)
    for _ in range(3):
        sim.move(rng.integers(0, 3, 4))
        sim.look(rng.integers(0, 3, 4))
    observation = sim.observe()
    pixels = np.stack([rng.integers(0, config.height, 200), rng.integers(0, config.width, 200)], axis=1)
    for room in range(4):
        depth, geoms = rays(sim, room, pixels)
        seen = observation["segmentation"][room][pixels[:, 0], pixels[:, 1]]
        assert (seen == geoms).mean() >= 0.97  # a pixel on an edge may show the other geom
        same = (seen == geoms) & (geoms >= 0)
        drawn = observation["depth"][room][pixels[:, 0], pixels[:, 1]]
        assert np.median(np.abs(drawn[same] - depth[same]) / depth[same]) < 1e-3
        assert np.all(drawn[seen < 0] == 0.0) and np.all(drawn[seen >= 0] > 0.0)


@pytest.mark.parametrize(("backend", "device"), BACKENDS)
def test_layers_drawn_in_several_passes_are_those_of_one(backend, device):
    config = EnvConfig(depth=True, segmentation=True)
    sim = Simulator(config, num_envs=5, nthread=1, backend=backend, device=device)
    sim.reset(seeds=list(range(5)))
    one_pass = (sim.render_depth(), sim.render_segmentation())
    if backend == "warp":
        from activeperc_env.warp_backend import WarpRenderer

        small = WarpRenderer(sim._batch, config.width, config.height, 2, config.fov, depth=True, segmentation=True)
    else:
        from activeperc_env.render import TiledRenderer

        small = TiledRenderer(sim.model, config.width, config.height, 2, config.fov)
    layers = small.render_layers(sim._qpos, sim._mocap_pos, ("depth", "segmentation"))
    depth, segmentation = layers["depth"], layers["segmentation"]
    small.close()
    assert small.views_per_pass == 2
    np.testing.assert_allclose(depth, one_pass[0], atol=1e-4)  # OpenGL rounds a little differently in another tile
    assert (segmentation == one_pass[1]).mean() > 0.999


def test_the_goal_is_segmented_where_the_image_shows_red():
    sim = Simulator(EnvConfig(segmentation=True, num_obstacles=0), num_envs=16, nthread=1)
    sim.reset(seeds=list(range(16)))
    observation = sim.observe()
    goal = sim.model.geom("goal").id
    image = observation["image"].astype(int)
    red = (image[..., 0] > 120) & (image[..., 1] < 80) & (image[..., 2] < 80)
    segmented = observation["segmentation"] == goal
    assert red.sum() > 20, "no goal in view: the test compared nothing"
    assert (red & segmented).sum() / (red | segmented).sum() >= 0.9


def test_layers_are_off_by_default_and_asked_for_by_name():
    sim = Simulator(num_envs=1)
    sim.reset(seeds=[0])
    assert set(sim.observe()) == {"image", "pan", "range"}
    with pytest.raises(ValueError, match=r"render_depth\(\) needs EnvConfig\(depth=True\)"):
        sim.render_depth()
    with pytest.raises(ValueError, match=r"EnvConfig.segmentation='yes' is invalid: expected True or False"):
        EnvConfig(segmentation="yes")


@pytest.mark.parametrize("version", [0, 1, 2, 3])
def test_every_rooms_geom_ids_lie_in_the_segmentation_space(version):
    assert Simulator(EnvConfig(version=version), num_envs=1).model.ngeom - 1 <= MAX_GEOM_ID


def test_every_api_gives_the_layers_inside_its_spaces():
    from torchrl.envs.utils import check_env_specs

    from activeperc_rl import make_env

    env = activeperc_env.parallel_env(depth=True, segmentation=True)
    observations, _ = env.reset(seed=2)
    for agent, observation in observations.items():
        assert {"depth", "segmentation"} <= set(observation)
        assert env.observation_space(agent).contains(observation)
    env.close()
    torchrl_env = make_env(num_envs=2, seed=0, depth=True, segmentation=True)
    check_env_specs(torchrl_env)
    torchrl_env.close()
