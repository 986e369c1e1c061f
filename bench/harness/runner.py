"""Each step of a benchmark in a fresh process, so that each figure has its own peak RSS and nothing cached
carries over from one step to the next.

The parent side, `Runner`, is held by `harness.bench.Bench`; the benchmark scripts call ``bench.runner.run(
job=..., **spec)``, which runs ``python <script> --child SPEC_JSON`` and reads back the JSON the child wrote.
The child side is `child_main`, which `harness.cli.Parser.parse_args` calls when ``--child`` is given, with the
script's table of jobs; a job timing a one-shot figure calls `one_shot`. `run_command` also runs whole
benchmarks for ``bench/all.py``; `log` writes the progress lines on stderr.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any, NoReturn

from harness.databases import settle
from harness.timing import maxrss, pc, timed


def log(msg: str) -> None:
    """A progress line on stderr (the figures go to stdout)."""
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def run_command(argv: list[str], timeout: float | None, *, quiet: bool = False) -> tuple[int | None, float]:
    """Run ``argv``, its stderr passed through, its stdout too unless ``quiet``.

    Returns
    -------
    status : int or None
        The exit status, None when it timed out.
    seconds : float
        How long it ran.
    """
    t0 = pc()
    try:
        proc = subprocess.run(argv, timeout=timeout, stdout=subprocess.DEVNULL if quiet else None)
    except subprocess.TimeoutExpired:
        return None, (pc() - t0) / 1e9
    return proc.returncode, (pc() - t0) / 1e9


class Runner:
    """Runs ``script --child SPEC_JSON`` in a fresh process per step; the child writes its result as JSON.

    Parameters
    ----------
    script : str
        The benchmark script.
    workdir : str
        The run's work folder, where the results are written (and, passed on in the spec, the step's files).
    timeout : float
        Seconds allowed per step.
    errors : list of str
        Where a failed or timed-out step is reported (the run's problems).
    """

    def __init__(self, script: str, workdir: str, timeout: float, errors: list[str]) -> None:
        self.script = os.path.abspath(script)
        self.workdir = workdir
        self.timeout = timeout
        self.errors = errors
        self._k = 0

    def run(self, **spec) -> dict | None:
        """One step, ``job`` and the rest of its spec as keywords: its result, or None when it failed."""
        self._k += 1
        spec["result"] = os.path.join(self.workdir, f"result-{self._k}.json")
        spec["workdir"] = self.workdir
        keys = ("job", "backend", "mesh", "fmt", "kind", "what", "variant")
        what = " ".join(str(spec[k]) for k in keys if spec.get(k))
        if spec.get("profile"):
            what += " (under cProfile)"
        status, seconds = run_command([sys.executable, self.script, "--child", json.dumps(spec)], self.timeout,
                                      quiet=True)
        if status is None:
            self.errors.append(f"{what}: timed out after {self.timeout:.0f} s")
            log(self.errors[-1])
            return None
        if status != 0 or not os.path.exists(spec["result"]):
            self.errors.append(f"{what}: the child process failed (exit {status}; its traceback is above)")
            log(self.errors[-1])
            return None
        with open(spec["result"]) as f:
            result = json.load(f)
        os.remove(spec["result"])
        log(f"{what}: done in {seconds:.1f} s")
        return result


def child_main(jobs: dict[str, Callable[[dict], dict]], spec_json: str) -> NoReturn:
    """The child side of `Runner.run`: run ``jobs[spec["job"]](spec)``, write its result, exit.

    Called by `harness.cli.Parser.parse_args` when the benchmark script was started with ``--child``.

    The process ends with ``os._exit``: a job may leave gigabytes of Python objects (a networkx graph) that the
    interpreter would otherwise free one by one on the way out, for nothing.
    """
    spec = json.loads(spec_json)
    result = jobs[spec["job"]](spec)
    with open(spec["result"], "w") as f:
        json.dump(result, f)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def one_shot(spec: dict, fn: Callable[[], Any], *, profile: bool = False, lines: int = 20) -> tuple[Any, dict]:
    """A one-shot figure in a step: `settle` the step's database, then ``fn()`` timed once.

    Parameters
    ----------
    spec : dict
        The step's spec.
    fn : callable
        The timed run, without arguments.
    profile : bool
        Whether to run it under cProfile.
    lines : int
        Functions listed in the profile.

    Returns
    -------
    result
        What ``fn()`` returned.
    fields : dict
        The figure's part of the step's result: ``seconds``, ``cpu``, ``rss`` (this process's peak RSS after the
        run) and ``rss_before``, ``profile`` and ``dominant`` (None without a profile).
    """
    settle(spec)
    rss0 = maxrss()
    run = timed(fn, profile=profile, lines=lines)
    return run.result, {"seconds": run.seconds, "cpu": run.cpu, "rss": maxrss(), "rss_before": rss0,
                        "profile": run.profile, "dominant": run.dominant}
