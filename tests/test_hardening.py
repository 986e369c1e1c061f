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

import math
import os
import re
import sqlite3
import threading
import time
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest
import sqlalchemy as sa

import hestore
from hestore import graphio, urls
from hestore import io as mesh_io
from hestore.errors import (
    ElementNotFoundError,
    HestoreError,
    InvalidInputError,
    MeshNotFoundError,
    PropertyNotFoundError,
    RevisionNotFoundError,
    StoreBusyError,
    StoreError,
    TopologyError,
    WrongThreadError,
    shown,
)

from helpers import dump


def in_thread(fn):
    """Run ``fn()`` in another thread; return what it raised (or None) and the processor time it took.

    Processor time of that thread: what it did, which other processes on a busy machine do not add to.
    """
    out = {}

    def run():
        t0 = time.thread_time()
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - reported to the test
            out["exc"] = exc
        out["seconds"] = time.thread_time() - t0

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


#: The asker's busy_timeout below: a question that waited for the writer's lock would wait this long.
ASKER_WAITS = 60.0


def test_can_add_never_waits_for_or_blocks_a_writer(db_url):
    with hestore.open(db_url, busy_timeout=ASKER_WAITS) as asker, hestore.open(db_url, busy_timeout=3) as writer:
        mesh = asker.create_mesh("m")
        (a, b, c), _ = triangle(mesh)
        theirs = writer.mesh("m")
        with writer.transaction():
            x = theirs.add_vertex()  # the writer now holds the lock (SQLite: the database's, PG: the mesh's)
            t0 = time.monotonic()
            assert mesh.can_add_polygon([a, c, b]) is True
            assert mesh.can_add_polygon([a, b, c]) is False
            assert mesh.can_add_edge(a, b) is True
            # Waiting for the lock would have lasted the whole busy_timeout: the writer holds it until
            # the questions are done.
            assert time.monotonic() - t0 < ASKER_WAITS
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


# --------------------------------------------------------------------------
# Every kind of value, at every entry point that converts one
#
# One test per kind of conversion (numbers, integers, flags, options, texts
# and names, sequences, dtypes, paths, progress callbacks): every public entry
# point that takes such a value is handed every hostile value of the kind, and
# must refuse each with a typed error — never Python's own (an OverflowError
# of float(10**400), a ValueError of a NUL in a path), never the driver's (a
# StoreError for an argument) — and store nothing.


class Hostile:
    """A caller's object whose every conversion raises, its repr included."""

    def __float__(self):
        raise RuntimeError("no float")

    def __int__(self):
        raise RuntimeError("no int")

    def __index__(self):
        raise RuntimeError("no index")

    def __eq__(self, other):
        raise RuntimeError("no eq")

    def __hash__(self):
        return 0

    def __len__(self):
        raise RuntimeError("no len")

    def __iter__(self):
        raise RuntimeError("no iter")

    def __fspath__(self):
        raise RuntimeError("no fspath")

    def __repr__(self):
        raise RuntimeError("no repr")


#: Values that are no real number (None is left out: for a property value it means "unset").
NOT_REALS = ["1", b"1", True, np.bool_(False), complex(1, 1), Decimal("1.5"), [1.0], object(), Hostile()]
#: Real numbers a float64 cannot hold.
BEYOND_FLOATS = [10**400, -(10**400), Fraction(10**400), 10**5000]
NOT_FINITE = [math.nan, math.inf, -math.inf, np.float64("nan")]
NOT_INTEGERS = [1.0, np.float32(2), Fraction(1, 1), "1", b"1", None, True, np.bool_(True), complex(1, 0),
                Decimal(1), [1], Hostile()]
BEYOND_64_BITS = [2**63, -(2**63) - 1, 2**64, np.uint64(2**64 - 1), 10**400, -(10**400), 10**5000]
NOT_FLAGS = [1, 0, 1.0, "True", "", None, [True], np.array(True), Hostile()]
NOT_CHOICES = [None, 1, b"vertex", ["vertex"], ("vertex",), "VERTEX", "vertex\x00", "\ud800", "x" * 100_000,
               10**5000, Hostile()]
