"""Mesh history (SPEC §4.1): revisions, views of the past, diffs, undo/redo/revert, branches, pruning.

Every test runs on SQLite and PostgreSQL (the ``store`` / ``db_url``
fixtures: a fresh database each), except that the tests which only read the
scripted mesh share one run of the script per backend (``scripted``, a
database of its own): views, history and diffs are not cheap, and the
script is the same for all of them.

The reference is a *snapshot* of a mesh taken through the public read API
only — `to_arrays`, `counts`, `stats`, every element with its stored
references and position, each polygon's corner loop, every property's
values — after each committed step of a script that makes every kind of
edit. Then:

* ``mesh.at(r)`` must give the snapshot taken at ``r``, for every ``r``,
  and a clean `check`;
* ``history()`` must list every revision with its message and its *net*
  changes, which must equal those computed from the snapshots;
* ``diff(a, b)`` must equal the set differences of the snapshots;
* undo, redo and revert must make the mesh equal to the snapshot they aim
  at (same ids, positions, values), and never hand an id out twice;
* a copy at a revision must equal that revision;
* pruned revisions and meshes without history must refuse to be read,
  diffed or undone, and nothing refused may change anything;
* two processes committing to one mesh must leave consecutive revisions
  and a readable history, and a process killed inside a block must leave
  no trace of it.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import traceback
import uuid
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa
from hypothesis import given, settings
from hypothesis import strategies as st

import hestore
from hestore import schema
from hestore import _persistence as persistence
from hestore.errors import (
    ElementNotFoundError,
    HestoreError,
    InvalidInputError,
    ReadOnlyError,
    RevisionNotFoundError,
)

from conftest import BACKENDS, _pg_schema_url
from helpers import STORED, Rollback, dump, triangle_grid
from test_concurrency import CTX, WAIT, _gather, _run, _stop

KINDS = ("vertex", "halfedge", "edge", "polygon")
EMPTY_COUNTS = {k: {"created": 0, "removed": 0, "changed": 0} for k in KINDS}


# --------------------------------------------------------------------------
# Snapshots through the public read API


def _value(x):
    """A property value as plain Python (tuples for vectors), comparable with ``==``."""
    if isinstance(x, np.ndarray):
        return tuple(_value(y) for y in x.tolist())
    if isinstance(x, (list, tuple)):
        return tuple(_value(y) for y in x)
    if isinstance(x, np.generic):
        return x.item()
    return x


def _explicit(prop, ids, values) -> dict:
    """``{id: value}`` of the elements whose value is not the default (set, for a property without one).

    So declaring a property with a default changes no element, and removing
    one changes the elements that had another value: what an element's
    value *is*, not whether a row stores it.
    """
    out = {}
    mask = np.ma.getmaskarray(values) if isinstance(values, np.ma.MaskedArray) else None
    default = _value(prop.default)
    for k, i in enumerate(ids.tolist()):
        if mask is not None and mask[k].any():
            continue
        v = _value(np.ma.getdata(values)[k])
        if mask is None and v == default:
            continue
        out[i] = v
    return out


def snapshot(mesh: hestore.Mesh) -> dict:
    """Everything the public read API tells about ``mesh`` (a mesh or a view), as plain comparable data."""
    arrays = mesh.to_arrays()
    polygons = arrays.polygons.tolist() if isinstance(arrays.polygons, np.ndarray) else list(arrays.polygons)
    positions = [tuple(None if math.isnan(c) else c for c in row) for row in arrays.positions.tolist()]
    elements = {
        "vertex": {
            v.id: (None if v.halfedge is None else v.halfedge.id, v.position) for v in mesh.vertices()
        },
        "halfedge": {
            h.id: (h.origin.id, h.next.id, h.prev.id, h.twin.id, h.edge.id, None if h.polygon is None else h.polygon.id)
            for h in mesh.halfedges()
        },
        "edge": {e.id: e.halfedge.id for e in mesh.edges()},
        "polygon": {p.id: p.halfedge.id for p in mesh.polygons()},
    }
    properties = {}
    for kind in KINDS:
        for name, prop in mesh.properties(kind).items():
            ids, values = mesh.property_array(kind, name)
            properties[(kind, name)] = (prop, _explicit(prop, ids, values))
    graph = mesh.to_networkx()
    return {
        "counts": mesh.counts(),
        "graph": (sorted(graph.nodes(data="pos")), sorted(graph.edges(keys=True, data="halfedges"))),
        "stats": mesh.stats().as_dict(),
        "arrays": (positions, polygons, arrays.vertex_ids.tolist()),
        "elements": elements,
        "loops": {p.id: [v.id for v in p.vertices()] for p in mesh.polygons()},
        "neighbors": {v.id: sorted(w.id for w in v.neighbors()) for v in mesh.vertices()},
        "properties": properties,
    }


def expected_diff(a: dict, b: dict) -> dict:
    """``{"created"|"removed"|"changed": {kind: sorted ids}}`` from two snapshots (``a`` before ``b``).

    Changed: in both, and its stored references, position or a property
    value (other than the default) differ.
    """
    out = {"created": {}, "removed": {}, "changed": {}}
    names = set(a["properties"]) | set(b["properties"])
    for kind in KINDS:
        ea, eb = a["elements"][kind], b["elements"][kind]
        out["created"][kind] = sorted(set(eb) - set(ea))
        out["removed"][kind] = sorted(set(ea) - set(eb))
        changed = {i for i in set(ea) & set(eb) if ea[i] != eb[i]}
        for key in names:
            if key[0] != kind:
                continue
            va = a["properties"].get(key, (None, {}))[1]
            vb = b["properties"].get(key, (None, {}))[1]
            changed |= {i for i in (set(va) | set(vb)) & set(ea) & set(eb) if va.get(i) != vb.get(i)}
        out["changed"][kind] = sorted(changed)
    return out


def export_bytes(mesh: hestore.Mesh, path: Path) -> bytes | None:
    """The PLY file ``mesh.export`` writes (None where it refuses: a vertex without a position)."""
    try:
        mesh.export(path)
    except InvalidInputError:
        return None
    return path.read_bytes()


def counts_of(d: dict) -> dict:
    return {k: {what: len(d[what][k]) for what in ("created", "removed", "changed")} for k in KINDS}


def as_dict(diff) -> dict:
    return {"created": diff.created, "removed": diff.removed, "changed": diff.changed}


# --------------------------------------------------------------------------
# The script: every kind of edit, a snapshot after each committed step


#: The snapshots of the first run of the script: it is deterministic, so later runs reuse them.
_SCRIPT_SNAPSHOTS: dict[int, dict] = {}


class Script:
    """Runs the scripted edits on a new mesh "m", recording a snapshot and the message of each revision.

    With ``known`` snapshots (an earlier run's) it takes none but the last,
    which must equal the known one.
    """

    def __init__(self, store: hestore.Store, name: str = "m", folder: Path | None = None, known=None) -> None:
        self.store = store
        self.mesh = store.create_mesh(name)
        self.known = known or None
        self.snaps = {0: snapshot(self.mesh) if self.known is None else self.known[0]}
        self.messages: dict[int, str | None] = {}
        self.folder = folder
        #: The PLY file of each revision, written then (None: a vertex had no position).
        self.exports: dict[int, bytes | None] = {}

    def committed(self, message: str | None = None) -> int:
        r = self.mesh.revision
        assert r == max(self.snaps) + 1, f"expected one new revision, the mesh is at {r}"
        self.snaps[r] = snapshot(self.mesh) if self.known is None else self.known[r]
        self.messages[r] = message
        if self.folder is not None:
            self.exports[r] = export_bytes(self.mesh, self.folder / f"then-{r}.ply")
        return r

    def run(self) -> "Script":
        store, mesh, step = self.store, self.mesh, self.committed
        a = mesh.add_vertex((0.0, 0.0, 0.0))
        step()
        with store.transaction(message="four corners"):
            b = mesh.add_vertex((1.0, 0.0, 0.0))
            c = mesh.add_vertex((1.0, 1.0, 0.0))
            d = mesh.add_vertex((0.0, 1.0, 0.0))
            e = mesh.add_vertex()  # no position
        step("four corners")
        mesh.add_edge(a, b)
        step()
        mesh.add_polygon([a, b, c])
        step()
        mesh.add_polygon([a, c, d])
        step()
        mesh.set_position(e, (0.5, 0.5, 1.0))
        step()
        mesh.set_positions([a, b], [(0.0, 0.0, 0.25), (1.0, 0.0, -0.25)])
        step()
        mesh.add_property("vertex", "t", "float64", default=0.0)
        step()
        a["t"] = 1.5
        step()
        mesh.add_property("polygon", "label", "str")  # no default: unset values are masked
        step()
        mesh.set_property_array("vertex", "t", [b.id, c.id], [2.0, 3.0])
        step()
        mesh.polygon(0)["label"] = "first"
        step()
        mesh.add_property("halfedge", "uv", "float64", shape=(5,), default=(0.0,) * 5)  # two value rows
        step()
        mesh.halfedge(0)["uv"] = (1.0, 2.0, 3.0, 4.0, 5.0)
        step()
        mesh.add_property("edge", "crease", "int64")
        step()
        mesh.set_property_array("edge", "crease", [x.id for x in mesh.edges()], list(range(mesh.counts().edges)))
        step()
        flipped = mesh.flip_edge(mesh.find_halfedge(a, c).edge)  # now b–d
        step()
        m1 = mesh.split_edge(flipped, triangulate=True)  # four triangles around m1
        step()
        with store.transaction(message="several edits"):
            f = mesh.add_vertex((2.0, 0.0, 0.0))
            g = mesh.add_vertex((2.0, 1.0, 0.0))
            mesh.add_polygon([b, f, g, c])
            f["t"] = 7.0
            mesh.set_position(m1, (0.5, 0.5, 0.5))
            gone = mesh.add_vertex((9.0, 9.0, 9.0))  # created and removed: nowhere
            gone["t"] = 9.0
            mesh.remove_vertex(gone)
            a["t"] = 2.5
            a["t"] = 1.5  # written back: no change for a
        step("several edits")
        mesh.collapse_edge(mesh.find_halfedge(m1, d))
        step()
        try:
            with store.transaction(message="never"):
                mesh.add_vertex((5.0, 5.0, 5.0))
                mesh.remove_polygon(next(iter(mesh.polygons())))
                a["t"] = 99.0
                raise Rollback
        except Rollback:
            pass
        assert mesh.revision == max(self.snaps)
        if self.known is None:
            assert snapshot(mesh) == self.snaps[max(self.snaps)]
        p = next(iter(mesh.polygons()))
        mesh.poke_polygon(p)
        step()
        q = max(mesh.polygons(), key=lambda x: x.degree)
        mesh.triangulate_polygon(q)
        step()
        mesh.remove_polygon(next(iter(mesh.polygons())))
        step()
        wire = mesh.add_edge(e, d)
        step()
        mesh.remove_edge(wire)
        step()
        mesh.remove_vertex(e)
        step()
        del a["t"]
        step()
        mesh.remove_property("edge", "crease")
        step()
        with store.transaction(message="label all"):
            ids = [x.id for x in mesh.polygons()]
            mesh.set_property_array("polygon", "label", ids, np.array([f"p{i}" for i in ids], dtype=object))
            mesh.polygon(ids[0])["label"] = "first again"
        step("label all")
        assert mesh.check() == []
        if self.known is None:
            _SCRIPT_SNAPSHOTS.update(self.snaps)
        else:
            assert self.known.keys() == self.snaps.keys() and snapshot(mesh) == self.known[self.last]
        return self

    @property
    def last(self) -> int:
        return max(self.snaps)



# --------------------------------------------------------------------------
# Fixtures

#: Every table hestore writes, history included: "nothing changed" is one equality.
ALL_TABLES = (
    schema.meshes, *schema.VERSIONED, schema.revisions, *schema.HISTORY.values(),
)


@pytest.fixture(scope="module", params=BACKENDS)
def scripted(request, tmp_path_factory):
    """The script, run once per backend on a database of its own, for the tests that only read it.

    (They may add other meshes, never edit "m".)
    """
    folder = tmp_path_factory.mktemp("history")
    drop = None
    if request.param == "sqlite":
        url = f"sqlite:///{folder / 'script.db'}"
    else:
        database_url = request.getfixturevalue("pg_database")
        name = f"h_{uuid.uuid4().hex[:12]}"
        admin = sa.create_engine(database_url, isolation_level="AUTOCOMMIT")
        with admin.connect() as conn:
            conn.execute(sa.text(f'CREATE SCHEMA "{name}"'))
        url = _pg_schema_url(database_url, name)

        def drop():
            with admin.connect() as conn:
                conn.execute(sa.text(f'DROP SCHEMA "{name}" CASCADE'))
            admin.dispose()

    store = hestore.open(url)
    try:
        yield Script(store, folder=folder, known=None).run()
    finally:
        store.close()
        if drop is not None:
            drop()


@pytest.fixture
def script(store) -> Script:
    """The script on the test's own database (for tests that go on editing "m")."""
    return Script(store, known=_SCRIPT_SNAPSHOTS).run()


# --------------------------------------------------------------------------
# 1. at(r) is the snapshot taken at r


@pytest.mark.slow
def test_every_revision_reads_back_as_it_was(scripted, tmp_path):
    mesh = scripted.mesh
    assert mesh.revision == scripted.last == 29
    assert not mesh.is_view
    for r, snap in scripted.snaps.items():
        view = mesh.at(r)
        assert view.is_view and view.revision == r and view.name == mesh.name and view.id == mesh.id
        assert snapshot(view) == snap, f"revision {r}"
        assert view.check() == [], f"revision {r}"
        if r and (r % 5 == 0 or r == scripted.last):
            assert export_bytes(view, tmp_path / f"now-{r}.ply") == scripted.exports[r], f"revision {r}"
    assert snapshot(mesh) == scripted.snaps[scripted.last]
    empty = mesh.at(0)
    assert empty.counts() == hestore.Counts(0, 0, 0, 0) and empty.stats().vertices == 0
    assert list(empty.vertices()) == [] and all(empty.properties(k) == {} for k in KINDS)
    # a view's reads of one element, navigation and circulators
    view = mesh.at(5)  # two triangles a b c, a c d, the wire edge a–b is their side now, e isolated
    a, c = view.vertex(0), view.vertex(2)
    h = view.find_halfedge(a, c)
    assert h is not None and h.origin == a and h.target == c and h.next.next.next == h
    assert {p.id for p in view.polygons()} == {0, 1} and sorted(w.id for w in a.neighbors()) == [1, 2, 3]
    assert view.vertex(4).position is None and view.vertex(4).is_isolated
    with pytest.raises(ElementNotFoundError):
        view.vertex(5)  # made later
    with pytest.raises(hestore.PropertyNotFoundError):
        view.property_array("vertex", "t")  # declared later
    later = mesh.at(9)
    assert later.vertex(0)["t"] == 1.5 and later.vertex(1)["t"] == 0.0
    ids, values = later.property_array("vertex", "t")
    assert ids.tolist() == [0, 1, 2, 3, 4] and values.tolist() == [1.5, 0.0, 0.0, 0.0, 0.0]
    # handles of a view belong to it: equal to the same view's, not to the mesh's
    assert later.vertex(0) == later.vertex(0) and later.vertex(0) != mesh.vertex(0)
    assert mesh.at(9).revision == 9 and mesh.at(9).vertex(0)["t"] == 1.5


def test_views_at_the_current_revision_and_inside_a_block(store):
    mesh = store.create_mesh("m")
    a, b, c = (mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(3))
    mesh.add_polygon([a, b, c])
    assert mesh.revision == 4 and snapshot(mesh.at(4)) == snapshot(mesh)
    before = snapshot(mesh)
    with store.transaction():
        mesh.set_position(a, (0.0, 0.0, 1.0))
        d = mesh.add_vertex((3.0, 0.0, 0.0))
        assert mesh.revision == 5  # the block's
        assert snapshot(mesh.at(4)) == before  # the committed past, seen from inside the block
        assert snapshot(mesh.at(5)) == snapshot(mesh)  # the block's own state
        with pytest.raises(RevisionNotFoundError):
            mesh.at(6)
    assert mesh.revision == 5 and snapshot(mesh.at(5)) == snapshot(mesh) and d.position == (3.0, 0.0, 0.0)
    assert snapshot(mesh.at(4)) == before


# --------------------------------------------------------------------------
# 2. history(): numbers, messages, net changes, times


def test_history_lists_every_revision_with_its_net_changes(scripted):
    mesh = scripted.mesh
    revisions = mesh.history()
    assert [r.number for r in revisions] == list(range(scripted.last, 0, -1))
    for r in revisions:
        assert r.message == scripted.messages[r.number], r.number
        expected = counts_of(expected_diff(scripted.snaps[r.number - 1], scripted.snaps[r.number]))
        assert r.changes == expected, f"revision {r.number}"
        assert isinstance(r.committed_at, datetime) and r.committed_at.utcoffset() is not None
        assert r.committed_at.utcoffset().total_seconds() == 0
    times = [r.committed_at for r in reversed(revisions)]
    assert times == sorted(times)
    now = datetime.now(timezone.utc)
    assert (now - times[0]).total_seconds() < 3600 and times[-1] <= now
    # the block's net changes: two new vertices and a quad; the vertex created and removed
    # in it appears nowhere, and a's value written back is no change
    several = next(r for r in revisions if r.message == "several edits")
    assert several.changes["vertex"]["created"] == 2 and several.changes["polygon"]["created"] == 1
    assert several.changes["vertex"]["removed"] == 0
    d = mesh.diff(several.number - 1, several.number)
    assert 0 not in d.changed["vertex"]
    assert len(d.created["vertex"]) == 2
    # limit: the newest first
    assert [r.number for r in mesh.history(limit=3)] == [scripted.last, scripted.last - 1, scripted.last - 2]
    assert mesh.history(limit=0) == []
    assert [r.number for r in mesh.history(limit=10**6)] == [r.number for r in revisions]
    for bad in (-1, 1.5, "3", True):
        with pytest.raises(InvalidInputError):
            mesh.history(limit=bad)
    # a view's history is its mesh's
    assert [r.number for r in mesh.at(3).history(limit=2)] == [scripted.last, scripted.last - 1]


def test_a_new_mesh_an_import_and_single_calls(store):
    mesh = store.create_mesh("m")
    assert mesh.revision == 0 and mesh.history() == []
    assert mesh.at(0).counts() == hestore.Counts(0, 0, 0, 0)
    with pytest.raises(RevisionNotFoundError):
        mesh.at(1)
    with pytest.raises(RevisionNotFoundError):
        mesh.undo()
    imported = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [[0, 1, 2], [1, 3, 2]]).mesh
    [r] = imported.history()
    assert r.number == 1 == imported.revision and r.message is None
    assert r.changes == {
        "vertex": {"created": 4, "removed": 0, "changed": 0},
        "halfedge": {"created": 10, "removed": 0, "changed": 0},
        "edge": {"created": 5, "removed": 0, "changed": 0},
        "polygon": {"created": 2, "removed": 0, "changed": 0},
    }
    d = imported.diff(0, 1)
    assert d.created == {"vertex": [0, 1, 2, 3], "halfedge": list(range(10)), "edge": list(range(5)), "polygon": [0, 1]}
    assert imported.at(0).counts() == hestore.Counts(0, 0, 0, 0)
    with store.transaction(message="named"):
        imported.set_position(imported.vertex(0), (0.0, 0.0, 1.0))
    with store.transaction():
        imported.set_position(imported.vertex(1), (1.0, 0.0, 1.0))
    assert [(r.number, r.message) for r in imported.history()] == [(3, None), (2, "named"), (1, None)]
    # a block that changes two meshes is a revision of each, with the block's message
    with store.transaction(message="both"):
        mesh.add_vertex()
        imported.set_position(imported.vertex(2), (0.0, 1.0, 1.0))
    assert (mesh.history()[0].number, mesh.history()[0].message) == (1, "both")
    assert (imported.history()[0].number, imported.history()[0].message) == (4, "both")
    # a block that changes nothing, and a refused edit, make no revision
    with store.transaction(message="nothing"):
        pass
    with pytest.raises(hestore.HestoreError):
        imported.add_polygon([imported.vertex(0), imported.vertex(1), imported.vertex(2)])
    assert imported.revision == 4 and len(imported.history()) == 4


