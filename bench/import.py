"""Benchmark: bulk import, to_arrays and export of 1 M-polygon meshes (SPEC §5, §9).

    python bench/import.py [--backends sqlite,postgresql] [--only grid,bunny,igea] [--n 710]

Meshes (``--only``):

grid    the triangulated N×N vertex grid (``--n``, default 710: 2·709² =
        1,005,362 triangles), positions and an (F, 3) int64 array made before
        the timed region, stored with ``store.import_arrays``;
bunny   ``stanford-bunny-subdiv2.obj`` (ASCII OBJ, 1.1 M triangles, boundary,
        unreferenced vertices), stored with ``store.import_file``;
igea    ``igea-subdiv1.ply`` (binary PLY, 1.07 M triangles, closed), stored
        with ``store.import_file``.

The two files are read in place from ``$HESTORE_BENCH_MESHES``, else
``../shared/meshes`` next to the repository (never copied).

Figures, each on a SQLite file and on PostgreSQL, each run in a fresh
subprocess that reports its own peak RSS and CPU time:

import      hestore's import into a fresh database, commit included (and, on
            PostgreSQL, the ANALYZE hestore runs after it).
            Floor = numpy build + insert (+ parse for a file):
              parse   the fastest few-line numpy parse of the file (OBJ:
                      ``np.fromstring`` / ``np.loadtxt`` of the ``v`` and ``f``
                      blocks; PLY: ``np.frombuffer`` with the header's dtype);
              build   a minimal numpy half-edge builder for manifold input
                      (`numpy_build`: seed 003's twin matching by sorting, no
                      validation), checked to give the same arrays as
                      `hestore.build.build`;
              insert  the same rows, with the same values, written with the
                      plain driver into a fresh database with hestore's schema
                      in one transaction: SQLite ``executemany`` or multi-row
                      ``VALUES``; PostgreSQL ``COPY`` with ``write_row`` or a
                      binary buffer assembled with numpy — each measured, the
                      faster taken.
            Target (SPEC §9): ≤ 2× floor and peak RSS ≤ 1.5 GB.
to_arrays   ``mesh.to_arrays()`` of the imported mesh. Floor: the plain-driver
            SELECT of the columns it needs (vertex positions, half-edge origin
            and next, polygon half-edge) into numpy. No SPEC target.
export      ``mesh.export`` to binary .ply and to .obj. Floor: the SELECT floor
            plus writing the same arrays (.ply: a few-line numpy writer; .obj:
            ``formats.write``, hestore's own writer, as no independent floor
            exists). No SPEC target.

After each import, ``mesh.check()`` must come back empty (a correctness gate,
timed but not a figure); to_arrays and a re-read of each exported file must
give back the input arrays. The output ends with a markdown table and notes on
the machine. Exit status is non-zero only when something is wrong (a failed
step, a violation, a mismatch), never for a slow figure.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import os
import sqlite3
import time
import warnings
from dataclasses import dataclass

import numpy as np
import sqlalchemy as sa

import hestore
from hestore import io as formats
from hestore import schema
from hestore.arrays import Ragged
from hestore.build import build

from floors import PGCOPY_HEADER, by_id, pg_copy_columns
from harness.bench import Bench
from harness.cli import Parser, wants_profile
from harness.databases import (
    open_store,
    pg_connect,
    pg_drop_schema,
    pg_fresh_schema,
    plain_connection,
    plain_mesh_id,
    remove_sqlite,
    settle,
    sqlite_connect,
    sqlite_url,
)
from harness.runner import log, one_shot
from harness.tables import Figure, fmt_time, verdict
from harness.timing import best_of, timed
from workloads import FILES, MESHES, counts_text, grid_arrays, import_mesh, mesh_label, present, timed_check

TARGET_RATIO = 2.0
TARGET_RSS = 1.5e9  # bytes ("1.5 GB")
CHUNK_ROWS = 131072  # rows per batch in the driver floors, as hestore's writer
VALUES_ROWS = 1000  # rows per multi-row INSERT (capped by SQLite's variable limit)
QUICK = {"n": 100, "only": "grid", "profile": "off"}
ABOUT = """\
Import targets are SPEC §9's (stated for SQLite and the OBJ); they are applied to PostgreSQL and to the
PLY as well. Peak RSS is the child process's own ru_maxrss (the PostgreSQL server is not included);
1.5 GB = 1.5e9 bytes = 1,431 MiB. to_arrays/export floors exclude walking the polygon loops, which
hestore must do (it stores next pointers, not corner lists). The .obj write 'floor' is formats.write,
hestore's own writer: that ratio shows only what export adds around it."""


# ==========================================================================
# Inputs


@dataclass
class Input:
    positions: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray
    faces: np.ndarray | None  # the (F, k) array given to import_arrays (grid only)
    path: str | None


def load_input(spec: dict) -> Input:
    if spec["mesh"] == "grid":
        pos, faces = grid_arrays(spec["n"])
        return Input(pos, np.arange(len(faces) + 1, dtype=np.int64) * 3, faces.reshape(-1), faces, None)
    path = os.path.join(spec["dir"], FILES[spec["mesh"]])
    soup = formats.read(path)
    return Input(soup.positions, soup.offsets, soup.indices, None, path)


# ==========================================================================
# Floors: parsing


