"""The networks: a CNN encoder of (image, pan) and the actors and critics built on it.

Every learned policy reads one agent's observation group (``("mover", "observation")`` or
``("looker", "observation")``) and is a TorchRL ``ProbabilisticActor`` over a categorical
distribution, writing ``(agent, "logits")``, ``(agent, "action")`` and
``(agent, "action_log_prob")``. Critics write ``"state_value"``. The mover's actor and critic
share one encoder (as in the usual pixel A2C); the looker's networks have their own.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.modules import ProbabilisticActor

from activeperc_env import EnvConfig
from activeperc_env.config import is_int, with_field_docs
from activeperc_env.core import HOLD, MOVER_ACTIONS
from activeperc_rl.config import Section, int_in
from activeperc_rl.envs import MAX_FRAME_STACK

JOINT = "joint"
NUM_ACTIONS = MOVER_ACTIONS  # the looker has as many (LOOKER_ACTIONS)


@with_field_docs
@dataclass(frozen=True)
class NetworkConfig(Section):
    """The networks every method builds: the encoder's size, the mover's bearing layout and the frames it reads."""

    NAME = "network"

    channels: tuple[int, ...] = (16, 32)
    """Output channels of the encoder's conv layers (kernels 8, 4, 3, ... with strides 4, 2, 1, ...)."""
    hidden_size: int = 256
    """Width of the encoder's output and of the heads' input."""
    bearing_bins: int = 30
    """Bins of the mover's bearing layout (0: none): its networks (and the joint agent's) lay the view's features
    out by bearing from the robot's heading, wherever the camera looks, so that its critic values a view by what it
    shows whatever the pan."""
    frame_stack: int = 1
    """Views of the latest cycles that every network reads, stacked on the image's channels (1: the current view
    only): a memory of where the goal was (make_env's frame_stack); needs bearing_bins 0."""

    def __post_init__(self) -> None:
        if isinstance(self.channels, (list, tuple)):  # YAML and the flags give lists
            object.__setattr__(self, "channels", tuple(int(c) if is_int(c) else c for c in self.channels))
        super().__post_init__()

    def checks(self) -> dict[str, tuple[bool, str]]:
        """Each field's check."""
        channels_ok = isinstance(self.channels, tuple) and len(self.channels) >= 1
        return {
            "channels": (
                channels_ok and all(int_in(c, 1, 4096) for c in self.channels),
                "one or more ints in 1 .. 4096",
            ),
            "hidden_size": (int_in(self.hidden_size, 1, 2**16), "an int in 1 .. 65536"),
            "bearing_bins": (int_in(self.bearing_bins, 0, 360), "an int in 0 .. 360"),
            "frame_stack": (
                int_in(self.frame_stack, 1, MAX_FRAME_STACK) and (self.frame_stack == 1 or self.bearing_bins == 0),
                f"an int in 1 .. {MAX_FRAME_STACK}, 1 with bearing_bins (which lays out one view: give bearing_bins 0)",
            ),
        }

    def encoder(self, env: EnvConfig, bearing: bool = True, frames: int | None = None) -> Encoder:
        """A fresh :class:`Encoder` of these sizes for ``env``'s observation (``bearing``: with the mover's bearing
        layout; ``frames``: the latest views it reads, if not ``frame_stack``)."""
        layout = self.bearing_bins if bearing else 0
        return make_encoder(env, self.channels, self.hidden_size, layout, frames or self.frame_stack)


def stacked_views(network: NetworkConfig, options: Section) -> int:
    """Views of the latest cycles in each observation of a run: as many as its networks read at most (the
    ``frame_stack`` of all of them, a method's ``looker_frames`` of its looker's)."""
    return max(network.frame_stack, getattr(options, "looker_frames", 1))


