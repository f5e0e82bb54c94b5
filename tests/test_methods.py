"""Pieces of the training methods on hand-made inputs: soft update, the looker's transitions, lookers."""

import math

import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from activeperc_env import EnvConfig
from activeperc_rl.methods import METHODS, Meta, finished_episodes, looker_transitions, soft_update, success_rate
from activeperc_rl.models import (
    BearingLayout,
    Encoder,
    EpsilonGreedyLooker,
    FixedLooker,
    ReadOnlyEncoder,
    SplitJoint,
    make_actor,
    make_encoder,
    start_holding,
)
from activeperc_rl.recipe import TrainConfig, make_method


def test_soft_update_is_eq_3():
    target, source = nn.Linear(2, 1), nn.Linear(2, 1)
    with torch.no_grad():
        target.weight.fill_(1.0), target.bias.fill_(-2.0)
        source.weight.fill_(3.0), source.bias.fill_(2.0)
    soft_update(target, source, 0.05)
    # 0.05 * 3 + 0.95 * 1 = 1.1 ; 0.05 * 2 + 0.95 * -2 = -1.8
    assert torch.allclose(target.weight, torch.full((1, 2), 1.1))
    assert torch.allclose(target.bias, torch.tensor([-1.8]))
    assert torch.equal(source.weight, torch.full((1, 2), 3.0))


def rollout(done, reward):
    """A looker-mode rollout of 1 room and len(done) steps whose looker pans are 0, 1, 2, ..."""
    t = len(done)
    pan = torch.arange(t, dtype=torch.float32).reshape(1, t, 1)
    record = {
        "observation": {"image": torch.zeros(1, t, 2, 2, 3, dtype=torch.uint8), "pan": pan},
        "action": torch.arange(t).reshape(1, t) % 3,
        "action_log_prob": torch.zeros(1, t),
        "reward": torch.tensor(reward, dtype=torch.float32).reshape(1, t, 1),
    }
    flags = torch.tensor(done).reshape(1, t, 1)
    nxt = {
        "looker": record,
        "done": flags,
        "terminated": flags.clone(),
        "mover": {"reward": torch.tensor(reward, dtype=torch.float32).reshape(1, t, 1)},
    }
    return TensorDict({"next": nxt}, batch_size=[1, t])


def test_looker_transitions_pay_the_next_move():
    # cycles 0..4; the move of cycle 2 ends the episode with reward 0.9
    td = rollout([False, False, True, False, False], [0.0, 0.0, 0.9, 0.0, 0.0])
    transitions, valid = looker_transitions(td)
    assert transitions.batch_size == (1, 4)
    # the look of cycle 1 is paid by the move of cycle 2 and ends there
    assert transitions["looker", "observation", "pan"][0, :, 0].tolist() == [0, 1, 2, 3]
    assert transitions["next", "looker", "observation", "pan"][0, :, 0].tolist() == [1, 2, 3, 4]
    assert transitions["next", "looker", "reward"][0, :, 0].tolist() == pytest.approx([0.0, 0.9, 0.0, 0.0])
    assert transitions["next", "done"][0, :, 0].tolist() == [False, True, False, False]
    # the look made after the episode-ending move (cycle 2) leads nowhere: invalid
    assert valid[0].tolist() == [True, True, False, True]


def test_finished_episodes_are_the_outcomes_the_env_reports():
    td = rollout([False, True, False, True, False], [0.1, 0.8, 0.1, 0.1, 0.1])  # a dense reward
    td["next", "mover", "episode_return"] = torch.tensor([0.1, 0.9, 0.1, 0.2, 0.3]).reshape(1, 5, 1)
    td["next", "mover", "episode_success"] = torch.tensor([False, True, False, False, False]).reshape(1, 5, 1)
    returns, successes = finished_episodes(td)
    assert returns == pytest.approx([0.9, 0.2]) and successes == [True, False]  # not the last rewards, nor > 0
    assert success_rate(successes) == 0.5 and math.isnan(success_rate([]))


def observation(n):
    """Random looker views of ``n`` rooms of the default room (its image, pan and range readings)."""
    rays = EnvConfig().range_rays
    return TensorDict(
        {
            "looker": {
                "observation": {
                    "image": torch.randint(0, 255, (n, 60, 80, 3), dtype=torch.uint8),
                    "pan": torch.zeros(n, 1),
                    "range": torch.rand(n, rays) * 2,
                }
            }
        },
        batch_size=[n],
    )


