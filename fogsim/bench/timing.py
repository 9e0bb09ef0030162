"""Wall-clock timing for the benchmarks: one call in milliseconds, and the medians of interleaved
repeats (each function once per round, so a slow spell of a shared machine hits every contender
alike; the ratio of two medians of one run is the figure worth reporting)."""
from __future__ import annotations

import statistics
import time
from typing import Callable


def elapsed_ms(fn: Callable[[], object]) -> float:
    """Milliseconds one call of ``fn`` takes (wall clock, ``time.perf_counter``)."""
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1e3


def median_ms(fns: dict[str, Callable[[], object]], repeat: int) -> dict[str, float]:
    """Run each function ``repeat`` times, interleaved, and return median milliseconds by name."""
    times = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            times[name].append(elapsed_ms(fn))
    return {name: statistics.median(v) for name, v in times.items()}


def median_wall_and_cpu_ms(fns: dict[str, Callable[[], object]], repeat: int
                           ) -> tuple[dict[str, float], dict[str, float]]:
    """As :func:`median_ms`, and the medians of the calling thread's CPU time (``time.thread_time``: what the
    work costs one core, whatever else the machine runs), by name: (wall, cpu)."""
    wall = {name: [] for name in fns}
    cpu = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.thread_time()
            fn()
            cpu[name].append((time.thread_time() - c0) * 1e3)
            wall[name].append((time.perf_counter() - t0) * 1e3)
    return ({name: statistics.median(v) for name, v in wall.items()},
            {name: statistics.median(v) for name, v in cpu.items()})
