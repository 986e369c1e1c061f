"""Benchmark: graph views and summaries of 1 M-polygon meshes (SPEC §3, §6, §9).

    python bench/graph.py [--backends sqlite,postgresql] [--only grid,bunny,igea] [--n 710]

Meshes (``--only``), each stored once per backend before anything is timed
(``store.import_arrays`` / ``store.import_file``, untimed setup):

grid    the triangulated N×N vertex grid (``--n``, default 710: 2·709² =
        1,005,362 triangles, 1,507,333 edges);
bunny   ``stanford-bunny-subdiv2.obj`` (1.1 M triangles, boundary,
        unreferenced vertices);
igea    ``igea-subdiv1.ply`` (1.07 M triangles, closed).

The two files are read in place from ``$HESTORE_BENCH_MESHES``, else
``../shared/meshes`` next to the repository (never copied).

Figures, each on a SQLite file and on PostgreSQL, each one run in a fresh
subprocess that reports its own peak RSS and CPU time:

to_networkx("multigraph")  the first call on a fresh store (nothing cached).
        Floor = fetch + build, measured in the same run:
          fetch  ONE plain-driver query of the edge array (edge id, origin of
                 its half-edge, origin of the twin: edges joined to
                 halfedges twice) into numpy, plus the vertex query (id, x, y,
                 z) for the node variants; SQLite ``fetchall`` + ``np.array``
                 vs ``np.fromiter(cursor)``, PostgreSQL ``fetchall`` vs a
                 binary ``COPY TO`` of ``array_agg`` columns; the fastest;
          build  ``nx.MultiGraph().add_edges_from`` of ``(u, v, key)`` —
                 as triples and as 4-tuples with an empty dict (the faster
                 taken) — in three variants, each printed: the edges alone;
                 **the same nodes with the same ``pos`` attribute, then the
                 edges (the floor: what a user must build to get the same
                 nodes and edges)**; and the same graph with hestore's edge
                 attributes too (the dicts ``halfedges`` / ``polygons``).
                 Each is timed with the garbage collector paused, as hestore
                 builds; the floor variant also with it on (what plain code
                 pays; the faster of the two is the floor).
        Target (SPEC §9): ≤ 1.3× the floor.
to_networkx("graph")  likewise; floor: ``nx.Graph().add_edges_from`` of the
        unique vertex pairs (``np.unique`` in the floor), after the same
        nodes with ``pos`` (hestore's "graph" has them too); variants as
        above. No SPEC target: a ratio, no verdict.
to_networkx again  a second call on the same store (the per-revision cache):
        must be about 0 (≤ 10 ms applied) and return the same object.
stats(), boundary_loops(), components(), check()  no library floor; SPEC's
        target for stats() and check() is ≤ 10 s, set-based; it is applied to
        boundary_loops() and components() too. As context for components():
        ``nx.number_connected_components`` on the floor's "graph" (fetch +
        build + count).

Local queries (``--parts local``; SPEC §9: ``shortest_path`` of ~10 edges
≤ 50 ms and ``k_ring(v, 3)`` ≤ 5 ms on the stored mesh, cold):

shortest_path, shortest_path "length", k_ring(v, 3)
        each the first call in a fresh process on a freshly opened store
        (opening it is not timed), one process per pair; the figure is the
        median of LOCAL_RUNS pairs (random vertices ``a``, and ``b`` drawn
        among the vertices exactly PATH_EDGES edges from ``a``), the slowest
        and the warm median (the same call repeated in that process) in the
        notes. Floor = networkx on a whole graph built for the purpose:
        fetch (edge and vertex arrays) + ``nx.MultiGraph`` of the nodes and
        ``(u, v, key, {"length": …})`` edges + the query on it
        (``nx.shortest_path``, by the lightest parallel edge's length for
        "length"; ``single_source_shortest_path_length(G, v, cutoff=3)``);
        the build's time and peak RSS are printed.
to_networkx("multigraph") memory
        what the graph holds (the process's RSS after the call and a
        collection, less before it), beside the bare networkx floor:
        ``nx.MultiGraph().add_edges_from`` of the same ``(u, v, key)``
        triples, measured the same way in its own process. No SPEC target.

Correctness gates (the exit status is non-zero only when one fails or a step
crashes, never for a slow figure): both backends give the same edge array;
every graph has exactly the floor's nodes, edges, keys, ``pos`` and
attributes, and is frozen; the second call returns the same graph; stats()
agrees with counts(), with len(boundary_loops()) and len(components()), and
with networkx's component count; check() is empty; every local answer
agrees with networkx's on the floor's graph (the path joins ``a`` to ``b``
along edges of the mesh, with as many edges, or the same total length within
1e-9 relative; the k-ring is the same set).

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import contextlib
import gc
import hashlib
import os
import time
from dataclasses import dataclass, field
from itertools import islice

import networkx as nx
import numpy as np

import hestore

from floors import pg_copy_columns
from harness.bench import Bench
from harness.cli import Parser, wants_profile
from harness.databases import open_store, plain_connection, plain_mesh_id, settle, url_of, vacuum
from harness.runner import one_shot
from harness.stats import finished
from harness.tables import Figure, fmt_mib, fmt_time, verdict
from harness.timing import gc_paused, maxrss, time_each, timed
from workloads import MESHES, counts_text, import_mesh, mesh_label, present

QUICK = {"n": 100, "only": "grid", "profile": "off"}
PARTS = ("views", "summaries", "local")
TARGET_RATIO = 1.3  # to_networkx("multigraph") ÷ floor
TARGET_SECONDS = 10.0  # stats(), check() (and, applied here, boundary_loops(), components())
TARGET_CACHE = 0.010  # a second to_networkx(): "about 0"
CACHE_CALLS = 20  # repeated calls after the second one; their median is the cache figure
KEEP: list = []  # a child's graphs: left to the process's exit (see `harness.runner.run_step`)
KINDS = ("multigraph", "graph")
SUMMARIES = ("stats", "boundary_loops", "components", "check")
#: Whether each kind's nodes carry ``pos`` (SPEC §6 names it for the multigraph; hestore's "graph" has it too).
NODE_POS = {"multigraph": True, "graph": True}
#: The floor variants of each kind (for "graph", "nodes" means the nodes with pos, as hestore's) ...
FLOOR_VARIANTS = {"multigraph": ("edges", "nodes+pos", "same graph"), "graph": ("edges", "nodes", "same graph")}
#: ... and the one the ratio and the verdict use.
FLOOR_OF = {"multigraph": "nodes+pos", "graph": "nodes"}
#: The local queries (SPEC §6) and their targets in seconds (SPEC §9).
LOCAL = {"shortest_path": 0.050, 'shortest_path "length"': 0.050, "k_ring(v, 3)": 0.005}
LOCAL_RUNS = 5  # fresh processes (pairs) per local figure; the median is the figure
WARM_CALLS = 20  # the same call again in that process: the warm median, a note
PATH_EDGES = 10  # how far apart a path's two vertices are, in edges
RING = 3
ABOUT = """\
The floors add the same nodes with the same `pos` attribute as hestore's graphs (an (x, y, z) tuple per
vertex), then the (u, v, key) edges ("graph": the unique pairs); the edges-only and same-graph
(hestore's edge attributes too) variants are printed above. Builds are timed with the garbage collector
paused, as hestore builds (the multigraph floor also with it on). Peak RSS is the child process's own
ru_maxrss (the PostgreSQL server is not included); it holds the whole graph, which networkx keeps as
dicts. The cached calls are timed one by one with the garbage collector paused."""


# ==========================================================================
# The floor's queries

# The edge array: edge id, origin of its half-edge, origin of that half-edge's twin.
EDGE_COLS = ["e.id", "h0.origin", "h1.origin"]
# The same join with the columns hestore's edge attributes need (NULL polygon -> -1).
FULL_COLS = EDGE_COLS + ["h0.id", "h1.id", "coalesce(h0.polygon, -1)", "coalesce(h1.polygon, -1)"]
EDGE_FROM = ("FROM edges e JOIN halfedges h0 ON h0.mesh_id = e.mesh_id AND h0.id = e.halfedge "
             "JOIN halfedges h1 ON h1.mesh_id = h0.mesh_id AND h1.id = h0.twin WHERE e.mesh_id = {m}")
VERTEX_COLS = ["id", "x", "y", "z"]
VERTEX_FROM = "FROM vertices WHERE mesh_id = {m}"
QUERIES = {  # name -> (columns, FROM ... WHERE, dtype)
    "edges": (EDGE_COLS, EDGE_FROM, np.int64),
    "vertices": (VERTEX_COLS, VERTEX_FROM, np.float64),
    "edges+attrs": (FULL_COLS, EDGE_FROM, np.int64),
}


def fetch_fetchall(cur, cols, rest, dtype) -> np.ndarray:
    cur.execute(f"SELECT {', '.join(cols)} {rest}")
    return np.array(cur.fetchall(), dtype=dtype).reshape(-1, len(cols))


def fetch_fromiter(cur, cols, rest, dtype) -> np.ndarray:
    cur.execute(f"SELECT {', '.join(cols)} {rest}")
    return np.fromiter(cur, dtype=np.dtype((dtype, (len(cols),))))


def fetch_copy(cur, cols, rest, dtype) -> np.ndarray:
    return np.column_stack(pg_copy_columns(cur, cols, rest, [dtype] * len(cols)))


FETCHES = {
    "sqlite": {"fetchall + np.array": fetch_fetchall, "np.fromiter(cursor)": fetch_fromiter},
    "postgresql": {"fetchall + np.array": fetch_fetchall, "COPY TO of array_agg + np.frombuffer": fetch_copy},
}


# ==========================================================================
# The floor's graphs (hestore's attribute conventions are in `edge_attrs`)


@dataclass
class Arrays:
    """What the floor fetched, in the fetch's row order: edges (key, u, v, h0, h1, p0, p1), vertices (id, xyz)."""

    key: np.ndarray
    u: np.ndarray
    v: np.ndarray
    h0: np.ndarray
    h1: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    vid: np.ndarray
    xyz: np.ndarray

    @classmethod
    def load(cls, path: str) -> "Arrays":
        with np.load(path) as z:
            return cls(**{k: z[k] for k in z.files})

    def save(self, path: str) -> None:
        np.savez(path, **self.__dict__)

    def digest(self) -> str:
        """The same for the same edges and vertices in any row order.

        Positions are compared as numbers: -0.0 counts as 0.0 (SQLite stores
        -0.0 as 0.0; PostgreSQL keeps the sign).
        """
        h = hashlib.sha256()
        o = np.argsort(self.key, kind="stable")
        for a in (self.key, self.u, self.v, self.h0, self.h1, self.p0, self.p1):
            h.update(np.ascontiguousarray(a[o]).tobytes())
        o = np.argsort(self.vid, kind="stable")
        h.update(np.ascontiguousarray(self.vid[o]).tobytes())
        h.update(np.ascontiguousarray(self.xyz[o] + 0.0).tobytes())  # -0.0 + 0.0 == +0.0
        return h.hexdigest()


def node_pos(xyz: np.ndarray) -> list:
    """The ``pos`` attribute values, one per vertex (a tuple, None where the vertex has no position)."""
    pos = [tuple(p) for p in xyz.tolist()]
    missing = np.flatnonzero(np.isnan(xyz).any(axis=1)).tolist()
    for i in missing:
        pos[i] = None
    return pos


def _poly(p: int):
    return None if p < 0 else p


def edge_attrs(kind: str, a: Arrays):
    """hestore's edge attributes, for the "same graph" floors and the checks.

    "multigraph": one dict per row of ``a``; "graph": ``(lo, hi, dicts)``, one
    dict per unordered vertex pair.
    """
    if kind == "multigraph":
        return [{"halfedges": (h0, h1), "polygons": (_poly(p0), _poly(p1))}
                for h0, h1, p0, p1 in zip(a.h0.tolist(), a.h1.tolist(), a.p0.tolist(), a.p1.tolist())]
    lo, hi = np.minimum(a.u, a.v), np.maximum(a.u, a.v)
    order = np.lexsort((a.key, hi, lo))
    lo, hi, key = lo[order], hi[order], a.key[order]
    start = np.flatnonzero(np.r_[True, (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])])
    ids = iter(key.tolist())
    attrs = [{"multiplicity": c, "edges": list(islice(ids, c))} for c in np.diff(np.r_[start, len(key)]).tolist()]
    return lo[start], hi[start], attrs


