"""Meta-evaluation loss on synthetic tensordicts against hand-computed numbers (no env, no rendering)."""

import math
import re

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.modules import ProbabilisticActor
from torchrl.objectives import ValueEstimators

from activeperc_env.core import HOLD
from activeperc_rl.losses import (
    BEST_LOOK_SHARES,
    LOOKER_CREDITS,
    JointA2CLoss,
    MetaEvaluationLoss,
    SharedEncoderA2CLoss,
    best_looks,
    mirror,
    trajectory_ids,
    trajectory_means,
)
from activeperc_rl.models import Encoder, make_critic
from activeperc_rl.models import make_actor as make_mover_actor

PAN = ("mover", "observation", "pan")
LOOKER_PAN = ("looker", "observation", "pan")


# ----------------------------------------------------------------------------- helpers


class FixedLogits(nn.Module):
    """The same logits at every step, whatever the observation (one learnable vector)."""

    def __init__(self, logits):
        super().__init__()
        self.logits = nn.Parameter(torch.as_tensor(logits, dtype=torch.float32))

    def forward(self, pan):
        return self.logits.expand(*pan.shape[:-1], 3)


def make_actor(module=None):
    module = FixedLogits([0.0, 0.0, 0.0]) if module is None else module
    return ProbabilisticActor(
        TensorDictModule(module, in_keys=[LOOKER_PAN], out_keys=[("looker", "logits")]),
        in_keys={"logits": ("looker", "logits")},
        out_keys=[("looker", "action")],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
    )


def pan_critic():
    """V(s) = the pan entry of the mover's observation: values are hand-chosen numbers."""
    return TensorDictModule(lambda pan: pan.clone(), in_keys=[PAN], out_keys=["state_value"])


def linear_critic(weight, bias):
    net = nn.Linear(1, 1)
    with torch.no_grad():
        net.weight.fill_(weight)
        net.bias.fill_(bias)
    return TensorDictModule(net, in_keys=[PAN], out_keys=["state_value"])


def make_td(values, done, actions=None, mask=None, done_key=("next", "done")):
    values = torch.as_tensor(values, dtype=torch.float32)
    shape = values.shape
    actions = torch.zeros(shape, dtype=torch.long) if actions is None else torch.as_tensor(actions)
    td = TensorDict(
        {
            PAN: values.unsqueeze(-1),
            done_key: torch.as_tensor(done, dtype=torch.bool).unsqueeze(-1),
            ("next", *LOOKER_PAN): torch.zeros(*shape, 1),
            ("next", "looker", "action"): actions,
        },
        batch_size=shape,
    )
    if mask is not None:
        td.set(("collector", "mask"), torch.as_tensor(mask, dtype=torch.bool))
    return td


def canonical(ids):
    """Relabel trajectory ids in order of first appearance (row-major), keeping -1."""
    mapping, out = {}, []
    for i in ids.reshape(-1).tolist():
        if i < 0:
            out.append(-1)
        else:
            out.append(mapping.setdefault(i, len(mapping)))
    return torch.tensor(out).reshape(ids.shape)


F, T_ = False, True

# 4 rooms x 5 steps
DONE = [
    [F, T_, F, F, F],  # ends at t=1: trajectories t0-1 and t2-4
    [F, F, F, F, T_],  # done at the last step: one trajectory t0-4
    [T_, F, T_, F, F],  # trajectories t0, t1-2, t3-4 (the last one is all padding below)
    [F, F, F, F, F],  # fully masked below
]
MASK = [
    [T_, T_, T_, T_, T_],
    [T_, T_, T_, T_, T_],
    [T_, T_, T_, F, F],  # padded at the end of the row
    [F, F, F, F, F],  # fully padded row
]
VALUES = [
    [1.0, 3.0, 2.0, 4.0, 6.0],  # means: (1+3)/2 = 2, (2+4+6)/3 = 4
    [5.0, 5.0, 5.0, 5.0, 0.0],  # (5+5+5+5+0)/5 = 4
    [7.0, 1.0, 3.0, 100.0, 100.0],  # 7, (1+3)/2 = 2, padding ignored
    [50.0, 50.0, 50.0, 50.0, 50.0],  # padding ignored
]


# ----------------------------------------------------------------------------- trajectory_ids / means


def test_trajectory_ids_without_mask():
    ids, n = trajectory_ids(torch.tensor(DONE).unsqueeze(-1))
    assert ids.shape == (4, 5) and ids.dtype == torch.long
    assert n == 7
    assert sorted(set(ids.reshape(-1).tolist())) == list(range(7))
    expected = [
        [0, 0, 1, 1, 1],
        [2, 2, 2, 2, 2],
        [3, 4, 4, 5, 5],
        [6, 6, 6, 6, 6],
    ]
    assert canonical(ids).tolist() == expected