NOT_TEXTS = [1, b"text", ["text"], "a\x00b", "\ud800", 10**5000, Hostile()]
NOT_NAMES = [None, *NOT_TEXTS, "", "   ", "tab\tname", "x" * 256]
NOT_PATHS = [None, 42, 1.5, ["a.off"], "a\x00b.off", b"a\x00b.off", "a\ud800.off", 10**5000, Hostile()]
NOT_CALLABLES = [1, "progress", b"progress", [print], 10**5000, Hostile()]
NOT_POSITIONS = ["xyz", b"xyz", {0: 1, 1: 2, 2: 3}, {1.0, 2.0, 3.0}, 5.0, np.array(1.0), (1, 2), (1, 2, 3, 4),
                 Hostile(), *((0.0, x, 0.0) for x in [None, *NOT_REALS, *BEYOND_FLOATS, *NOT_FINITE])]


def refused(label: str, call, value, error: type[BaseException] | tuple = InvalidInputError) -> BaseException:
    """``call(value)`` raises ``error``, a hestore error that is no StoreError; return it."""
    try:
        call(value)
    except error as exc:
        assert isinstance(exc, HestoreError) and not isinstance(exc, StoreError), f"{label}: {exc!r}"
        str(exc)  # the message itself can be made
        return exc
    except Exception as exc:  # noqa: BLE001 - reported: the point of the test
        pytest.fail(f"{label} with {shown(value)} raised {type(exc).__module__}.{type(exc).__name__}: {exc}")
    pytest.fail(f"{label} accepted {shown(value)}")


def refuses_all(store, calls: dict, values: list, error: type[BaseException] | tuple = InvalidInputError) -> None:
    """Every call refuses every value with ``error``, and the database is as it was."""
    before = dump(store)
    for label, call in calls.items():
        for value in values:
            refused(label, call, value, error)
    assert dump(store) == before


@pytest.fixture
def files(tmp_path):
    """A folder for the files a test writes (SQLite's database is in ``tmp_path`` itself)."""
    folder = tmp_path / "files"
    folder.mkdir()
    return folder


@pytest.fixture
def triangle_mesh(store):
    """A triangle with a float64, an int64, a bool, a str and a float64 (3,) vertex property."""
    mesh = store.create_mesh("m")
    corners, p = triangle(mesh)
    for name, dtype, shape in [("f", "float64", ()), ("i", "int64", ()), ("b", "bool", ()), ("s", "str", ()),
                               ("f3", "float64", (3,))]:
        mesh.add_property("vertex", name, dtype, shape=shape)
    return mesh, corners, p


@pytest.mark.parametrize("big", [10**400, Fraction(10**400)], ids=["int", "fraction"])
def test_a_number_too_large_for_a_float_is_invalid_input(store, triangle_mesh, big):
    # Was OverflowError ("int too large to convert to float") from float() in the value and position checks.
    mesh, (a, b, _c), p = triangle_mesh
    e = mesh.find_halfedge(a, b).edge
    calls = {
        "v['f'] = x": lambda x: a.__setitem__("f", x),
        "set_property_array": lambda x: mesh.set_property_array("vertex", "f", [a], np.array([x], dtype=object)),
        "add_property(default=x)": lambda x: mesh.add_property("vertex", "d", "float64", default=x),
        "add_vertex": lambda x: mesh.add_vertex((x, 0, 0)),
        "set_position": lambda x: mesh.set_position(a, (0, x, 0)),
        "set_positions": lambda x: mesh.set_positions([a], np.array([(0, 0, x)], dtype=object)),
        "split_edge(position=x)": lambda x: mesh.split_edge(e, position=(x, 0, 0)),
        "poke_polygon(position=x)": lambda x: mesh.poke_polygon(p, position=(x, 0, 0)),
    }
    refuses_all(store, calls, [big])


