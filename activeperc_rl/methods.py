"""The training methods: the paper's meta-evaluation and its four baselines, each with its options beside it.

Every method owns its networks, optimizers, environments and collectors (:class:`~activeperc_rl.method_base.Method`),
and one iteration of it (:meth:`iterate`) collects rollouts, then updates. The mover is always trained by A2C
(TorchRL's ``A2CLoss`` with GAE) on its own rollouts.

========================  ===========================================================================
method                    what runs in the mover's loop, and what learns
========================  ===========================================================================
``meta``                  the paper's section 3 (see :class:`Meta`): phi1 in E1, epsilon-greedy phi2 in E2
``fixed_forward``         the camera held forward; only the mover learns
``joint``                 one agent with the action space U^m x U^c (9 actions) on the mover's view
``ia2c``                  a looker trained by its own A2C on the shared reward, acting on ``s_bar``
``curriculum``            ``joint``, pre-trained without obstacles for a fraction of the frames
========================  ===========================================================================

A method's options are a section of the training config named after it (``meta:`` in YAML; ``--epsilon`` and the
other flags of its group on the command line).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictSequential
from torch import nn

from activeperc_env.config import is_number, with_field_docs
from activeperc_env.core import JOINT_ACTIONS, MAX_ENVS
from activeperc_rl.config import Section, finite, int_in
from activeperc_rl.envs import LOOKER, MAX_FRAME_STACK, MOVER
from activeperc_rl.losses import LOOKER_CREDITS, VIEW_CREDITS, MetaEvaluationLoss
from activeperc_rl.method_base import Iteration, Method
from activeperc_rl.models import (
    HOLD,
    JOINT,
    NUM_ACTIONS,
    Encoder,
    EpsilonGreedyLooker,
    FixedLooker,
    ReadOnlyEncoder,
    make_actor,
    make_joint_policy,
    start_holding,
)

MOVER_ROLLOUTS = ("d1", "all", "each")
E1_LOOKS = ("greedy", "sample")
OPTIMIZERS = ("adam", "sgd")
LOOKER_ENCODERS = ("own", "own_bearing", "mover")


@with_field_docs
@dataclass(frozen=True)
class LookerOptions(Section):
    """The options of every method with a learned look: its entropy bonus and how an untrained one looks."""

    looker_entropy_coeff: float = 0.0
    """Weight of the entropy bonus in the looker's loss (phi2's REINFORCE, the IA2C looker's A2C; the joint
    agent's look, given its move)."""
    looker_hold_prob: float = 0.95
    """Probability that an untrained looker holds the camera (phi1 and phi2, the IA2C looker, the joint agent's
    look); 1/3 makes every look equally likely."""

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        return {
            "looker_entropy_coeff": (
                finite(self.looker_entropy_coeff) and self.looker_entropy_coeff >= 0,
                "a finite number >= 0",
            ),
            "looker_hold_prob": (
                is_number(self.looker_hold_prob) and 0.0 < self.looker_hold_prob < 1.0,
                "a probability in (0, 1)",
            ),
        }


def positive_rate(value) -> tuple[bool, str]:
    """The check of a learning rate."""
    return finite(value) and value > 0, "a finite number > 0"


class _MoverA2C(Method):
    """The mover's actor and critic w1 (one shared encoder) and their A2C loss."""

    def __init__(self, options: Section, **parts):
        super().__init__(options, **parts)
        self.actor, self.critic, self.mover_loss = self._actor_critic("mover", MOVER, self.a2c.lr)

    def _update_mover(self, rollout: TensorDictBase) -> dict[str, float]:
        return self._step("mover", self.mover_loss, rollout)