def test_trajectory_ids_with_mask():
    ids, n = trajectory_ids(torch.tensor(DONE), torch.tensor(MASK))
    # row 2's last trajectory (t3-4) is only padding and row 3 is only padding: 5 trajectories.
    assert n == 5
    assert sorted(set(ids[ids >= 0].tolist())) == list(range(5))
    expected = [
        [0, 0, 1, 1, 1],
        [2, 2, 2, 2, 2],
        [3, 4, 4, -1, -1],
        [-1, -1, -1, -1, -1],
    ]
    assert canonical(ids).tolist() == expected
    # a [B, T, 1] mask is accepted too
    ids3, n3 = trajectory_ids(torch.tensor(DONE).unsqueeze(-1), torch.tensor(MASK).unsqueeze(-1))
    assert n3 == 5 and torch.equal(ids3, ids)


def test_trajectory_ids_single_row_and_errors():
    ids, n = trajectory_ids(torch.tensor([[F, F, T_]]))
    assert n == 1 and ids.tolist() == [[0, 0, 0]]
    ids, n = trajectory_ids(torch.tensor([[T_, T_, T_]]))
    assert n == 3 and canonical(ids).tolist() == [[0, 1, 2]]
    with pytest.raises(ValueError, match="shape"):
        trajectory_ids(torch.zeros(2, 3, 2, dtype=torch.bool))
    with pytest.raises(ValueError, match="mask"):
        trajectory_ids(torch.zeros(2, 3, dtype=torch.bool), torch.ones(2, 4, dtype=torch.bool))


def test_trajectory_means():
    ids, n = trajectory_ids(torch.tensor(DONE), torch.tensor(MASK))
    values = torch.tensor(VALUES)
    means = trajectory_means(values, ids, n)
    assert means.shape == (5,)
    # trajectory means, by hand (see VALUES): 2, 4, 4, 7, 2
    assert sorted(means.tolist()) == pytest.approx([2.0, 2.0, 4.0, 4.0, 7.0])
    per_step = means[ids.clamp_min(0)]
    expected = torch.tensor(
        [
            [2.0, 2.0, 4.0, 4.0, 4.0],
            [4.0, 4.0, 4.0, 4.0, 4.0],
            [7.0, 2.0, 2.0, 0.0, 0.0],
        ]
    )
    valid = ids >= 0
    assert torch.allclose(per_step[:3][valid[:3]], expected[valid[:3]])
    # a critic's [B, T, 1] output gives the same
    assert torch.allclose(trajectory_means(values.unsqueeze(-1), ids, n), means)
    # padded entries may hold anything, even NaN
    values[2, 3:] = float("nan")
    values[3] = float("nan")
    assert torch.allclose(trajectory_means(values, ids, n), means)


def test_trajectory_means_is_differentiable():
    values = torch.tensor([[1.0, 2.0, 3.0]], requires_grad=True)
    ids, n = trajectory_ids(torch.tensor([[T_, F, F]]))
    trajectory_means(values, ids, n).sum().backward()
    # d/dv of [v0, (v1 + v2)/2]
    assert values.grad.tolist() == [[1.0, 0.5, 0.5]]


# ----------------------------------------------------------------------------- the loss


def reference_td():
    # D1: room 0 has K = 2 trajectories of different lengths: t0 (V = 10) and t1-3 (V = 1, 2, 3, mean 2).
    # baseline = (10 + 2) / 2 = 6, whereas the mean over all steps would be 16 / 4 = 4.
    # room 1 is only padding (huge values that must not count).
    return make_td(
        values=[[10.0, 1.0, 2.0, 3.0], [1000.0, 1000.0, 1000.0, 1000.0]],
        done=[[T_, F, F, F], [F, F, F, F]],
        mask=[[T_, T_, T_, T_], [F, F, F, F]],
    )


def rollout_td(actions=((1, 0, 2), (1, 1, 0))):
    # D2, 2 rooms x 3 steps (another shape than D1):
    #   room 0: done at t=1 -> tau_0 = t0-1 (V 7, 9: mean 8, M = 8 - 6 = 2), tau_1 = t2 (V 4, M = -2)
    #   room 1: t2 padded -> tau_2 = t0-1 (V 6, 10: mean 8, M = 2)
    return make_td(
        values=[[7.0, 9.0, 4.0], [6.0, 10.0, 999.0]],
        done=[[F, T_, F], [F, F, F]],
        actions=list(actions),
        mask=[[T_, T_, T_], [T_, T_, F]],
    )


def test_baseline_is_mean_of_trajectory_means():
    loss = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())
    out = loss(rollout_td(), reference_td())
    assert out["baseline"].item() == pytest.approx(6.0)
    assert out["num_reference_trajectories"].item() == 2.0
    assert out["num_trajectories"].item() == 3.0
    assert out["num_trajectories"].dtype.is_floating_point
    # meta values 2, -2, 2
    assert out["meta_value"].item() == pytest.approx(2.0 / 3.0)


