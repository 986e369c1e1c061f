"""The options every benchmark takes, and ``--quick``.

Called by each benchmark script's ``main`` (and by ``bench/all.py``), which builds a `Parser` with the option
groups it needs and then adds its own options. `Parser.parse_args` turns ``--backends`` (and ``--only``) into
lists, checked against what exists, and in a step's process (``--child``) runs the step instead of returning;
`at_least` and `cells` are argparse types for counts and ``WxH`` sizes; `wants_profile` reads ``--profile``.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

from harness.runner import child_main

DEFAULT_PG_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
BACKENDS = ("sqlite", "postgresql")
WORKDIR_HELP = "where SQLite files go (default: a temporary folder, removed at the end)"
PROFILE_HELP = "profile hestore in a separate run when a figure is over target (default), always, or never"
_BENCH = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def meshes_dir() -> str:
    """Where the shared large meshes are read from: ``$HESTORE_BENCH_MESHES``, else ``../shared/meshes`` next to
    the repository."""
    env = os.environ.get("HESTORE_BENCH_MESHES")
    if env:
        return env
    return os.path.normpath(os.path.join(_BENCH, "..", "..", "shared", "meshes"))


class Parser(argparse.ArgumentParser):
    """The options every benchmark takes; ``--quick`` sets the benchmark's smoke-run defaults.

    Options given explicitly win over ``--quick``'s. The option groups a benchmark asks for: ``grid``
    (``--n``), ``meshes`` (``--only`` among these names, ``--meshes-dir``), ``jobs`` (``--timeout``, and the
    hidden ``--child`` that `harness.runner.Runner` passes, and ``jobs`` itself, in the parsed options for
    `harness.bench.Bench` to hand to its runner), ``profile`` (``--profile``), ``seed``.

    Parameters
    ----------
    doc : str
        The benchmark's module docstring: its first paragraph is the description.
    quick : dict
        The smoke run's option values, by destination name.
    workdir_help : str
        What ``--workdir`` holds in this benchmark (default: SQLite files).
    jobs : dict, optional
        The benchmark's steps by name, each run in a process of its own (`harness.runner`): a fresh interpreter,
        or with ``--quick`` a fork of the benchmark's process.
    profile : bool or str
        Whether the benchmark takes ``--profile``; a string is its help text.
    """

    def __init__(self, doc: str, *, quick: dict, workdir_help: str = WORKDIR_HELP, grid: int | None = None,
                 meshes: tuple[str, ...] = (), jobs: dict[str, Callable[[dict], dict]] | None = None,
                 profile: bool | str = False, seed: int | None = None) -> None:
        super().__init__(description=doc.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
        self.quick = quick
        self.meshes = meshes
        self.jobs = jobs
        smoke = " ".join(f"--{k.replace('_', '-')} {v}" for k, v in quick.items()) or "each benchmark's own"
        forked = ", each step forked from this process instead of a fresh interpreter" if jobs is not None else ""
        self.add_argument("--quick", action="store_true", help=f"a smoke run of small sizes: {smoke}{forked}")
        self.add_argument("--backends", default=",".join(BACKENDS), help="sqlite and/or postgresql (default both)")
        self.add_argument("--pg-url", default=os.environ.get("HESTORE_BENCH_PG_URL", DEFAULT_PG_URL),
                          help="PostgreSQL server to use; a database is created there for the run and dropped at "
                               "the end (default $HESTORE_BENCH_PG_URL, else %(default)s)")
        self.add_argument("--workdir", help=workdir_help)
        if grid is not None:
            self.add_argument("--n", type=int, default=grid,
                              help=f"grid vertices per side (default {grid}: {2 * (grid - 1) ** 2:,} triangles)")
        if meshes:
            self.add_argument("--only", default=",".join(meshes),
                              help=f"meshes to run: {', '.join(meshes)} (default all)")
            self.add_argument("--meshes-dir", default=meshes_dir(),
                              help="folder of the shared mesh files (default $HESTORE_BENCH_MESHES, else "
                                   "../shared/meshes)")
        if profile:
            self.add_argument("--profile", choices=("over", "all", "off"), default="over",
                              help=PROFILE_HELP if profile is True else profile)
        if seed is not None:
            self.add_argument("--seed", type=int, default=seed, help="random seed (default %(default)s)")
        if jobs is not None:
            self.add_argument("--timeout", type=float, default=1800, help="seconds allowed per step (default 1800)")
            self.add_argument("--child", help=argparse.SUPPRESS)
            self.set_defaults(jobs=jobs)

    def parse_args(self, args=None, namespace=None):
        """Parse the command line with ``--quick``'s defaults when it is given; ``backends`` (and ``only``)
        become lists of names.

        In a step's process (``--child SPEC``, from `harness.runner.Runner`) this runs the step's job and ends
        the process instead of returning, so that a benchmark's ``main`` is only ever its parent side.
        """
        argv = sys.argv[1:] if args is None else list(args)
        if "--quick" in argv:
            self.set_defaults(**self.quick)
        parsed = super().parse_args(argv, namespace)
        if self.jobs is not None and parsed.child:
            child_main(self.jobs, parsed.child)
        if getattr(parsed, "n", 2) < 2:
            self.error("--n must be at least 2")
        parsed.backends = self.names(parsed.backends, BACKENDS, "backend")
        if self.meshes:
            parsed.only = self.names(parsed.only, self.meshes, "mesh")
        return parsed

    def names(self, text: str, choices: tuple[str, ...], what: str) -> list[str]:
        """A comma-separated list of names, each one of ``choices`` (else the usage error names ``what``)."""
        names = [x.strip() for x in text.split(",") if x.strip()]
        for x in names:
            if x not in choices:
                self.error(f"unknown {what} {x!r} (choose from {', '.join(choices)})")
        return names


def at_least(minimum: int) -> Callable[[str], int]:
    """An argparse ``type``: a whole number no smaller than ``minimum`` (a count of runs, calls, vertices)."""

    def count(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, not {value}")
        return value

    return count


def cells(text: str) -> tuple[int, int]:
    """A grid size in cells, ``"50x100"`` → (50, 100): an argparse ``type`` for ``--small``."""
    try:
        w, h = (int(x) for x in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--small takes WxH cells, such as 50x100, not {text!r}") from None
    if w < 2 or h < 2:
        raise argparse.ArgumentTypeError("--small needs at least 2x2 cells")
    return w, h


def wants_profile(args: argparse.Namespace, over: bool) -> bool:
    """Whether to rerun a figure under cProfile: always with ``--profile all``, when ``over`` its target with
    ``--profile over``."""
    return args.profile == "all" or (args.profile == "over" and over)
