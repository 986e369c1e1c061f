"""Concurrency (SPEC §4): several processes editing one database.

Real processes (``multiprocessing`` with the ``spawn`` start method), each
with its own `hestore.open` on the test's database. Every wait is bounded:
events and queues are waited on with timeouts, processes are joined with
timeouts and terminated if they overstay, so a broken lock never hangs the
test run.

* Writers to the same mesh are serialized: workers adding triangles to one
  mesh in small transactions (retrying on `StoreBusyError`) lose nothing, and
  the revision counts exactly the committed transactions.
* A writer that cannot get its lock in time gets `StoreBusyError` (after about
  its ``busy_timeout``) and changes nothing; once the holder commits it succeeds.
* PostgreSQL: writers to different meshes are not serialized, and a lock
  timeout inside a block leaves the block usable. SQLite has one writer per
  database, so there a writer to another mesh is refused as busy too.
"""

from __future__ import annotations

import multiprocessing
import queue
import random
import threading
import time
import traceback

import pytest

import hestore
from hestore.errors import MeshNotFoundError, StoreBusyError

from helpers import dump, triangle_grid

CTX = multiprocessing.get_context("spawn")

#: Upper bound for anything a child process is waited for (start-up included).
WAIT = 90.0


# --------------------------------------------------------------------------
# Child processes (module level, so that "spawn" can import them)


def _adder(url: str, worker: int, k: int, start, results) -> None:
    """Add ``k`` small transactions to mesh "m"; report (worker, commits, busy, added)."""
    try:
        store = hestore.open(url, busy_timeout=5.0)
        mesh = store.mesh("m")
        hub = mesh.vertex(0)
        start.wait(timeout=WAIT)  # all workers begin editing together
        rng = random.Random(worker)
        commits = busy = 0
        added = {"vertices": 0, "edges": 0, "polygons": 0}
        deadline = time.monotonic() + WAIT - 10
        for i in range(k):
            kind = i % 3
            while True:
                try:
                    if kind == 0:  # a triangle of new vertices, in a block
                        with store.transaction():
                            vs = [mesh.add_vertex((worker, i, j)) for j in range(3)]
                            mesh.add_polygon(vs)
                        delta = (3, 3, 1)
                    elif kind == 1:  # a triangle on the shared hub vertex, in a block
                        with store.transaction():
                            a, b = mesh.add_vertex((worker, i, 10)), mesh.add_vertex((worker, i, 11))
                            mesh.add_polygon([hub, a, b])
                        delta = (2, 3, 1)
                    else:  # one call outside a block: its own transaction
                        mesh.add_vertex((worker, i, -1))
                        delta = (1, 0, 0)
                    break
                except StoreBusyError:
                    busy += 1
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(rng.uniform(0.001, 0.02))
            commits += 1
            for key, d in zip(("vertices", "edges", "polygons"), delta):
                added[key] += d
        store.close()
        results.put(("ok", worker, commits, busy, added))
    except BaseException:
        results.put(("error", worker, traceback.format_exc()))


def _holder(url: str, mesh_name: str, held, release, results, action: str = "edit") -> None:
    """Open a block, edit (or delete) ``mesh_name``, signal ``held``, wait for ``release``, commit."""
    try:
        store = hestore.open(url)
        mesh = store.mesh(mesh_name)
        with store.transaction():
            if action == "delete":
                store.delete_mesh(mesh_name)
            else:
                a, b, c = (mesh.add_vertex() for _ in range(3))
                mesh.add_polygon([a, b, c])
            held.set()
            if not release.wait(WAIT):
                raise TimeoutError("the test never released the holder")
        store.close()
        results.put(("committed", None))
    except BaseException:
        results.put(("error", traceback.format_exc()))


def _cross(url: str, first: str, second: str, ready, results) -> None:
    """In one block: edit ``first``, wait until the partner has edited its first mesh, edit ``second``.

    Two of these with opposite orders deadlock on PostgreSQL; the loser gets
    `StoreBusyError` and retries its whole block.
    """
    try:
        store = hestore.open(url, busy_timeout=20.0)
        a, b = store.mesh(first), store.mesh(second)
        attempts = 0
        deadline = time.monotonic() + WAIT - 10
        while True:
            attempts += 1
            try:
                with store.transaction():
                    a.add_vertex((attempts, 0, 0))
                    if attempts == 1:
                        ready.wait(timeout=30)  # both hold their first mesh now
                    b.add_vertex((attempts, 1, 0))
                break
            except StoreBusyError:
                if time.monotonic() > deadline:
                    raise
        store.close()
        results.put(("ok", first, attempts))
    except BaseException:
        results.put(("error", first, traceback.format_exc()))


