"""The training methods: the paper's meta-evaluation and its four baselines, one iteration each.

Every method owns its networks, optimizers, environments and collectors, and exposes
:meth:`Method.iterate` (collect, then update) plus what a checkpoint and an evaluation need.
The mover is always trained by A2C (TorchRL's ``A2CLoss`` with GAE) on its own rollouts.

========================  ===========================================================================
method                    what runs in the mover's loop, and what learns
========================  ===========================================================================
``meta``                  the paper's section 3 (see :class:`Meta`): phi1 in E1, epsilon-greedy phi2 in E2
``fixed_forward``         the camera held forward; only the mover learns
``joint``                 one agent with the action space U^m x U^c (9 actions) on the mover's view
``ia2c``                  a looker trained by its own A2C on the shared reward, acting on ``s_bar``
``curriculum``            ``joint``, pre-trained without obstacles for a fraction of the frames
========================  ===========================================================================
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictSequential
from torch import nn
from torchrl.objectives import A2CLoss, ValueEstimators

from activeperc_env.core import JOINT_ACTIONS, usable_cpus
from activeperc_rl.collection import Rollouts
from activeperc_rl.envs import LOOKER, MOVER
from activeperc_rl.losses import VIEW_CREDITS, JointA2CLoss, MetaEvaluationLoss
from activeperc_rl.models import (
    HOLD,
    JOINT,
    NUM_ACTIONS,
    EpsilonGreedyLooker,
    FixedLooker,
    make_actor,
    make_critic,
    make_encoder,
    make_joint_policy,
    start_holding,
)

if TYPE_CHECKING:  # the config names the methods (METHODS), so it imports this module
    from activeperc_rl.config import TrainConfig


@dataclass
class Iteration:
    """What one training iteration did."""

    frames: int
    """Environment cycles stepped, over every room of every environment."""
    returns: list[float] = field(default_factory=list)
    """Returns of the episodes that ended in the rollouts that measure the deployed policy."""
    successes: list[bool] = field(default_factory=list)
    """Whether each of those episodes reached the goal (in the order of :attr:`returns`)."""
    losses: dict[str, float] = field(default_factory=dict)
    """Scalar losses and diagnostics of the updates."""


class Method:
    """Base of the training methods: builds the mover's A2C; subclasses add the looker's part.

    Args:
        config: the training configuration.
        device: where the networks run.
    """

    name: str
    """The method's name in configs and on the command line (``--method``)."""
    READS: tuple[str, ...] = ()
    """The :class:`TrainConfig` options this method reads beyond those every method reads."""
    LOGGED: dict[str, str] = {}
    """The entries of :attr:`Iteration.losses` that ``metrics.csv`` holds too, and their columns there (nan where an
    iteration has no such entry)."""

    def __init__(self, config: TrainConfig, device: torch.device):
        self.config = config
        self.device = device
        self.env_seed = config.seed
        self.collectors: list[Rollouts] = []
        self.modules: dict[str, nn.Module] = {}
        self.optimizers: dict[str, torch.optim.Optimizer] = {}

    # ---------------------------------------------------------------- construction helpers
    def _encoder(self, bearing: bool = True):
        """A fresh encoder (``bearing``: with the mover's bearing layout), built on the CPU (the same initial weights
        on every device); the networks around it move to the device."""
        cfg = self.config
        bins = cfg.bearing_bins if bearing else 0
        return make_encoder(cfg.env, cfg.channels, cfg.hidden_size, bins, cfg.frame_stack)

    def _a2c(self, actor, critic, agent: str, action_agent: str | None = None) -> A2CLoss:
        """An A2C loss on ``agent``'s reward for ``actor`` (whose action lies under ``action_agent``)."""
        cfg, owner = self.config, action_agent or agent
        common = dict(critic_coeff=cfg.critic_coeff, loss_critic_type="l2", functional=False)
        if owner == JOINT:  # the move's entropy bonus and the look's apart, as the other methods weigh them
            loss = JointA2CLoss(
                actor, critic, entropy_coeff=cfg.entropy_coeff, look_entropy_coeff=cfg.looker_entropy_coeff, **common
            )
        else:
            coeff = cfg.looker_entropy_coeff if owner == LOOKER else cfg.entropy_coeff
            loss = A2CLoss(actor, critic, entropy_coeff=coeff, **common)
        loss.set_keys(
            reward=(agent, "reward"),
            action=(owner, "action"),
            sample_log_prob=(owner, "action_log_prob"),
            value="state_value",
        )
        loss.make_value_estimator(ValueEstimators.GAE, gamma=cfg.gamma, lmbda=cfg.gae_lambda)
        return loss

    def _actor_critic(
        self, name: str, agent: str, lr: float, action_agent: str | None = None, num_actions: int = NUM_ACTIONS
    ):
        """An actor and a critic on ``agent``'s view sharing one encoder, their A2C loss, and optimizer ``name``.

        The networks are registered as ``{name}_actor`` and ``{name}_critic``; the actor's action lies
        under ``action_agent`` (default: ``agent``).
        """
        encoder = self._encoder(bearing=agent == MOVER)
        actor = make_actor(encoder, self.config.hidden_size, action_agent or agent, num_actions, reads=agent)
        critic = make_critic(encoder, self.config.hidden_size, agent)
        actor.to(self.device)
        critic.to(self.device)
        loss = self._a2c(actor, critic, agent, action_agent)
        self.modules.update({f"{name}_actor": actor, f"{name}_critic": critic})
        self._optimizer(name, [actor, critic], lr)
        return actor, critic, loss

    def _collector(
        self,
        policy,
        looker=None,
        seed_offset: int = 0,
        name: str = "collector",
        room: dict | None = None,
        look_views: bool = False,
    ) -> Rollouts:
        """Rollouts ``[num_envs, rollout_length]`` of ``policy`` (and ``looker`` in the loop), collected in this process
        or by ``collect_workers`` workers (``name``: what their error messages call them), in the configured room
        with the options in ``room`` changed."""
        cfg = self.config
        # the workers' torch streams: from the run's seed (or the resumed run's env_seed) and the collector's index
        entropy = [self.env_seed, len(self.collectors)]
        collector = Rollouts(
            policy,
            looker,
            dataclasses.replace(cfg.env, **(room or {})),
            cfg.num_envs,
            cfg.rollout_length,
            env_seed=self.env_seed + seed_offset,
            torch_seed=int(np.random.SeedSequence(entropy).generate_state(1)[0]),
            workers=cfg.collect_workers,
            collector=cfg.collector,
            backend=cfg.backend,
            ray_address=cfg.ray_address,
            device=self.device,
            name=name,
            look_views=look_views,
            frame_stack=cfg.frame_stack,
        )
        self.collectors.append(collector)
        return collector

    def _next(self, collector: Rollouts) -> TensorDictBase:
        """The next rollout of ``collector``, shape ``[num_envs, rollout_length]``."""
        return next(collector)

    def _optimizer(self, name: str, modules: list[nn.Module], lr: float, kind: str = "adam") -> None:
        params = list(dict.fromkeys(p for m in modules for p in m.parameters()))
        if kind == "sgd":
            self.optimizers[name] = torch.optim.SGD(params, lr=lr)
        else:
            # portable: torch's fused step, whose square root rounds alike on every CPU (the unfused step's is MKL's)
            fused = True if self.config.portable else None
            self.optimizers[name] = torch.optim.Adam(params, lr=lr, eps=1e-5, fused=fused)

    def _step(self, name: str, loss: nn.Module, *inputs: TensorDictBase) -> dict[str, float]:
        """One step of optimizer ``name`` on the sum of the ``loss_*`` entries of ``loss(*inputs)``.

        Returns the loss's scalar entries as floats. The loss and its gradients run on ``learner_threads``
        CPU threads (the environments wait meanwhile).
        """
        with torch_threads(self.config.learner_threads or usable_cpus()):
            losses = loss(*inputs)
            total = sum(v for k, v in losses.items() if k.startswith("loss_"))
            optimizer = self.optimizers[name]
            optimizer.zero_grad(set_to_none=True)
            total.backward()
            params = [p for group in optimizer.param_groups for p in group["params"]]
            torch.nn.utils.clip_grad_norm_(params, self.config.max_grad_norm)
            optimizer.step()
        return {f"{name}/{k}": float(v.detach()) for k, v in losses.items() if v.numel() == 1}

    # ---------------------------------------------------------------- interface
    def start(self) -> None:
        """Build the environments and collectors."""
        raise NotImplementedError

    def iterate(self) -> Iteration:
        """Collect rollouts and update the networks once."""
        raise NotImplementedError

    def policy(self):
        """The deployed policy for evaluation: ``(mover_policy, looker_module_or_None)``.

        With a looker module, the env runs it inside the cycle (looker mode); without one the
        mover policy writes both agents' actions (external mode, the joint agent).
        """
        raise NotImplementedError

    def non_finite(self) -> str | None:
        """The name of the first network with a weight that is NaN or infinite (the learning diverged), or ``None``."""
        for name, module in self.modules.items():
            if not all(torch.isfinite(p).all() for p in module.parameters()):
                return name
        return None

    def state_dict(self) -> dict:
        """Networks, optimizers and the method's own counters."""
        return {
            "modules": {k: m.state_dict() for k, m in self.modules.items()},
            "optimizers": {k: o.state_dict() for k, o in self.optimizers.items()},
        }

    def load_state_dict(self, state: dict) -> None:
        """Restore what :meth:`state_dict` returned; ``ValueError`` when it does not fit these networks."""
        if not isinstance(state, dict) or not all(isinstance(state.get(k), dict) for k in ("modules", "optimizers")):
            raise ValueError("it holds no networks and optimizers")
        missing = sorted(set(self.modules) ^ set(state["modules"]))
        if missing:
            raise ValueError(f"its networks {sorted(state['modules'])} do not match {sorted(self.modules)}")
        try:
            for k, module in self.modules.items():
                module.load_state_dict(state["modules"][k])
            for k, optimizer in self.optimizers.items():
                optimizer.load_state_dict(state["optimizers"][k])
                for group in optimizer.param_groups:  # the step the config asks for, not the saved one's
                    if "fused" in group:
                        group["fused"] = optimizer.defaults["fused"]
        except (RuntimeError, ValueError, KeyError) as error:  # shapes or parameter groups of other networks
            lines = [line.strip() for line in str(error).splitlines() if line.strip()]
            raise ValueError(f"its {k!r} does not fit the config: {' '.join(lines[:2])}") from error

    def collection_state(self) -> list[dict]:
        """Where each collector's rooms stand between two rollouts (:meth:`Rollouts.state`): with
        :meth:`load_collection_state` after :meth:`start`, a resumed run with as many workers collects exactly what
        the uninterrupted run would have."""
        return [collector.state() for collector in self.collectors]

    def load_collection_state(self, states: list[dict]) -> None:
        """Put the collectors where :meth:`collection_state` left them; ``ValueError`` when they do not fit."""
        if len(states) != len(self.collectors):
            raise ValueError(f"its {len(states)} collectors' state does not fit this run's {len(self.collectors)}")
        try:
            for collector, state in zip(self.collectors, states, strict=True):
                collector.load_state(state)
        except (KeyError, TypeError, RuntimeError, ValueError) as error:  # a damaged or hand-edited checkpoint
            raise ValueError(f"its collectors' state does not fit this run: {error}") from error

    def close(self) -> None:
        """Shut the collectors and their environments down."""
        for collector in self.collectors:
            collector.shutdown()
        self.collectors.clear()


