"""Benchmark: the Euler operators of SPEC §3.1, one call inside a transaction and a whole-mesh job (SPEC §9).

    python bench/euler.py [--backends sqlite,postgresql] [--n 710] [--small 50x100] [--repeat 200]

Workloads: the triangulated N×N vertex grid (``--n``, default 710: 1,005,362
triangles) and a small grid of ``--small`` cells (default 50×100: 10,000
triangles), both with 2 triangles per cell, each stored once per backend with
``store.import_arrays`` (untimed setup; on PostgreSQL followed by ``VACUUM
(ANALYZE)``). Storing, the operators of one grid, and each subdivision run
in fresh processes (each operator on a freshly opened store); before each
timed region they run ``os.sync()`` and, on PostgreSQL, a ``CHECKPOINT``.

Sites: cells of a lattice every 4th cell in both directions, 2 cells from the
boundary, so that no two sites share a vertex or a star (an operator reads
the stars of its edge's ends and of the opposite corners: one cell around
the site). At each site the operators work on the cell's diagonal, its two
triangles and its corners, all interior. On the 1 M grid every operator gets
its own random sites; on the small grid, which has too few, the operators
that need the same preparation share them (an element is then used again in
a later block, a fresh transaction).

Per operator, on each grid, ``--repeat`` timed calls (after ``--warmup``
untimed ones), in blocks of ``--block`` calls on distinct sites, each block
one transaction rolled back at its end (so the grid stays as stored); an
untimed ``add_vertex`` opens each block (the mesh lock, a per-transaction
cost that belongs to the commit). Each call is timed alone with
``perf_counter_ns``, the cyclic garbage collector paused; the figure is the
median, with p90 and the median CPU time of the call (``process_time``).

split_edge            ``split_edge(e)``, e the diagonal: both triangles become quads.
split_edge, tri       ``split_edge(e, triangulate=True)``: four triangles.
split_polygon         ``split_polygon(q, b, d)`` on a quad ``(a, b, c, d)``,
                      across the other diagonal; the quads are made by
                      ``join_polygons`` of the cell's diagonal, committed in
                      the setup.
join_polygons         ``join_polygons(e)``, e the diagonal.
poke_polygon          ``poke_polygon(t)``, t the cell's lower triangle.
flip_edge             ``flip_edge(e)``, e the diagonal.
collapse_edge         ``collapse_edge(h)``, h the diagonal's half-edge in a
                      random direction (an interior collapse: V-1, E-3, F-2).
heal_edges            ``heal_edges(e1, e2)`` at a vertex of degree 2 made by
                      ``split_edge`` of the diagonal, committed in the setup.
fill_hole             ``fill_hole(h)``, h a free half-edge of a hole left by
                      ``remove_polygon`` of the lower triangle, committed in
                      the setup.
triangulate_polygon   ``triangulate_polygon(q)`` on the setup's quads.
can_flip_edge, can_collapse_edge
                      the predicates, on the same kind of elements, inside
                      the open transaction (each answers True).
context: add_polygon  ``add_polygon([a, b, c])``: a triangle on a free
                      boundary half-edge a→b and a new vertex c (its
                      ``add_vertex`` untimed), as ``bench/edits.py`` measures
                      it; SPEC §9 gives it the same ≤ 1 ms target. Its median
                      is printed as every operator's floor, for context.

Every element's predicate (``can_<op>``) is checked before the blocks,
outside the timing, each in its own read transaction, so the blocks start
with nothing cached. Target (SPEC §9): ≤ 1 ms median, flat in mesh size —
the two grids are printed side by side with the ratio (flat: ≤ 1.5×,
applied). Timings exclude writing: hestore writes a transaction's changes at
commit (or before a read).

The whole-mesh job: a 1-to-4 subdivision of every triangle of a fresh copy of
the small grid (10,000 triangles), through the public API in one
transaction, commit included: ``split_edge`` of every edge once, then for
each triangle three ``split_polygon`` cuts between the new vertices, each
cutting off a corner. The plan (handles, and the corner to cut last, the one
whose piece keeps ``p.halfedge`` after the splits) is read before the timed
region. The same job then runs on a 10,000-triangle patch of the 1 M grid
(its last step there). Figures: the whole job, its amortised cost per
operator (target ≤ 100 µs: the 1,000-edit transaction's, applied), each
phase per operator, and the flush + COMMIT part.

Correctness gates (the exit status is non-zero only when one fails or a step
crashes, never on a slow figure): every element passes its predicate and
every call succeeds (predicates answer True); each block's counts before its
rollback are the stored counts plus each operator's known change; the mesh
is unchanged after the rollbacks; on the small grid ``check()`` is empty
after the first block of each operator; after the subdivision the counts are
``V + E, 2E + 3F, 4F`` (on the patch: ``V + E', E + E' + 3F', F + 3F'``),
``check()`` is empty and, on the small grid, every polygon is a triangle.

With ``--profile over`` (the default) an operator over its target is run once
more under cProfile (the profiler on during the timed calls only) and its top
functions are printed; a subdivision over its target is profiled on a fresh
copy of the small grid.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import cProfile
import random
import time
from collections import Counter

import hestore

from harness.bench import Bench
from harness.cli import Parser, at_least, cells, wants_profile
from harness.databases import open_store, settle, url_of, vacuum
from harness.profiling import Statements, profile_report, traced
from harness.stats import median
from harness.tables import Figure, fmt_time, verdict
from harness.timing import gc_paused, maxrss, pc
from workloads import Rollback, grid_arrays, grid_counts, import_mesh, triangles_label

QUICK = {"n": 60, "small": "20x25", "repeat": 40, "warmup": 5, "block": 20, "profile": "off"}
TARGET_OP = 1e-3  # seconds, median of one operator inside a transaction
TARGET_AMORTISED = 100e-6  # seconds per operator of the whole-mesh job, commit included (applied)
FLAT = 1.5  # the 1 M median ÷ the 10 k median that still counts as flat (applied)
COUNTED = 20  # calls of the untimed pass that counts hestore's statements
SPACING, MARGIN = 4, 2  # the lattice of sites: every 4th cell, from cell 2
MESH = "grid"

#: Operator families: label, setup preparation of their sites, change of (vertices, edges, polygons) per call.
OPS = {
    "split_edge": ("split_edge(e)", None, (1, 1, 0)),
    "split_edge_tri": ("split_edge(e, triangulate=True)", None, (1, 3, 2)),
    "split_polygon": ("split_polygon(quad, b, d)", "quad", (0, 1, 1)),
    "join_polygons": ("join_polygons(e)", None, (0, -1, -1)),
    "poke_polygon": ("poke_polygon(triangle)", None, (1, 3, 2)),
    "flip_edge": ("flip_edge(e)", None, (0, 0, 0)),
    "collapse_edge": ("collapse_edge(h)", None, (-1, -3, -2)),
    "heal_edges": ("heal_edges(e1, e2), degree-2 vertex", "split", (-1, -1, 0)),
    "fill_hole": ("fill_hole(h), triangular hole", "hole", (0, 0, 1)),
    "triangulate_polygon": ("triangulate_polygon(quad)", "quad", (0, 1, 1)),
    "can_flip_edge": ("can_flip_edge(e)", None, (0, 0, 0)),
    "can_collapse_edge": ("can_collapse_edge(h)", None, (0, 0, 0)),
}
CONTEXT = "add_polygon"
CONTEXT_LABEL = "context: add_polygon([a, b, c]), boundary"
CONTEXT_DELTA = (1, 2, 1)  # with its untimed add_vertex
PREPS = (None, "split", "hole", "quad")
SUBDIVISION = "1-to-4 subdivision"
ABOUT = """\
Gates: every element passes its predicate first; every call succeeds (predicates answer True); each
block's counts equal the stored ones plus each call's known change; rollbacks leave the mesh as
stored; check() is empty after a block of each operator on the small grid and after each subdivision;
the subdivided small grid has V + E vertices, 2E + 3F edges and 4F triangles."""


# ==========================================================================
# The grids and their sites


def cell_vertex(nx: int, i: int, j: int) -> int:
    """The lower-left corner of cell (i, j) of a grid with ``nx`` vertices per row."""
    return j * nx + i


def cell_triangles(nx: int, i: int, j: int) -> tuple[int, int]:
    """The polygon ids of cell (i, j)'s triangles after ``import_arrays`` of `grid_arrays`: lower, upper."""
    c = j * (nx - 1) + i
    return 2 * c, 2 * c + 1


