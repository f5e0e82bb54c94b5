"""The batched TorchRL env (specs, auto-reset, seeding, the looker in the loop) and PettingZooWrapper."""

import inspect
import math
import warnings

import numpy as np
import pytest
import torch
from conftest import assert_same_view, goal_seeking_move
from tensordict.nn import (
    ProbabilisticTensorDictModule,
    ProbabilisticTensorDictSequential,
    TensorDictModule,
)
from torchrl.collectors import Collector
from torchrl.envs import GymEnv, PettingZooWrapper
from torchrl.envs.utils import ExplorationType, check_env_specs, set_exploration_type

import activeperc_env
from activeperc_env import EnvConfig
from activeperc_env.rooms import ROOMS
from activeperc_rl.envs import ActivePerceptionEnv, make_env

# fast episodes: each move lasts 0.5 s, so a scripted mover reaches the goal in 5-16 cycles
FAST = dict(num_obstacles=0, control_hz=2.0, forward_speed=2.0)


def random_looker():
    """A ProbabilisticActor-shaped looker: uniform logits, a sampled action and its log-probability."""
    logits = TensorDictModule(
        lambda image: torch.zeros(*image.shape[:-3], 3),
        in_keys=[("looker", "observation", "image")],
        out_keys=[("looker", "logits")],
    )
    sample = ProbabilisticTensorDictModule(
        in_keys=[("looker", "logits")],
        out_keys=[("looker", "action")],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
    )
    return ProbabilisticTensorDictSequential(logits, sample)


def constant_looker(action: int):
    """A looker that always takes ``action`` (1 = hold: the Fixed_Forward camera)."""
    return TensorDictModule(
        lambda image: torch.full(image.shape[:1], action, dtype=torch.int64),
        in_keys=[("looker", "observation", "image")],
        out_keys=[("looker", "action")],
    )


def replay(actions):
    """A policy that plays the rows of ``actions`` ((T, n) movers' or (T, n, 2) both agents')."""
    rows = iter(actions)

    def policy(td):
        row = next(rows)
        if row.ndim == 1:
            td.set(("mover", "action"), row)
        else:
            td.set(("mover", "action"), row[:, 0])
            td.set(("looker", "action"), row[:, 1])
        return td

    return policy


@pytest.mark.parametrize("version", ROOMS)
def test_specs_external_mode(version):
    env = make_env(num_envs=4, max_cycles=5, version=version)
    assert env.sim.config.version == version
    assert env.batch_size == (4,)
    assert set(env.action_keys) == {("mover", "action"), ("looker", "action")}
    assert set(env.reward_keys) == {("mover", "reward"), ("looker", "reward")}
    assert set(env.done_keys) == {"done", "terminated", "truncated"}
    image = env.observation_spec["mover", "observation", "image"]
    assert image.shape == (4, 60, 80, 3) and image.dtype == torch.uint8
    assert env.full_action_spec["mover", "action"].space.n == 3
    assert ("looker", "observation") not in env.observation_spec.keys(True)
    assert env.observation_spec["mover", "episode_success"].dtype == torch.bool
    assert env.observation_spec["mover", "episode_return"].shape == (4, 1)
    check_env_specs(env, seed=0)
    env.close()


def test_a_device_torch_does_not_know_or_see_is_named():
    from activeperc_rl.evaluate import evaluate
    from activeperc_rl.recipe import TrainConfig

    bad = ["tpu", 5] + ([] if torch.cuda.is_available() else ["cuda"])
    for device in bad:
        with pytest.raises(ValueError, match=f"device={device!r} is invalid"):
            make_env(num_envs=1, device=device)
        with pytest.raises(ValueError, match=f"device={device!r} is invalid"):
            evaluate(TrainConfig(), episodes=1, device=device)


def test_a_bad_look_is_refused_before_the_rooms_move():
    env = make_env(num_envs=2, max_cycles=5)
    td = env.reset()
    before = env.sim.get_state()
    td.set(("mover", "action"), torch.tensor([2, 2]))
    td.set(("looker", "action"), torch.tensor([5, 1]))
    with pytest.raises(ValueError, match=r"looker action 5 of room 0 is outside its action space Discrete\(3\)"):
        env.step(td)
    after = env.sim.get_state()
    assert np.array_equal(before["physics"], after["physics"]) and np.array_equal(before["cycle"], after["cycle"])
    env.close()