def test_loss_uniform_policy():
    # uniform logits: log pi = -ln 3 at every step; valid steps' M: 2, 2, -2, 2, 2 (sum 6)
    # sum: -(-ln 3) * 6 = 6 ln 3; mean over 5 valid steps: 1.2 ln 3
    ln3 = math.log(3.0)
    td, ref = rollout_td(), reference_td()
    out = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())(td, ref)
    assert out["loss_looker"].item() == pytest.approx(1.2 * ln3)
    assert out["entropy"].item() == pytest.approx(ln3)
    assert out["loss_entropy"].item() == pytest.approx(-0.01 * ln3)
    out = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), reduction="sum")(td, ref)
    assert out["loss_looker"].item() == pytest.approx(6.0 * ln3)
    assert out["loss_entropy"].item() == pytest.approx(-0.01 * 5 * ln3)


def test_loss_known_log_probs():
    # probs (1/4, 1/2, 1/4); actions row 0: 1, 0, 2 with M 2, 2, -2; row 1: 1, 1 with M 2, 2
    # sum_t log pi * M = 2 ln(1/2) + 2 ln(1/4) - 2 ln(1/4) + 2 ln(1/2) + 2 ln(1/2) = -6 ln 2
    # loss sum = 6 ln 2, mean = 6 ln 2 / 5
    # entropy = -(1/4 ln 1/4 + 1/2 ln 1/2 + 1/4 ln 1/4) = 1.5 ln 2
    ln2 = math.log(2.0)
    actor = make_actor(FixedLogits(torch.tensor([0.25, 0.5, 0.25]).log()))
    loss = MetaEvaluationLoss(actor, pan_critic(), pan_critic(), entropy_coeff=0.5)
    out = loss(rollout_td(), reference_td())
    assert out["loss_looker"].item() == pytest.approx(1.2 * ln2)
    assert out["entropy"].item() == pytest.approx(1.5 * ln2)
    assert out["loss_entropy"].item() == pytest.approx(-0.5 * 1.5 * ln2)
    loss = MetaEvaluationLoss(actor, pan_critic(), pan_critic(), reduction="sum")
    assert loss(rollout_td(), reference_td())["loss_looker"].item() == pytest.approx(6.0 * ln2)


def test_importance_weights_of_the_epsilon_greedy_looks():
    # probs (1/4, 1/2, 1/4), argmax 1; epsilon 0.3: b = (0.1, 0.8, 0.1), rho = pi / b = (2.5, 0.625, 2.5)
    # actions row 0: 1, 0, 2 with M 2, 2, -2; row 1: 1, 1 with M 2, 2
    # sum_t rho log pi * M = 3 * 0.625 * 2 ln(1/2) + 2.5 * 2 ln(1/4) - 2.5 * 2 ln(1/4) = -3.75 ln 2
    # loss mean = 3.75 ln 2 / 5 = 0.75 ln 2; mean rho = (3 * 0.625 + 2 * 2.5) / 5 = 1.375
    ln2 = math.log(2.0)
    actor = make_actor(FixedLogits(torch.tensor([0.25, 0.5, 0.25]).log()))
    out = MetaEvaluationLoss(actor, pan_critic(), pan_critic(), behaviour_epsilon=0.3)(rollout_td(), reference_td())
    assert out["loss_looker"].item() == pytest.approx(0.75 * ln2)
    assert out["importance_weight"].item() == pytest.approx(1.375)
    out = MetaEvaluationLoss(actor, pan_critic(), pan_critic())(rollout_td(), reference_td())
    assert out["importance_weight"].item() == 1.0 and out["loss_looker"].item() == pytest.approx(1.2 * ln2)


@pytest.mark.parametrize("epsilon", [0.1, 0.3])
def test_importance_weights_remove_the_bias_of_a_meta_value_the_looks_do_not_change(epsilon):
    """Looks in the behaviour's proportions with one M for all: the weighted gradient on the logits is 0, the
    paper's unweighted one is M * n * (b - pi) (every look taken more often than pi takes it is pushed)."""
    pi = torch.tensor([0.025, 0.95, 0.025])
    b = torch.tensor([epsilon / 3, 1 - epsilon + epsilon / 3, epsilon / 3])
    counts = [int(round(n)) for n in (b * 300).tolist()]
    actions = [look for look, n in enumerate(counts) for _ in range(n)]
    # one trajectory of value 5 against the baseline 6: M = -1 at every step
    td = make_td(values=[[5.0] * len(actions)], done=[[F] * len(actions)], actions=[actions])
    for weighted, expected in ((True, torch.zeros(3)), (False, -1.0 * (b - pi))):
        logits = FixedLogits(pi.log())
        loss = MetaEvaluationLoss(
            make_actor(logits),
            pan_critic(),
            pan_critic(),
            entropy_coeff=0.0,
            behaviour_epsilon=epsilon if weighted else None,
        )
        (-loss(td, reference_td())["loss_looker"]).backward()  # the ascent direction, per step
        assert torch.allclose(logits.logits.grad, expected, atol=1e-6), (weighted, logits.logits.grad)