@with_field_docs
@dataclass(frozen=True)
class MetaConfig(LookerOptions):
    """The options of meta-evaluation (``--method meta``): the paper's epsilon and alpha, and the choices it left
    open (docs/training.md, "Choices the paper left open")."""

    NAME = "meta"

    epsilon: float = 0.3
    """Probability of a uniformly random look in E2 (otherwise argmax of phi2); the paper uses 0.1 and 0.3."""
    alpha: float = 0.05
    """Soft-update rate, phi1 <- alpha phi2 + (1 - alpha) phi1 (the paper's 0.05)."""
    looker_credit: str = "best_look"
    """What each look of D2 is credited with: 'best_look' (phi2 learns which look's view the mover's critic values
    most), 'trajectory' (the paper: its trajectory's meta-evaluator), 'look' (the value the look added,
    V(s') - V(s_bar)), 'look_return' (that plus the mover's advantage at the next move: the lambda-return after the
    look against V(s_bar)) or 'every_look' (expected over the three looks' values)."""
    looker_lr: float = 3e-4
    """Adam learning rate of phi2 (the paper's preset: 3e-5)."""
    looker_optimizer: str = "adam"
    """phi2's optimizer, 'adam' or 'sgd' (whose steps grow with the meta-evaluator's size)."""
    looker_steps: int = 1
    """phi2's optimizer steps on each D2 (the paper: 1)."""
    shared_seeds: bool = True
    """E1 and E2 get the same layout streams (room i's k-th episode is the same layout in both)."""
    resample_d1: bool = True
    """Sample D1 again after the soft update for the A2C step, as the paper does (3 rollouts per iteration); False
    reuses the first D1 (2 rollouts per iteration)."""
    e2_rooms: int = 0
    """Rooms of E2 (0: as many as E1's ``num_envs``); fewer give the mover more A2C steps a frame."""
    mover_rollouts: str = "all"
    """What the mover learns from: 'all' (one A2C step on the first D1 and D2 together, then one on the D1 sampled
    after the soft update), 'each' (one step on each of those) or 'd1' (the paper: that last D1 only)."""
    e1_looks: str = "greedy"
    """How phi1 picks its looks in E1 and at test time: 'greedy' (its argmax) or 'sample' (drawn from its
    distribution)."""
    looker_importance_weights: bool = False
    """Weight each look's REINFORCE term by pi_phi2 / b, b the epsilon-greedy behaviour that drew it (the paper
    does not)."""
    looker_encoder: str = "own"
    """What phi2 (and phi1) read the looker's view with: 'own' (an encoder of their own, on the view's columns),
    'own_bearing' (their own, with the mover's bearing layout) or 'mover' (the mover's encoder, without gradient:
    only their output layer learns)."""
    mirror_looks: bool = False
    """With the 'best_look' and 'every_look' credits, value each look's view as the mean of the critic's value of it
    and of its mirror image: what the look is worth to a mover as able on either side of the room."""
    best_look_margin: float = 0.0
    """With the 'best_look' credit, a pan is the label only where the critic values its view above holding's by more
    than this (0: by any amount): where the goal is in no view, pans gain the critic about 0.01."""
    looker_frames: int = 1
    """Views of the latest cycles that phi2 and phi1 read, stacked on the image's channels (1: the view before the
    look): a memory of where the goal was, for the looker alone; needs looker_encoder 'own'."""

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        return super().checks() | {
            "epsilon": (is_number(self.epsilon) and 0.0 <= self.epsilon <= 1.0, "a probability in [0, 1]"),
            "alpha": (is_number(self.alpha) and 0.0 < self.alpha <= 1.0, "a number in (0, 1]"),
            "looker_credit": (self.looker_credit in LOOKER_CREDITS, f"one of {LOOKER_CREDITS}"),
            "looker_lr": positive_rate(self.looker_lr),
            "looker_optimizer": (self.looker_optimizer in OPTIMIZERS, f"one of {OPTIMIZERS}"),
            "looker_steps": (int_in(self.looker_steps, 1, 1000), "an int in 1 .. 1000"),
            "shared_seeds": (isinstance(self.shared_seeds, bool), "true or false"),
            "resample_d1": (isinstance(self.resample_d1, bool), "true or false"),
            "e2_rooms": (int_in(self.e2_rooms, 0, MAX_ENVS), f"an int in 0 .. {MAX_ENVS}"),
            "mover_rollouts": (self.mover_rollouts in MOVER_ROLLOUTS, f"one of {MOVER_ROLLOUTS}"),
            "e1_looks": (self.e1_looks in E1_LOOKS, f"one of {E1_LOOKS}"),
            "looker_importance_weights": (isinstance(self.looker_importance_weights, bool), "true or false"),
            "looker_encoder": (self.looker_encoder in LOOKER_ENCODERS, f"one of {LOOKER_ENCODERS}"),
            "mirror_looks": (
                self.mirror_looks is False or (self.mirror_looks is True and self.looker_credit in VIEW_CREDITS),
                f"true or false; true values every look: looker_credit one of {VIEW_CREDITS}",
            ),
            "best_look_margin": (
                finite(self.best_look_margin)
                and self.best_look_margin >= 0
                and (self.best_look_margin == 0 or self.looker_credit == "best_look"),
                "a finite number >= 0, 0 unless looker_credit is 'best_look'",
            ),
            "looker_frames": (
                int_in(self.looker_frames, 1, MAX_FRAME_STACK)
                and (self.looker_frames == 1 or self.looker_encoder == "own"),
                f"an int in 1 .. {MAX_FRAME_STACK}, 1 unless looker_encoder is 'own' (the others read one view)",
            ),
        }