# --------------------------------------------------------------------------
# 3. diff(a, b) is the difference of the snapshots


def _pairs(last: int) -> list[tuple[int, int]]:
    """Consecutive revisions, from 0, to the last, and a spread of the others (diffs are not cheap)."""
    pairs = {(a, a + 1) for a in range(last)} | {(0, b) for b in range(2, last + 1, 3)}
    pairs |= {(a, last) for a in range(1, last - 1, 3)}
    pairs |= {(a, b) for a in range(1, last) for b in range(a + 2, last) if (3 * a + b) % 37 == 0}
    return sorted(pairs)


def test_diff_is_the_difference_of_the_snapshots(scripted):
    mesh = scripted.mesh
    pairs = _pairs(scripted.last)
    assert len(pairs) > 50
    for a, b in pairs:
        expected = expected_diff(scripted.snaps[a], scripted.snaps[b])
        d = mesh.diff(a, b)
        assert as_dict(d) == expected, (a, b)
        assert d.counts() == counts_of(expected)
        assert bool(d) == any(expected[w][k] for w in expected for k in KINDS)
        if (a + b) % 5 == 0:
            back = mesh.diff(b, a)
            assert (back.created, back.removed, back.changed) == (d.removed, d.created, d.changed), (b, a)
    for r in (0, 7, scripted.last):
        same = mesh.diff(r, r)
        assert not same and same.counts() == EMPTY_COUNTS
    # from a view: the same
    assert as_dict(mesh.at(4).diff(2, 9)) == expected_diff(scripted.snaps[2], scripted.snaps[9])


