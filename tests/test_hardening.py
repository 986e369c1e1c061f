"""SPEC §10: everything a user can throw at a store gets a typed error and changes nothing.

Threads, stale mesh handles, bad arrays, bad names and ids, bad URLs and
paths, databases that are not hestore's or cannot be written, handles from
elsewhere. Every storage test runs on SQLite and PostgreSQL; "changes
nothing" is a full dump of every hestore table before and after
(`helpers.dump`), and "typed" means a `HestoreError` subclass with no driver
exception escaping (a database-level problem is a `StoreError` whose
``__cause__`` is the driver's exception).
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time

import numpy as np
import pytest
import sqlalchemy as sa

import hestore
from hestore import urls
from hestore.errors import (
    ElementNotFoundError,
    HestoreError,
    InvalidInputError,
    MeshNotFoundError,
    StoreBusyError,
    StoreError,
    TopologyError,
    WrongThreadError,
)

from helpers import dump


def in_thread(fn):
    """Run ``fn()`` in another thread; return what it raised (or None) and how long it took."""
    out = {}

    def run():
        t0 = time.monotonic()
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - reported to the test
            out["exc"] = exc
        out["seconds"] = time.monotonic() - t0

    thread = threading.Thread(target=run)
    thread.start()
    thread.join(30)
    assert not thread.is_alive(), "the call from another thread hung"
    return out.get("exc"), out["seconds"]


def triangle(mesh):
    a, b, c = (mesh.add_vertex((float(i), float(i % 2), 0.0)) for i in range(3))
    return (a, b, c), mesh.add_polygon([a, b, c])


# --------------------------------------------------------------------------
# Threads


def test_a_store_refuses_every_call_from_another_thread(store):
    mesh = store.create_mesh("m")
    (a, b, c), p = triangle(mesh)
    before = dump(store)
    calls = {
        "mesh": lambda: store.mesh("m"),
        "meshes": store.meshes,
        "create_mesh": lambda: store.create_mesh("other"),
        "delete_mesh": lambda: store.delete_mesh("m"),
        "transaction": lambda: store.transaction().__enter__(),
        "import_arrays": lambda: store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]),
        "add_vertex": mesh.add_vertex,
        "add_polygon": lambda: mesh.add_polygon([a, c, b]),
        "can_add_polygon": lambda: mesh.can_add_polygon([a, c, b]),
        "remove_polygon": lambda: mesh.remove_polygon(p),
        "revision": lambda: mesh.revision,
        "counts": mesh.counts,
        "vertex": lambda: mesh.vertex(0),
        "neighbors": a.neighbors,
        "halfedge.next": lambda: p.halfedge.next,
        "stats": mesh.stats,
        "check": mesh.check,
        "to_arrays": mesh.to_arrays,
        "to_networkx": mesh.to_networkx,
        "close": store.close,
    }
    for name, call in calls.items():
        exc, seconds = in_thread(call)
        assert isinstance(exc, WrongThreadError), f"{name}: {exc!r}"
        assert "thread" in str(exc) and seconds < 1, name
    # The owner goes on as if nothing happened, and nothing did.
    assert dump(store) == before
    assert mesh.add_vertex().id == 3
    assert mesh.check() == []


def test_another_thread_is_refused_while_the_owner_holds_a_block(store, db_url):
    mesh = store.create_mesh("m")
    committed = dump(db_url)
    with store.transaction():
        (a, b, c), _ = triangle(mesh)
        exc, _ = in_thread(lambda: mesh.add_polygon([a, c, b]))
        assert isinstance(exc, WrongThreadError)
        exc, _ = in_thread(lambda: store.transaction().__enter__())
        assert isinstance(exc, WrongThreadError)
        assert dump(db_url) == committed  # nothing was committed behind the block's back
    assert mesh.counts().polygons == 1 and mesh.revision == 1
    assert mesh.check() == []


def test_an_in_memory_store_refuses_other_threads_too():
    with hestore.open("sqlite://") as store:
        mesh = store.create_mesh("m")
        exc, _ = in_thread(mesh.add_vertex)
        assert isinstance(exc, WrongThreadError)
        assert mesh.counts().vertices == 0


def test_one_store_per_thread_works(db_url):
    with hestore.open(db_url) as setup:
        setup.create_mesh("a")
        setup.create_mesh("b")
    errors = []

    def work(name):
        try:
            with hestore.open(db_url) as own:
                mesh = own.mesh(name)
                for _ in range(5):
                    triangle(mesh)
                assert mesh.check() == []
        except BaseException as exc:  # noqa: BLE001 - reported to the test
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(n,)) for n in "ab"]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert errors == []
    with hestore.open(db_url) as check:
        assert [check.mesh(n).counts().polygons for n in "ab"] == [5, 5]


# --------------------------------------------------------------------------
# Stale mesh handles


def test_a_mesh_created_in_a_rolled_back_block_never_aliases_the_next(store, db_url):
    with pytest.raises(RuntimeError):
        with store.transaction():
            stale = store.create_mesh("gone")
            v = stale.add_vertex((1.0, 2.0, 3.0))
            raise RuntimeError("roll back")
    fresh = store.create_mesh("fresh")  # SQLite hands out the rolled-back id again
    w = fresh.add_vertex((7.0, 7.0, 7.0))
    before = dump(db_url)
    for call in (
        stale.add_vertex,
        lambda: stale.revision,
        stale.counts,
        stale.check,
        stale.stats,
        lambda: stale.vertex(0),
        lambda: v.position,
        lambda: v.neighbors(),
        lambda: stale.add_edge(v, v),
        lambda: stale.can_add_edge(v, v),
        stale.to_arrays,
    ):
        with pytest.raises(MeshNotFoundError, match="rolled back"):
            call()
    assert stale != fresh and v != w
    assert dump(db_url) == before
    assert fresh.counts().vertices == 1 and w.position == (7.0, 7.0, 7.0)


def test_a_mesh_created_in_a_rolled_back_savepoint_dies_with_it(store):
    with store.transaction():
        keep = store.create_mesh("keep")
        try:
            with store.transaction():
                gone = store.create_mesh("gone")
                gone.add_vertex()
                raise RuntimeError
        except RuntimeError:
            pass
        with pytest.raises(MeshNotFoundError):
            gone.add_vertex()
        again = store.create_mesh("again")
        again.add_vertex()
        keep.add_vertex()
    assert store.meshes() == ["again", "keep"]
    with pytest.raises(MeshNotFoundError):
        gone.counts()
    assert store.mesh("keep") == keep and store.mesh("again") == again


def test_a_stale_handle_never_reaches_a_mesh_another_store_created(db_url):
    with hestore.open(db_url) as a, hestore.open(db_url) as b:
        with pytest.raises(RuntimeError):
            with a.transaction():
                stale = a.create_mesh("x")
                raise RuntimeError
        other = b.create_mesh("y")
        other.add_vertex()
        before = dump(db_url)
        with pytest.raises(MeshNotFoundError):
            stale.add_vertex()
        with pytest.raises(MeshNotFoundError):
            stale.counts()
        assert dump(db_url) == before


def test_a_deleted_mesh_raises_mesh_not_found_everywhere(store):
    mesh = store.create_mesh("m")
    (a, _, _), p = triangle(mesh)
    store.delete_mesh("m")
    for call in (mesh.check, mesh.validate, mesh.stats, mesh.counts, mesh.to_arrays, mesh.components,
                 mesh.boundary_loops, lambda: mesh.revision, lambda: mesh.vertex(0), lambda: a.neighbors(),
                 lambda: p.vertices(), mesh.add_vertex, lambda: list(mesh.vertices()), mesh.to_networkx):
        with pytest.raises(MeshNotFoundError):
            call()


# --------------------------------------------------------------------------
# Arrays


@pytest.mark.parametrize(
    "positions, polygons, fragment",
    [
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [0, 1, 2], "polygon 0 is 0", id="flat-list"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], np.array([0, 1, 2]), "1-d array", id="1-d-array"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], {0: [0, 1, 2]}, "not dict", id="dict-polygons"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, [1], 2]], "not a flat sequence", id="nested"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], "012", "not str", id="string-polygons"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1.5, 2]], "integers", id="fractional-index"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[True, False, True]], "booleans", id="bool-index"),
        pytest.param([(0, 0, 0), (1, 0, 0), (0, 1, 1j)], [[0, 1, 2]], "real numbers", id="complex"),
        pytest.param(np.array([(0, 0, 0), (1, 0, 0), (0, 1, 1j)]), [[0, 1, 2]], "real numbers", id="complex-array"),
        pytest.param([("0", "0", "0")] * 3, [[0, 1, 2]], "real numbers", id="text-positions"),
        pytest.param([(True, False, True)] * 3, [[0, 1, 2]], "real numbers", id="bool-positions"),
        pytest.param({0: (0, 0, 0)}, [[0]], "not dict", id="dict-positions"),
        pytest.param([(0, 0), (1, 0, 0)], [[0, 1]], "real numbers", id="ragged-positions"),
        pytest.param([(0, 0, 0), (1, 0, np.nan), (0, 1, 0)], [[0, 1, 2]], "finite", id="nan"),
        pytest.param([(0, 0, 0, 0)], [[0]], "shape", id="four-columns"),
    ],
)
def test_bad_arrays_are_invalid_input_and_store_nothing(store, positions, polygons, fragment):
    before = dump(store)
    with pytest.raises(InvalidInputError, match=fragment):
        store.import_arrays("bad", positions, polygons)
    assert dump(store) == before and store.meshes() == []


def test_good_arrays_of_every_numeric_kind_are_taken(store):
    pos = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0)], dtype=np.int32)
    report = store.import_arrays("ints", pos, np.array([[0, 1, 2]], dtype=np.uint16))
    assert report.mesh.to_arrays().positions.dtype == np.float64 and report.polygons == 1
    report = store.import_arrays("ragged", [(0, 0), (1, 0), (0, 1), (1, 1)], [(0, 1, 3), [0, 3, 2, 1][:3]])
    assert report.polygons == 2


# --------------------------------------------------------------------------
# Names and ids


@pytest.mark.parametrize(
    "name",
    ["", "   ", "a\x00b", "bad\ud800", "line\nbreak", "tab\t", "x" * 256, 123, None, b"bytes", ("t",)],
    ids=["empty", "blank", "nul", "surrogate", "newline", "tab", "too-long", "int", "none", "bytes", "tuple"],
)
def test_bad_mesh_names_are_invalid_input_everywhere(store, name):
    before = dump(store)
    for call in (
        lambda: store.create_mesh(name),
        lambda: store.mesh(name),
        lambda: store.delete_mesh(name),
        lambda: store.import_arrays(name, [(0, 0, 0)], []),
    ):
        with pytest.raises(InvalidInputError):
            call()
    assert dump(store) == before


def test_unicode_names_that_are_valid_work(store):
    for name in ("éèà", "日本語", "emoji 🙂", "x" * 255):
        store.create_mesh(name)
        assert store.mesh(name).name == name
    assert len(store.meshes()) == 4


@pytest.mark.parametrize(
    "bad, error",
    [
        (2**70, ElementNotFoundError),
        (-(2**70), ElementNotFoundError),
        (-1, ElementNotFoundError),
        (2**63 - 1, ElementNotFoundError),
        ("1", InvalidInputError),
        (1.0, InvalidInputError),
        (True, InvalidInputError),
        (None, InvalidInputError),
    ],
)
def test_bad_ids_are_typed(store, bad, error):
    mesh = store.create_mesh("m")
    triangle(mesh)
    for lookup in (mesh.vertex, mesh.halfedge, mesh.edge, mesh.polygon):
        with pytest.raises(error):
            lookup(bad)
    with pytest.raises(error):
        hestore.Vertex(mesh, bad).neighbors()


def test_numpy_integer_ids_are_ids(store):
    mesh = store.create_mesh("m")
    (a, _, _), p = triangle(mesh)
    assert mesh.vertex(np.int64(0)) == a and mesh.polygon(np.uint8(0)) == p
    assert hestore.Vertex(mesh, np.int32(0)) == a


def test_handles_and_meshes_of_another_store_are_refused(db_url):
    with hestore.open(db_url) as one, hestore.open(db_url) as two:
        mine = one.create_mesh("m")
        (a, b, c), _ = triangle(mine)
        theirs = two.mesh("m")
        before = dump(db_url)
        with pytest.raises(ElementNotFoundError, match="belongs to mesh"):
            theirs.add_polygon([a, c, b])
        with pytest.raises(ElementNotFoundError):
            theirs.remove_vertex(a)
        assert dump(db_url) == before


def test_topology_errors_carry_handles_on_every_path(store):
    mesh = store.create_mesh("m", allow_loops=False)
    (a, b, c), p = triangle(mesh)
    h = mesh.find_halfedge(a, b)
    refusals = [
        lambda: mesh.add_polygon([a, b, c]),
        lambda: mesh.add_polygon([h]),
        lambda: mesh.add_edge(a, a),
    ]
    for refuse in refusals:
        with pytest.raises(TopologyError) as info:
            refuse()
        assert info.value.elements and all(isinstance(e, hestore.handles.Handle) for e in info.value.elements)
        assert [(type(e).__name__.lower(), e.id) for e in info.value.elements] == list(info.value.refs)
        assert all(e.mesh == mesh for e in info.value.elements)


# --------------------------------------------------------------------------
# URLs and paths


def test_a_bare_path_is_exactly_that_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("what?is=this.db", "hash#tag.db", "both?a#b.db", "spaces and % signs.db"):
        with hestore.open(name) as store:
            store.create_mesh("m")
        assert (tmp_path / name).is_file(), name
        with hestore.open(str(tmp_path / name)) as store:
            assert store.meshes() == ["m"]
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix == ".db") == sorted(
        ["what?is=this.db", "hash#tag.db", "both?a#b.db", "spaces and % signs.db"]
    )


@pytest.mark.parametrize(
    "url, fragment",
    [
        ("postgres://me@localhost/db", "postgresql+psycopg://"),
        ("mysql://me@localhost/db", "unsupported database 'mysql'"),
        ("mysql+pymysql://me@localhost/db", "unsupported database 'mysql'"),
        ("oracle://me@localhost/db", "unsupported database 'oracle'"),
        ("postgresql+psycopg2://me@localhost/db", "unsupported driver 'psycopg2'"),
        ("sqlite+aiosqlite:///x.db", "unsupported driver 'aiosqlite'"),
        ("://nothing", "not a database URL"),
        ("", "no database given"),
        ("a\x00b.db", "NUL"),
    ],
)
def test_bad_urls_are_one_clear_invalid_input(url, fragment):
    with pytest.raises(InvalidInputError, match=fragment.replace("+", r"\+").replace("(", r"\(")):
        hestore.open(url)


def test_postgresql_without_a_driver_means_psycopg():
    assert urls.resolve("postgresql://me@host/db").drivername == "postgresql+psycopg"
    assert urls.resolve("sqlite:///x.db").drivername == "sqlite"


def test_passwords_never_show(monkeypatch):
    with pytest.raises(InvalidInputError) as info:
        hestore.open("mysql://me:s3cret@host/db")
    assert "s3cret" not in str(info.value)


# --------------------------------------------------------------------------
# Databases that are not hestore's, or cannot be written


def test_a_file_that_is_not_a_database(tmp_path):
    path = tmp_path / "notes.db"
    path.write_bytes(b"these are my notes, not a database\n" * 200)
    content = path.read_bytes()
    with pytest.raises(StoreError, match="not a SQLite database") as info:
        hestore.open(str(path))
    assert isinstance(info.value.__cause__, (sqlite3.Error, sa.exc.SQLAlchemyError))
    assert path.read_bytes() == content


def test_a_folder_is_not_a_database(tmp_path):
    with pytest.raises(StoreError):
        hestore.open(str(tmp_path))


def test_another_applications_tables_are_left_alone(db_url):
    engine = sa.create_engine(db_url)
    with engine.begin() as conn:
        conn.execute(sa.text("CREATE TABLE vertices (name TEXT)"))
        conn.execute(sa.text("INSERT INTO vertices VALUES ('mine')"))
    with pytest.raises(StoreError, match="did not create \\(vertices\\)"):
        hestore.open(db_url)
    with engine.connect() as conn:
        assert conn.execute(sa.text("SELECT name FROM vertices")).scalars().all() == ["mine"]
        assert not sa.inspect(conn).has_table("meshes")
    engine.dispose()


def _read_only_url(db_url: str, backend: str) -> str:
    if backend == "sqlite":
        return f"sqlite:///file:{db_url.removeprefix('sqlite:///')}?mode=ro&uri=true"
    return db_url + "%20-cdefault_transaction_read_only%3Don"


def test_a_read_only_database_reads_and_refuses_writes(db_url, backend):
    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        triangle(mesh)
    before = dump(db_url)
    with hestore.open(_read_only_url(db_url, backend)) as store:
        mesh = store.mesh("m")
        assert mesh.counts().polygons == 1 and mesh.check() == []
        assert mesh.can_add_edge(mesh.vertex(0), mesh.vertex(1))  # a question needs no write
        for write in (
            mesh.add_vertex,
            lambda: store.create_mesh("n"),
            lambda: store.delete_mesh("m"),
            lambda: store.import_arrays("t", [(0, 0, 0)], []),
        ):
            with pytest.raises(StoreError, match="read-only") as info:
                write()
            assert info.value.__cause__ is not None
        with pytest.raises(StoreError, match="read-only"):
            with store.transaction():
                mesh.add_vertex()
        assert mesh.counts().vertices == 3
    assert dump(db_url) == before


@pytest.mark.parametrize("backend", [pytest.param("postgresql", marks=pytest.mark.postgresql)])
def test_a_lost_connection_is_a_store_error(db_url, backend):
    # PostgreSQL only: a SQLite file has no connection to lose.
    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        triangle(mesh)
        with store.session.reading() as conn:
            pid = conn.execute(sa.text("SELECT pg_backend_pid()")).scalar()
        admin = sa.create_engine(db_url, isolation_level="AUTOCOMMIT")
        with admin.connect() as conn:
            conn.execute(sa.text("SELECT pg_terminate_backend(:p)"), {"p": pid})
        admin.dispose()
        with pytest.raises(StoreError) as info:
            mesh.add_vertex()
        assert not isinstance(info.value, StoreBusyError)
        assert info.value.__cause__ is not None
    with hestore.open(db_url) as store:
        assert store.mesh("m").counts().vertices == 3


# --------------------------------------------------------------------------
# Questions never wait for writers


def test_can_add_never_waits_for_or_blocks_a_writer(db_url):
    with hestore.open(db_url, busy_timeout=3) as asker, hestore.open(db_url, busy_timeout=3) as writer:
        mesh = asker.create_mesh("m")
        (a, b, c), _ = triangle(mesh)
        theirs = writer.mesh("m")
        with writer.transaction():
            x = theirs.add_vertex()  # the writer now holds the lock (SQLite: the database's, PG: the mesh's)
            t0 = time.monotonic()
            assert mesh.can_add_polygon([a, c, b]) is True
            assert mesh.can_add_polygon([a, b, c]) is False
            assert mesh.can_add_edge(a, b) is True
            assert time.monotonic() - t0 < 1.0
            theirs.add_polygon([theirs.vertex(0), x, theirs.vertex(1)])  # the writer goes on
        assert mesh.counts().polygons == 2


def test_can_add_inside_a_block_sees_the_block_and_leaves_it_usable(store):
    mesh = store.create_mesh("m")
    with store.transaction():
        (a, b, c), _ = triangle(mesh)
        before = dump(store)
        assert not mesh.can_add_polygon([a, b, c]) and mesh.can_add_polygon([c, b, a])
        assert dump(store) == before
        mesh.add_polygon([c, b, a])
    assert mesh.stats().is_closed


def test_every_error_is_a_hestore_error(store):
    # A sample of misuses from all over the API: none may escape as a bare Python or driver error.
    mesh = store.create_mesh("m")
    (a, b, c), p = triangle(mesh)
    misuses = [
        lambda: mesh.add_vertex("xyz"),
        lambda: mesh.add_vertex((1, 2)),
        lambda: mesh.add_vertex((1, 2, "3")),
        lambda: mesh.add_vertex((1, 2, float("inf"))),
        lambda: mesh.add_vertex({1: 2, 3: 4, 5: 6}),
        lambda: mesh.add_edge(a, "b"),
        lambda: mesh.add_polygon(a),
        lambda: mesh.add_polygon([]),
        lambda: mesh.add_polygon([a, p]),
        lambda: mesh.remove_polygon(a),
        lambda: mesh.to_networkx("tree"),
        lambda: store.import_file(os.devnull + ".xyz"),
        lambda: store.import_arrays("m", [(0, 0, 0)], [], on_error="ignore"),
        lambda: hestore.open("sqlite://", busy_timeout=-1),
        lambda: hestore.open("sqlite://", busy_timeout=float("nan")),
        lambda: hestore.open(42),
    ]
    before = dump(store)
    for misuse in misuses:
        with pytest.raises(HestoreError):
            misuse()
    assert dump(store) == before