class Meta(_MoverA2C):
    """The paper's meta-evaluation (section 3), one iteration (docs/training.md, "The algorithm in code").

    1. roll the mover out with phi1 in E1 (D1) and with epsilon-greedy phi2 in E2 (D2);
    2. meta-evaluator V(tau_k) of each D2 trajectory (eq. 2, :class:`MetaEvaluationLoss`);
    3. REINFORCE step on phi2 (``looker_steps`` of them) with V(tau_k) in place of the return (``looker_credit``:
       what each look is credited with; the default, ``best_look``, credits the look whose view the critic values
       most);
    4. soft update phi1 <- alpha phi2 + (1 - alpha) phi1 (eq. 3);
    5. sample D1 again with the new phi1 (``resample_d1``) and take an A2C step of theta and w1 on it
       (``mover_rollouts='all'``: first one on the first D1 and D2 together; ``'each'``: one on each);
    6. copy w1 -> w2.
    """

    Options = MetaConfig
    LOGGED = {
        "looker/meta_value": "meta_value",
        "looker/meta_value_std": "meta_value_std",
        "looker/baseline": "meta_baseline",
        "looker/entropy": "looker_entropy",
        "meta/e1_pan_rate": "e1_pan_rate",
        "meta/e2_pan_rate": "e2_pan_rate",
        "meta/e2_success_rate": "e2_success_rate",
        "looker/best_look_agreement": "best_look_agreement",
        "looker/best_look_left": "best_look_left",
        "looker/best_look_right": "best_look_right",
    }

    def __init__(self, options: MetaConfig, **parts):
        super().__init__(options, **parts)
        self.phi2 = make_actor(self._looker_encoder(), self.network.hidden_size, LOOKER).to(self.device)
        start_holding(self.phi2, options.looker_hold_prob)
        self.phi1 = copy.deepcopy(self.phi2)
        self.phi1.requires_grad_(False)
        # E1's looker: phi1's argmax ('greedy') or phi1 itself, which samples ('sample')
        self.e1_looker = EpsilonGreedyLooker(self.phi1, 0.0) if options.e1_looks == "greedy" else self.phi1
        self.w2 = copy.deepcopy(self.critic)
        self.w2.requires_grad_(False)
        self.meta_loss = MetaEvaluationLoss(
            self.phi2,
            self.w2,
            self.critic,
            entropy_coeff=options.looker_entropy_coeff,
            behaviour_epsilon=options.epsilon if options.looker_importance_weights else None,
            credit=options.looker_credit,
            mirrored=options.mirror_looks,
            margin=options.best_look_margin,
        )
        self.modules.update(phi1=self.phi1, phi2=self.phi2, w2=self.w2)
        self._optimizer("looker", [self.phi2], options.looker_lr, options.looker_optimizer)

    def _looker_encoder(self) -> nn.Module:
        """phi2's encoder (``looker_encoder``)."""
        if self.options.looker_encoder == "mover":
            return ReadOnlyEncoder(next(m for m in self.actor.modules() if isinstance(m, Encoder)))
        return self._encoder(self.options.looker_encoder == "own_bearing", self.options.looker_frames)

    def start(self) -> None:
        """Build E1 (phi1 in the loop) and E2 (epsilon-greedy phi2), with shared layout streams by default."""
        e2_seed_offset = 0 if self.options.shared_seeds else 1
        self.e1 = self._collector(self.actor, looker=self.e1_looker, name="E1's collector")
        self.e2 = self._collector(
            self.actor,
            looker=EpsilonGreedyLooker(self.phi2, self.options.epsilon),
            seed_offset=e2_seed_offset,
            name="E2's collector",
            look_views=self.options.looker_credit in VIEW_CREDITS,
            num_envs=self.options.e2_rooms or None,
        )

    def iterate(self) -> Iteration:
        """Steps 1 to 6 of the class docstring."""
        options = self.options
        d1, d2 = self._next(self.e1), self._next(self.e2)
        frames, (returns, successes) = d1.numel() + d2.numel(), finished_episodes(d1)
        looker_d2 = self._with_mover_advantage(d2) if options.looker_credit == "look_return" else d2
        with self.meta_loss.same_rollouts():
            for _ in range(options.looker_steps):
                losses = self._step("looker", self.meta_loss, looker_d2, d1)
        soft_update(self.phi1, self.phi2, options.alpha)
        if options.mover_rollouts == "all":
            both = torch.cat([d.exclude(LOOKER, ("next", LOOKER)) for d in (d1, d2)], 0)
            first = self._update_mover(both)  # logged apart from the D1 step's losses, which would overwrite them
            losses |= {key.replace("mover/", "mover_d1_d2/", 1): value for key, value in first.items()}
        elif options.mover_rollouts == "each":
            for name, rollout in (("mover_d1", d1), ("mover_d2", d2)):
                step = self._update_mover(rollout.exclude(LOOKER, ("next", LOOKER)))
                losses |= {key.replace("mover/", f"{name}/", 1): value for key, value in step.items()}
        if options.resample_d1:
            d1 = self._next(self.e1)
            frames += d1.numel()
            more_returns, more_successes = finished_episodes(d1)
            returns, successes = returns + more_returns, successes + more_successes
        if options.resample_d1 or options.mover_rollouts == "d1":
            losses |= self._update_mover(d1)
        self.w2.load_state_dict(self.critic.state_dict())
        losses["meta/e2_success_rate"] = success_rate(finished_episodes(d2)[1])
        losses["meta/e1_pan_rate"] = _pan_rate(d1)
        losses["meta/e2_pan_rate"] = _pan_rate(d2)
        return Iteration(frames, returns, successes, losses)

    def _with_mover_advantage(self, rollout: TensorDictBase) -> TensorDictBase:
        """A copy of ``rollout`` with the mover's GAE advantage of each step (by w1, which is w2 until the mover's
        update), what the ``look_return`` credit reads past each look."""
        rollout = rollout.clone(False)
        with torch.no_grad():
            self.mover_loss.value_estimator(rollout)
        return rollout

    def policy(self):
        """The mover with phi1 (the soft-updated looker) in the loop, as at test time in the paper, picking its
        looks as in E1 (``e1_looks``)."""
        return self.actor, self.e1_looker