@pytest.mark.parametrize("version", ROOMS)
def test_specs_looker_mode_and_switching(version):
    env = make_env(num_envs=4, looker=random_looker(), max_cycles=5, version=version)
    assert env.action_keys == [("mover", "action")]
    keys = set(env.observation_spec.keys(True, True))
    assert {("looker", "action"), ("looker", "action_log_prob"), ("looker", "observation", "image")} <= keys
    check_env_specs(env, seed=0)
    env.set_looker(None)
    assert set(env.action_keys) == {("mover", "action"), ("looker", "action")}
    check_env_specs(env, seed=0)
    outside = TensorDictModule(
        lambda image: torch.ones(image.shape[:1], dtype=torch.int64),
        in_keys=[("looker", "observation", "image")],
        out_keys=["action"],
    )
    with pytest.raises(ValueError, match="only entries under 'looker'"):
        env.set_looker(outside)
    env.close()


def test_rollout_auto_resets_finished_rooms():
    """Rooms 0-1 drive to the goal (terminating at various cycles), rooms 2-3 drive at random."""
    n, steps, max_cycles = 4, 30, 12
    env = make_env(num_envs=n, looker=random_looker(), seed=3, max_cycles=max_cycles, **FAST)

    def policy(td):
        action = torch.randint(0, 3, (n,))
        action[:2] = torch.tensor([goal_seeking_move(env.sim, i) for i in range(2)])
        td.set(("mover", "action"), action)
        return td

    data = env.rollout(steps, policy=policy, break_when_any_done=False)
    assert data.batch_size == (n, steps)
    nxt = data["next"]
    assert nxt["mover", "observation", "image"].shape == (n, steps, 60, 80, 3)
    assert nxt["mover", "observation", "image"].dtype == torch.uint8
    assert nxt["looker", "observation", "image"].dtype == torch.uint8
    assert nxt["mover", "observation", "pan"].shape == (n, steps, 1)
    assert nxt["mover", "reward"].shape == nxt["looker", "reward"].shape == (n, steps, 1)
    assert nxt["done"].shape == (n, steps, 1) and nxt["done"].dtype == torch.bool
    assert data["mover", "action"].shape == nxt["looker", "action"].shape == (n, steps)
    assert nxt["looker", "action_log_prob"].shape == (n, steps)
    assert torch.allclose(nxt["looker", "action_log_prob"], torch.tensor(-math.log(3)))

    done = nxt["done"].squeeze(-1)
    assert nxt["terminated"][:2].any() and nxt["truncated"][2:].any()
    assert (done.any(0) & ~done.all(0)).any(), "expected partial resets"
    assert torch.equal(nxt["mover", "reward"] > 0, nxt["terminated"])
    assert torch.equal(nxt["looker", "reward"], nxt["mover", "reward"])  # looker_reward="shared"
    # the outcome: the running return and success, the episode's at its last step; a reset clears them
    summed = torch.zeros(n)
    for t in range(steps):
        summed += nxt["mover", "reward"][:, t, 0]
        assert torch.equal(nxt["mover", "episode_return"][:, t, 0], summed)
        assert torch.equal(nxt["mover", "episode_success"][:, t], nxt["terminated"][:, t])
        summed[done[:, t]] = 0.0
    assert not data["mover", "episode_return"][done.roll(1, 1)].any()
    assert not data["mover", "episode_success"].any()
    # the cycle: s_bar keeps the pan of s, the look turns it by pan_step, s' sees the result
    pan_bar = nxt["looker", "observation", "pan"]
    assert torch.equal(pan_bar, data["mover", "observation", "pan"])
    step = math.radians(30.0) * (1 - nxt["looker", "action"].unsqueeze(-1).float())
    limit = math.radians(120.0)
    assert torch.allclose(nxt["mover", "observation", "pan"], (pan_bar + step).clamp(-limit, limit), atol=1e-5)
    # after a done, the room starts afresh (camera forward); otherwise the next step starts from s'
    for t in range(steps - 1):
        for i in range(n):
            s_next, s_root = nxt[i, t]["mover", "observation"], data[i, t + 1]["mover", "observation"]
            if done[i, t]:
                assert s_root["pan"].item() == 0.0
                assert not torch.equal(s_next["image"], s_root["image"])
            else:
                assert torch.equal(s_next["image"], s_root["image"])
                assert torch.equal(s_next["pan"], s_root["pan"])
    env.close()


