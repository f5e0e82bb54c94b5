"""Collection in worker processes: one environment's rooms split over several processes.

One process steps its rooms one after the other: physics, the software renderer, the policy's forward
passes and TorchRL's bookkeeping take turns, and on 2 cores one process trains only about 1.3x faster
than on one (docs/performance.md). :class:`ProcessCollector` gives each of ``workers`` processes a
slice of the rooms and its own TorchRL ``Collector``; a rollout is every worker's slice collected at
once, joined along the rooms.

- Same layouts: worker ``k`` builds its env with ``first_room`` set to its slice's first room, so room
  ``i`` gets the episode seeds it would get in one env of all the rooms (``activeperc_rl.envs``).
- Current weights: the workers run CPU copies of the policy and the looker held in shared memory,
  refreshed from the live networks before every rollout, so each rollout acts with the weights of
  the moment, as an in-process ``Collector`` does. The workers only read them.
- Own random streams: each worker seeds torch from ``torch_seed`` and its index, so a run repeats
  itself; its sampled actions differ from an in-process run's, whose actions come from the main
  process's stream.
- Checkpoints: :meth:`ProcessCollector.state` gathers each worker's rooms, carried step and torch random
  state between rollouts, and :meth:`ProcessCollector.load_state` puts them back, so that a resumed run with
  the same number of workers collects what the uninterrupted one would have.
- Ctrl-C, SIGTERM and SIGHUP reach the main process only (the workers ignore them, even when they are sent
  to the whole process group, as a closing terminal sends SIGHUP), which saves its checkpoint and then shuts
  the workers down; a worker whose main process is gone exits. A worker that dies (killed, out of memory) is a
  :class:`WorkerError` naming it and how it died.
"""

from __future__ import annotations

import copy
import os
import signal
import threading
import traceback
from dataclasses import dataclass
from multiprocessing import resource_tracker

import numpy as np
import torch
import torch.multiprocessing as mp
from tensordict import TensorDictBase
from torch import nn

from activeperc_env.core import usable_cpus
from activeperc_rl.checkpoint import collector_state, load_collector_state

TRAJ_IDS = ("collector", "traj_ids")
START_TIMEOUT_S = 300.0


class WorkerError(RuntimeError):
    """A collector worker died, failed, or did not start; the message names the worker and the cause."""


@dataclass
class _WorkerSpec:
    """What worker ``index`` needs to build its env and collector (pickled into the spawned process)."""

    index: int
    workers: int
    first_room: int
    num_rooms: int
    rollout_length: int
    env_config: dict
    env_seed: int
    torch_seed: int
    threads: int
    modules: tuple[nn.Module, nn.Module | None]