def test_epsilon_greedy_looker():
    torch.manual_seed(0)
    actor = make_actor(make_encoder(EnvConfig(), (4,), 8), 8, "looker")
    td = observation(300)
    greedy = actor[0](td.clone())["looker", "logits"].argmax(-1)
    assert torch.equal(EpsilonGreedyLooker(actor, 0.0)(td.clone())["looker", "action"], greedy)
    uniform = EpsilonGreedyLooker(actor, 1.0)(td.clone())["looker", "action"]
    counts = torch.bincount(uniform, minlength=3)
    assert (counts > 60).all(), counts  # about 100 each
    mixed = EpsilonGreedyLooker(actor, 0.3)(td.clone())["looker", "action"]
    # 70 % greedy plus a third of the 30 % random picks the greedy action by chance: about 80 %
    agree = (mixed == greedy).float().mean()
    assert 0.7 < agree < 0.9, agree


@pytest.mark.parametrize("hold_prob", [0, 1.0, 1.5, "0.9"])
def test_start_holding_names_a_bad_probability(hold_prob):
    actor = make_actor(make_encoder(EnvConfig(), (4,), 8), 8, "looker")
    with pytest.raises(ValueError, match=f"hold_prob={hold_prob!r} is invalid"):
        start_holding(actor, hold_prob)


@pytest.mark.parametrize(("num_actions", "hold_prob"), [(3, 0.95), (9, 0.9), (3, 1 / 3)])
def test_start_holding_sets_the_untrained_look(num_actions, hold_prob):
    torch.manual_seed(0)
    actor = make_actor(make_encoder(EnvConfig(), (4,), 8), 8, "looker", num_actions=num_actions)
    start_holding(actor, hold_prob)
    td = observation(50)
    td["looker", "observation", "pan"] = torch.rand(50, 1) * 4 - 2
    probs = torch.softmax(actor[0](td)["looker", "logits"], -1)
    look = torch.arange(num_actions) % 3
    # every view gets the same start: the looks' marginal is (q, p, q); the moves under each look are uniform
    assert torch.allclose(probs[:, look == 1].sum(-1), torch.full((50,), hold_prob))
    assert torch.allclose(probs[:, look == 0].sum(-1), torch.full((50,), (1 - hold_prob) / 2))
    assert torch.allclose(probs, probs[:1].expand_as(probs))
    if hold_prob > 1 / 3:
        assert (probs.argmax(-1) % 3 == 1).all()
    actor[0](td)["looker", "logits"].sum().backward()
    assert actor[0].module.out.weight.grad.abs().sum() > 0  # it still learns


def test_fixed_looker_and_joint_split():
    td = FixedLooker()(observation(4))
    assert td["looker", "action"].tolist() == [1, 1, 1, 1]
    mover, looker = SplitJoint()(torch.arange(9))
    assert mover.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2] and looker.tolist() == [0, 1, 2] * 3


def test_encoder_scales_images_without_touching_its_input():
    encoder = make_encoder(EnvConfig(), (4,), 8)
    image = torch.randint(0, 256, (2, 60, 80, 3), dtype=torch.uint8)
    pan, ranges = torch.zeros(2, 1), torch.full((2, EnvConfig().range_rays), 1.0)
    as_float = image.float()  # a float image is scaled in the encoder's own copy, never in place
    kept = as_float.clone()
    assert torch.equal(encoder(image, pan, ranges), encoder(as_float, pan, ranges))
    assert torch.equal(as_float, kept)


def test_encoder_reads_the_range_sensor_where_the_room_has_one():
    torch.manual_seed(0)
    image, pan = torch.randint(0, 256, (2, 60, 80, 3), dtype=torch.uint8), torch.zeros(2, 1)
    ranged = make_encoder(EnvConfig(), (4,), 8)
    near, far = torch.full((2, 13), 0.2), torch.full((2, 13), 2.0)
    assert not torch.equal(ranged(image, pan, near), ranged(image, pan, far))
    assert make_encoder(EnvConfig(version=0), (4,), 8)(image, pan).shape == (2, 8)  # v0: image and pan only


def test_encoder_names_an_image_of_another_layout():
    encoder = make_encoder(EnvConfig(), (4,), 8)
    chw = torch.rand(2, 3, 60, 80)  # what TorchRL's ToTensorImage makes of the env's images
    with pytest.raises(ValueError, match=r"shape \(2, 3, 60, 80\).*ToTensorImage"):
        encoder(chw, torch.zeros(2, 1))