# --------------------------------------------------------------------------
# 4. undo, redo, revert


def _message(mesh: hestore.Mesh) -> str | None:
    return mesh.history(limit=1)[0].message


@pytest.mark.slow
def test_undo_walks_the_script_back_to_empty_and_redo_walks_it_forward(script):
    mesh, snaps, last = script.mesh, script.snaps, script.last
    for k in range(1, last + 1):
        number = mesh.undo()
        assert number == mesh.revision == last + k
        assert snapshot(mesh) == snaps[last - k], f"after {k} undos"
        if k % 7 == 0:
            assert mesh.check() == []
            [r] = mesh.history(limit=1)
            assert r.message == f"undo of revision {last - k + 1}"
            assert r.changes == counts_of(expected_diff(snaps[last - k + 1], snaps[last - k]))
    assert mesh.counts() == hestore.Counts(0, 0, 0, 0) and all(mesh.properties(k) == {} for k in KINDS)
    with pytest.raises(RevisionNotFoundError, match="nothing to undo"):
        mesh.undo()
    assert mesh.revision == 2 * last
    # the undo revisions are revisions like any other: viewable, and the past is unchanged
    assert snapshot(mesh.at(last + 3)) == snaps[last - 3] and snapshot(mesh.at(7)) == snaps[7]
    messages = {r.number: r.message for r in mesh.history(limit=last)}
    assert messages == {last + k: f"undo of revision {last - k + 1}" for k in range(1, last + 1)}
    # redo walks forward again
    for k in range(1, 7):
        assert mesh.redo() == mesh.revision == 2 * last + k
        assert snapshot(mesh) == snaps[k], f"after {k} redos"
    assert _message(mesh) == "redo of revision 6"
    # undo of a redo goes back to before it; redo again
    mesh.undo()
    assert snapshot(mesh) == snaps[5] and _message(mesh) == f"undo of revision {2 * last + 6}"
    mesh.redo()
    assert snapshot(mesh) == snaps[6]
    mesh.redo()
    assert snapshot(mesh) == snaps[7] and mesh.check() == []
    # an edit clears what could be redone
    before = mesh.revision
    next_vertex = _counters(script.store, mesh)[0]
    v = mesh.add_vertex((4.0, 4.0, 4.0))
    assert v.id == next_vertex > max(set().union(*(x["elements"]["vertex"] for x in snaps.values())))
    with pytest.raises(RevisionNotFoundError, match="nothing to redo"):
        mesh.redo()
    assert mesh.revision == before + 1
    # undo of that edit, then undo goes on where the stack was
    mesh.undo()
    assert snapshot(mesh) == snaps[7]
    with pytest.raises(ElementNotFoundError):
        mesh.vertex(v.id)
    mesh.undo()
    assert snapshot(mesh) == snaps[6] and mesh.check() == []


def test_revert_to_any_revision_and_undo_it(script):
    mesh, snaps, last = script.mesh, script.snaps, script.last
    current = last
    for r in (3, 0, 17, last - 1, 9, last):
        number = mesh.revert(r)
        current += 1
        assert number == current == mesh.revision
        assert _message(mesh) == f"revert to revision {r}"
        assert snapshot(mesh) == snaps[r], f"revert to {r}"
        assert mesh.check() == []
    # a revert is undone like any edit: back to what was before it (the revert to `last`)
    mesh.revert(5)
    assert snapshot(mesh) == snaps[5]
    mesh.undo()
    assert snapshot(mesh) == snaps[last] and _message(mesh) == f"undo of revision {current + 1}"
    mesh.redo()
    assert snapshot(mesh) == snaps[5]
    # revert to a revert: to the state it made
    assert snapshot(mesh.at(current - 3)) == snaps[17]
    mesh.revert(current - 3)
    assert snapshot(mesh) == snaps[17]
    # revert to the current revision changes nothing (but is a revision)
    before = snapshot(mesh)
    number = mesh.revert(mesh.revision)
    assert snapshot(mesh) == before and mesh.history(limit=1)[0].changes == EMPTY_COUNTS
    assert number == mesh.revision


def test_undo_of_an_import_empties_the_mesh(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [[0, 1, 2], [1, 3, 2]]).mesh
    imported = snapshot(mesh)
    assert mesh.undo() == 2
    assert mesh.counts() == hestore.Counts(0, 0, 0, 0) and mesh.check() == []
    assert _message(mesh) == "undo of revision 1"
    assert mesh.history(limit=1)[0].changes == {
        "vertex": {"created": 0, "removed": 4, "changed": 0},
        "halfedge": {"created": 0, "removed": 10, "changed": 0},
        "edge": {"created": 0, "removed": 5, "changed": 0},
        "polygon": {"created": 0, "removed": 2, "changed": 0},
    }
    with pytest.raises(RevisionNotFoundError):
        mesh.undo()
    assert snapshot(mesh.at(1)) == imported
    assert mesh.redo() == 3
    assert snapshot(mesh) == imported and mesh.check() == []
    # new elements after all that: fresh ids
    assert mesh.add_vertex().id == 4


def test_ids_are_never_handed_out_twice_after_an_undo(store):
    mesh = store.create_mesh("m")
    a, b, c = (mesh.add_vertex((float(i), float(i * i), 0.0)) for i in range(3))
    e = mesh.add_edge(a, b)
    p = mesh.add_polygon([a, b, c])
    mesh.add_property("vertex", "t", "int64", default=0)
    assert (a.id, b.id, c.id, e.id, p.id) == (0, 1, 2, 0, 0)
    for _ in range(3):
        mesh.undo()  # the property, the polygon, the edge
    assert mesh.counts() == hestore.Counts(3, 0, 0, 0) and mesh.properties("vertex") == {}
    d = mesh.add_vertex()
    assert d.id == 3
    e2 = mesh.add_edge(a, b)
    p2 = mesh.add_polygon([b, c, a])
    assert e2.id not in (0, 1, 2) and e2.id >= 3  # the polygon made edges 1 and 2
    assert p2.id == 1
    assert {h.id for h in mesh.halfedges()}.isdisjoint(range(6))
    prop = mesh.add_property("vertex", "t", "int64", default=0)
    assert prop.name == "t"
    # ... and after an undo of a creation, the next creation gets a fresh id
    mesh.undo()
    mesh.undo()
    mesh.undo()  # the property, p2, e2
    assert mesh.add_vertex().id == 4
    assert mesh.check() == []


def test_undo_redo_and_revert_inside_a_block(store):
    mesh = store.create_mesh("m")
    a = mesh.add_vertex((0.0, 0.0, 0.0))
    b = mesh.add_vertex((1.0, 0.0, 0.0))
    mesh.set_position(b, (2.0, 0.0, 0.0))
    mesh.undo()  # revision 4: something to undo and something to redo
    before = dump(store, ALL_TABLES)
    with pytest.raises(Rollback):
        with store.transaction():
            mesh.add_edge(a, b)
            for op in (mesh.undo, lambda: mesh.revert(1), lambda: mesh.revert(4)):
                with pytest.raises(InvalidInputError, match="block"):
                    op()
            assert mesh.counts().edges == 1 and b.position == (1.0, 0.0, 0.0)  # the block goes on
            raise Rollback
    assert dump(store, ALL_TABLES) == before
    # first in a block: allowed, its own revision; a rollback takes it back
    with pytest.raises(Rollback):
        with store.transaction():
            assert mesh.redo() == 5
            assert b.position == (2.0, 0.0, 0.0)
            raise Rollback
    assert dump(store, ALL_TABLES) == before and mesh.revision == 4 and b.position == (1.0, 0.0, 0.0)
    with store.transaction():
        assert mesh.redo() == 5
    assert b.position == (2.0, 0.0, 0.0) and _message(mesh) == "redo of revision 3"


def test_redo_inside_a_block_that_changed_the_mesh_is_invalid_input(store):
    mesh = store.create_mesh("m")
    a = mesh.add_vertex((0.0, 0.0, 0.0))
    mesh.set_position(a, (2.0, 0.0, 0.0))
    mesh.undo()  # revision 3: revision 2 can be redone
    before = dump(store, ALL_TABLES)
    with pytest.raises(Rollback):
        with store.transaction():
            mesh.add_vertex()
            with pytest.raises(InvalidInputError, match="block"):
                mesh.redo()
            raise Rollback
    assert dump(store, ALL_TABLES) == before