@with_field_docs
@dataclass(frozen=True)
class FixedForwardConfig(Section):
    """The options of Fixed_Forward (``--method fixed_forward``): none of its own."""

    NAME = "fixed_forward"


class FixedForward(_MoverA2C):
    """Fixed_Forward: the looker always holds, so the camera stays forward; the mover learns by A2C.

    The hold is written by the policy next to the mover's action (the env's external mode), so no
    looker view is rendered.
    """

    Options = FixedForwardConfig

    def __init__(self, options: FixedForwardConfig, **parts):
        super().__init__(options, **parts)
        self.fixed_policy = TensorDictSequential(self.actor, FixedLooker())

    def start(self) -> None:
        """Build the environment."""
        self.collector = self._collector(self.fixed_policy)

    def iterate(self) -> Iteration:
        """One rollout, one A2C step."""
        rollout = self._next(self.collector)
        losses = self._update_mover(rollout)
        return Iteration(rollout.numel(), *finished_episodes(rollout), losses)

    def policy(self):
        """The mover, with the camera held forward."""
        return self.fixed_policy, None


@with_field_docs
@dataclass(frozen=True)
class IA2CConfig(LookerOptions):
    """The options of IA2C (``--method ia2c``): its looker's own A2C."""

    NAME = "ia2c"

    looker_lr: float = 3e-4
    """Adam learning rate of the looker's actor and critic (the paper's preset: 3e-5)."""

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        return super().checks() | {"looker_lr": positive_rate(self.looker_lr)}


