"""What a benchmark run prints: its tables of figures and its own tables as it goes, then one tail that is the
same in every benchmark.

Called by each benchmark script's report code, through the `Report` its `harness.bench.Bench` holds; the
runner and the backends add to its ``problems`` and ``skipped`` during the run. The tail, in order: the profiles
of figures rerun under cProfile, "Correctness and notes:" (the notes, the benchmark's fixed remarks, each
``SKIPPED`` part and each ``PROBLEM``), and every figure again as one markdown table. `print_machine` prints
the machine notes that end every output.
"""

from __future__ import annotations

import contextlib
import os
import platform
import sqlite3

import numpy as np
import sqlalchemy as sa

import hestore
from harness.tables import Figure, print_figures, print_markdown, print_table
from harness.timing import maxrss


class Report:
    """The tables, notes, skipped parts, problems and profiles of one benchmark run.

    ``notes`` are lines under "Correctness and notes:"; ``skipped`` the parts not run and why (a mesh file
    missing, the PostgreSQL server not reachable); ``problems`` the failed correctness gates and steps, which
    make the exit status non-zero; ``profiles`` ``(title, heaviest function, cProfile text)`` of reruns under
    cProfile.
    """

    def __init__(self) -> None:
        self.notes: list[str] = []
        self.skipped: list[str] = []
        self.problems: list[str] = []
        self.profiles: list[tuple[str, str, str]] = []
        self._figures: list[Figure] = []

    def title(self, text: str) -> None:
        """The line that opens the benchmark's tables."""
        print()
        print(text)

    def figures(self, figures: list[Figure], caption: str = "", after: str = "") -> None:
        """A table of figures, with ``caption`` lines above it and ``after`` lines below (nothing without
        figures); the figures are kept for the markdown at the end."""
        if not figures:
            return
        print()
        _lines(caption)
        print_figures(figures)
        _lines(after)
        self._figures.extend(figures)

    def table(self, caption: str, headers: list[str], rows: list[list[str]], align: str) -> None:
        """One of the benchmark's own tables, with ``caption`` lines above it (nothing without rows)."""
        if not rows:
            return
        print()
        _lines(caption)
        print_table(headers, rows, align)

    def close(self, about: str, *, profiles: str = "Profiles:", rss: str = "") -> None:
        """The tail of the output.

        Parameters
        ----------
        about : str
            The benchmark's fixed remarks (what its gates check, how its floors run), printed after the notes.
        profiles : str
            The heading of the profiles (printed only when there are some).
        rss : str
            When given, a last note with this label and the peak RSS of this process.
        """
        if self.profiles:
            print()
            print(profiles)
            for title, dominant, text in self.profiles:
                print(f"  {title}")
                print(f"    heaviest: {dominant}")
                for line in text.splitlines():
                    print(f"    {line}")
        print()
        print("Correctness and notes:")
        for line in (*self.notes, *about.splitlines()):
            print(f"  {line}")
        for s in self.skipped:
            print(f"  SKIPPED {s}")
        for p in self.problems:
            print(f"  PROBLEM {p}")
        if rss:
            print(f"  {rss}: {maxrss() / 2**20:.0f} MiB")
        if self._figures:
            print_markdown(self._figures)


def _lines(text: str) -> None:
    for line in text.splitlines():
        print(line)


def print_machine(pg_version: str | None, load_start: tuple, elapsed: float, *, meshes: str | None = None,
                  libraries: str = "") -> None:
    """The machine notes that end a benchmark's output: CPUs, memory, load, database and library versions, the
    run's duration."""
    print()
    print("Machine:")
    cpu = ""
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    mem = ""
    with contextlib.suppress(OSError, ValueError, IndexError):
        with open("/proc/meminfo") as fh:
            mem = f"{int(fh.readline().split()[1]) / 2**20:.1f} GiB RAM"
    load_end = os.getloadavg()
    print(f"  {os.cpu_count()} CPUs ({cpu or platform.machine()}), {mem}, {platform.platform()}")
    print(f"  load average (1/5/15 min) {' '.join(f'{x:.2f}' for x in load_start)} at the start, "
          f"{' '.join(f'{x:.2f}' for x in load_end)} at the end")
    print(f"  SQLite {sqlite3.sqlite_version} (journal_mode=WAL, synchronous=NORMAL, cache_size=64 MiB, "
          "as hestore sets)")
    print(f"  PostgreSQL {pg_version or '— (not run)'}, on the same machine")
    try:
        import psycopg

        drivers = f"psycopg {psycopg.__version__}"
    except ImportError:
        drivers = "psycopg not installed"
    print(f"  hestore {hestore.__version__}, Python {platform.python_version()}, numpy {np.__version__}, "
          f"SQLAlchemy {sa.__version__}, {drivers}" + (f", {libraries}" if libraries else ""))
    print(f"  {'meshes from ' + meshes + '; ' if meshes else ''}whole run {elapsed / 60:.1f} min")
