"""What the benchmarks learn about where hestore spends a figure's time: cProfile reports, and counts of the SQL
statements hestore sends.

Called by `harness.timing.timed` (a run under cProfile) and by the benchmark scripts' steps, which rerun a
figure over its target under cProfile and count statements in untimed passes (a callback per statement would
be timed with the figure). The reports are printed by `harness.report.Report`.
"""

from __future__ import annotations

import contextlib
import cProfile
import io
import os
import pstats
from collections import Counter

from harness.tables import fmt_time


def profile_report(profiler: cProfile.Profile, lines: int = 20) -> tuple[str, str]:
    """A finished profile as text, and a line naming where the time went.

    Parameters
    ----------
    profiler : cProfile.Profile
        The profile, disabled.
    lines : int
        Functions listed, by own time and by cumulative time.

    Returns
    -------
    text : str
        The top ``lines`` functions by own time, then by cumulative time.
    dominant : str
        The function with the most own time, and hestore's functions by time with callees.
    """
    raw = pstats.Stats(profiler)
    ours = f"{os.sep}hestore{os.sep}"
    mine = sorted(((row[3], f"{func} ({os.path.basename(file)}:{line})")
                   for (file, line, func), row in raw.stats.items() if ours in file), reverse=True)
    buf = io.StringIO()
    stats = pstats.Stats(profiler, stream=buf).strip_dirs()
    stats.sort_stats("tottime").print_stats(lines)
    stats.sort_stats("cumulative").print_stats(lines)
    (file, line, func), row = max(stats.stats.items(), key=lambda kv: kv[1][2])
    heaviest = ", ".join(f"{name} {fmt_time(t)}" for t, name in mine[:5])
    dominant = (f"{func} ({file}:{line}): {fmt_time(row[2])} of its own time, {fmt_time(row[3])} with callees; "
                f"hestore's functions by time with callees: {heaviest}")
    return buf.getvalue(), dominant


def first_word(sql: str) -> str:
    """A statement's first word, upper case: SELECT, INSERT, BEGIN, ..."""
    return sql.lstrip().split(None, 1)[0].upper()


class Statements:
    """Counts the statements hestore sends on its driver cursor: install with ``store.session.traced(counter)``
    (or `traced`).

    ``by_kind`` counts them by kind (`KINDS`, transaction control as TXN), ``by_word`` by their first word. The
    callback sees the SQL text only: an ``executemany`` counts as one statement, and how many parameter sets
    (rows) it carried is not known.
    """

    KINDS = ("SELECT", "INSERT", "UPDATE", "DELETE", "TXN")

    def __init__(self) -> None:
        self.by_kind: Counter = Counter()
        self.by_word: Counter = Counter()

    def __call__(self, sql: str) -> None:
        word = first_word(sql)
        self.by_word[word] += 1
        if word in ("WITH", "(SELECT"):
            word = "SELECT"
        self.by_kind[word if word in self.KINDS else "TXN"] += 1  # TXN: BEGIN, COMMIT, SAVEPOINT, RELEASE, ...

    def snapshot(self) -> Counter:
        """The counts by kind so far, to subtract from a later snapshot."""
        return Counter(self.by_kind)

    @classmethod
    def per(cls, counts: dict, n: float = 1, unit: str = " statements") -> str:
        """Counts by kind per operation, as ``"12 statements: SELECT 4, INSERT 6, TXN 2"``.

        Parameters
        ----------
        counts : dict
            Statements by kind, over ``n`` operations.
        n : float
            The operations counted.
        unit : str
            What follows the total (``""`` for a bare number).

        Returns
        -------
        str
        """
        parts = [f"{k} {counts[k] / n:.3g}" for k in cls.KINDS if counts.get(k)]
        return f"{sum(counts.values()) / n:.3g}{unit}: " + ", ".join(parts)

    @staticmethod
    def per_word(counts: dict, n: int) -> str:
        """Counts by first word per operation, as ``"BEGIN 1, COMMIT 1, UPDATE 1"`` (``"none"`` without)."""
        return ", ".join(f"{k} {c / n:g}" for k, c in sorted(counts.items())) or "none"


def traced(store, counter: Statements | None):
    """``store.session.traced(counter)``, or nothing without a counter: for code that counts in one pass only."""
    return store.session.traced(counter) if counter else contextlib.nullcontext()