def test_partial_steps_leave_finished_rooms_alone():
    """rollout(break_when_all_done=True) steps only the rooms not yet done (TorchRL's "_step" mask): each room's
    rows up to its end are those of a rollout that steps every room, and the rollout stops when all are done."""
    n, max_cycles = 4, 12
    actions = torch.randint(0, 3, (max_cycles, n, 2), generator=torch.Generator().manual_seed(0))
    actions[:, :2, 0] = -1  # rooms 0-1 drive to the goal: they end at various cycles, rooms 2-3 at max_cycles

    def policy_for(env):
        rows = iter(actions)

        def policy(td):
            row = next(rows).clone()
            row[:2, 0] = torch.tensor([goal_seeking_move(env.sim, i) for i in range(2)])
            return td.set(("mover", "action"), row[:, 0]).set(("looker", "action"), row[:, 1])

        return policy

    env = make_env(num_envs=n, seed=3, max_cycles=max_cycles, **FAST)
    every = env.rollout(max_cycles, policy_for(env), break_when_any_done=False)
    env = make_env(num_envs=n, seed=3, max_cycles=max_cycles, **FAST)
    partial = env.rollout(100, policy_for(env), break_when_any_done=False, break_when_all_done=True)
    assert partial.batch_size == (n, max_cycles)
    ends = every["next", "done"].squeeze(-1).float().argmax(1)  # each room's first done
    assert len(set(ends.tolist())) > 1, "the rooms should end at different cycles"
    for i, end in enumerate(ends.tolist()):
        assert (partial[i, : end + 1] == every[i, : end + 1]).all()
        assert partial["next", "done"][i, end:].all()
    env.close()


def test_a_partial_step_in_looker_mode_turns_only_the_stepped_rooms_cameras():
    env = make_env(num_envs=2, seed=0, looker=constant_looker(0), **FAST)  # the looker always pans left
    td = env.reset().set(("mover", "action"), torch.tensor([0, 0])).set("_step", torch.tensor([True, False]))
    env.step(td)
    assert env.sim.pan()[:, 0].tolist() == [pytest.approx(math.radians(30.0)), 0.0]
    env.close()


def test_a_room_reset_and_left_out_of_the_next_step_is_not_done():
    """The done flags a partial step reports for a room it leaves out are those of the room's current episode."""
    env = make_env(num_envs=2, seed=0, max_cycles=1, **FAST)
    actions = {"mover": {"action": torch.tensor([0, 0])}, "looker": {"action": torch.tensor([1, 1])}}
    td = env.reset().update(actions)
    assert env.step(td)["next", "done"].all()  # both rooms truncated after one cycle
    td = env.reset().update(actions).set("_step", torch.tensor([False, True]))
    assert env.step(td)["next", "done"].squeeze(-1).tolist() == [False, True]
    env.close()


def test_same_seed_same_observations():
    steps, n = 12, 3
    actions = torch.randint(0, 3, (steps, n, 2), generator=torch.Generator().manual_seed(0))
    runs = []
    for seed in (5, 5, 6):
        env = make_env(num_envs=n, seed=seed, max_cycles=5)
        runs.append(env.rollout(steps, policy=replay(actions), break_when_any_done=False))
        env.close()
    keys = [("mover", "observation", "image"), ("next", "mover", "observation", "image"), ("next", "done")]
    for key in keys:
        assert torch.equal(runs[0][key], runs[1][key])
    assert not torch.equal(runs[0]["mover", "observation", "image"], runs[2]["mover", "observation", "image"])


