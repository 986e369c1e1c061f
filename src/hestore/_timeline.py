"""The history engine: a mesh's revisions as data — listing them, the rows between two, restoring one, pruning.

This module owns what the session does *with* history rather than *for*
reads: the kept revisions (`revisions`, `oldest_kept`), the row versions
that changed between two revisions (`versions`), making a new revision
equal to an earlier one (`restore`, refused by `restorable` in a block that
changed the mesh already) and forgetting old revisions (`prune`). Each is a
free function on a mesh's identity (`hestore._session.MeshRef`) that runs
the statements of `hestore._queries.history` inside the session's scopes —
`Session.scope` for a write, `Session.querying` or `Session.snapshot` for
a read — and asks the session for what only it knows (the writer lock and
the revision a transaction makes, whether the open block changed the mesh).

The session keeps what a read of the past needs on every call: a view's
identity (`hestore._session.Session.view`), the check that its revision is
still kept, and the rewriting of its statements (`hestore._journal.as_of`).
How history is written is `hestore._persistence`'s (every flush), what the
rows mean is `hestore.history`'s (`Revision`, `Diff`, the undo stack),
which is the caller of this module, with `hestore.store` (a copy checks its
revision here).

The name: it is the mesh's line of revisions — read along it, cut back to
a point (`restore`), or shortened at its start (`prune`) — beside
`hestore._journal`, the SQL of the rows it is made of.
"""

from __future__ import annotations

from typing import Callable

from hestore import schema
from hestore.errors import InvalidInputError, RevisionNotFoundError
from hestore._journal import COUNTERS
from hestore._queries import Executor
from hestore._queries import history as q
from hestore._session import MeshRef

__all__ = ["oldest_kept", "revisions", "versions", "restorable", "restore", "prune"]


def _reading(ref: MeshRef):
    return ref.session.querying(ref, f"could not read the history of mesh {ref.name!r}")


def oldest_kept(ref: MeshRef) -> int:
    """The oldest revision of the mesh that can still be read (its current one if it keeps no history).

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = [mesh.add_vertex() for _ in range(3)]
    >>> oldest_kept(identity(mesh)), prune(identity(mesh), 2), oldest_kept(identity(mesh))
    (0, 2, 2)
    """
    with _reading(ref):
        current, kept_from, keep = ref.session.history_row(ref)
    return kept_from if keep else current


def revisions(ref: MeshRef, limit: int | None = None, *, newest_first: bool = True) -> list[tuple]:
    """The kept revisions ``>= 1``: ``(number, committed_at, message, changes JSON or None, action, target)``.

    ``committed_at`` is an aware datetime in UTC. ``action`` and ``target``
    say what an undo, redo or revert did (None for an ordinary revision):
    what `hestore.history` replays.

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = mesh.add_vertex()
    >>> [(n, message, action) for n, _, message, _, action, _ in revisions(identity(mesh))]
    [(1, None, None)]
    """
    with _reading(ref) as db:
        _, kept_from, keep = ref.session.history_row(ref)
        if not keep:
            return []
        values = {"m": ref.id, "first": max(kept_from, 1), "limit": limit}
        rows = db.rows(q.revisions(newest_first, limit is not None), values)
    return [(n, q.timestamp(at), *rest) for n, at, *rest in rows]


def _counters_after(rows: Callable[..., list], revision: int) -> dict:
    """The id counters after ``revision``: when the next one began, or the mesh's own after the last.

    ``rows(query, values)`` runs a query about the mesh (a `Snapshot`'s, or `_of` an executor's).
    """
    found = rows(q.counters_at, {"n": revision + 1}) or rows(q.counters, {})
    return dict(zip(COUNTERS, found[0]))


def _of(db: Executor, ref: MeshRef) -> Callable[..., list]:
    """``rows(query, values)`` of the mesh through ``db``: its id bound as ``:m``."""
    return lambda query, values: db.rows(query, {**values, "m": ref.id})


def versions(ref: MeshRef, a: int, b: int, *, check: bool = True) -> dict[str, tuple[list, list]]:
    """Per versioned table, its rows at revisions ``a`` and ``b`` of every key changed in between.

    The catalogue of properties comes whole at both. From revision 0
    (empty), every row at ``b``. One consistent snapshot; the cost grows
    with the changes between the two, not with the mesh.

    Raises
    ------
    RevisionNotFoundError
        ``a`` or ``b`` is not kept (with ``check``; without, the rows
        that history still has are read: a kept revision's changes).

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = mesh.add_vertex((1, 2, 3))
    >>> versions(identity(mesh), 0, 1)["vertices"]
    ([], [(0, None, 1.0, 2.0, 3.0)])
    """
    with ref.session.snapshot(ref, kept=(a, b) if check else ()) as snap:
        lo, hi = min(a, b), max(a, b)
        values = {"lo": lo, "hi": hi}
        values.update({f"s_{n}": v for n, v in _counters_after(snap.rows, lo).items()})
        values.update({f"e_{n}": v for n, v in _counters_after(snap.rows, hi).items()})
        out = {}
        for table in schema.VERSIONED:
            whole = table is schema.properties or lo == 0
            rows = []
            for r in (a, b):
                side = "whole" if whole else "before" if r == lo else "after"
                rows.append(snap.rows(q.changed(table, side), {**values, "r": r}) if r else [])
            out[table.name] = (rows[0], rows[1])
        return out


