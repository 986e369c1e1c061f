"""Transactions (SPEC §4): blocks, savepoints, failed operations, revisions, isolation.

Every test runs on SQLite (a file, so that a second connection sees the same
database) and on PostgreSQL. "Nothing changed" is always asserted on a full
dump of every row of every hestore table (`helpers.dump` on the store's
own connection, or on a fresh one from the URL), not on counts alone.
"""

from __future__ import annotations

import math

import pytest

import hestore
from hestore.errors import (
    ElementNotFoundError,
    HalfEdgeNotFreeError,
    HestoreError,
    InvalidInputError,
    MeshExistsError,
    MeshNotFoundError,
    NonManifoldError,
    NotAChainError,
    PolicyError,
    VertexNotFreeError,
)

from helpers import dump


class Boom(Exception):
    """Raised on purpose to leave a block."""


def build(mesh):
    """A small mixed mesh, in one transaction; returns its handles by name.

    Two triangles sharing an edge, a wire edge, a self-loop bounding a 1-gon,
    two parallel edges bounding a 2-gon, a closed "pillow" (two triangles on
    the two sides of the same three edges, so its vertices are not free) and
    an isolated vertex with a position.
    """
    store = mesh.store
    with store.transaction():
        v = [mesh.add_vertex((float(i), float(i * i), 0.5)) for i in range(8)]
        t1 = mesh.add_polygon([v[0], v[1], v[2]])
        t2 = mesh.add_polygon([v[0], v[2], v[3]])
        wire = mesh.add_edge(v[3], v[4])
        one_gon = mesh.add_polygon([v[5]])
        e1, e2 = mesh.add_edge(v[6], v[7]), mesh.add_edge(v[6], v[7])
        digon = mesh.add_polygon([e1.halfedges()[0], e2.halfedges()[1]])
        pillow = [mesh.add_vertex() for _ in range(3)]
        p1 = mesh.add_polygon(pillow)
        p2 = mesh.add_polygon(pillow[::-1])
        iso = mesh.add_vertex((-1.0, 2.5, 1e-300))
    return dict(v=v, t1=t1, t2=t2, wire=wire, one_gon=one_gon, e1=e1, e2=e2, digon=digon,
                pillow=pillow, p1=p1, p2=p2, iso=iso)


BUILT_COUNTS = hestore.Counts(vertices=12, halfedges=24, edges=12, polygons=6)


@pytest.fixture
def other(db_url):
    """A second, independent store on the same database."""
    s = hestore.open(db_url)
    yield s
    s.close()


# --------------------------------------------------------------------------
# Commit and rollback of a whole block


def test_block_commits_everything_together(store, mesh, other, db_url):
    before = dump(db_url)
    seen = other.mesh("m")
    with store.transaction():
        assert store.in_transaction
        a, b, c = (mesh.add_vertex((i, 0, 0)) for i in range(3))
        p = mesh.add_polygon([a, b, c])
        d = mesh.add_vertex()
        mesh.add_edge(c, d)
        # nothing is visible to the other connection before the commit
        assert seen.counts() == hestore.Counts(0, 0, 0, 0)
        assert dump(db_url) == before
    assert not store.in_transaction
    assert seen.counts() == hestore.Counts(vertices=4, halfedges=8, edges=4, polygons=1)
    assert [x.id for x in seen.polygon(p.id).vertices()] == [a.id, b.id, c.id]
    assert seen.revision == 1
    assert seen.check() == []
    assert dump(db_url) == dump(store)


def test_exception_rolls_back_everything_byte_for_byte(store, mesh, db_url):
    h = build(mesh)
    spare = store.create_mesh("spare", allow_loops=False)
    spare.add_edge(spare.add_vertex(), spare.add_vertex())
    before = dump(store)
    assert dump(db_url) == before
    rev = mesh.revision

    with pytest.raises(Boom):
        with store.transaction():
            # every kind of edit, on existing and on new elements
            new = [mesh.add_vertex((9.0, 9.0, 9.0)) for _ in range(3)]
            mesh.add_polygon(new)
            mesh.add_polygon([h["v"][1], h["v"][0], h["v"][3]])
            mesh.remove_polygon(h["t1"])
            mesh.remove_edge(h["wire"])
            mesh.remove_edge(h["e2"])
            mesh.remove_vertex(h["v"][5])
            mesh.remove_vertex(h["iso"])
            mesh.add_edge(h["v"][4], h["v"][4])
            store.create_mesh("created")
            store.delete_mesh("spare")
            assert mesh.check() == []
            assert dump(store) != before
            raise Boom

    assert not store.in_transaction
    assert dump(store) == before
    assert dump(db_url) == before
    assert mesh.revision == rev
    assert store.meshes() == ["m", "spare"]
    assert mesh.check() == [] and spare.check() == []
    # old handles are valid again, and the store goes on working
    assert h["t1"].degree == 3 and h["iso"].position == (-1.0, 2.5, 1e-300)
    mesh.remove_edge(h["wire"])
    assert mesh.revision == rev + 1
    assert mesh.counts().edges == BUILT_COUNTS.edges - 1