def lattice(nx: int, ny: int, patch: list[int] | None) -> list[tuple[int, int]]:
    """The cells of the lattice of sites, away from the boundary and from the subdivision's patch."""
    out = []
    for j in range(MARGIN, ny - 2, SPACING):
        for i in range(MARGIN, nx - 2, SPACING):
            if patch:
                i0, j0, w, h = patch
                if i0 - 2 <= i < i0 + w + 1 and j0 - 2 <= j < j0 + h + 1:
                    continue
            out.append((i, j))
    return out


def boundary_sites(nx: int, ny: int) -> list[tuple[int, int]]:
    """Free boundary half-edges ``(a, b)`` (a→b free), every third along each side, corners left out."""
    top = (ny - 1) * nx
    out = []
    for i in range(1, nx - 2, 3):
        out.append((i + 1, i))  # bottom: the lower triangles hold i→i+1
        out.append((top + i, top + i + 1))  # top: the upper triangles hold (i+1)→i
    for j in range(1, ny - 2, 3):
        out.append((j * nx, (j + 1) * nx))  # left: the upper triangles hold v+nx→v
        out.append(((j + 1) * nx + nx - 1, j * nx + nx - 1))  # right: the lower triangles hold v→v+nx
    return out


def allocate(sites: list, need: int, rng: random.Random) -> dict[str, list]:
    """Sites per operator: disjoint when the lattice has enough, else shared by the operators of one
    preparation (each preparation its own quarter of the lattice)."""
    sites = list(sites)
    rng.shuffle(sites)
    out: dict[str, list] = {}
    if len(sites) >= need * len(OPS):
        for k, name in enumerate(OPS):
            out[name] = sites[k * need:(k + 1) * need]
        return out
    share = len(sites) // len(PREPS)
    for k, prep in enumerate(PREPS):
        group = sites[k * share:(k + 1) * share]
        for name, (_, p, _) in OPS.items():
            if p == prep:
                out[name] = rng.sample(group, len(group))
    return out