def test_undo_and_redo_of_a_mesh_seen_by_another_store(db_url):
    """The undo stack is the history's: another connection (or a reopened store) sees the same one."""
    with hestore.open(db_url) as one:
        mesh = one.create_mesh("m")
        v = mesh.add_vertex((1.0, 2.0, 3.0))
        mesh.set_position(v, (4.0, 5.0, 6.0))
        with hestore.open(db_url) as two:
            other = two.mesh("m")
            assert other.undo() == 3
            assert v.position == (1.0, 2.0, 3.0)
            assert mesh.undo() == 4 and other.counts().vertices == 0
        assert mesh.redo() == 5 and v.position == (1.0, 2.0, 3.0)
    with hestore.open(db_url) as three:
        mesh = three.mesh("m")
        assert mesh.redo() == 6 and mesh.vertex(0).position == (4.0, 5.0, 6.0)
        with pytest.raises(RevisionNotFoundError):
            mesh.redo()


# --------------------------------------------------------------------------
# 5. Branches: copy_mesh(revision=r)


def _counters(store: hestore.Store, mesh: hestore.Mesh) -> tuple[int, int, int]:
    m = schema.meshes
    with store.session.reading() as conn:
        row = conn.execute(sa.select(m.c.next_vertex, m.c.next_edge, m.c.next_polygon).where(m.c.id == mesh.id)).one()
    return tuple(row)


def test_a_copy_at_a_revision_is_that_revision_and_independent(scripted):
    store, mesh, snaps = scripted.store, scripted.mesh, scripted.snaps
    counters = _counters(store, mesh)
    ever = {k: set().union(*(s["elements"][k] for s in snaps.values())) for k in KINDS}
    assert counters[0] > max(ever["vertex"]) and counters[2] > max(ever["polygon"])
    for r in (0, 4, 13, 20, scripted.last):
        copy = store.copy_mesh("m", f"branch-{r}", revision=r)
        assert copy.revision == 1 and not copy.is_view
        assert snapshot(copy) == snaps[r], f"revision {r}"
        assert snapshot(copy.at(1)) == snaps[r] and copy.check() == []
        assert copy.at(0).counts() == hestore.Counts(0, 0, 0, 0)
        [first] = copy.history()
        assert first.number == 1 and first.message == f"copy of 'm' at revision {r}"
        created = counts_of(expected_diff(snaps[0], snaps[r]))
        assert first.changes == created
        assert counts_of(as_dict(copy.diff(0, 1))) == created
        assert _counters(store, copy) == counters  # ids go on from the source's current counters
    # independent: the copy's edits do not reach the source, and its new ids were never the source's
    copy = store.mesh("branch-13")
    a, b = copy.vertex(0), copy.vertex(1)
    v = copy.add_vertex((7.0, 7.0, 7.0))
    e = copy.add_edge(v, a)
    p = copy.add_polygon([b, a, v])  # beside the free side of a–b
    copy.set_position(a, (-1.0, -1.0, -1.0))
    copy.vertex(1)["t"] = 42.0
    assert (v.id, e.id, p.id) == (counters[0], counters[1], counters[2])
    assert v.id not in ever["vertex"] and e.id not in ever["edge"] and p.id not in ever["polygon"]
    assert copy.revision == 6 and copy.check() == []
    assert snapshot(copy.at(1)) == snaps[13]
    assert snapshot(mesh) == snaps[scripted.last] and mesh.revision == scripted.last
    # undo of the copy's first revision empties it (revision 0 of a copy is empty)
    for _ in range(6):
        copy.undo()
    assert copy.counts() == hestore.Counts(0, 0, 0, 0)
    assert snapshot(mesh) == snaps[scripted.last]
    # a copy of a copy, at its revision 1
    again = store.copy_mesh("branch-13", "again", revision=1)
    assert snapshot(again) == snaps[13] and again.history()[0].message == "copy of 'branch-13' at revision 1"
    for bad in (-1, scripted.last + 1):
        with pytest.raises(RevisionNotFoundError):
            store.copy_mesh("m", "nope", revision=bad)
    for bad in (True, 1.0, "3"):
        with pytest.raises(InvalidInputError):
            store.copy_mesh("m", "nope", revision=bad)
    assert "nope" not in store.meshes()