def _run(target, *args) -> multiprocessing.Process:
    p = CTX.Process(target=target, args=args, daemon=True)
    p.start()
    return p


def _stop(processes) -> None:
    for p in processes:
        p.join(timeout=30)
    for p in processes:
        if p.is_alive():
            p.terminate()
            p.join(timeout=5)


def _gather(procs, results) -> list:
    """One report per worker; the workers are stopped; none may have failed."""
    try:
        reports = [_get(results) for _ in procs]
    finally:
        _stop(procs)
    errors = [r for r in reports if r[0] != "ok"]
    assert not errors, "\n".join(r[2] for r in errors)
    return reports


def _get(results, timeout: float = WAIT):
    try:
        return results.get(timeout=timeout)
    except queue.Empty:
        pytest.fail(f"a child process reported nothing within {timeout} s")


# --------------------------------------------------------------------------
# Many writers, one mesh


@pytest.mark.parametrize("n_workers, k", [(2, 30), (3, 30)])
def test_concurrent_writers_to_one_mesh_lose_nothing(db_url, n_workers, k):
    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        hub = mesh.add_vertex((0, 0, 0))
        assert hub.id == 0
        rev0 = mesh.revision
    results = CTX.Queue()
    start = CTX.Barrier(n_workers)
    procs = [_run(_adder, db_url, w, k, start, results) for w in range(n_workers)]
    reports = _gather(procs, results)
    assert all(p.exitcode == 0 for p in procs)

    commits = sum(r[2] for r in reports)
    assert commits == n_workers * k
    added = {key: sum(r[4][key] for r in reports) for key in ("vertices", "edges", "polygons")}
    with hestore.open(db_url) as store:
        mesh = store.mesh("m")
        counts = mesh.counts()
        assert counts.vertices == 1 + added["vertices"]
        assert counts.edges == added["edges"]
        assert counts.halfedges == 2 * added["edges"]
        assert counts.polygons == added["polygons"]
        assert mesh.revision == rev0 + commits
        assert mesh.check() == []
        # every hub triangle is its own fan around the hub
        hub = mesh.vertex(0)
        hub_triangles = n_workers * len([i for i in range(k) if i % 3 == 1])
        assert len(hub.polygons()) == hub_triangles
        assert hub.degree == 2 * hub_triangles
        # ids are unique (the tables' keys) and dense: no id handed out twice, none lost
        d = dump(store)
        vertex_ids = sorted(r[1] for r in d["vertices"] if r[0] == mesh.id)
        assert vertex_ids == list(range(len(vertex_ids)))
        polygon_ids = sorted(r[1] for r in d["polygons"] if r[0] == mesh.id)
        assert polygon_ids == list(range(len(polygon_ids)))
        # each worker's vertices are all there (x = worker number)
        xs = [r[3] for r in d["vertices"] if r[0] == mesh.id and r[1] != 0]
        for r in reports:
            assert xs.count(float(r[1])) == r[4]["vertices"]


# --------------------------------------------------------------------------
# Lock behaviour


def _hold(db_url, mesh_name="m", action="edit"):
    """Start a holder on ``mesh_name``; returns (process, release event, results)."""
    held, release = CTX.Event(), CTX.Event()
    results = CTX.Queue()
    p = _run(_holder, db_url, mesh_name, held, release, results, action)
    if not held.wait(WAIT):
        release.set()
        _stop([p])
        try:
            report = results.get(timeout=1)
        except queue.Empty:
            report = None
        pytest.fail(f"the holder process never got its lock: {report}")
    return p, release, results


def _setup(db_url, *names):
    with hestore.open(db_url) as store:
        for name in names:
            m = store.create_mesh(name)
            with store.transaction():  # revision 1
                m.add_edge(m.add_vertex(), m.add_vertex())


