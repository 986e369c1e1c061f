"""One run of a benchmark in its parent process: the work folder, the runner of its steps, each backend in turn,
the report and the exit status.

Called by each benchmark script's ``main`` after parsing its options::

    with Bench(args, "reads", __file__) as bench:
        for place in bench.for_each_backend():
            spec = place.fresh("reads_grid")
            result = bench.runner.run(job="setup", **spec)
            ...
    report(bench, ...)          # the script's figures, through bench.report
    return bench.finish()       # machine notes; 1 when a gate failed or a step crashed

The exit status is non-zero only for a problem (a failed correctness gate or a crashed step), never for a slow
figure.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import tempfile
import time
from collections.abc import Iterator

from harness.databases import Place, open_backend
from harness.report import Report, print_machine
from harness.runner import FORKED_NOTE, Runner


class Bench:
    """One run of a benchmark: where its files go, how its steps run, and what it reports.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options (`harness.cli.Parser`): ``backends``, ``pg_url``, ``workdir``, ``quick`` and, for a
        benchmark whose steps run in processes of their own, ``timeout`` and ``jobs`` (its table of jobs, which
        the runner forks in a ``--quick`` run).
    name : str
        The benchmark's name, for the temporary work folder.
    script : str, optional
        The benchmark script, whose ``--child`` runs the steps; without it there is no `runner`.
    clean : tuple of str
        Prefixes of the files removed from a work folder given with ``--workdir`` at the end (a temporary one
        is removed whole).

    Attributes
    ----------
    workdir : str
    runner : harness.runner.Runner or None
        Reports failed steps in ``report.problems``; when it forks the steps, ``report.notes`` says so.
    report : harness.report.Report
    """

    def __init__(self, args: argparse.Namespace, name: str, script: str | None = None, *,
                 clean: tuple[str, ...] = ()) -> None:
        self.args = args
        self.report = Report()
        self._own = args.workdir is None
        self._clean = clean
        self.workdir = args.workdir or tempfile.mkdtemp(prefix=f"hestore_bench_{name}_")
        os.makedirs(self.workdir, exist_ok=True)
        self.runner = None
        if script:
            self.runner = Runner(script, self.workdir, args.timeout, self.report.problems,
                                 jobs=args.jobs if args.quick else None)
            if self.runner.forks:
                self.report.notes.append(FORKED_NOTE)
        self.pg_version: str | None = None
        self._load_start = os.getloadavg()
        self._t0 = time.perf_counter()

    def __enter__(self) -> "Bench":
        return self

    def __exit__(self, *exc) -> None:
        if self._own:
            shutil.rmtree(self.workdir, ignore_errors=True)
            return
        for name in os.listdir(self.workdir) if self._clean else ():
            if name.startswith(self._clean):
                with contextlib.suppress(OSError):
                    os.remove(os.path.join(self.workdir, name))

    def for_each_backend(self) -> Iterator[Place]:
        """The `Place` of each backend of ``--backends`` in turn, closed (its PostgreSQL database dropped) after
        the loop's body; a backend that cannot be reached is skipped, and ``report.skipped`` says why."""
        for backend in self.args.backends:
            with open_backend(backend, self.workdir, self.args.pg_url, self.report.skipped) as place:
                if place is None:
                    continue
                self.pg_version = place.version or self.pg_version
                yield place

    def finish(self, *, meshes: str | None = None, libraries: str = "") -> int:
        """Print the machine notes; the exit status: 1 when the report has a problem, else 0."""
        print_machine(self.pg_version, self._load_start, time.perf_counter() - self._t0, meshes=meshes,
                      libraries=libraries)
        return 1 if self.report.problems else 0