def add_nodes(g, a: Arrays, pos: bool) -> None:
    if pos:
        g.add_nodes_from(zip(a.vid.astype(np.int64).tolist(), ({"pos": p} for p in node_pos(a.xyz))))
    else:
        g.add_nodes_from(a.vid.astype(np.int64).tolist())


def floor_multigraph(a: Arrays, variant: str, form: str):
    """The multigraph floor's build.

    ``variant``: "edges" / "nodes+pos" / "same graph"; ``form``: "triples" / "4-tuples".
    """
    g = nx.MultiGraph()
    if variant != "edges":
        add_nodes(g, a, NODE_POS["multigraph"])
    u, v, k = a.u.tolist(), a.v.tolist(), a.key.tolist()
    if variant == "same graph":
        g.add_edges_from(zip(u, v, k, edge_attrs("multigraph", a)))
    elif form == "triples":
        g.add_edges_from(zip(u, v, k))
    else:
        g.add_edges_from(zip(u, v, k, iter(dict, None)))
    return g


def unique_pairs(a: Arrays) -> tuple[np.ndarray, np.ndarray]:
    """The unordered vertex pairs joined by edges, each once (one int64 key per pair for ``np.unique``)."""
    lo, hi = np.minimum(a.u, a.v), np.maximum(a.u, a.v)
    base = int(hi.max()) + 1 if len(hi) else 1
    key = np.unique(lo * base + hi)
    return key // base, key % base