def test_writer_to_a_locked_mesh_gets_store_busy_quickly(db_url):
    _setup(db_url, "m")
    committed = dump(db_url)
    p, release, results = _hold(db_url, "m")
    try:
        with hestore.open(db_url, busy_timeout=0.3) as b:
            m = b.mesh("m")
            # reads are not blocked, and see the committed state
            assert m.counts().edges == 1
            for attempt in (
                lambda: m.add_vertex(),
                lambda: m.add_edge(m.vertex(0), m.vertex(1)),
                lambda: m.remove_vertex(m.vertex(0)),
            ):
                t0 = time.monotonic()
                with pytest.raises(StoreBusyError):
                    attempt()
                elapsed = time.monotonic() - t0
                assert 0.2 <= elapsed < 5.0, f"StoreBusyError after {elapsed:.2f} s with busy_timeout=0.3"
                assert dump(db_url) == committed
                assert not b.in_transaction
            t0 = time.monotonic()
            with pytest.raises(StoreBusyError):
                with b.transaction():
                    m.add_vertex()
            assert time.monotonic() - t0 < 5.0
            assert not b.in_transaction
            assert dump(db_url) == committed
            assert m.revision == 1

            release.set()
            assert _get(results) == ("committed", None)
            p.join(timeout=30)
            # the holder's edit is there, and now B gets the lock
            assert m.counts().polygons == 1
            v = m.add_vertex()
            with b.transaction():
                m.add_edge(v, m.vertex(0))
            assert m.counts().vertices == 2 + 3 + 1
            assert m.revision == 1 + 1 + 2
            assert m.check() == []
    finally:
        release.set()
        _stop([p])
    assert p.exitcode == 0


def test_writer_to_another_mesh_while_one_is_locked(db_url, backend):
    _setup(db_url, "m", "n")
    p, release, results = _hold(db_url, "m")
    try:
        with hestore.open(db_url, busy_timeout=0.3) as b:
            n = b.mesh("n")
            if backend == "postgresql":
                # Writers to different meshes are not serialized: no waiting at all.
                t0 = time.monotonic()
                v = n.add_vertex()
                with b.transaction():
                    n.add_edge(v, n.vertex(0))
                    n.add_polygon([v, n.vertex(0), n.vertex(1)])
                assert time.monotonic() - t0 < 5.0
                assert n.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
                assert n.revision == 1 + 2
            else:
                # SQLite has a single writer per database (BEGIN IMMEDIATE takes the
                # database's write lock), so a writer to *any* mesh waits for the
                # holder and, after its busy_timeout, gets StoreBusyError.
                before = dump(db_url)
                with pytest.raises(StoreBusyError):
                    n.add_vertex()
                with pytest.raises(StoreBusyError):
                    with b.transaction():
                        n.add_vertex()
                assert dump(db_url) == before
            release.set()
            assert _get(results) == ("committed", None)
            p.join(timeout=30)
            n.add_vertex()
            assert b.mesh("m").counts().polygons == 1
            assert b.mesh("m").check() == [] and n.check() == []
    finally:
        release.set()
        _stop([p])
    assert p.exitcode == 0


@pytest.mark.postgresql
def test_store_busy_inside_a_block_leaves_the_block_usable(db_url, backend):
    if backend != "postgresql":
        pytest.skip("SQLite takes its single write lock when the block begins: there is no per-mesh lock to miss")
    _setup(db_url, "m", "n")
    with hestore.open(db_url) as s:
        m_id = s.mesh("m").id
    committed_m = [r for r in dump(db_url)["vertices"] if r[0] == m_id]
    p, release, results = _hold(db_url, "m")
    try:
        with hestore.open(db_url, busy_timeout=0.3) as b:
            m, n = b.mesh("m"), b.mesh("n")
            with b.transaction():
                v = n.add_vertex()  # an edit before the refused lock ...
                with pytest.raises(StoreBusyError):
                    m.add_vertex()
                assert b.in_transaction
                with pytest.raises(StoreBusyError):  # ... asking again is refused again ...
                    m.add_edge(m.vertex(0), m.vertex(1))
                w = n.add_vertex()  # ... and the block goes on
                n.add_edge(v, w)
                assert n.counts().vertices == 4
            assert n.counts() == hestore.Counts(vertices=4, halfedges=4, edges=2, polygons=0)
            assert n.revision == 2
            assert n.check() == []
            # a block whose first edit is the refused one also goes on
            with b.transaction():
                with pytest.raises(StoreBusyError):
                    m.add_vertex()
                n.add_vertex()
            assert n.counts().vertices == 5 and n.revision == 3
            # nothing reached m while A holds it
            release.set()
            assert _get(results) == ("committed", None)
            p.join(timeout=30)
            after_m = [r for r in dump(db_url)["vertices"] if r[0] == m_id]
            assert len(after_m) == len(committed_m) + 3  # only the holder's triangle
            assert m.revision == 2
            assert m.check() == []
    finally:
        release.set()
        _stop([p])
    assert p.exitcode == 0