def test_reset_takes_a_seed_and_names_other_arguments():
    """reset(seed=s) is set_seed(s) then the reset, as TorchRL's Gym wrappers read it."""
    image = ("mover", "observation", "image")
    a, b, c = (make_env(num_envs=2) for _ in range(3))
    assert torch.equal(a.reset(seed=3)[image], b.reset(seed=3)[image])
    assert torch.equal(a.reset(seed=3)[image], make_env(num_envs=2, seed=3).reset()[image])
    assert not torch.equal(a.reset(seed=3)[image], c.reset(seed=4)[image])
    with pytest.raises(TypeError, match="seeds"):
        a.reset(seeds=3)
    for bad in (-1, 1.5, "a"):
        with pytest.raises(ValueError, match=f"seed={bad!r}"):
            a.set_seed(bad)


def test_bad_action_shapes_and_a_device_of_none():
    env = make_env(num_envs=2)
    td = env.reset()
    td.set(("mover", "action"), torch.nn.functional.one_hot(torch.tensor([0, 2]), 3))
    td.set(("looker", "action"), torch.tensor([1, 1]))
    with pytest.raises(ValueError, match=r"\('mover', 'action'\) of shape \(2, 3\) is invalid.*one-hot"):
        env.step(td)
    looking = make_env(num_envs=2, device=None, looker=constant_looker(1))
    looking.rollout(2, policy=replay(torch.zeros(2, 2, dtype=torch.int64)))


def test_collector_set_seed_then_reset_repeats_the_layouts():
    """The Collector resets its env when built, before set_seed; its reset() restarts the rooms on the new seeds."""

    def layouts(seed):
        collector = Collector(lambda: make_env(num_envs=2, max_cycles=5), None, frames_per_batch=20, total_frames=20)
        collector.set_seed(seed)
        collector.reset()
        first = next(iter(collector)).get(("mover", "observation", "image"))[:, 0].clone()
        collector.shutdown()
        return first

    assert torch.equal(layouts(7), layouts(7)) and not torch.equal(layouts(7), layouts(8))


def test_a_rooms_episode_seed_replays_it_in_a_one_room_env():
    """make_env seeds its rooms from SeedSequence streams, not with the base seed itself: ``episode_seeds`` says
    which layout each room plays, and a PettingZoo env reset with it plays the same start (docs/env.md)."""
    env = make_env(num_envs=3, seed=5)
    images = env.reset()["mover", "observation", "image"]
    assert len(set(env.episode_seeds.tolist()) | {5}) == 4
    for room, seed in enumerate(env.episode_seeds.tolist()):
        one = activeperc_env.parallel_env()
        observations, _ = one.reset(seed=seed)
        assert_same_view(observations["mover_0"]["image"], images[room].numpy())
        one.close()
    env.close()


def test_e1_e2_share_reset_seeds():
    """Same base seed: room i's k-th episode has the same layout whatever the looker and num_envs."""
    steps = 12
    movers = torch.randint(0, 3, (steps, 3), generator=torch.Generator().manual_seed(1))
    e1 = make_env(num_envs=2, seed=7, looker=constant_looker(1), max_cycles=4)
    e2 = make_env(num_envs=3, seed=7, looker=constant_looker(0), max_cycles=4)
    d1 = e1.rollout(steps, policy=replay(movers[:, :2]), break_when_any_done=False)
    d2 = e2.rollout(steps, policy=replay(movers), break_when_any_done=False)
    assert (e1.episode_seeds == e2.episode_seeds[:2]).all()
    image1, image2 = d1["mover", "observation", "image"], d2["mover", "observation", "image"][:2]
    for t in (0, 4, 8):  # the starts of episodes 1, 2, 3 (max_cycles=4)
        assert torch.equal(image1[:, t], image2[:, t])
    assert not torch.equal(image1[:, 1:4], image2[:, 1:4])  # the cameras pan differently
    e1.close()
    e2.close()


def test_a_hold_leaves_the_mover_the_view_the_looker_had():
    """After 'hold' the mover's view is the looker's (what the credit per look of meta relies on: a hold adds
    nothing); after a pan it is another."""
    env = make_env(num_envs=3, looker=random_looker(), seed=0)
    with set_exploration_type(ExplorationType.RANDOM):  # the looker samples its looks
        data = env.rollout(12, break_when_any_done=False)
    env.close()
    step = data["next"]
    holds = step["looker", "action"] == 1
    assert holds.any() and (~holds).any()
    for key in ("image", "pan", "range"):
        before, after = step["looker", "observation", key], step["mover", "observation", key]
        same = (before == after).reshape(*holds.shape, -1).all(-1)
        assert same[holds].all()
        if key == "pan":
            assert not same[~holds & (before.abs() < 2).squeeze(-1)].any()  # a pan inside the limits turns the camera