def _diagonal(mesh, nx: int, i: int, j: int):
    v = cell_vertex(nx, i, j)
    h = mesh.find_halfedge(hestore.Vertex(mesh, v), hestore.Vertex(mesh, v + nx + 1))
    if h is None:
        raise RuntimeError(f"cell ({i}, {j}) has no diagonal {v}–{v + nx + 1}")
    return h.edge


def job_setup(spec: dict) -> dict:
    """Store the grid (untimed), choose the sites, prepare them (committed), VACUUM (ANALYZE) on PostgreSQL."""
    nx, ny = spec["nx"], spec["ny"]
    t0 = time.perf_counter()
    problems = []
    with open_store(spec) as store:
        import_mesh(store, "grid", nx, "", grid=grid_arrays(nx, ny))
        mesh = store.mesh(MESH)
        seconds = time.perf_counter() - t0
        stored = mesh.counts()
        expected = grid_counts(nx, ny)
        if (stored.vertices, stored.edges, stored.polygons) != expected:
            problems.append(f"the stored grid has counts {stored}, not V, E, F = {expected}")
        rng = random.Random(spec["seed"])
        cells = lattice(nx, ny, spec.get("patch"))
        chosen = allocate(cells, spec["need"], rng)
        prepared: dict[str, dict] = {"split": {}, "hole": {}, "quad": {}}
        for name, sites in chosen.items():
            prep = OPS[name][1]
            if prep:
                prepared[prep].update(dict.fromkeys(sites))
        t1 = time.perf_counter()
        for prep, sites in prepared.items():
            if not sites:
                continue
            # Handles read before the transaction (a read inside it would write the pending changes first).
            diagonals = {s: _diagonal(mesh, nx, *s) for s in sites}
            with store.transaction():
                for (i, j), e in diagonals.items():
                    if prep == "split":
                        sites[(i, j)] = mesh.split_edge(e).id
                    elif prep == "hole":
                        mesh.remove_polygon(hestore.Polygon(mesh, cell_triangles(nx, i, j)[0]))
                    else:
                        sites[(i, j)] = mesh.join_polygons(e).id
        n = {p: len(s) for p, s in prepared.items()}
        want = (stored.vertices + n["split"], stored.edges + n["split"] - n["quad"],
                stored.polygons - n["hole"] - n["quad"])
        got = mesh.counts()
        if (got.vertices, got.edges, got.polygons) != want:
            problems.append(f"after preparing the sites the counts are {got}, not V, E, F = {want}")
        prep_seconds = time.perf_counter() - t1
        sites_out = {name: [[i, j, prepared[OPS[name][1]][(i, j)] if OPS[name][1] else None] for i, j in sites]
                     for name, sites in chosen.items()}
    vacuum(spec)
    return {"seconds": seconds, "prep_seconds": prep_seconds, "vertices": stored.vertices,
            "polygons": stored.polygons, "edges": stored.edges, "lattice": len(cells), "sites": sites_out,
            "shared": len(cells) < spec["need"] * len(OPS), "boundary": boundary_sites(nx, ny), "prepared": n,
            "problems": problems, "rss": maxrss()}


# ==========================================================================
# One operator, timed call by call


def _items(mesh, name: str, nx: int, sites: list, rng: random.Random) -> list[tuple]:
    """The arguments of each call (handles read here, untimed)."""
    V, P = hestore.Vertex, hestore.Polygon
    items = []
    for i, j, extra in sites:
        v = cell_vertex(nx, i, j)
        if name in ("split_edge", "split_edge_tri", "join_polygons", "flip_edge", "can_flip_edge"):
            items.append((_diagonal(mesh, nx, i, j),))
        elif name in ("collapse_edge", "can_collapse_edge"):
            h = _diagonal(mesh, nx, i, j).halfedge
            items.append((h if rng.random() < 0.5 else h.twin,))
        elif name == "poke_polygon":
            items.append((P(mesh, cell_triangles(nx, i, j)[0]),))
        elif name == "split_polygon":
            items.append((P(mesh, extra), V(mesh, v + 1), V(mesh, v + nx)))
        elif name == "triangulate_polygon":
            items.append((P(mesh, extra),))
        elif name == "heal_edges":
            w = V(mesh, extra)
            e1 = mesh.find_halfedge(V(mesh, v), w).edge  # the diagonal: it kept its id and ends at w
            e2 = mesh.find_halfedge(w, V(mesh, v + nx + 1)).edge
            items.append((e1, e2))
        elif name == "fill_hole":
            items.append((mesh.find_halfedge(V(mesh, v), V(mesh, v + 1)),))
        else:
            raise ValueError(name)
    return items