def test_a_nul_in_a_path_is_invalid_input_naming_the_path(store, triangle_mesh, files):
    # Was ValueError ("embedded null byte") from the OS call.
    mesh, _corners, _p = triangle_mesh
    graph = mesh.to_networkx()
    calls = {
        ".ply": mesh.export,
        ".stl": mesh.export,
        ".off": store.import_file,
        ".png": mesh.render,
        ".graphml": lambda x: graphio.write_graph(graph, x),
    }
    before = dump(store)
    for suffix, call in calls.items():
        for path in (f"a\x00b{suffix}", f"a\x00b{suffix}".encode(), files / f"a\x00b{suffix}"):
            assert "a\\x00b" in str(refused(f"{suffix} to {path!r}", call, path))
    assert dump(store) == before and os.listdir(files) == []


def test_numbers_beyond_float64_and_non_numbers_are_refused_as_values(store, triangle_mesh):
    mesh, (a, b, _c), _p = triangle_mesh
    calls = {
        "v['f'] = x": lambda x: a.__setitem__("f", x),
        "v['f3'] = (x, 0, 0)": lambda x: a.__setitem__("f3", (x, 0, 0)),
        "set_property_array(..., [x])": lambda x: mesh.set_property_array("vertex", "f", [a], [x]),
        "add_property(default=x)": lambda x: mesh.add_property("vertex", "d", "float64", default=x),
        "add_property(shape=(2,), default=(x, 0))": lambda x: mesh.add_property(
            "vertex", "d", "float64", shape=(2,), default=(x, 0)
        ),
        "v['i'] = x": lambda x: a.__setitem__("i", x),
    }
    refuses_all(store, calls, NOT_REALS + BEYOND_FLOATS)
    refuses_all(store, {"v['i'] = x": lambda x: a.__setitem__("i", x)}, [1.5, math.nan, math.inf, 2**63, 2**64])


def test_coordinates_are_finite_real_numbers_everywhere(store, triangle_mesh):
    mesh, (a, b, _c), p = triangle_mesh
    e = mesh.find_halfedge(a, b).edge
    calls = {
        "add_vertex": lambda x: mesh.add_vertex((0, 0, x)),
        "set_position": lambda x: mesh.set_position(a, (x, 0, 0)),
        "split_edge(position=)": lambda x: mesh.split_edge(e, position=(0, 0, x)),
        "poke_polygon(position=)": lambda x: mesh.poke_polygon(p, position=(x, 0, 0)),
        "plot(view=(x, 0))": lambda x: mesh.plot(view=(x, 0)),
        "open(busy_timeout=x)": lambda x: hestore.open("sqlite://", busy_timeout=x),
    }
    refuses_all(store, calls, [None, *NOT_REALS, *BEYOND_FLOATS, *NOT_FINITE])
    # Arrays are numpy's to convert: a bool or a Decimal among numbers is a number there (an array of bools is not).
    arrays = {
        "set_positions": lambda x: mesh.set_positions([a], [(0, x, 0)]),
        "import_arrays": lambda x: store.import_arrays("t", [(0, 0, 0), (1, 0, x), (0, 1, 0)], [[0, 1, 2]]),
    }
    refuses_all(store, arrays, [None, "1", b"1", complex(1, 1), [1.0], Hostile(), *BEYOND_FLOATS, *NOT_FINITE])


def test_real_numbers_of_every_kind_are_taken_exactly(store, triangle_mesh):
    mesh, (a, b, _c), _p = triangle_mesh
    a["f"], b["f"] = Fraction(1, 4), np.float32(0.5)
    a["i"], b["i"] = Fraction(2**53 + 1), np.uint64(7)  # exact: not through a float
    assert (a["f"], b["f"], a["i"], b["i"]) == (0.25, 0.5, 2**53 + 1, 7)
    assert mesh.add_vertex((Fraction(1, 2), np.int8(-3), np.float16(2))).position == (0.5, -3.0, 2.0)
    with hestore.open(store.url, busy_timeout=10**9) as patient:  # PostgreSQL waits its longest: 24.8 days
        assert patient.meshes() == ["m"]


