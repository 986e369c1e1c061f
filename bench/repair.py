"""Benchmark: imports that repair their input (``on_error="split"``, ``orient=True``) against the plain import.

    python bench/repair.py [--backends sqlite,postgresql] [--only grid,bunny,igea] [--n 710] [--runs 3]
                           [--reversed 0.1] [--duplicates 1000] [--files large|small]

The requirement (issue 11): repairs are decided set-based on the arrays
before anything is written; a 1 M-face import with ``on_error="split"`` and
``orient=True`` stays within 1.5× of the plain import of the same file.

Meshes (``--only``), as ``bench/import.py`` has them:

grid    the triangulated N×N vertex grid (``--n``, default 710: 2·709² =
        1,005,362 triangles), its arrays made before the timed region,
        stored with ``store.import_arrays``;
bunny   ``stanford-bunny-subdiv2.obj`` (ASCII OBJ, 1.1 M triangles, boundary,
        unreferenced vertices), stored with ``store.import_file``;
igea    ``igea-subdiv1.ply`` (binary PLY, 1.07 M triangles, closed), stored
        with ``store.import_file``.

The files are read in place from ``$HESTORE_BENCH_MESHES``, else
``../shared/meshes`` next to the repository. ``--files small`` (``--quick``'s)
takes small stand-ins from the same folder instead: ``spot.obj`` (5,856
triangles, closed, with ``vt`` corners that become a half-edge ``uv``
property) and ``bob_small.ply`` (500 triangles, binary, closed).

With the grid comes a **broken grid**: the same grid with a random
``--reversed`` share (default 10 %) of its triangles reversed and
``--duplicates`` (default 1,000) of its interior triangles appended once more
at the end, their vertex triples repeated. The duplicates lie in cells three
apart, so no two share a vertex and each one's edges are all taken: each
becomes a triangle of its own on three copies of its vertices. Polygon 0 and
the duplicated triangles are never reversed, so ``orient`` must turn back
exactly the reversed ones. Drawn with ``--seed``.

Figures, each on a SQLite file and on PostgreSQL; every import runs in a
fresh process into a fresh database, commit included (and, on PostgreSQL, the
ANALYZE hestore runs after it); before it, ``os.sync()`` and on PostgreSQL a
``CHECKPOINT``:

repaired import   ``import_file(path, name, on_error="split", orient=True)``
                  (``import_arrays`` for the grid). Floor: the plain import
                  (``on_error="raise"``) of the same input, which is printed
                  as a row of its own too. Target: ≤ 1.5× floor.
broken grid       ``import_arrays`` of the broken grid with the same options.
                  Floor: the plain import of the unbroken grid (the same
                  runs as the grid's floor). Target: ≤ 1.5× floor (applied).

Each import figure and its floor is the median of ``--runs`` runs; within a
run the plain and repaired imports alternate their order. The repair
decisions alone are measured in-process, without a database, so that a
reader sees what the repair itself costs: ``hestore.build.build(n, soup)``
against ``orient(soup, cut=True)`` (with the gather of the oriented corners)
+ ``build(n, oriented, split=True)``, on the broken grid against ``build``
of the unbroken grid. Each is the first call in a fresh process, after the
input is read, as in an import (a second call in the same process runs on
memory the first one left mapped, and a plain build then takes a third of
the time); the median of ``--runs`` runs, alternating.

Correctness gates (the exit status is non-zero only when one fails or a step
crashes, never for a slow figure): a repaired import of a clean input stores
the plain import's vertex, edge and polygon counts and reports
``split == {}``, ``cut == []``, ``flipped == []`` and nothing skipped, and its
in-process build gives the plain build's arrays column for column; the
repaired broken grid stores every input polygon (``report.polygons`` = the
input's count), ``report.flipped`` is exactly the reversed triangles,
``report.split`` maps each vertex of each duplicate to one copy (the copies
numbered on from the grid's vertices), nothing is cut or skipped, the counts
are the grid's plus the copies and the duplicates' edges; ``mesh.check()``
is empty after the first repaired import of each input (run in a child step
of its own).

With ``--profile over`` (the default) a repaired import over its target is
run once more under cProfile and its top functions are printed.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np

import hestore
from hestore import io as formats
from hestore.arrays import Ragged, ragged
from hestore.build import build, orient

from harness.bench import Bench
from harness.cli import Parser, at_least, wants_profile
from harness.databases import open_store, url_of
from harness.runner import one_shot
from harness.stats import finished, median_of
from harness.tables import Figure, fmt_mib, fmt_time, verdict
from harness.timing import maxrss, timed
from workloads import FILES, MESHES, grid_arrays, grid_counts, import_mesh, mesh_label, present, timed_check

TARGET_RATIO = 1.5
REPAIR = {"on_error": "split", "orient": True}
SMALL_FILES = {"bunny": "spot.obj", "igea": "bob_small.ply"}
LATTICE = 3  # duplicated triangles lie in cells this far apart, both ways
QUICK = {"n": 100, "files": "small", "runs": 1, "duplicates": 100, "profile": "off"}
SPLIT = 'on_error="split", orient=True'
PLAIN = 'on_error="raise"'
ABOUT = """\
Gates: a repaired import of a clean input stores the plain import's counts and reports no repair,
and its in-process build gives the plain build's arrays; the broken grid keeps every input polygon,
flips back exactly the reversed triangles, copies each duplicate's three vertices once (the copies
numbered on from the grid's vertices), cuts and skips nothing, and stores the expected counts; check()
is empty after the first repaired import of each input. Target: ≤ 1.5× the plain import (issue 11),
applied to the broken grid against the unbroken grid's plain import; no RSS target."""


