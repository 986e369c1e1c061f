"""Progress on a terminal: one reusable bar for long operations.

This module owns `ProgressBar`, the ``progress(stage, done, total)``
callable that long library calls (imports, exports) accept, and
`check_progress`, the check every such call makes of the one it is given.
The command line passes one for every long command; a program can pass its
own, or any callable with that signature.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from typing import TextIO

from hestore.errors import InvalidInputError

__all__ = ["ProgressBar", "silent", "check_progress"]


def _isatty(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def _columns(stream: TextIO) -> int:
    """The width of the terminal behind ``stream`` (80 when it cannot be told)."""
    try:
        return os.get_terminal_size(stream.fileno()).columns or 80
    except (AttributeError, ValueError, OSError):  # no file descriptor, or not a terminal
        return 80


def _amount(n: int, unit: str | None) -> str:
    """``n`` in ``unit``, for people: bytes in B/KiB/MiB/GiB, anything else counted."""
    if unit == "bytes":
        if n < 1024:
            return f"{n} B"
        value = float(n)
        for prefix in "KMGT":
            value /= 1024
            if value < 1024 or prefix == "T":
                return f"{value:.1f} {prefix}iB"
    return f"{n:,} {unit}" if unit else ""


def _progress_amount(done: int, total: int, unit: str) -> str:
    """``done`` of ``total``, e.g. ``1.2 MiB of 4.9 MiB`` or ``1,000 of 20,000 rows``."""
    if unit == "bytes":
        return f"{_amount(done, unit)} of {_amount(total, unit)}"
    return f"{done:,} of {_amount(total, unit)}"


def silent(stage: str, done: int, total: int) -> None:
    """A ``progress(stage, done, total)`` that shows nothing: what a long call reports to when given none.

    >>> silent("read", 1, 2)
    """


def check_progress(progress: object) -> Callable:
    """What a long call reports to: ``progress`` if it is callable, `silent` for None.

    Checked before the call does anything, so that a wrong argument is not
    found only at the first report, half-way through; and never asked for
    its truth value, which a callable object may refuse.

    Examples
    --------
    >>> check_progress(None) is silent, check_progress(print) is print
    (True, True)
    >>> check_progress("bar")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: progress is a callable progress(stage, done, total) or None, not str
    """
    if progress is None:
        return silent
    if callable(progress):
        return progress
    raise InvalidInputError(
        f"progress is a callable progress(stage, done, total) or None, not {type(progress).__name__}"
    )


class ProgressBar:
    """A one-line progress display, called as ``progress(stage, done, total)``.

    On a terminal it redraws one line in place (with ``\\r``), at most once
    per ``interval`` seconds: the stage, a bar, the percentage and the amount
    done (``units`` names each stage's unit; ``"bytes"`` is shown in
    KiB/MiB/GiB, a stage without a unit shows only the percentage). Anywhere
    else (a pipe, a log file) it draws nothing while running, so the output
    holds no control characters. Either way, `close` after success writes one
    plain line: each stage with its amount and time. After a failure it
    erases the bar and writes nothing, so that the error stays one line.

    Use it as a context manager: leaving the block closes it, successfully
    unless an exception is leaving too.

    Parameters
    ----------
    stream : text stream, optional
        Where to draw; default ``sys.stderr``.
    units : dict, optional
        Stage name to unit (``{"read": "bytes", "write": "rows"}``).
    interval : float
        Least time between two redraws, in seconds.
    width : int
        Characters in the bar itself.
    clock : callable
        Returns the time in seconds (`time.monotonic`; tests pass a fake).
    min_seconds : float
        Show nothing, bar or final line, for an operation that ends sooner
        (for commands that are long only on large meshes: ``check``, ``info``).

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()  # not a terminal: one plain line at the end
    >>> with ProgressBar(out, units={"read": "bytes", "write": "rows"}, clock=lambda: 0.0) as bar:
    ...     bar("read", 2048, 4096)
    ...     bar("read", 4096, 4096)
    ...     bar("write", 12000, 12000)
    >>> out.getvalue()
    'read 4.0 KiB in 0.0 s, write 12,000 rows in 0.0 s\\n'
    """

    def __init__(
        self,
        stream: TextIO | None = None,
        *,
        units: dict[str, str] | None = None,
        interval: float = 0.1,
        width: int = 24,
        clock: Callable[[], float] = time.monotonic,
        min_seconds: float = 0.0,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.tty = _isatty(self.stream)
        self._columns = _columns(self.stream) if self.tty else 80
        self.units = dict(units or {})
        self.interval = interval
        self.width = width
        self.clock = clock
        self.min_seconds = min_seconds
        self._started = clock()
        # stage -> [done, total, time of its last call], in the order the stages began
        self._stages: dict[str, list] = {}
        self._stage: str | None = None
        self._drawn_at: float | None = None
        self._shown = 0  # characters of the line now on screen
        self._closed = False

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = self.clock()
        new_stage = stage != self._stage
        if new_stage:
            self._stage = stage
            self._stages.pop(stage, None)  # a stage that comes back starts over, at the end
        self._stages[stage] = [int(done), int(total), now]
        # A new stage is always shown (there are a few); within one, at most every `interval`.
        if now - self._started < self.min_seconds:
            return
        if self.tty and (new_stage or self._drawn_at is None or now - self._drawn_at >= self.interval):
            # Never wider than the terminal: a wrapped line cannot be redrawn in place.
            self._draw(self.line(stage, int(done), int(total))[: max(self._columns - 1, 1)])
            self._drawn_at = now

    def line(self, stage: str, done: int, total: int) -> str:
        """The bar as drawn on a terminal, e.g. ``read  [######..................]  25%  1.0 MiB of 4.0 MiB``."""
        done = min(max(done, 0), total) if total > 0 else done
        fraction = done / total if total > 0 else 1.0
        filled = int(fraction * self.width)
        text = f"{stage:<5} [{'#' * filled}{'.' * (self.width - filled)}] {int(fraction * 100):3d}%"
        unit = self.units.get(stage)
        if unit:
            text += "  " + _progress_amount(done, total, unit)
        return text

    def summary(self) -> str:
        """Each stage with its amount and time, e.g. ``read 4.0 KiB in 0.1 s, build in 0.2 s``.

        A stage's time runs from the previous stage's last call (or from the
        bar's creation) to its own last call.
        """
        parts = []
        since = self._started
        for stage, (done, _total, last) in self._stages.items():
            amount = _amount(done, self.units.get(stage))
            seconds = max(last - since, 0.0)
            parts.append(f"{stage} {amount} in {seconds:.1f} s" if amount else f"{stage} in {seconds:.1f} s")
            since = last
        return ", ".join(parts)

    def _draw(self, text: str) -> None:
        # Pad with spaces over what the previous line left on screen.
        self.stream.write("\r" + text + " " * max(0, self._shown - len(text)))
        self.stream.flush()
        self._shown = len(text)

    def close(self, ok: bool = True) -> None:
        """Finish: the plain final line after success, nothing (the bar erased) after a failure."""
        if self._closed:
            return
        self._closed = True
        if ok and self._stages and self.clock() - self._started >= self.min_seconds:
            if self.tty:
                self._draw(self.summary())
                self.stream.write("\n")
            else:
                self.stream.write(self.summary() + "\n")
        elif self.tty and self._shown:
            self._draw("")
            self.stream.write("\r")
        self.stream.flush()

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(ok=exc_type is None)