def test_integers_ids_and_revisions_are_typed(store, triangle_mesh):
    mesh, (a, b, _c), _p = triangle_mesh
    lookups = {
        "vertex(x)": mesh.vertex,
        "halfedge(x)": mesh.halfedge,
        "edge(x)": mesh.edge,
        "polygon(x)": mesh.polygon,
        "Vertex(mesh, x).position": lambda x: hestore.Vertex(mesh, x).position,
        "set_position(x, ...)": lambda x: mesh.set_position(x, (0, 0, 0)),
    }
    refuses_all(store, lookups, NOT_INTEGERS)
    refuses_all(store, lookups, BEYOND_64_BITS, ElementNotFoundError)
    arrays = {
        "set_positions([x], ...)": lambda x: mesh.set_positions([x], [(0, 0, 0)]),
        "set_property_array(..., [x], ...)": lambda x: mesh.set_property_array("vertex", "f", [x], [1.0]),
    }
    refuses_all(store, arrays, NOT_INTEGERS + BEYOND_64_BITS, (InvalidInputError, ElementNotFoundError))
    revisions = {
        "at(x)": mesh.at,
        "diff(x, 1)": lambda x: mesh.diff(x, 1),
        "diff(1, x)": lambda x: mesh.diff(1, x),
        "revert(x)": mesh.revert,
    }
    refuses_all(store, revisions, NOT_INTEGERS)
    copy = {"copy_mesh(revision=x)": lambda x: store.copy_mesh("m", "copy", revision=x)}  # None: the current one
    refuses_all(store, copy, [x for x in NOT_INTEGERS if x is not None])
    refuses_all(store, {**revisions, **copy}, BEYOND_64_BITS, RevisionNotFoundError)
    counts = {
        "k_ring(v, x)": lambda x: mesh.k_ring(a, x),
        "prune_history(keep=x)": mesh.prune_history,
        "plot(max_polygons=x)": lambda x: mesh.plot(max_polygons=x),
        "add_property(shape=(x,))": lambda x: mesh.add_property("vertex", "d", "float64", shape=(x,)),
    }
    negative = [-1, -(10**400), -(10**5000)]
    refuses_all(store, counts, [*NOT_INTEGERS, *negative])
    limit = [x for x in NOT_INTEGERS if x is not None] + negative + BEYOND_64_BITS[:1]  # None: every revision
    refuses_all(store, {"history(limit=x)": mesh.history}, limit)
    # A count beyond anything there is asks for everything there is.
    assert mesh.k_ring(a, 10**400) == set(mesh.vertices())
    assert [r.number for r in mesh.history(np.int64(1))] == [mesh.revision]


def test_flags_are_true_or_false(store, triangle_mesh, files):
    mesh, (a, b, _c), _p = triangle_mesh
    e = mesh.find_halfedge(a, b).edge
    soup = [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]
    (files / "t.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    calls = {
        "split_edge(triangulate=x)": lambda x: mesh.split_edge(e, triangulate=x),
        "can_split_edge(triangulate=x)": lambda x: mesh.can_split_edge(e, triangulate=x),
        "export(binary=x)": lambda x: mesh.export(files / "m.ply", binary=x),
        "render(title=x)": lambda x: mesh.render(files / "m.png", title=x),
        "plot(labels=x)": lambda x: mesh.plot(labels=x),
    }
    for flag in ("allow_loops", "allow_multi_edges", "history"):
        calls[f"create_mesh({flag}=x)"] = lambda x, flag=flag: store.create_mesh("new", **{flag: x})
        calls[f"import_arrays({flag}=x)"] = lambda x, flag=flag: store.import_arrays("new", *soup, **{flag: x})
    for flag in ("replace", "orient"):
        calls[f"import_file({flag}=x)"] = lambda x, flag=flag: store.import_file(files / "t.off", **{flag: x})
    refuses_all(store, calls, NOT_FLAGS)
    # None means something here: unset the value, check when the mesh is small.
    optional = {"v['b'] = x": lambda x: a.__setitem__("b", x), "plot(check=x)": lambda x: mesh.plot(check=x)}
    refuses_all(store, optional, [x for x in NOT_FLAGS if x is not None and not isinstance(x, np.ndarray)])
    a["b"] = np.array(True)  # a 0-d array of a bool is a bool, as for every scalar property
    assert a["b"] is True
    assert sorted(os.listdir(files)) == ["t.off"]


