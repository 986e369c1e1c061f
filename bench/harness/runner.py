"""Each step of a benchmark in a process of its own, so that nothing cached carries over from one step to the next
and (in a full run) each figure has its own peak RSS.

The parent side, `Runner`, is held by `harness.bench.Bench`; the benchmark scripts call ``bench.runner.run(
job=..., **spec)`` and read back the JSON the step wrote. In a full run a step is a fresh interpreter, ``python
<script> --child SPEC_JSON``, whose `harness.cli.Parser.parse_args` calls `child_main` with the script's table of
jobs: cold caches, and a peak RSS that is the step's alone. In a ``--quick`` run (a smoke test, whose figures
matter only as far as they are printed) a step is a child forked from the benchmark's own process, which has
already imported the script and its libraries, saving the interpreter's start and those imports (about a second
a step); its peak RSS starts from the parent's (`Runner.process` names the kind for the report). Both kinds run
the step through `run_step`. A job timing a one-shot figure calls `one_shot`. `run_command` also runs whole
benchmarks for ``bench/all.py``; `log` writes the progress lines on stderr.
"""

from __future__ import annotations

import gc
import json
import os
import signal
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from typing import Any, NoReturn

from harness.databases import settle
from harness.timing import maxrss, pc, timed

#: The report's note in a run whose steps were forked.
FORKED_NOTE = ("--quick: each step ran in a process forked from the benchmark's own (its libraries already "
               "imported), not a fresh interpreter, so a step's peak RSS starts from that process's")


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
    """Runs each step in a process of its own, a fresh interpreter or (given ``jobs``) a fork of this process;
    the step writes its result as JSON.

    Parameters
    ----------
    script : str
        The benchmark script, whose ``--child SPEC_JSON`` runs a step in a fresh interpreter.
    workdir : str
        The run's work folder, where the results are written (and, passed on in the spec, the step's files).
    timeout : float
        Seconds allowed per step.
    errors : list of str
        Where a failed or timed-out step is reported (the run's problems).
    jobs : dict, optional
        The script's table of jobs (`harness.cli.Parser`'s ``jobs``), given in a ``--quick`` run: each step then
        runs ``jobs[spec["job"]]`` in a child forked from this process, where ``os.fork`` exists (else in a fresh
        interpreter, as without it).

    Attributes
    ----------
    forks : bool
        Whether the steps are forked.
    process : str
        What a step runs in, for the report's titles: ``"fresh process"`` or ``"forked process"``.
    """

    def __init__(self, script: str, workdir: str, timeout: float, errors: list[str], *,
                 jobs: dict[str, Callable[[dict], dict]] | None = None) -> None:
        self.script = os.path.abspath(script)
        self.workdir = workdir
        self.timeout = timeout
        self.errors = errors
        self.jobs = jobs
        self.forks = jobs is not None and hasattr(os, "fork")
        self.process = "forked process" if self.forks else "fresh process"
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
        if self.forks:
            status, seconds = self._fork(spec)
        else:
            status, seconds = run_command([sys.executable, self.script, "--child", json.dumps(spec)],
                                          self.timeout, quiet=True)
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

    def _fork(self, spec: dict) -> tuple[int | None, float]:
        """Run the step in a forked child, as `run_command` runs a fresh one: its exit status (None when it timed
        out and was killed) and how long it ran."""
        t0 = pc()
        # Output still buffered here would be written twice, by the parent and again by the child.
        sys.stdout.flush()
        sys.stderr.flush()
        # The parent's objects frozen, the child's collector never finalizes one of them (a connection it would
        # close on the parent's behalf); the parent's collector takes them back after the fork.
        gc.freeze()
        try:
            pid = os.fork()
            if pid == 0:
                run_step(self.jobs, spec, quiet=True)  # never returns
        finally:
            gc.unfreeze()
        deadline = time.monotonic() + self.timeout
        pause = 0.001
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                return os.waitstatus_to_exitcode(status), (pc() - t0) / 1e9
            if time.monotonic() >= deadline:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                return None, (pc() - t0) / 1e9
            time.sleep(pause)
            pause = min(2 * pause, 0.02)


def child_main(jobs: dict[str, Callable[[dict], dict]], spec_json: str) -> NoReturn:
    """The step of a fresh interpreter started by `Runner.run` (``--child SPEC_JSON``): `run_step`.

    Called by `harness.cli.Parser.parse_args` when the benchmark script was started with ``--child``.
    """
    run_step(jobs, json.loads(spec_json))


def run_step(jobs: dict[str, Callable[[dict], dict]], spec: dict, *, quiet: bool = False) -> NoReturn:
    """The child side of `Runner.run`, in a fresh interpreter or a forked child: run ``jobs[spec["job"]](spec)``,
    write its result as JSON to ``spec["result"]``, end the process.

    Parameters
    ----------
    jobs : dict
        The script's table of jobs.
    spec : dict
        The step's spec.
    quiet : bool
        Whether to discard the step's stdout (a fresh interpreter's is discarded by `run_command`).

    Notes
    -----
    The process ends with ``os._exit``, status 0, or 1 after the traceback of an exception on stderr: a forked
    child must not run the parent's atexit handlers and finalizers (the temporary work folder removed, the
    parent's connections closed), and a job may leave gigabytes of Python objects (a networkx graph) that the
    interpreter would otherwise free one by one on the way out, for nothing.
    """
    status = 1
    try:
        if quiet:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.close(devnull)
        result = jobs[spec["job"]](spec)
        with open(spec["result"], "w") as f:
            json.dump(result, f)
        status = 0
    except BaseException:
        traceback.print_exc()
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(status)


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