class Encoder(nn.Module):
    """Conv stack over the uint8 image, concatenated with (sin, cos) of the pan and the range readings scaled to
    [0, 1] (where the room has a range sensor), then a linear layer.

    With ``frames`` > 1 it reads a frame stack (``make_env(frame_stack=frames)``): the views of the latest cycles on
    the image's channels, ``(*batch, H, W, 3 * frames)``, their pans ``(*batch, frames)``, and convolves them together.
    Given a deeper stack it reads its latest ``frames`` views (a mover of one view beside a looker that remembers).

    With ``bearing_bins`` the conv features are first laid out by bearing from the robot's heading instead of by
    column of the view: ``bearing_bins`` bins span every bearing the camera can see, and each bin takes the
    features of the view's column that looks that way (the pan plus the column's angle from the camera's axis),
    zero where the camera does not look. A goal seen 40 degrees to the left then lands in the same features
    whether the camera looks ahead or 30 degrees left (:class:`BearingLayout`).

    It reads the images as the env gives them, of shape ``(*batch, height, width, 3 * stack)``, ``stack >= frames``,
    with values 0 to 255 (``uint8``, or a float copy of them), and scales them itself; another shape (e.g. the
    ``(3, H, W)`` images of TorchRL's ``ToTensorImage``, which are scaled to [0, 1] too) raises ``ValueError``.

    Args:
        height, width: the image size.
        channels: output channels of the conv layers (kernel 8 stride 4, then 4/2, then 3/1).
        hidden_size: width of the output features.
        range_rays: readings of the range sensor it also reads (0: none).
        range_max: the range sensor's longest reading, which it scales the readings by.
        bearing_bins: bins of the bearing layout (0: the features as the conv stack gives them).
        fov: the camera's horizontal field of view, degrees (read with ``bearing_bins``).
        pan_range: the camera's pan limit, degrees (read with ``bearing_bins``).
        frames: the views stacked in each observation (``bearing_bins`` needs 1: it lays out one view).
    """

    KERNELS = ((8, 4), (4, 2), (3, 1))

    def __init__(
        self,
        height: int,
        width: int,
        channels: tuple[int, ...],
        hidden_size: int,
        range_rays: int = 0,
        range_max: float = 1.0,
        bearing_bins: int = 0,
        fov: float = 60.0,
        pan_range: float = 120.0,
        frames: int = 1,
    ):
        super().__init__()
        if bearing_bins and frames > 1:
            raise ValueError(f"bearing_bins={bearing_bins} lays out one view: it needs frames=1, got {frames}")
        self.image_shape = (height, width, 3 * frames)
        self.frames = frames
        self.range_rays, self.range_max = range_rays, range_max
        layers, in_ch, h, w = [], 3 * frames, height, width
        for i, out_ch in enumerate(channels):
            kernel, stride = self.KERNELS[min(i, len(self.KERNELS) - 1)]
            if h < kernel or w < kernel:
                raise ValueError(f"channels={tuple(channels)} has too many conv layers for a {width}x{height} image")
            layers += [nn.Conv2d(in_ch, out_ch, kernel, stride), nn.ReLU()]
            in_ch, h, w = out_ch, (h - kernel) // stride + 1, (w - kernel) // stride + 1
        self.conv = nn.Sequential(*layers)
        self.layout = BearingLayout(bearing_bins, h, fov, pan_range) if bearing_bins else None
        columns = bearing_bins or w
        self.linear = nn.Sequential(nn.Linear(in_ch * h * columns + 2 * frames + range_rays, hidden_size), nn.ReLU())
        self.kept: list | None = None  # within reusing(): the inputs and features of every pass

    @contextmanager
    def reusing(self) -> Iterator[None]:
        """Within the block, a pass on the very tensors of an earlier one (with gradients enabled alike) returns its
        features: an actor and a critic on one encoder read one pass, and its backward pass is taken once."""
        self.kept = []
        try:
            yield
        finally:
            self.kept = None

    def forward(self, image: torch.Tensor, pan: torch.Tensor, ranges: torch.Tensor | None = None) -> torch.Tensor:
        """Features of shape ``(*batch, hidden_size)`` from ``image (*batch, H, W, 3 * stack)``, ``pan (*batch,
        stack)`` (``stack >= frames``: the latest ``frames`` views are read) and, with a range sensor, ``ranges
        (*batch, range_rays)``."""
        height, width, channels = self.image_shape
        shape = tuple(image.shape[-3:])
        if len(shape) < 3 or shape[:2] != (height, width) or shape[2] < channels or shape[2] % 3:
            raise ValueError(
                f"the encoder reads images of shape (*batch, {height}, {width}, 3 * stack), stack >= {self.frames}, "
                f"with values 0 to 255, as the env gives them (frame_stack >= {self.frames}); got shape "
                f"{tuple(image.shape)} (give the env a frame_stack of the encoder's frames or more, and leave out "
                "transforms that permute or scale the image, such as ToTensorImage)"
            )
        if self.kept is not None:
            key = (image, pan, ranges, torch.is_grad_enabled())
            for seen, features in self.kept:
                if all(a is b for a, b in zip(seen, key, strict=True)):  # the same tensors, and grad mode
                    return features
            features = self._features(image, pan, ranges)
            self.kept.append((key, features))
            return features
        return self._features(image, pan, ranges)

    def _features(self, image: torch.Tensor, pan: torch.Tensor, ranges: torch.Tensor | None) -> torch.Tensor:
        batch = image.shape[:-3]
        if image.shape[-1] > self.image_shape[2]:  # the latest views of a deeper stack
            image, pan = image[..., -self.image_shape[2] :], pan[..., -self.frames :]
        # a fresh float copy (never the caller's tensor), scaled in place: one pass over the images fewer
        x = image.reshape(-1, *image.shape[-3:]).permute(0, 3, 1, 2).to(torch.float32, copy=True).div_(255.0)
        x = self.conv(x)
        pan = pan.reshape(-1, self.frames).to(x.dtype)
        if self.layout is not None:
            x = self.layout(x, pan)
        parts = [x.flatten(1), torch.sin(pan), torch.cos(pan)]
        if self.range_rays:
            parts.append(ranges.reshape(-1, self.range_rays).to(x.dtype) / self.range_max)
        return self.linear(torch.cat(parts, dim=-1)).reshape(*batch, -1)