def look_td(actions=((0, 1, 2), (2, 1, 0))):
    """D2 with the view before each look (the looker's pan) and after it (the mover's pan under "next"), V = pan:
    credits room 0: 3 - 1 = 2, none at t1 (its move ended the episode), 1 - 2 = -1; room 1: 2 - 0 = 2, 3 - 3 = 0,
    t2 padded."""
    td = make_td(
        values=[[0.0] * 3] * 2, done=[[F, T_, F], [F, F, F]], actions=list(actions), mask=[[T_] * 3, [T_, T_, F]]
    )
    td.set(("next", *LOOKER_PAN), torch.tensor([[1.0, 5.0, 2.0], [0.0, 3.0, 9.0]]).unsqueeze(-1))
    td.set(("next", *PAN), torch.tensor([[3.0, 0.0, 1.0], [2.0, 3.0, 99.0]]).unsqueeze(-1))
    return td


def test_credit_per_look_is_the_value_the_look_added():
    # uniform logits: sum_t log pi * M_t = -ln 3 * (2 - 1 + 2 + 0) = -3 ln 3 over 4 looks: mean loss 0.75 ln 3
    ln3 = math.log(3.0)
    out = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="look")(look_td(), reference_td())
    assert out["loss_looker"].item() == pytest.approx(0.75 * ln3)
    assert out["meta_value"].item() == pytest.approx(0.75)
    assert out["meta_value_std"].item() == pytest.approx(math.sqrt(((1.25**2) * 2 + 1.75**2 + 0.75**2) / 4))
    assert out["baseline"].item() == pytest.approx(6.0)  # D1's, reported
    # importance weights as for the trajectory credit: probs (1/4, 1/2, 1/4), epsilon 0.3, rho (2.5, 0.625, 2.5)
    # looks 0, 2 (M 2, -1) and 2, 1 (M 2, 0): sum rho log pi M = 2.5 ln(1/4) (2 - 1 + 2) = -15 ln 2, mean 3.75 ln 2
    actor = make_actor(FixedLogits(torch.tensor([0.25, 0.5, 0.25]).log()))
    loss = MetaEvaluationLoss(actor, pan_critic(), pan_critic(), behaviour_epsilon=0.3, credit="look")
    assert loss(look_td(), reference_td())["loss_looker"].item() == pytest.approx(3.75 * math.log(2.0))


def test_credit_of_a_look_and_its_return_adds_the_movers_advantage_at_the_next_move():
    """look_td's credits (2, none, -1; 2, 0, padded) plus the advantage of the step after each look: room 0 t0
    gets t1's 20 (the move that ended the episode), t2 none (past the rollout); room 1 t0 gets 50, t1 none (t2 is
    padding): 22, -1, 52, 0."""
    td = look_td()
    td.set("advantage", torch.tensor([[10.0, 20.0, 30.0], [40.0, 50.0, 60.0]]).unsqueeze(-1))
    loss = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="look_return")
    out = loss(td, reference_td())
    assert out["meta_value"].item() == pytest.approx(73 / 4)
    assert out["loss_looker"].item() == pytest.approx(73 / 4 * math.log(3.0))
    assert "advantage" in loss.in_keys
    with pytest.raises(ValueError, match="needs the mover's advantage of each step of D2 at 'advantage'"):
        loss(look_td(), reference_td())


def test_credit_per_look_needs_a_look_that_a_move_followed():
    td = make_td(values=[[0.0, 0.0]], done=[[T_, T_]])
    td.set(("next", *PAN), torch.zeros(1, 2, 1))
    with pytest.raises(ValueError, match="no look that a move followed"):
        MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="look")(td, reference_td())


def every_look_td():
    """D2 of one room, two cycles, with the pan after each look (left, hold, right) under ("looker", "look_views"),
    V = pan: Q = (1, 0, 3) and (0, 0, -2)."""
    td = make_td(values=[[0.0, 0.0]], done=[[F, F]])
    td.set(("next", "looker", "look_views", "pan"), torch.tensor([[[1.0, 0.0, 3.0], [0.0, 0.0, -2.0]]]).unsqueeze(-1))
    return td


def test_credit_of_every_look_follows_the_expected_gradient():
    # uniform pi: E = 4/3 and -2/3; d(sum_u pi (Q - E)) / d logit_k = pi_k (Q_k - E): (-1, -4, 5) / 9, (2, 2, -4) / 9,
    # mean (1, -2, 1) / 18; the loss is its negative. meta_value: mean of E - Q(hold) = (4/3 - 2/3) / 2
    logits = FixedLogits([0.0, 0.0, 0.0])
    out = MetaEvaluationLoss(make_actor(logits), pan_critic(), pan_critic(), entropy_coeff=0.0, credit="every_look")(
        every_look_td(), reference_td()
    )
    out["loss_looker"].backward()
    assert torch.allclose(logits.logits.grad, torch.tensor([-1.0, 2.0, -1.0]) / 18, atol=1e-7)
    assert out["meta_value"].item() == pytest.approx(1 / 3)
    assert out["importance_weight"].item() == 1.0 and out["baseline"].item() == pytest.approx(6.0)