def _predicate(mesh, name: str):
    """The predicate checked before the blocks (for a predicate family, itself)."""
    base = name[4:] if name.startswith("can_") else ("split_edge" if name == "split_edge_tri" else name)
    return getattr(mesh, f"can_{base}")


def _call(mesh, name: str):
    """The timed call of an operator family, on one item."""
    if name == "split_edge_tri":
        return lambda e: mesh.split_edge(e, triangulate=True)
    method = getattr(mesh, name)
    return lambda *args: method(*args)


def job_op(spec: dict) -> dict:
    """One operator: its predicate on every element first, then the timed calls in rolled-back blocks."""
    name, nx = spec["family"], spec["nx"]
    rng = random.Random(spec["seed"])
    store = hestore.open(url_of(spec))
    mesh = store.mesh(MESH)
    problems = []
    V = hestore.Vertex
    if name == CONTEXT:
        items = []
        for a, b in spec["boundary"]:
            A, B = V(mesh, a), V(mesh, b)
            h = mesh.find_halfedge(A, B)
            if h is None or h.polygon is not None or h.twin.polygon is None:
                problems.append(f"{a}→{b} is not a free boundary half-edge")
                continue
            (xa, ya, _), (xb, yb, _) = A.position, B.position
            items.append((A, B, ((xa + xb) / 2, (ya + yb) / 2, 0.5)))
        delta = CONTEXT_DELTA
        refused = 0
    else:
        items = _items(mesh, name, nx, spec["sites"], rng)
        can = _predicate(mesh, name)
        ok = [it for it in items if can(*it)]
        refused = len(items) - len(ok)
        if refused:
            problems.append(f"{name}: {refused} of {len(items)} elements refused by their predicate")
        items = ok
        delta = OPS[name][2]
    if not items:
        store.close()
        return {"samples": [], "cpu": [], "problems": problems + [f"{name}: no element to time"], "rss": maxrss()}

    base = mesh.counts()
    want = spec["warmup"] + spec["repeat"]
    block = max(1, min(spec["block"], len(items)))
    predicate = name.startswith("can_")
    call = _call(mesh, name) if name != CONTEXT else mesh.add_polygon
    add_vertex = mesh.add_vertex
    profiler = cProfile.Profile() if spec.get("profile") else None
    ptime = time.process_time_ns
    samples: list[int] = []
    cpus: list[int] = []
    checked = not spec.get("check")
    k = 0

    def run_block(chunk: list, counter=None) -> None:
        nonlocal checked
        calls: Counter = Counter()
        try:
            with gc_paused(), traced(store, counter), store.transaction():
                add_vertex()  # opens the block's unit of work (the mesh lock), untimed
                for it in chunk:
                    if name == CONTEXT:
                        a, b, pos = it
                        it = ([a, b, add_vertex(pos)],)
                    before = Counter(counter.by_kind) if counter else None
                    c0 = ptime()
                    t0 = pc()
                    if profiler:
                        profiler.enable()
                    r = call(*it)
                    if profiler:
                        profiler.disable()
                    t1 = pc()
                    c1 = ptime()
                    if counter:
                        calls.update(Counter(counter.by_kind) - before)
                    elif predicate and r is not True:
                        problems.append(f"{name}{tuple(it)} answered {r!r} inside the block")
                    else:
                        samples.append(t1 - t0)
                        cpus.append(c1 - c0)
                got = mesh.counts()
                n = len(chunk)
                exp = (base.vertices + 1 + n * delta[0], base.edges + n * delta[1], base.polygons + n * delta[2])
                if (got.vertices, got.edges, got.polygons) != exp:
                    problems.append(f"{name}: after a block of {n} calls the counts are {got}, not V, E, F = {exp}")
                if not checked:
                    checked = True
                    bad = mesh.check()
                    if bad:
                        problems.append(f"{name}: check() after a block: {len(bad)} violation(s), e.g. {bad[:3]}")
                raise Rollback
        except Rollback:
            pass
        except hestore.HestoreError as exc:
            problems.append(f"{name}: a call raised {type(exc).__name__}: {exc}")
        if counter:
            counter.calls = calls

    settle(spec)
    while len(samples) < want and not problems:
        chunk = [items[(k + x) % len(items)] for x in range(min(block, want - len(samples)))]
        k += len(chunk)
        run_block(chunk)
    counter = Statements()
    if not problems:
        run_block([items[x % len(items)] for x in range(min(COUNTED, len(items)))], counter)
    if mesh.counts() != base:
        problems.append(f"{name}: the mesh changed after the rolled-back blocks: {mesh.counts()} vs {base}")
    store.close()
    out = {"samples": samples[spec["warmup"]:], "cpu": cpus[spec["warmup"]:], "elements": len(items),
           "refused": refused, "block": block, "problems": problems, "rss": maxrss(),
           "statements": {kind: c / min(COUNTED, len(items)) for kind, c in getattr(counter, "calls", {}).items()}}
    if profiler:
        out["profile"] = profile_report(profiler)
    return out