def test_keyboard_interrupt_rolls_back_too(store, mesh, db_url):
    build(mesh)
    before = dump(db_url)
    with pytest.raises(KeyboardInterrupt):
        with store.transaction():
            mesh.add_vertex()
            raise KeyboardInterrupt
    assert dump(db_url) == before == dump(store)


# --------------------------------------------------------------------------
# Nested blocks are savepoints


def test_nested_inner_rollback_keeps_outer_edits(store, mesh, db_url):
    with store.transaction():
        a = mesh.add_vertex()
        b = mesh.add_vertex()
        mesh.add_edge(a, b)
        at_savepoint = dump(store)
        with pytest.raises(Boom):
            with store.transaction():
                c = mesh.add_vertex()
                mesh.add_polygon([a, b, c])
                mesh.remove_vertex(a)
                raise Boom
        assert dump(store) == at_savepoint
        assert mesh.counts() == hestore.Counts(vertices=2, halfedges=2, edges=1, polygons=0)
        d = mesh.add_vertex()
        mesh.add_polygon([a, b, d])
    assert mesh.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
    assert mesh.revision == 1
    assert mesh.check() == []
    assert dump(db_url) == dump(store)


def test_nested_inner_commit_outer_rollback_loses_both(store, mesh, db_url):
    build(mesh)
    before = dump(db_url)
    rev = mesh.revision
    with pytest.raises(Boom):
        with store.transaction():
            mesh.add_vertex()
            with store.transaction():
                mesh.add_polygon([mesh.add_vertex() for _ in range(4)])
            assert mesh.counts().polygons == BUILT_COUNTS.polygons + 1
            raise Boom
    assert dump(db_url) == before == dump(store)
    assert mesh.revision == rev


def test_three_levels(store, mesh, db_url):
    start = dump(db_url)
    with store.transaction():
        v1 = mesh.add_vertex()
        level1 = dump(store)
        with store.transaction():
            v2 = mesh.add_vertex()
            mesh.add_edge(v1, v2)
            level2 = dump(store)
            with pytest.raises(Boom):
                with store.transaction():
                    v3 = mesh.add_vertex()
                    mesh.add_polygon([v1, v2, v3])
                    raise Boom
            assert dump(store) == level2
            with store.transaction():  # a third level that commits into the second
                v4 = mesh.add_vertex()
                p = mesh.add_polygon([v1, v2, v4])
            assert p.vertices() == [v1, v2, v4]
        assert mesh.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
        with pytest.raises(Boom):
            with store.transaction():
                mesh.remove_vertex(v1)
                with store.transaction():
                    mesh.add_vertex()
                    with store.transaction():
                        mesh.add_vertex()
                raise Boom
        assert mesh.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
        assert dump(db_url) == start  # nothing committed yet
        assert level1 != level2
    assert mesh.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
    assert mesh.revision == 1
    assert mesh.check() == []
    assert dump(db_url) == dump(store)


def test_three_levels_innermost_commit_outermost_rollback(store, mesh, db_url):
    build(mesh)
    before = dump(db_url)
    with pytest.raises(Boom):
        with store.transaction():
            with store.transaction():
                with store.transaction():
                    mesh.add_vertex()
                mesh.add_vertex()
            raise Boom
    assert dump(db_url) == before == dump(store)


# --------------------------------------------------------------------------
# An operation that raises changes nothing, inside a block too, and the block goes on


