"""What every training method is built from: :class:`Method` (its networks, optimizers and collectors, and one
optimizer step) and :class:`Iteration`, what one iteration did. The methods themselves are in
:mod:`activeperc_rl.methods`."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import torch
from tensordict import TensorDictBase
from torch import nn
from torchrl.objectives import A2CLoss, ValueEstimators

from activeperc_env import EnvConfig
from activeperc_env.core import usable_cpus
from activeperc_rl.collection import Rollouts
from activeperc_rl.config import A2CConfig, RunConfig, Section
from activeperc_rl.envs import LOOKER, MOVER
from activeperc_rl.losses import JointA2CLoss, SharedEncoderA2CLoss
from activeperc_rl.models import JOINT, NUM_ACTIONS, NetworkConfig, make_actor, make_critic, stacked_views


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
        options: the method's own options (its :attr:`Options`).
        run: the run's settings (rooms, rollout length, seed, collection, threads).
        a2c: the A2C settings every method shares.
        network: the networks' settings.
        env: the room (the same for every environment of the run and for evaluation).
        device: where the networks run.
    """

    Options: ClassVar[type[Section]]
    """The method's options (a section of the training config named after the method: ``Options.NAME``)."""
    LOGGED: ClassVar[dict[str, str]] = {}
    """The entries of :attr:`Iteration.losses` that ``metrics.csv`` holds too, and their columns there (nan where an
    iteration has no such entry)."""

    def __init__(
        self,
        options: Section,
        *,
        run: RunConfig,
        a2c: A2CConfig,
        network: NetworkConfig,
        env: EnvConfig,
        device: torch.device,
    ):
        self.options, self.run, self.a2c, self.network, self.env = options, run, a2c, network, env
        self.device = device
        self.env_seed = run.seed
        self.collectors: list[Rollouts] = []
        self.modules: dict[str, nn.Module] = {}
        self.optimizers: dict[str, torch.optim.Optimizer] = {}
        self.learning_rates: dict[str, float] = {}  # each optimizer's learning rate at the first frame

    # ---------------------------------------------------------------- construction helpers
    def _encoder(self, bearing: bool = True, frames: int | None = None):
        """A fresh encoder (``bearing``: with the mover's bearing layout; ``frames``: the latest views it reads, if not
        ``frame_stack``), built on the CPU (the same initial weights on every device); the networks around it move to
        the device."""
        return self.network.encoder(self.env, bearing, frames)

    def _a2c(self, actor, critic, agent: str, action_agent: str | None = None) -> A2CLoss:
        """An A2C loss on ``agent``'s reward for ``actor`` (whose action lies under ``action_agent``); a look's entropy
        bonus is weighted by the method's ``looker_entropy_coeff``, a move's by A2C's ``entropy_coeff``."""
        a2c, owner = self.a2c, action_agent or agent
        common = dict(
            critic_coeff=a2c.critic_coeff,
            loss_critic_type="l2",
            functional=False,
            reuse_features=a2c.reuse_features,
        )
        if owner == JOINT:  # the move's entropy bonus and the look's apart, as the other methods weigh them
            look = self.options.looker_entropy_coeff
            loss = JointA2CLoss(actor, critic, entropy_coeff=a2c.entropy_coeff, look_entropy_coeff=look, **common)
        else:
            coeff = self.options.looker_entropy_coeff if owner == LOOKER else a2c.entropy_coeff
            loss = SharedEncoderA2CLoss(actor, critic, entropy_coeff=coeff, **common)
        loss.set_keys(
            reward=(agent, "reward"),
            action=(owner, "action"),
            sample_log_prob=(owner, "action_log_prob"),
            value="state_value",
        )
        loss.make_value_estimator(ValueEstimators.GAE, gamma=a2c.gamma, lmbda=a2c.gae_lambda)
        return loss

    def _actor_critic(
        self,
        name: str,
        agent: str,
        lr: float,
        action_agent: str | None = None,
        num_actions: int = NUM_ACTIONS,
    ):
        """An actor and a critic on ``agent``'s view sharing one encoder, their A2C loss, and optimizer ``name``.

        The networks are registered as ``{name}_actor`` and ``{name}_critic``; the actor's action lies
        under ``action_agent`` (default: ``agent``).
        """
        encoder = self._encoder(bearing=agent == MOVER)
        hidden = self.network.hidden_size
        actor = make_actor(encoder, hidden, action_agent or agent, num_actions, reads=agent)
        critic = make_critic(encoder, hidden, agent)
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
        num_envs: int | None = None,
    ) -> Rollouts:
        """Rollouts ``[num_envs, rollout_length]`` of ``policy`` (and ``looker`` in the loop), collected in this process
        or by ``collect_workers`` workers (``name``: what their error messages call them), in the configured room
        with the options in ``room`` changed (``num_envs``: rooms, if not the run's)."""
        run = self.run
        num_envs = num_envs or run.num_envs
        # the workers' torch streams: from the run's seed (or the resumed run's env_seed) and the collector's index
        entropy = [self.env_seed, len(self.collectors)]
        collector = Rollouts(
            policy,
            looker,
            dataclasses.replace(self.env, **(room or {})),
            num_envs,
            run.rollout_length,
            env_seed=self.env_seed + seed_offset,
            torch_seed=int(np.random.SeedSequence(entropy).generate_state(1)[0]),
            workers=run.collect_workers,
            collector=run.collector,
            backend=run.backend,
            ray_address=run.ray_address,
            device=self.device,
            name=name,
            look_views=look_views,
            frame_stack=stacked_views(self.network, self.options),
        )
        self.collectors.append(collector)
        return collector

    def _next(self, collector: Rollouts) -> TensorDictBase:
        """The next rollout of ``collector``, shape ``[num_envs, rollout_length]`` (every method draws its rollouts
        here, which ``benchmarks/train_speed.py`` times)."""
        return next(collector)

    def _optimizer(self, name: str, modules: list[nn.Module], lr: float, kind: str = "adam") -> None:
        self.learning_rates[name] = lr
        params = list(dict.fromkeys(p for m in modules for p in m.parameters()))
        if kind == "sgd":
            self.optimizers[name] = torch.optim.SGD(params, lr=lr)
        else:
            # portable: torch's fused step, whose square root rounds alike on every CPU (the unfused step's is MKL's)
            fused = True if self.run.portable else None
            self.optimizers[name] = torch.optim.Adam(params, lr=lr, eps=1e-5, fused=fused)

    def _step(self, name: str, loss: nn.Module, *inputs: TensorDictBase) -> dict[str, float]:
        """One step of optimizer ``name`` on the sum of the ``loss_*`` entries of ``loss(*inputs)``.

        Returns the loss's scalar entries as floats. The loss and its gradients run on ``learner_threads``
        CPU threads (the environments wait meanwhile).
        """
        with torch_threads(self.run.learner_threads or usable_cpus()):
            losses = loss(*inputs)
            total = sum(v for k, v in losses.items() if k.startswith("loss_"))
            optimizer = self.optimizers[name]
            optimizer.zero_grad(set_to_none=True)
            total.backward()
            params = [p for group in optimizer.param_groups for p in group["params"]]
            torch.nn.utils.clip_grad_norm_(params, self.a2c.max_grad_norm)
            optimizer.step()
        return {f"{name}/{k}": float(v.detach()) for k, v in losses.items() if v.numel() == 1}

    def schedule_learning_rates(self, frames: int) -> None:
        """Set every optimizer's learning rate for an iteration that starts after ``frames`` of the run's frames, as
        A2C's ``lr_schedule`` says."""
        if self.a2c.lr_schedule == "linear":
            scale = max(0.0, 1.0 - frames / self.run.frames)
            for name, optimizer in self.optimizers.items():
                for group in optimizer.param_groups:
                    group["lr"] = self.learning_rates[name] * scale

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

    def state_dict(self) -> dict:
        """Networks, optimizers and the method's own counters."""
        return {
            "modules": {k: m.state_dict() for k, m in self.modules.items()},
            "optimizers": {k: o.state_dict() for k, o in self.optimizers.items()},
        }

    def load_state_dict(self, state: dict) -> None:
        """Restore the networks and optimizers of :meth:`state_dict`; ``ValueError`` naming the first that does not
        fit (:func:`activeperc_rl.runtime.checkpoint.restore_method` checks the rest)."""
        parts = [(k, m, state["modules"]) for k, m in self.modules.items()]
        parts += [(k, o, state["optimizers"]) for k, o in self.optimizers.items()]
        for k, part, saved in parts:
            try:
                part.load_state_dict(saved[k])
            except (RuntimeError, ValueError, KeyError) as error:  # shapes or parameter groups of other networks
                lines = [line.strip() for line in str(error).splitlines() if line.strip()]
                raise ValueError(f"its {k!r} does not fit the config: {' '.join(lines[:2])}") from error

    def non_finite(self) -> str | None:
        """The name of the first network with a weight that is NaN or infinite (the learning diverged), or ``None``."""
        for name, module in self.modules.items():
            if not all(torch.isfinite(p).all() for p in module.parameters()):
                return name
        return None

    def close(self) -> None:
        """Shut the collectors and their environments down."""
        for collector in self.collectors:
            collector.shutdown()
        self.collectors.clear()


@contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Run torch's CPU ops on ``count`` threads inside the block, then restore the previous count."""
    previous = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