def test_the_bearing_layout_puts_a_view_where_the_camera_looks():
    """A feature seen at the view's left edge lands one pan step further left with the camera panned one step left,
    and nothing lands where the camera does not look."""
    layout = BearingLayout(bins=30, rows=2, fov=60.0, pan_range=120.0)  # 10-degree bins, -150 .. 150
    features = torch.zeros(2, 1, 2, 8)
    features[:, 0, :, 0] = 1.0  # the view's leftmost column (26 degrees left of the camera's axis)
    laid = layout(features, torch.tensor([[0.0], [math.radians(30)]]))
    bins = [row.nonzero().flatten().tolist() for row in laid[:, 0, 0]]
    assert [layout.bearings[b].rad2deg().round().tolist() for b in bins] == [[25.0], [55.0]]
    assert torch.equal(laid[:, :, 0], laid[:, :, 1])  # every row alike
    seen = layout(torch.ones(1, 1, 2, 8), torch.zeros(1, 1))[0, 0, 0] > 0
    assert layout.bearings[seen].abs().max() < math.radians(30) and seen.sum() == 6  # the 60 degrees in view


def test_a_mover_with_the_bearing_layout_reads_the_pan_into_its_features():
    encoder = make_encoder(EnvConfig(), (4,), 8, bearing_bins=12)
    image, ranges = torch.randint(0, 256, (1, 60, 80, 3), dtype=torch.uint8), torch.ones(1, 13)
    ahead, left = encoder(image, torch.zeros(1, 1), ranges), encoder(image, torch.full((1, 1), 0.5), ranges)
    assert ahead.shape == left.shape == (1, 8) and not torch.equal(ahead, left)


def test_an_encoder_of_a_frame_stack_reads_every_view_and_pan():
    encoder = make_encoder(EnvConfig(), (4,), 8, frames=3)
    image, ranges = torch.randint(0, 256, (2, 60, 80, 9), dtype=torch.uint8), torch.ones(2, 13)
    pans = torch.zeros(2, 3)
    features = encoder(image, pans, ranges)
    assert features.shape == (2, 8)
    older = image.clone()
    older[..., :3] = 0  # only the oldest view changes
    assert not torch.equal(encoder(older, pans, ranges), features)
    assert not torch.equal(encoder(image, pans + torch.tensor([0.5, 0, 0]), ranges), features)
    with pytest.raises(ValueError, match=r"\(\*batch, 60, 80, 3 \* stack\), stack >= 3.*frame_stack >= 3"):
        encoder(image[..., :3], pans[:, :1], ranges)
    with pytest.raises(ValueError, match="bearing_bins=12 lays out one view"):
        make_encoder(EnvConfig(), (4,), 8, bearing_bins=12, frames=2)


def test_an_encoder_given_a_deeper_stack_reads_its_latest_views():
    torch.manual_seed(0)
    encoder = make_encoder(EnvConfig(), (4,), 8, frames=2)
    image, pans, ranges = torch.randint(0, 256, (2, 60, 80, 12), dtype=torch.uint8), torch.rand(2, 4), torch.ones(2, 13)
    latest = encoder(image[..., 6:], pans[:, 2:], ranges)
    assert torch.equal(encoder(image, pans, ranges), latest)
    image[..., :6], pans[:, :2] = 0, 0.0  # the older views are not read
    assert torch.equal(encoder(image, pans, ranges), latest)


def test_a_meta_looker_that_remembers_reads_a_stack_beside_a_mover_of_one_view():
    config = TrainConfig.from_options(
        num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, bearing_bins=6, looker_frames=3, looker_lr=0.01,
        env={"version": 3},
    )  # fmt: skip
    assert config.stacked_views == 3 and config.network.frame_stack == 1
    meta = make_method(config, torch.device("cpu"))
    phi2 = _parameters(meta.phi2)
    try:
        d2 = meta._next(meta.e2)
        meta.iterate()
    finally:
        meta.close()
    assert d2.get(("looker", "observation", "image")).shape[-1] == 9
    assert d2.get(("looker", "observation", "pan")).shape[-1] == 3
    assert [e.frames for e in _encoders(meta.phi2) + _encoders(meta.phi1)] == [3, 3]
    assert [e.frames for e in _encoders(meta.actor)] == [1]
    assert any(not torch.equal(a, b) for a, b in zip(phi2, _parameters(meta.phi2), strict=True))