def test_credit_of_the_best_look_is_a_cross_entropy_toward_it_with_hold_winning_ties():
    # Q = (1, 0, 3): right is best; Q = (0, 0, -2): left ties with hold, so hold. Uniform pi: d(-log pi_best) / d logit
    # = pi - onehot(best): (1, 1, -2) / 3 and (1, -2, 1) / 3, mean (2, -1, -1) / 6
    logits = FixedLogits([0.0, 0.0, 0.0])
    out = MetaEvaluationLoss(make_actor(logits), pan_critic(), pan_critic(), entropy_coeff=0.0, credit="best_look")(
        every_look_td(), reference_td()
    )
    out["loss_looker"].backward()
    assert torch.allclose(logits.logits.grad, torch.tensor([2.0, -1.0, -1.0]) / 6, atol=1e-7)
    assert out["loss_looker"].item() == pytest.approx(math.log(3))
    assert out["meta_value"].item() == pytest.approx(1 / 3)  # as every_look's: what pi adds over holding


def test_a_margin_keeps_hold_the_best_look_unless_a_pan_gains_more():
    # Q = (1, 0, 3): right gains 3 over hold; Q = (0, 0, -2): nothing does. A margin of 3 labels both cycles 'hold'.
    values = torch.tensor([[1.0, 0.0, 3.0], [0.0, 0.0, -2.0]])
    assert best_looks(values).tolist() == [2, HOLD] and best_looks(values, 2.9).tolist() == [2, HOLD]
    assert best_looks(values, 3.0).tolist() == [HOLD, HOLD]
    logits = FixedLogits([0.0, 0.0, 0.0])
    loss = MetaEvaluationLoss(make_actor(logits), pan_critic(), pan_critic(), credit="best_look", margin=3.0)
    loss(every_look_td(), reference_td())["loss_looker"].backward()
    assert torch.allclose(logits.logits.grad, torch.tensor([1.0, -2.0, 1.0]) / 3, atol=1e-7)  # both toward hold
    with pytest.raises(ValueError, match="margin must be a finite number >= 0, got -1"):
        MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="best_look", margin=-1)


@pytest.mark.parametrize("credit", ["every_look", "best_look"])
def test_credits_that_value_every_look_log_how_often_phi2_picks_the_best_one(credit):
    # best looks: right (Q = 1, 0, 3), then hold (Q = 0, 0, -2, a tie); phi2's argmax is right in both cycles
    out = MetaEvaluationLoss(make_actor(FixedLogits([0.0, 0.0, 1.0])), pan_critic(), pan_critic(), credit=credit)(
        every_look_td(), reference_td()
    )
    shares = {key: out[key].item() for key in BEST_LOOK_SHARES}
    assert shares == {"best_look_agreement": 0.5, "best_look_left": 0.0, "best_look_right": 0.5}


def test_mirrored_labels_value_each_look_for_a_mover_as_able_on_either_side():
    # V = pan + pan^2: the views' Q = (2, 0, 12) and (0, 0, 2), labels right and right; their mirror images' V =
    # -pan + pan^2; the mean, pan^2 = (1, 0, 9) and (0, 0, 4), keeps the labels. With V = pan alone the mean is 0:
    # every look ties and 'hold' is the label.
    def critic(value):
        return TensorDictModule(value, in_keys=[PAN], out_keys=["state_value"])

    def labels(value):
        out = MetaEvaluationLoss(
            make_actor(FixedLogits([0.0, 0.0, 1.0])), critic(value), pan_critic(), credit="best_look", mirrored=True
        )(every_look_td(), reference_td())
        return out["best_look_right"].item(), out["best_look_agreement"].item()

    assert labels(lambda pan: pan + pan**2) == (1.0, 1.0)
    assert labels(lambda pan: pan.clone()) == (0.0, 0.0)  # phi2's argmax, right, is never the label


def test_the_mirror_image_of_an_observation():
    image = torch.arange(2 * 3 * 4 * 3, dtype=torch.uint8).reshape(2, 3, 4, 3)  # (batch, height, width, rgb)
    obs = TensorDict({("mover", "observation", "image"): image, ("mover", "observation", "pan"): torch.ones(2, 1)})
    obs.set(("mover", "observation", "range"), torch.tensor([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]))
    seen = mirror(obs)
    assert torch.equal(seen["mover", "observation", "image"][:, :, 0], image[:, :, 3])  # left column <- right
    assert torch.equal(seen["mover", "observation", "pan"], -torch.ones(2, 1))
    assert seen["mover", "observation", "range"].tolist() == [[3.0, 2.0, 1.0], [6.0, 5.0, 4.0]]
    assert torch.equal(mirror(seen)["mover", "observation", "image"], image)
    with pytest.raises(KeyError):
        mirror(TensorDict({"depth": torch.zeros(1)}))


def test_credits_that_value_one_look_have_no_best_look_shares():
    out = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="look")(look_td(), reference_td())
    assert not set(BEST_LOOK_SHARES) & set(out.keys())


def test_credit_of_every_look_needs_the_views_of_every_look():
    with pytest.raises(ValueError, match="look_views=True"):
        MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="every_look")(look_td(), reference_td())