def test_reader_during_a_writers_block_sees_committed_state(db_url):
    """Another process's open block is invisible, then visible in full after its commit."""
    _setup(db_url, "m")
    committed = dump(db_url)
    p, release, results = _hold(db_url, "m")
    try:
        with hestore.open(db_url, busy_timeout=0.3) as b:
            m = b.mesh("m")
            assert dump(b) == committed
            assert m.counts() == hestore.Counts(vertices=2, halfedges=2, edges=1, polygons=0)
            assert m.check() == []
            assert m.revision == 1
            release.set()
            assert _get(results) == ("committed", None)
            p.join(timeout=30)
            assert m.counts() == hestore.Counts(vertices=5, halfedges=8, edges=4, polygons=1)
            assert m.revision == 2
    finally:
        release.set()
        _stop([p])


def test_writer_waiting_for_a_mesh_that_gets_deleted(db_url):
    """B waits for A's lock; A deletes the mesh and commits; B gets MeshNotFoundError, leaving no rows."""
    _setup(db_url, "m", "n")
    with hestore.open(db_url) as s:
        m_id = s.mesh("m").id
    p, release, results = _hold(db_url, "m", action="delete")
    try:
        with hestore.open(db_url, busy_timeout=30.0) as b:
            m = b.mesh("m")  # the deletion is not committed yet: B still finds it
            timer = threading.Timer(0.5, release.set)
            timer.start()
            try:
                t0 = time.monotonic()
                with pytest.raises(MeshNotFoundError):
                    m.add_polygon([m.add_vertex() for _ in range(3)])
                assert time.monotonic() - t0 < 25.0
            finally:
                timer.cancel()
                release.set()
            assert _get(results) == ("committed", None)
            assert b.meshes() == ["n"]
            d = dump(db_url)
            for table, rows in d.items():
                assert not [r for r in rows if r[0] == m_id], f"rows of the deleted mesh left in {table}"
            assert b.mesh("n").check() == []
    finally:
        release.set()
        _stop([p])
    assert p.exitcode == 0


def test_crossed_blocks_deadlock_loser_retries_and_nothing_is_lost(db_url, backend):
    """Two blocks lock "m" then "n" and "n" then "m": a deadlock on PostgreSQL.

    PostgreSQL breaks it: one block gets `StoreBusyError`, rolls back and
    retries; both blocks' edits end up committed exactly once. (On SQLite
    the second block cannot even begin while the first is open, so there is
    no deadlock to provoke.)
    """
    if backend != "postgresql":
        pytest.skip("SQLite serializes whole write transactions: blocks cannot deadlock")
    _setup(db_url, "m", "n")
    ready = CTX.Barrier(2)
    results = CTX.Queue()
    procs = [_run(_cross, db_url, "m", "n", ready, results), _run(_cross, db_url, "n", "m", ready, results)]
    reports = _gather(procs, results)
    with hestore.open(db_url) as store:
        for name in ("m", "n"):
            mesh = store.mesh(name)
            assert mesh.counts().vertices == 2 + 2  # one vertex from each block
            assert mesh.revision == 1 + 2
            assert mesh.check() == []
    assert max(r[2] for r in reports) >= 2, "expected the deadlock to make one block retry"


# --------------------------------------------------------------------------
# Undo and redo among other writers (SPEC §4, §4.1): what they restore is decided under the lock