def restorable(ref: MeshRef, action: str) -> None:
    """Raise unless the mesh may be restored now: `InvalidInputError` in a block that changed it already.

    Examples
    --------
    >>> import hestore
    >>> from hestore._session import identity
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.create_mesh("m")
    >>> with store.transaction():
    ...     _ = mesh.add_vertex()
    ...     restorable(identity(mesh), "undo")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: undo makes a revision of its own, but this block has already changed mesh 'm': \
call it outside the block, or before the block's other edits of the mesh
    """
    session = ref.session
    session.writable(ref)
    if session.changed(ref):
        raise InvalidInputError(
            f"{action} makes a revision of its own, but this block has already changed mesh {ref.name!r}: "
            f"call it outside the block, or before the block's other edits of the mesh"
        )


def restore(ref: MeshRef, target: int, message: str, action: str, acted_on: int) -> int:
    """Commit a new revision of the mesh whose rows equal those at ``target``; return its number.

    Set-based (`hestore._journal.restore_statements`), recorded in history
    like any edit: ids, positions and property values come back as they
    were, and the id counters do not move back, so no id is handed out
    twice. Its own transaction, or a savepoint of the open block, which
    must not have changed the mesh already. ``action`` (``"undo"``,
    ``"redo"``, ``"revert"``) and ``acted_on`` are recorded with it.

    Raises
    ------
    RevisionNotFoundError
        ``target`` is not kept.
    InvalidInputError
        The open block has already changed the mesh.

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = mesh.add_vertex()
    >>> restore(identity(mesh), 0, "back to empty", "revert", 0), mesh.counts().vertices
    (2, 0)
    """
    restorable(ref, action)
    session = ref.session
    with session.scope() as db:
        uow = session.lock(ref)  # the writer lock, and the revision this makes
        current = session.kept(ref, target)
        if not uow.history:
            raise RevisionNotFoundError(
                f"mesh {ref.name!r} keeps no history (created with history=False): there is nothing to {action}"
            )
        revision = uow.revision
        dialect = db.dialect.name
        since = _counters_after(_of(db, ref), target)
        values = {"m": ref.id, "r": revision}
        for table in schema.VERSIONED:
            steps = 3 if target > 0 else 2
            for step in range(steps):
                db.run(q.restore(table, step, target, revision, since), values)
            if steps > 2:  # rows came back: those that did not exist before get their record
                db.run(q.restore_new(table, target, revision, dialect), values)
        db.run(q.set_revision, {"m": ref.id, "revision": revision})
        # Its id counters are the mesh's (a restore hands out no id): what later revisions create starts there.
        sv, se, sp, sq = _counters_after(_of(db, ref), revision).values()
        db.run(q.add_revision, {
            "m": ref.id, "n": revision, "at": q.now(dialect == "sqlite"), "msg": message, "ch": None,
            "sv": sv, "se": se, "sp": sp, "sq": sq, "act": action, "tgt": acted_on,
        })
        assert current == revision - 1
        session.written(ref)
    return revision


def prune(ref: MeshRef, keep: int) -> int:
    """Forget all but the newest ``keep`` revisions (the current one included); return the oldest kept.

    Views of the revisions forgotten end (they raise `RevisionNotFoundError`).

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = [mesh.add_vertex() for _ in range(4)]
    >>> prune(identity(mesh), 1), oldest_kept(identity(mesh))
    (4, 4)
    """
    session = ref.session
    session.writable(ref)
    with session.scope() as db:
        session.lock(ref)
        current, kept_from, _ = session.history_row(ref)
        oldest = max(kept_from, current - keep + 1, 0)
        values = {"m": ref.id, "oldest": oldest}
        for history in schema.HISTORY.values():
            # Rows superseded by the oldest kept revision stay: they say what it changed.
            db.run(q.forget_history(history), values)
        db.run(q.forget_revisions, values)
        db.run(q.set_kept_from, values)
        session.end_views(ref, oldest)
    return oldest