def test_a_bad_credit_is_named():
    with pytest.raises(ValueError, match=re.escape(f"credit must be one of {LOOKER_CREDITS}, got 'step'")):
        MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), credit="step")


@pytest.mark.parametrize("epsilon", [-0.1, 1.5, math.nan, "0.3", True])
def test_a_bad_behaviour_epsilon_is_named(epsilon):
    with pytest.raises(
        ValueError,
        match=f"behaviour_epsilon must be None or a probability in \\[0, 1\\], got {re.escape(repr(epsilon))}",
    ):
        MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), behaviour_epsilon=epsilon)


def test_masked_steps_change_nothing():
    actor = make_actor(FixedLogits(torch.tensor([0.25, 0.5, 0.25]).log()))
    loss = MetaEvaluationLoss(actor, pan_critic(), pan_critic())
    out = loss(rollout_td(), reference_td())

    td = rollout_td(actions=((1, 0, 2), (1, 1, 2)))  # other action at the padded step
    # write in place into the entries (indexing a TensorDict first would only change a copy)
    td.get(PAN)[1, 2] = -123.0
    td.get(("next", *LOOKER_PAN))[1, 2] = float("nan")
    td.get(("next", "done"))[1, 2] = True
    ref = reference_td()
    ref.get(PAN)[1] = float("nan")
    ref.get(("next", "done"))[1] = True
    assert td[PAN][1, 2].item() == -123.0 and ref[PAN][1].isnan().all()
    other = loss(td, ref)
    for key in out.keys():
        assert torch.equal(out[key], other[key]), key


def test_no_mask_means_all_valid_and_trailing_action_dim():
    # D2 without mask, one room, action stored as [B, T, 1]:
    # V = 8, 4 with done at t0 -> M = 2, -2 (baseline 6); uniform: loss = -(-ln3)(2 - 2) / 2 = 0
    td = make_td(values=[[8.0, 4.0]], done=[[T_, F]], actions=[[[0], [2]]])
    out = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())(td, reference_td())
    assert out["num_trajectories"].item() == 2.0
    assert out["loss_looker"].item() == pytest.approx(0.0, abs=1e-6)
    assert out["meta_value"].item() == pytest.approx(0.0)


def test_one_dimensional_rollout():
    # a [T] rollout (single room) is one row: V 8, 10 -> M = 9 - 6 = 3; uniform: loss = ln 3 * 3
    td = make_td(values=[8.0, 10.0], done=[F, F], actions=[0, 1])
    out = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())(td, reference_td())
    assert out["num_trajectories"].item() == 1.0
    assert out["loss_looker"].item() == pytest.approx(3.0 * math.log(3.0))


def test_entropy_coeff_zero_omits_loss_entropy():
    loss = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), entropy_coeff=0.0)
    out = loss(rollout_td(), reference_td())
    assert "loss_entropy" not in out.keys()
    assert "loss_entropy" not in loss.out_keys
    assert [k for k in out.keys() if k.startswith("loss_")] == ["loss_looker"]


def test_gradients_reach_only_the_looker_and_have_the_right_sign():
    torch.manual_seed(0)
    actor = make_actor(nn.Linear(1, 3))
    critic = linear_critic(1.0, 0.0)  # V_w2 = pan
    reference_critic = linear_critic(1.0, -10.0)  # V_w1 = pan - 10: baseline = 6 - 10 = -4
    loss = MetaEvaluationLoss(actor, critic, reference_critic, entropy_coeff=0.0)
    td = rollout_td()
    td[PAN] = td[PAN] + 1.0  # lower D2 values a bit; all M_k stay positive (M = 13, 9, 13)
    td[("next", *LOOKER_PAN)] = torch.randn(2, 3, 1)
    out = loss(td, reference_td())
    assert out["baseline"].item() == pytest.approx(-4.0)
    assert out["meta_value"].item() == pytest.approx((13.0 + 9.0 + 13.0) / 3.0)
    out["loss_looker"].backward()

    actor_params = list(actor.parameters())
    assert actor_params and all(p.grad is not None and p.grad.abs().sum() > 0 for p in actor_params)
    for module in (critic, reference_critic):
        assert all(p.grad is None for p in module.parameters())

    def taken_log_prob():
        valid = td["collector", "mask"]
        with torch.no_grad():
            dist = actor.get_dist(td["next"][valid])
        return dist.log_prob(td["next", "looker", "action"][valid]).sum()

    before = taken_log_prob()
    with torch.no_grad():
        for p in actor_params:
            p -= 0.01 * p.grad
    assert taken_log_prob() > before


def test_set_keys_done():
    td = rollout_td()
    done = td.pop(("next", "done"))
    td.set(("next", "episode_end"), done)
    ref = reference_td()
    ref.set(("next", "episode_end"), ref.pop(("next", "done")))
    loss = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())
    with pytest.raises(ValueError, match="done"):
        loss(td, ref)
    loss.set_keys(done=("next", "episode_end"))
    assert loss.tensor_keys.done == ("next", "episode_end")
    assert ("next", "episode_end") in loss.in_keys
    out = loss(td, ref)
    assert out["num_trajectories"].item() == 3.0
    assert out["loss_looker"].item() == pytest.approx(1.2 * math.log(3.0))
    with pytest.raises(ValueError, match="not an accepted"):
        loss.set_keys(nonsense="x")


