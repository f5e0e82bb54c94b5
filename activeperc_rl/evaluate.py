"""Evaluation on held-out layouts: success rate and mean return, optionally a video.

Evaluation rooms draw odd episode seeds and training rooms even ones (``split="eval"`` of
:func:`~activeperc_rl.envs.make_env`), so no evaluation layout was seen in training. ``N`` episodes
are spread over the rooms as fixed quotas (room ``i`` plays its first ``N_i`` episodes), so short
episodes are not over-counted, and the same seed gives the same episodes.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type, step_mdp
from tqdm import tqdm

from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_env.checks import check_seed
from activeperc_env.config import is_int
from activeperc_env.render import side_by_side
from activeperc_rl.config import DEVICES
from activeperc_rl.envs import LOOKER, MOVER, latest_view, make_env, torch_device
from activeperc_rl.models import RandomPolicy
from activeperc_rl.policies import PRETRAINED, is_policy, policy_from_saved, pretrained
from activeperc_rl.recipe import TrainConfig
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.atomic import atomic_path, check_writable
from activeperc_rl.runtime.checkpoint import CHECKPOINT, checked_checkpoint, read_saved, restored_method
from activeperc_rl.runtime.signals import stop_raises_interrupt

MAX_ROOMS = 16
VIDEO_SUFFIXES = (".mp4", ".gif")


def evaluate(
    config: TrainConfig,
    mover_policy=None,
    looker=None,
    episodes: int = 100,
    seed: int = 0,
    device="cpu",
    video: str | Path | None = None,
    progress: bool = False,
    on_cycle=None,
    look_views: bool = False,
) -> dict:
    """Play ``episodes`` held-out episodes and summarise them.

    Args:
        config: the run's config (its env config is used).
        mover_policy: the mover's policy; ``None`` evaluates uniformly random mover and looker.
        looker: a looker module run inside the cycle, or ``None`` when ``mover_policy`` writes both
            actions (or for the random policy).
        episodes: number of episodes.
        seed: seed of the layouts and of the policies' sampling.
        device: where the policies run.
        video: write room 0's first episode (first-person view beside the bird's-eye map) here.
        progress: show a progress bar of the finished episodes on stderr while it runs (gone when it ends).
        on_cycle: called after every cycle as ``on_cycle(env, td, counted)``: the env, the step's tensordict (its
            ``"next"`` entries before any reset) and a bool array of the rooms whose episode is one of those played.
        look_views: draw what each look would show before the looker picks one, for a looker that reads them
            (:func:`~activeperc_rl.envs.make_env`'s ``look_views``).

    Returns:
        ``{"episodes", "success_rate", "mean_return", "mean_length"}``.
    """
    if not isinstance(config, TrainConfig):
        raise TypeError(f"config={config!r} is invalid: expected a TrainConfig (TrainConfig.from_options(...))")
    if mover_policy is None and looker is not None:
        raise ValueError("a looker was given without a mover_policy (None plays random movers and lookers)")
    for name, module in (("mover_policy", mover_policy), ("looker", looker)):
        if module is not None and not callable(module):
            raise TypeError(f"{name}={module!r} is invalid: expected a module called on the env's tensordict")
    if not is_int(episodes) or episodes < 1:
        raise ValueError(f"episodes={episodes!r} is invalid: expected an int >= 1")
    check_seed(seed)
    device = torch_device(device)
    if video is not None:
        if Path(video).suffix.lower() not in VIDEO_SUFFIXES:
            raise ValueError(f"video file {str(video)!r} must end in one of {VIDEO_SUFFIXES} (it picks the format)")
        check_writable(video)  # before the episodes are played, not after
    if mover_policy is None:
        mover_policy, looker = RandomPolicy((MOVER, LOOKER)), None
    quota = room_quotas(episodes)
    rooms = len(quota)
    returns, successes, lengths = ([[] for _ in range(rooms)] for _ in range(3))
    frames = []
    env = make_env(
        rooms,
        device=device,
        looker=looker,
        seed=seed,
        split="eval",
        backend=config.run.backend,
        frame_stack=config.stacked_views,
        look_views=look_views,
        config=config.env,
    )
    bar = tqdm(total=episodes, unit="episode", desc="evaluating", disable=not progress, leave=False, dynamic_ncols=True)
    try:
        with torch.random.fork_rng(), torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
            torch.manual_seed(seed)
            td = env.reset()
            if video is not None:
                frames.append(_video_frame(env, td.get((MOVER, "observation", "image"))))  # the start
            steps = np.zeros(rooms, dtype=np.int64)
            while any(len(r) < q for r, q in zip(returns, quota, strict=True)):
                td = mover_policy(td)
                td = env.step(td)
                steps += 1
                if on_cycle is not None:
                    on_cycle(env, td, np.array([len(r) < q for r, q in zip(returns, quota, strict=True)]))
                if video is not None and not returns[0]:
                    # before an auto-reset replaces room 0
                    frames.append(_video_frame(env, td.get(("next", MOVER, "observation", "image"))))
                following = env.maybe_reset(step_mdp(td, keep_other=True))
                done = td.get(("next", "done")).reshape(-1).cpu().numpy()
                episode_return = td.get(("next", MOVER, "episode_return")).reshape(-1).cpu().numpy()
                success = td.get(("next", MOVER, "episode_success")).reshape(-1).cpu().numpy()
                for i in np.flatnonzero(done):
                    if len(returns[i]) < quota[i]:
                        returns[i].append(float(episode_return[i]))
                        successes[i].append(bool(success[i]))
                        lengths[i].append(int(steps[i]))
                        bar.update()
                    steps[i] = 0
                td = following
    finally:
        bar.close()
        env.close()
    if video is not None:
        _write_video(video, frames, fps=config.env.control_hz)
    flat = np.concatenate([np.asarray(r) for r in returns])
    return {
        "episodes": int(flat.size),
        "success_rate": float(np.mean(np.concatenate(successes))),
        "mean_return": float(np.mean(flat)),
        "mean_length": float(np.mean(np.concatenate([np.asarray(n) for n in lengths]))),
    }


def room_quotas(episodes: int) -> np.ndarray:
    """How many of ``episodes`` each evaluation room plays: ``min(episodes, MAX_ROOMS)`` rooms, the first ones one
    more where they do not divide evenly."""
    rooms = min(episodes, MAX_ROOMS)
    return np.full(rooms, episodes // rooms) + (np.arange(rooms) < episodes % rooms)


def load_policy(path: str | Path, device="cpu"):
    """Load a run directory, a checkpoint file or a policy file (:mod:`activeperc_rl.policies`):
    ``(config, mover_policy, looker)``.

    Raises ``ValueError`` naming the path when it is none of them, or when the file is unusable.
    """
    path = Path(path)
    file = path / CHECKPOINT if path.is_dir() else path
    if not path.exists():
        raise ValueError(f"{str(path)!r} does not exist: give a run directory, a checkpoint or a policy file")
    kind = "checkpoint" if path.is_dir() else "checkpoint or policy file"
    saved = read_saved(file, kind, weights_only=None)  # a policy file is read weights-only, a checkpoint in full
    if is_policy(saved):
        return policy_from_saved(saved, file, device)
    config, method = restored_method(checked_checkpoint(saved, file), file, torch_device(device))
    return (config, *method.policy())


def _video_frame(env, images: torch.Tensor) -> np.ndarray:
    """Room 0's bird's-eye map with its first-person view (the latest view of ``images[0]``, the mover's) on the
    right."""
    return side_by_side(env.sim.render_map(0), latest_view(images[0]).cpu().numpy())


def _write_video(path: str | Path, frames: list[np.ndarray], fps: float) -> None:
    """Write ``frames`` at ``fps`` (the env's control rate: the video plays in simulated time); a GIF loops."""
    import imageio.v2 as imageio

    if Path(path).suffix.lower() == ".gif":
        options = {"duration": 1000 / fps, "loop": 0}  # milliseconds a frame; played over and over
    else:
        options = {"fps": fps, "macro_block_size": 1}
    with atomic_path(path) as temporary:
        imageio.mimwrite(temporary, frames, **options)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``activeperc-eval``."""
    parser = ArgumentParser(
        prog="activeperc-eval",
        description="Evaluate a run, a policy file or a shipped policy (or random play in its config) on held-out "
        "episodes.",
    )
    parser.add_argument(
        "run", nargs="?", help="a run directory (holding checkpoint.pt), a checkpoint file or a policy file"
    )
    parser.add_argument(
        "--pretrained",
        choices=tuple(PRETRAINED),
        help="a policy shipped with activeperc instead of RUN: the default recipe trained at 60 or 100 degrees",
    )
    parser.add_argument("--episodes", type=whole_number, default=100, help="number of episodes (default 100)")
    parser.add_argument(
        "--seed",
        type=whole_number,
        default=0,
        help="seed of the held-out layouts and of the policies' sampling (default 0)",
    )
    parser.add_argument("--random", action="store_true", help="evaluate uniformly random mover and looker instead")
    parser.add_argument(
        "--video", metavar="FILE.mp4", help="write the first episode's view and map to FILE.mp4 (or FILE.gif)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--device", default="cpu", choices=DEVICES, help="device of the policy (default cpu; auto: cuda when available)"
    )
    args = parser.parse_args(argv)
    if (args.run is None) == (args.pretrained is None):
        parser.error("give either RUN or --pretrained NAME")
    try:
        with stop_raises_interrupt():  # a kill or a closing terminal stops it as Ctrl-C does
            device = torch_device(args.device)
            if args.pretrained is None:
                config, mover_policy, looker = load_policy(args.run, device)
            else:
                config, mover_policy, looker = pretrained(args.pretrained, device)
            if config.run.portable and argv is None:
                portable.restart_pinned("activeperc-eval")  # a portable run is evaluated with its kernels too
            if args.random:
                mover_policy, looker = None, None
            result = evaluate(
                config, mover_policy, looker, args.episodes, args.seed, device, args.video, progress=sys.stderr.isatty()
            )
    except ValueError as error:
        print(f"activeperc-eval: error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # the disk is full, the folder went away, ...
        print(f"activeperc-eval: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C, SIGTERM, SIGHUP: no result, and no video or a half-written one
        unwritten = f"; {args.video!r} not written" if args.video else ""
        print(f"\nactiveperc-eval: interrupted{unwritten}", file=sys.stderr)
        return 130
    result = {
        "policy": "random" if args.random else config.method,
        **result,
        "torch_cpu_capability": portable.cpu_capability(),
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{result['policy']}: success rate {result['success_rate']:.3f}, mean return {result['mean_return']:.3f} "
            f"over {result['episodes']} held-out episodes (seed {args.seed})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