def _failing_operations(mesh, h):
    """(label, expected error, callable) for operations that must be refused."""
    v, pillow = h["v"], h["pillow"]
    t1_halfedges = h["t1"].halfedges()
    free_03 = mesh.find_halfedge(v[0], v[3])  # 0 -> 3 is free (t2 runs 3 -> 0)
    removed = mesh.add_vertex()  # committed below, then removed: a stale handle
    mesh.remove_vertex(removed)
    strict = mesh.store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    sa_, sb = strict.add_vertex(), strict.add_vertex()
    strict.add_edge(sa_, sb)
    # a vertex with a 1-gon on a loop and a wire edge: the polygon on both sides
    # of the wire edge would close a second fan at the vertex with no free gap left
    wire_h = h["wire"].halfedges()
    loop_vertex = mesh.add_vertex()
    mesh.add_polygon([loop_vertex])
    x = mesh.add_vertex()
    lw = mesh.add_edge(loop_vertex, x).halfedges()
    return [
        ("add_edge at a vertex that is not free", VertexNotFreeError, lambda: mesh.add_edge(pillow[0], v[4])),
        ("add_polygon on taken half-edges", HalfEdgeNotFreeError, lambda: mesh.add_polygon(pillow)),
        ("add_polygon by taken half-edges", HalfEdgeNotFreeError, lambda: mesh.add_polygon(t1_halfedges)),
        ("add_polygon by half-edges that do not chain", NotAChainError,
         lambda: mesh.add_polygon([free_03, wire_h[0]])),
        ("add_polygon closing a second fan at a vertex", NonManifoldError, lambda: mesh.add_polygon(list(lw))),
        # creates the edge v4 -> v6 first, then finds the pillow vertex not free
        ("add_polygon that fails after creating an edge", VertexNotFreeError,
         lambda: mesh.add_polygon([v[4], v[6], pillow[1]])),
        ("stale vertex handle", ElementNotFoundError, lambda: mesh.remove_vertex(removed)),
        ("stale handle in add_edge", ElementNotFoundError, lambda: mesh.add_edge(v[0], removed)),
        ("handle of another mesh", ElementNotFoundError, lambda: mesh.add_edge(v[0], sa_)),
        ("NaN position", InvalidInputError, lambda: mesh.add_vertex((math.nan, 0, 0))),
        ("empty polygon", InvalidInputError, lambda: mesh.add_polygon([])),
        ("mixed handle kinds", InvalidInputError, lambda: mesh.add_polygon([v[0], free_03])),
        ("self-loop forbidden", PolicyError, lambda: strict.add_edge(sa_, sa_)),
        ("parallel edge forbidden", PolicyError, lambda: strict.add_edge(sb, sa_)),
        ("mesh exists", MeshExistsError, lambda: mesh.store.create_mesh("m")),
        ("no such mesh to delete", MeshNotFoundError, lambda: mesh.store.delete_mesh("nope")),
    ]


def _failing_cases(mesh):
    h = build(mesh)
    return h, _failing_operations(mesh, h)


CASE_LABELS = [
    "add_edge at a vertex that is not free",
    "add_polygon on taken half-edges",
    "add_polygon by taken half-edges",
    "add_polygon by half-edges that do not chain",
    "add_polygon closing a second fan at a vertex",
    "add_polygon that fails after creating an edge",
    "stale vertex handle",
    "stale handle in add_edge",
    "handle of another mesh",
    "NaN position",
    "empty polygon",
    "mixed handle kinds",
    "self-loop forbidden",
    "parallel edge forbidden",
    "mesh exists",
    "no such mesh to delete",
]


def _case(mesh, label):
    h, cases = _failing_cases(mesh)
    by_label = {c[0]: c for c in cases}
    assert set(by_label) == set(CASE_LABELS)
    return h, by_label[label]


@pytest.mark.parametrize("label", CASE_LABELS)
def test_failed_operation_outside_block_changes_nothing(store, mesh, db_url, label):
    h, (_, error, op) = _case(mesh, label)
    before = dump(db_url)
    with pytest.raises(error):
        op()
    assert not store.in_transaction
    assert dump(store) == before
    assert dump(db_url) == before
    # the store goes on working
    mesh.add_edge(h["v"][4], h["iso"])
    assert mesh.check() == []