def test_set_keys_looker_record():
    # the looker's record stored at the root instead of under "next"
    td = rollout_td()
    td.set("looker", td.pop(("next", "looker")))
    loss = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())
    loss.set_keys(looker_record=())
    out = loss(td, reference_td())
    assert out["loss_looker"].item() == pytest.approx(1.2 * math.log(3.0))


def test_errors():
    actor, critic = make_actor(), pan_critic()
    with pytest.raises(ValueError, match="reduction"):
        MetaEvaluationLoss(actor, critic, critic, reduction="none")
    loss = MetaEvaluationLoss(actor, critic, critic)
    td = rollout_td()
    del td["next", "looker", "action"]
    with pytest.raises(ValueError, match="looker action"):
        loss(td, reference_td())

    ref = reference_td()
    ref["collector", "mask"] = torch.zeros(2, 4, dtype=torch.bool)
    with pytest.raises(ValueError, match=r"reference \(D1\) has no valid step"):
        loss(rollout_td(), ref)
    td = rollout_td()
    td["collector", "mask"] = torch.zeros(2, 3, dtype=torch.bool)
    with pytest.raises(ValueError, match=r"\(D2\) has no valid step"):
        loss(td, reference_td())
    with pytest.raises(TypeError, match="get_dist"):
        MetaEvaluationLoss(critic, critic, critic)
    with pytest.raises(ValueError, match=r"reference \(D1\) has no steps \(batch shape \(2, 0\)\)"):
        loss(rollout_td(), reference_td()[:, :0])  # not 'masked out': there is no mask
    with pytest.raises(NotImplementedError, match="no value estimator"):
        loss.make_value_estimator()


@pytest.mark.parametrize("coeff", [math.nan, math.inf, -1.0, "0.1", True, None])
def test_a_bad_entropy_coeff_is_named(coeff):
    with pytest.raises(ValueError, match=f"entropy_coeff must be a finite number >= 0, got {re.escape(repr(coeff))}"):
        MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic(), entropy_coeff=coeff)


def test_meaningless_rollouts_are_named():
    loss = MetaEvaluationLoss(make_actor(), pan_critic(), pan_critic())
    td = rollout_td()
    td["next", "done"] = td["next", "done"].float() * 0.5  # a float done would have read as True
    with pytest.raises(ValueError, match=r"\(D2\)'s \('next', 'done'\) must be bool, got torch.float32"):
        loss(td, reference_td())
    td = rollout_td()
    td["collector", "mask"] = torch.ones(2, 3)
    with pytest.raises(ValueError, match=r"'mask'\) must be bool"):
        loss(td, reference_td())
    ref = reference_td()
    ref["next", "done"] = torch.zeros(2, 4, 2, dtype=torch.bool)  # two flags per step
    with pytest.raises(ValueError, match=r"of shape \(2, 4, 2\) does not fit its batch shape \(2, 4\)"):
        loss(rollout_td(), ref)
    with pytest.raises(ValueError, match=r"must lie in 0 \.\. 2, got \[0, 1, 7\]"):
        loss(rollout_td(actions=((1, 0, 7), (1, 1, 0))), reference_td())
    td = rollout_td()
    td["next", "looker", "action"] = td["next", "looker", "action"].float() + 0.5  # 1.5 would read as 1
    with pytest.raises(ValueError, match="must be integer indices"):
        loss(td, reference_td())
    with pytest.raises(TypeError, match=r"reference \(D1\) must be a TensorDict rollout, got NoneType"):
        loss(rollout_td(), None)


def test_nan_at_padded_steps_does_not_reach_the_gradients():
    torch.manual_seed(0)
    actor = make_actor(nn.Linear(1, 3))
    loss = MetaEvaluationLoss(actor, pan_critic(), pan_critic())
    td = rollout_td()
    td.get(("next", *LOOKER_PAN))[1, 2] = float("nan")  # padded step: NaN logits if it were evaluated
    td.get(PAN)[1, 2] = float("nan")
    out = loss(td, reference_td())
    (out["loss_looker"] + out["loss_entropy"]).backward()
    assert torch.isfinite(out["loss_looker"])
    assert all(torch.isfinite(p.grad).all() for p in actor.parameters())


def _joint_loss(entropy_coeff, look_entropy_coeff):
    encoder = nn.Linear(2, 9)
    actor = ProbabilisticActor(
        TensorDictModule(encoder, in_keys=["obs"], out_keys=[("joint", "logits")]),
        in_keys={"logits": ("joint", "logits")},
        out_keys=[("joint", "action")],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
        log_prob_key=("joint", "action_log_prob"),
    )
    critic = TensorDictModule(nn.Linear(2, 1), in_keys=["obs"], out_keys=["state_value"])
    return JointA2CLoss(actor, critic, entropy_coeff=entropy_coeff, look_entropy_coeff=look_entropy_coeff)


