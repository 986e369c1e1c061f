"""The repeats of a figure and their statistics: percentiles, medians, and the runs that finished.

A figure is often the median of several runs (timed calls, or steps each in a fresh process); the benchmark
scripts' report code and `harness.tables` call these. A step that failed leaves None among its runs' results
(`harness.runner.Runner.run`), so the statistics are taken over `finished` runs.
"""

from __future__ import annotations

import math


def percentile(values: list[float], q: float) -> float:
    """The ``q``-quantile of some values, with linear interpolation as numpy's default.

    Parameters
    ----------
    values : list of float
        The values, in any order; NaN when there are none.
    q : float
        The quantile, from 0 to 1.

    Returns
    -------
    float
    """
    if not values:
        return math.nan
    s = sorted(values)
    pos = (len(s) - 1) * q
    lo = math.floor(pos)
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (pos - lo)


def median(values: list[float]) -> float:
    """The median of some values (`percentile` 0.5)."""
    return percentile(values, 0.5)


def finished(runs: dict, key) -> list[dict]:
    """The results of the runs of one figure that finished.

    Parameters
    ----------
    runs : dict
        Lists of results, one per run, under each figure's key; a failed run's result is None.
    key
        The figure's key; a missing key has no runs.

    Returns
    -------
    list of dict
    """
    return [r for r in runs.get(key) or [] if r]


def median_of(results: list[dict], field: str = "seconds") -> float | None:
    """The median of one field over some runs' results, None without runs."""
    return median([r[field] for r in results]) if results else None


def fastest(results: list[dict] | None) -> dict | None:
    """The run with the fewest ``seconds`` among those that finished, None without one."""
    done = [r for r in results or [] if r]
    return min(done, key=lambda r: r["seconds"]) if done else None
