"""The MuJoCo Warp backend gives the default backend's episodes: the same layouts, rewards and ends, trajectories
within float32's rounding, the goal in the same views (on Warp's CPU device, and on a GPU where there is one)."""

import pickle

import numpy as np
import pytest

from activeperc_env import EnvConfig, Simulator
from activeperc_env.scripted import ScanLooker, VisionMover

pytest.importorskip("mujoco_warp", reason="the warp extra is not installed: pip install -e '.[warp]'")

ROOMS = 6
TRAJECTORY_TOLERANCE = 2e-3  # state() differences: float32 physics against MuJoCo's float64 (docs/env.md)


def gpus() -> int:
    """CUDA GPUs Warp sees."""
    import warp

    return warp.get_cuda_device_count()


ON_CUDA = pytest.mark.skipif("gpus() == 0", reason="needs a CUDA GPU")
DEVICES = ["cpu", pytest.param("cuda", marks=ON_CUDA)]


def pair(config: EnvConfig | None = None, rooms: int = ROOMS, device: str = "cpu") -> tuple[Simulator, Simulator]:
    """The default backend and the warp backend on ``device``, reset with the same seeds."""
    ours = Simulator(config, num_envs=rooms, nthread=1)
    warp = Simulator(config, num_envs=rooms, nthread=1, backend="warp", device=device)
    for sim in (ours, warp):
        sim.reset(seeds=list(range(rooms)))
    return ours, warp


def red(views: np.ndarray) -> np.ndarray:
    """Where the views show the red goal: (n, height, width) bool."""
    v = views.astype(int)
    return (v[..., 0] > 120) & (v[..., 1] < 80) & (v[..., 2] < 80)


@pytest.mark.parametrize("device", DEVICES)
def test_random_cycles_keep_both_backends_together(device):
    ours, warp = pair(device=device)
    assert np.array_equal(ours.state(), warp.state())  # the same layouts
    rng = np.random.default_rng(0)
    intersections = unions = 0
    for _ in range(60):
        alive = np.flatnonzero(~ours.done)
        if not alive.size:
            ours.reset(np.flatnonzero(ours.done))
            warp.reset(np.flatnonzero(warp.done))
            alive = np.arange(ROOMS)
        moves, looks = rng.integers(0, 3, (2, alive.size))
        a, b = ours.move(moves, alive), warp.move(moves, alive)
        assert np.array_equal(a.reward, b.reward) and np.array_equal(a.terminated, b.terminated)
        assert np.array_equal(a.truncated, b.truncated)
        ours.look(looks, alive)
        warp.look(looks, alive)
        assert np.abs(ours.state(alive) - warp.state(alive)).max() < TRAJECTORY_TOLERANCE
        seen_ours, seen_warp = red(ours.render(alive)), red(warp.render(alive))
        intersections += (seen_ours & seen_warp).sum()
        unions += (seen_ours | seen_warp).sum()
    assert unions > 100, "the goal was hardly in view: the test compared nothing"
    assert intersections / unions >= 0.8


def test_scripted_episodes_end_alike():
    config = EnvConfig(version=2)
    ours, warp = pair(config)
    movers, lookers = [VisionMover(config, ROOMS) for _ in range(2)], [ScanLooker(config, ROOMS) for _ in range(2)]
    outcomes = []
    for sim, mover, looker in zip((ours, warp), movers, lookers, strict=True):
        while not sim.done.all():
            alive = np.flatnonzero(~sim.done)
            sim.move(mover.act(sim.observe(alive), alive), alive)
            sim.look(looker.act(sim.observe(alive), alive), alive)
        outcomes.append((sim.success.copy(), sim.episode_return.copy(), sim.cycle.copy()))
    (success, returns, cycles), (warp_success, warp_returns, warp_cycles) = outcomes
    assert success.any() and np.array_equal(success, warp_success)
    np.testing.assert_allclose(returns, warp_returns)
    assert np.abs(cycles - warp_cycles).max() <= 1  # a view a level lighter may shift a scripted turn by a cycle


def test_a_step_of_some_rooms_leaves_the_others_as_they_were():
    _, warp = pair(rooms=3)
    before = warp.get_state()["physics"]
    warp.move([2], ids=[1])
    after = warp.get_state()["physics"]
    assert np.array_equal(after[[0, 2]], before[[0, 2]]) and not np.array_equal(after[1], before[1])


def test_a_copy_keeps_its_backend_and_state():
    _, warp = pair(rooms=2)
    warp.move([2, 2])
    twin = pickle.loads(pickle.dumps(warp))
    assert (twin.backend, twin.device) == ("warp", "cpu")
    assert np.array_equal(twin.state(), warp.state())
    twin.move([0, 1])
    warp.move([0, 1])
    assert np.array_equal(twin.state(), warp.state())