def _stepper(url: str, worker: int, attempts: int, start, results) -> None:
    """Make ``attempts`` random attempts on mesh "m": an Euler operator (predicate first), undo or redo."""
    from hestore.errors import ElementNotFoundError, RevisionNotFoundError, TopologyError

    try:
        store = hestore.open(url, busy_timeout=20.0)
        mesh = store.mesh("m")
        rng = random.Random(worker)
        start.wait(timeout=WAIT)
        done = {"operator": 0, "undo": 0, "redo": 0, "refused": 0, "busy": 0}
        deadline = time.monotonic() + WAIT - 20
        for _ in range(attempts):
            if time.monotonic() > deadline:
                break
            what = rng.choice(["operator", "operator", "undo", "redo"])
            try:
                if what == "undo":
                    mesh.undo()
                elif what == "redo":
                    mesh.redo()
                else:
                    edges = list(mesh.edges())  # none after an undo of the import
                    edge = rng.choice(edges) if edges else None
                    op = rng.choice(["flip", "split", "poke", "collapse"])
                    if edge is None:
                        what = "refused"
                    elif op == "flip" and mesh.can_flip_edge(edge):
                        mesh.flip_edge(edge)
                    elif op == "split":
                        mesh.split_edge(edge)
                    elif op == "poke" and edge.halfedge.polygon is not None:
                        mesh.poke_polygon(edge.halfedge.polygon)
                    elif op == "collapse" and mesh.can_collapse_edge(edge.halfedge):
                        mesh.collapse_edge(edge.halfedge)
                    else:
                        what = "refused"
                done[what] += 1
            except (RevisionNotFoundError, ElementNotFoundError, TopologyError):
                # nothing to undo or redo, or an element another process removed meanwhile
                done["refused"] += 1
            except StoreBusyError:
                done["busy"] += 1
        store.close()
        results.put(("ok", worker, done))
    except BaseException:
        results.put(("error", worker, traceback.format_exc()))


def _viewer(url: str, worker: int, stop, results) -> None:
    """Read views ``at(r)`` of random committed revisions until ``stop``: each must be a valid mesh."""
    try:
        store = hestore.open(url)
        mesh = store.mesh("m")
        rng = random.Random(100 + worker)
        seen = 0
        bad = []
        deadline = time.monotonic() + WAIT - 20
        while not stop.is_set() and time.monotonic() < deadline:
            r = rng.randint(1, mesh.revision)
            view = mesh.at(r)
            problems = view.check()
            if problems:
                bad.append((r, [str(p) for p in problems[:3]]))
            seen += 1
        store.close()
        results.put(("ok", worker, seen, bad))
    except BaseException:
        results.put(("error", worker, traceback.format_exc()))


@pytest.mark.slow
def test_undo_and_redo_among_concurrent_writers_lose_no_edit(db_url):
    """Four processes make random operators, undos and redos on one mesh while two read views of it.

    Afterwards the whole history is replayed: every undo must have undone
    the most recent change not yet undone at its commit, every redo
    re-applied the most recently undone one, and each must equal the state
    it claims to restore. An undo decided from a stale history would restore
    an older state and throw away another process's committed edit.
    """
    with hestore.open(db_url) as store:
        store.import_arrays("m", *triangle_grid(4))
    writers, attempts = 4, 30
    start, stop = CTX.Barrier(writers), CTX.Event()
    results, views = CTX.Queue(), CTX.Queue()
    readers = [_run(_viewer, db_url, w, stop, views) for w in range(2)]
    procs = [_run(_stepper, db_url, w, attempts, start, results) for w in range(writers)]
    try:
        reports = _gather(procs, results)
    finally:
        stop.set()
    seen = _gather(readers, views)
    assert all(not r[3] for r in seen), f"a view of a committed revision is broken: {seen}"
    done = {k: sum(r[2][k] for r in reports) for k in reports[0][2]}
    assert done["undo"] > 0 and done["operator"] > 0, done

    with hestore.open(db_url) as store:
        mesh = store.mesh("m")
        history = list(reversed(mesh.history()))
        assert [r.number for r in history] == list(range(1, mesh.revision + 1))
        assert sum(done[k] for k in ("operator", "undo", "redo")) == mesh.revision - 1
        undo_stack, redo_stack = [], []
        for rev in history:
            message = rev.message or ""
            n = rev.number
            if message.startswith(("undo of revision ", "redo of revision ")):
                target = int(message.rsplit(" ", 1)[1])
                action = message.split(" ")[0]
                stack = undo_stack if action == "undo" else redo_stack
                assert stack, f"revision {n} is an {action} of {target}, but there was nothing to {action}"
                assert stack[-1] == target, (
                    f"revision {n} is an {action} of {target}, but the most recent change that could be "
                    f"{action}ne was {stack[-1]}: an edit was lost"
                )
                stack.pop()
                state = target - 1 if action == "undo" else target
                assert not mesh.diff(state, n), f"revision {n} ({message}) is not equal to revision {state}"
                if action == "undo":
                    redo_stack.append(target)
                else:
                    undo_stack.append(n)
            else:
                undo_stack.append(n)
                redo_stack.clear()
        assert mesh.check() == []