@pytest.mark.parametrize("label", CASE_LABELS)
def test_failed_operation_inside_block_changes_nothing_and_block_goes_on(store, mesh, db_url, label):
    h, (_, error, op) = _case(mesh, label)
    committed = dump(db_url)
    rev = mesh.revision
    with store.transaction():
        v = mesh.add_vertex((1.0, 2.0, 3.0))  # an edit before the failure
        before = dump(store)
        with pytest.raises(error):
            op()
        assert store.in_transaction
        assert dump(store) == before
        assert mesh.check() == []
        mesh.add_edge(v, h["iso"])  # and one after it
    assert mesh.revision == rev + 1
    assert mesh.check() == []
    after = dump(db_url)
    assert after == dump(store)
    assert len(after["vertices"]) == len(committed["vertices"]) + 1
    assert len(after["edges"]) == len(committed["edges"]) + 1
    assert after["polygons"] == committed["polygons"]


@pytest.mark.parametrize("label", CASE_LABELS)
def test_block_whose_only_edit_failed_does_not_bump_revision(store, mesh, db_url, label):
    h, (_, error, op) = _case(mesh, label)
    before = dump(db_url)
    revs = {name: store.mesh(name).revision for name in store.meshes()}
    with store.transaction():
        with pytest.raises(error):
            op()
    assert {name: store.mesh(name).revision for name in store.meshes()} == revs
    assert dump(db_url) == before == dump(store)


# --------------------------------------------------------------------------
# Revisions


def test_outside_a_block_each_mutating_call_is_its_own_transaction(store, mesh, other):
    seen = other.mesh("m")
    assert mesh.revision == 0
    a = mesh.add_vertex()
    assert mesh.revision == 1 and seen.counts().vertices == 1
    b = mesh.add_vertex()
    c = mesh.add_vertex()
    assert mesh.revision == 3
    e = mesh.add_edge(a, b)
    assert mesh.revision == 4 and seen.counts().edges == 1
    p = mesh.add_polygon([a, b, c])
    assert mesh.revision == 5 and seen.counts() == hestore.Counts(3, 6, 3, 1)
    mesh.remove_polygon(p)
    assert mesh.revision == 6 and seen.counts().polygons == 0
    mesh.remove_edge(e)
    assert mesh.revision == 7
    mesh.remove_vertex(c)
    assert mesh.revision == 8 and seen.revision == 8
    assert seen.counts() == hestore.Counts(vertices=2, halfedges=0, edges=0, polygons=0)
    # reads and refused edits are not transactions that changed the mesh
    mesh.counts(), mesh.check(), a.neighbors(), mesh.can_add_polygon([a, b])
    with pytest.raises(ElementNotFoundError):
        mesh.remove_vertex(c)
    with pytest.raises(HestoreError):
        mesh.add_polygon([a, b, c])  # c is stale
    assert mesh.revision == 8


def test_revision_block_with_50_edits_is_one(store, mesh):
    with store.transaction():
        vs = [mesh.add_vertex() for _ in range(20)]
        for i in range(18):
            mesh.add_edge(vs[i], vs[i + 1])
        ps = [mesh.add_polygon([vs[i], vs[i + 1], vs[i + 2]]) for i in range(0, 18, 2)]
        mesh.remove_polygon(ps[0])
        mesh.remove_vertex(vs[19])
        mesh.remove_edge(mesh.find_halfedge(vs[0], vs[1]).edge)
    assert mesh.revision == 1
    assert mesh.check() == []


def test_revision_rolled_back_block_is_zero(store, mesh):
    mesh.add_vertex()
    with pytest.raises(Boom):
        with store.transaction():
            for _ in range(5):
                mesh.add_vertex()
            raise Boom
    assert mesh.revision == 1


def test_revision_read_only_block_is_zero(store, mesh):
    h = build(mesh)
    rev = mesh.revision
    with store.transaction():
        mesh.counts(), mesh.check(), list(mesh.vertices()), list(mesh.polygons())
        h["v"][0].neighbors(), h["t1"].vertices(), h["wire"].vertices(), h["e1"].halfedges()[0].next
        mesh.find_halfedge(h["v"][0], h["v"][1]), store.meshes(), store.mesh("m")
    assert mesh.revision == rev