class BearingLayout(nn.Module):
    """Lays the columns of a view's feature map out by bearing from the robot's heading.

    ``bins`` bins of equal width span the bearings ``-reach .. +reach`` (``reach``: the pan limit plus half the field
    of view, at most 180 degrees). Bin ``j`` at bearing ``b`` takes, by linear interpolation, the features of the
    view's column at angle ``b - pan`` from the camera's axis (a pinhole's ``tan``), and zeros where that angle lies
    outside the field of view. Positive bearings are to the left, as the pan's.

    Args:
        bins: the bins.
        rows: the feature map's rows (each row is laid out alike).
        fov: horizontal field of view, degrees.
        pan_range: the pan limit, degrees.
    """

    def __init__(self, bins: int, rows: int, fov: float, pan_range: float):
        super().__init__()
        reach = min(math.radians(pan_range + fov / 2), math.pi)
        edges = torch.linspace(-reach, reach, bins + 1)
        self.register_buffer("bearings", (edges[:-1] + edges[1:]) / 2, persistent=False)
        self.register_buffer("rows", (2 * torch.arange(rows) + 1) / rows - 1, persistent=False)  # cell centres
        self.half_fov = math.radians(fov) / 2

    def forward(self, features: torch.Tensor, pan: torch.Tensor) -> torch.Tensor:
        """``(n, C, rows, bins)`` from the feature maps ``(n, C, rows, columns)`` and the pans ``(n, 1)``, radians."""
        angle = self.bearings[None, :] - pan  # (n, bins): from the camera's axis, positive to the left
        inside = angle.abs() < self.half_fov
        x = -torch.tan(angle.clamp(-self.half_fov, self.half_fov)) / math.tan(self.half_fov)  # -1: the left edge
        n, rows, bins = features.shape[0], self.rows.numel(), self.bearings.numel()
        grid = torch.stack([x[:, None, :].expand(n, rows, bins), self.rows[None, :, None].expand(n, rows, bins)], -1)
        laid = nn.functional.grid_sample(features, grid.to(features.dtype), align_corners=False)
        return laid * inside[:, None, None, :].to(laid.dtype)


class Head(nn.Module):
    """An encoder followed by a linear layer: ``(image, pan[, ranges]) -> (*batch, out_features)``."""

    def __init__(self, encoder: Encoder, hidden_size: int, out_features: int):
        super().__init__()
        self.encoder = encoder
        self.out = nn.Linear(hidden_size, out_features)

    def forward(self, image: torch.Tensor, pan: torch.Tensor, ranges: torch.Tensor | None = None) -> torch.Tensor:
        """Apply the encoder, then the output layer."""
        return self.out(self.encoder(image, pan, ranges))


class ReadOnlyEncoder(nn.Module):
    """Another network's :class:`Encoder`, read without gradient: a head on it learns from its features and leaves its
    weights alone (they are not this module's parameters, nor in its state dict)."""

    def __init__(self, encoder: Encoder):
        super().__init__()
        self.__dict__["source"] = encoder  # not a submodule
        self.range_rays = encoder.range_rays

    def forward(self, image: torch.Tensor, pan: torch.Tensor, ranges: torch.Tensor | None = None) -> torch.Tensor:
        """The source encoder's features, without gradient."""
        with torch.no_grad():
            return self.source(image, pan, ranges)

    def __deepcopy__(self, memo: dict) -> ReadOnlyEncoder:
        """A copy reads the same encoder."""
        return ReadOnlyEncoder(self.source)


def make_encoder(
    env: EnvConfig, channels: tuple[int, ...], hidden_size: int, bearing_bins: int = 0, frames: int = 1
) -> Encoder:
    """An :class:`Encoder` sized for ``env``'s observation (``bearing_bins``, ``frames``: see :class:`Encoder`)."""
    return Encoder(
        env.height,
        env.width,
        channels,
        hidden_size,
        env.range_rays,
        env.range_max,
        bearing_bins,
        env.fov,
        env.pan_range,
        frames,
    )


