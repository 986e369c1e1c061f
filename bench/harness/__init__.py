"""The harness hestore's benchmarks run on: timing, repeats and their statistics, parameters, steps in processes
of their own, the backends, and the report.

Each benchmark file in ``bench/`` (``edits.py``, ``reads.py``, ...) keeps its workloads, floors and targets and
hands everything else to this package, as networkx's asv benchmarks leave timing, parameters and reporting to
asv; ``bench/all.py`` uses it to run them one after the other. Nothing in hestore or its tests imports it.

Its modules, by topic (each says in its docstring who calls it):

* `harness.cli`: the options every benchmark takes, and ``--quick``; in a step's process, the step;
* `harness.bench`: one run of a benchmark in its parent process: the work folder, the runner, each backend in
  turn (`Bench.for_each_backend`), the exit status;
* `harness.runner`: each step in a process of its own, a fresh interpreter or, with ``--quick``, a fork of the
  benchmark's (`Runner`, `child_main`, `run_step`), and the one-shot figure a step times (`one_shot`);
* `harness.databases`: where a run's databases live (`Place`), plain-driver connections to them, and what a step
  does to them before a timed region;
* `harness.timing`: clocks, loops timed call by call, one-shot timing, peak RSS and CPU time;
* `harness.stats`: the repeats of a figure and their medians and percentiles;
* `harness.profiling`: cProfile reports and counts of the statements hestore sends;
* `harness.tables`: `Figure` (one row: a time beside its floor and target) and the tables that print figures;
* `harness.report`: `Report` (the tables, notes, skipped parts, problems and profiles of a run) and the machine
  notes that end every output.

The benchmark scripts run as ``python bench/<name>.py``, so ``bench/`` is the first entry of ``sys.path`` and
``import harness`` needs no path set-up, in the parent and in every fresh child step alike.
"""