def job_ops(spec: dict) -> dict:
    """Every operator of one grid in turn, each on a freshly opened store: ``{family: job_op's result}``."""
    return {family: job_op(dict(spec, family=family, sites=spec["sites"].get(family, [])))
            for family in (CONTEXT, *OPS)}


# ==========================================================================
# The whole-mesh job: 1-to-4 subdivision


def job_subdivide(spec: dict) -> dict:
    """Split every edge of the patch's triangles once, then cut each triangle's three corners off: one
    transaction, commit included."""
    nx, ny = spec["nx"], spec["ny"]
    i0, j0, w, h = spec["patch"]
    store = hestore.open(url_of(spec))
    if spec.get("import"):
        import_mesh(store, "grid", nx, "", grid=grid_arrays(nx, ny))
        vacuum(spec)
    mesh = store.mesh(MESH)
    V, P = hestore.Vertex, hestore.Polygon
    problems = []

    # The plan, read before the timed region.
    t_plan = time.perf_counter()
    triangles = []  # (polygon, its corners a, b, c from p.halfedge's origin, the id of p.halfedge)
    edges: dict[tuple[int, int], object] = {}
    for j in range(j0, j0 + h):
        for i in range(i0, i0 + w):
            for pid in cell_triangles(nx, i, j):
                p = P(mesh, pid)
                corners = [v.id for v in p.vertices()]
                if len(corners) != 3:
                    problems.append(f"polygon {pid} of the patch is not a triangle: {corners}")
                    continue
                for a, b in zip(corners, corners[1:] + corners[:1]):
                    key = _key(a, b)
                    if key not in edges:
                        he = mesh.find_halfedge(V(mesh, key[0]), V(mesh, key[1]))
                        edges[key] = he.edge
                triangles.append((p, corners))
    plan = [(p, cut_plan(a, b, c)) for p, (a, b, c) in triangles]
    plan_seconds = time.perf_counter() - t_plan
    E, F = len(edges), len(triangles)
    before = mesh.counts()
    split_edge, split_polygon = mesh.split_edge, mesh.split_polygon

    # Under cProfile the statements are counted too, phase by phase (not in the timed run: a callback per
    # statement would be timed with it).
    counter = Statements() if spec.get("profile") else None
    phases: list[Counter] = []

    def mark() -> None:
        if counter:
            phases.append(Counter(counter.by_kind))

    def run():
        mid = {}
        t0 = pc()
        with store.transaction():
            for key, e in edges.items():
                mid[key] = split_edge(e)
            t1 = pc()
            mark()
            for p, cuts in plan:
                for y, z in cuts:
                    split_polygon(p, mid[y], mid[z])
            t2 = pc()
            mark()
        t3 = pc()
        mark()
        return t0, t1, t2, t3

    settle(spec)
    profiler = cProfile.Profile() if spec.get("profile") else None
    c0 = time.process_time()
    with gc_paused(), traced(store, counter):
        if profiler:
            profiler.enable()
        try:
            t0, t1, t2, t3 = run()
        except hestore.HestoreError as exc:
            problems.append(f"the subdivision raised {type(exc).__name__}: {exc}")
            t0 = t1 = t2 = t3 = 0
        finally:
            if profiler:
                profiler.disable()
    cpu = time.process_time() - c0
    rss_job = maxrss()

    after = mesh.counts()
    whole = spec.get("whole", False)
    exp = (before.vertices + E, before.edges + E + 3 * F, before.polygons + 3 * F)
    if (after.vertices, after.edges, after.polygons) != exp:
        problems.append(f"after the subdivision the counts are {after}, not V, E, F = {exp} "
                        f"(before: {before}; {E} edges split, {F} triangles cut)")
    t_check = time.perf_counter()
    bad = mesh.check()
    check_seconds = time.perf_counter() - t_check
    if bad:
        problems.append(f"check() after the subdivision: {len(bad)} violation(s), e.g. {bad[:3]}")
    if whole:
        polygons = mesh.to_arrays().polygons
        if getattr(polygons, "shape", None) != (4 * F, 3):
            problems.append("after the subdivision not every polygon is a triangle")
    store.close()
    out = {"edges": E, "triangles": F, "ops": E + 3 * F, "total": (t3 - t0) / 1e9, "splits": (t1 - t0) / 1e9,
           "cuts": (t2 - t1) / 1e9, "commit": (t3 - t2) / 1e9, "cpu": cpu, "plan_seconds": plan_seconds,
           "check_seconds": check_seconds, "before": [before.vertices, before.edges, before.polygons],
           "after": [after.vertices, after.edges, after.polygons], "problems": problems, "rss": rss_job,
           "rss_after_check": maxrss()}
    if profiler:
        out["profile"] = profile_report(profiler)
    if len(phases) == 3:
        split, cut, commit = phases[0], phases[1] - phases[0], phases[2] - phases[1]
        out["statements"] = {"split_edge": {k: c / E for k, c in split.items()},
                             "split_polygon": {k: c / (3 * F) for k, c in cut.items()},
                             "flush + COMMIT": dict(commit)}
    return out