class ProcessCollector:
    """Rollouts of one environment of ``num_envs`` rooms whose rooms are split over ``workers`` processes.

    An iterator like TorchRL's ``Collector``: each ``next()`` returns a rollout of shape
    ``[num_envs, rollout_length]`` on ``device``, worker ``k``'s rooms at rows
    ``first_k .. first_k + n_k - 1`` (the rooms are split as evenly as possible, in order).

    Args:
        policy: the mover's policy module (as for ``Collector``).
        looker: the looker module run inside the env's cycle, or ``None`` (external mode).
        env_config: the :class:`~activeperc_env.EnvConfig` fields, as a dict.
        num_envs: rooms in the whole environment.
        rollout_length: cycles per room in one rollout.
        workers: worker processes (at most ``num_envs``).
        env_seed: base seed of the rooms' layout streams (as ``make_env(seed=...)``).
        torch_seed: seed of the workers' torch random streams (worker ``k`` adds ``k``).
        device: where the rollouts are returned.
        name: what error messages call this collector (``"E2's collector"``): "NAME worker k died ...".
    """

    def __init__(
        self,
        policy: nn.Module,
        looker: nn.Module | None,
        env_config: dict,
        num_envs: int,
        rollout_length: int,
        workers: int,
        env_seed: int,
        torch_seed: int,
        device: torch.device | str = "cpu",
        name: str = "collector",
    ):
        if not isinstance(workers, int) or not 1 <= workers <= num_envs:
            raise ValueError(f"workers={workers!r} is invalid: expected an int in 1 .. num_envs={num_envs}")
        self.device = torch.device(device)
        self.workers = workers
        self.name = name
        self._live = (policy, looker)
        self._shared = copy.deepcopy(self._live)  # one copy of both keeps the weights they share shared
        for module in self._shared:
            if module is not None:
                module.cpu().share_memory()
        bounds = np.linspace(0, num_envs, workers + 1).round().astype(int)
        threads = max(1, usable_cpus() // workers)
        context = mp.get_context("spawn")
        _start_resource_tracker()
        self._conns, self._processes, self._buffers = [], [], []
        try:
            for k in range(workers):
                spec = _WorkerSpec(
                    index=k,
                    workers=workers,
                    first_room=int(bounds[k]),
                    num_rooms=int(bounds[k + 1] - bounds[k]),
                    rollout_length=rollout_length,
                    env_config=env_config,
                    env_seed=env_seed,
                    torch_seed=torch_seed + k,
                    threads=threads,
                    modules=self._shared,
                )
                here, there = context.Pipe()
                self._conns.append(here)
                name = f"activeperc-collector-{k}"
                process = context.Process(target=_work, args=(there, spec), daemon=True, name=name)
                process.start()
                there.close()
                self._processes.append(process)
            for k in range(workers):
                self._receive(k, "ready", timeout=START_TIMEOUT_S)
        except BaseException:
            self.shutdown()  # no worker outlives a failed start, whether it failed to start or to report ready
            raise

    def __iter__(self) -> ProcessCollector:
        return self

    def __next__(self) -> TensorDictBase:
        """Refresh the workers' weights, collect one rollout in every worker at once, and join them."""
        self._refresh()
        self._send_all(lambda k: "next")
        for k in range(self.workers):
            buffer = self._receive(k, "rollout")
            if buffer is not None:  # the first rollout: the worker's shared buffer, reused from then on
                self._buffers.append(buffer)
        return torch.cat(self._buffers, 0).to(self.device)

    def state(self) -> list[dict]:
        """Each worker's state between two rollouts: its env's rooms (``rooms_state``), the step its ``Collector``
        carries to the next rollout, and its torch random state."""
        self._send_all(lambda k: "state")
        states = [self._receive(k, "state") for k in range(self.workers)]
        return [state | {"carrier": state["carrier"].clone()} for state in states]  # out of the shared memory

    def load_state(self, states: list[dict]) -> None:
        """Put the workers where :meth:`state` left them; ``ValueError`` when the states do not fit them."""
        if not isinstance(states, list) or len(states) != self.workers:
            raise ValueError(f"its workers' states do not fit {self.workers} workers")
        self._send_all(lambda k: ("load", states[k]))
        for k in range(self.workers):
            self._receive(k, "loaded")

    def _send_all(self, message) -> None:
        """Send ``message(k)`` to every worker ``k``."""
        for k, conn in enumerate(self._conns):
            try:
                conn.send(message(k))
            except (BrokenPipeError, ConnectionResetError):
                raise self._died(k) from None

    def shutdown(self) -> None:
        """Stop the workers (each closes its env) and wait for them."""
        for conn in self._conns:
            try:
                conn.send("close")
            except (BrokenPipeError, OSError):
                pass
        for process in self._processes:
            process.join(timeout=30)
            if process.is_alive():
                process.kill()  # the workers ignore SIGTERM
                process.join()
        for conn in self._conns:
            conn.close()
        self._conns, self._processes, self._buffers = [], [], []

    @torch.no_grad()
    def _refresh(self) -> None:
        """Copy the live networks' weights into the workers' shared copies."""
        for live, shared in zip(self._live, self._shared, strict=True):
            if live is not None:
                for source, target in zip(live.state_dict().values(), shared.state_dict().values(), strict=True):
                    target.copy_(source)

    def _receive(self, k: int, expected: str, timeout: float | None = None):
        """The payload of worker ``k``'s next message, which must be ``expected``; its error otherwise."""
        conn = self._conns[k]
        try:
            if timeout is not None and not conn.poll(timeout):
                raise WorkerError(f"{self.name} worker {k} did not start within {timeout:.0f} s")
            kind, payload = conn.recv()
        except (EOFError, ConnectionResetError):
            raise self._died(k) from None
        if kind == "error":
            raise WorkerError(f"{self.name} worker {k} failed:\n{payload}")
        if kind == "unfit":
            raise ValueError(f"{self.name} worker {k}: {payload}")
        if kind != expected:
            raise WorkerError(f"{self.name} worker {k} sent {kind!r} where {expected!r} was expected")
        return payload

    def _died(self, k: int) -> WorkerError:
        """The error for worker ``k``, whose pipe closed: how its process ended."""
        process = self._processes[k]
        process.join(timeout=5)
        code = process.exitcode
        how = f"killed by {signal.Signals(-code).name}" if code is not None and code < 0 else f"exit code {code}"
        hint = " (the kernel's out-of-memory killer sends SIGKILL)" if code == -signal.SIGKILL else ""
        return WorkerError(f"{self.name} worker {k} died ({how}){hint}")


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker, unless it runs, with SIGHUP ignored for its whole life.

    The tracker is a process of its own in the run's process group: a closing terminal's SIGHUP would kill it
    while the run saves its checkpoint (and the run would warn that resources may leak). The workers ignore
    SIGHUP for the same reason (:func:`_work`).
    """
    if threading.current_thread() is not threading.main_thread():
        return  # signal dispositions can only be set from the main thread: the tracker starts as it would anyway
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)  # a new process keeps what its parent ignores
    try:
        resource_tracker.ensure_running()
    finally:
        signal.signal(signal.SIGHUP, previous)


def _work(conn, spec: _WorkerSpec) -> None:
    """A worker's life: build the env and collector of its rooms, then answer ``next``, ``state`` and
    ``("load", state)`` until ``close``."""
    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(number, signal.SIG_IGN)
    # llvmpipe draws with as many threads as there are cores unless told; share the cores among the workers. A
    # worker with one core draws in its own thread (0): the same pixels without waiting for a helper thread
    os.environ.setdefault("LP_NUM_THREADS", str(spec.threads if spec.threads > 1 else 0))
    from torchrl.collectors import Collector

    from activeperc_rl.envs import make_env

    collector = None
    try:
        torch.set_num_threads(spec.threads)
        torch.manual_seed(spec.torch_seed)
        policy, looker = spec.modules
        env = make_env(
            spec.num_rooms,
            looker=looker,
            seed=spec.env_seed,
            first_room=spec.first_room,
            nthread=spec.threads,
            **spec.env_config,
        )
        collector = Collector(
            env,
            policy,
            frames_per_batch=spec.num_rooms * spec.rollout_length,
            total_frames=-1,
            auto_register_policy_transforms=False,
        )
        rollouts = iter(collector)
        buffer = None
        conn.send(("ready", None))
        while (message := conn.recv()) != "close":
            if message == "state":
                conn.send(("state", collector_state(collector) | {"torch_rng": torch.get_rng_state()}))
                continue
            if message != "next":
                try:
                    _load(collector, message[1])
                except (KeyError, TypeError, RuntimeError, ValueError) as error:  # a damaged checkpoint
                    conn.send(("unfit", f"its state does not fit: {error}"))
                else:
                    conn.send(("loaded", None))
                continue
            rollout = next(rollouts)
            # trajectory ids stay unique over the joined rollout: worker k's id i becomes i * workers + k
            rollout.set(TRAJ_IDS, rollout.get(TRAJ_IDS) * spec.workers + spec.index)
            if buffer is None:
                buffer = rollout.clone().share_memory_()
                conn.send(("rollout", buffer))
            else:
                buffer.update_(rollout)
                conn.send(("rollout", None))
    except (EOFError, BrokenPipeError):
        pass  # the main process is gone
    except Exception:
        try:
            conn.send(("error", traceback.format_exc()))
        except (BrokenPipeError, OSError):
            pass
    finally:
        if collector is not None:
            collector.shutdown()
        conn.close()


def _load(collector, state: dict) -> None:
    """Put a worker's collector (and its env) and torch stream where :meth:`ProcessCollector.state` found them."""
    load_collector_state(collector, state)
    torch.set_rng_state(state["torch_rng"])