def files_of(spec: dict) -> dict[str, str]:
    return FILES if spec["files"] == "large" else SMALL_FILES


def label_of(mesh: str, variant: str, spec: dict) -> str:
    """The mesh column: the file, the grid, or the broken grid."""
    label = mesh_label(mesh, spec["n"], files_of(spec))
    return f"{label}, broken" if variant == "broken" else label


# ==========================================================================
# Inputs


class Broken(NamedTuple):
    """The broken grid: its arrays, the reversed triangles and the duplicated ones (input indices, ascending)."""

    positions: np.ndarray
    faces: np.ndarray
    reversed: np.ndarray
    duplicated: np.ndarray


def broken_grid(n: int, share: float, duplicates: int, seed: int) -> Broken:
    """The n×n grid with ``share`` of its triangles reversed and ``duplicates`` interior triangles appended again.

    The duplicated triangles are one of the two triangles of random cells
    ``(i, j)`` with ``i, j ≡ 1 (mod 3)``, one cell in from the boundary: no
    two share a vertex, and each one's three edges are interior. Polygon 0 and
    the duplicated triangles keep their orientation, so that ``orient``, which
    keeps the lowest polygon of each component, turns back exactly the
    reversed ones (each duplicated triangle and its duplicate are
    components of their own: their edges have three uses and decide
    nothing).
    """
    positions, faces = grid_arrays(n)
    rng = np.random.default_rng(seed)
    k = np.arange(1, n - 2, LATTICE, dtype=np.int64)
    cells = (k[:, None] * (n - 1) + k[None, :]).ravel()
    if duplicates > len(cells):
        raise ValueError(f"--duplicates {duplicates}: the {n}×{n} grid has {len(cells)} cells to duplicate from")
    duplicated = np.sort(2 * rng.choice(cells, size=duplicates, replace=False) + rng.integers(0, 2, duplicates))
    free = np.ones(len(faces), dtype=bool)
    free[0] = False
    free[duplicated] = False
    turned = np.sort(rng.choice(np.flatnonzero(free), size=round(share * len(faces)), replace=False))
    out = faces.copy()
    out[turned] = out[turned, ::-1]
    return Broken(positions, np.concatenate([out, faces[duplicated]]), turned, duplicated)


def _broken(spec: dict) -> Broken:
    return broken_grid(spec["n"], spec["reversed"], spec["duplicates"], spec["seed"])


def broken_gates(b: Broken, report, n: int) -> list[str]:
    """What the repaired import of the broken grid must report and store."""
    problems = []
    v, d = len(b.positions), len(b.duplicated)
    if report.polygons != len(b.faces):
        problems.append(f"stored {report.polygons:,} polygons of {len(b.faces):,}")
    if report.skipped:
        problems.append(f"skipped {len(report.skipped)} polygons, e.g. {report.skipped[0]}")
    if report.flipped != b.reversed.tolist():
        extra = sorted(set(report.flipped) - set(b.reversed.tolist()))[:5]
        missed = sorted(set(b.reversed.tolist()) - set(report.flipped))[:5]
        problems.append(f"flipped {len(report.flipped):,} polygons, not the {len(b.reversed):,} reversed "
                        f"(extra e.g. {extra}, missed e.g. {missed})")
    if report.cut:
        problems.append(f"cut {len(report.cut)} edges, e.g. {report.cut[:3]}")
    copied = sorted(np.unique(b.faces[len(b.faces) - d:]).tolist())
    copies = sorted(c for cs in report.split.values() for c in cs)
    if sorted(report.split) != copied or any(len(cs) != 1 for cs in report.split.values()):
        problems.append(f"split copied {len(report.split):,} vertices into {len(copies):,} copies; expected each of "
                        f"the duplicates' {len(copied):,} vertices copied once")
    if copies != list(range(v, v + 3 * d)):
        problems.append(f"the copies are not vertices {v:,}..{v + 3 * d - 1:,}")
    if report.vertices != v + 3 * d or report.edges != grid_counts(n, n)[1] + 3 * d:
        problems.append(f"stored {report.vertices:,} vertices and {report.edges:,} edges; expected "
                        f"{v + 3 * d:,} and {grid_counts(n, n)[1] + 3 * d:,}")
    return problems