class _MoverA2C(Method):
    """The mover's actor and critic w1 (one shared encoder) and their A2C loss."""

    def __init__(self, config: TrainConfig, device: torch.device):
        super().__init__(config, device)
        self.actor, self.critic, self.mover_loss = self._actor_critic("mover", MOVER, config.lr)

    def _update_mover(self, rollout: TensorDictBase) -> dict[str, float]:
        return self._step("mover", self.mover_loss, rollout)


class FixedForward(_MoverA2C):
    """Fixed_Forward: the looker always holds, so the camera stays forward; the mover learns by A2C.

    The hold is written by the policy next to the mover's action (the env's external mode), so no
    looker view is rendered.
    """

    name = "fixed_forward"

    def __init__(self, config: TrainConfig, device: torch.device):
        super().__init__(config, device)
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


class IA2C(_MoverA2C):
    """IA2C: mover and looker are independent A2C learners on the shared reward.

    The looker acts on ``s_bar`` inside the cycle. Its transition runs from ``s_bar_t`` to
    ``s_bar_{t+1}`` and its reward is the next move's, ``r_{t+1}`` (see :func:`looker_transitions`).
    """

    name = "ia2c"
    READS = ("looker_lr", "looker_entropy_coeff", "looker_hold_prob")
    LOGGED = {"looker/pan_rate": "pan_rate", "looker/entropy": "looker_entropy"}

    def __init__(self, config: TrainConfig, device: torch.device):
        super().__init__(config, device)
        self.looker_actor, _, self.looker_loss = self._actor_critic("looker", LOOKER, config.looker_lr)
        start_holding(self.looker_actor, config.looker_hold_prob)

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