def test_the_views_of_every_look_are_recorded_on_request():
    env = make_env(num_envs=2, looker=constant_looker(0), seed=0, look_views=True)
    step = env.rollout(3)["next"]
    env.close()
    views = step["looker", "look_views"]
    assert views["image"].shape == (2, 3, 3, 60, 80, 3) and views["pan"].shape == (2, 3, 3, 1)
    assert torch.equal(views["image"][:, :, 1], step["looker", "observation", "image"])  # a hold: s_bar itself
    assert torch.equal(views["pan"][:, :, 0], step["mover", "observation", "pan"])  # the look taken: pan left
    assert "look_views" not in make_env(num_envs=1, looker=constant_looker(0)).full_observation_spec["looker"].keys()


def test_collector_records_the_looker():
    """A mover policy under ``Collector``; the looker's cycle record comes along under ("next", "looker")."""
    env = make_env(num_envs=4, looker=random_looker(), seed=0, max_cycles=6)
    mover = ProbabilisticTensorDictSequential(
        TensorDictModule(
            lambda image: torch.zeros(*image.shape[:-3], 3),
            in_keys=[("mover", "observation", "image")],
            out_keys=[("mover", "logits")],
        ),
        ProbabilisticTensorDictModule(
            in_keys=[("mover", "logits")],
            out_keys=[("mover", "action")],
            distribution_class=torch.distributions.Categorical,
            return_log_prob=True,
        ),
    )
    collector = Collector(env, mover, frames_per_batch=40, total_frames=80, auto_register_policy_transforms=False)
    batches = list(collector)
    collector.shutdown()
    assert len(batches) == 2
    assert all(data.batch_size == (4, 10) for data in batches)
    data = torch.cat(batches, dim=1)  # the second batch continues the first one's episodes
    assert data["next", "looker", "action"].shape == (4, 20)
    assert data["next", "looker", "observation", "image"].dtype == torch.uint8
    done_at = data["next", "done"].squeeze(-1).any(0).nonzero().squeeze(-1)
    assert done_at.tolist() == [5, 11, 17]  # max_cycles=6, no room reaches the goal at random
    env.close()


def test_pettingzoo_wrapper_aec():
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="PettingZoo in TorchRL is tested")
        env = PettingZooWrapper(activeperc_env.env(max_cycles=3), use_mask=True)
    assert env.group_map == {"mover_0": ["mover_0"], "looker_0": ["looker_0"]}
    check_env_specs(env, seed=0)
    data = env.rollout(14, break_when_any_done=False)
    mask = data["mover_0", "mask"].squeeze(-1)
    assert torch.equal(mask, torch.arange(14) % 2 == 0)  # the mover acts first, then the looker
    assert torch.equal(data["looker_0", "mask"].squeeze(-1), ~mask)
    done = data["next", "done"].squeeze(-1)
    assert torch.equal(done, torch.arange(14) % 6 == 5)  # 3 cycles of 2 turns, then a reset
    assert data["mover_0", "observation", "image"].shape == (14, 1, 60, 80, 3)
    assert (data["mover_0", "observation", "pan"][6] == 0).all()
    env.close()


def test_torchrl_gym_env_builds_the_gymnasium_ids():
    """TorchRL's GymEnv passes frameskip= and drops it when the env refuses it as an unexpected keyword (TypeError)."""
    for env_id in ("activeperc/Joint-v1", "activeperc/FixedForward-v1"):
        env = GymEnv(env_id, max_cycles=3)
        check_env_specs(env, seed=0)
        data = env.rollout(6, break_when_any_done=False)
        assert data["image"].shape == (6, 60, 80, 3)
        assert torch.equal(data["next", "done"].squeeze(-1), torch.arange(6) % 3 == 2)
        env.close()