class IA2C(_MoverA2C):
    """IA2C: mover and looker are independent A2C learners on the shared reward.

    The looker acts on ``s_bar`` inside the cycle. Its transition runs from ``s_bar_t`` to
    ``s_bar_{t+1}`` and its reward is the next move's, ``r_{t+1}`` (see :func:`looker_transitions`).
    """

    Options = IA2CConfig
    LOGGED = {"looker/pan_rate": "pan_rate", "looker/entropy": "looker_entropy"}

    def __init__(self, options: IA2CConfig, **parts):
        super().__init__(options, **parts)
        self.looker_actor, _, self.looker_loss = self._actor_critic("looker", LOOKER, options.looker_lr)
        start_holding(self.looker_actor, options.looker_hold_prob)

    def start(self) -> None:
        """Build the environment, with the looker in the loop."""
        self.collector = self._collector(self.actor, looker=self.looker_actor)

    def iterate(self) -> Iteration:
        """One rollout; an A2C step for the mover and one for the looker on the same rollout."""
        rollout = self._next(self.collector)
        losses = self._update_mover(rollout)
        transitions, valid = looker_transitions(rollout)
        if valid.any():  # none when every look of the rollout came after its episode's last move
            with torch.no_grad():
                self.looker_loss.value_estimator(transitions)
            losses |= self._step("looker", self.looker_loss, transitions[valid])
        losses["looker/pan_rate"] = _pan_rate(rollout)
        losses["looker/entropy"] = _entropy(rollout.get(("next", LOOKER, "logits")))
        return Iteration(rollout.numel(), *finished_episodes(rollout), losses)

    def policy(self):
        """The mover with the learned looker in the loop."""
        return self.actor, self.looker_actor


@with_field_docs
@dataclass(frozen=True)
class JointConfig(LookerOptions):
    """The options of Joint (``--method joint``): how its look is explored and starts."""

    NAME = "joint"


class Joint(Method):
    """Joint: one agent picks (u_m, u_c) as one of 9 actions from the mover's view, trained by A2C."""

    Options = JointConfig
    LOGGED = {"joint/pan_rate": "pan_rate", "joint/look_entropy": "looker_entropy"}

    def __init__(self, options: JointConfig, **parts):
        super().__init__(options, **parts)
        self.actor, _, self.loss = self._actor_critic(
            "joint", MOVER, self.a2c.lr, action_agent=JOINT, num_actions=JOINT_ACTIONS
        )
        start_holding(self.actor, options.looker_hold_prob)
        self.joint_policy = make_joint_policy(self.actor)

    def start(self) -> None:
        """Build the environment."""
        self.collector = self._collector(self.joint_policy)

    def iterate(self) -> Iteration:
        """One rollout, one A2C step."""
        rollout = self._next(self.collector)
        losses = self._step("joint", self.loss, rollout)
        losses["joint/pan_rate"] = _pan_rate(rollout, (LOOKER, "action"))  # external mode: the action at the root
        moves_by_looks = rollout.get((JOINT, "logits")).unflatten(-1, (NUM_ACTIONS, NUM_ACTIONS))  # a = 3 u_m + u_c
        losses["joint/look_entropy"] = _entropy(moves_by_looks.logsumexp(-2))
        return Iteration(rollout.numel(), *finished_episodes(rollout), losses)

    def policy(self):
        """The joint agent, writing both actions."""
        return self.joint_policy, None


@with_field_docs
@dataclass(frozen=True)
class CurriculumConfig(LookerOptions):
    """The options of Curriculum (``--method curriculum``): Joint's, and how long it trains without obstacles."""

    NAME = "curriculum"

    curriculum_fraction: float = 0.3
    """Fraction of the frames spent pre-training the joint agent in a room without obstacles."""

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        fraction = self.curriculum_fraction
        return super().checks() | {
            "curriculum_fraction": (is_number(fraction) and 0.0 < fraction < 1.0, "a number in (0, 1)")
        }