def load_soup(spec: dict) -> tuple[int, Ragged]:
    """Vertex count and polygons of a clean input, as the import gets them."""
    if spec["mesh"] == "grid":
        positions, faces = grid_arrays(spec["n"])
        return len(positions), ragged(faces)
    soup = formats.read(os.path.join(spec["dir"], files_of(spec)[spec["mesh"]]))
    return len(soup.positions), Ragged(soup.offsets, soup.indices)


# ==========================================================================
# Child jobs (each runs in its own process)


def oriented(soup: Ragged):
    """``orient(soup, cut=True)`` and the soup it turns, as the import gathers it."""
    turn = orient(soup, cut=True)
    return turn, Ragged(soup.offsets, soup.indices[turn.order])


def job_build(spec: dict) -> dict:
    """The repair decisions alone, in-process, each the first call in a fresh process as in an import:
    ``build()`` (variant plain) or ``orient(cut=True)`` + ``build(split=True)`` (repair, broken)."""
    variant = spec["variant"]
    broken = _broken(spec) if variant == "broken" else None
    n, soup = (len(broken.positions), ragged(broken.faces)) if broken else load_soup(spec)
    if variant == "plain":
        run = timed(lambda: build(n, soup))
        return {"seconds": run.seconds, "cpu": run.cpu, "rss": maxrss(), "problems": []}
    turn = timed(lambda: oriented(soup))
    flips, turned = turn.result
    split = timed(lambda: build(n, turned, split=True))
    rss = maxrss()
    repaired = split.result
    problems = []
    if broken:
        if len(repaired.accepted) != len(broken.faces) or int(flips.flip.sum()) != len(broken.reversed):
            problems.append(f"build(split=True) kept {len(repaired.accepted):,} of {len(broken.faces):,} polygons, "
                            f"orient flipped {int(flips.flip.sum()):,} of the {len(broken.reversed):,} reversed")
    else:
        if flips.flip.any() or len(flips.cut) or len(repaired.copied) or repaired.refused:
            problems.append(f"the repaired build of a clean input flipped {int(flips.flip.sum())}, cut "
                            f"{len(flips.cut)}, copied {len(repaired.copied)} and refused {len(repaired.refused)}")
        if spec["run"] == 0:  # untimed, after the RSS: the plain build to compare with
            plain = build(n, soup).arrays
            differ = [f for f, x, y in zip(plain._fields, plain, repaired.arrays) if not np.array_equal(x, y)]
            if differ:
                problems.append(f"the repaired build differs from the plain one in {', '.join(differ)}")
    return {"seconds": turn.seconds + split.seconds, "cpu": turn.cpu + split.cpu, "orient": turn.seconds,
            "split": split.seconds, "rss": rss, "flipped": int(flips.flip.sum()), "copied": len(repaired.copied),
            "problems": problems}


def job_import(spec: dict) -> dict:
    variant = spec["variant"]
    options = {} if variant == "plain" else REPAIR
    broken = _broken(spec) if variant == "broken" else None
    grid = grid_arrays(spec["n"]) if spec["mesh"] == "grid" and not broken else None  # arrays a user already has
    store = hestore.open(url_of(spec))
    if broken:
        def run():
            return store.import_arrays(spec["name"], broken.positions, broken.faces, **options)
    else:
        def run():
            return import_mesh(store, spec["mesh"], spec["n"], spec["dir"], grid, files=files_of(spec), **options)
    report, out = one_shot(spec, run, profile=spec.get("profile", False))
    store.close()
    out.update(vertices=report.vertices, edges=report.edges, polygons=report.polygons, skipped=len(report.skipped),
               flipped=len(report.flipped), split=len(report.split),
               copies=sum(len(c) for c in report.split.values()), cut=len(report.cut), problems=[])
    if broken:
        out["input_polygons"] = len(broken.faces)
        out["reversed"] = len(broken.reversed)
        out["problems"] = broken_gates(broken, report, spec["n"])
    return out