def test_curriculum_keeps_its_switch_point_on_resume():
    from activeperc_rl.recipe import TrainConfig, make_method

    small = dict(method="curriculum", channels=(4,), hidden_size=8)
    first = make_method(TrainConfig.from_options(frames=1000, **small), torch.device("cpu"), start=False)
    first.frames = 400  # past the switch at 300
    resumed = make_method(TrainConfig.from_options(frames=5000, **small), torch.device("cpu"), start=False)
    assert resumed.switch_at == 1500
    resumed.load_state_dict(first.state_dict())
    assert (resumed.frames, resumed.switch_at) == (400, 300) and resumed._phase() == {}


@pytest.mark.parametrize(
    ("mover_rollouts", "resample_d1", "expected", "logged"),
    [
        ("d1", True, [2], {"mover"}),
        ("all", True, [4, 2], {"mover_d1_d2", "mover"}),
        ("all", False, [4], {"mover_d1_d2"}),
        ("each", True, [2, 2, 2], {"mover_d1", "mover_d2", "mover"}),
        ("each", False, [2, 2], {"mover_d1", "mover_d2"}),
    ],
)
def test_meta_mover_rollouts(mover_rollouts, resample_d1, expected, logged):
    from activeperc_rl.recipe import TrainConfig, make_method

    config = TrainConfig.from_options(
        num_envs=2, rollout_length=4, channels=(4,), hidden_size=8,
        mover_rollouts=mover_rollouts, resample_d1=resample_d1,
    )  # fmt: skip
    method = make_method(config, torch.device("cpu"))
    rooms, update = [], method._update_mover
    method._update_mover = lambda rollout: rooms.append(rollout.shape[0]) or update(rollout)
    try:
        iteration = method.iterate()
    finally:
        method.close()
    assert rooms == expected
    assert {key.split("/")[0] for key in iteration.losses if key.endswith("/loss_objective")} == logged
    assert iteration.losses["meta/e1_pan_rate"] == 0.0  # E1 plays the untrained phi1's argmax: hold
    assert iteration.frames == (3 if resample_d1 else 2) * 2 * 4


def test_meta_collects_e2_in_e2_rooms_and_counts_its_frames():
    config = TrainConfig.from_options(num_envs=4, rollout_length=4, channels=(4,), hidden_size=8, e2_rooms=1)
    method = make_method(config, torch.device("cpu"))
    rooms, update = [], method._update_mover
    method._update_mover = lambda rollout: rooms.append(rollout.shape[0]) or update(rollout)
    try:
        iteration = method.iterate()
        d2 = method._next(method.e2)
    finally:
        method.close()
    assert d2.shape == (1, 4) and rooms == [4 + 1, 4]
    assert iteration.frames == (4 + 1 + 4) * 4


def _encoders(module) -> list:
    return [m for m in module.modules() if isinstance(m, (Encoder, ReadOnlyEncoder))]


@pytest.mark.parametrize(("looker_encoder", "bins"), [("own", None), ("own_bearing", 6)])
def test_meta_builds_phi1_and_phi2_on_their_own_encoder_with_or_without_the_bearing_layout(looker_encoder, bins):
    config = TrainConfig.from_options(
        num_envs=2, rollout_length=2, channels=(4,), hidden_size=8, bearing_bins=6, looker_encoder=looker_encoder
    )
    method = make_method(config, torch.device("cpu"), start=False)
    for name in ("phi1", "phi2"):
        (encoder,) = _encoders(method.modules[name])
        assert isinstance(encoder, Encoder) and encoder is not _encoders(method.actor)[0]
        assert (encoder.layout and encoder.layout.bearings.numel()) == bins


def test_meta_with_the_mover_s_encoder_trains_only_the_looker_s_output_layer():
    config = TrainConfig.from_options(
        num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, looker_encoder="mover", mover_rollouts="d1",
        resample_d1=False,
    )  # fmt: skip
    method = make_method(config, torch.device("cpu"))
    (mover_encoder,) = _encoders(method.actor)
    try:
        before = {k: v.clone() for k, v in mover_encoder.state_dict().items()}
        heads = [dict(method.modules[name].named_parameters()) for name in ("phi1", "phi2")]
        d1, d2 = method._next(method.e1), method._next(method.e2)
        method._step("looker", method.meta_loss, d2, d1)
    finally:
        method.close()
    assert [_encoders(method.modules[name])[0].source for name in ("phi1", "phi2")] == [mover_encoder] * 2
    assert all(set(head) == {"module.0.module.out.weight", "module.0.module.out.bias"} for head in heads)
    assert all(torch.equal(before[k], v) for k, v in mover_encoder.state_dict().items())
    assert heads[1]["module.0.module.out.weight"].abs().sum() > 0  # phi2's layer learned (it starts at zero)


