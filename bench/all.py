"""Run every benchmark, one after the other (SPEC §9).

    python bench/all.py [--quick] [--benchmarks edits,import,graph,reads,properties,euler,repair,history]
                        [--backends sqlite,postgresql]

Each benchmark runs in its own process (``python bench/<name>.py``), never two
at once, with ``--quick`` and the common options (``--backends``,
``--pg-url``, ``--workdir``; ``--meshes-dir`` for the benchmarks that read
the shared meshes) passed on. Their output goes straight through; a summary
of exit statuses and times ends it. The exit status is non-zero when any
benchmark's is (a failed correctness gate or a crash, never a slow figure).

Run by hand (``tests/test_bench.py`` runs it with ``--quick --benchmarks
edits``). It owns only the order of the benchmarks and what it passes on;
the options, the subprocess runner and the summary table are the harness's
(``bench/harness/``).
"""

from __future__ import annotations

import os
import sys
import time

from harness.cli import Parser, meshes_dir
from harness.runner import log, run_command
from harness.tables import print_table

HERE = os.path.dirname(os.path.abspath(__file__))
BENCHMARKS = ("edits", "import", "graph", "reads", "properties", "euler", "repair", "history")
TAKES_MESHES = ("import", "graph", "repair")  # the benchmarks that take --meshes-dir


def main(argv=None) -> int:
    ap = Parser(__doc__, quick={}, workdir_help="passed on: where the benchmarks put their SQLite files")
    ap.add_argument("--benchmarks", default=",".join(BENCHMARKS),
                    help=f"which to run, in this order: {', '.join(BENCHMARKS)} (default all)")
    ap.add_argument("--meshes-dir", default=meshes_dir(), help=f"passed on to {', '.join(TAKES_MESHES)}")
    ap.add_argument("--timeout", type=float, default=None, help="seconds allowed per benchmark (default: no limit)")
    args = ap.parse_args(argv)
    chosen = ap.names(args.benchmarks, BENCHMARKS, "benchmark")

    common = ["--backends", ",".join(args.backends), "--pg-url", args.pg_url]
    if args.quick:
        common.append("--quick")
    if args.workdir:
        common += ["--workdir", args.workdir]
    rows, failed = [], 0
    t_start = time.perf_counter()
    for name in BENCHMARKS:
        if name not in chosen:
            continue
        argv_b = [sys.executable, os.path.join(HERE, f"{name}.py"), *common]
        if name in TAKES_MESHES:
            argv_b += ["--meshes-dir", args.meshes_dir]
        log(f"all: {name}.py {' '.join(argv_b[2:])}")
        print(f"\n{'=' * 30} bench/{name}.py {'=' * 30}", flush=True)
        status, seconds = run_command(argv_b, args.timeout)
        failed += status != 0
        rows.append([f"bench/{name}.py", "timed out" if status is None else str(status), f"{seconds:.1f} s"])
    print()
    print(f"Benchmarks run{' (--quick)' if args.quick else ''}, in {(time.perf_counter() - t_start) / 60:.1f} min:")
    print_table(["benchmark", "exit status", "wall time"], rows, "lrr")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