def test_revision_block_with_can_add_polygon_only_is_zero(store, mesh, db_url):
    """`can_add_polygon` writes nothing, also inside a block (and also when it would create edges)."""
    h = build(mesh)
    rev = mesh.revision
    before = dump(db_url)
    with store.transaction():
        assert mesh.can_add_polygon([h["v"][1], h["v"][0], h["v"][3]]) is True  # would use existing edges
        assert mesh.can_add_polygon(list(h["t1"].halfedges())) is False
        assert dump(store) == before
        assert mesh.can_add_polygon([h["v"][4], h["iso"], h["v"][1]]) is True  # would create edges
        assert dump(store) == before
        assert mesh.counts() == BUILT_COUNTS
    assert mesh.revision == rev
    assert dump(db_url) == before == dump(store)


def test_can_add_polygon_in_block_then_real_edits(store, mesh):
    """After a dry run inside a block, the block's real edits still commit correctly."""
    a, b, c = (mesh.add_vertex() for _ in range(3))
    with store.transaction():
        assert mesh.can_add_polygon([a, b, c])
        p = mesh.add_polygon([a, b, c])
    assert mesh.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
    assert p.vertices() == [a, b, c]
    assert mesh.check() == []
    assert mesh.revision == 4


def test_revision_block_editing_two_meshes_bumps_each_once(store, mesh):
    n = store.create_mesh("n")
    untouched = store.create_mesh("untouched")
    with store.transaction():
        for _ in range(3):
            mesh.add_vertex()
            n.add_vertex()
        mesh.add_polygon(list(mesh.vertices()))
        n.add_polygon(list(n.vertices()))
        untouched.counts()
    assert (mesh.revision, n.revision, untouched.revision) == (1, 1, 0)


def test_revision_nested_rolled_back_savepoint_only(store, mesh):
    """A block whose only edits were in a rolled-back savepoint changed nothing."""
    mesh.add_vertex()
    with store.transaction():
        with pytest.raises(Boom):
            with store.transaction():
                mesh.add_vertex()
                assert mesh.revision == 2  # the open transaction's own bump is visible to it
                raise Boom
        assert mesh.revision == 1
    assert mesh.revision == 1
    with store.transaction():
        with pytest.raises(Boom):
            with store.transaction():
                mesh.add_vertex()
                raise Boom
        mesh.add_vertex()  # the edit after the rolled-back savepoint still counts once
    assert mesh.revision == 2
    assert mesh.counts().vertices == 2


def test_revision_edits_before_and_after_savepoints_count_once(store, mesh):
    with store.transaction():
        mesh.add_vertex()
        with store.transaction():
            mesh.add_vertex()
            with store.transaction():
                mesh.add_vertex()
        mesh.add_vertex()
    assert mesh.revision == 1


# --------------------------------------------------------------------------
# Isolation: reads inside a block see its edits, other connections see commits


def test_reads_inside_block_see_own_uncommitted_edits(store, mesh, other):
    seen = other.mesh("m")
    with store.transaction():
        a, b, c, d = (mesh.add_vertex((i, i, 0)) for i in range(4))
        p = mesh.add_polygon([a, b, c])
        e = mesh.add_edge(c, d)
        assert mesh.counts() == hestore.Counts(vertices=4, halfedges=8, edges=4, polygons=1)
        assert p.vertices() == [a, b, c] and p.degree == 3
        h = mesh.find_halfedge(a, b)
        assert h.polygon == p and h.next.origin == b and h.next.next.next == h
        assert h.twin.is_boundary and h.twin.polygon is None
        assert e.vertices() == (c, d) and e.is_boundary
        assert sorted(x.id for x in c.neighbors()) == sorted([a.id, b.id, d.id])
        assert mesh.vertex(d.id) == d and mesh.edge(e.id) == e and mesh.polygon(p.id) == p
        assert [x.id for x in mesh.polygons()] == [p.id]
        assert mesh.check() == []
        assert mesh.revision == 1
        # the other connection still sees the committed (empty) mesh
        assert seen.counts() == hestore.Counts(0, 0, 0, 0)
        assert seen.revision == 0
        with pytest.raises(ElementNotFoundError):
            seen.vertex(a.id)
        # removals are seen at once too
        mesh.remove_polygon(p)
        assert mesh.counts().polygons == 0 and h.polygon is None
        with pytest.raises(ElementNotFoundError):
            p.vertices()
        assert mesh.check() == []
    assert seen.counts() == hestore.Counts(vertices=4, halfedges=8, edges=4, polygons=0)
    assert seen.revision == 1
    assert seen.check() == []