def test_options_are_one_of_their_strings(store, triangle_mesh, files):
    mesh, (a, b, _c), _p = triangle_mesh
    tri = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    (files / "t.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    calls = {
        "add_property(kind=x)": lambda x: mesh.add_property(x, "d", "float64"),
        "properties(x)": mesh.properties,
        "remove_property(x, ...)": lambda x: mesh.remove_property(x, "f"),
        "property_array(x, ...)": lambda x: mesh.property_array(x, "f"),
        "set_property_array(x, ...)": lambda x: mesh.set_property_array(x, "f", [0], [1.0]),
        "to_networkx(kind=x)": mesh.to_networkx,
        "import_arrays(on_error=x)": lambda x: store.import_arrays("new", tri, [[0, 1, 2]], on_error=x),
        "import_file(on_error=x)": lambda x: store.import_file(files / "t.off", on_error=x),
        "plot(labels=x)": lambda x: mesh.plot(labels=x),
    }
    refuses_all(store, calls, NOT_CHOICES)
    # None means something here: count the edges, the default view.
    optional = {"plot(view=x)": lambda x: mesh.plot(view=x)}
    refuses_all(store, optional, [x for x in NOT_CHOICES if x is not None])
    # A weight is "length" or the name of an edge property: a text that names none is a property not found.
    weight = {"shortest_path(weight=x)": lambda x: mesh.shortest_path(a, b, weight=x)}
    refuses_all(store, weight, [x for x in NOT_CHOICES if x is not None], (InvalidInputError, PropertyNotFoundError))


def test_names_and_texts_are_text_sql_can_hold(store, triangle_mesh, files):
    mesh, (a, _b, _c), _p = triangle_mesh
    tri = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    (files / "t.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    names = {
        "create_mesh(x)": store.create_mesh,
        "mesh(x)": store.mesh,
        "delete_mesh(x)": store.delete_mesh,
        "rename_mesh(m, x)": lambda x: store.rename_mesh("m", x),
        "copy_mesh(m, x)": lambda x: store.copy_mesh("m", x),
        "import_arrays(x, ...)": lambda x: store.import_arrays(x, tri, [[0, 1, 2]]),
        "dual(x)": mesh.dual,
        "add_property(name=x)": lambda x: mesh.add_property("vertex", x, "float64"),
    }
    refuses_all(store, names, NOT_NAMES)
    # None means something here: the file's name.
    refuses_all(store, {"import_file(name=x)": lambda x: store.import_file(files / "t.off", x)}, NOT_NAMES[1:])
    # A name no property can have is one no property has: never a driver's error about it.
    lookups = {
        "v[x]": lambda x: a[x],
        "v[x] = 1.0": lambda x: a.__setitem__(x, 1.0),
        "del v[x]": lambda x: a.__delitem__(x),
        "remove_property(vertex, x)": lambda x: mesh.remove_property("vertex", x),
        "property_array(vertex, x)": lambda x: mesh.property_array("vertex", x),
        "to_networkx(attrs=[x])": lambda x: mesh.to_networkx(attrs=[x]),
    }
    refuses_all(store, lookups, NOT_NAMES, (PropertyNotFoundError, InvalidInputError))
    texts = {
        "v['s'] = x": lambda x: a.__setitem__("s", x),
        "add_property(str, default=x)": lambda x: mesh.add_property("vertex", "d", "str", default=x),
        "transaction(message=x)": lambda x: _edit_in_a_block(store, mesh, x),
    }
    refuses_all(store, texts, NOT_TEXTS)


def _edit_in_a_block(store, mesh, message) -> None:
    with store.transaction(message=message):
        mesh.add_vertex()