def floor_graph(a: Arrays, variant: str):
    """The simple-graph floor's build: ``variant`` "edges" / "nodes" / "same graph"."""
    g = nx.Graph()
    if variant != "edges":
        add_nodes(g, a, NODE_POS["graph"])
    if variant == "same graph":
        lo, hi, attrs = edge_attrs("graph", a)
        g.add_edges_from(zip(lo.tolist(), hi.tolist(), attrs))
    else:
        lo, hi = unique_pairs(a)
        g.add_edges_from(zip(lo.tolist(), hi.tolist()))
    return g


# ==========================================================================
# The untimed setup


def job_setup(spec: dict) -> dict:
    """Store the mesh (untimed setup); on PostgreSQL then VACUUM (ANALYZE), as autovacuum soon would."""
    t0 = time.perf_counter()
    with open_store(spec) as store:
        report = import_mesh(store, spec["mesh"], spec["n"], spec["dir"])
        counts = report.mesh.counts()
    seconds = time.perf_counter() - t0
    vacuum(spec)
    return {"seconds": seconds, "skipped": len(report.skipped),
            "counts": [counts.vertices, counts.halfedges, counts.edges, counts.polygons]}


# ==========================================================================
# Child jobs: floors


def job_fetch(spec: dict) -> dict:
    """Every fetch variant of the three queries, each once, in its own read snapshot; saves the arrays."""
    plain = plain_connection(spec)
    con, cur, begin = plain.con, plain.cur, plain.begin
    mesh_id = plain_mesh_id(plain, spec["mesh"])
    times: dict = {}
    out: dict = {}
    for qname, (cols, rest, dtype) in QUERIES.items():
        times[qname] = {}
        for vname, fn in FETCHES[spec["backend"]].items():
            settle(spec)
            t0 = time.perf_counter()
            cur.execute(begin)
            arr = fn(cur, cols, rest.format(m=int(mesh_id)), dtype)
            cur.execute("ROLLBACK")
            times[qname][vname] = time.perf_counter() - t0
            arr = arr[np.argsort(arr[:, 0], kind="stable")]  # the join's row order is the planner's choice
            if qname in out:
                assert np.array_equal(arr, out[qname]), f"{vname} fetched other {qname} rows"
            out[qname] = arr
    con.close()
    e, v = out["edges+attrs"], out["vertices"]
    assert np.array_equal(e[:, :3], out["edges"]), "the two edge queries disagree"
    a = Arrays(*(e[:, j].copy() for j in range(7)), v[:, 0].astype(np.int64), v[:, 1:].copy())
    if spec.get("save"):
        a.save(spec["save"])
    return {"times": times, "digest": a.digest(), "edges": len(a.key), "vertices": len(a.vid),
            "free_halfedges": int(np.count_nonzero(a.p0 < 0) + np.count_nonzero(a.p1 < 0)),
            "negative_zeros": int(np.count_nonzero((a.xyz == 0) & np.signbit(a.xyz)))}


def _timed_build(spec: dict, fn, collector: bool) -> tuple[float, float, object]:
    """Time ``fn()`` with the cyclic garbage collector on or paused (hestore pauses it while it builds)."""
    gc.collect()
    settle(spec)
    with contextlib.nullcontext() if collector else gc_paused():
        run = timed(fn)
    return run.seconds, run.cpu, run.result


def job_build(spec: dict) -> dict:
    """One build variant of one kind's floor, on the saved arrays (loading them is not timed).

    Every variant is timed with the collector paused, as hestore builds; the
    multigraph's floor variant also with it on (what plain code pays). For the
    multigraph's "edges" variant, ``(u, v, key)`` triples and ``(u, v, key,
    {})`` 4-tuples are both timed; the faster form is used by the others.
    """
    a = Arrays.load(spec["arrays"])
    kind, variant = spec["kind"], spec["variant"]
    runs: dict = {}  # label -> (seconds, cpu)
    if kind == "multigraph":
        forms = ("triples", "4-tuples") if variant == "edges" else (spec.get("form") or "4-tuples",)
        if variant == "same graph":
            forms = ("attribute dicts",)
        for form in forms:
            g = None
            t, c, g = _timed_build(spec, lambda form=form: floor_multigraph(a, variant, form), False)
            runs[f"{form}, collector paused"] = (t, c)
        if variant == FLOOR_OF[kind]:
            g = None
            t, c, g = _timed_build(spec, lambda: floor_multigraph(a, variant, forms[0]), True)
            runs[f"{forms[0]}, collector on"] = (t, c)
        best_form = min((k for k in runs if k.endswith("paused")), key=lambda k: runs[k][0]).split(",")[0]
    else:
        g = None
        t, c, g = _timed_build(spec, lambda: floor_graph(a, variant), False)
        runs["collector paused"] = (t, c)
        best_form = None
    KEEP.append(g)
    best = min(runs, key=lambda k: runs[k][0])
    out = {"runs": {k: v[0] for k, v in runs.items()}, "best": best, "seconds": runs[best][0], "cpu": runs[best][1],
           "form": best_form, "rss": maxrss(), "nodes": g.number_of_nodes(), "graph_edges": g.number_of_edges()}
    if kind == "graph" and variant == FLOOR_OF[kind]:  # context for components(): networkx's own count
        t0 = time.perf_counter()
        out["ncc"] = nx.number_connected_components(g)
        out["ncc_seconds"] = time.perf_counter() - t0
    return out