def test_other_connection_sees_only_committed_state(store, mesh, other, db_url):
    h = build(mesh)
    seen = other.mesh("m")
    committed = dump(db_url)
    rev = seen.revision
    with store.transaction():
        mesh.remove_vertex(h["v"][0])
        mesh.add_polygon([mesh.add_vertex() for _ in range(5)])
        n = store.create_mesh("n")
        n.add_vertex()
        assert mesh.counts() != BUILT_COUNTS
        # other connection: old counts, old revision, no new mesh, valid mesh
        assert seen.counts() == BUILT_COUNTS
        assert seen.revision == rev
        assert other.meshes() == ["m"]
        with pytest.raises(MeshNotFoundError):
            other.mesh("n")
        assert seen.check() == []
        assert h["t1"].mesh is mesh and seen.polygon(h["t1"].id).degree == 3
        assert dump(db_url) == committed
    assert seen.counts() == hestore.Counts(
        vertices=BUILT_COUNTS.vertices - 1 + 5,
        halfedges=BUILT_COUNTS.halfedges - 6 + 10,
        edges=BUILT_COUNTS.edges - 3 + 5,
        polygons=BUILT_COUNTS.polygons - 2 + 1,
    )
    assert seen.revision == rev + 1
    assert other.meshes() == ["m", "n"]
    assert other.mesh("n").counts().vertices == 1
    assert seen.check() == []
    assert dump(db_url) == dump(other) == dump(store)


def test_other_connection_never_sees_rolled_back_block(store, mesh, other, db_url):
    build(mesh)
    before = dump(other)
    with pytest.raises(Boom):
        with store.transaction():
            mesh.add_vertex()
            assert dump(other) == before
            raise Boom
    assert dump(other) == before


# --------------------------------------------------------------------------
# The mesh catalogue inside blocks


def test_create_mesh_rolls_back(store, db_url):
    before = dump(db_url)
    with pytest.raises(Boom):
        with store.transaction():
            m = store.create_mesh("a")
            m.add_polygon([m.add_vertex() for _ in range(3)])
            assert store.meshes() == ["a"]
            raise Boom
    assert store.meshes() == []
    with pytest.raises(MeshNotFoundError):
        store.mesh("a")
    assert dump(db_url) == before
    # the name is free again
    again = store.create_mesh("a")
    assert again.counts().vertices == 0


def test_delete_mesh_rolls_back(store, mesh, db_url):
    build(mesh)
    before = dump(db_url)
    with pytest.raises(Boom):
        with store.transaction():
            store.delete_mesh("m")
            assert store.meshes() == []
            raise Boom
    assert store.meshes() == ["m"]
    assert dump(db_url) == before == dump(store)
    assert mesh.check() == [] and mesh.counts() == BUILT_COUNTS


def test_delete_mesh_after_edits_in_same_block_rolls_back(store, mesh, db_url):
    build(mesh)
    before = dump(db_url)
    with pytest.raises(Boom):
        with store.transaction():
            mesh.add_vertex()
            store.delete_mesh("m")
            store.create_mesh("m").add_vertex()
            raise Boom
    assert dump(db_url) == before == dump(store)


def test_catalogue_changes_in_savepoints(store, db_url):
    with store.transaction():
        a = store.create_mesh("a")
        a.add_vertex()
        with pytest.raises(Boom):
            with store.transaction():
                store.create_mesh("b").add_vertex()
                store.delete_mesh("a")
                raise Boom
        assert store.meshes() == ["a"]
        with store.transaction():
            store.create_mesh("c")
        store.delete_mesh("c")
        store.create_mesh("c", allow_loops=False)
    assert store.meshes() == ["a", "c"]
    assert store.mesh("a").counts().vertices == 1
    assert store.mesh("c").allow_loops is False
    assert dump(db_url) == dump(store)


def test_delete_mesh_commit_removes_every_row(store, mesh, db_url):
    build(mesh)
    keep = store.create_mesh("keep")
    keep.add_polygon([keep.add_vertex() for _ in range(3)])
    # meshes rows start with the mesh id, element rows with their mesh_id
    kept = {t: [r for r in rows if r[0] == keep.id] for t, rows in dump(db_url).items()}
    with store.transaction():
        store.delete_mesh("m")
    after = dump(db_url)
    assert after == kept


