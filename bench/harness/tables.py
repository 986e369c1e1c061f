"""The figures of a benchmark and the tables that print them.

A `Figure` is one row: a time beside its floor (the same work done with the plain tools, measured in the same
run) and its target, with the verdict. `print_figures` prints a list of them as the table every benchmark shares
(and `print_markdown` again as markdown); `print_table` prints a benchmark's own tables. Called by
`harness.report.Report`, which prints a run's tables, and by the benchmark scripts, which build the figures and
their own tables' rows; the ``fmt_*`` functions are the units every table reads in.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

from harness.stats import median, percentile


def fmt_time(seconds: float | None) -> str:
    """A duration in the unit that reads best: µs below 1 ms, ms below 0.1 s, else s; ``—`` for none."""
    if seconds is None or (isinstance(seconds, float) and math.isnan(seconds)):
        return "—"
    if seconds < 1e-3:
        us = seconds * 1e6
        return f"{us:.0f} µs" if us >= 100 else f"{us:.1f} µs"
    if seconds < 0.1:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def fmt_mib(b: int | None) -> str:
    """Bytes in MiB; ``—`` for none."""
    return "—" if b is None else f"{b / 2**20:,.0f} MiB"


def fmt_ratio(r: float | None) -> str:
    """A ratio as ``1.23×``; ``—`` for none."""
    return "—" if r is None else f"{r:.2f}×"


def verdict(ok: bool | None) -> str:
    """``ok`` / ``over`` beside a target, ``—`` without one."""
    return "—" if ok is None else ("ok" if ok else "over")


@dataclass
class Figure:
    """One row of a benchmark's table: a time beside its floor and target.

    ``time`` and ``floor`` are seconds; what ``time`` is (one run, a median of calls, a mean per vertex) each
    benchmark says under its table.
    """

    name: str
    backend: str
    time: float | None
    floor: float | None = None
    target: str = "—"
    verdict: str = "—"
    mesh: str = ""
    n: int | None = None  # timed calls behind a median
    p90: float | None = None
    cpu: float | None = None  # user + system time of the measuring process
    rss: int | None = None  # its peak RSS, bytes
    floor_parts: str = ""

    @classmethod
    def of_calls(cls, name: str, backend: str, samples: list[int], *, p90: bool = True, **fields) -> "Figure":
        """The figure of calls timed one by one: their median, with their count and (``p90``) their p90.

        Parameters
        ----------
        name, backend : str
            As the row shows them.
        samples : list of int
            Nanoseconds per call.
        p90 : bool
            Whether the p90 means anything (not for a handful of runs).
        **fields
            The other fields (``floor``, ``target``, ``verdict``, ``mesh``, ...).

        Returns
        -------
        Figure
        """
        return cls(name, backend, median(samples) / 1e9, n=len(samples),
                   p90=percentile(samples, 0.9) / 1e9 if p90 else None, **fields)

    @property
    def ratio(self) -> float | None:
        """``time`` ÷ ``floor``, None without a floor."""
        if self.time is None or not self.floor:
            return None
        return self.time / self.floor


def print_table(headers: list[str], rows: list[list[str]], align: str | None = None, out=sys.stdout) -> None:
    """A plain-text table; ``align`` has one 'l' or 'r' per column."""
    align = align or "l" * len(headers)
    widths = [max(len(str(x)) for x in col) for col in zip(headers, *rows)]

    def line(cells):
        return "  ".join(
            (str(c).ljust(w) if a == "l" else str(c).rjust(w)) for c, w, a in zip(cells, widths, align)
        ).rstrip()

    print(line(headers), file=out)
    print("  ".join("-" * w for w in widths), file=out)
    for r in rows:
        print(line(r), file=out)
    out.flush()


# (header, alignment, cell, optional): optional columns are printed only when some figure has a value.
_COLUMNS = [
    ("figure", "l", lambda f: f.name, False),
    ("mesh", "r", lambda f: f.mesh, True),
    ("backend", "l", lambda f: f.backend, False),
    ("n", "r", lambda f: "" if f.n is None else f"{f.n:,}", True),
    ("time", "r", lambda f: fmt_time(f.time), False),
    ("p90", "r", lambda f: "" if f.p90 is None else fmt_time(f.p90), True),
    ("its CPU", "r", lambda f: "" if f.cpu is None else fmt_time(f.cpu), True),
    ("floor", "r", lambda f: fmt_time(f.floor), False),
    ("ratio", "r", lambda f: fmt_ratio(f.ratio), False),
    ("target", "l", lambda f: f.target, False),
    ("peak RSS", "r", lambda f: "" if f.rss is None else fmt_mib(f.rss), True),
    ("verdict", "l", lambda f: f.verdict, False),
]


def _columns(figures: list[Figure]):
    return [c for c in _COLUMNS if not c[3] or any(c[2](f) for f in figures)]


def print_figures(figures: list[Figure]) -> None:
    """The figures table (ratio = time ÷ floor), then each floor's parts where it has some."""
    cols = _columns(figures)
    print_table([c[0] for c in cols], [[c[2](f) or "—" for c in cols] for f in figures], "".join(c[1] for c in cols))
    parts = [[f.name, f.mesh, f.backend, f.floor_parts] for f in figures if f.floor_parts]
    if parts:
        print()
        print("Floor parts (seconds):")
        print_table(["figure", "mesh", "backend", "floor ="], parts, "lrll")


def print_markdown(figures: list[Figure]) -> None:
    """The same figures as a markdown table, the floor's parts beside it."""
    cols = _columns(figures)
    heads = [c[0] for c in cols]
    print()
    print("| " + " | ".join(heads) + " |")
    print("|" + "|".join("---:" if a == "r" else "---" for _, a, _, _ in cols) + "|")
    for f in figures:
        cells = []
        for head, _, cell, _ in cols:
            text = cell(f) or "—"
            if head == "floor" and f.floor_parts:
                text = f"{text} = {f.floor_parts}" if f.floor else f.floor_parts
            cells.append(text)
        print("| " + " | ".join(cells) + " |")
