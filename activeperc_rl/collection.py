"""Rollouts of one environment's rooms through TorchRL's collectors: in this process, in worker processes, or on Ray.

:class:`Rollouts` wraps ``torchrl.collectors.Collector``: with ``workers == 0`` one collector steps every room here;
with ``workers == k`` the rooms are split over ``k`` workers (TorchRL's multi-process collector, or its Ray
collector on a Ray cluster) whose rollouts are joined along the rooms.

- Same layouts: worker ``j`` builds its env with ``first_room`` at its slice's first room (:class:`WorkerEnv`), so
  room ``i`` gets the episode seeds it gets in one env of all the rooms.
- Current weights: before every rollout the mover's policy and the looker (which runs inside the env) reach every
  worker through the collector's ``map_fn``: its collector's ``update_policy_weights_`` and its ``env.looker``.
- Own random streams: each worker seeds torch from ``torch_seed`` plus its index as it builds its env.
- Checkpoints: :meth:`Rollouts.state` holds each env's rooms (and each worker's torch random state);
  :meth:`Rollouts.load_state` puts them back through ``reset(rooms_state=...)``, which resumes the rooms instead
  of starting episodes, so a resumed run with as many workers collects what the uninterrupted one would have.
- Stops: workers ignore SIGINT, SIGTERM and SIGHUP (the main process saves its checkpoint, then shuts them down);
  a worker that dies is a :class:`WorkerError` naming it.
"""

from __future__ import annotations

import importlib.util
import os
import signal
import threading
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.collectors import Collector

from activeperc_env import EnvConfig
from activeperc_env.core import usable_cpus
from activeperc_rl.envs import make_env

COLLECTORS = ("process", "ray")
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
DEATH_GRACE = 2.0  # seconds an error from the workers waits for a worker's death to show


class WorkerError(RuntimeError):
    """A collector worker died or failed; the message names the worker and the cause."""


def split_rooms(num_envs: int, workers: int) -> list[tuple[int, int]]:
    """``(first_room, num_rooms)`` of each worker: ``num_envs`` rooms split in order, as evenly as possible."""
    bounds = np.linspace(0, num_envs, workers + 1).round().astype(int)
    return [(int(bounds[k]), int(bounds[k + 1] - bounds[k])) for k in range(workers)]


def ignore_stop_signals() -> None:
    """Ignore SIGINT, SIGTERM and SIGHUP in this process (a worker's: its main process handles them)."""
    if threading.current_thread() is threading.main_thread():
        for number in STOP_SIGNALS:
            signal.signal(number, signal.SIG_IGN)


@dataclass
class WorkerEnv:
    """The env factory of one worker: its slice of the rooms, with torch seeded and threaded for the worker."""

    config: EnvConfig
    num_rooms: int
    first_room: int
    env_seed: int
    torch_seed: int
    threads: int
    looker: nn.Module | None
    look_views: bool = False
    backend: str = "mujoco"
    frame_stack: int = 1

    def __call__(self):
        """Build the worker's env (TorchRL calls this in the worker)."""
        ignore_stop_signals()
        # llvmpipe draws with as many threads as there are cores unless told; a worker with one core draws in its
        # own thread (0): the same pixels without waiting for a helper thread
        os.environ.setdefault("LP_NUM_THREADS", str(self.threads if self.threads > 1 else 0))
        torch.set_num_threads(self.threads)
        torch.manual_seed(self.torch_seed)
        return make_env(
            self.num_rooms,
            looker=self.looker,
            seed=self.env_seed,
            first_room=self.first_room,
            nthread=self.threads,
            look_views=self.look_views,
            backend=self.backend,
            frame_stack=self.frame_stack,
            config=self.config,
        )