# ==========================================================================
# Child jobs: hestore


def verify_graph(kind: str, g, a: Arrays) -> list[str]:
    """Differences between hestore's graph and the floor's arrays (empty when the same).

    One pass over the graph's edges into numpy columns, compared with the
    arrays sorted the same way: nodes, ``pos``, keys, end points and every
    edge attribute.
    """
    bad = []
    if not nx.is_frozen(g):
        bad.append("not frozen")
    if g.graph.get("kind") != kind:
        bad.append(f"G.graph = {g.graph!r}")
    want_type = nx.MultiGraph if kind == "multigraph" else nx.Graph
    if type(g) is not want_type:
        bad.append(f"a {type(g).__name__}, not a {want_type.__name__}")
        return bad
    vid = a.vid.astype(np.int64)
    nodes = np.fromiter(g.nodes, dtype=np.int64, count=g.number_of_nodes())
    if not np.array_equal(np.sort(nodes), np.sort(vid)):
        bad.append(f"nodes: {len(nodes):,} vs {len(vid):,} vertices, or other ids")
        return bad
    if NODE_POS[kind]:
        gn = g.nodes
        if any(gn[i].get("pos") != p for i, p in zip(vid.tolist(), node_pos(a.xyz))):
            bad.append("node pos")
    elif any(d for _, d in g.nodes(data=True)):
        bad.append("node attributes the benchmark does not expect: update NODE_POS")
    lo, hi = np.minimum(a.u, a.v), np.maximum(a.u, a.v)
    if kind == "multigraph":
        def row(u, v, k, d):
            (h0, h1), (p0, p1) = d["halfedges"], d["polygons"]
            return (k, min(u, v), max(u, v), h0, h1, -1 if p0 is None else p0, -1 if p1 is None else p1, len(d))

        got = np.array([row(*e) for e in g.edges(keys=True, data=True)], dtype=np.int64).reshape(-1, 8)
        got = got[np.argsort(got[:, 0], kind="stable")]
        o = np.argsort(a.key, kind="stable")
        want = np.column_stack([a.key[o], lo[o], hi[o], a.h0[o], a.h1[o], a.p0[o], a.p1[o], np.full(len(o), 2)])
        if got.shape != want.shape:
            bad.append(f"{len(got):,} edges, {len(want):,} expected")
        else:
            for j, name in enumerate(("keys", "end points", "end points", "halfedges", "halfedges", "polygons",
                                      "polygons", "attribute names")):
                if not np.array_equal(got[:, j], want[:, j]):
                    bad.append(f"edge {name}")
                    break
    else:
        rows, flat = [], []
        for u, v, d in g.edges(data=True):
            rows.append((min(u, v), max(u, v), d["multiplicity"], len(d["edges"]), len(d)))
            flat += d["edges"]
        got = np.array(rows, dtype=np.int64).reshape(-1, 5)
        ids = np.array(flat, dtype=np.int64)
        start = np.r_[0, np.cumsum(got[:, 3])[:-1]]
        o = np.lexsort((got[:, 1], got[:, 0]))
        got, start = got[o], start[o]
        ids = ids[np.repeat(start - np.r_[0, np.cumsum(got[:, 3])[:-1]], got[:, 3]) + np.arange(len(ids))]
        order = np.lexsort((a.key, hi, lo))
        slo, shi, skey = lo[order], hi[order], a.key[order]
        first = np.r_[True, (slo[1:] != slo[:-1]) | (shi[1:] != shi[:-1])]
        mult = np.diff(np.r_[np.flatnonzero(first), len(skey)])
        if len(got) != len(mult):
            bad.append(f"{len(got):,} edges, {len(mult):,} vertex pairs")
        elif not (np.array_equal(got[:, 0], slo[first]) and np.array_equal(got[:, 1], shi[first])):
            bad.append("end points")
        elif not (np.array_equal(got[:, 2], mult) and np.array_equal(got[:, 3], mult)):
            bad.append("multiplicity")
        elif not np.array_equal(ids, skey):
            bad.append("edges (the ids, ascending)")
        elif not (got[:, 4] == 2).all():
            bad.append("attribute names")
    return bad


def job_to_networkx(spec: dict) -> dict:
    kind = spec["kind"]
    with open_store(spec) as store:
        mesh = store.mesh(spec["mesh"])
        g, out = one_shot(spec, lambda: mesh.to_networkx(kind), profile=spec.get("profile", False))
        # The cache: the second call, then CACHE_CALLS more (their median is the figure).
        calls, again, _ = time_each(lambda _: mesh.to_networkx(kind), range(1 + CACHE_CALLS))
        same_object = all(x is g for x in again)
        del again
        cached = [c / 1e9 for c in calls[1:]]
        out.update(second_call=calls[0] / 1e9, cached=float(np.median(cached)), cached_max=max(cached),
                   same_object=same_object, nodes=g.number_of_nodes(), graph_edges=g.number_of_edges())
    if not spec.get("profile"):
        out["mismatch"] = verify_graph(kind, g, Arrays.load(spec["arrays"]))
    KEEP.extend((store, g))  # freed by the process's exit, not timed, not waited for
    return out


def _summary_result(what: str, result) -> dict:
    if what == "stats":
        d = dict(result.__dict__)
        d["polygon_sizes"] = {str(k): v for k, v in d["polygon_sizes"].items()}
        return {"stats": d}
    if what == "boundary_loops":
        return {"count": len(result), "halfedges": sum(len(x) for x in result)}
    if what == "components":
        return {"count": len(result), "vertices": sum(len(x) for x in result),
                "largest": max(map(len, result), default=0)}
    return {"violations": len(result), "examples": [str(v) for v in result[:5]]}


def job_summary(spec: dict) -> dict:
    what = spec["what"]
    with open_store(spec) as store:
        result, out = one_shot(spec, getattr(store.mesh(spec["mesh"]), what), profile=spec.get("profile", False))
        out.update(_summary_result(what, result))
    return out


# ==========================================================================
# Local queries (SPEC §6) and memory


def lightest_length(u, v, keydict) -> float:
    """The weight of ``graph … path --weight length``: the lightest parallel edge's length."""
    return min(d["length"] for d in keydict.values())