def test_mesh_exists_and_not_found_errors(store, mesh):
    with pytest.raises(MeshExistsError) as info:
        store.create_mesh("m")
    assert isinstance(info.value, InvalidInputError) and isinstance(info.value, ValueError)
    with pytest.raises(MeshNotFoundError) as info:
        store.mesh("nope")
    assert isinstance(info.value, ElementNotFoundError) and isinstance(info.value, KeyError)
    with pytest.raises(MeshNotFoundError):
        store.delete_mesh("nope")
    # inside a block: the refused call changes nothing and the block goes on
    with store.transaction():
        store.create_mesh("n")
        with pytest.raises(MeshExistsError):
            store.create_mesh("n")
        with pytest.raises(MeshExistsError):
            store.create_mesh("m")
        with pytest.raises(MeshNotFoundError):
            store.mesh("nope")
        store.mesh("n").add_vertex()
    assert store.meshes() == ["m", "n"]
    assert store.mesh("n").counts().vertices == 1


def test_handle_of_deleted_mesh(store, mesh):
    v = mesh.add_vertex()
    store.delete_mesh("m")
    with pytest.raises(MeshNotFoundError):
        mesh.add_vertex()
    with pytest.raises(ElementNotFoundError):
        mesh.revision
    with pytest.raises(ElementNotFoundError):
        v.degree


@pytest.mark.parametrize("new_name", ["m", "other"])
def test_mesh_object_of_deleted_mesh_never_reaches_a_newer_mesh(store, mesh, db_url, new_name):
    """A `Mesh` whose mesh was deleted stays dead, also after another mesh is created.

    Mesh ids must not be handed out again (as element ids are not): otherwise a
    stale `Mesh` object (or another process's) silently reads and edits
    whatever mesh gets the old id next.
    """
    v = mesh.add_vertex()
    store.delete_mesh("m")
    again = store.create_mesh(new_name)
    again.add_vertex()
    before = dump(db_url)
    assert again != mesh
    with pytest.raises(MeshNotFoundError):
        mesh.add_vertex()
    with pytest.raises(ElementNotFoundError):
        mesh.revision
    with pytest.raises(ElementNotFoundError):
        v.degree
    assert dump(db_url) == before
    assert again.counts().vertices == 1


# --------------------------------------------------------------------------
# Ids


def _all_ids(mesh) -> dict:
    return {
        "vertices": {x.id for x in mesh.vertices()},
        "halfedges": {x.id for x in mesh.halfedges()},
        "edges": {x.id for x in mesh.edges()},
        "polygons": {x.id for x in mesh.polygons()},
    }


def test_ids_of_committed_then_deleted_elements_are_never_reused(store, mesh, db_url):
    h = build(mesh)
    ever = _all_ids(mesh)

    def step(m, fn):
        before = _all_ids(m)
        result = fn()
        after = _all_ids(m)
        for kind in ever:
            new = after[kind] - before[kind]
            assert not new & ever[kind], f"{kind} ids reused: {sorted(new & ever[kind])}"
            ever[kind] |= new
        return result

    # delete the newest of each kind (committed), then add elements of each kind
    step(mesh, lambda: mesh.remove_vertex(h["iso"]))
    step(mesh, lambda: mesh.remove_polygon(h["p2"]))
    step(mesh, lambda: mesh.remove_vertex(h["pillow"][2]))
    step(mesh, lambda: mesh.remove_edge(max(mesh.edges(), key=lambda e: e.id)))
    v = step(mesh, lambda: mesh.add_vertex())
    step(mesh, lambda: mesh.add_edge(v, h["v"][4]))
    step(mesh, lambda: mesh.add_polygon([v, h["v"][4], h["v"][3]]))
    # inside a block: delete and add again, several times
    with store.transaction():
        for _ in range(3):
            step(mesh, lambda: mesh.remove_vertex(max(mesh.vertices(), key=lambda x: x.id)))
            w = step(mesh, lambda: mesh.add_vertex())
            step(mesh, lambda: mesh.add_polygon([w, mesh.add_vertex(), mesh.add_vertex()]))
            step(mesh, lambda: mesh.remove_polygon(max(mesh.polygons(), key=lambda x: x.id)))
    # and from a fresh store on the same database
    with hestore.open(db_url) as fresh:
        m2 = fresh.mesh("m")
        step(m2, lambda: m2.remove_vertex(max(m2.vertices(), key=lambda x: x.id)))
        a = step(m2, lambda: m2.add_vertex())
        b = step(m2, lambda: m2.add_vertex())
        step(m2, lambda: m2.add_edge(a, b))
        step(m2, lambda: m2.add_polygon([a, b, m2.add_vertex()]))
        assert m2.check() == []