def job_check(spec: dict) -> dict:
    with open_store(spec) as store:
        return timed_check(store, spec["name"])


JOBS = {"build": job_build, "import": job_import, "check": job_check}


# ==========================================================================
# Driver


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, meshes=MESHES, jobs=JOBS, seed=20240601,
                profile="profile a repaired import in a separate run when it is over target (default), always, "
                        "or never")
    ap.add_argument("--runs", type=at_least(1), default=3,
                    help="runs of each import and in-process build, plain and repaired alternating (default 3); "
                         "the median is the figure")
    ap.add_argument("--reversed", type=float, default=0.1,
                    help="share of the broken grid's triangles reversed (default 0.1)")
    ap.add_argument("--duplicates", type=at_least(0), default=1000,
                    help="interior triangles of the broken grid appended once more (default 1000)")
    ap.add_argument("--files", choices=("large", "small"), default="large",
                    help="the 1 M-face files (default), or small stand-ins from the same folder: "
                         + ", ".join(SMALL_FILES.values()))
    args = ap.parse_args(argv)
    only, missing = present(args.only, args.meshes_dir, files_of(vars(args)))
    if not 0 <= args.reversed < 1:
        ap.error("--reversed must be in [0, 1)")
    lattice = len(np.arange(1, args.n - 2, LATTICE)) ** 2
    if "grid" in only and args.duplicates > lattice:
        ap.error(f"--duplicates {args.duplicates}: the {args.n}×{args.n} grid has {lattice} cells to duplicate from")

    base = {"n": args.n, "dir": args.meshes_dir, "files": args.files, "reversed": args.reversed,
            "duplicates": args.duplicates, "seed": args.seed}
    builds: dict = {}  # (mesh, variant) -> [result per run]
    runs: dict = {}  # (backend, mesh, variant) -> [result per run]
    checks: dict = {}  # (backend, mesh, variant) -> result
    with Bench(args, "repair", __file__, clean=("repair_", "result-")) as bench:
        bench.report.skipped.extend(missing)
        for m in only:  # the repair decisions alone, without a database
            variants = variants_of(m)
            for r in range(args.runs):
                for variant in variants if r % 2 == 0 else variants[::-1]:
                    result = bench.runner.run(job="build", mesh=m, variant=variant, run=r, what="in-process", **base)
                    builds.setdefault((m, variant), []).append(result)
        for place in bench.for_each_backend():
            bname = place.backend
            for m in only:
                variants = variants_of(m)
                for r in range(args.runs):
                    for variant in variants if r % 2 == 0 else variants[::-1]:
                        name = "broken" if variant == "broken" else m
                        spec = dict(base, mesh=m, variant=variant, name=name, run=r,
                                    **place.fresh(f"repair_{m}_{variant}"))
                        result = bench.runner.run(job="import", **spec)
                        runs.setdefault((bname, m, variant), []).append(result)
                        if r == 0 and variant != "plain" and result:
                            checks[(bname, m, variant)] = bench.runner.run(job="check", what="check()", **spec)
                        place.drop(spec)
                profile_over(bench, place, base, m, runs)
    report(bench, only, builds, runs, checks)
    return bench.finish(meshes=args.meshes_dir)


def variants_of(mesh: str) -> tuple[str, ...]:
    """The imports of one input: the plain one (the floor) first, then the repaired ones."""
    return ("plain", "repair", "broken") if mesh == "grid" else ("plain", "repair")


def profile_over(bench: Bench, place, base: dict, mesh: str, runs: dict) -> None:
    """A repaired import over its target (or every one, with ``--profile all``): once more under cProfile."""
    args, bname = bench.args, place.backend
    if args.profile == "off":
        return
    floor = median_of(finished(runs, (bname, mesh, "plain")))
    for variant in variants_of(mesh)[1:]:
        t = median_of(finished(runs, (bname, mesh, variant)))
        if t is None or floor is None or not wants_profile(args, t > TARGET_RATIO * floor):
            continue
        name = "broken" if variant == "broken" else mesh
        spec = dict(base, mesh=mesh, variant=variant, name=name, profile=True, **place.fresh(f"repair_profile_{mesh}"))
        prof = bench.runner.run(job="import", **spec)
        place.drop(spec)
        if prof and prof.get("profile"):
            bench.report.profiles.append((
                f"{bname} {label_of(mesh, variant, base)}: import with {SPLIT} under cProfile ({prof['seconds']:.2f} s "
                f"with the profiler on; median {t:.2f} s without, floor {floor:.2f} s)", prof["dominant"],
                prof["profile"]))