def test_e2_with_fewer_rooms_than_workers_is_refused():
    refused = r"meta.e2_rooms=1 is invalid: expected 0 or at least run.collect_workers=2"
    with pytest.raises(ValueError, match=refused):
        TrainConfig.from_options(num_envs=4, collect_workers=2, e2_rooms=1)
    assert TrainConfig.from_options(num_envs=4, collect_workers=2, e2_rooms=2).options.e2_rooms == 2


def test_a_failed_start_shuts_down_the_collectors_it_had_opened(monkeypatch):
    config = TrainConfig.from_options(num_envs=4, collect_workers=2, channels=(4,), hidden_size=8)
    closed, close, collector = [], Meta.close, Meta._collector
    monkeypatch.setattr(Meta, "close", lambda self: closed.append(len(self.collectors)) or close(self))

    def failing_e2(self, *args, name="collector", **kwargs):
        if name == "E2's collector":
            raise ValueError("E2 refused")
        return collector(self, *args, name=name, **kwargs)

    monkeypatch.setattr(Meta, "_collector", failing_e2)
    with pytest.raises(ValueError, match="E2 refused"):
        make_method(config, torch.device("cpu"))
    assert closed == [1]  # E1's workers, started first, were shut down


@pytest.mark.parametrize("looker_steps", [1, 3])
def test_meta_takes_looker_steps_on_each_d2(looker_steps, monkeypatch):
    from activeperc_rl import losses
    from activeperc_rl.recipe import TrainConfig, make_method

    config = TrainConfig.from_options(
        num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, looker_steps=looker_steps
    )
    method = make_method(config, torch.device("cpu"))
    steps, step = [], method._step
    method._step = lambda name, *args: steps.append(name) or step(name, *args)
    valued, value = [], losses.view_values
    monkeypatch.setattr(losses, "view_values", lambda *args: valued.append(1) or value(*args))
    try:
        method.iterate()
    finally:
        method.close()
    assert steps.count("looker") == looker_steps
    assert len(valued) == 1  # the critic values the looks' views once for all the steps
    state = method.optimizers["looker"].state
    assert {int(s["step"]) for s in state.values()} == {looker_steps}


def test_looker_and_mover_entropy_weights_are_separate():
    from activeperc_rl.recipe import TrainConfig, make_method

    small = dict(channels=(4,), hidden_size=8, entropy_coeff=0.02, looker_entropy_coeff=0.005)
    ia2c = make_method(TrainConfig.from_options(method="ia2c", **small), torch.device("cpu"), start=False)
    meta = make_method(TrainConfig.from_options(method="meta", **small), torch.device("cpu"), start=False)
    assert float(ia2c.mover_loss.entropy_coeff) == pytest.approx(0.02)
    assert float(ia2c.looker_loss.entropy_coeff) == pytest.approx(0.005)
    assert float(meta.mover_loss.entropy_coeff) == pytest.approx(0.02)
    assert float(meta.meta_loss.entropy_coeff) == pytest.approx(0.005)


def test_looker_importance_weights_flag_reaches_the_meta_loss():
    from activeperc_rl.cli import build_parser, config_from_args
    from activeperc_rl.recipe import make_method

    for argv, expected in (([], None), (["--looker-importance-weights", "--epsilon", "0.1"], 0.1)):
        args = build_parser().parse_args(["--channels", "4", "--hidden-size", "8", *argv])
        meta = make_method(config_from_args(args), torch.device("cpu"), start=False)
        assert meta.meta_loss.behaviour_epsilon == expected