class Rollouts:
    """An iterator of rollouts ``[num_envs, rollout_length]`` of ``policy`` (and ``looker`` inside the env).

    Args:
        policy: the mover's policy module (as for ``Collector``).
        looker: the looker module run inside the env's cycle, or ``None`` (external mode).
        config: the room.
        num_envs: rooms in the whole environment.
        rollout_length: cycles per room in one rollout.
        env_seed: base seed of the rooms' layout streams (as ``make_env(seed=...)``).
        torch_seed: seed of the workers' torch streams (worker ``j`` adds ``j``).
        workers: 0 (this process steps the rooms) or the number of workers.
        collector: where the workers run: ``"process"`` or ``"ray"``.
        ray_address: the Ray cluster to join (``"local"``: a Ray instance of its own on this machine).
        device: where the rollouts are returned (and, with ``workers == 0``, where the env runs).
        name: what error messages call these rollouts (``"E2's collector"``).
        look_views: record what each look would have shown (``make_env``'s ``look_views``).
        backend: the rooms' physics and renderer (``make_env``'s ``backend``).
        frame_stack: the latest cycles' views in each observation (``make_env``'s ``frame_stack``).
    """

    def __init__(
        self,
        policy: nn.Module,
        looker: nn.Module | None,
        config: EnvConfig,
        num_envs: int,
        rollout_length: int,
        *,
        env_seed: int,
        torch_seed: int,
        workers: int = 0,
        collector: str = "process",
        ray_address: str = "local",
        device: torch.device | str = "cpu",
        name: str = "collector",
        look_views: bool = False,
        backend: str = "mujoco",
        frame_stack: int = 1,
    ):
        if collector not in COLLECTORS:
            raise ValueError(f"collector={collector!r} is invalid: expected one of {COLLECTORS}")
        if not isinstance(workers, int) or not 0 <= workers <= num_envs:
            raise ValueError(f"{name}: workers={workers!r} is invalid: expected an int in 0 .. its {num_envs} rooms")
        if collector == "ray" and workers and num_envs % workers:
            raise ValueError(f"num_envs={num_envs} does not split evenly over {workers} Ray workers")
        if collector == "ray" and workers and importlib.util.find_spec("ray") is None:
            raise ValueError("collector='ray' needs Ray, which is not installed: pip install -e '.[distributed]'")
        self.device, self.workers, self.name = torch.device(device), workers, name
        self._policy, self._looker = policy, looker
        if workers == 0:
            env = make_env(
                num_envs,
                device=self.device,
                looker=looker,
                seed=env_seed,
                look_views=look_views,
                backend=backend,
                frame_stack=frame_stack,
                config=config,
            )
            try:
                self.collector = Collector(
                    env,
                    policy,
                    frames_per_batch=num_envs * rollout_length,
                    total_frames=-1,
                    device=self.device,
                    auto_register_policy_transforms=False,
                )
            except BaseException:
                env.close()  # its GL context and physics threads, which the collector would have shut down
                raise
        else:
            threads = max(1, usable_cpus() // workers)
            envs = [
                WorkerEnv(config, n, first, env_seed, torch_seed + k, threads, looker, look_views, backend, frame_stack)
                for k, (first, n) in enumerate(split_rooms(num_envs, workers))
            ]
            frames = [env.num_rooms * rollout_length for env in envs]
            try:
                if collector == "ray":
                    self.collector = _ray_collector(envs, policy, frames, ray_address)
                else:
                    self.collector = _process_collector(envs, policy, frames, threads)
            except OSError:  # this machine could not start a worker (out of processes, say)
                raise
            except Exception as error:  # TorchRL re-raises a worker's error with the worker's traceback
                raise WorkerError(f"{name}: a worker failed to start: {type(error).__name__}: {error}") from None
        self._iterator = iter(self.collector)

    @property
    def env(self):
        """The env of an in-process collector (``workers == 0``)."""
        return self.collector.env

    def __iter__(self) -> Rollouts:
        return self

    def __next__(self) -> TensorDictBase:
        """The next rollout, acted with the weights of the moment."""
        with self._named_failures():
            if self.workers:
                self._send_weights()
            with warnings.catch_warnings():
                # Ray's: it cannot see that Rollouts sends the weights itself (_send_weights)
                warnings.filterwarnings("ignore", "RayCollector iteration started before weight synchronization")
                rollout = next(self._iterator)
        if rollout.ndim == 3:  # Ray stacks its workers' rollouts, each numbering its trajectories from 0
            ids = rollout["collector", "traj_ids"]
            worker = torch.arange(self.workers, device=ids.device).view(-1, 1, 1)
            rollout["collector", "traj_ids"] = ids * self.workers + worker
            rollout = rollout.reshape(-1, rollout.shape[-1])
        return rollout.to(self.device)

    def _send_weights(self) -> None:
        """Copy the live policy's and looker's weights into every worker's (through ``map_fn``, which names a worker
        that died instead of waiting for it)."""
        policy = TensorDict.from_module(self._policy).data.clone().cpu()
        try:
            self.collector.map_fn("update_policy_weights_", [(policy,)] * self.workers)
            if self._looker is not None:
                looker = {k: v.detach().clone().cpu() for k, v in self._looker.state_dict().items()}
                self.collector.map_fn("env.looker.load_state_dict", [(looker,)] * self.workers)
        except RuntimeError as error:  # the tensors go through torch's shared-memory manager, a process of its own
            if _dead_worker(self.collector, wait=DEATH_GRACE) is not None:
                raise
            raise WorkerError(
                f"{self.name}: the weights could not be sent to its workers ({error}): torch's shared-memory manager"
                " (torch_shm_manager), through which they go, has died or cannot be reached"
            ) from None

    def state(self) -> dict:
        """Where the rooms stand between two rollouts (each worker's rooms and torch random state)."""
        with self._named_failures():
            if not self.workers:
                return {"rooms": self.collector.env.rooms_state()}
            rooms = self.collector.map_fn("env.rooms_state")
            streams = self.collector.map_fn("env.random_state")
        return {"workers": [{"rooms": r, "torch_rng": s} for r, s in zip(rooms, streams, strict=True)]}

    def load_state(self, state: dict) -> None:
        """Put the rooms where :meth:`state` found them; ``ValueError`` when the state does not fit them."""
        if not self.workers:
            self.collector.reset(rooms_state=state["rooms"])
            return
        workers = state.get("workers")
        if not isinstance(workers, list) or len(workers) != self.workers:
            raise ValueError(f"its workers' states do not fit {self.workers} workers")
        with self._named_failures():
            self.collector.map_fn("env.set_random_state", [(w["torch_rng"],) for w in workers])
            kwargs = [{"rooms_state": w["rooms"]} for w in workers]
            for result in self.collector.map_fn("reset", list_of_kwargs=kwargs):
                if isinstance(result, Exception):
                    raise ValueError(str(result))

    def shutdown(self) -> None:
        """Stop the collector and its workers (each closes its env)."""
        self.collector.shutdown()
        # TorchRL's weight-sync scheme stops its threads in __del__; at exit (a collector kept alive by a
        # traceback) that would wait forever on a thread that can no longer start: stop them now
        for scheme in (getattr(self.collector, "_weight_sync_schemes", None) or {}).values():
            scheme.shutdown()

    @contextmanager
    def _named_failures(self):
        """Turn a worker's death inside the block into a :class:`WorkerError` naming it."""
        died = _dead_worker(self.collector)  # before TorchRL waits on a worker that will never answer
        if died is not None:
            raise WorkerError(f"{self.name} worker {died}")
        try:
            yield
        except WorkerError:
            raise
        except Exception as error:  # TorchRL's own error after a death, or the death's aftermath
            # a pipe breaks as its worker dies, a moment before the process can be seen to have ended
            died = _dead_worker(self.collector, wait=DEATH_GRACE)
            if died is not None:
                raise WorkerError(f"{self.name} worker {died}") from None
            if type(error).__name__ in ("RayActorError", "ActorDiedError"):
                raise WorkerError(f"{self.name}: a Ray worker died: {str(error).splitlines()[0]}") from None
            raise


def _dead_worker(collector, wait: float = 0.0) -> str | None:
    """``"k died (how)"`` for the first worker process of ``collector`` that has ended (looking again for up to ``wait``
    seconds while none has), or ``None``."""
    deadline = time.monotonic() + wait
    while True:
        died = _ended_worker(collector)
        if died is not None or time.monotonic() >= deadline:
            return died
        time.sleep(0.05)


def _ended_worker(collector) -> str | None:
    """``"k died (how)"`` for the first worker process of ``collector`` that has ended, or ``None``."""
    for k, process in enumerate(getattr(collector, "procs", None) or []):
        try:
            code = process.exitcode
        except ValueError:  # closed by TorchRL after another worker failed
            continue
        if code is not None:
            how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
            hint = " (the kernel's out-of-memory killer sends SIGKILL)" if code == -signal.SIGKILL else ""
            return f"{k} died ({how}){hint}"
    return None


def _process_collector(envs: list[WorkerEnv], policy, frames: list[int], threads: int):
    """TorchRL's multi-process collector over ``envs``, its workers' rollouts joined along the rooms."""
    from torchrl.collectors import MultiSyncCollector

    # the weights travel to the workers as tensors through pipes: with file descriptors a worker that dies while
    # it fetches one leaves a traceback in multiprocessing's descriptor-sharing thread; named files do not
    torch.multiprocessing.set_sharing_strategy("file_system")
    return MultiSyncCollector(
        envs,
        policy,
        frames_per_batch=frames,
        total_frames=-1,
        cat_results=0,
        init_fn=ignore_stop_signals,
        num_threads=torch.get_num_threads(),
        num_sub_threads=threads,
        auto_register_policy_transforms=False,
        weight_sync_schemes={},  # Rollouts sends the weights itself, before every rollout
    )


def _ray_collector(envs: list[WorkerEnv], policy, frames: list[int], ray_address: str):
    """TorchRL's Ray collector over ``envs`` on the cluster at ``ray_address`` (``"local"``: a Ray instance of its
    own)."""
    from torchrl.collectors.distributed import RayCollector

    if ray_address == "local":
        init = {"num_cpus": usable_cpus(), "include_dashboard": False}
    else:
        init = {"address": ray_address}
    init["log_to_driver"] = False  # each worker would print its collector's repr; its errors reach us as exceptions
    return RayCollector(
        envs,
        policy,
        frames_per_batch=sum(frames),
        total_frames=2**62,  # unbounded: the trainer decides when to stop
        sync=True,
        ray_init_config=init,
        # a run's collectors take turns (E1's, then E2's): its workers reserve no CPU of the cluster, which a
        # cluster of fewer CPUs than workers would leave them waiting for, and Ray spreads them over its nodes
        remote_configs={"num_cpus": 0, "memory": None, "scheduling_strategy": "SPREAD"},
        collector_kwargs={"auto_register_policy_transforms": False},
        weight_sync_schemes={},  # Rollouts sends the weights itself, before every rollout
    )