# ==========================================================================
# Report


def _what(mesh: str) -> str:
    return "import_arrays" if mesh == "grid" else "import_file"


def import_figures(args, only, runs) -> list[Figure]:
    """Per backend and input: the plain import (the floor) and each repaired one beside it."""
    out = []
    for bname in args.backends:
        for m in only:
            plain = finished(runs, (bname, m, "plain"))
            floor = median_of(plain)
            label = label_of(m, "plain", vars(args))
            if plain:
                out.append(Figure(f"{_what(m)}, {PLAIN} (the floor)", bname, floor, mesh=label, n=len(plain),
                                  cpu=median_of(plain, "cpu"), rss=max(r["rss"] for r in plain)))
            for variant in variants_of(m)[1:]:
                mine = finished(runs, (bname, m, variant))
                if not mine:
                    continue
                t = median_of(mine)
                ok = None if floor is None else t <= TARGET_RATIO * floor
                what = "the unbroken grid's plain import" if variant == "broken" else f"plain {_what(m)}"
                target = f"≤ {TARGET_RATIO:g}× floor" + (" (applied)" if variant == "broken" else "")
                out.append(Figure(f"{_what(m)}, {SPLIT}", bname, t, floor, target, verdict(ok),
                                  label_of(m, variant, vars(args)), n=len(mine), cpu=median_of(mine, "cpu"),
                                  rss=max(r["rss"] for r in mine),
                                  floor_parts=f"{what} {floor:.2f}" if floor is not None else "missing"))
    return out


def build_figures(args, only, builds) -> list[Figure]:
    """The repair decisions alone, in-process: orient(cut=True) + build(split=True) against build()."""
    out = []
    for m in only:
        plain = finished(builds, (m, "plain"))
        floor = median_of(plain)
        if plain:
            out.append(Figure("build() (the floor)", "in-process", floor, mesh=label_of(m, "plain", vars(args)),
                              n=len(plain), cpu=median_of(plain, "cpu"), rss=max(r["rss"] for r in plain)))
        for variant in variants_of(m)[1:]:
            mine = finished(builds, (m, variant))
            if not mine:
                continue
            what = "build() of the unbroken grid" if variant == "broken" else "build()"
            out.append(Figure("orient(cut=True) + build(split=True)", "in-process", median_of(mine), floor,
                              mesh=label_of(m, variant, vars(args)), n=len(mine), cpu=median_of(mine, "cpu"),
                              rss=max(r["rss"] for r in mine),
                              floor_parts=f"{what} {floor:.2f}" if floor is not None else "missing"))
    return out


def cost_rows(args, only, builds, runs) -> list[list[str]]:
    """What the repair costs: its parts in-process, and the repaired import over the plain one on each backend."""
    rows = []
    for m in only:
        floor = median_of(finished(builds, (m, "plain")))
        for variant in variants_of(m)[1:]:
            mine = finished(builds, (m, variant))
            if not mine or floor is None:
                continue
            row = [label_of(m, variant, vars(args)), fmt_time(floor), fmt_time(median_of(mine, "orient")),
                   fmt_time(median_of(mine, "split")), f"{median_of(mine) - floor:+.2f} s"]
            for bname in args.backends:
                mine_i, plain_i = finished(runs, (bname, m, variant)), finished(runs, (bname, m, "plain"))
                row.append("—" if not mine_i or not plain_i else
                           f"{median_of(mine_i) - median_of(plain_i):+.2f} s / "
                           f"{median_of(mine_i, 'cpu') - median_of(plain_i, 'cpu'):+.2f} s")
            rows.append(row)
    return rows