@pytest.mark.parametrize("e1_looks", ["greedy", "sample"])
def test_meta_e1_looks(e1_looks):
    from activeperc_rl.recipe import TrainConfig, make_method

    config = TrainConfig.from_options(channels=(4,), hidden_size=8, e1_looks=e1_looks, looker_hold_prob=0.9)
    meta = make_method(config, torch.device("cpu"), start=False)
    mover, looker = meta.policy()
    assert mover is meta.actor
    views = observation(400)
    views["looker", "observation", "pan"] = torch.rand(400, 1)
    with set_exploration_type(ExplorationType.RANDOM):  # as in the collectors and activeperc-eval
        looks = looker(views.clone()).get(("looker", "action"))
    if e1_looks == "greedy":
        assert (looks == 1).all()  # the untrained phi1's argmax holds
        with torch.no_grad():
            meta.phi1[0].module.out.bias.copy_(torch.tensor([5.0, 0.0, 0.0]))
        assert (looker(views.clone()).get(("looker", "action")) == 0).all()  # it follows phi1's weights
    else:
        assert 0.8 < (looks == 1).float().mean() < 0.97  # draws from phi1: hold with probability 0.9


def test_updates_run_on_learner_threads():
    from activeperc_rl.recipe import TrainConfig, make_method

    config = TrainConfig.from_options(num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, learner_threads=2)
    method = make_method(config, torch.device("cpu"))
    seen, loss = [], method.mover_loss

    class Spy(nn.Module):
        def forward(self, rollout):
            seen.append(torch.get_num_threads())
            return loss(rollout)

    method.mover_loss = Spy()
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        method.iterate()
        assert torch.get_num_threads() == 1  # collection keeps its thread count
    finally:
        method.close()
        torch.set_num_threads(before)
    assert seen == [2, 2]  # both of the mover's A2C steps ('all')


@pytest.mark.parametrize("method", METHODS)
def test_every_network_lands_on_the_device(method):
    # torch's "meta" device stands in for a GPU: a layer left on the CPU shows up here without one
    config = TrainConfig.from_options(method=method, channels=(8,), hidden_size=16)
    built = make_method(config, torch.device("meta"), start=False)
    for name, module in built.modules.items():
        for key, tensor in [*module.named_parameters(), *module.named_buffers()]:
            assert tensor.device.type == "meta", (name, key, tensor.device)


def test_ia2c_skips_the_looker_update_when_no_look_of_a_rollout_is_valid():
    """With 2-cycle rollouts and 3-cycle episodes, some rollouts hold only the look after an episode's last move."""
    config = TrainConfig.from_options(
        method="ia2c", num_envs=1, rollout_length=2, channels=(8,), hidden_size=16, env={"max_cycles": 3}
    )
    method = make_method(config, torch.device("cpu"))
    try:
        logged = [method.iterate().losses for _ in range(3)]
    finally:
        method.close()
    assert ["looker/loss_objective" in losses for losses in logged] == [True, False, True]


def test_a_collector_that_fails_to_start_closes_its_env(monkeypatch):
    """The env made for a collector holds a GL context and physics threads: a failed Collector must not leak them."""
    from activeperc_rl import collection as methods

    made, original = [], methods.make_env

    def make_env(*args, **kwargs):
        made.append(original(*args, **kwargs))
        return made[-1]

    def broken_collector(*args, **kwargs):
        raise RuntimeError("collector refused")

    monkeypatch.setattr(methods, "make_env", make_env)
    monkeypatch.setattr(methods, "Collector", broken_collector)
    method = make_method(TrainConfig.from_options(method="fixed_forward", num_envs=2), torch.device("cpu"), start=False)
    with pytest.raises(RuntimeError, match="collector refused"):
        method.start()
    assert len(made) == 1 and made[0].is_closed


def _parameters(module: nn.Module) -> list[torch.Tensor]:
    return [p.detach().clone() for p in module.parameters()]


def test_a_meta_iteration_soft_updates_phi1_towards_the_new_phi2_and_copies_w1_to_w2():
    """Steps 4 and 6 of Meta.iterate, where they are called: phi1 <- alpha phi2 + (1 - alpha) phi1 with the phi2 of
    this iteration's REINFORCE step, and w2 = w1 after the mover's A2C steps."""
    config = TrainConfig.from_options(
        num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, alpha=0.5, looker_lr=0.01,
        looker_entropy_coeff=0.01,  # a gradient on phi2 from the first iteration on
    )  # fmt: skip
    meta = make_method(config, torch.device("cpu"))
    phi1, phi2, critic = _parameters(meta.phi1), _parameters(meta.phi2), _parameters(meta.critic)
    try:
        meta.iterate()
    finally:
        meta.close()
    new_phi2 = _parameters(meta.phi2)
    assert any(not torch.equal(a, b) for a, b in zip(phi2, new_phi2, strict=True))  # the REINFORCE step
    for before, after, source in zip(phi1, _parameters(meta.phi1), new_phi2, strict=True):
        assert torch.allclose(after, 0.5 * source + 0.5 * before)
    assert any(not torch.equal(a, b) for a, b in zip(critic, _parameters(meta.critic), strict=True))  # A2C steps
    for key, value in meta.critic.state_dict().items():
        assert torch.equal(meta.w2.state_dict()[key], value), key