def job_local_floor(spec: dict) -> dict:
    """networkx's answers on a whole graph built for the purpose; picks the pairs (a, b PATH_EDGES apart)."""
    a = Arrays.load(spec["arrays"])
    xyz = a.xyz[np.searchsorted(a.vid, a.u)], a.xyz[np.searchsorted(a.vid, a.v)]
    lengths = np.sqrt(((xyz[0] - xyz[1]) ** 2).sum(axis=1))

    def build():
        g = nx.MultiGraph()
        add_nodes(g, a, True)
        g.add_edges_from(zip(a.u.tolist(), a.v.tolist(), a.key.tolist(), ({"length": x} for x in lengths.tolist())))
        return g

    gc.collect()
    with gc_paused():
        run = timed(build)
    g = run.result
    rng = np.random.default_rng(spec["seed"])
    joined = np.unique(np.concatenate([a.u, a.v]))
    pairs, queries = [], {name: [] for name in LOCAL}
    while len(pairs) < LOCAL_RUNS:
        s = int(rng.choice(joined))
        t0 = time.perf_counter()
        ring = nx.single_source_shortest_path_length(g, s, cutoff=RING)
        queries["k_ring(v, 3)"].append(time.perf_counter() - t0)
        far = [v for v, d in nx.single_source_shortest_path_length(g, s, cutoff=PATH_EDGES).items() if d == PATH_EDGES]
        if not far:
            continue
        t = int(far[int(rng.integers(len(far)))])
        t0 = time.perf_counter()
        hops = len(nx.shortest_path(g, s, t)) - 1
        queries["shortest_path"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        path = nx.shortest_path(g, s, t, weight=lightest_length)
        queries['shortest_path "length"'].append(time.perf_counter() - t0)
        total = sum(lightest_length(u, v, g[u][v]) for u, v in zip(path, path[1:]))
        pairs.append({"a": s, "b": t, "edges": hops, "length": total, "ring": sorted(ring)})
    KEEP.append(g)
    return {"build": run.seconds, "rss": maxrss(), "pairs": pairs,
            "queries": {k: float(np.median(v)) for k, v in queries.items()}}


def job_local(spec: dict) -> dict:
    """One local query, cold: the first call in this process on a freshly opened store; then warm calls."""
    pair, query = spec["pair"], spec["query"]
    with open_store(spec) as store:
        mesh = store.mesh(spec["mesh"])
        a, b = hestore.Vertex(mesh, pair["a"]), hestore.Vertex(mesh, pair["b"])
        if query == "k_ring(v, 3)":
            def call():
                return sorted(v.id for v in mesh.k_ring(a, RING))
        else:
            weight = "length" if "length" in query else None

            def call():
                return [v.id for v in mesh.shortest_path(a, b, weight)]

        answer, out = one_shot(spec, call, profile=spec.get("profile", False))
        calls, _, _ = time_each(lambda _: call(), range(WARM_CALLS))
    problems = path_problems(Arrays.load(spec["arrays"]), pair, query, answer)  # after the timing
    return dict(out, problems=problems, warm=float(np.median(calls)) / 1e9)


def current_rss() -> int:
    """This process's resident set now, in bytes (Linux ``/proc/self/statm``)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def job_memory(spec: dict) -> dict:
    """What one graph holds in RSS: hestore's ``to_networkx("multigraph")``, or the bare networkx floor."""
    if spec["variant"] == "bare":
        a = Arrays.load(spec["arrays"])
        u, v, k = a.u, a.v, a.key
        gc.collect()
        before = current_rss()
        with gc_paused():
            g = nx.MultiGraph()
            g.add_edges_from(zip(u.tolist(), v.tolist(), k.tolist()))
    else:
        store = hestore.open(url_of(spec))
        mesh = store.mesh(spec["mesh"])
        gc.collect()
        before = current_rss()
        g = mesh.to_networkx("multigraph")
        KEEP.append(store)
    gc.collect()
    held = current_rss() - before
    KEEP.append(g)
    return {"held": held, "peak": maxrss(), "nodes": g.number_of_nodes(), "graph_edges": g.number_of_edges()}


def path_problems(a: Arrays, pair: dict, query: str, answer: list[int]) -> list[str]:
    """How a local answer differs from networkx's (empty when it agrees)."""
    if query == "k_ring(v, 3)":
        return [] if answer == pair["ring"] else [f"k_ring has {len(answer)} vertices, networkx {len(pair['ring'])}"]
    if not answer or answer[0] != pair["a"] or answer[-1] != pair["b"]:
        return [f"the path does not run from {pair['a']} to {pair['b']}: {answer[:3]} … {answer[-3:]}"]
    p = np.array(answer, dtype=np.int64)
    lo, hi = np.minimum(p[:-1], p[1:]), np.maximum(p[:-1], p[1:])
    base = int(max(a.u.max(), a.v.max())) + 1
    edges = np.minimum(a.u, a.v) * base + np.maximum(a.u, a.v)
    if not np.isin(lo * base + hi, edges).all():
        return ["the path steps between vertices no edge joins"]
    if "length" not in query:
        ok = len(answer) - 1 == pair["edges"]
        return [] if ok else [f"the path has {len(answer) - 1} edges, networkx's {pair['edges']}"]
    xyz = a.xyz[np.searchsorted(a.vid, p)]
    total = float(np.sqrt(((xyz[1:] - xyz[:-1]) ** 2).sum(axis=1)).sum())
    ok = abs(total - pair["length"]) <= 1e-9 * max(1.0, pair["length"])
    return [] if ok else [f"the path is {total!r} long, networkx's {pair['length']!r}"]


JOBS = {"setup": job_setup, "fetch": job_fetch, "build": job_build, "to_networkx": job_to_networkx,
        "summary": job_summary, "local_floor": job_local_floor, "local": job_local, "memory": job_memory}


# ==========================================================================
# The parent



def fetch_best(fetch: dict, query: str) -> tuple[float, str]:
    t = fetch["times"][query]
    best = min(t, key=t.get)
    return t[best], best


def floor_of(kind: str, variant: str, fetch: dict | None, build: dict | None) -> tuple[float, str] | None:
    """fetch + build of one floor variant: (seconds, its parts)."""
    if not fetch or not build:
        return None
    queries = ["edges+attrs" if variant == "same graph" else "edges"]
    if variant != "edges":
        queries.append("vertices")
    total, parts = 0.0, []
    for q in queries:
        t, how = fetch_best(fetch, q)
        total += t
        parts.append(f"fetch {q} {t:.2f} ({how})")
    what = {"edges": "edges only", "nodes+pos": "nodes with pos + edges", "nodes": "nodes with pos + unique pairs",
            "same graph": "the same graph, attributes included"}[variant]
    parts.append(f"build {build['seconds']:.2f} ({what}; {build['best']})")
    return total + build["seconds"], " + ".join(parts)


@dataclass
class Results:
    """What the steps of a run gave back, filled as they finish (a failed step leaves None)."""

    setups: dict = field(default_factory=dict)  # (backend, mesh) -> result
    fetches: dict = field(default_factory=dict)  # (backend, mesh) -> result
    builds: dict = field(default_factory=dict)  # (mesh, kind, variant), (mesh, "local"|"memory") -> result
    figures: dict = field(default_factory=dict)  # (backend, mesh, figure) -> result (list of results: local)
    arrays: dict = field(default_factory=dict)  # mesh -> path of the saved floor arrays


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, meshes=MESHES, jobs=JOBS,
                workdir_help="where SQLite files and arrays go (default: a temporary folder, removed at the end)",
                profile="rerun a figure under cProfile when it is over its target (default), always, or never")
    ap.add_argument("--parts", default=",".join(PARTS),
                    help="what to measure: views (to_networkx and its floors), summaries, local (the local "
                         "queries and to_networkx's memory) (default all)")
    ap.add_argument("--seed", type=int, default=1, help="random seed of the local queries' pairs (default 1)")
    args = ap.parse_args(argv)
    parts = ap.names(args.parts, PARTS, "part")
    only, missing = present(args.only, args.meshes_dir)

    found = Results()
    with Bench(args, "graph", __file__, clean=("graph_", "arrays-", "result-")) as bench:
        bench.report.skipped.extend(missing)
        for place in bench.for_each_backend():
            for m in only:
                spec = dict(n=args.n, dir=args.meshes_dir, mesh=m, **place.fresh(f"graph_{m}"))
                run_mesh(bench, spec, parts, found)
                place.drop(spec)
    report(bench, only, found)
    return bench.finish(meshes=args.meshes_dir, libraries=f"networkx {nx.__version__}")