def test_sequences_are_refused_when_iterating_them_fails(store, triangle_mesh, files):
    mesh, (a, b, c), p = triangle_mesh
    e = mesh.find_halfedge(a, b).edge
    positions = {
        "add_vertex(x)": mesh.add_vertex,
        "set_position(v, x)": lambda x: mesh.set_position(a, x),
        "split_edge(e, position=x)": lambda x: mesh.split_edge(e, position=x),
        "poke_polygon(p, position=x)": lambda x: mesh.poke_polygon(p, position=x),
    }
    refuses_all(store, positions, NOT_POSITIONS)
    refuses_all(store, {"v['f3'] = x": lambda x: a.__setitem__("f3", x)}, NOT_POSITIONS[:9])  # NaN is a float64
    not_iterable = [5, b"abc", np.array(1.0), Hostile(), a]
    refuses_all(store, {"to_networkx(attrs=x)": lambda x: mesh.to_networkx(attrs=x)}, not_iterable)  # a str: one
    calls = {
        "add_polygon(x)": mesh.add_polygon,
        "can_add_polygon(x)": mesh.can_add_polygon,
        "to_networkx(vertices=x)": lambda x: mesh.to_networkx(vertices=x),
        "render(size=x)": lambda x: mesh.render(files / "never.png", size=x),
        "import_arrays(positions=x)": lambda x: store.import_arrays("new", x, [[0, 1, 2]]),
        "import_arrays(polygons=x)": lambda x: store.import_arrays("new", [(0, 0, 0)] * 3, x),
        "set_positions(x, ...)": lambda x: mesh.set_positions(x, [(0, 0, 0)]),
        "set_positions(..., x)": lambda x: mesh.set_positions([a], x),
        "set_property_array(..., x)": lambda x: mesh.set_property_array("vertex", "f", [a], x),
    }
    refuses_all(store, calls, ["abc", *not_iterable])
    rows = {
        "import_arrays(polygons=[[0, 1, x]])": lambda x: store.import_arrays("new", [(0, 0, 0)] * 3, [[0, 1, x]]),
        "import_arrays(positions=[..., (0, 0, x)])": lambda x: store.import_arrays(
            "new", [(0, 0, 0), (1, 0, 0), (0, 0, x)], [[0, 1, 2]]
        ),
        "add_polygon([a, b, x])": lambda x: mesh.add_polygon([a, b, x]),
    }
    refuses_all(store, rows, [Hostile(), 10**5000, "1", None])
    assert os.listdir(files) == []


def test_numpy_dtypes_and_python_types_declare_properties_by_name(store):
    mesh = store.create_mesh("m")
    v = mesh.add_vertex()
    spellings = {
        "float64": [np.dtype("float64"), np.float64, float, np.dtype(">f8")],
        "int64": [np.dtype("int64"), np.int64, int],
        "bool": [np.dtype(bool), np.bool_, bool],
        "str": [str, np.str_, np.dtype("U"), np.dtype("U8")],
    }
    values = {"float64": 1.5, "int64": 7, "bool": True, "str": "seven"}
    for name, dtypes in spellings.items():
        for k, dtype in enumerate(dtypes):
            prop = mesh.add_property("vertex", f"{name}{k}", dtype)
            assert prop.dtype == name and type(prop.dtype) is str, dtype
            assert mesh.properties("vertex")[prop.name].dtype == name
            v[prop.name] = values[name]
            assert v[prop.name] == values[name]
            assert mesh.property_array("vertex", prop.name)[1].tolist() == [values[name]]


def test_other_dtypes_are_refused_naming_the_four(store, triangle_mesh):
    mesh, _corners, _p = triangle_mesh
    others = [None, np.float32, np.dtype("float32"), np.int32, np.dtype(object), object, complex, np.dtype("S"), bytes,
              "f8", "float", "double", "Float64", ["float64"], 10**5000, Hostile()]
    before = dump(store)
    for dtype in others:
        exc = refused("add_property(dtype=x)", lambda x: mesh.add_property("vertex", "d", x), dtype)
        assert "float64, int64, bool, str" in str(exc), str(exc)
    assert dump(store) == before