def _key(x: int, y: int) -> tuple[int, int]:
    return (x, y) if x < y else (y, x)


def cut_plan(a: int, b: int, c: int) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """The three cuts of triangle (a, b, c), ``p.halfedge`` from a, once its edges are split: the edge keys of
    the new vertices each cut joins.

    ``split_edge`` keeps each polygon's first corner (``p.halfedge``'s origin) and ``split_polygon`` leaves
    ``p`` the part holding ``p.halfedge``, so cutting off b, then c, then a leaves ``p`` holding both ends of
    every cut.
    """
    ab, bc, ca = _key(a, b), _key(b, c), _key(c, a)
    return [(ab, bc), (bc, ca), (ca, ab)]


JOBS = {"setup": job_setup, "ops": job_ops, "op": job_op, "subdivide": job_subdivide}


# ==========================================================================
# The parent


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, jobs=JOBS, profile=True, seed=20240601)
    ap.add_argument("--small", type=cells, default="50x100",
                    help="cells of the small grid, WxH (default 50x100: 10,000 triangles; also the subdivision's "
                         "size, and that of its patch of the large grid)")
    ap.add_argument("--repeat", type=at_least(1), default=200, help="timed calls per operator and grid (default 200)")
    ap.add_argument("--warmup", type=at_least(0), default=20, help="untimed calls before them (default 20)")
    ap.add_argument("--block", type=at_least(1), default=50, help="calls per rolled-back transaction (default 50)")
    args = ap.parse_args(argv)
    sw, sh = args.small
    if args.n - 1 < max(sw, sh) + 2 * SPACING + 2 * MARGIN:
        ap.error(f"--n {args.n} is too small for a {sw}x{sh} patch with sites around it")

    grids = {"small": (sw + 1, sh + 1), "large": (args.n, args.n)}
    patches = {"small": [0, 0, sw, sh], "large": [(args.n - 1 - sw) // 2, (args.n - 1 - sh) // 2, sw, sh]}
    setups: dict = {}  # (backend, grid) -> result
    results: dict = {}  # (backend, grid, family) -> result
    subdivisions: dict = {}  # (backend, grid) -> result
    with Bench(args, "euler", __file__) as bench:
        run = bench.runner.run
        for place in bench.for_each_backend():
            bname = place.backend
            for grid in ("small", "large"):
                nx, ny = grids[grid]
                spec = dict(place.fresh(f"euler_{grid}"), nx=nx, ny=ny, seed=args.seed)
                # The small grid's subdivision runs on a copy of its own; the large grid's on a patch kept free of
                # sites, as the last step on that grid.
                patch = patches[grid] if grid == "large" else None
                setup = run(job="setup", patch=patch, need=args.repeat + args.warmup, what=f"{grid} grid {nx}×{ny}",
                            **spec)
                setups[(bname, grid)] = setup
                if setup is None:
                    continue
                common = dict(spec, repeat=args.repeat, warmup=args.warmup, block=args.block,
                              boundary=setup["boundary"])
                ops = run(job="ops", sites=setup["sites"], check=grid == "small",
                          what=f"every operator on the {grid} grid", **common) or {}
                for family, r in ops.items():
                    results[(bname, grid, family)] = r
                profile_ops(bench, common, setup, bname, grid, results)
                if grid == "small":
                    copy = dict(place.fresh("euler_subdivision"), nx=nx, ny=ny, seed=args.seed)
                    copy["import"] = True
                    subdivisions[(bname, grid)] = run(job="subdivide", patch=patches[grid], whole=True,
                                                      what="subdivision of the small grid", **copy)
                    place.drop(copy)
                else:
                    subdivisions[(bname, grid)] = run(job="subdivide", patch=patches[grid], whole=False,
                                                      what="subdivision of a patch of the large grid", **spec)
                place.drop(spec)
            profile_subdivision(bench, place, grids["small"], patches["small"], subdivisions)
    report(bench, grids, setups, results, subdivisions)
    return bench.finish()


def profile_ops(bench: Bench, common: dict, setup: dict, bname: str, grid: str, results: dict) -> None:
    """Run each operator over its target (or every one, with ``--profile all``) once more under cProfile."""
    if bench.args.profile == "off":
        return
    label = triangles_label(common["nx"], common["ny"])
    for family in (CONTEXT, *OPS):
        r = results.get((bname, grid, family))
        if not r or not r["samples"]:
            continue
        t = median(r["samples"]) / 1e9
        if wants_profile(bench.args, t > TARGET_OP):
            prof = bench.runner.run(job="op", family=family, sites=setup["sites"].get(family, []), check=False,
                                    profile=True, what=f"{family} on the {grid} grid", **common)
            if prof and prof.get("profile"):
                text, dominant = prof["profile"]
                bench.report.profiles.append((f"{bname}, {label} triangles: {family} under cProfile (median "
                                              f"{fmt_time(t)} without the profiler; {len(prof['samples'])} calls "
                                              "profiled)", dominant, text))


def profile_subdivision(bench: Bench, place, dims: tuple[int, int], patch: list[int], subdivisions: dict) -> None:
    """A subdivision over its target (on either grid), or every one with ``--profile all``: once more under
    cProfile, on a fresh copy of the small grid."""
    args, bname = bench.args, place.backend
    if args.profile == "off":
        return
    over = [grid for (b, grid), r in subdivisions.items()
            if b == bname and r and r["ops"] and r["total"] / r["ops"] > TARGET_AMORTISED]
    if not wants_profile(args, bool(over)):
        return
    copy = dict(place.fresh("euler_subdivision_profile"), nx=dims[0], ny=dims[1], seed=args.seed)
    copy["import"] = True
    prof = bench.runner.run(job="subdivide", patch=patch, whole=True, profile=True,
                            what="subdivision of the small grid", **copy)
    place.drop(copy)
    if prof and prof.get("profile"):
        text, dominant = prof["profile"]
        why = f"over target on the {' and '.join(over)} grid" if over else "--profile all"
        counted = "; ".join(f"{phase}: " + ", ".join(f"{k} {c:.3g}" for k, c in sorted(kinds.items()))
                            for phase, kinds in prof.get("statements", {}).items())
        bench.report.profiles.append((f"{bname}: {SUBDIVISION} of the small grid under cProfile ({prof['total']:.2f} "
                                      f"s with the profiler on; {why}). Statements sent per call ({counted})",
                                      dominant, text))


# ==========================================================================
# Figures


def _label(family: str) -> str:
    return CONTEXT_LABEL if family == CONTEXT else OPS[family][0]


def op_figures(results: dict, backends, grids: dict) -> list[Figure]:
    """One figure per operator, grid and backend: the median call, the context add_polygon as floor."""
    out = []
    for bname in backends:
        for grid, (nx, ny) in grids.items():
            ctx = results.get((bname, grid, CONTEXT))
            floor = median(ctx["samples"]) / 1e9 if ctx and ctx["samples"] else None
            for family in (CONTEXT, *OPS):
                r = results.get((bname, grid, family))
                if not r or not r["samples"]:
                    continue
                t = median(r["samples"]) / 1e9
                out.append(Figure.of_calls(_label(family), bname, r["samples"],
                                           floor=None if family == CONTEXT else floor,
                                           target=f"≤ {fmt_time(TARGET_OP)}", verdict=verdict(t <= TARGET_OP),
                                           mesh=triangles_label(nx, ny), cpu=median(r["cpu"]) / 1e9, rss=r["rss"]))
    return out


def subdivision_figures(subdivisions: dict, backends, grids: dict) -> list[Figure]:
    out = []
    for bname in backends:
        for grid, (nx, ny) in grids.items():
            r = subdivisions.get((bname, grid))
            if not r or not r["ops"] or not r["total"]:
                continue
            label = triangles_label(nx, ny)
            what = "whole grid" if grid == "small" else "a patch"
            per = r["total"] / r["ops"]
            out.append(Figure(f"{SUBDIVISION} of {r['triangles']:,} triangles ({what}), 1 txn incl. COMMIT",
                              bname, r["total"], mesh=label, cpu=r["cpu"], rss=r["rss"]))
            out.append(Figure(f"  per operator, amortised ({r['ops']:,} operators)", bname, per,
                              target=f"≤ {fmt_time(TARGET_AMORTISED)} (applied)",
                              verdict=verdict(per <= TARGET_AMORTISED), mesh=label, cpu=r["cpu"] / r["ops"]))
            out.append(Figure(f"  split_edge phase, per call ({r['edges']:,})", bname, r["splits"] / r["edges"],
                              mesh=label))
            out.append(Figure(f"  split_polygon phase, per call ({3 * r['triangles']:,})", bname,
                              r["cuts"] / (3 * r["triangles"]), mesh=label))
            out.append(Figure("  flush + COMMIT", bname, r["commit"], mesh=label))
    return out


def flat_row(bname: str, name: str, small: float | None, large: float | None) -> list[str]:
    """One row of the flat-in-mesh-size table: the figure on each grid, the ratio and whether it is flat."""
    ratio = large / small if None not in (small, large) else None
    return [bname, name, fmt_time(small), fmt_time(large), "—" if ratio is None else f"{ratio:.2f}×",
            "—" if ratio is None else ("flat" if ratio <= FLAT else "grows")]


def flat_rows(backends, results: dict, subdivisions: dict) -> list[list[str]]:
    """Every operator's median, and the subdivision per operator, on the small grid beside the large one."""
    rows = []
    for bname in backends:
        for family in (CONTEXT, *OPS):
            vals = []
            for grid in ("small", "large"):
                r = results.get((bname, grid, family))
                vals.append(median(r["samples"]) / 1e9 if r and r["samples"] else None)
            rows.append(flat_row(bname, _label(family), *vals))
        vals = []
        for grid in ("small", "large"):
            r = subdivisions.get((bname, grid))
            vals.append(r["total"] / r["ops"] if r and r["ops"] and r["total"] else None)
        rows.append(flat_row(bname, f"{SUBDIVISION}, per operator", *vals))
    return rows


def gates(bench: Bench, grids: dict, setups: dict, results: dict, subdivisions: dict) -> None:
    """The steps' problems (their gates failed), and the notes on the grids, the sites and the subdivisions."""
    args, rep = bench.args, bench.report
    for (bname, grid), s in setups.items():
        if not s:
            continue
        nx, ny = grids[grid]
        rep.problems.extend(f"{bname} {grid} grid: {p}" for p in s["problems"])
        shared = "shared by the operators of one preparation" if s["shared"] else "disjoint per operator"
        rep.notes.append(f"{bname} {triangles_label(nx, ny)} ({nx}×{ny} vertices): stored in {s['seconds']:.1f} s, "
                         f"sites prepared in {s['prep_seconds']:.1f} s ({s['prepared']['split']} degree-2 vertices, "
                         f"{s['prepared']['hole']} holes, {s['prepared']['quad']} quads); lattice of {s['lattice']:,} "
                         f"sites, {shared}")
    reused: dict = {}
    for (bname, grid, _family), r in results.items():
        if r is None:
            continue
        rep.problems.extend(f"{bname} {grid} grid: {p}" for p in r["problems"])
        if r.get("elements") is not None and r["elements"] < args.repeat + args.warmup:
            reused.setdefault((bname, grid), []).append(r["elements"])
    for (bname, grid), counts in reused.items():
        rep.notes.append(f"{bname} {triangles_label(*grids[grid])}: {len(counts)} operator(s) had "
                         f"{min(counts)}–{max(counts)} distinct elements for {args.warmup + args.repeat} calls "
                         "(distinct within each block; later blocks, fresh transactions, use them again)")
    for (bname, grid), r in subdivisions.items():
        if r is None:
            continue
        rep.problems.extend(f"{bname} {grid} grid, subdivision: {p}" for p in r["problems"])
        b, a = r["before"], r["after"]
        rep.notes.append(f"{bname} {triangles_label(*grids[grid])}: subdivision: V, E, F {b[0]:,}, {b[1]:,}, "
                         f"{b[2]:,} → {a[0]:,}, {a[1]:,}, {a[2]:,}; {r['edges']:,} split_edge + "
                         f"{3 * r['triangles']:,} split_polygon; plan read in {r['plan_seconds']:.1f} s (untimed); "
                         f"check() {r['check_seconds']:.1f} s; peak RSS {r['rss'] / 2**20:,.0f} MiB after the job, "
                         f"{r['rss_after_check'] / 2**20:,.0f} MiB after check()")


def report(bench: Bench, grids: dict, setups: dict, results: dict, subdivisions: dict) -> None:
    args, rep = bench.args, bench.report
    gates(bench, grids, setups, results, subdivisions)
    rep.title(f"hestore Euler-operator benchmark — seed {args.seed}, {args.repeat} timed calls per operator and grid "
              f"(after {args.warmup} untimed), blocks of {args.block} calls, each block one rolled-back transaction")
    rep.figures(op_figures(results, args.backends, grids), caption="""\
Operators inside an open transaction (time: the median call; p90; its CPU: the median call's CPU time in
the measuring process, without the database server's; mesh: triangles of the grid; floor: the median
add_polygon of the same grid and backend, measured in the same run — the edit SPEC §9 gives the same
target — for context; target = SPEC §9; timings exclude writing, done at commit):""")
    rep.figures(subdivision_figures(subdivisions, args.backends, grids), caption=f"""\
Whole-mesh job: {SUBDIVISION}, one transaction through the public API, commit included (time: one
run; amortised = total ÷ operators; the target is the 1,000-edit transaction's, applied):""")
    if results:
        small, large = (triangles_label(*grids[g]) for g in ("small", "large"))
        rep.table(f"Flat in mesh size: the median on each grid side by side (ratio = {large} ÷ {small} triangles; "
                  f"flat: ≤ {FLAT:g}×, applied):", ["backend", "figure", small, large, "ratio", "verdict"],
                  flat_rows(args.backends, results, subdivisions), "llrrrl")
    srows = [[bname, _label(family), Statements.per(r["statements"], unit="")]
             for (bname, grid, family), r in results.items() if r and r.get("statements") and grid == "large"]
    rep.table(f"SQL statements hestore sent on its driver cursor during one call, on the large grid ({COUNTED} calls "
              "counted in an untimed block through store.session.traced; the writes come at the flush):",
              ["backend", "figure", "statements per call"], srows, "lll")
    rep.close(ABOUT, profiles="Profiles (cProfile on during the calls only):", rss="Peak RSS of the parent")


if __name__ == "__main__":
    raise SystemExit(main())