def test_pettingzoo_wrapper_reads_the_global_state():
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="PettingZoo in TorchRL is tested")
        env = PettingZooWrapper(activeperc_env.parallel_env(max_cycles=3), return_state=True)
    check_env_specs(env, seed=0)
    data = env.rollout(3)
    assert data["state"].shape == (3, 14) and data["next", "state"].shape == (3, 14)
    assert torch.equal(data["next", "state"][:, -1], torch.tensor([1, 2, 3]) / 3)  # cycle / max_cycles
    env.close()


def test_help_shows_the_constructors_arguments():
    assert list(inspect.signature(ActivePerceptionEnv).parameters)[:3] == ["config", "num_envs", "device"]


def test_the_room_is_given_typed_or_by_its_fields_not_both():
    room = EnvConfig(max_cycles=5, num_obstacles=1)
    env = make_env(num_envs=1, config=room)
    assert env.sim.config == room
    env.close()
    with pytest.raises(ValueError, match="not both"):
        make_env(num_envs=1, config=room, fov=100)
    with pytest.raises(TypeError, match="expected an EnvConfig"):
        make_env(num_envs=1, config={"fov": 100})


def test_a_frame_stack_holds_each_rooms_latest_views_oldest_first():
    """With ``frame_stack=3`` every observation is the last three views of the unstacked env's episode on the
    channels (the first view repeated at an episode's start, auto-resets included) and their pans."""
    steps, n = 14, 3
    actions = torch.randint(0, 3, (steps, n, 2), generator=torch.Generator().manual_seed(1))
    runs = []
    for frame_stack in (1, 3):
        env = make_env(num_envs=n, seed=2, max_cycles=5, frame_stack=frame_stack)
        runs.append(env.rollout(steps, replay(actions), break_when_any_done=False))
        env.close()
    single, stacked = runs
    assert stacked["mover", "observation", "image"].shape == (n, steps, 60, 80, 9)
    assert stacked["mover", "observation", "pan"].shape == (n, steps, 3)
    assert torch.equal(stacked["mover", "observation", "range"], single["mover", "observation", "range"])
    starts = torch.cat([torch.ones(n, 1, dtype=torch.bool), single["next", "done"][:, :-1, 0]], 1)
    assert starts[:, 1:].any()  # episodes restart inside the rollout
    for i in range(n):
        first = 0
        for t in range(steps):
            first = t if starts[i, t] else first
            back = [max(t - k, first) for k in (2, 1, 0)]
            views = [single["mover", "observation", "image"][i, s] for s in back]
            pans = [single["mover", "observation", "pan"][i, s] for s in back]
            assert torch.equal(stacked["mover", "observation", "image"][i, t], torch.cat(views, -1))
            assert torch.equal(stacked["mover", "observation", "pan"][i, t], torch.cat(pans, -1))


def test_a_frame_stacks_look_views_share_the_past_and_its_state_resumes():
    env = make_env(num_envs=2, looker=constant_looker(0), seed=0, look_views=True, frame_stack=2)
    step = env.rollout(3)["next"]
    views, seen = step["looker", "look_views"], step["looker", "observation"]
    assert views["image"].shape == (2, 3, 3, 60, 80, 6) and views["pan"].shape == (2, 3, 3, 2)
    assert torch.equal(views["image"][:, :, 1], seen["image"])  # a hold: s_bar itself
    for look in range(3):  # every look follows the same past view
        assert torch.equal(views["image"][:, :, look, ..., :3], seen["image"][..., :3])
    state = env.rooms_state()
    moves = {"mover": {"action": torch.tensor([2, 0])}}
    expected = env.step(env.reset(rooms_state=state).update(moves))["next", "mover", "observation"]
    other = make_env(num_envs=2, looker=constant_looker(0), seed=5, frame_stack=2)
    got = other.step(other.reset(rooms_state=state).update(moves))["next", "mover", "observation"]
    assert torch.equal(got["image"], expected["image"]) and torch.equal(got["pan"], expected["pan"])
    with pytest.raises(ValueError, match="past_images of shape"):
        make_env(num_envs=2, frame_stack=3).load_rooms_state(state)
    with pytest.raises(ValueError, match="frame_stack=0 is invalid"):
        make_env(num_envs=1, frame_stack=0)
    env.close()
    other.close()
