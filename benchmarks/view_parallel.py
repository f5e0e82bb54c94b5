"""Can one process draw views on two cores? Views/s of the default room's renderer drawn by one thread, by two threads
with a GL context each, and by two processes, measured in one run.

With ``LP_NUM_THREADS=0`` (what ``import activeperc_env`` sets) llvmpipe draws in the calling thread; the question is
whether two threads of one process draw side by side, or only two processes do. Run it from the repository root on
a machine with two free cores::

    python benchmarks/view_parallel.py                  # 64 views a pass, 4 s a figure, 2 rounds
    python benchmarks/view_parallel.py --views 32 --seconds 2
"""

from __future__ import annotations

import argparse
import multiprocessing
import threading
import time

import harness


def views_per_second(views: int, seconds: float, copies: int = 1, offset: int = 0) -> float:
    """Views/s of ``copies`` renderers of ``views`` tiles each, in as many threads of this process, each drawing the
    same ``views`` rooms' states (rooms ``offset`` on) again and again; summed over the threads."""
    import numpy as np

    from activeperc_env import EnvConfig, Simulator
    from activeperc_env.render import TiledRenderer

    config = EnvConfig()
    sim = Simulator(config, num_envs=offset + views, nthread=1)
    sim.reset(seeds=np.arange(offset + views))
    qpos, mocap = sim._qpos[offset:], sim._mocap_pos[offset:]  # noqa: SLF001 (the states, as the renderer reads them)
    renderers = [TiledRenderer(sim.model, config.width, config.height, views, config.fov) for _ in range(copies)]
    counts = [0] * copies

    def draw(k: int, until: float) -> None:
        while time.perf_counter() < until:
            renderers[k].render(qpos, mocap)
            counts[k] += views

    for renderer in renderers:
        renderer.render(qpos, mocap)  # a context's first draw compiles llvmpipe's shaders
    start = time.perf_counter()
    threads = [threading.Thread(target=draw, args=(k, start + seconds)) for k in range(copies)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    rate = sum(counts) / (time.perf_counter() - start)
    for renderer in renderers:
        renderer.close()
    sim.close()
    return rate


def _in_child(views: int, seconds: float, offset: int, answers) -> None:
    answers.put(views_per_second(views, seconds, offset=offset))


def in_processes(views: int, seconds: float, processes: int) -> float:
    """Views/s summed over ``processes`` spawned processes, each drawing its own ``views`` rooms."""
    context = multiprocessing.get_context("spawn")
    answers = context.Queue()
    children = [context.Process(target=_in_child, args=(views, seconds, k * views, answers)) for k in range(processes)]
    for child in children:
        child.start()
    rates = [answers.get() for _ in children]
    for child in children:
        child.join()
    return sum(rates)


def main(argv: list[str] | None = None) -> None:
    """Print each way's views/s and its ratio to one thread's, round by round."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=harness.at_least(int, "views", 2), default=64, help="views a pass (64)")
    parser.add_argument("--seconds", type=harness.at_least(float, "seconds", 0.5), default=4.0, help="per figure (4)")
    parser.add_argument("--rounds", type=harness.at_least(int, "rounds", 1), default=2, help="rounds (2)")
    args = parser.parse_args(argv)
    import activeperc_env  # noqa: F401 (sets LP_NUM_THREADS=0 when it is unset, for this process and its children)

    half = args.views // 2
    machine = harness.machine_info()
    print(f"{harness.machine_line(machine)}, LP_NUM_THREADS={machine['lp_num_threads']}")
    print(f"{args.views} views of the default room, {args.seconds:g} s a figure; ratios to one thread's views/s")
    for round_ in range(1, args.rounds + 1):
        one = in_processes(args.views, args.seconds, 1)  # one thread, in a process of its own like the others
        two_threads = views_per_second(half, args.seconds, copies=2)
        two_processes = in_processes(half, args.seconds, 2)
        print(
            f"round {round_}: one thread {one:,.0f} views/s; two threads, a context each, {two_threads:,.0f} "
            f"({two_threads / one:.2f}x); two processes {two_processes:,.0f} ({two_processes / one:.2f}x)",
            flush=True,
        )


if __name__ == "__main__":
    main()