def run_mesh(bench: Bench, spec: dict, parts: list[str], found: Results) -> None:
    """Every step of one mesh on one backend: its setup, the fetch floor, then the parts asked for."""
    run, bname, m = bench.runner.run, spec["backend"], spec["mesh"]
    found.setups[(bname, m)] = setup = run(job="setup", **spec)
    if setup is None:
        return
    first = m not in found.arrays
    if first:
        found.arrays[m] = os.path.join(bench.workdir, f"arrays-{m}.npz")
    found.fetches[(bname, m)] = run(job="fetch", save=found.arrays[m] if first else None, **spec)
    if found.fetches[(bname, m)] is None and first:
        del found.arrays[m]
        return
    spec["arrays"] = found.arrays[m]
    if "local" in parts:
        run_local(bench, spec, first, found)
    for kind in KINDS if "views" in parts else ():
        if first:  # the builds do not depend on the backend: once per mesh
            form = None
            for variant in FLOOR_VARIANTS[kind]:
                r = run(job="build", kind=kind, variant=variant, form=form, **dict(spec, backend=None))
                found.builds[(m, kind, variant)] = r
                if r and variant == "edges" and kind == "multigraph":
                    form = r["form"]
        found.figures[(bname, m, kind)] = run(job="to_networkx", kind=kind, **spec)
    for what in SUMMARIES if "summaries" in parts else ():
        found.figures[(bname, m, what)] = run(job="summary", what=what, **spec)
    # Profiles of whatever is over its target.
    for key in [*KINDS, *SUMMARIES]:
        r = found.figures.get((bname, m, key))
        if not r:
            continue
        if key in KINDS:
            fl = floor_of(key, FLOOR_OF[key], found.fetches.get((bname, m)), found.builds.get((m, key, FLOOR_OF[key])))
            over = key == "multigraph" and fl is not None and r["seconds"] > TARGET_RATIO * fl[0]
        else:
            over = r["seconds"] > TARGET_SECONDS
        if wants_profile(bench.args, over):
            job, extra = ("to_networkx", {"kind": key}) if key in KINDS else ("summary", {"what": key})
            p = run(job=job, profile=True, **extra, **spec)
            if p:
                bench.report.profiles.append((f"{bname} {mesh_label(m, bench.args.n)}: {figure_name(key)} under "
                                              f"cProfile ({p['seconds']:.2f} s with the profiler on, "
                                              f"{r['seconds']:.2f} s without)", p["dominant"], p["profile"]))


def run_local(bench: Bench, spec: dict, first: bool, found: Results) -> None:
    """The local queries' floor (once per mesh), each query cold in LOCAL_RUNS fresh processes, and the memory."""
    run, bname, m, args = bench.runner.run, spec["backend"], spec["mesh"], bench.args
    if first:
        found.builds[(m, "local")] = run(job="local_floor", seed=args.seed, **dict(spec, backend=None))
        found.builds[(m, "memory")] = run(job="memory", variant="bare", **dict(spec, backend=None))
    floor = found.builds.get((m, "local"))
    if not floor:
        return
    for query, target in LOCAL.items():
        runs = [run(job="local", query=query, pair=pair, **spec) for pair in floor["pairs"]]
        found.figures[(bname, m, query)] = runs
        slow = [r for r in runs if r and r["seconds"] > target]
        if wants_profile(args, bool(slow)):
            pair = floor["pairs"][runs.index(slow[0]) if slow else 0]
            p = run(job="local", query=query, pair=pair, profile=True, **spec)
            if p:
                bench.report.profiles.append((f"{bname} {mesh_label(m, args.n)}: {query} under cProfile "
                                              f"({p['seconds'] * 1e3:.2f} ms with the profiler on)", p["dominant"],
                                              p["profile"]))
    found.figures[(bname, m, "memory")] = run(job="memory", variant="to_networkx", **spec)


