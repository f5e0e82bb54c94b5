"""The losses of our own: the meta-evaluation loss of the perceptual policy (paper section 3, eq. 2) and the joint
agent's A2C (:class:`JointA2CLoss`).

The meta-evaluator
------------------
Two copies of the environment run the same mover ``pi_theta^m``: E1 with the perceptual policy
``pi_phi1^c`` and critic ``V_w1`` (rollouts ``D1``), E2 with the epsilon-greedy perceptual policy
``pi_phi2^c`` and critic ``V_w2`` (rollouts ``D2``). The meta-evaluator of a trajectory ``tau_k``
of ``D2`` is (eq. 2)::

    M(tau_k) = mean_{t in tau_k} V_w2(s_t)  -  (1/K) sum_{tau in D1} mean_{t in tau} V_w1(s_t)

where ``K`` is the number of trajectories of ``D1``. The second term, the *baseline*, is the mean
over ``D1``'s trajectories of each trajectory's mean value: every trajectory weighs the same
whatever its length (it is not the mean over all steps of ``D1``). ``M(tau_k) > 0`` says the mover
expects more reward with ``pi_phi2`` than with ``pi_phi1``.

``pi_phi2`` is trained by REINFORCE with ``M`` in place of the return: every look ``u^c_t`` of
``tau_k``, taken on the looker's state ``s_bar_t``, is credited with its trajectory's ``M``::

    loss_looker = - sum_k sum_{t in tau_k} log pi_phi2(u^c_t | s_bar_t) * M(tau_k)

divided by the number of steps with ``reduction="mean"``. ``M`` is a constant for this loss: the
critics are evaluated without gradients. The log-probabilities are those of ``pi_phi2`` itself,
also at the steps where the epsilon-greedy behaviour took a random look, as in the paper.

Because the looks are drawn from the epsilon-greedy behaviour ``b`` and not from ``pi_phi2``, this
gradient is biased: where ``M`` does not depend on the looks, its expectation on ``phi2``'s logits is
``mean(M) * (b - pi_phi2)``, not 0, so a negative mean ``M`` pushes down every look ``b`` takes more
often than ``pi_phi2`` would. With ``behaviour_epsilon=epsilon`` each term is weighted by the
importance ratio ``rho_t = pi_phi2(u^c_t | s_bar_t) / b(u^c_t | s_bar_t)`` (detached, per step), with
``b = (1 - epsilon) [u^c_t = argmax pi_phi2] + epsilon / |U^c|``, which removes that bias (the paper
does not weight)::

    loss_looker = - sum_k sum_{t in tau_k} rho_t log pi_phi2(u^c_t | s_bar_t) * M(tau_k)

Credit per look
---------------
With ``credit="look"`` each look is credited with the value difference it made instead of its trajectory's
``M``. The looker acts where no time passes: ``s_bar_t`` (the view after the move) is what the mover would
have seen had the camera held, ``s'_t`` what it sees after the look, in the same state of the room. So the
mover's critic values both, and::

    M_t = V_w2(s'_t) - V_w2(s_bar_t)

is 0 for 'hold' and, for a pan, the value the mover expects to gain from the new view: the advantage of the
look over holding, one per look rather than one scalar per trajectory. Looks made after the move that ended an
episode change nothing and get no term. The loss is the REINFORCE loss above with ``M_t`` in place of
``M(tau_k)`` (importance-weighted the same way with ``behaviour_epsilon``); ``D1`` then only supplies the
reported ``baseline``.

With ``credit="look_return"`` each look is credited past its own cycle: with the value it added and then the mover's
advantage at the next move, ``A_{t+1}`` (GAE over the following moves, the looks among them, as the mover's A2C
estimates it on ``D2``, read at the ``advantage`` key)::

    M_t = V_w2(s'_t) - V_w2(s_bar_t) + A_{t+1}  =  G^lambda(s'_t) - V_w2(s_bar_t)

the lambda-return from the view after the look against the value of the view before it: a look that pays only
cycles later (a pan on the way to a goal that is not yet in view) gets its due. ``A_{t+1}`` is 0 where step
``t + 1`` lies outside the rollout or is padding.

With ``credit="every_look"`` the critic values the view of every look ``u`` in each cycle, ``Q_t(u) =
V_w2(s'_t(u))`` (the views recorded under ``("looker", "look_views")``, :func:`~activeperc_rl.envs.make_env`'s
``look_views``), and ``pi_phi2`` follows the expected gradient of ``sum_u pi_phi2(u | s_bar_t) Q_t(u)`` instead of
one sampled look's::

    loss_looker = - sum_t sum_u pi_phi2(u | s_bar_t) (Q_t(u) - sum_u' pi_phi2(u' | s_bar_t) Q_t(u'))

(the baseline inside the bracket is held constant). No look is drawn for the update, so no importance weight
is needed; ``M_t`` is reported as ``sum_u pi_phi2(u) Q_t(u) - Q_t('hold')``, what the looker's policy adds over
holding by the critic's account.

With ``credit="best_look"`` the same values train ``pi_phi2`` as a classifier of the best look: cross-entropy
toward ``argmax_u Q_t(u)`` ('hold' where no pan's view is valued above holding)::

    loss_looker = - sum_t log pi_phi2(argmax_u Q_t(u) | s_bar_t)

Unlike the policy gradient, whose step on a look shrinks with that look's probability, it moves a look that
``pi_phi2`` deems unlikely as fast as a likely one; ``pi_phi2`` learns how often each look is the best from what
the looker sees, so where the views do not tell, its looks spread over the ones that are best there.

Trajectories
------------
The rollouts are tensordicts of batch shape ``[B, T]`` (``B`` rooms, time last; any leading batch
dimensions are flattened into ``B``), of fixed length ``T``, as a ``Collector`` or ``env.rollout``
gives them. A trajectory is a maximal run of steps of one room that no episode end interrupts: one
starts at ``t = 0`` and after every step whose ``("next", "done")`` is set. So a trajectory is an
episode, or the part of it that falls inside this rollout when the episode began before ``t = 0``
or goes on after ``t = T - 1`` (cut at the batch edges). Steps masked out by
``("collector", "mask")`` (padding) belong to no trajectory, and a trajectory made only of masked
steps is not counted.

The keys (docs/training.md, "The TorchRL env"): the critics read the mover's observation ``s_t`` at the
root of each step; the looker's record of cycle ``t`` (``s_bar_t`` under
``("looker", "observation")`` and ``u^c_t`` at ``("looker", "action")``) is read under
``"next"``. All of them can be renamed with :meth:`MetaEvaluationLoss.set_keys`.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule
from tensordict.utils import NestedKey
from torchrl.objectives import A2CLoss
from torchrl.objectives.common import LossModule
from torchrl.objectives.value import GAE

from activeperc_env.core import HOLD, LOOKER_ACTIONS

__all__ = [
    "LOOKER_CREDITS", "VIEW_CREDITS", "MetaEvaluationLoss", "best_looks", "mirror", "trajectory_ids", "view_values",
    "trajectory_means",
]  # fmt: skip

LOOKER_CREDITS = ("trajectory", "look", "look_return", "every_look", "best_look")
"""What :class:`MetaEvaluationLoss` credits each look with (its ``credit``)."""
VIEW_CREDITS = ("every_look", "best_look")
"""The credits that value the view of every look: D2 must record them (``make_env(look_views=True)``)."""
BEST_LOOK_SHARES = ("best_look_agreement", "best_look_left", "best_look_right")
"""The shares of D2's cycles in which phi2's argmax is the critic's best look, and in which that is a pan left or
right (logged with the credits that value every look)."""

_REDUCTIONS = ("mean", "sum")


MIRRORS = {"image": lambda x: x.flip(-2), "pan": torch.neg, "range": lambda x: x.flip(-1)}
"""How each observation the critics read is seen in a mirror: the image flipped left to right (its width is the
second-last axis), the pan negated, the range rays (right to left, symmetric about the heading) reversed."""


def mirror(td: TensorDictBase) -> TensorDictBase:
    """A copy of the observations ``td`` as seen in a mirror (:data:`MIRRORS`, by each key's last name); ``KeyError``
    for an observation without a mirror image."""
    mirrored = td.clone(False)
    for key in td.keys(include_nested=True, leaves_only=True):
        name = key[-1] if isinstance(key, tuple) else key
        mirrored.set(key, MIRRORS[name](td.get(key)))
    return mirrored


def best_looks(values: torch.Tensor, margin: float = 0.0) -> torch.Tensor:
    """The ``best_look`` label of each cycle from the critic's values of its looks' views ``(cycles, looks)``: the look
    valued most, 'hold' unless a pan's view is valued above holding's by more than ``margin``."""
    return torch.where(values.max(-1).values > values[:, HOLD] + margin, values.argmax(-1), HOLD)


def view_values(
    critic, steps: TensorDictBase, views: TensorDictBase, group: str, value_key="state_value", mirrored: bool = False
) -> torch.Tensor:
    """``(steps, looks)``: ``critic``'s value (at ``value_key``) of every look's view ``views`` (``image`` and ``pan``,
    ``(steps, looks, ...)``) of each step, with the ``group``'s other observations, without gradient (``mirrored``:
    the mean of its values of the view and of the view's mirror image)."""
    values = []
    for look in range(views.get("pan").shape[-2]):
        td = steps.select(*critic.in_keys, strict=False).clone(False)
        for key in critic.in_keys:  # ("mover", "observation", k): the look's view, the looker's range
            name = key[-1]
            td.set(key, views.get(name)[:, look] if name in views.keys() else steps.get((group, *key[1:])))
        with torch.no_grad():
            value = critic(td).get(value_key).reshape(-1)
            if mirrored:
                value = (value + critic(mirror(td.select(*critic.in_keys))).get(value_key).reshape(-1)) / 2
        values.append(value)
    return torch.stack(values, -1).detach()


def trajectory_ids(done: torch.Tensor, mask: torch.Tensor | None = None) -> tuple[torch.Tensor, int]:
    """Number the trajectories of a ``[B, T]`` rollout.

    A trajectory starts at ``t = 0`` of each row and at every step that follows a step with
    ``done`` set; masked-out steps belong to no trajectory (see the module docstring).

    Args:
        done: bool tensor of shape ``[B, T]`` or ``[B, T, 1]``: the episode ended at this step. A one-room rollout
            of batch shape ``[T]`` has a ``done`` of shape ``[T, 1]``, which reads as ``T`` rows of one step: pass
            ``done.reshape(1, -1)`` (:class:`MetaEvaluationLoss` does so for its tensordicts).
        mask: optional bool tensor of shape ``[B, T]`` or ``[B, T, 1]``; ``False`` marks a
            padded step, which is ignored.

    Returns:
        ``(ids, n)``: a long tensor of shape ``[B, T]`` holding, for every valid step, the id of
        its trajectory in ``0 .. n - 1`` (``-1`` at masked steps), and ``n``, the number of
        trajectories with at least one valid step. Every id in ``0 .. n - 1`` is used.
    """
    done = _as_2d(done, "done").bool()
    if done.numel() == 0:
        return torch.full(done.shape, -1, dtype=torch.long, device=done.device), 0
    starts = torch.zeros_like(done)
    starts[:, 0] = True
    starts[:, 1:] = done[:, :-1]
    # Flattened row-major, each row begins with a start, so rows never share a trajectory.
    raw = starts.reshape(-1).long().cumsum(0).reshape(done.shape) - 1
    if mask is None:
        return raw, int(raw[-1, -1].item()) + 1
    valid = _as_2d(mask, "mask").bool()
    if valid.shape != done.shape:
        raise ValueError(f"mask of shape {tuple(valid.shape)} does not match done of shape {tuple(done.shape)}.")
    ids = torch.full_like(raw, -1)
    used, inverse = torch.unique(raw[valid], return_inverse=True)
    ids[valid] = inverse
    return ids, used.numel()


def trajectory_means(values: torch.Tensor, ids: torch.Tensor, n: int) -> torch.Tensor:
    """Mean of ``values`` over the valid steps of each trajectory.

    Args:
        values: per-step values, of the shape of ``ids`` or with one more trailing dimension of
            size 1 (e.g. a critic's ``[B, T, 1]`` output).
        ids: trajectory id of every step, ``-1`` for steps to ignore (as :func:`trajectory_ids`
            returns them).
        n: the number of trajectories.

    Returns:
        A tensor of shape ``[n]``: entry ``k`` is the mean of ``values`` over the steps whose id is
        ``k`` (differentiable with respect to ``values``).
    """
    if values.shape != ids.shape:
        if values.shape[:-1] == ids.shape and values.shape[-1] == 1:
            values = values.squeeze(-1)
        else:
            raise ValueError(f"values of shape {tuple(values.shape)} do not match ids of shape {tuple(ids.shape)}.")
    valid = ids >= 0
    index = ids[valid]
    dtype = values.dtype if values.is_floating_point() else torch.get_default_dtype()
    sums = torch.zeros(n, dtype=dtype, device=values.device).index_add(0, index, values[valid].to(dtype))
    counts = torch.zeros(n, dtype=dtype, device=values.device).index_add(0, index, torch.ones_like(index, dtype=dtype))
    return sums / counts


def _as_2d(tensor: torch.Tensor, name: str) -> torch.Tensor:
    if tensor.ndim == 3 and tensor.shape[-1] == 1:
        tensor = tensor.squeeze(-1)
    if tensor.ndim != 2:
        raise ValueError(f"{name} must have shape [B, T] or [B, T, 1], got {tuple(tensor.shape)}.")
    return tensor


def _flags(value: torch.Tensor, shape: torch.Size, name: str, key: NestedKey) -> torch.Tensor:
    """The bool entry ``key`` of ``name`` (a done flag or a mask) reshaped to ``shape``; ``ValueError`` when it is not
    bool (a float 0.3 would read as True) or holds another number of steps."""
    if value.dtype != torch.bool:
        raise ValueError(f"{name}'s {key!r} must be bool, got {value.dtype}.")
    if value.numel() != shape.numel():
        raise ValueError(f"{name}'s {key!r} of shape {tuple(value.shape)} does not fit its batch shape {tuple(shape)}.")
    return value.reshape(shape)


def _join(prefix: NestedKey, key: NestedKey) -> tuple[str, ...]:
    prefix = ((prefix,) if prefix else ()) if isinstance(prefix, str) else tuple(prefix)
    key = (key,) if isinstance(key, str) else tuple(key)
    return prefix + key


class MetaEvaluationLoss(LossModule):
    """REINFORCE loss of the perceptual policy ``pi_phi2`` with the meta-evaluator as return.

    See the module docstring for the formula and the trajectory definition.

    Args:
        looker_actor: ``pi_phi2``, a :class:`~tensordict.nn.ProbabilisticTensorDictSequential`
            (e.g. a :class:`~torchrl.modules.ProbabilisticActor`) whose ``get_dist`` gives a
            ``Categorical`` over the looks, reading keys under ``"looker"`` (e.g.
            ``("looker", "observation", "image")``). It gets the gradients of this loss.
        critic: ``V_w2``, a :class:`~tensordict.nn.TensorDictModule` reading the mover's
            observation at the root and writing ``"state_value"`` of shape ``[..., 1]``;
            evaluated on ``D2`` without gradients.
        reference_critic: ``V_w1``, the same for ``D1`` (may be the same module as ``critic``).
        entropy_coeff: weight of the entropy bonus ``loss_entropy``; ``0`` leaves it out.
        behaviour_epsilon: ``None`` (the paper): no importance weights. A probability ``epsilon``: the looks of
            ``D2`` were drawn epsilon-greedily from ``pi_phi2`` (argmax with probability ``1 - epsilon``, else
            uniform), and each term is weighted by ``pi_phi2 / b`` of its look (see the module docstring);
            ``pi_phi2``'s parameters must be those that drew ``D2``.
        reduction: ``"mean"`` divides the sums over steps by the number of valid steps of ``D2``,
            ``"sum"`` does not.
        credit: ``"trajectory"`` (the paper): each look gets its trajectory's ``M(tau_k)``; ``"look"``: each look
            gets ``M_t = V_w2(s'_t) - V_w2(s_bar_t)``; ``"look_return"``: that plus the mover's advantage at the next
            move (``D2`` must hold it at the ``advantage`` key); ``"every_look"`` and ``"best_look"``: every look of
            each cycle is valued (see the module docstring).
        mirrored: with ``"every_look"`` and ``"best_look"``, value each look's view as the mean of the critic's
            value of it and of its mirror image (flipped left to right, pan negated, range rays reversed): what the
            look is worth to a mover as able on either side.
        margin: with ``"best_look"``, a pan is the label only where its view is valued above holding's by more than
            this.

    Calling the loss as ``loss(D2, D1)`` returns a tensordict with ``loss_looker``, ``loss_entropy``
    (unless ``entropy_coeff == 0``) and, detached: ``entropy`` (mean over steps), ``importance_weight`` (mean
    of ``rho`` over steps; 1 without ``behaviour_epsilon``), ``meta_value`` and ``meta_value_std``
    (mean and standard deviation of ``M`` over the trajectories of ``D2``), ``baseline``, ``num_trajectories`` (the
    trajectories of ``D2``), ``num_reference_trajectories`` (``K``, those of ``D1``) and, where ``credit`` values
    every look, the shares of :data:`BEST_LOOK_SHARES`.

    The three modules are held as they are (not functionalised): ``loss.looker_actor`` is
    ``looker_actor`` itself, and an optimizer over ``looker_actor.parameters()`` trains it.
    """

    @dataclass
    class _AcceptedKeys:
        """Tensordict keys of the loss, settable with ``set_keys(name=key)``.

        Attributes:
            value (NestedKey): where both critics write the state value. Defaults to ``"state_value"``.
            done (NestedKey): end of an episode at this step, in both ``D1`` and ``D2``.
                Defaults to ``("next", "done")``.
            mask (NestedKey): validity of each step (``False`` = padding); absent = all valid.
                Defaults to ``("collector", "mask")``.
            looker_record (NestedKey): the sub-tensordict of ``D2`` holding the looker's record of
                each cycle (the looker actor's in_keys and its action); ``()`` for the root.
                Defaults to ``"next"``.
            looker_action (NestedKey): the look ``u^c_t``, relative to ``looker_record``.
                Defaults to ``("looker", "action")``.
            advantage (NestedKey): the mover's advantage of each step of ``D2`` (``credit="look_return"`` only).
                Defaults to ``"advantage"``.
        """

        value: NestedKey = "state_value"
        done: NestedKey = ("next", "done")
        mask: NestedKey = ("collector", "mask")
        looker_record: NestedKey = "next"
        looker_action: NestedKey = ("looker", "action")
        advantage: NestedKey = "advantage"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    _schedulable_buffers = frozenset({"entropy_coeff"})

    looker_actor: ProbabilisticTensorDictSequential
    critic: TensorDictModule
    reference_critic: TensorDictModule

    def __init__(
        self,
        looker_actor: ProbabilisticTensorDictSequential,
        critic: TensorDictModule,
        reference_critic: TensorDictModule,
        *,
        entropy_coeff: float = 0.01,
        behaviour_epsilon: float | None = None,
        reduction: str = "mean",
        credit: str = "trajectory",
        mirrored: bool = False,
        margin: float = 0.0,
    ):
        if reduction not in _REDUCTIONS:
            raise ValueError(f"reduction must be one of {_REDUCTIONS}, got {reduction!r}.")
        if credit not in LOOKER_CREDITS:
            raise ValueError(f"credit must be one of {LOOKER_CREDITS}, got {credit!r}.")
        if behaviour_epsilon is not None and not (
            isinstance(behaviour_epsilon, numbers.Real)
            and not isinstance(behaviour_epsilon, bool)
            and 0 <= behaviour_epsilon <= 1
        ):
            raise ValueError(f"behaviour_epsilon must be None or a probability in [0, 1], got {behaviour_epsilon!r}.")
        if not (isinstance(margin, numbers.Real) and not isinstance(margin, bool) and 0 <= margin < math.inf):
            raise ValueError(f"margin must be a finite number >= 0, got {margin!r}.")
        number = isinstance(entropy_coeff, numbers.Real) and not isinstance(entropy_coeff, bool)
        if not (number and math.isfinite(entropy_coeff) and entropy_coeff >= 0):
            raise ValueError(f"entropy_coeff must be a finite number >= 0, got {entropy_coeff!r}.")
        if not hasattr(looker_actor, "get_dist"):
            raise TypeError(
                "looker_actor must be a ProbabilisticTensorDictSequential (e.g. a ProbabilisticActor) "
                f"with a get_dist method, got {type(looker_actor).__name__}."
            )
        super().__init__()
        self.looker_actor = looker_actor
        self.critic = critic
        self.reference_critic = reference_critic
        self.reduction = reduction
        self.credit = credit
        self.mirrored = bool(mirrored)
        self.margin = float(margin)
        self.behaviour_epsilon = None if behaviour_epsilon is None else float(behaviour_epsilon)
        self.register_coeff_buffer("entropy_coeff", float(entropy_coeff))
        self._entropy_bonus = float(entropy_coeff) != 0.0
        self._kept: dict[str, torch.Tensor] | None = None  # within same_rollouts(): the critics' values

    @property
    def functional(self) -> bool:
        """``False``: the modules are used as given, with their own parameters."""
        return False

    @contextmanager
    def same_rollouts(self) -> Iterator[None]:
        """Within the block every call is on the same D2 and D1 with the same critics: their values (the baseline,
        the credits) are computed once, and only ``pi_phi2``'s pass is taken again (several steps on one D2)."""
        self._kept = {}
        try:
            yield
        finally:
            self._kept = None

    def _held(self, name: str, compute: Callable[[], torch.Tensor]) -> torch.Tensor:
        """``compute()``, or within :meth:`same_rollouts` what it gave the first time."""
        if self._kept is None:
            return compute()
        if name not in self._kept:
            self._kept[name] = compute()
        return self._kept[name]

    @property
    def in_keys(self) -> list[NestedKey]:
        """Keys read from ``D2`` (``D1`` is read at the same done, mask and critic keys). The mask is optional, as
        rollouts without padding lack it: select with ``td.select(*loss.in_keys, strict=False)``."""
        keys = self.tensor_keys
        record = keys.looker_record
        in_keys = [keys.done, keys.mask, _join(record, keys.looker_action)]
        in_keys += [_join(record, key) for key in self.looker_actor.in_keys]
        in_keys += list(self.critic.in_keys) + list(self.reference_critic.in_keys)
        if self.credit == "look_return":
            in_keys.append(keys.advantage)
        return list(dict.fromkeys(in_keys))

    @property
    def out_keys(self) -> list[str]:
        """Keys of the output tensordict."""
        out = ["loss_looker"]
        if self._entropy_bonus:
            out.append("loss_entropy")
        return [
            *out,
            "entropy",
            "importance_weight",
            "meta_value",
            "meta_value_std",
            "baseline",
            "num_trajectories",
            "num_reference_trajectories",
        ]

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        # No value estimator: the keys are read directly from tensor_keys.
        pass

    def make_value_estimator(self, value_type=None, **hyperparams):
        """Not available: the meta-evaluator reads the critics' values of the states themselves (eq. 2), no return
        or advantage is estimated."""
        raise NotImplementedError(
            "MetaEvaluationLoss has no value estimator: it averages the critics' values over each trajectory (eq. 2)"
        )

    def _steps(self, tensordict: TensorDictBase, name: str) -> tuple[TensorDictBase, torch.Tensor, torch.Tensor, int]:
        """Flatten ``tensordict`` to ``[B, T]`` and number its trajectories.

        Returns the flattened tensordict, the validity mask ``[B, T]``, the trajectory ids and
        their count.
        """
        if tensordict.batch_dims < 1:
            raise ValueError(f"{name} must have a time dimension (batch shape [B, T]), got {tensordict.batch_size}.")
        if tensordict.batch_size.numel() == 0:  # (TensorDict.numel() is 1 for an empty batch)
            raise ValueError(f"{name} has no steps (batch shape {tuple(tensordict.batch_size)}).")
        if tensordict.batch_dims == 1:
            tensordict = tensordict.unsqueeze(0)
        elif tensordict.batch_dims > 2:
            tensordict = tensordict.reshape(-1, tensordict.batch_size[-1])
        shape = tensordict.batch_size
        keys = self.tensor_keys
        done = tensordict.get(keys.done, None)
        if done is None:
            raise ValueError(f"{name} has no done entry {keys.done!r}.")
        done = _flags(done, shape, name, keys.done)
        mask = tensordict.get(keys.mask, None)
        if mask is None:
            mask = torch.ones(shape, dtype=torch.bool, device=done.device)
        else:
            mask = _flags(mask, shape, name, keys.mask)
        ids, n = trajectory_ids(done, mask)
        if n == 0:
            raise ValueError(f"{name} has no valid step: every step is masked out by {keys.mask!r}.")
        return tensordict, mask, ids, n

    def _trajectory_values(
        self, critic: TensorDictModule, tensordict: TensorDictBase, mask: torch.Tensor, ids: torch.Tensor, n: int
    ) -> torch.Tensor:
        """Mean critic value of each trajectory, computed on the valid steps only, without gradient."""
        steps = tensordict.select(*critic.in_keys, strict=False)[mask]
        with torch.no_grad():
            value = critic(steps).get(self.tensor_keys.value)
        return trajectory_means(value.reshape(-1).detach(), ids[mask], n)

    def forward(self, tensordict: TensorDictBase, reference: TensorDictBase) -> TensorDictBase:
        """Compute the loss of ``pi_phi2`` on ``D2`` (``tensordict``) against the baseline of ``D1`` (``reference``).

        Args:
            tensordict: ``D2``, the rollout of E2, batch shape ``[B, T]``.
            reference: ``D1``, the rollout of E1, batch shape ``[B', T']``.

        Returns:
            A tensordict with empty batch size; see the class docstring for its entries.
        """
        for name, value in (("tensordict (D2)", tensordict), ("reference (D1)", reference)):
            if not isinstance(value, TensorDictBase):
                raise TypeError(f"{name} must be a TensorDict rollout, got {type(value).__name__}.")
        keys = self.tensor_keys
        record_key = keys.looker_record
        action_key = _join(record_key, keys.looker_action)
        if tensordict.get(action_key, None) is None:
            raise ValueError(
                f"D2 (the first argument) has no looker action at {action_key!r}: it must be a rollout "
                "with a looker module in the env (looker mode), or set_keys(looker_record=..., looker_action=...)."
            )

        # Baseline: (1/K) sum over D1's trajectories of mean_t V_w1(s_t).
        reference, ref_mask, ref_ids, num_ref = self._steps(reference, "reference (D1)")
        baseline = self._held(
            "baseline",
            lambda: self._trajectory_values(self.reference_critic, reference, ref_mask, ref_ids, num_ref).mean(),
        )

        tensordict, mask, ids, num = self._steps(tensordict, "tensordict (D2)")
        record = tensordict if record_key in ((), "") else tensordict.get(record_key)
        if self.credit == "trajectory":  # the meta-evaluator of each trajectory of D2, for each of its steps
            values = self._held("meta", lambda: self._trajectory_values(self.critic, tensordict, mask, ids, num))
            meta = (values - baseline).detach()
            step_credit = meta[ids[mask]]
        else:  # a look after the episode's last move counts for nothing
            valid = mask
            done = _flags(tensordict.get(keys.done), tensordict.batch_size, "tensordict (D2)", keys.done)
            mask = mask & ~done
            if not mask.any():
                raise ValueError(
                    "tensordict (D2) has no look that a move followed: every valid step ended its episode."
                )
            if self.credit in VIEW_CREDITS:
                return self._every_look(record, mask, baseline, num, num_ref)
            # each look's own value difference
            step_credit = meta = self._held("look", lambda: self._look_values(record, mask))
            if self.credit == "look_return":
                step_credit = meta = meta + self._held("ahead", lambda: self._advantage_ahead(tensordict, valid, mask))

        # REINFORCE on the valid steps of D2, each weighted by its credit.
        steps = record.select(*self.looker_actor.in_keys, keys.looker_action, strict=False)[mask]
        action = steps.get(keys.looker_action)
        dist = self.looker_actor.get_dist(steps.exclude(keys.looker_action))
        if action.ndim == len(dist.batch_shape) + 1 and action.shape[-1] == 1:
            action = action.squeeze(-1)
        looks = dist.logits.shape[-1]
        if action.is_floating_point() or action.is_complex() or action.shape != dist.batch_shape:
            raise ValueError(
                f"the looks at {action_key!r} must be integer indices, one per step ({tuple(dist.batch_shape)}), "
                f"got {action.dtype} of shape {tuple(action.shape)}."
            )
        if action.numel() and (action.min() < 0 or action.max() >= looks):
            found = action.unique().tolist()
            raise ValueError(f"the looks at {action_key!r} must lie in 0 .. {looks - 1}, got {found}.")
        log_prob = dist.log_prob(action).reshape(-1)
        rho = self._importance_weights(dist.logits, action).reshape(-1)
        weights = step_credit * rho
        loss_looker = -(log_prob * weights).sum()
        entropy = dist.entropy().reshape(-1)
        loss_entropy = -self.entropy_coeff * entropy.sum()
        if self.reduction == "mean":
            loss_looker = loss_looker / log_prob.numel()
            loss_entropy = loss_entropy / log_prob.numel()

        weight = rho.mean() if rho.numel() else None
        return self._output(loss_looker, loss_entropy, entropy, weight, meta, baseline, num, num_ref)

    def _every_look(
        self, record: TensorDictBase, mask: torch.Tensor, baseline: torch.Tensor, num: int, num_ref: int
    ) -> TensorDictBase:
        """The loss with ``credit="every_look"`` or ``"best_look"`` on the valid steps ``mask`` of D2's looker
        ``record``."""
        steps = record[mask]
        group = self._looker_group()
        views = steps.get((group, "look_views"), None)
        if views is None:
            raise ValueError(
                f"credit='every_look' needs the views of every look at {(group, 'look_views')!r}: collect D2 with "
                "make_env(..., look_views=True)"
            )
        value_key = self.tensor_keys.value
        q = self._held("views", lambda: view_values(self.critic, steps, views, group, value_key, self.mirrored))
        dist = self.looker_actor.get_dist(steps.select(*self.looker_actor.in_keys, strict=False))
        probs = dist.probs.reshape(q.shape)
        expected = (probs * q).sum(-1)
        best = best_looks(q, self.margin)
        if self.credit == "best_look":  # cross-entropy toward the best look, 'hold' on a tie
            gain = dist.log_prob(best.reshape(dist.batch_shape)).reshape(-1)
        else:
            gain = (probs * (q - expected.detach()[:, None])).sum(-1)  # its gradient is the policy gradient
        entropy = dist.entropy().reshape(-1)
        loss_looker, loss_entropy = -gain.sum(), -self.entropy_coeff * entropy.sum()
        if self.reduction == "mean":
            loss_looker, loss_entropy = loss_looker / len(q), loss_entropy / len(q)
        meta = (expected - q[:, HOLD]).detach()
        shares = {
            "best_look_agreement": probs.argmax(-1) == best,
            "best_look_left": best == LOOKER_ACTIONS.index("pan_left"),
            "best_look_right": best == LOOKER_ACTIONS.index("pan_right"),
        }
        return self._output(loss_looker, loss_entropy, entropy, None, meta, baseline, num, num_ref, shares)

    def _output(self, loss_looker, loss_entropy, entropy, importance_weight, meta, baseline, num, num_ref, shares=None):
        """The loss's tensordict: the losses, and the diagnostics of the looks (``importance_weight`` ``None``: 1;
        ``shares``: the best-look shares' flags, one per cycle, for the credits that value every look)."""
        dtype, device = meta.dtype, meta.device
        out = TensorDict({"loss_looker": loss_looker}, batch_size=[])
        if self._entropy_bonus:
            out.set("loss_entropy", loss_entropy)
        out.set("entropy", entropy.detach().mean())
        ones = torch.ones((), dtype=dtype, device=device)
        out.set("importance_weight", ones if importance_weight is None else importance_weight)
        out.set("meta_value", meta.mean())
        out.set("meta_value_std", meta.std(correction=0))
        out.set("baseline", baseline.detach())
        out.set("num_trajectories", torch.tensor(float(num), dtype=dtype, device=device))
        out.set("num_reference_trajectories", torch.tensor(float(num_ref), dtype=dtype, device=device))
        for key, share in (shares or {}).items():
            out.set(key, share.to(dtype).mean())
        return out

    def _look_values(self, record: TensorDictBase, mask: torch.Tensor) -> torch.Tensor:
        """``V(s'_t) - V(s_bar_t)`` of each valid step, by :attr:`critic`, without gradient: ``s'_t`` is the mover's
        observation of the looker's record (the view after the look), ``s_bar_t`` the looker's own (before it)."""
        steps = record[mask]
        after = steps.select(*self.critic.in_keys, strict=False)
        before = after.clone(False)
        for key in self.critic.in_keys:  # ("mover", "observation", k) -> the looker's ("looker", "observation", k)
            before.set(key, steps.get((self._looker_group(), *key[1:])))
        with torch.no_grad():
            values = [self.critic(td).get(self.tensor_keys.value).reshape(-1) for td in (after, before)]
        return (values[0] - values[1]).detach()

    def _advantage_ahead(self, tensordict: TensorDictBase, valid: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """The mover's advantage at the step after each step of ``mask`` (0 past the rollout's end or on padding)."""
        key = self.tensor_keys.advantage
        advantage = tensordict.get(key, None)
        if advantage is None:
            raise ValueError(
                f"credit='look_return' needs the mover's advantage of each step of D2 at {key!r} (its A2C loss's "
                "value estimator writes it)"
            )
        advantage = _as_2d(advantage.detach(), "the advantage")
        if advantage.shape != valid.shape:
            raise ValueError(f"the advantage must have D2's shape {tuple(valid.shape)}, got {tuple(advantage.shape)}")
        ahead = torch.zeros_like(advantage)
        ahead[:, :-1] = torch.where(valid[:, 1:], advantage[:, 1:], 0.0)
        return ahead[mask]

    def _looker_group(self) -> str:
        """The group under which the looker's record holds ``s_bar`` (the first entry of its action key)."""
        action = self.tensor_keys.looker_action
        return action[0] if isinstance(action, tuple) else action

    def _importance_weights(self, logits: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """``pi_phi2(u) / b(u)`` of each look, detached; ones without ``behaviour_epsilon``."""
        if self.behaviour_epsilon is None:
            return torch.ones(action.shape, dtype=logits.dtype, device=logits.device)
        with torch.no_grad():
            looks = logits.shape[-1]
            probs = torch.softmax(logits, dim=-1).gather(-1, action.unsqueeze(-1)).squeeze(-1)
            greedy = action == logits.argmax(dim=-1)
            behaviour = (1 - self.behaviour_epsilon) * greedy + self.behaviour_epsilon / looks
            return probs / behaviour


class SharedEncoderA2CLoss(A2CLoss):
    """TorchRL's A2C loss for an actor and a critic that share one encoder, which reads each observation of the
    rollout once per update instead of four times.

    TorchRL's loss runs the encoder for the critic's values of the observations and of the next ones (for GAE,
    without gradients), then for the actor and for the critic (each with its own backward pass). Here the critic's
    values for GAE come from the same forward pass that the actor's and the critic's terms then read (the encoder
    keeps its features within the update, :meth:`Encoder.reusing`), and the next observations' values from one pass
    without gradients: the same loss, with one backward pass through the encoder. With ``reuse_features=False`` it is
    TorchRL's loss as it ships.
    """

    def __init__(self, *args, reuse_features: bool = True, **kwargs):
        super().__init__(*args, **kwargs)
        self.reuse_features = reuse_features

    def make_value_estimator(self, value_type=None, **hyperparams):
        """TorchRL's estimator (kept for ``value_estimator``), and the same GAE on values given to it."""
        super().make_value_estimator(value_type, **hyperparams)
        self.given_values_gae = GAE(value_network=None, **hyperparams)
        self.given_values_gae.set_keys(
            **{key: getattr(self.tensor_keys, key) for key in ("advantage", "value_target", "value", "reward")},
            done=self.tensor_keys.done,
            terminated=self.tensor_keys.terminated,
        )
        return self

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """The A2C losses of ``tensordict`` (a rollout ``[B, T]``), the encoder run once on its observations."""
        if not self.reuse_features:
            return super().forward(tensordict)
        encoder = self.critic_network.module.encoder
        with encoder.reusing():
            tensordict = tensordict.clone(False)
            if self.tensor_keys.advantage not in tensordict.keys(True):
                value_key = self.tensor_keys.value
                value = self.critic_network(tensordict).get(value_key)
                with torch.no_grad():
                    next_value = self.critic_network(tensordict.get("next").copy()).get(value_key)
                tensordict.set(value_key, value.detach())
                tensordict.set(("next", value_key), next_value)
                self.given_values_gae(tensordict)
            return super().forward(tensordict)


class JointA2CLoss(SharedEncoderA2CLoss):
    """TorchRL's A2C for the joint agent (``a = 3 u_m + u_c``), whose entropy bonus weighs the move and the look
    apart: ``entropy_coeff * H(u_m) + look_entropy_coeff * H(u_c | u_m)`` (the two add up to the joint entropy).

    The logged ``entropy`` is the bonus divided by the larger coefficient: with ``look_entropy_coeff`` 0, the move's
    entropy ``H(u_m)``.
    """

    def __init__(self, *args, entropy_coeff: float, look_entropy_coeff: float, **kwargs):
        scale = max(entropy_coeff, look_entropy_coeff)
        super().__init__(*args, entropy_coeff=scale, entropy_bonus=scale > 0, **kwargs)
        self.move_weight = entropy_coeff / scale if scale else 0.0
        self.look_weight = look_entropy_coeff / scale if scale else 0.0

    def get_entropy_bonus(self, dist: torch.distributions.Categorical) -> torch.Tensor:
        """``move_weight * H(u_m) + look_weight * H(u_c | u_m)`` of ``dist`` over the 9 joint actions."""
        moves_by_looks = dist.logits.unflatten(-1, (3, 3))
        move = torch.distributions.Categorical(logits=moves_by_looks.logsumexp(-1)).entropy()
        look_given_move = dist.entropy() - move
        return (self.move_weight * move + self.look_weight * look_given_move).unsqueeze(-1)