class Curriculum(Joint):
    """Curriculum: :class:`Joint` trained in an empty room for ``curriculum_fraction`` of the frames, then with
    the configured obstacles (same networks and optimizer)."""

    Options = CurriculumConfig

    def __init__(self, options: CurriculumConfig, **parts):
        super().__init__(options, **parts)
        self.frames = 0
        self.switch_at = int(options.curriculum_fraction * self.run.frames)
        self.phase = self._phase()
        self._restored_phase: dict | None = None  # a checkpoint's phase, which start() builds once

    def _phase(self) -> dict:
        """Env options of the current phase: no obstacles until ``switch_at`` frames."""
        return {"num_obstacles": 0} if self.frames < self.switch_at else {}

    def start(self) -> None:
        """Build the environment of the current phase (after :meth:`load_state_dict`, the checkpoint's: a run
        stopped in the iteration that crossed the switch point switches at its next iteration, as it would have)."""
        self.phase = self._phase() if self._restored_phase is None else self._restored_phase
        self._restored_phase = None
        self.collector = self._collector(self.joint_policy, room=self.phase)

    def iterate(self) -> Iteration:
        """One joint iteration; switches to the obstacle room once the pre-training frames are spent."""
        if self.phase != self._phase():
            self.close()
            self.start()
        iteration = super().iterate()
        self.frames += iteration.frames
        obstacles = self.phase.get("num_obstacles", self.env.num_obstacles)
        iteration.losses["curriculum/obstacles"] = float(obstacles)
        return iteration

    def state_dict(self) -> dict:
        """Networks, optimizer, the frames seen, the switch point and the phase of the environment in use."""
        return super().state_dict() | {"frames": self.frames, "switch_at": self.switch_at, "phase": self.phase}

    def load_state_dict(self, state: dict) -> None:
        """Restore networks, optimizer and the phase."""
        super().load_state_dict(state)
        self.frames, self.switch_at = state["frames"], state["switch_at"]
        self._restored_phase = state.get("phase")  # absent in older checkpoints: start() then picks the phase


METHOD_CLASSES: dict[str, type[Method]] = {
    cls.Options.NAME: cls for cls in (Meta, FixedForward, Joint, IA2C, Curriculum)
}
"""The training methods by name: the one registry that ``--method``, the configs and the option tables read."""
METHODS = tuple(METHOD_CLASSES)


@torch.no_grad()
def soft_update(target: nn.Module, source: nn.Module, alpha: float) -> None:
    """``target <- alpha * source + (1 - alpha) * target``, parameter by parameter (the paper's eq. 3)."""
    for t, s in zip(target.parameters(), source.parameters(), strict=True):
        t.lerp_(s, alpha)


def finished_episodes(rollout: TensorDictBase) -> tuple[list[float], list[bool]]:
    """The returns and successes of the episodes that ended inside ``rollout``, as the env reports them at their
    last step (``("mover", "episode_return")`` and ``("mover", "episode_success")``)."""
    done = rollout.get(("next", "done")).reshape(-1)
    returns = rollout.get(("next", MOVER, "episode_return")).reshape(-1)
    successes = rollout.get(("next", MOVER, "episode_success")).reshape(-1)
    return returns[done].tolist(), successes[done].tolist()


def looker_transitions(rollout: TensorDictBase) -> tuple[TensorDict, torch.Tensor]:
    """The looker's own transitions from a looker-mode rollout of shape ``[N, T]``, and which are valid.

    Step ``t`` of the result is ``(s_bar_t, u_c_t) -> (r_{t+1}, s_bar_{t+1}, done_{t+1})``: the look at
    cycle ``t`` pays off at the next move. A look made after the move that ended the episode
    (``done_t``) has no consequence and is invalid. The shape is ``[N, T - 1]``.
    """
    record = rollout.get(("next", LOOKER))
    done = rollout.get(("next", "done"))
    now = record[:, :-1].select("observation", "action", "action_log_prob")
    following = TensorDict(
        {
            LOOKER: {"observation": record.get("observation")[:, 1:], "reward": record.get("reward")[:, 1:]},
            "done": done[:, 1:],
            "terminated": rollout.get(("next", "terminated"))[:, 1:],
        },
        batch_size=now.batch_size,
    )
    transitions = TensorDict({LOOKER: now, "next": following}, batch_size=now.batch_size)
    return transitions, ~done[..., :-1, 0]


def _pan_rate(rollout: TensorDictBase, key: tuple[str, ...] = ("next", LOOKER, "action")) -> float:
    """The fraction of the looks of a rollout that turned the camera (``key``: where the looks are; by default the
    looker's record of a looker-mode rollout)."""
    return float((rollout.get(key) != HOLD).float().mean())


def _entropy(logits: torch.Tensor) -> float:
    """The mean entropy of the categorical distributions with these ``logits`` (last dimension)."""
    return float(torch.distributions.Categorical(logits=logits).entropy().mean())


def success_rate(successes) -> float:
    """The fraction of ``successes`` (one bool an episode) that are true; ``nan`` without an episode."""
    return float(np.mean(list(successes))) if len(successes) else float("nan")