def _obj_blocks(path: str) -> tuple[bytes, bytes]:
    """The ``v`` lines and the ``f`` lines of an OBJ whose vertices all come before its faces."""
    with open(path, "rb") as f:
        data = f.read()
    v0 = 0 if data.startswith(b"v ") else data.find(b"\nv ") + 1
    f0 = data.find(b"\nf ") + 1
    return data[v0:f0], data[f0:]


def parse_obj_fromstring(path: str):
    """OBJ of ``v x y z`` then ``f a b c`` lines: drop the letters, ``np.fromstring`` each block."""
    vs, fs = _obj_blocks(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        pos = np.fromstring(vs.replace(b"v", b" "), dtype=np.float64, sep=" ").reshape(-1, 3)
        idx = np.fromstring(fs.replace(b"f", b" "), dtype=np.int64, sep=" ") - 1
    return pos, np.arange(len(idx) // 3 + 1, dtype=np.int64) * 3, idx


def parse_obj_loadtxt(path: str):
    """The same blocks through ``np.loadtxt(usecols=(1, 2, 3))``."""
    vs, fs = _obj_blocks(path)
    pos = np.loadtxt(io.BytesIO(vs), usecols=(1, 2, 3), dtype=np.float64, ndmin=2)
    idx = np.loadtxt(io.BytesIO(fs), usecols=(1, 2, 3), dtype=np.int64, ndmin=2).reshape(-1) - 1
    return pos, np.arange(len(idx) // 3 + 1, dtype=np.int64) * 3, idx


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def parse_ply_frombuffer(path: str):
    """Binary PLY of a vertex element and a face element whose lists all have 3 entries: ``np.frombuffer``."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    lines = data[:end].decode("ascii").splitlines()
    bo = "<" if "binary_little_endian" in lines[1] else ">"
    elements = []
    for line in lines:
        w = line.split()
        if w[0] == "element":
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property" and w[1] == "list":
            elements[-1][2].append((w[4], bo + _PLY_TYPES[w[2]], bo + _PLY_TYPES[w[3]]))
        elif w[0] == "property":
            elements[-1][2].append((w[2], bo + _PLY_TYPES[w[1]]))
    (_, nv, vprops), (_, nf, fprops) = elements
    vdt = np.dtype([p[:2] for p in vprops])
    (_, count_t, index_t), = fprops
    fdt = np.dtype([("n", count_t), ("i", index_t, (3,))])
    v = np.frombuffer(data, dtype=vdt, count=nv, offset=end)
    f = np.frombuffer(data, dtype=fdt, count=nf, offset=end + nv * vdt.itemsize)
    pos = np.column_stack([v["x"], v["y"], v["z"]]).astype(np.float64)
    return pos, np.arange(nf + 1, dtype=np.int64) * 3, f["i"].reshape(-1).astype(np.int64)


PARSE_FLOORS = {
    "bunny": {"np.fromstring": parse_obj_fromstring, "np.loadtxt": parse_obj_loadtxt},
    "igea": {"np.frombuffer": parse_ply_frombuffer},
}


# ==========================================================================
# Floors: the numpy half-edge build


def numpy_build(n_vertices: int, offsets: np.ndarray, indices: np.ndarray, sort: str = "stable"):
    """Half-edge arrays of a manifold, consistently oriented polygon soup (no validation).

    Seed 003's construction with numpy: one half-edge per corner; twins by
    sorting the corners by their undirected vertex pair (``sort``: a stable
    argsort, or quicksort and then putting the earlier corner of each pair
    first); edges numbered in order of first use, edge ``e`` owning ``2e``
    (first use) and ``2e + 1``; next/prev within each polygon; a pair used
    once gets a free twin, whose next is the one free half-edge leaving its
    target (a manifold boundary vertex has exactly one); ``vertex.halfedge``
    prefers a free half-edge. These are hestore's conventions, so the
    arrays are comparable one for one with `hestore.build.build`'s.

    Returns ``(origin, next, prev, polygon, vertex_halfedge, polygon_halfedge)``
    with -1 for NULL; twin and edge are implicit (``h ^ 1``, ``h >> 1``).
    """
    counts = np.diff(offsets)
    c = len(indices)
    succ = np.arange(1, c + 1, dtype=np.int64)
    succ[offsets[1:] - 1] = offsets[:-1]  # a polygon's last corner wraps to its first
    a, b = indices, indices[succ]
    key = np.minimum(a, b) * n_vertices + np.maximum(a, b)
    order = np.argsort(key, kind=sort)
    sorted_key = key[order]
    start = np.ones(c, dtype=bool)
    start[1:] = sorted_key[1:] != sorted_key[:-1]
    if sort != "stable":
        pair = np.flatnonzero(~start[1:])  # sorted positions i whose i + 1 is the same pair
        swap = pair[order[pair] > order[pair + 1]]
        order[swap], order[swap + 1] = order[swap + 1], order[swap]
    first = np.zeros(c, dtype=bool)
    first[order[start]] = True
    edge_of_first = np.cumsum(first) - 1  # edges in order of first use
    group = np.cumsum(start) - 1
    he = np.empty(c, dtype=np.int64)
    he[order] = 2 * edge_of_first[order[start]][group] + ~start
    n_he = 2 * len(np.flatnonzero(start))
    origin = np.empty(n_he, dtype=np.int64)
    origin[he] = a
    polygon = np.full(n_he, -1, dtype=np.int64)
    polygon[he] = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    nxt = np.empty(n_he, dtype=np.int64)
    prv = np.empty(n_he, dtype=np.int64)
    nxt[he] = he[succ]
    prv[he[succ]] = he
    lone = start.copy()
    lone[:-1] &= start[1:]
    lone_corner = order[lone]
    free = he[lone_corner] + 1
    origin[free] = b[lone_corner]
    free_out = np.full(n_vertices, -1, dtype=np.int64)
    free_out[origin[free]] = free
    after = free_out[origin[free ^ 1]]  # the free half-edge leaving the target
    nxt[free] = after
    prv[after] = free
    vertex_he = np.full(n_vertices, -1, dtype=np.int64)
    vertex_he[origin] = np.arange(n_he, dtype=np.int64)
    vertex_he[origin[free]] = free
    return origin, nxt, prv, polygon, vertex_he, he[offsets[:-1]]


# ==========================================================================
# Floors: writing rows with the plain driver


def table_rows(positions: np.ndarray, built) -> list[tuple[sa.Table, dict]]:
    """Every table's columns, with the values hestore writes (-1 / NaN = NULL): ``built.arrays`` as they are."""
    a = built.arrays
    return [
        (schema.vertices, {"id": a.v_id, "halfedge": a.v_halfedge,
                           "x": positions[:, 0], "y": positions[:, 1], "z": positions[:, 2]}),
        (schema.halfedges, {"id": a.he_id, "origin": a.he_origin, "next": a.he_next, "prev": a.he_prev,
                            "twin": a.he_twin, "edge": a.he_edge, "polygon": a.he_polygon}),
        (schema.edges, {"id": a.e_id, "halfedge": a.e_halfedge}),
        (schema.polygons, {"id": a.p_id, "halfedge": a.p_halfedge}),
    ]


def _nulls(values: np.ndarray) -> np.ndarray:
    return np.isnan(values) if values.dtype.kind == "f" else values < 0


def _py_list(values: np.ndarray, nullable: bool) -> list:
    if nullable:
        nulls = _nulls(values)
        if nulls.any():
            boxed = values.astype(object)
            boxed[nulls] = None
            return boxed.tolist()
    return values.tolist()


def sqlite_executemany(con: sqlite3.Connection, mesh_id: int, tables) -> dict:
    cur = con.cursor()
    cur.execute("BEGIN")
    for table, cols in tables:
        names = list(cols)
        marks = ", ".join("?" * len(names))
        sql = f"INSERT INTO {table.name} (mesh_id, {', '.join(names)}) VALUES ({mesh_id}, {marks})"
        n = len(cols["id"])
        for s in range(0, n, CHUNK_ROWS):
            lists = [_py_list(cols[k][s : s + CHUNK_ROWS], table.c[k].nullable) for k in names]
            cur.executemany(sql, zip(*lists))
    cur.execute("COMMIT")
    return {}


def sqlite_values(con: sqlite3.Connection, mesh_id: int, tables) -> dict:
    limit = con.getlimit(sqlite3.SQLITE_LIMIT_VARIABLE_NUMBER)
    cur = con.cursor()
    cur.execute("BEGIN")
    per_stmt = {}
    for table, cols in tables:
        names = list(cols)
        k = len(names)
        per = max(1, min(VALUES_ROWS, limit // k))
        per_stmt[table.name] = per
        row = f"({mesh_id}, {', '.join('?' * k)})"
        head = f"INSERT INTO {table.name} (mesh_id, {', '.join(names)}) VALUES "
        full = head + ", ".join([row] * per)
        n = len(cols["id"])
        step = per * max(1, CHUNK_ROWS // per)
        for s in range(0, n, step):
            m = min(n, s + step) - s
            block = np.empty((m, k), dtype=object)
            for j, name in enumerate(names):
                values = cols[name][s : s + m]
                block[:, j] = values
                if table.c[name].nullable:
                    nulls = _nulls(values)
                    if nulls.any():
                        block[nulls, j] = None
            flat = block.ravel().tolist()
            del block
            q = 0
            while q + per <= m:
                cur.execute(full, flat[q * k : (q + per) * k])
                q += per
            if q < m:
                cur.execute(head + ", ".join([row] * (m - q)), flat[q * k :])
    cur.execute("COMMIT")
    return {"rows per statement": per_stmt, "variable limit": limit}


def pg_write_row(conn, mesh_id: int, tables) -> dict:
    with conn.cursor() as cur:
        for table, cols in tables:
            names = list(cols)
            n = len(cols["id"])
            with cur.copy(f"COPY {table.name} (mesh_id, {', '.join(names)}) FROM STDIN") as copy:
                for s in range(0, n, CHUNK_ROWS):
                    lists = [_py_list(cols[k][s : s + CHUNK_ROWS], table.c[k].nullable) for k in names]
                    for row in zip(itertools.repeat(mesh_id), *lists):
                        copy.write_row(row)
    conn.commit()
    return {}


def _pg_type(column: sa.Column) -> str:
    if isinstance(column.type, sa.Float):
        return ">f8"
    return ">i8" if isinstance(column.type, sa.BigInteger) else ">i4"


def pg_binary(conn, mesh_id: int, tables) -> dict:
    """Binary COPY: each block of rows one numpy structured array per pattern of NULL columns."""
    with conn.cursor() as cur:
        for table, cols in tables:
            names = list(cols)
            columns = [table.c.mesh_id] + [table.c[k] for k in names]
            types = [_pg_type(c) for c in columns]
            n = len(cols["id"])
            with cur.copy(f"COPY {table.name} (mesh_id, {', '.join(names)}) FROM STDIN (FORMAT BINARY)") as copy:
                copy.write(PGCOPY_HEADER)
                for s in range(0, n, CHUNK_ROWS):
                    m = min(n, s + CHUNK_ROWS) - s
                    values = [np.full(m, mesh_id)] + [cols[k][s : s + m] for k in names]
                    pattern = np.zeros(m, dtype=np.int64)
                    for j, c in enumerate(columns):
                        if c.nullable:
                            pattern |= _nulls(values[j]).astype(np.int64) << j
                    patterns = np.unique(pattern).tolist()
                    for p in patterns:
                        rows = slice(None) if len(patterns) == 1 else np.flatnonzero(pattern == p)
                        fields = [("count", ">i2")]
                        for j, t in enumerate(types):
                            fields.append((f"l{j}", ">i4"))
                            if not (p >> j) & 1:
                                fields.append((f"v{j}", t))
                        block = np.empty(m if len(patterns) == 1 else len(rows), dtype=fields)
                        block["count"] = len(columns)
                        for j, t in enumerate(types):
                            if (p >> j) & 1:
                                block[f"l{j}"] = -1
                            else:
                                block[f"l{j}"] = np.dtype(t).itemsize
                                block[f"v{j}"] = values[j][rows]
                        copy.write(block.tobytes())
                copy.write(b"\xff\xff")
    conn.commit()
    return {}


INSERT_FLOORS = {
    "sqlite": {"executemany": sqlite_executemany, "multi-row VALUES": sqlite_values},
    "postgresql": {"COPY write_row": pg_write_row, "COPY binary (numpy)": pg_binary},
}


# ==========================================================================
# Floors: reading columns and writing files

_SELECTS = [
    ("vertices", "id, x, y, z", np.float64),
    ("halfedges", "id, origin, next", np.int64),
    ("polygons", "id, halfedge", np.int64),
]


def select_fetchall(cursor, mesh_id: int, placeholder: str) -> list[np.ndarray]:
    out = []
    for table, cols, dtype in _SELECTS:
        cursor.execute(f"SELECT {cols} FROM {table} WHERE mesh_id = {placeholder}", (mesh_id,))
        out.append(by_id(np.array(cursor.fetchall(), dtype=dtype)))
    return out


def select_fromiter(cursor, mesh_id: int, placeholder: str) -> list[np.ndarray]:
    out = []
    for table, cols, dtype in _SELECTS:
        k = len(cols.split(","))
        cursor.execute(f"SELECT {cols} FROM {table} WHERE mesh_id = {placeholder}", (mesh_id,))
        out.append(by_id(np.fromiter(cursor, dtype=np.dtype((dtype, (k,))))))
    return out


def select_pg_array_agg(cursor, mesh_id: int, placeholder: str) -> list[np.ndarray]:
    """Per table one ``COPY (SELECT array_agg(col), ...) TO STDOUT (FORMAT BINARY)``: a single row whose
    array fields are decoded with ``np.frombuffer``. (A row-per-row ``COPY TO`` is far slower: the
    driver hands over every row as its own message.)"""
    out = []
    for table, cols, dtype in _SELECTS:
        names = [c.strip() for c in cols.split(",")]
        columns = pg_copy_columns(cursor, names, f"FROM {table} WHERE mesh_id = {int(mesh_id)}", [dtype] * len(names))
        out.append(by_id(np.column_stack(columns)))
    return out


SELECT_FLOORS = {
    "sqlite": {"fetchall + np.array": select_fetchall, "np.fromiter(cursor)": select_fromiter},
    "postgresql": {"fetchall + np.array": select_fetchall, "COPY TO of array_agg + np.frombuffer": select_pg_array_agg},
}


def write_ply_numpy(path: str, positions: np.ndarray, offsets: np.ndarray, indices: np.ndarray) -> None:
    """Binary little-endian PLY of triangles: a header, then two arrays' bytes."""
    f = len(offsets) - 1
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(positions)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {f}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    records = np.empty(f, dtype=[("n", "u1"), ("i", "<i4", (3,))])
    records["n"] = 3
    records["i"] = indices.reshape(-1, 3)
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(positions.astype("<f8").tobytes())
        out.write(records.tobytes())


# ==========================================================================
# Child jobs (each runs in its own process)


def job_parse_floor(spec: dict) -> dict:
    path = os.path.join(spec["dir"], FILES[spec["mesh"]])
    variants = {}
    outputs = {}
    for name, fn in PARSE_FLOORS[spec["mesh"]].items():
        variants[name], outputs[name] = best_of(fn, path)
    t0 = time.perf_counter()
    soup = formats.read(path)
    read_s = time.perf_counter() - t0
    same = {name: bool(np.array_equal(p, soup.positions) and np.array_equal(o, soup.offsets)
                       and np.array_equal(i, soup.indices))
            for name, (p, o, i) in outputs.items()}
    usable = {k: v for k, v in variants.items() if same[k]}
    best = min(usable, key=usable.get) if usable else None
    return {"variants": variants, "same": same, "best": best, "seconds": usable[best] if best else None,
            "formats_read": read_s, "vertices": len(soup.positions), "polygons": len(soup.offsets) - 1}


def job_build_floor(spec: dict) -> dict:
    inp = load_input(spec)
    nv = len(inp.positions)
    variants, outputs = {}, {}
    for sort in ("stable", "quicksort"):

        def run(sort=sort):
            if inp.faces is not None:  # the (F, k) array, as import_arrays gets it
                f, k = inp.faces.shape
                return numpy_build(nv, np.arange(f + 1, dtype=np.int64) * k, inp.faces.reshape(-1), sort)
            return numpy_build(nv, inp.offsets, inp.indices, sort)

        variants[f"argsort {sort}"], outputs[sort] = best_of(run)
    t0 = time.perf_counter()
    built = build(nv, Ragged(inp.offsets, inp.indices))
    hestore_build = time.perf_counter() - t0
    a = built.arrays
    ref = (a.he_origin, a.he_next, a.he_prev, a.he_polygon, a.v_halfedge, a.p_halfedge)
    names = ("origin", "next", "prev", "polygon", "vertex.halfedge", "polygon.halfedge")
    diffs = sorted({nm for out in outputs.values() for nm, x, y in zip(names, out, ref) if not np.array_equal(x, y)})
    # The floor's implicit numbering: half-edge ids 0..H-1, twin h ^ 1, edge h >> 1 owning 2e, polygons 0..P-1.
    ids = np.arange(len(a.he_id), dtype=np.int64)
    edges = np.arange(len(a.e_id), dtype=np.int64)
    implicit = {"halfedge.id": (a.he_id, ids), "twin": (a.he_twin, ids ^ 1), "edge": (a.he_edge, ids >> 1),
                "edge.id": (a.e_id, edges), "edge.halfedge": (a.e_halfedge, 2 * edges),
                "polygon.id": (a.p_id, np.arange(len(a.p_id))), "vertex.id": (a.v_id, np.arange(nv))}
    diffs += sorted(nm for nm, (x, y) in implicit.items() if not np.array_equal(x, y))
    counts_equal = all(len(out[0]) == len(a.he_id) for out in outputs.values())
    best = min(variants, key=variants.get)
    return {"variants": variants, "best": best, "seconds": variants[best], "hestore_build": hestore_build,
            "halfedges": len(a.he_id), "edges": len(a.e_id), "polygons": len(built.accepted),
            "refused": len(built.refused),
            "counts_equal": counts_equal, "arrays_differ": diffs, "vertices": nv}


@contextlib.contextmanager
def _floor_database(spec: dict):
    """A fresh database with hestore's schema and one empty mesh, and a plain-driver connection on it (SQLite with
    hestore's pragmas; psycopg in a transaction), closed and removed at the end: ``(connection, mesh id)``."""
    if spec["backend"] == "sqlite":
        path = os.path.join(spec["workdir"], f"floor-{spec['mesh']}.db")
        remove_sqlite(path)
        url = sqlite_url(path)
    else:
        schema_name = f"floor_{spec['mesh']}"
        url = pg_fresh_schema(spec["db_url"], schema_name)
    with contextlib.closing(hestore.open(url)) as store:
        mesh_id = store.create_mesh("floor").id
    con = sqlite_connect(path) if spec["backend"] == "sqlite" else pg_connect(url)
    try:
        yield con, mesh_id
    finally:
        con.close()
        if spec["backend"] == "sqlite":
            remove_sqlite(path)
        else:
            pg_drop_schema(spec["db_url"], schema_name)


def job_insert_floor(spec: dict) -> dict:
    inp = load_input(spec)
    built = build(len(inp.positions), Ragged(inp.offsets, inp.indices))
    tables = table_rows(inp.positions, built)
    rows = sum(len(cols["id"]) for _, cols in tables)
    variants, details, cpu = {}, {}, {}
    analyze = None
    for name, fn in INSERT_FLOORS[spec["backend"]].items():
        with _floor_database(spec) as (con, mesh_id):
            settle(spec)
            run = timed(lambda fn=fn, con=con, mesh_id=mesh_id: fn(con, mesh_id, tables))
            details[name], variants[name], cpu[name] = run.result, run.seconds, run.cpu
            if spec["backend"] == "postgresql" and analyze is None:
                con.autocommit = True
                t0 = time.perf_counter()
                for table, _ in tables:
                    con.execute(f"ANALYZE {table.name}")
                analyze = time.perf_counter() - t0
        log(f"  {spec['backend']} {spec['mesh']} insert floor, {name}: {variants[name]:.2f} s")
    best = min(variants, key=variants.get)
    return {"variants": variants, "cpu": cpu, "details": details, "best": best, "seconds": variants[best], "rows": rows,
            "analyze": analyze}


def job_import(spec: dict) -> dict:
    inp = load_input(spec) if spec["mesh"] == "grid" else None  # the arrays a user already has
    grid = (inp.positions, inp.faces) if inp else None
    with open_store(spec) as store:
        report, out = one_shot(spec, lambda: import_mesh(store, spec["mesh"], spec["n"], spec["dir"], grid),
                               profile=spec.get("profile", False))
    return dict(out, vertices=report.vertices, edges=report.edges, polygons=report.polygons,
                skipped=len(report.skipped))


def job_check(spec: dict) -> dict:
    with open_store(spec) as store:
        return timed_check(store, spec["mesh"])


def _same_as_input(inp: Input, positions, offsets, indices) -> list[str]:
    bad = []
    if not np.array_equal(positions, inp.positions):
        bad.append("positions")
    if not (np.array_equal(offsets, inp.offsets) and np.array_equal(indices, inp.indices)):
        bad.append("polygons")
    return bad


def job_to_arrays(spec: dict) -> dict:
    with open_store(spec) as store:
        arrays, out = one_shot(spec, store.mesh(spec["mesh"]).to_arrays)
    inp = load_input(spec)
    polys = arrays.polygons
    if isinstance(polys, np.ndarray):
        offsets = np.arange(len(polys) + 1, dtype=np.int64) * polys.shape[1]
        indices = polys.reshape(-1)
    else:
        offsets = np.concatenate([[0], np.cumsum([len(p) for p in polys])])
        indices = np.concatenate([np.asarray(p) for p in polys])
    bad = _same_as_input(inp, arrays.positions, offsets, indices)
    if not np.array_equal(arrays.vertex_ids, np.arange(len(inp.positions))):
        bad.append("vertex_ids")
    return dict(out, mismatch=bad)


def job_select_floor(spec: dict) -> dict:
    variants = {}
    shapes = None
    for name, fn in SELECT_FLOORS[spec["backend"]].items():
        plain = plain_connection(spec)
        mesh_id = plain_mesh_id(plain, spec["mesh"])
        settle(spec)
        t0 = time.perf_counter()
        plain.cur.execute(plain.begin)  # one snapshot, as hestore reads
        out = fn(plain.cur, mesh_id, plain.mark)
        plain.cur.execute("ROLLBACK")
        variants[name] = time.perf_counter() - t0
        plain.con.close()
        shapes = [list(x.shape) for x in out]
        assert all(len(x) < 2 or (x[1:, 0] > x[:-1, 0]).all() for x in out), "rows did not come back in id order"
        del out
    best = min(variants, key=variants.get)
    return {"variants": variants, "best": best, "seconds": variants[best], "shapes": shapes}


def job_export(spec: dict) -> dict:
    out_path = os.path.join(spec["workdir"], f"export-{spec['mesh']}.{spec['fmt']}")
    with open_store(spec) as store:
        mesh = store.mesh(spec["mesh"])
        _, out = one_shot(spec, lambda: mesh.export(out_path))
    size = os.path.getsize(out_path)
    soup = formats.read(out_path)
    os.remove(out_path)
    bad = _same_as_input(load_input(spec), soup.positions, soup.offsets, soup.indices)
    return dict(out, bytes=size, mismatch=bad)


def job_write_floor(spec: dict) -> dict:
    inp = load_input(spec)
    path = os.path.join(spec["workdir"], f"floor-{spec['mesh']}.{spec['fmt']}")
    out = {}
    if spec["fmt"] == "ply":
        out["numpy writer"], _ = best_of(write_ply_numpy, path, inp.positions, inp.offsets, inp.indices)
        soup = formats.read(path)
        out_same = not _same_as_input(inp, soup.positions, soup.offsets, soup.indices)
        t0 = time.perf_counter()
        formats.write(path, inp.positions, inp.offsets, inp.indices)
        info = {"formats.write": time.perf_counter() - t0}
        best = "numpy writer"
    else:
        t0 = time.perf_counter()
        formats.write(path, inp.positions, inp.offsets, inp.indices)
        out["formats.write"] = time.perf_counter() - t0
        out_same = True
        info = {}
        best = "formats.write"
    os.remove(path)
    return {"variants": out, "best": best, "seconds": out[best], "info": info, "same": out_same}


JOBS = {
    "parse_floor": job_parse_floor,
    "build_floor": job_build_floor,
    "insert_floor": job_insert_floor,
    "import": job_import,
    "check": job_check,
    "to_arrays": job_to_arrays,
    "select_floor": job_select_floor,
    "export": job_export,
    "write_floor": job_write_floor,
}


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, meshes=MESHES, jobs=JOBS,
                workdir_help="where SQLite files and exports go (default: a temporary folder, removed at the end)",
                profile="profile hestore's import in a separate run when it is over target (default), always, or never")
    args = ap.parse_args(argv)
    only, missing = present(args.only, args.meshes_dir)

    base = {"n": args.n, "dir": args.meshes_dir}
    floors: dict = {}  # (kind, mesh[, backend|fmt]) -> result
    results: dict = {}  # (job, backend, mesh[, fmt]) -> result
    with Bench(args, "import", __file__, clean=("import_", "floor-", "profile_", "export-", "result-")) as bench:
        bench.report.skipped.extend(missing)
        run = bench.runner.run
        for m in only:  # the floors that do not depend on the backend
            if m in FILES:
                floors[("parse", m)] = run(job="parse_floor", mesh=m, **base)
            floors[("build", m)] = run(job="build_floor", mesh=m, **base)
            for fmt in ("ply", "obj"):
                floors[("write", m, fmt)] = run(job="write_floor", mesh=m, fmt=fmt, **base)
        for place in bench.for_each_backend():
            bname = place.backend
            for m in only:
                floors[("insert", m, bname)] = run(job="insert_floor", **base, backend=bname, mesh=m,
                                                   db_url=place.db_url)
                spec = dict(base, mesh=m, **place.fresh(f"import_{m}"))
                results[("import", bname, m)] = imp = run(job="import", **spec)
                if imp is None:
                    continue
                results[("check", bname, m)] = run(job="check", **spec)
                results[("to_arrays", bname, m)] = run(job="to_arrays", **spec)
                floors[("select", m, bname)] = run(job="select_floor", **spec)
                for fmt in ("ply", "obj"):
                    results[("export", bname, m, fmt)] = run(job="export", fmt=fmt, **spec)
                place.drop(spec)
                # A profile of the import when it is over its target.
                floor = _import_floor(floors, m, bname)
                if wants_profile(args, floor is not None and imp["seconds"] > TARGET_RATIO * floor[0]):
                    spec = dict(base, mesh=m, **place.fresh(f"profile_{m}"))
                    prof = run(job="import", profile=True, **spec)
                    if prof:
                        bench.report.profiles.append((f"{bname} {mesh_label(m, args.n)}: import under cProfile "
                                                      f"({prof['seconds']:.2f} s with the profiler on)",
                                                      prof["dominant"], prof["profile"]))
                    place.drop(spec)
    report(bench, only, floors, results)
    return bench.finish(meshes=args.meshes_dir)


def _import_floor(floors: dict, mesh: str, backend: str) -> tuple[float, str] | None:
    """The import floor and its parts, or None when one is missing."""
    build_f = floors.get(("build", mesh))
    insert_f = floors.get(("insert", mesh, backend))
    parse_f = floors.get(("parse", mesh)) if mesh in FILES else {"seconds": 0.0}
    if not build_f or not insert_f or not parse_f or parse_f.get("seconds") is None:
        return None
    parts = []
    if mesh in FILES:
        parts.append(f"parse {parse_f['seconds']:.2f} ({parse_f['best']})")
    parts.append(f"build {build_f['seconds']:.2f}")
    parts.append(f"insert {insert_f['seconds']:.2f} ({insert_f['best']})")
    total = parse_f["seconds"] + build_f["seconds"] + insert_f["seconds"]
    return total, " + ".join(parts)


def floor_gates(bench: Bench, only: list[str], floors: dict) -> None:
    """What the floors must reproduce: hestore's build, formats.read, the input (a gate each), and a note on each
    mesh's build."""
    rep, n = bench.report, bench.args.n
    for m in only:
        bf = floors.get(("build", m))
        if bf:
            same = "identical arrays" if not bf["arrays_differ"] else f"arrays differ in {bf['arrays_differ']}"
            rep.notes.append(f"{mesh_label(m, n)}: {bf['vertices']:,} vertices, {bf['polygons']:,} polygons, "
                             f"{bf['edges']:,} edges, {bf['halfedges']:,} half-edges; numpy build floor vs "
                             f"hestore.build.build: {'same counts' if bf['counts_equal'] else 'DIFFERENT COUNTS'}, "
                             f"{same}")
            if not bf["counts_equal"]:
                rep.problems.append(f"{m}: the numpy build floor gives other half-edge counts than hestore.build.build")
            if bf["refused"]:
                rep.problems.append(f"{m}: hestore.build.build refused {bf['refused']} polygons")
        pf = floors.get(("parse", m))
        if pf and not pf["best"]:
            rep.problems.append(f"{m}: no parse floor reproduced formats.read")
        for fmt in ("ply", "obj"):
            wf = floors.get(("write", m, fmt))
            if wf and not wf["same"]:
                rep.problems.append(f"{m}: the numpy .{fmt} writer floor does not read back as the input")


def mesh_figures(bench: Bench, bname: str, m: str, floors: dict, results: dict) -> list[Figure]:
    """The import, to_arrays and export figures of one mesh on one backend, their gates and notes."""
    rep = bench.report
    imp = results.get(("import", bname, m))
    if imp is None:
        return []
    label = mesh_label(m, bench.args.n)
    what = "import_arrays" if m == "grid" else "import_file"
    fl = _import_floor(floors, m, bname)
    judged = verdict(None)
    if fl:
        over = [x for x, bad in (("time", imp["seconds"] > TARGET_RATIO * fl[0]), ("RSS", imp["rss"] > TARGET_RSS))
                if bad]
        judged = verdict(True) if not over else f"{verdict(False)} ({', '.join(over)})"
    figures = [Figure(what, bname, imp["seconds"], fl[0] if fl else None, "≤ 2× floor, RSS ≤ 1.5 GB", judged, label,
                      cpu=imp["cpu"], rss=imp["rss"], floor_parts=fl[1] if fl else "missing")]
    bf = floors.get(("build", m))
    if bf and (imp["edges"] != bf["edges"] or imp["polygons"] != bf["polygons"]):
        rep.problems.append(f"{bname} {label}: import stored {imp['edges']} edges / {imp['polygons']} polygons, "
                            f"the build gave {bf['edges']} / {bf['polygons']}")
    chk = results.get(("check", bname, m))
    if chk:
        rep.notes.append(f"{bname} {label}: mesh.check() {chk['seconds']:.2f} s, {chk['violations']} "
                         f"violation(s); counts {counts_text(chk['counts'])}")
        if chk["violations"]:
            rep.problems.append(f"{bname} {label}: check() found {chk['violations']} violations, "
                                f"e.g. {chk['examples']}")
    sel = floors.get(("select", m, bname))
    ta = results.get(("to_arrays", bname, m))
    if ta:
        figures.append(Figure("to_arrays", bname, ta["seconds"], sel["seconds"] if sel else None,
                              "— (none in SPEC)", verdict(None), label, cpu=ta["cpu"], rss=ta["rss"],
                              floor_parts=f"SELECT {sel['seconds']:.2f} ({sel['best']})" if sel else "missing"))
        if ta["mismatch"]:
            rep.problems.append(f"{bname} {label}: to_arrays differs from the input in {ta['mismatch']}")
    for fmt in ("ply", "obj"):
        ex = results.get(("export", bname, m, fmt))
        wf = floors.get(("write", m, fmt))
        if not ex:
            continue
        floor = parts = None
        if sel and wf:
            floor = sel["seconds"] + wf["seconds"]
            parts = f"SELECT {sel['seconds']:.2f} + write {wf['seconds']:.2f} ({wf['best']})"
        figures.append(Figure(f"export → .{fmt}", bname, ex["seconds"], floor, "— (none in SPEC)", verdict(None),
                              label, cpu=ex["cpu"], rss=ex["rss"], floor_parts=parts or "missing"))
        rows_per_s = (chk["counts"][0] + chk["counts"][3]) / ex["seconds"] if ta and chk else None
        rep.notes.append(f"{bname} {label}: export .{fmt} wrote {ex['bytes'] / 1e6:.1f} MB"
                         + (f", {rows_per_s:,.0f} vertices+polygons/s" if rows_per_s else ""))
        if ex["mismatch"]:
            rep.problems.append(f"{bname} {label}: the exported .{fmt} reads back different {ex['mismatch']}")
    return figures


def floor_rows(n: int, floors: dict) -> list[list[str]]:
    """Every variant of every floor, the one taken marked."""
    rows = []
    for key, fl in floors.items():
        if not fl:
            continue
        kind, m = key[0], key[1]
        where = key[2] if len(key) > 2 else ""
        for name, t in fl["variants"].items():
            mark = "← floor" if name == fl["best"] else ""
            if "cpu" in fl:
                name = f"{name} (its CPU {fl['cpu'][name]:.2f} s)"
            extra = ""
            if kind == "parse" and not fl["same"].get(name, True):
                extra = "(differs from formats.read: not used)"
            rows.append([kind, mesh_label(m, n), where, name, fmt_time(t),
                         mark + (" " if mark and extra else "") + extra])
        if kind == "insert" and fl.get("analyze") is not None:
            rows.append([kind, mesh_label(m, n), where, "(ANALYZE after it, not in the floor)",
                         fmt_time(fl["analyze"]), ""])
        if kind == "insert" and "multi-row VALUES" in fl.get("details", {}):
            d = fl["details"]["multi-row VALUES"]
            per = sorted(set(d["rows per statement"].values()))
            rows.append([kind, mesh_label(m, n), where,
                         f"(VALUES: {'/'.join(map(str, per))} rows per statement; "
                         f"variable limit {d['variable limit']:,})", "", ""])
    return rows


def part_rows(args, only: list[str], floors: dict, results: dict) -> list[list[str]]:
    """hestore's own parts (build, read) beside their floors, and what the import spends writing."""
    rows = []
    for m in only:
        bf = floors.get(("build", m))
        pf = floors.get(("parse", m))
        if not bf:
            continue
        parts = [f"hestore.build.build {bf['hestore_build']:.2f} s vs numpy build floor {bf['seconds']:.2f} s "
                 f"({bf['hestore_build'] / bf['seconds']:.1f}×)"]
        if pf:
            ratio = f"{pf['seconds']:.2f} s ({pf['formats_read'] / pf['seconds']:.1f}×)" if pf["seconds"] else "—"
            parts.append(f"formats.read {pf['formats_read']:.2f} s vs parse floor {ratio}")
        rows.append([mesh_label(m, args.n), "; ".join(parts)])
        for bname in args.backends:
            imp = results.get(("import", bname, m))
            ins = floors.get(("insert", m, bname))
            if imp and ins:
                rest = imp["seconds"] - bf["hestore_build"] - (pf["formats_read"] if pf else 0.0)
                rows.append(["", f"{bname}: import − read − build ≈ {rest:.2f} s of writing, vs insert floor "
                                 f"{ins['seconds']:.2f} s ({rest / ins['seconds']:.2f}×); {ins['rows']:,} rows"])
    return rows


def report(bench: Bench, only: list[str], floors: dict, results: dict) -> None:
    args, rep = bench.args, bench.report
    floor_gates(bench, only, floors)
    figures = [f for bname in args.backends for m in only for f in mesh_figures(bench, bname, m, floors, results)]
    rep.title(f"hestore bulk import/export benchmark — every figure one run in a {bench.runner.process}")
    rep.figures(figures, after="""\
(time: wall clock, the figure; its CPU: user + system time of the measuring process alone, without the
 database server's, a hint of how much other load on the machine slowed the wall clock down)""")
    rep.table("Floors, every variant measured (the fastest is taken; build/parse/write: best of 2 runs, "
              "insert/SELECT: one run each into a fresh database):",
              ["floor", "mesh", "backend/fmt", "variant", "time", ""], floor_rows(args.n, floors), "llllrl")
    rep.table("hestore's parts, measured separately (the import figure is one run of all of them, plus the writes):",
              ["mesh", "parts"], part_rows(args, only, floors, results), "ll")
    rep.close(ABOUT, profiles="Profiles of the imports over their target, each rerun under cProfile:")


if __name__ == "__main__":
    raise SystemExit(main())