@pytest.mark.parametrize("coeffs", [(0.01, 0.0), (0.01, 0.01), (0.0, 0.02), (0.02, 0.005)])
def test_the_joint_agents_entropy_bonus_weighs_the_move_and_the_look_apart(coeffs):
    """The bonus is c_m H(u_m) + c_c H(u_c | u_m) of the 9 joint actions a = 3 u_m + u_c, whatever the coefficients."""
    torch.manual_seed(0)
    logits = torch.randn(5, 9) * 2
    probs = torch.softmax(logits, -1).reshape(5, 3, 3)  # [u_m, u_c]
    move = probs.sum(-1)
    h_move = -(move * move.log()).sum(-1)
    h_look_given_move = -(probs * (probs / move[..., None]).log()).sum((-1, -2))
    loss = _joint_loss(*coeffs)
    bonus = loss.entropy_coeff * loss.get_entropy_bonus(torch.distributions.Categorical(logits=logits)).squeeze(-1)
    torch.testing.assert_close(bonus, coeffs[0] * h_move + coeffs[1] * h_look_given_move)


def test_the_joint_agent_without_a_look_entropy_coeff_gets_no_push_towards_random_looks():
    """With look_entropy_coeff 0, the bonus's gradient leaves how the looks split within each move alone."""
    logits = torch.tensor([[3.0, 0.0, 0.0, 2.0, -1.0, 0.0, 0.0, 0.0, 1.0]], requires_grad=True)
    _joint_loss(0.01, 0.0).get_entropy_bonus(torch.distributions.Categorical(logits=logits)).sum().backward()
    grad = logits.grad.reshape(3, 3)
    probs = torch.softmax(logits.detach(), -1).reshape(3, 3)
    # within a move the gradient is proportional to the looks' probabilities: it only moves mass between the moves
    torch.testing.assert_close(grad / probs, (grad.sum(-1) / probs.sum(-1))[:, None].expand(3, 3))


def _mover_a2c(reuse_features: bool):
    """An A2C loss of a mover whose actor and critic share one small encoder (the same weights for either choice)."""
    torch.manual_seed(0)
    encoder = Encoder(12, 16, (4,), 8)
    actor, critic = make_mover_actor(encoder, 8, "mover"), make_critic(encoder, 8, "mover")
    loss = SharedEncoderA2CLoss(
        actor, critic, entropy_coeff=0.01, critic_coeff=0.5, loss_critic_type="l2", reuse_features=reuse_features
    )
    loss.set_keys(reward=("mover", "reward"), action=("mover", "action"), sample_log_prob=("mover", "action_log_prob"))
    loss.make_value_estimator(ValueEstimators.GAE, gamma=0.99, lmbda=0.95)
    return loss, encoder


def _mover_rollout(actor, rooms=3, steps=6):
    """A rollout ``[rooms, steps]`` of random views, with an episode ending inside it, and the actor's actions."""
    generator = torch.Generator().manual_seed(1)
    images = torch.randint(0, 256, (rooms, steps + 1, 12, 16, 3), dtype=torch.uint8, generator=generator)
    pans = torch.rand(rooms, steps + 1, 1, generator=generator)
    done = torch.zeros(rooms, steps, 1, dtype=torch.bool)
    done[1, 2] = True
    observation = lambda t: TensorDict({"image": images[:, t], "pan": pans[:, t]}, [rooms, steps])  # noqa: E731
    td = TensorDict(
        {
            "mover": {"observation": observation(slice(0, steps))},
            "next": {
                "mover": {"observation": observation(slice(1, steps + 1)), "reward": torch.randn(rooms, steps, 1)},
                "done": done,
                "terminated": done.clone(),
            },
        },
        [rooms, steps],
    )
    with torch.no_grad():
        return actor(td)


def test_the_a2c_loss_reusing_the_encoders_features_is_torchrls_to_rounding():
    """One encoder pass with gradients per update (plus one without, for the next observations) gives TorchRL's
    A2C losses and gradients, which take four passes and two backward passes through the encoder."""
    results = []
    for reuse in (False, True):
        loss, encoder = _mover_a2c(reuse)
        td = _mover_rollout(loss.actor_network)
        passes = []
        encoder._features = _counted(encoder._features, passes)
        out = loss(td)
        sum(v for k, v in out.items() if k.startswith("loss_")).backward()
        grads = {name: p.grad for name, p in encoder.named_parameters()}
        results.append(({k: v.detach() for k, v in out.items()}, grads, len(passes)))
    (old, old_grads, old_passes), (new, new_grads, new_passes) = results
    assert new_passes == 2 and old_passes > new_passes
    torch.testing.assert_close(new, old)
    torch.testing.assert_close(new_grads, old_grads)


def _counted(function, calls: list):
    def counted(*args):
        calls.append(args)
        return function(*args)

    return counted