def test_the_source_goes_on_independently_of_its_branch(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    mesh.add_vertex((3.0, 3.0, 3.0))
    at2 = snapshot(mesh)
    mesh.remove_polygon(mesh.polygon(0))
    branch = store.copy_mesh("t", "b", revision=2)
    assert snapshot(branch) == at2
    mesh.set_position(mesh.vertex(0), (0.0, 0.0, 5.0))
    mesh.undo()
    mesh.undo()
    assert snapshot(branch) == at2 and branch.revision == 1 and len(branch.history()) == 1
    assert snapshot(mesh) == at2


# --------------------------------------------------------------------------
# 6. prune_history


def test_prune_keeps_the_newest_revisions(script):
    mesh, snaps, last = script.mesh, script.snaps, script.last
    store = script.store
    before = dump(store, ALL_TABLES)
    oldest = mesh.prune_history(keep=10)
    assert oldest == last - 9
    assert mesh.revision == last  # pruning is not a revision
    assert dump(store, ALL_TABLES)["meshes"] != before["meshes"]  # (only kept_from moved)
    kept = mesh.history()
    assert [r.number for r in kept] == list(range(last, oldest - 1, -1))
    for r in kept:  # the oldest kept says what it changed still
        assert r.changes == counts_of(expected_diff(snaps[r.number - 1], snaps[r.number])), r.number
    for r in range(oldest, last + 1, 2):
        assert snapshot(mesh.at(r)) == snaps[r]
    assert as_dict(mesh.diff(oldest, last)) == expected_diff(snaps[oldest], snaps[last])
    rows = dump(store, ALL_TABLES)
    for r in (0, 1, oldest - 1):
        with pytest.raises(RevisionNotFoundError, match="no longer kept"):
            mesh.at(r)
        with pytest.raises(RevisionNotFoundError):
            mesh.diff(r, last)
        with pytest.raises(RevisionNotFoundError):
            mesh.diff(last, r)
        with pytest.raises(RevisionNotFoundError):
            mesh.revert(r)
        with pytest.raises(RevisionNotFoundError):
            store.copy_mesh("m", "old", revision=r)
    assert dump(store, ALL_TABLES) == rows and mesh.revision == last
    # undo walks back to the oldest kept, not past it
    for k in range(1, 10):
        mesh.undo()
        assert snapshot(mesh) == snaps[last - k]
    assert snapshot(mesh) == snaps[oldest]
    with pytest.raises(RevisionNotFoundError):
        mesh.undo()
    assert mesh.revision == last + 9
    # pruning again, down to the current revision alone
    assert mesh.prune_history(keep=1) == mesh.revision
    assert [r.number for r in mesh.history()] == [mesh.revision]
    assert snapshot(mesh.at(mesh.revision)) == snaps[oldest]
    with pytest.raises(RevisionNotFoundError):
        mesh.at(mesh.revision - 1)
    with pytest.raises(RevisionNotFoundError):
        mesh.undo()
    # keeping more than there are keeps everything that is left; bad keeps are refused
    assert mesh.prune_history(keep=1000) == mesh.revision
    for bad in (0, -3):
        with pytest.raises(InvalidInputError):
            mesh.prune_history(keep=bad)
    for bad in (True, 2.0, "2", None):
        with pytest.raises(InvalidInputError):
            mesh.prune_history(keep=bad)
    # edits go on, and are kept
    mesh.add_vertex((1.0, 2.0, 3.0))
    assert len(mesh.history()) == 2 and mesh.check() == []
    mesh.undo()
    assert snapshot(mesh) == snaps[oldest]


def test_prune_of_a_young_mesh_keeps_all(store):
    mesh = store.create_mesh("m")
    assert mesh.prune_history(keep=5) == 0 and mesh.revision == 0
    mesh.add_vertex()
    mesh.add_vertex()
    assert mesh.prune_history(keep=5) == 0
    assert mesh.at(0).counts().vertices == 0 and [r.number for r in mesh.history()] == [2, 1]
    assert mesh.prune_history(keep=2) == 1
    with pytest.raises(RevisionNotFoundError):
        mesh.at(0)
    assert mesh.at(1).counts().vertices == 1


def test_a_view_of_a_revision_pruned_since_refuses_to_read(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    mesh.set_position(mesh.vertex(0), (0.0, 0.0, 1.0))
    mesh.add_vertex((3.0, 3.0, 3.0))
    mesh.remove_polygon(mesh.polygon(0))
    view = mesh.at(1)
    before = snapshot(view)
    assert mesh.prune_history(keep=1) == 4
    with pytest.raises(RevisionNotFoundError):
        mesh.at(1)
    # the view made before: refuses (as at(1) does now), or still shows revision 1 whole; never a broken mesh
    try:
        assert snapshot(view) == before and view.check() == []
    except RevisionNotFoundError:
        pass


def _view_reads(view: hestore.Mesh, tmp_path: Path) -> dict:
    """Every kind of read of a view, each a call: what must all refuse once the view's revision is gone."""
    v = view.vertex(0)
    h = v.halfedge
    p = view.polygon(0)
    return {
        "counts": view.counts,
        "vertex": lambda: view.vertex(1),
        "missing vertex": lambda: view.vertex(10**6),
        "position": lambda: v.position,
        "halfedge of a vertex": lambda: v.halfedge,
        "neighbors": lambda: v.neighbors(),
        "one ring": lambda: list(v.outgoing()),
        "twin": lambda: h.twin,
        "next": lambda: h.next,
        "polygon corners": lambda: p.vertices(),
        "find_halfedge": lambda: view.find_halfedge(v, view.vertex(1)),
        "is_boundary": lambda: v.is_boundary,
        "vertices": lambda: list(view.vertices()),
        "property": lambda: v["t"],
        "properties": lambda: view.properties("vertex"),
        "property_array": lambda: view.property_array("vertex", "t"),
        "k_ring": lambda: view.k_ring(v, 2),
        "shortest_path": lambda: view.shortest_path(v, view.vertex(5)),
        "stats": view.stats,
        "check": view.check,
        "boundary_loops": view.boundary_loops,
        "components": view.components,
        "to_arrays": view.to_arrays,
        "to_networkx": lambda: view.to_networkx(),
        "export": lambda: view.export(tmp_path / "view.ply"),
        "at": lambda: view.at(view.revision),
    }


def _refused(reads: dict, error: type, match: str) -> list:
    """The names of the ``reads`` that do not raise ``error`` with ``match``, and what they did instead."""
    wrong = []
    for name, read in reads.items():
        try:
            got = read()
        except error as exc:
            if not re.search(match, str(exc)):
                wrong.append((name, str(exc)))
        except Exception as exc:  # noqa: BLE001 - reported
            wrong.append((name, repr(exc)))
        else:
            wrong.append((name, f"returned {got!r:.80}"))
    return wrong


def _edited_grid(store: hestore.Store, name: str = "g", **options) -> hestore.Mesh:
    """A 3 × 3 grid (revision 1) with a property (2), three moved vertices (3–5) and a removed polygon (6)."""
    mesh = store.import_arrays(name, *triangle_grid(3), **options).mesh
    mesh.add_property("vertex", "t", "float64", default=1.0)
    for i in range(3):
        mesh.set_position(mesh.vertex(i), (float(i), -1.0, 0.5))
    mesh.remove_polygon(mesh.polygon(17))
    return mesh


def test_a_view_another_store_prunes_away_refuses_every_read(db_url, tmp_path):
    """SPEC §4.1: pruned revisions can no longer be viewed, also through a view opened before the prune."""
    with hestore.open(db_url) as one, hestore.open(db_url) as two:
        mesh = _edited_grid(one)
        views = {r: mesh.at(r) for r in (2, 3, 6)}
        reads = {r: _view_reads(view, tmp_path) for r, view in views.items()}
        expected = {r: snapshot(view) for r, view in views.items()}
        with pytest.raises(ElementNotFoundError):
            reads[2].pop("missing vertex")()  # while the revision is kept, an element it never had is missing
        for read in reads[2].values():
            read()  # and every other read works
        assert two.mesh("g").prune_history(keep=2) == 5
        assert _refused(reads[2], RevisionNotFoundError, "no longer kept") == []
        with pytest.raises(RevisionNotFoundError):
            snapshot(views[3])
        assert snapshot(views[6]) == expected[6] and views[6].check() == []
        assert [r.number for r in mesh.history()] == [6, 5]
        with pytest.raises(RevisionNotFoundError):
            mesh.diff(3, 6)
        # the mesh is unchanged: only its past went
        assert snapshot(mesh) == expected[6] and mesh.check() == []


def test_a_view_of_a_mesh_another_store_deletes_refuses_every_read(db_url, tmp_path):
    with hestore.open(db_url) as one, hestore.open(db_url) as two:
        mesh = _edited_grid(one)
        reads = _view_reads(mesh.at(2), tmp_path)
        two.delete_mesh("g")
        assert _refused(reads, hestore.MeshNotFoundError, "deleted") == []


def test_a_view_of_a_mesh_without_history_refuses_once_another_store_edits_it(db_url, tmp_path):
    with hestore.open(db_url) as one, hestore.open(db_url) as two:
        mesh = _edited_grid(one, history=False)
        view = mesh.at(mesh.revision)  # the current revision is the one that can be read
        expected = snapshot(view)
        reads = _view_reads(view, tmp_path)
        assert snapshot(view) == snapshot(mesh)
        other = two.mesh("g")
        other.set_position(other.vertex(4), (9.0, 9.0, 9.0))
        assert _refused(reads, RevisionNotFoundError, "no history") == []
        assert snapshot(mesh) != expected


def _pruner(url: str, rounds: int, results) -> None:
    """Split an edge per revision (so revision ``r`` has ``r + 15`` vertices), pruning to 3 revisions now and then."""
    try:
        store = hestore.open(url, busy_timeout=20.0)
        mesh = store.mesh("g")
        for i in range(rounds):
            mesh.split_edge(mesh.edge(i % 20))
            if i % 4 == 3:
                mesh.prune_history(keep=3)
        store.close()
        results.put(("ok", rounds))
    except BaseException:
        results.put(("error", None, traceback.format_exc()))


def _pruned_viewer(url: str, seed: int, stop, results) -> None:
    """Read views of random revisions while another process prunes: right, or `RevisionNotFoundError`."""
    import random

    try:
        store = hestore.open(url)
        mesh = store.mesh("g")
        rng = random.Random(seed)
        read = gone = 0
        wrong = []
        while not stop.is_set() and len(wrong) < 5:
            r = rng.randint(1, mesh.revision)
            try:
                view = mesh.at(r)
            except RevisionNotFoundError:
                gone += 1
                continue
            for what in ("counts", "check", "arrays", "ring", "position"):
                try:
                    if what == "counts":
                        got = view.counts().vertices
                    elif what == "check":
                        got = [str(p) for p in view.check()]
                    elif what == "arrays":
                        got = len(view.to_arrays().positions)
                    elif what == "ring":
                        got = len(view.k_ring(view.vertex(0), 1)) > 1
                    else:
                        got = view.vertex(15 + r - 1).position is not None if r > 1 else True
                except RevisionNotFoundError:
                    gone += 1
                    continue
                want = {"counts": r + 15, "check": [], "arrays": r + 15, "ring": True, "position": True}[what]
                read += 1
                if got != want:
                    wrong.append((r, what, got, want))
        store.close()
        results.put(("ok", read, gone, wrong))
    except BaseException:
        results.put(("error", None, traceback.format_exc()))


@pytest.mark.slow
def test_views_read_while_another_process_prunes_are_right_or_refuse(db_url):
    """Two processes read views of random revisions while a third edits and prunes: never a broken mesh."""
    with hestore.open(db_url) as store:
        store.import_arrays("g", *triangle_grid(3))
    stop = CTX.Event()
    results, views = CTX.Queue(), CTX.Queue()
    viewers = [_run(_pruned_viewer, db_url, seed, stop, views) for seed in range(2)]
    pruner = [_run(_pruner, db_url, 40, results)]
    try:
        _gather(pruner, results)
    finally:
        stop.set()
    reports = _gather(viewers, views)
    assert all(not r[3] for r in reports), f"views read states that never existed: {reports}"
    assert sum(r[1] for r in reports) > 0 and sum(r[2] for r in reports) > 0, reports


# --------------------------------------------------------------------------
# 7. Meshes without history


def test_a_mesh_without_history(store):
    for how in ("create", "import"):
        _without_history(store, how)
    with pytest.raises(InvalidInputError):
        store.create_mesh("x", history=1)
    with pytest.raises(InvalidInputError):
        store.import_arrays("x", [(0, 0, 0), (1, 1, 0), (2, 0, 0)], [[0, 1, 2]], history="no")
    assert store.meshes() == ["c-create", "c-import", "m-create", "m-import"]


def _without_history(store: hestore.Store, how: str) -> None:
    name = f"m-{how}"
    if how == "create":
        mesh = store.create_mesh(name, history=False)
        a, b, c = (mesh.add_vertex((float(i), float(i % 2), 0.0)) for i in range(3))
        mesh.add_polygon([a, b, c])
        expected = 4
    else:
        mesh = store.import_arrays(name, [(0, 0, 0), (1, 1, 0), (2, 0, 0)], [[0, 1, 2]], history=False).mesh
        expected = 1
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.vertex(0)["t"] = 3.0
    mesh.set_position(mesh.vertex(1), (1.0, 2.0, 0.0))
    expected += 3
    assert mesh.revision == expected  # revisions still count
    assert mesh.history() == [] and mesh.history(limit=2) == []
    assert snapshot(mesh.at(expected)) == snapshot(mesh) and mesh.at(expected).check() == []
    before = dump(store, ALL_TABLES)
    for r in (0, 1, expected - 1):
        with pytest.raises(RevisionNotFoundError, match="history"):
            mesh.at(r)
        with pytest.raises(RevisionNotFoundError):
            mesh.diff(r, expected)
        with pytest.raises(RevisionNotFoundError):
            mesh.revert(r)
        with pytest.raises(RevisionNotFoundError):
            store.copy_mesh(name, "c", revision=r)
    with pytest.raises(RevisionNotFoundError):
        mesh.undo()
    with pytest.raises(RevisionNotFoundError):
        mesh.redo()
    with pytest.raises(RevisionNotFoundError):
        mesh.revert(expected)
    assert dump(store, ALL_TABLES) == before and mesh.revision == expected
    # no row version of its past is kept
    assert all(not [row for row in before[h.name] if row[0] == mesh.id] for h in schema.HISTORY.values())
    # a copy at the current revision works, and keeps no history either
    copy = store.copy_mesh(name, f"c-{how}", revision=expected)
    assert snapshot(copy) == snapshot(mesh) and copy.history() == []
    copy.add_vertex()
    assert copy.history() == [] and copy.revision == 2
    with pytest.raises(RevisionNotFoundError):
        copy.at(1)
    assert mesh.diff(expected, expected).counts() == EMPTY_COUNTS


def _grid(store: hestore.Store, name: str, n: int, history: bool) -> hestore.Mesh:
    """An n×n-cell grid of triangles, each cell split by its diagonal v → v+n+2."""
    return store.import_arrays(name, *triangle_grid(n), history=history).mesh


def _work(store: hestore.Store, db_url: str, call) -> tuple[object, int]:
    """``call()``'s result, and the work its reads cost the database, counted, not timed.

    Every SELECT the call sends is run again on a connection of its own:
    on PostgreSQL under ``EXPLAIN (ANALYZE, BUFFERS)`` (the buffers its
    plan touched), on SQLite with a progress handler (its virtual machine's
    instructions, in thousands). Both grow with the rows a plan visits, so a
    plan that turns a linear read quadratic shows, whatever the clock says.
    """
    sent = []
    with store.session.traced(lambda sql, params: sent.append((sql, params)), parameters=True):
        result = call()
    reads = [(sql, params) for sql, params in sent if sql.lstrip().upper().startswith(("SELECT", "WITH", "("))]
    work = 0
    if store.session.is_sqlite:
        import sqlite3

        conn = sqlite3.connect(sa.engine.make_url(db_url).database)
        steps = [0]

        def count():
            steps[0] += 1
            return 0

        conn.set_progress_handler(count, 1000)
        for sql, params in reads:
            conn.execute(sql, params or ()).fetchall()
        conn.close()
        return result, steps[0]
    engine = sa.create_engine(db_url, poolclass=sa.pool.NullPool)
    try:
        raw = engine.raw_connection()
        cur = raw.cursor()
        for sql, params in reads:
            cur.execute("EXPLAIN (ANALYZE, BUFFERS, FORMAT JSON) " + sql, params)
            plan = cur.fetchone()[0][0]["Plan"]
            work += plan.get("Shared Hit Blocks", 0) + plan.get("Shared Read Blocks", 0)
        raw.close()
    finally:
        engine.dispose()
    return result, work


def test_history_of_bulk_writes_costs_what_they_changed(store, db_url):
    """``history`` and ``diff`` of a bulk property write and of ``set_positions`` read in linear time.

    On PostgreSQL right after such a write the planner has no statistics of
    the rows just written, and a read that joined the history to itself by
    key was planned as a loop over one range of it per changed key: 19 s
    for 43,680 values. Here the work per changed value must stay bounded,
    on both databases, whatever the planner knows.
    """
    mesh = _grid(store, "g", 60, True)  # 22,080 half-edges, 3,721 vertices
    counts = mesh.counts()
    mesh.add_property("halfedge", "w", "float64", default=0.0)
    ids, _ = mesh.property_array("halfedge", "w")
    mesh.set_property_array("halfedge", "w", ids, np.arange(1, len(ids) + 1, dtype=np.float64))  # revision 3
    positions = mesh.to_arrays().positions
    mesh.set_positions(np.arange(counts.vertices), positions + 1.0)  # revision 4
    changed = counts.halfedges + counts.vertices
    calls = {
        "history(limit=1) after set_positions": lambda: mesh.history(limit=1)[0].changes["vertex"]["changed"],
        "history(limit=2)": lambda: [r.changes for r in mesh.history(limit=2)],
        "diff(2, 3), before the last revision": lambda: len(mesh.diff(2, 3).changed["halfedge"]),
        "diff(3, 2)": lambda: len(mesh.diff(3, 2).changed["halfedge"]),
        "diff(2, 4)": lambda: mesh.diff(2, 4).counts(),
    }
    results = {}
    for name, call in calls.items():
        results[name], work = _work(store, db_url, call)
        assert work < 20 * changed, f"{name}: {work} units of work for {changed} changed values"
    assert results["history(limit=1) after set_positions"] == counts.vertices
    assert results["diff(2, 3), before the last revision"] == results["diff(3, 2)"] == counts.halfedges
    assert results["history(limit=2)"][1]["halfedge"] == {"created": 0, "removed": 0, "changed": counts.halfedges}
    assert results["diff(2, 4)"]["vertex"]["changed"] == counts.vertices


@pytest.mark.parametrize("backend", [pytest.param("postgresql", marks=pytest.mark.postgresql)])
def test_postgresql_keeps_one_plan_for_each_write(store):
    """Writes send their rows as arrays; PostgreSQL must not plan a write again at each call.

    A planner that can count an array's elements finds every call's own plan
    cheaper than the generic one, and plans each write anew: about half the
    server's time for a small flush, and more for the history records that
    ride on it. So the arrays reach ``unnest`` through scalar subqueries,
    whose length no plan knows, and after psycopg prepares a statement and
    PostgreSQL has tried five plans of its own, one generic plan serves.
    """
    n, runs = 40, 14
    plans = []
    for history in (True, False):
        mesh = _grid(store, f"g{history:d}", n, history)
        mesh.add_property("vertex", "t", "float64", default=0.0)
        free = [mesh.add_vertex((float(k), -1.0, 0.0)) for k in range(3 * runs)]
        for k in range(runs):
            v = (k // n) * (n + 1) + k % n  # the lower-left corner of cell k
            with store.transaction():
                mesh.flip_edge(mesh.find_halfedge(mesh.vertex(v), mesh.vertex(v + n + 2)).edge)
                mesh.set_position(mesh.vertex(v), (0.0, 0.0, float(k)))
                mesh.vertex(v)["t"] = float(k)
                p = mesh.add_polygon(free[3 * k:3 * k + 3])
                if k % 2:
                    mesh.remove_polygon(p)
        with store.session.reading() as conn:
            plans += conn.execute(sa.text(
                "SELECT statement, generic_plans, custom_plans FROM pg_prepared_statements "
                "WHERE statement LIKE '%unnest(%'"
            )).all()
        # After the look: check() ends its read transaction with a ROLLBACK, and psycopg then forgets them all.
        assert mesh.check() == []
    runs_of = {sql: generic + custom for sql, generic, custom in plans}
    # Not vacuous: the half-edge updates with and without their history record each ran at every flush.
    assert [sql for sql, k in runs_of.items() if sql.startswith('UPDATE "halfedges"') and k >= runs - 6], plans
    assert [sql for sql, k in runs_of.items() if "halfedges_history" in sql and k >= runs - 6], plans
    replanned = [(sql[:80], generic, custom) for sql, generic, custom in plans if generic + custom > 5 and not generic]
    assert not replanned, replanned


@pytest.mark.slow
@pytest.mark.parametrize("backend", [pytest.param("postgresql", marks=pytest.mark.postgresql)])
def test_postgresql_writes_sized_for_the_planner_write_the_same(store, monkeypatch):
    """From ``_SIZED_ROWS`` rows a write lets the planner see its arrays: the same rows and history result."""
    plain = Script(store, "plain").run()
    monkeypatch.setattr(persistence, "_SIZED_ROWS", 1)  # every write of the second run is a sized one
    sized = Script(store, "sized").run()
    assert sized.snaps == plain.snaps
    for r, snap in sized.snaps.items():
        assert snapshot(sized.mesh.at(r)) == snap, r


# --------------------------------------------------------------------------
# 8. Values and positions: net, per revision and between revisions


#: A property of each kind: dtype, shape, a value, another.
SET_BACK = [
    ("vertex", "float64", (), 1.25, -7.5),
    ("edge", "int64", (3,), (1, 2, 3), (1, 2, 4)),
    ("polygon", "str", (), "roof", "wall"),
    ("halfedge", "float64", (6,), (1.0, 2.0, 3.0, 4.0, 5.0, 6.0), (1.0, 2.0, 3.0, 4.0, 5.0, -6.0)),  # two rows
]


def test_a_value_set_and_set_back(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    for kind, dtype, shape, first, second in SET_BACK:
        mesh.add_property(kind, "x", dtype, shape=shape)  # no default: unset is masked
        lookup = {"vertex": mesh.vertex, "halfedge": mesh.halfedge, "edge": mesh.edge, "polygon": mesh.polygon}[kind]
        element = lookup(0 if kind == "polygon" else 1)
        element["x"] = first
        r1 = mesh.revision
        element["x"] = second
        element["x"] = first  # back, in a later revision
        r3 = mesh.revision
        element["x"] = first  # the value it has: no change
        r4 = mesh.revision
        assert (r1 + 2, r1 + 3) == (r3, r4)
        changes = {r.number: r.changes for r in mesh.history(limit=4)}
        one = {**EMPTY_COUNTS, kind: {"created": 0, "removed": 0, "changed": 1}}
        assert changes == {r1: one, r1 + 1: one, r3: one, r4: EMPTY_COUNTS}, kind
        assert mesh.diff(r1, r1 + 1).changed[kind] == [element.id] == mesh.diff(r1 + 1, r3).changed[kind]
        assert not mesh.diff(r3, r4)
        assert not mesh.diff(r1, r3) and not mesh.diff(r1, r4) and mesh.diff(r1, r4).counts() == EMPTY_COUNTS
        assert mesh.diff(r1 - 1, r4).changed[kind] == [element.id]
        ids, values = mesh.at(r1 + 1).property_array(kind, "x")
        assert _value(values[ids.tolist().index(element.id)]) == _value(second)
        # set-based: the same values again are no change
        ids, values = mesh.property_array(kind, "x")
        mesh.set_property_array(kind, "x", ids, values)
        assert mesh.history(limit=1)[0].changes == EMPTY_COUNTS, kind
        # unset, then set back in one block: no change
        with store.transaction():
            del element["x"]
            element["x"] = first
        assert mesh.history(limit=1)[0].changes == EMPTY_COUNTS, kind
        mesh.undo()
        mesh.undo()
        assert _value(element["x"]) == _value(first)
        mesh.revert(r1 + 1)
        assert _value(element["x"]) == _value(second) and mesh.history(limit=1)[0].changes == one
    assert mesh.check() == []


def test_positions_set_and_set_back(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    v = mesh.vertex(2)
    mesh.set_position(v, (0.0, 2.0, 0.0))
    mesh.set_position(v, (0.0, 1.0, 0.0))  # back to the import's
    mesh.set_position(v, (0.0, 1.0, 0.0))  # the same
    assert [r.changes["vertex"]["changed"] for r in mesh.history()] == [0, 1, 1, 0]
    assert not mesh.diff(1, 3) and mesh.diff(1, 2).changed["vertex"] == [2] and not mesh.diff(3, 4)
    mesh.set_positions([mesh.vertex(0), mesh.vertex(1)], [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)])  # all the same
    assert mesh.history()[0].changes == EMPTY_COUNTS
    mesh.set_positions([mesh.vertex(0), mesh.vertex(1)], [(0.0, 0.0, 0.0), (1.0, 0.0, 1e-300)])
    assert mesh.history()[0].changes["vertex"]["changed"] == 1 and mesh.diff(4, 6).changed["vertex"] == [1]
    # -0.0 and 0.0 are different bits but the same value: stored as given, read back as given
    mesh.set_position(mesh.vertex(0), (-0.0, 0.0, 0.0))
    assert math.copysign(1.0, mesh.at(mesh.revision).vertex(0).position[0]) == -1.0
    assert math.copysign(1.0, mesh.at(mesh.revision - 1).vertex(0).position[0]) == 1.0
    with store.transaction():
        mesh.set_position(v, (5.0, 5.0, 5.0))
        mesh.set_position(v, (0.0, 1.0, 0.0))  # written back in the same block
    assert mesh.history()[0].changes == EMPTY_COUNTS


def test_setting_the_default_value_an_element_already_has_is_no_change(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    mesh.add_property("vertex", "t", "float64", default=0.5)
    v = mesh.vertex(0)
    assert v["t"] == 0.5
    r = mesh.revision
    v["t"] = 0.5  # the value it has (its default)
    assert v["t"] == 0.5 and mesh.property_array("vertex", "t")[1].tolist() == [0.5, 0.5, 0.5]
    assert mesh.revision == r + 1
    assert mesh.diff(r, r + 1).changed["vertex"] == []
    assert mesh.history()[0].changes == EMPTY_COUNTS


# --------------------------------------------------------------------------
# 9. Refusals change nothing


def test_bad_revision_numbers_are_refused_and_change_nothing(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    mesh.add_vertex((2.0, 2.0, 2.0))
    url = store.url.render_as_string(hide_password=False)
    before = dump(store, ALL_TABLES)
    missing = (-1, -(2**63), 3, 2**63 - 1, 2**63, 2**70)
    wrong_type = (True, False, "1", 1.0, 1.5, None, [1], np.float64(1.0))
    calls = {
        "at": lambda r: mesh.at(r),
        "diff a": lambda r: mesh.diff(r, 1),
        "diff b": lambda r: mesh.diff(1, r),
        "revert": lambda r: mesh.revert(r),
        "copy": lambda r: store.copy_mesh("t", "c", revision=r),
    }
    for name, call in calls.items():
        for r in missing:
            with pytest.raises(RevisionNotFoundError) as info:
                call(r)
            assert isinstance(info.value, KeyError) and isinstance(info.value, HestoreError), name
        for r in wrong_type:
            if r is None and name == "copy":
                continue  # revision=None: the current one
            with pytest.raises(InvalidInputError):
                call(r)
    assert dump(store, ALL_TABLES) == before and dump(url, ALL_TABLES) == before and mesh.revision == 2
    # numpy integers are integers
    assert mesh.at(np.int64(1)).counts().vertices == 3 and mesh.diff(np.int32(1), np.int64(2)).created["vertex"] == [3]
    # inside a block: refused, and the block goes on
    with store.transaction():
        with pytest.raises(RevisionNotFoundError):
            mesh.revert(7)
        with pytest.raises(InvalidInputError):
            mesh.at("2")
        mesh.add_vertex()
    assert mesh.revision == 3 and mesh.counts().vertices == 5


def test_views_refuse_every_edit(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [[0, 1, 2], [1, 3, 2]]).mesh
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_vertex((5.0, 5.0, 5.0))
    view = mesh.at(2)
    v0, v1, v2, v3 = (view.vertex(i) for i in range(4))
    e = view.find_halfedge(v1, v2).edge
    h = view.find_halfedge(v0, v1)
    p = view.polygon(0)
    edits = {
        "add_vertex": lambda: view.add_vertex((1.0, 1.0, 1.0)),
        "add_edge": lambda: view.add_edge(v0, v3),
        "add_polygon": lambda: view.add_polygon([v0, v3, v2]),
        "remove_polygon": lambda: view.remove_polygon(p),
        "remove_edge": lambda: view.remove_edge(e),
        "remove_vertex": lambda: view.remove_vertex(v3),
        "set_position": lambda: view.set_position(v0, (9.0, 9.0, 9.0)),
        "set_positions": lambda: view.set_positions([v0], [(9.0, 9.0, 9.0)]),
        "split_edge": lambda: view.split_edge(e),
        "split_polygon": lambda: view.split_polygon(p, v0, v2),
        "join_polygons": lambda: view.join_polygons(e),
        "poke_polygon": lambda: view.poke_polygon(p),
        "flip_edge": lambda: view.flip_edge(e),
        "collapse_edge": lambda: view.collapse_edge(h),
        "triangulate_polygon": lambda: view.triangulate_polygon(p),
        "fill_hole": lambda: view.fill_hole(h.twin),
        "add_property": lambda: view.add_property("vertex", "u", "int64"),
        "remove_property": lambda: view.remove_property("vertex", "t"),
        "set_property_array": lambda: view.set_property_array("vertex", "t", [0], [1.0]),
        "setitem": lambda: v0.__setitem__("t", 2.0),
        "delitem": lambda: v0.__delitem__("t"),
        "undo": lambda: view.undo(),
        "redo": lambda: view.redo(),
        "revert": lambda: view.revert(1),
        "prune_history": lambda: view.prune_history(keep=1),
    }
    url = store.url.render_as_string(hide_password=False)
    before = dump(store, ALL_TABLES)
    refused = {}
    for name, edit in edits.items():
        try:
            edit()
        except ReadOnlyError as exc:
            refused[name] = str(exc)
        except Exception as exc:  # noqa: BLE001 - reported below
            refused[name] = exc
    assert {n: m for n, m in refused.items() if not isinstance(m, str)} == {}
    assert set(refused) == set(edits)
    assert all("read-only" in m for m in refused.values())
    assert dump(store, ALL_TABLES) == before and dump(url, ALL_TABLES) == before and mesh.revision == 3
    assert snapshot(mesh.at(2)) == snapshot(view)
    # the predicates answer: no operation can be done on a view, though each can on the mesh
    predicates = {
        "can_add_edge": lambda m: m.can_add_edge(m.vertex(0), m.vertex(3)),
        "can_split_edge": lambda m: m.can_split_edge(m.edge(e.id)),
        "can_flip_edge": lambda m: m.can_flip_edge(m.edge(e.id)),
        "can_collapse_edge": lambda m: m.can_collapse_edge(m.halfedge(h.id)),
        "can_join_polygons": lambda m: m.can_join_polygons(m.edge(e.id)),
        "can_poke_polygon": lambda m: m.can_poke_polygon(m.polygon(p.id)),
        "can_triangulate_polygon": lambda m: m.can_triangulate_polygon(m.polygon(p.id)),
        "can_fill_hole": lambda m: m.can_fill_hole(m.halfedge(h.twin.id)),
    }
    assert {n: f(mesh) for n, f in predicates.items()} == dict.fromkeys(predicates, True)
    assert {n: f(view) for n, f in predicates.items()} == dict.fromkeys(predicates, False)
    assert view.can_add_polygon([v0, v2, v3]) is False and mesh.can_add_polygon([mesh.vertex(i) for i in (0, 2, 3)])
    assert dump(store, ALL_TABLES) == before
    # inside a block: refused, nothing changed, and the block goes on
    with store.transaction(message="after refusals"):
        for name in ("add_vertex", "setitem", "flip_edge", "undo", "revert"):
            with pytest.raises(ReadOnlyError):
                edits[name]()
        assert dump(store, ALL_TABLES) == before
        w = mesh.add_vertex((0.5, 0.25, 0.125))
    assert mesh.revision == 4 and _message(mesh) == "after refusals"
    assert mesh.diff(3, 4).created["vertex"] == [w.id] and not any(mesh.diff(3, 4).changed.values())
    assert snapshot(view) == snapshot(mesh.at(2))


def test_handles_of_a_mesh_and_of_its_views_do_not_mix(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [[0, 1, 2], [1, 3, 2]]).mesh
    mesh.add_vertex((5.0, 5.0, 5.0))
    view, other = mesh.at(1), mesh.at(2)
    before = dump(store, ALL_TABLES)
    mine = [mesh.vertex(0), mesh.vertex(1), mesh.halfedge(0), mesh.edge(0), mesh.polygon(0)]
    theirs = [view.vertex(0), view.vertex(1), view.halfedge(0), view.edge(0), view.polygon(0)]
    # a view's handles on the mesh
    for call in (
        lambda: mesh.add_edge(theirs[0], mine[1]),
        lambda: mesh.add_polygon([theirs[0], mine[1], mesh.vertex(2)]),
        lambda: mesh.remove_vertex(theirs[0]),
        lambda: mesh.remove_edge(theirs[3]),
        lambda: mesh.remove_polygon(theirs[4]),
        lambda: mesh.set_position(theirs[0], (1.0, 1.0, 1.0)),
        lambda: mesh.flip_edge(theirs[3]),
        lambda: mesh.collapse_edge(theirs[2]),
        lambda: mesh.find_halfedge(theirs[0], mine[1]),
        lambda: mesh.split_edge(theirs[3]),
    ):
        with pytest.raises(ElementNotFoundError):
            call()
    # the mesh's handles (and another view's) on a view: refused as well, typed
    for call in (
        lambda: view.find_halfedge(mine[0], theirs[1]),
        lambda: view.find_halfedge(other.vertex(0), theirs[1]),
        lambda: other.find_halfedge(theirs[0], theirs[1]),
        lambda: view.can_flip_edge(mine[3]),
        lambda: view.add_edge(mine[0], mine[1]),
        lambda: view.remove_vertex(mine[0]),
    ):
        with pytest.raises((ElementNotFoundError, ReadOnlyError)):
            call()
    assert dump(store, ALL_TABLES) == before and mesh.revision == 2
    # reads through a handle answer for its own mesh or view
    assert theirs[0].position == (0.0, 0.0, 0.0) and len(mesh.vertex(0).neighbors()) == 2
    with pytest.raises(ElementNotFoundError):
        view.vertex(4)
    assert other.vertex(4).position == (5.0, 5.0, 5.0)


def test_edits_after_an_undo_in_the_same_block_are_part_of_the_history(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    mesh.add_vertex((5.0, 5.0, 5.0))  # revision 2
    with store.transaction(message="undo, then an edit"):
        assert mesh.undo() == 3
        w = mesh.add_vertex((8.0, 8.0, 8.0))
    assert mesh.counts().vertices == 4 and w.position == (8.0, 8.0, 8.0)
    # whatever the numbering, the current revision is the current mesh, and history accounts for w
    assert snapshot(mesh.at(mesh.revision)) == snapshot(mesh)
    assert w.id in mesh.diff(2, mesh.revision).created["vertex"]
    created = sum(r.changes["vertex"]["created"] for r in mesh.history() if r.number > 2)
    assert created == 1


def test_a_view_of_a_rolled_back_revision_is_gone(store):
    mesh = store.create_mesh("m")
    mesh.add_vertex((1.0, 1.0, 1.0))
    with pytest.raises(Rollback):
        with store.transaction():
            mesh.add_vertex((2.0, 2.0, 2.0))
            mesh.add_vertex((3.0, 3.0, 3.0))
            view = mesh.at(2)
            assert view.counts().vertices == 3
            raise Rollback
    assert mesh.revision == 1
    seen = None
    with contextlib.suppress(RevisionNotFoundError):
        seen = view.counts().vertices  # revision 2 was never made
    mesh.add_vertex((4.0, 4.0, 4.0))  # now a different revision 2
    later = None
    with contextlib.suppress(RevisionNotFoundError):
        later = view.counts().vertices
    assert (seen, later) in ((None, None), (3, 3))


# --------------------------------------------------------------------------
# 10. Several processes


def _committer(url: str, worker: int, n: int, start, results) -> None:
    """Commit ``n`` blocks to mesh "m", each adding one vertex (and setting its "w"); report back."""
    try:
        store = hestore.open(url, busy_timeout=5.0)
        mesh = store.mesh("m")
        start.wait(timeout=WAIT)
        busy = 0
        for i in range(n):
            while True:
                try:
                    with store.transaction(message=f"worker {worker} edit {i}"):
                        v = mesh.add_vertex((float(worker), float(i), 0.0))
                        v["w"] = float(worker)
                    break
                except hestore.StoreBusyError:
                    busy += 1
                    if busy > 200:
                        raise
        store.close()
        results.put(("ok", worker, busy))
    except BaseException:
        results.put(("error", worker, traceback.format_exc()))


def test_two_processes_committing_to_one_mesh(db_url):
    n = 8
    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        mesh.add_property("vertex", "w", "float64", default=-1.0)  # revision 1
    results = CTX.Queue()
    start = CTX.Barrier(2)
    procs = [_run(_committer, db_url, w, n, start, results) for w in range(2)]
    _gather(procs, results)
    assert all(p.exitcode == 0 for p in procs)
    with hestore.open(db_url) as store:
        mesh = store.mesh("m")
        last = 1 + 2 * n
        assert mesh.revision == last and mesh.check() == []
        revisions = mesh.history()
        assert [r.number for r in revisions] == list(range(last, 0, -1))
        assert {r.message for r in revisions[:-1]} == {f"worker {w} edit {i}" for w in range(2) for i in range(n)}
        for w in range(2):  # each worker's blocks are in its order
            mine = [int(r.message.split()[-1]) for r in reversed(revisions[:-1]) if r.message.startswith(f"worker {w}")]
            assert mine == list(range(n))
        times = [r.committed_at for r in reversed(revisions)]
        assert times == sorted(times)
        one_vertex = {**EMPTY_COUNTS, "vertex": {"created": 1, "removed": 0, "changed": 0}}
        assert all(r.changes == one_vertex for r in revisions[:-1])
        # revision r holds the vertices of the r - 1 blocks before it, in commit order
        for r in range(1, last + 1):
            view = mesh.at(r)
            assert [v.id for v in view.vertices()] == list(range(r - 1))
            if r > 1:
                worker = int(revisions[last - r].message.split()[1])
                assert view.vertex(r - 2).position[0] == float(worker) and view.vertex(r - 2)["w"] == float(worker)
        assert mesh.at(last // 2).check() == []
        assert mesh.undo() == last + 1 and mesh.counts().vertices == 2 * n - 1


def _die_in_a_block(url: str) -> None:
    """Edit mesh "m" in a block, make the block write its rows (a read flushes them), then die."""
    store = hestore.open(url)
    mesh = store.mesh("m")
    with store.transaction(message="never committed"):
        v = mesh.add_vertex((9.0, 9.0, 9.0))
        mesh.add_edge(v, mesh.vertex(0))
        mesh.set_position(mesh.vertex(1), (5.0, 5.0, 5.0))
        mesh.vertex(0)["t"] = 4.0
        mesh.remove_polygon(mesh.polygon(0))
        assert mesh.history()[0].message == "never committed"  # written, not committed
        os._exit(3)


def test_a_process_killed_inside_a_block_leaves_no_revision(db_url):
    with hestore.open(db_url) as store:
        mesh = store.import_arrays("m", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        mesh.add_property("vertex", "t", "float64", default=0.0)
        mesh.vertex(2)["t"] = 1.0
        snaps = {r: snapshot(mesh.at(r)) for r in range(4)}
        history = [(r.number, r.message, r.changes) for r in mesh.history()]
    committed = dump(db_url, ALL_TABLES)
    p = _run(_die_in_a_block, db_url)
    p.join(timeout=WAIT)
    if p.is_alive():
        _stop([p])
        pytest.fail("the child process did not finish")
    assert p.exitcode == 3
    assert dump(db_url, ALL_TABLES) == committed
    with hestore.open(db_url) as store:
        mesh = store.mesh("m")
        assert mesh.revision == 3 and mesh.check() == []
        assert [(r.number, r.message, r.changes) for r in mesh.history()] == history
        for r, snap in snaps.items():
            assert snapshot(mesh.at(r)) == snap
        with pytest.raises(RevisionNotFoundError):
            mesh.at(4)
        v = mesh.add_vertex((1.0, 1.0, 1.0))  # revision 4 is this one
        assert v.id == 3 and mesh.revision == 4 and mesh.history()[0].message is None
        d = mesh.diff(3, 4)
        assert d.created["vertex"] == [3] and not d.removed["polygon"] and not any(d.changed.values())
        mesh.undo()
        assert snapshot(mesh) == snaps[3]


# --------------------------------------------------------------------------
# Random edits: every revision reads back, and undo walks them all back


EDITS = ("add_vertex", "position", "value", "unset", "remove_polygon", "remove_vertex", "split_edge", "flip_edge",
         "collapse_edge", "poke_polygon", "add_polygon", "block")


def _random_edit(store: hestore.Store, mesh: hestore.Mesh, edit: str, seed: int) -> None:
    """One edit chosen by ``edit``, its elements by ``seed`` (it may be refused)."""

    def pick(items):
        items = list(items)
        return items[seed % len(items)] if items else None

    v, e, p = pick(mesh.vertices()), pick(mesh.edges()), pick(mesh.polygons())
    if edit == "add_vertex":
        mesh.add_vertex((seed % 5 / 4, seed % 7 / 4, seed % 3 / 4))
    elif edit == "position" and v is not None:
        mesh.set_position(v, (seed % 11 / 8, 0.5, -seed % 13 / 8))
    elif edit == "value" and v is not None:
        v["t"] = float(seed % 3)
    elif edit == "unset" and v is not None:
        del v["t"]
    elif edit == "remove_polygon" and p is not None:
        mesh.remove_polygon(p)
    elif edit == "remove_vertex" and v is not None:
        mesh.remove_vertex(v)
    elif edit == "split_edge" and e is not None:
        mesh.split_edge(e, triangulate=seed % 2 == 0)
    elif edit == "flip_edge" and e is not None and mesh.can_flip_edge(e):
        mesh.flip_edge(e)
    elif edit == "collapse_edge" and e is not None and mesh.can_collapse_edge(e.halfedge):
        mesh.collapse_edge(e.halfedge)
    elif edit == "poke_polygon" and p is not None:
        mesh.poke_polygon(p)
    elif edit == "add_polygon":
        free = [h for h in mesh.halfedges() if h.is_boundary]
        h = pick(free)
        if h is not None and mesh.can_fill_hole(h):
            mesh.fill_hole(h)
    elif edit == "block":
        with store.transaction(message=f"block {seed}"):
            w = mesh.add_vertex((1.0, 1.0, 1.0))
            if v is not None:
                mesh.add_edge(w, v)
                w["t"] = 5.0
                mesh.set_position(v, (2.0, 2.0, 2.0))


@pytest.mark.slow
@settings(max_examples=3, **STORED)
@given(edits=st.lists(st.tuples(st.sampled_from(EDITS), st.integers(0, 1000)), min_size=2, max_size=6))
def test_random_edits_read_back_and_undo_back(store, edits):
    name = f"r-{uuid.uuid4().hex[:8]}"
    xyz = [(x, y, 0.0) for y in range(3) for x in range(3)]
    quads = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]]
    mesh = store.import_arrays(name, xyz, quads).mesh
    # no default: an unset value is told apart from any set one (a default makes an unset value equal to it: see above)
    mesh.add_property("vertex", "t", "float64")
    snaps = {r: snapshot(mesh.at(r)) for r in (0, 1, 2)}
    for edit, seed in edits:
        before = mesh.revision
        try:
            _random_edit(store, mesh, edit, seed)
        except HestoreError:  # refused (an edge to a vertex that is not free, ...): nothing changed
            assert mesh.revision == before and snapshot(mesh) == snaps[before]
        if mesh.revision != before:
            assert mesh.revision == before + 1
            snaps[mesh.revision] = snapshot(mesh)
    last = mesh.revision
    assert mesh.check() == []
    revisions = mesh.history()
    assert [r.number for r in revisions] == list(range(last, 0, -1))
    for r in revisions:
        if r.number > 1:
            assert r.changes == counts_of(expected_diff(snaps[r.number - 1], snaps[r.number])), r.number
    for r, snap in snaps.items():
        assert snapshot(mesh.at(r)) == snap, r
    assert as_dict(mesh.diff(1, last)) == expected_diff(snaps[1], snaps[last])
    for k in range(1, last - 1):
        mesh.undo()
        assert snapshot(mesh) == snaps[last - k], f"undo {k}"
    assert mesh.check() == []


def test_a_trace_sees_the_catalogue_and_history_statements(store):
    # Every statement goes on the session's cursor, the catalogue's and history's too: a trace misses none.
    sent: list[str] = []
    with store.session.traced(sent.append):
        mesh = store.import_arrays("traced", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        mesh.add_vertex()
        [v.id for v in mesh.at(1).vertex(0).neighbors()]
        mesh.history()
    text = [" ".join(sql.split()).lower() for sql in sent]

    def seen(*words: str) -> bool:
        return any(all(w in sql for w in words) for sql in text)

    assert seen("select", "from meshes", "meshes.name =")  # the catalogue: is the name taken?
    assert seen("insert into meshes")  # the catalogue: the new mesh
    assert seen("kept_from", "from meshes")  # the view's revision is kept
    assert seen("insert into revisions")  # the import's and the edit's revisions
    assert seen("from revisions", "order by revisions.number desc")  # the history listed
    assert seen("from halfedges", "rev_to")  # the view's read, as of its revision