@pytest.mark.parametrize("credit", ["every_look", "best_look"])
def test_a_meta_iteration_that_values_every_look_draws_their_views_and_steps_phi2(credit):
    config = TrainConfig.from_options(num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, looker_lr=0.01,
                         looker_credit=credit, env={"version": 3})  # fmt: skip
    meta = make_method(config, torch.device("cpu"))
    phi2 = _parameters(meta.phi2)
    try:
        meta.iterate()
    finally:
        meta.close()
    # (the loss refuses a D2 without the views of every look: E2 drew them)
    assert any(not torch.equal(a, b) for a, b in zip(phi2, _parameters(meta.phi2), strict=True))


def test_a_meta_iteration_with_the_look_return_credit_reads_the_movers_advantage_of_a_copy_of_d2():
    config = TrainConfig.from_options(num_envs=2, rollout_length=4, channels=(4,), hidden_size=8, looker_lr=0.01,
                         looker_credit="look_return", looker_importance_weights=True, env={"version": 3})  # fmt: skip
    meta = make_method(config, torch.device("cpu"))
    phi2 = _parameters(meta.phi2)
    try:
        d2 = meta._next(meta.e2)
        copy = meta._with_mover_advantage(d2)
        meta.iterate()
    finally:
        meta.close()
    assert copy.get("advantage").shape == (2, 4, 1) and copy.get("advantage").abs().sum() > 0
    assert "advantage" not in d2.keys() and ("next", "state_value") not in d2.keys(True)  # the mover's D2 as it was
    assert any(not torch.equal(a, b) for a, b in zip(phi2, _parameters(meta.phi2), strict=True))


@pytest.mark.parametrize("shared_seeds", [True, False])
def test_e2_explores_with_epsilon_on_e1s_layouts_unless_told_otherwise(shared_seeds):
    config = TrainConfig.from_options(num_envs=4, rollout_length=8, channels=(4,), hidden_size=8, epsilon=1.0,
                         shared_seeds=shared_seeds)  # fmt: skip
    meta = make_method(config, torch.device("cpu"))
    try:
        d1, d2 = meta._next(meta.e1), meta._next(meta.e2)
        same_layouts = (meta.e1.env.episode_seeds == meta.e2.env.episode_seeds).all()
    finally:
        meta.close()
    assert (d1.get(("next", "looker", "action")) == 1).all()  # E1: the untrained phi1's argmax holds
    holds = (d2.get(("next", "looker", "action")) == 1).float().mean()
    assert 0.1 < holds < 0.6  # E2 at epsilon 1: uniformly random looks, a third of them 'hold'
    assert same_layouts == shared_seeds


def test_curriculum_trains_in_the_empty_room_then_with_the_obstacles():
    config = TrainConfig.from_options(
        method="curriculum", frames=100, curriculum_fraction=0.3, num_envs=4, rollout_length=8, channels=(4,),
        hidden_size=8,
    )  # fmt: skip
    curriculum = make_method(config, torch.device("cpu"))
    try:
        assert curriculum.switch_at == 30 and curriculum.collector.env.config.num_obstacles == 0
        logged = [curriculum.iterate().losses["curriculum/obstacles"] for _ in range(2)]  # 32 frames each
        assert curriculum.collector.env.config.num_obstacles == 3
    finally:
        curriculum.close()
    assert logged == [0.0, 3.0]


def test_method_registry_names_real_options_and_feeds_the_cli():
    """Each method class's options are a section named after it, and --method offers exactly the registered
    classes."""
    from activeperc_rl import cli
    from activeperc_rl.config import Section
    from activeperc_rl.methods import METHOD_CLASSES

    for name, cls in METHOD_CLASSES.items():
        assert issubclass(cls.Options, Section) and cls.Options.NAME == name
        assert TrainConfig(method=name).options == cls.Options()
    method_flag = next(a for a in cli.build_parser()._actions if a.dest == "method")
    assert tuple(method_flag.choices) == METHODS