def gates(bench: Bench, only, builds, runs, checks) -> None:
    """The correctness gates over every step's result, and the notes on what each import stored."""
    args, rep = bench.args, bench.report
    spec = vars(args)
    for (m, variant), results in builds.items():
        for b in results:
            if b:
                rep.problems.extend(f"{label_of(m, variant, spec)}, in-process: {p}" for p in b["problems"])
    for (bname, m, variant), results in runs.items():
        label = label_of(m, variant, spec)
        done = [r for r in results if r]
        for r in done:
            rep.problems.extend(f"{bname} {label}: {p}" for p in r["problems"])
        if variant == "repair":
            plain = finished(runs, (bname, m, "plain"))
            for r in done:
                counts = [r["vertices"], r["edges"], r["polygons"]]
                for p in plain:
                    if [p["vertices"], p["edges"], p["polygons"]] != counts:
                        rep.problems.append(f"{bname} {label}: the repaired import stored V/E/F "
                                            f"{'/'.join(map(str, counts))}, the plain one "
                                            f"{p['vertices']}/{p['edges']}/{p['polygons']}")
                        break
                repairs = {k: r[k] for k in ("split", "cut", "flipped", "skipped") if r[k]}
                if repairs:
                    rep.problems.append(f"{bname} {label}: the repaired import of a clean input reported repairs: "
                                        + ", ".join(f"{k} {v}" for k, v in repairs.items()))
            if done:
                r = done[0]
                rep.notes.append(f"{bname} {label}: the repaired import stored {r['vertices']:,} vertices, "
                                 f"{r['edges']:,} edges, {r['polygons']:,} polygons; split {r['split']}, cut "
                                 f"{r['cut']}, flipped {r['flipped']}, skipped {r['skipped']} (first run)")
        if variant == "broken" and done:
            r = done[0]
            rep.notes.append(f"{bname} {label}: {r['input_polygons']:,} input polygons ({r['reversed']:,} reversed, "
                             f"{args.duplicates:,} duplicates appended) → {r['polygons']:,} stored, "
                             f"{r['flipped']:,} flipped back, {r['split']:,} vertices copied into {r['copies']:,} "
                             f"copies, {r['cut']} edges cut, {r['skipped']} skipped; stored {r['vertices']:,} "
                             f"vertices, {r['edges']:,} edges")
    for (bname, m, variant), c in checks.items():
        label = label_of(m, variant, spec)
        if not c:
            continue
        first = finished(runs, (bname, m, variant))
        rep.notes.append(f"{bname} {label}: mesh.check() after the first repaired import {c['seconds']:.2f} s, "
                         f"{c['violations']} violation(s)")
        if c["violations"]:
            rep.problems.append(f"{bname} {label}: check() found {c['violations']} violations, e.g. {c['examples']}")
        if first and [c["counts"][k] for k in (0, 2, 3)] != [first[0][k] for k in ("vertices", "edges", "polygons")]:
            rep.problems.append(f"{bname} {label}: counts() {c['counts']} differ from the import report's")
    for bname in args.backends:
        for m in only:
            for variant in variants_of(m):
                done = finished(runs, (bname, m, variant))
                if done:
                    each = ", ".join(f"{r['seconds']:.2f}" for r in done)
                    rss = ", ".join(fmt_mib(r["rss"]) for r in done)
                    rep.notes.append(f"{bname} {label_of(m, variant, spec)}: {variant} import, each run (s): {each}; "
                                     f"peak RSS {rss}")


def report(bench: Bench, only, builds, runs, checks) -> None:
    args, rep = bench.args, bench.report
    gates(bench, only, builds, runs, checks)
    rep.title(f"hestore repair benchmark — imports with {SPLIT} against the plain import ({PLAIN}) of the same "
              f"input; {args.runs} run(s) of each, each in a {bench.runner.process} into a fresh database")
    rep.figures(import_figures(args, only, runs), after="""\
(time: one import, commit included, the median of the runs (n); floor: the plain import's median; its CPU:
 the median user + system time of the importing process alone, without the database server's; peak RSS:
 the largest of the runs', ru_maxrss of the importing process)""")
    parts = build_figures(args, only, builds)
    rep.figures(parts, caption=f"""\
Repair decisions alone, in-process, no database (time: the median of the runs (n), each the first call
in a {bench.runner.process}, as in an import; the floor is build() of the same clean input — for the broken
grid, of the unbroken grid — as the plain import runs it):""")
    if parts:
        rep.table("What the repair costs: its parts (medians), and the repaired import's time over the plain import's "
                  "on\neach backend (medians; wall clock / the importing process's CPU):",
                  ["input", "build()", "orient(cut=True)", "build(split=True)", "repair − build()",
                   *(f"{b}: repaired − plain import" for b in args.backends)],
                  cost_rows(args, only, builds, runs), "l" + "r" * (4 + len(args.backends)))
    rep.close(ABOUT, profiles="Profiles of the repaired imports over their target:")


if __name__ == "__main__":
    raise SystemExit(main())