class Joint(Method):
    """Joint: one agent picks (u_m, u_c) as one of 9 actions from the mover's view, trained by A2C."""

    name = "joint"
    READS = ("looker_entropy_coeff", "looker_hold_prob")
    LOGGED = {"joint/pan_rate": "pan_rate", "joint/look_entropy": "looker_entropy"}

    def __init__(self, config: TrainConfig, device: torch.device):
        super().__init__(config, device)
        self.actor, _, self.loss = self._actor_critic(
            "joint", MOVER, config.lr, action_agent=JOINT, num_actions=JOINT_ACTIONS
        )
        start_holding(self.actor, config.looker_hold_prob)
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


class Curriculum(Joint):
    """Curriculum: :class:`Joint` trained in an empty room for ``curriculum_fraction`` of the frames, then with
    the configured obstacles (same networks and optimizer)."""

    name = "curriculum"
    READS = (*Joint.READS, "curriculum_fraction")

    def __init__(self, config: TrainConfig, device: torch.device):
        super().__init__(config, device)
        self.frames = 0
        self.switch_at = int(config.curriculum_fraction * config.frames)
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
        obstacles = self.phase.get("num_obstacles", self.config.env.num_obstacles)
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


class Meta(_MoverA2C):
    """The paper's meta-evaluation (section 3), one iteration (docs/training.md, "The algorithm in code").

    1. roll the mover out with phi1 in E1 (D1) and with epsilon-greedy phi2 in E2 (D2);
    2. meta-evaluator V(tau_k) of each D2 trajectory (eq. 2, :class:`MetaEvaluationLoss`);
    3. REINFORCE step on phi2 with V(tau_k) in place of the return;
    4. soft update phi1 <- alpha phi2 + (1 - alpha) phi1 (eq. 3);
    5. sample D1 again with the new phi1 (``resample_d1``) and take an A2C step of theta and w1 on it
       (``mover_rollouts='all'``: first one on the first D1 and D2 together);
    6. copy w1 -> w2.
    """

    name = "meta"
    READS = (
        "epsilon",
        "alpha",
        "shared_seeds",
        "resample_d1",
        "e1_looks",
        "mover_rollouts",
        "looker_importance_weights",
        "looker_credit",
        "looker_optimizer",
        "looker_lr",
        "looker_entropy_coeff",
        "looker_hold_prob",
    )
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

    def __init__(self, config: TrainConfig, device: torch.device):
        super().__init__(config, device)
        self.phi2 = make_actor(self._encoder(bearing=False), config.hidden_size, LOOKER).to(self.device)
        start_holding(self.phi2, config.looker_hold_prob)
        self.phi1 = copy.deepcopy(self.phi2)
        self.phi1.requires_grad_(False)
        # E1's looker: phi1's argmax ('greedy') or phi1 itself, which samples ('sample')
        self.e1_looker = EpsilonGreedyLooker(self.phi1, 0.0) if config.e1_looks == "greedy" else self.phi1
        self.w2 = copy.deepcopy(self.critic)
        self.w2.requires_grad_(False)
        self.meta_loss = MetaEvaluationLoss(
            self.phi2,
            self.w2,
            self.critic,
            entropy_coeff=config.looker_entropy_coeff,
            behaviour_epsilon=config.epsilon if config.looker_importance_weights else None,
            credit=config.looker_credit,
        )
        self.modules.update(phi1=self.phi1, phi2=self.phi2, w2=self.w2)
        self._optimizer("looker", [self.phi2], config.looker_lr, config.looker_optimizer)

    def start(self) -> None:
        """Build E1 (phi1 in the loop) and E2 (epsilon-greedy phi2), with shared layout streams by default."""
        e2_seed_offset = 0 if self.config.shared_seeds else 1
        self.e1 = self._collector(self.actor, looker=self.e1_looker, name="E1's collector")
        self.e2 = self._collector(
            self.actor,
            looker=EpsilonGreedyLooker(self.phi2, self.config.epsilon),
            seed_offset=e2_seed_offset,
            name="E2's collector",
            look_views=self.config.looker_credit in VIEW_CREDITS,
        )

    def iterate(self) -> Iteration:
        """Steps 1 to 6 of the class docstring."""
        d1, d2 = self._next(self.e1), self._next(self.e2)
        frames, (returns, successes) = d1.numel() + d2.numel(), finished_episodes(d1)
        losses = self._step("looker", self.meta_loss, d2, d1)
        soft_update(self.phi1, self.phi2, self.config.alpha)
        if self.config.mover_rollouts == "all":
            both = torch.cat([d.exclude(LOOKER, ("next", LOOKER)) for d in (d1, d2)], 0)
            first = self._update_mover(both)  # logged apart from the D1 step's losses, which would overwrite them
            losses |= {key.replace("mover/", "mover_d1_d2/", 1): value for key, value in first.items()}
        if self.config.resample_d1:
            d1 = self._next(self.e1)
            frames += d1.numel()
            more_returns, more_successes = finished_episodes(d1)
            returns, successes = returns + more_returns, successes + more_successes
        if self.config.resample_d1 or self.config.mover_rollouts == "d1":
            losses |= self._update_mover(d1)
        self.w2.load_state_dict(self.critic.state_dict())
        losses["meta/e2_success_rate"] = success_rate(finished_episodes(d2)[1])
        losses["meta/e1_pan_rate"] = _pan_rate(d1)
        losses["meta/e2_pan_rate"] = _pan_rate(d2)
        return Iteration(frames, returns, successes, losses)

    def policy(self):
        """The mover with phi1 (the soft-updated looker) in the loop, as at test time in the paper, picking its
        looks as in E1 (``e1_looks``)."""
        return self.actor, self.e1_looker


METHOD_CLASSES = {cls.name: cls for cls in (Meta, FixedForward, Joint, IA2C, Curriculum)}
"""The training methods by name: the one registry that ``--method``, the config's check and the option tables
read."""
METHODS = tuple(METHOD_CLASSES)
METHOD_OPTIONS = {
    option: tuple(name for name, cls in METHOD_CLASSES.items() if option in cls.READS)
    for option in dict.fromkeys(option for cls in METHOD_CLASSES.values() for option in cls.READS)
}
"""The options that only some methods read, and those methods; every other option is read by every method."""


def unused_options(config: TrainConfig, names) -> list[str]:
    """Those of the option ``names`` that ``config``'s method does not read."""
    reads = METHOD_CLASSES[config.method].READS
    return [name for name in names if name in METHOD_OPTIONS and name not in reads]


def make_method(config: TrainConfig, device: torch.device, start: bool = True) -> Method:
    """Build the configured method's networks and optimizers, and (``start``) its environments and collectors."""
    method = METHOD_CLASSES[config.method](config, device)
    if start:
        method.start()
    return method


@contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Run torch's CPU ops on ``count`` threads inside the block, then restore the previous count."""
    previous = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


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