@pytest.mark.parametrize(
    ("backend", "device", "named"),
    [("jax", "cpu", "backend='jax' is invalid"), ("mujoco", "cuda", "device='cuda' is invalid for backend='mujoco'"),
     ("warp", "tpu", "device='tpu' is invalid"), ("warp", "cuda:x", "device='cuda:x' is invalid"),
     ("warp", "cuda:99", "device='cuda:99' is invalid: Warp sees")],
)  # fmt: skip
def test_bad_backends_and_devices_are_named(backend, device, named):
    with pytest.raises(ValueError, match=named):
        Simulator(num_envs=1, backend=backend, device=device)


def test_the_torchrl_env_on_warp_gives_the_default_envs_rollout():
    import torch

    from activeperc_rl.envs import make_env
    from activeperc_rl.models import RandomPolicy

    rollouts = []
    for backend in ("mujoco", "warp"):
        env = make_env(3, seed=5, backend=backend, max_cycles=10)
        torch.manual_seed(0)
        rollouts.append(env.rollout(12, RandomPolicy(("mover", "looker")), break_when_any_done=False))
        env.close()
    ours, warp = rollouts
    assert torch.equal(ours["next", "mover", "observation", "pan"], warp["next", "mover", "observation", "pan"])
    assert torch.equal(ours["next", "mover", "reward"], warp["next", "mover", "reward"])
    assert torch.equal(ours["next", "done"], warp["next", "done"])
    images = [r["next", "mover", "observation", "image"].float() for r in rollouts]
    assert (images[0] - images[1]).abs().mean() < 2.0  # levels of 255: the two renderers shade alike


@pytest.mark.parametrize("device", DEVICES)
def test_views_left_on_the_device_are_the_rendered_views(device):
    import torch

    _, warp = pair(device=device)
    warp.move([2] * ROOMS)
    warp.look([0, 1, 2] * (ROOMS // 3))
    lent = torch.from_dlpack(warp.device_views([1, 3, 4])).cpu().numpy().copy()
    assert lent.shape == (3, warp.config.height, warp.config.width, 3)
    assert np.array_equal(lent, warp.render([1, 3, 4]))
    assert warp.device_views([]).shape == (0, warp.config.height, warp.config.width, 3)
    with pytest.raises(ValueError, match="device_views\\(\\) needs backend='warp'"):
        Simulator(num_envs=1).device_views()


def test_observations_with_layers_lend_the_views_of_their_last_pass():
    import torch

    _, warp = pair(EnvConfig(depth=True, segmentation=True), rooms=3)
    seen = warp.observe([2, 0], device_images=True)
    assert list(seen) == ["image", "pan", "range", "depth", "segmentation"]
    assert warp.renderer._lent  # the layers' pass came first: the next pass waits for what reads the image
    assert np.array_equal(torch.from_dlpack(seen["image"]).numpy().copy(), warp.render([2, 0]))


@pytest.mark.parametrize(("device", "frame_stack"), [("cpu", 1), ("cpu", 2), pytest.param("cuda", 1, marks=ON_CUDA)])
def test_the_torchrl_env_reads_warp_views_on_the_device_as_it_reads_them_on_the_host(device, frame_stack):
    import torch

    from activeperc_rl.envs import make_env
    from activeperc_rl.models import RandomPolicy

    rollouts = []
    for device_images in (True, False):
        looker = RandomPolicy(("looker",))
        options = {"max_cycles": 6, "frame_stack": frame_stack, "looker": looker, "look_views": True, "depth": True}
        env = make_env(3, device=device, seed=5, backend="warp", **options)
        env._device_images = device_images  # False: the views come through the host, as on the default backend
        torch.manual_seed(0)
        rollouts.append(env.rollout(9, RandomPolicy(("mover",)), break_when_any_done=False))
        env.close()
    assert (rollouts[0] == rollouts[1]).all()
    images = rollouts[0]["next", "mover", "observation", "image"]
    assert not torch.equal(images[:, 0], images[:, -1])  # each cycle kept its own views, not the last pass's


def test_activeperc_train_runs_on_warp(tmp_path, capsys):
    from activeperc_rl import cli

    out = tmp_path / "run"
    tiny = ["--num-envs", "2", "--rollout-length", "8", "--max-cycles", "12", "--channels", "8", "--hidden-size", "32"]
    argv = [*tiny, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "2", "--no-progress"]
    assert cli.main([*argv, "--backend", "warp", "--out", str(out)]) == 0
    assert "backend: warp" in (out / "config.yaml").read_text()
    assert (out / "eval.json").is_file()


def test_the_agreement_script_prints_a_row_per_room_version(capsys):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "warp_agreement.py"
    spec = importlib.util.spec_from_file_location("warp_agreement", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    script.main(["--rooms", "2", "--cycles", "3", "--versions", "1", "2"])
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(" | ")[0] for line in lines[2:]] == ["| v1", "| v2"]
    assert all(" | 0 | " in line for line in lines[2:])  # no episode ended apart


def test_training_on_warp_keeps_its_rooms_in_one_process():
    from activeperc_rl.recipe import TrainConfig

    with pytest.raises(ValueError, match="run.collect_workers=2 is invalid: expected 0 with backend 'warp'"):
        TrainConfig.from_options(backend="warp", collect_workers=2)