def test_paths_are_checked_before_any_file_is_touched(store, triangle_mesh, files, monkeypatch):
    monkeypatch.chdir(files)
    mesh, _corners, _p = triangle_mesh
    graph = mesh.to_networkx()
    calls = {
        "export(x)": mesh.export,
        "import_file(x)": store.import_file,
        "render(x)": mesh.render,
        "write_graph(g, x)": lambda x: graphio.write_graph(graph, x),
        "hestore.io.read(x)": mesh_io.read,
    }
    refuses_all(store, calls, NOT_PATHS)
    refuses_all(store, {"open(x)": hestore.open}, NOT_PATHS[1:])  # None: the default database
    assert os.listdir(files) == []


def test_files_the_system_refuses_are_invalid_input_naming_them(store, triangle_mesh, files):
    mesh, _corners, _p = triangle_mesh
    for name in ("folder.off", "folder.stl", "folder.ply"):
        (files / name).mkdir()
    graph = mesh.to_networkx()
    calls = {
        "import_file(missing)": lambda: store.import_file(files / "missing.off"),
        "import_file(folder)": lambda: store.import_file(files / "folder.off"),
        "import_file(folder, meshio)": lambda: store.import_file(files / "folder.stl"),
        "export(no folder)": lambda: mesh.export(files / "no" / "such" / "m.off"),
        "export(no folder, meshio)": lambda: mesh.export(files / "no" / "such" / "m.vtk"),
        "export(onto a folder)": lambda: mesh.export(files / "folder.ply"),
        "write_graph(no folder)": lambda: graphio.write_graph(graph, files / "no" / "g.graphml"),
        "io.read(missing)": lambda: mesh_io.read(files / "missing.ply"),
    }
    before = dump(store)
    for label, call in calls.items():
        exc = refused(label, lambda _: call(), None)
        assert re.match(f"cannot (read|write) {re.escape(str(files))}/", str(exc)), f"{label}: {exc}"
        assert isinstance(exc.__cause__, OSError), label
    assert dump(store) == before


def test_bytes_and_path_objects_are_paths(store, triangle_mesh, files):
    mesh, _corners, _p = triangle_mesh
    mesh.export(os.fsencode(files / "a.off"))
    assert store.import_file(os.fsencode(files / "a.off"), "a").mesh.counts().polygons == 1
    mesh.export(files / "b.ply")
    assert store.import_file(files / "b.ply").mesh.name == "b"


def test_progress_is_a_callable(store, triangle_mesh, files):
    mesh, _corners, _p = triangle_mesh
    (files / "t.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    calls = {
        "stats(x)": mesh.stats,
        "components(x)": mesh.components,
        "check(x)": mesh.check,
        "to_networkx(progress=x)": lambda x: mesh.to_networkx(progress=x),
        "export(progress=x)": lambda x: mesh.export(files / "m.off", progress=x),
        "render(progress=x)": lambda x: mesh.render(files / "m.png", progress=x),
        "plot(progress=x)": lambda x: mesh.plot(progress=x),
        "import_arrays(progress=x)": lambda x: store.import_arrays("new", [(0, 0, 0)] * 3, [[0, 1, 2]], progress=x),
        "import_file(progress=x)": lambda x: store.import_file(files / "t.off", progress=x),
    }
    refuses_all(store, calls, NOT_CALLABLES)
    assert sorted(os.listdir(files)) == ["t.off"]


def test_render_sizes_are_whole_pixels_within_bounds(store, triangle_mesh, files):
    mesh, _corners, _p = triangle_mesh
    calls = {
        "render(size=(x, 10))": lambda x: mesh.render(files / "m.png", size=(x, 10)),
        "render(dpi=x)": lambda x: mesh.render(files / "m.png", dpi=x),
    }
    refuses_all(store, calls, [*NOT_INTEGERS, *BEYOND_64_BITS, 0, -1, 10**6])
    refused("render(dpi=5)", lambda x: mesh.render(files / "m.png", dpi=x), 5)  # text cannot be drawn
    assert os.listdir(files) == []
