"""How the benchmarks take time: clocks, loops timed call by call, one-shot timing, CPU time and peak RSS.

Called by the benchmark scripts' steps (in-process loops and child jobs) and by `harness.runner.one_shot`.
Loops are timed call by call with ``perf_counter_ns``, Python's cyclic garbage collector paused (after a full
collection) for the whole loop, since a collection landing in one call would be timed with it; one-shot figures
are timed once, wall clock and this process's CPU time, optionally under cProfile.
"""

from __future__ import annotations

import contextlib
import cProfile
import gc
import resource
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, NamedTuple

from harness.profiling import profile_report

pc = time.perf_counter_ns


@contextlib.contextmanager
def gc_paused() -> Iterator[None]:
    """A timed region's surroundings: a full collection first, then the cyclic collector off until its end."""
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


class Loop(NamedTuple):
    """A loop timed call by call: nanoseconds per call, the calls' results, and the CPU seconds of the loop."""

    samples: list[int]
    results: list
    cpu: float


def time_each(fn: Callable[[Any], Any], items: Iterable) -> Loop:
    """``fn(item)`` for each item, each call timed alone with ``perf_counter_ns``, the collector paused.

    Parameters
    ----------
    fn : callable
        The call timed, with one item.
    items : iterable
        One item per call.

    Returns
    -------
    Loop
    """
    samples: list[int] = []
    results: list = []
    append, keep = samples.append, results.append
    with gc_paused():
        c0 = cpu_seconds()
        for item in items:
            t0 = pc()
            r = fn(item)
            t1 = pc()
            append(t1 - t0)
            keep(r)
        cpu = cpu_seconds() - c0
    return Loop(samples, results, cpu)


def maxrss() -> int:
    """Peak RSS of this process so far, in bytes."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb * 1024 if sys.platform != "darwin" else kb


def cpu_seconds() -> float:
    """User + system CPU time of this process so far."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class Timed(NamedTuple):
    """One timed run: its result, wall seconds, CPU seconds, and with a profile its text and heaviest function."""

    result: Any
    seconds: float
    cpu: float
    profile: str | None = None
    dominant: str | None = None


def timed(fn: Callable[[], Any], *, profile: bool = False, lines: int = 20) -> Timed:
    """Run ``fn()`` once, timed (wall clock and this process's CPU), under cProfile when ``profile``.

    Parameters
    ----------
    fn : callable
        The run, without arguments.
    profile : bool
        Whether to run it under cProfile (see `harness.profiling.profile_report` for what is kept).
    lines : int
        Functions listed in the profile's text, by own time and by cumulative time.

    Returns
    -------
    Timed
    """
    profiler = cProfile.Profile() if profile else None
    c0 = cpu_seconds()
    t0 = pc()
    if profiler:
        profiler.enable()
    result = fn()
    if profiler:
        profiler.disable()
    seconds = (pc() - t0) / 1e9
    cpu = cpu_seconds() - c0
    if not profiler:
        return Timed(result, seconds, cpu)
    text, dominant = profile_report(profiler, lines)
    return Timed(result, seconds, cpu, text, dominant)


def best_of(fn: Callable, *args, repeat: int = 2) -> tuple[float, Any]:
    """The fastest of ``repeat`` runs of ``fn(*args)`` in seconds, and the last run's result."""
    times, out = [], None
    for _ in range(repeat):
        out = None  # the previous result is freed before the next run, not during it
        t0 = pc()
        out = fn(*args)
        times.append((pc() - t0) / 1e9)
    return min(times), out