def observation_keys(agent: str, encoder: Encoder) -> list[tuple[str, ...]]:
    """The input keys of ``agent``'s networks on ``encoder``: its image, its pan and (with a range sensor) its range."""
    keys = ["image", "pan"] + (["range"] if encoder.range_rays else [])
    return [(agent, "observation", key) for key in keys]


def make_actor(
    encoder: Encoder, hidden_size: int, agent: str, num_actions: int = NUM_ACTIONS, reads: str | None = None
):
    """A categorical ``ProbabilisticActor`` for ``agent`` on the observation of ``reads`` (default: ``agent``)."""
    logits = TensorDictModule(
        Head(encoder, hidden_size, num_actions),
        in_keys=observation_keys(reads or agent, encoder),
        out_keys=[(agent, "logits")],
    )
    return ProbabilisticActor(
        logits,
        in_keys={"logits": (agent, "logits")},
        out_keys=[(agent, "action")],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
        log_prob_key=(agent, "action_log_prob"),
    )


def start_holding(actor, hold_prob: float) -> None:
    """Set ``actor``'s output layer so that, untrained, it picks a look of 'hold' with probability ``hold_prob``.

    The layer's weights become zero and its bias ``log(2 p / (1 - p))`` on the actions whose look is 'hold'
    (action 1 of a looker; actions 1, 4, 7 of the joint agent, ``a = 3 u_m + u_c``), 0 elsewhere: every
    view gets the same start, the moves stay uniform, and ``argmax`` holds. ``hold_prob = 1/3`` is uniform.
    """
    if not (isinstance(hold_prob, (int, float)) and 0 < hold_prob < 1):
        raise ValueError(f"hold_prob={hold_prob!r} is invalid: expected a probability in (0, 1)")
    out = actor[0].module.out
    holds = torch.arange(out.out_features) % NUM_ACTIONS == HOLD
    with torch.no_grad():
        out.weight.zero_()
        out.bias.copy_(holds * math.log(2 * hold_prob / (1 - hold_prob)))


def make_critic(encoder: Encoder, hidden_size: int, agent: str) -> TensorDictModule:
    """A state-value network on ``agent``'s observation, writing ``"state_value"``."""
    return TensorDictModule(
        Head(encoder, hidden_size, 1), in_keys=observation_keys(agent, encoder), out_keys=["state_value"]
    )


class SplitJoint(nn.Module):
    """Split a joint action ``a = 3 u_m + u_c`` (as in ``activeperc/Joint-v1``) into the two agents' actions."""

    def forward(self, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(u_m, u_c)`` from the joint action."""
        return torch.div(action, NUM_ACTIONS, rounding_mode="floor"), action % NUM_ACTIONS


def make_joint_policy(actor) -> TensorDictSequential:
    """The joint actor (acting on the mover's view) followed by the split into the two agents' actions."""
    split = TensorDictModule(
        SplitJoint(), in_keys=[(JOINT, "action")], out_keys=[("mover", "action"), ("looker", "action")]
    )
    return TensorDictSequential(actor, split)


class EpsilonGreedyLooker(nn.Module):
    """Epsilon-greedy looker: ``argmax`` of the actor's logits with probability ``1 - epsilon``, else a uniform
    random look (E2's with ``phi2``; E1's greedy ``phi1`` with ``epsilon`` 0).

    Reads ``("looker", "observation")`` and writes ``("looker", "action")`` (the paper's eq. after (3)).
    """

    def __init__(self, actor, epsilon: float):
        super().__init__()
        self.actor = actor
        self.epsilon = epsilon

    def forward(self, tensordict):
        """Write the epsilon-greedy action into ``tensordict``."""
        logits = self.actor[0](tensordict.copy()).get(("looker", "logits"))
        greedy = logits.argmax(-1)
        random = torch.randint_like(greedy, NUM_ACTIONS)
        explore = torch.rand(greedy.shape, device=greedy.device) < self.epsilon
        tensordict.set(("looker", "action"), torch.where(explore, random, greedy))
        return tensordict


class FixedLooker(nn.Module):
    """Writes 'hold' for every room: the camera stays forward."""

    def forward(self, tensordict):
        """Write 'hold' into ``tensordict``."""
        action = torch.full(tuple(tensordict.batch_size), HOLD, device=tensordict.device)
        tensordict.set(("looker", "action"), action)
        return tensordict


class RandomPolicy(nn.Module):
    """Uniformly random actions for the given agents (for the random baseline of ``activeperc-eval``)."""

    def __init__(self, agents: tuple[str, ...]):
        super().__init__()
        self.agents = agents

    def forward(self, tensordict):
        """Write a uniform random action for every agent into ``tensordict``."""
        for agent in self.agents:
            action = torch.randint(NUM_ACTIONS, tuple(tensordict.batch_size), device=tensordict.device)
            tensordict.set((agent, "action"), action)
        return tensordict