def local_figures(bench: Bench, bname: str, m: str, fetch: dict | None, found: Results) -> list[Figure]:
    """The local queries' figures of one mesh on one backend, their notes and gates, and the memory note."""
    rep, label = bench.report, mesh_label(m, bench.args.n)
    floor = found.builds.get((m, "local"))
    if not floor:
        return []
    figures = []
    fe = fetch_best(fetch, "edges")[0] + fetch_best(fetch, "vertices")[0] if fetch else None
    for query, target in LOCAL.items():
        runs = finished(found.figures, (bname, m, query))
        if not runs:
            continue
        cold = sorted(r["seconds"] for r in runs)
        median_cold = cold[len(cold) // 2]
        q = floor["queries"][query]
        total = None if fe is None else fe + floor["build"] + q
        parts = (f"fetch {fe:.2f} + nx.MultiGraph with lengths {floor['build']:.2f} (peak RSS "
                 f"{fmt_mib(floor['rss'])}) + the query {fmt_time(q)}") if fe is not None else ""
        figures.append(Figure(f"{query}, cold", bname, median_cold, total, f"≤ {target * 1e3:g} ms",
                              verdict(median_cold <= target), label, n=len(runs),
                              cpu=float(np.median([r["cpu"] for r in runs])), floor_parts=parts))
        rep.notes.append(f"{bname} {label}: {query}: cold {', '.join(fmt_time(c) for c in cold)} ({len(runs)} "
                         f"{bench.runner.process}es, the median is the figure); warm (the same call again, median of "
                         f"{WARM_CALLS}) {fmt_time(float(np.median([r['warm'] for r in runs])))}; networkx on its "
                         f"prebuilt graph {fmt_time(q)}")
        for pair, r in zip(floor["pairs"], found.figures.get((bname, m, query)) or []):
            if r:
                rep.problems += [f"{bname} {label}: {query} from {pair['a']} to {pair['b']}: {x}"
                                 for x in r["problems"]]
    mem, bare = found.figures.get((bname, m, "memory")), found.builds.get((m, "memory"))
    if mem and bare:
        rep.notes.append(f"{bname} {label}: MEMORY to_networkx(\"multigraph\") holds {fmt_mib(mem['held'])} (RSS "
                         f"after − before; peak RSS {fmt_mib(mem['peak'])}); floor: the bare nx.MultiGraph()."
                         f"add_edges_from((u, v, key)) {fmt_mib(bare['held'])} (peak {fmt_mib(bare['peak'])}): "
                         f"{mem['held'] / bare['held']:.2f}× (no SPEC target)")
    return figures


def figure_name(key: str) -> str:
    return f'to_networkx("{key}")' if key in KINDS else f"{key}()"


def view_figures(bench: Bench, bname: str, m: str, fetch: dict | None, found: Results,
                 variant_rows: list) -> list[Figure]:
    """The to_networkx figures of one mesh on one backend (first call, then cached), their gates and notes, and
    a row per floor variant."""
    rep, label = bench.report, mesh_label(m, bench.args.n)
    figures = []
    for kind in KINDS:
        r = found.figures.get((bname, m, kind))
        if not r:
            continue
        fl = floor_of(kind, FLOOR_OF[kind], fetch, found.builds.get((m, kind, FLOOR_OF[kind])))
        ok, target = None, "— (none in SPEC)"
        if kind == "multigraph":
            target = "≤ 1.3× floor"
            if fl:
                ok = r["seconds"] <= TARGET_RATIO * fl[0]
        figures.append(Figure(f'to_networkx("{kind}")', bname, r["seconds"], fl[0] if fl else None, target,
                              verdict(ok), label, cpu=r["cpu"], rss=r["rss"], floor_parts=fl[1] if fl else "missing"))
        figures.append(Figure(f'to_networkx("{kind}") again (cache)', bname, r["cached"], None,
                              "≈ 0 (≤ 10 ms), same object", verdict(r["cached"] <= TARGET_CACHE and r["same_object"]),
                              label, n=CACHE_CALLS))
        rep.notes.append(f"{bname} {label}: to_networkx(\"{kind}\") cached: the second call "
                         f"{fmt_time(r['second_call'])}; {CACHE_CALLS} more: median {fmt_time(r['cached'])} "
                         f"(the figure), slowest {fmt_time(r['cached_max'])}")
        if not r["same_object"]:
            rep.problems.append(f"{bname} {label}: a second to_networkx(\"{kind}\") returned another object")
        if r.get("mismatch"):
            rep.problems.append(f"{bname} {label}: to_networkx(\"{kind}\") differs from the floor's graph in "
                                f"{'; '.join(r['mismatch'])}")
        rep.notes.append(f"{bname} {label}: to_networkx(\"{kind}\") {r['nodes']:,} nodes, "
                         f"{r['graph_edges']:,} edges; RSS {fmt_mib(r['rss_before'])} before the call, "
                         f"{fmt_mib(r['rss'])} after")
        for variant in FLOOR_VARIANTS[kind]:
            b = found.builds.get((m, kind, variant))
            f = floor_of(kind, variant, fetch, b)
            if not f:
                continue
            runs = ", ".join(f"{k} {v:.2f} s" for k, v in b["runs"].items())
            variant_rows.append([bname, label, kind, variant + (" ← floor" if variant == FLOOR_OF[kind] else ""),
                                 fmt_time(f[0]), f"build {runs}", fmt_mib(b["rss"]), f"{r['seconds'] / f[0]:.2f}×"])
    return figures


def summary_figures(bench: Bench, bname: str, m: str, fetch: dict | None, found: Results) -> list[Figure]:
    """The four summaries' figures of one mesh on one backend, and their cross-checks."""
    label = mesh_label(m, bench.args.n)
    ctx = found.builds.get((m, "graph", "nodes"))
    figures = []
    for what in SUMMARIES:
        r = found.figures.get((bname, m, what))
        if not r:
            continue
        floor, parts = None, ""
        if what == "components" and ctx and fetch and "ncc" in ctx:
            fe, fv = fetch_best(fetch, "edges")[0], fetch_best(fetch, "vertices")[0]
            floor = fe + fv + ctx["seconds"] + ctx["ncc_seconds"]
            parts = (f"context: fetch {fe + fv:.2f} + nx.Graph {ctx['seconds']:.2f} + "
                     f"number_connected_components {ctx['ncc_seconds']:.2f}")
        applied = "" if what in ("stats", "check") else " (applied)"
        figures.append(Figure(f"{what}()", bname, r["seconds"], floor, f"≤ 10 s{applied}",
                              verdict(r["seconds"] <= TARGET_SECONDS), label, cpu=r["cpu"], rss=r["rss"],
                              floor_parts=parts))
    if figures:
        bench.report.problems += summary_problems(bname, m, label, bench.args.n, found.setups[(bname, m)], fetch,
                                                  ctx, {w: found.figures.get((bname, m, w)) for w in SUMMARIES},
                                                  bench.report.notes)
    return figures


def fetch_rows(n: int, fetches: dict) -> list[list[str]]:
    """Every fetch variant of every backend and mesh, the one used marked."""
    rows = []
    for (bname, m), fetch in fetches.items():
        if not fetch:
            continue
        for q, t in fetch["times"].items():
            best = min(t, key=t.get)
            for name, s in t.items():
                rows.append([bname, mesh_label(m, n), q, name, fmt_time(s), "← used" if name == best else ""])
    return rows


def report(bench: Bench, only: list[str], found: Results) -> None:
    args, rep = bench.args, bench.report
    figures: list[Figure] = []
    variant_rows: list[list[str]] = []
    digests: dict = {}
    zeros: dict = {}
    for bname in args.backends:
        for m in only:
            setup = found.setups.get((bname, m))
            if not setup:
                continue
            label = mesh_label(m, args.n)
            V, H, E, P = setup["counts"]
            rep.notes.append(f"{bname} {label}: stored in {setup['seconds']:.1f} s (setup, not a figure): "
                             f"{counts_text(setup['counts'])}"
                             + (f", {setup['skipped']} polygons skipped" if setup["skipped"] else ""))
            fetch = found.fetches.get((bname, m))
            if fetch:
                digests.setdefault(m, {})[bname] = fetch["digest"]
                zeros.setdefault(m, {})[bname] = fetch["negative_zeros"]
                if fetch["edges"] != E or fetch["vertices"] != V:
                    rep.problems.append(f"{bname} {label}: the floor fetched {fetch['edges']:,} edges / "
                                        f"{fetch['vertices']:,} vertices, counts() says {E:,} / {V:,}")
            figures += view_figures(bench, bname, m, fetch, found, variant_rows)
            figures += summary_figures(bench, bname, m, fetch, found)
            figures += local_figures(bench, bname, m, fetch, found)
    for m, d in digests.items():
        if len(set(d.values())) > 1:
            rep.problems.append(f"{mesh_label(m, args.n)}: the backends store different edge arrays or positions")
        elif len(d) > 1:
            rep.notes.append(f"{mesh_label(m, args.n)}: both backends store the same edges, half-edges, polygons and "
                             "positions")
        if len(set(zeros[m].values())) > 1:
            rep.notes.append(f"{mesh_label(m, args.n)}: -0.0 coordinates stored: "
                             + ", ".join(f"{b} {z}" for b, z in zeros[m].items())
                             + " (SQLite stores -0.0 as 0.0; compared as numbers they are equal)")

    rep.title(f"hestore graph views and summaries benchmark — every figure one run in a {bench.runner.process}")
    rep.figures(figures, after="""\
(time: wall clock; its CPU: user + system time of the measuring process alone, without the database
 server's, a hint of how much other load on the machine slowed the wall clock down)""")
    rep.table("Graph floors, every variant (fetch of this backend + build, the build once per mesh in its own "
              "process;\nthe ratio is hestore's first to_networkx call ÷ that variant):",
              ["backend", "mesh", "kind", "variant", "floor", "its build", "build's peak RSS", "hestore ÷"],
              variant_rows, "lllllllr")
    rep.table("Fetch variants (one plain-driver query each, in its own read snapshot, one run each; the fastest is "
              "used):", ["backend", "mesh", "query", "variant", "time", ""], fetch_rows(args.n, found.fetches),
              "llllrl")
    rep.close(ABOUT, profiles="Profiles of the figures over their target, each rerun under cProfile:")


def summary_problems(bname, m, label, n, setup, fetch, ctx, r, notes) -> list[str]:
    """Cross-checks of the four summaries with each other, with counts(), the floor and (grid) known topology."""
    problems = []
    V, H, E, P = setup["counts"]
    st = r["stats"]["stats"] if r.get("stats") else None
    if st:
        notes.append(f"{bname} {label}: stats() = " + ", ".join(f"{k}={v}" for k, v in st.items()))
        got = (st["vertices"], st["halfedges"], st["edges"], st["polygons"])
        if got != (V, H, E, P):
            problems.append(f"{bname} {label}: stats() counts V/H/E/P {got} vs counts() {(V, H, E, P)}")
        expect = {}
        if ctx and "ncc" in ctx:
            expect["components"] = ctx["ncc"]
        if r.get("boundary_loops"):
            expect["boundary_loops"] = r["boundary_loops"]["count"]
        if r.get("components"):
            expect["components"] = r["components"]["count"]
        if m == "grid":
            expect.update(boundary_loops=1, components=1, euler_characteristic=1, genus=0, is_closed=False,
                          is_manifold=True, boundary_edges=4 * (n - 1), isolated_vertices=0)
        if fetch:
            expect["boundary_edges"] = expect.get("boundary_edges", fetch["free_halfedges"] - 2 * st["wire_edges"])
        for k, v in expect.items():
            if st[k] != v:
                problems.append(f"{bname} {label}: stats().{k} = {st[k]}, expected {v}")
    bl = r.get("boundary_loops")
    if bl:
        notes.append(f"{bname} {label}: boundary_loops() {bl['count']:,} loops, {bl['halfedges']:,} half-edges")
        if fetch and bl["halfedges"] != fetch["free_halfedges"]:
            problems.append(f"{bname} {label}: boundary_loops() holds {bl['halfedges']:,} half-edges, "
                            f"the mesh has {fetch['free_halfedges']:,} free ones")
    cc = r.get("components")
    if cc:
        notes.append(f"{bname} {label}: components() {cc['count']:,} components, the largest {cc['largest']:,} "
                     "vertices")
        if cc["vertices"] != V:
            problems.append(f"{bname} {label}: components() cover {cc['vertices']:,} vertices of {V:,}")
        if ctx and "ncc" in ctx and cc["count"] != ctx["ncc"]:
            problems.append(f"{bname} {label}: components() gives {cc['count']:,}, networkx {ctx['ncc']:,}")
    ch = r.get("check")
    if ch and ch["violations"]:
        problems.append(f"{bname} {label}: check() found {ch['violations']} violations, e.g. {ch['examples']}")
    return problems


if __name__ == "__main__":
    raise SystemExit(main())