def test_ids_after_rollback(store, mesh):
    """After a rolled-back block, ids it handed out may be handed out again.

    Those elements never existed, so reusing their ids breaks no handle that
    was ever valid; ids of committed elements are still never reused.
    """
    committed = [mesh.add_vertex() for _ in range(3)]
    mesh.remove_vertex(committed[-1])
    with pytest.raises(Boom):
        with store.transaction():
            ghost = mesh.add_vertex()
            raise Boom
    v = mesh.add_vertex()
    assert v.id not in {c.id for c in committed}
    assert v.id >= ghost.id  # may be equal: the ghost never existed
    assert mesh.check() == []


def test_ids_in_a_block_are_never_reused_within_it(store, mesh):
    with store.transaction():
        ids = set()
        for _ in range(5):
            v = mesh.add_vertex()
            assert v.id not in ids
            ids.add(v.id)
            mesh.remove_vertex(v)
        a, b = mesh.add_vertex(), mesh.add_vertex()
        edges = set()
        for _ in range(5):
            e = mesh.add_edge(a, b)
            assert e.id not in edges
            edges.add(e.id)
            mesh.remove_edge(e)


# --------------------------------------------------------------------------
# Closing


def test_close_after_use_and_twice(db_url):
    store = hestore.open(db_url)
    m = store.create_mesh("m")
    v = m.add_vertex()
    store.close()
    store.close()  # idempotent
    for call in (lambda: m.add_vertex(), lambda: m.counts(), lambda: v.degree, lambda: store.meshes(),
                 lambda: store.create_mesh("x")):
        with pytest.raises(HestoreError):
            call()
    with hestore.open(db_url) as again:
        assert again.mesh("m").counts().vertices == 1


def test_close_inside_block_rolls_back(db_url):
    store = hestore.open(db_url)
    m = store.create_mesh("m")
    m.add_vertex()
    before = dump(db_url)
    # Leaving the block after the store was closed cannot commit: it must say so
    # with a hestore error, and nothing of the block may be stored.
    with pytest.raises(HestoreError):
        with store.transaction():
            m.add_vertex()
            store.close()
    assert dump(db_url) == before
    with pytest.raises(HestoreError):
        m.add_vertex()


def test_transaction_on_a_closed_store_raises_hestore_error(db_url):
    store = hestore.open(db_url)
    store.close()
    with pytest.raises(HestoreError):
        with store.transaction():
            pass
    assert not store.in_transaction


def test_close_inside_nested_block_rolls_back_everything(db_url):
    store = hestore.open(db_url)
    m = store.create_mesh("m")
    before = dump(db_url)
    with pytest.raises(HestoreError):
        with store.transaction():
            m.add_vertex()
            with store.transaction():
                m.add_vertex()
                store.close()
    assert dump(db_url) == before
    assert not store.in_transaction


def test_close_inside_block_data_is_rolled_back(db_url):
    """Whatever the block exit raises, close() inside a block stores nothing of it."""
    store = hestore.open(db_url)
    m = store.create_mesh("m")
    before = dump(db_url)
    try:
        with store.transaction():
            m.add_polygon([m.add_vertex() for _ in range(3)])
            store.close()
    except Exception:
        pass
    assert dump(db_url) == before


def test_store_context_manager_rolls_back_open_block(db_url):
    with hestore.open(db_url) as store:
        store.create_mesh("m")
    before = dump(db_url)
    with pytest.raises(Boom):
        with hestore.open(db_url) as store:
            with store.transaction():
                store.mesh("m").add_vertex()
                raise Boom
    assert dump(db_url) == before


def test_a_new_block_after_failures_works(store, mesh):
    """A failed block, a failed call and a failed savepoint leave no state behind."""
    a, b = mesh.add_vertex(), mesh.add_vertex()
    for _ in range(3):
        with pytest.raises(Boom):
            with store.transaction():
                mesh.add_edge(a, b)
                raise Boom
    with store.transaction():
        e = mesh.add_edge(a, b)
    assert e.vertices() == (a, b)
    assert mesh.counts().edges == 1
    assert mesh.check() == []
