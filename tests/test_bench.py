"""Smoke test of the benchmarks in ``bench/``: each runs in its quickest mode and prints its tables.

Every benchmark runs with ``--quick`` in a subprocess, on SQLite and on
PostgreSQL (the server of ``$HESTORE_TEST_PG_URL``, through the
``pg_database`` fixture, so it is skipped where there is none and fails under
``CI=true``), and must exit 0, print its table headers for both backends, and
report no problem. Timings are not looked at, and nothing here depends on how
long a run takes (a minute or two in all on a quiet machine).
"""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

from meshes import require_shared_meshes, shared_meshes

BENCH = pathlib.Path(__file__).resolve().parents[1] / "bench"
FIGURES_HEADER = ("figure", "backend", "time", "floor", "ratio", "target", "verdict")
MARKDOWN_HEADER = "| figure | mesh | backend |"
#: A header of each benchmark's own tables.
OWN_HEADER = {
    "edits": "Growth with the mesh",
    "import": "Floors, every variant measured",
    "graph": "Graph floors, every variant",
    "reads": "The floor's query plan",
    "properties": "Floor variants, every one measured",
    "euler": "Flat in mesh size",
    "repair": "Repair decisions alone",
    "history": "Proportional to the changes since r",
}
#: The benchmarks that take ``--meshes-dir``; those that need the shared meshes even with ``--quick`` (repair reads
#: small stand-ins of its files) are skipped where the meshes are missing, and fail under ``CI=true``.
TAKES_MESHES = ("import", "graph", "repair")
NEEDS_MESHES = ("repair",)


#: Only a guard against a benchmark that hangs, never a limit on how fast it runs: a test asserts behaviour, not
#: that something was fast enough, and a quick run that takes a minute on a quiet machine took over 300 s (the old
#: limit) on a busy one. An hour is far beyond any quick run, however loaded the machine.
HANG = 3600


def run(script: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(BENCH / script), "--quick", *args], capture_output=True, text=True,
                          timeout=HANG)


def meshes_args(name: str) -> list[str]:
    folder = require_shared_meshes() if name in NEEDS_MESHES else shared_meshes()
    return ["--meshes-dir", str(folder)] if folder is not None and name in TAKES_MESHES else []


@pytest.mark.postgresql
@pytest.mark.parametrize("name", sorted(OWN_HEADER))
def test_benchmark_quick_run(name, pg_database):
    url = pg_database.render_as_string(hide_password=False)
    done = run(f"{name}.py", "--pg-url", url, *meshes_args(name))
    out = done.stdout
    assert done.returncode == 0, out[-3000:] + done.stderr[-3000:]
    header = next((line for line in out.splitlines() if line.startswith("figure ")), None)
    assert header is not None, out[-3000:]
    assert all(word in header for word in FIGURES_HEADER), header
    assert MARKDOWN_HEADER in out
    assert OWN_HEADER[name] in out
    rows = [line.split() for line in out.splitlines() if line.startswith("|")]
    assert {"sqlite", "postgresql"} <= {cell for row in rows for cell in row}, "a backend is missing"
    assert "SKIPPED" not in out and "PROBLEM" not in out, out[-3000:]
    assert "Machine:" in out


def test_all_runs_the_chosen_benchmarks():
    done = run("all.py", "--benchmarks", "edits", "--backends", "sqlite")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert OWN_HEADER["edits"] in done.stdout and OWN_HEADER["reads"] not in done.stdout
    assert "bench/edits.py" in done.stdout.splitlines()[-1]
