"""The statements of history: a mesh's history row, its revisions, the rows changed between two, restores and prunes.

The meaning is `hestore._timeline`'s (which runs them inside the session's
scopes) and `hestore.history`'s; the rewriting of statements into reads of
the past is `hestore._journal`'s, whose builders the families here compile.
The session reads `mesh_history` to check that a view's revision is kept;
`hestore._persistence` composes `revision_insert` into a flush's writes.
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Any

import sqlalchemy as sa

from hestore import schema
from hestore.errors import RevisionNotFoundError
from hestore._journal import COUNTERS, changed_rows, restore_statements, restored, to_history
from hestore._queries import query

__all__ = [
    "mesh_history", "revisions", "counters_at", "counters", "changed", "restore", "restore_new", "set_revision",
    "add_revision", "revision_insert", "forget_history", "forget_revisions", "set_kept_from", "now", "timestamp",
    "kept", "newer", "bad_versions", "stale", "recorded",
]

_M, _R = schema.meshes, schema.revisions


@query("history.mesh")
def mesh_history():
    """``(revision, kept_from, history)`` of mesh ``:m``: its revision, the oldest kept, whether it keeps any."""
    return sa.select(_M.c.revision, _M.c.kept_from, _M.c.history).where(_M.c.id == sa.bindparam("m"))


def kept(name: str, revision: int, row: tuple) -> int:
    """Whether ``revision`` of mesh ``name`` can be read, from its `mesh_history` row; the current revision.

    Raises
    ------
    RevisionNotFoundError
        It was never made, or is no longer kept.

    Examples
    --------
    >>> kept("m", 3, (5, 2, True))
    5
    >>> kept("m", 1, (5, 2, True))
    Traceback (most recent call last):
    ...
    hestore.errors.RevisionNotFoundError: revision 1 of mesh 'm' is no longer kept: its history was pruned, \
and the oldest revision kept is 2
    """
    current, kept_from, keep = row
    if revision == current:
        return current
    if revision < 0 or revision > current:
        raise RevisionNotFoundError(f"mesh {name!r} has no revision {revision}: it is at revision {current}")
    if not keep:
        raise RevisionNotFoundError(
            f"mesh {name!r} keeps no history (created with history=False): only its current "
            f"revision {current} can be read"
        )
    if revision < kept_from:
        raise RevisionNotFoundError(
            f"revision {revision} of mesh {name!r} is no longer kept: its history was pruned, "
            f"and the oldest revision kept is {kept_from}"
        )
    return current


@query("history.revisions")
def revisions(newest_first: bool, limited: bool):
    """``(number, committed_at, message, changes, action, target)`` of the revisions ``>= :first`` of mesh ``:m``.

    Newest first or oldest first; at most ``:limit`` of them if ``limited``.
    Convert ``committed_at`` with `timestamp`.
    """
    stmt = (
        sa.select(_R.c.number, _R.c.committed_at, _R.c.message, _R.c.changes, _R.c.action, _R.c.target)
        .where(_R.c.mesh_id == sa.bindparam("m"), _R.c.number >= sa.bindparam("first"))
        .order_by(_R.c.number.desc() if newest_first else _R.c.number)
    )
    return stmt.limit(sa.bindparam("limit")) if limited else stmt


@query("history.counters_at")
def counters_at():
    """The id counters (`hestore._journal.COUNTERS`) when revision ``:n`` of mesh ``:m`` began."""
    counters = (_R.c[n] for n in COUNTERS)
    return sa.select(*counters).where(_R.c.mesh_id == sa.bindparam("m"), _R.c.number == sa.bindparam("n"))


@query("history.counters")
def counters():
    """The id counters of mesh ``:m`` now."""
    return sa.select(*(_M.c[n] for n in COUNTERS)).where(_M.c.id == sa.bindparam("m"))


@query("history.changed", prepare=False)
def changed(table: sa.Table, side: str):
    """`hestore._journal.changed_rows` of ``table``: planned per call, the best plan depends on the revisions."""
    return changed_rows(table, side)


@query("history.restore", prepare=False, cached=False)
def restore(table: sa.Table, step: int, target: int, revision: int, since: dict):
    """Step ``step`` of `hestore._journal.restore_statements` (copy old rows, delete, write back), for mesh ``:m``."""
    return restore_statements(table, target, revision, since)[step]


@query("history.restore_new", prepare=False, cached=False)
def restore_new(table: sa.Table, target: int, revision: int, dialect: str):
    """The "did not exist" records of the rows a restore brought back (``:m``, revision ``:r``)."""
    return to_history(table, "new", dialect, restored(table, target, revision))


@query("history.set_revision")
def set_revision():
    """Set mesh ``:m``'s revision to ``:revision``."""
    return _M.update().where(_M.c.id == sa.bindparam("m")).values(revision=sa.bindparam("revision"))


def revision_insert() -> sa.Insert:
    """A kept revision's row: number, time, message, ``changes``, the id counters at its start, action and target.

    Parameters ``:m :n :at :msg :ch :sv :se :sp :sq :act :tgt``.
    """
    return _R.insert().values(
        mesh_id=sa.bindparam("m"), number=sa.bindparam("n"), committed_at=sa.bindparam("at"),
        message=sa.bindparam("msg"), changes=sa.bindparam("ch"), next_vertex=sa.bindparam("sv"),
        next_edge=sa.bindparam("se"), next_polygon=sa.bindparam("sp"), next_property=sa.bindparam("sq"),
        action=sa.bindparam("act"), target=sa.bindparam("tgt"),
    )


#: `revision_insert`, registered.
add_revision = query("history.add_revision")(revision_insert)


@query("history.forget_history")
def forget_history(history: sa.Table):
    """Delete the rows of a history table of mesh ``:m`` superseded before revision ``:oldest``."""
    return history.delete().where(history.c.mesh_id == sa.bindparam("m"), history.c.rev_to < sa.bindparam("oldest"))


@query("history.forget_revisions")
def forget_revisions():
    """Delete the revisions of mesh ``:m`` before ``:oldest``."""
    return _R.delete().where(_R.c.mesh_id == sa.bindparam("m"), _R.c.number < sa.bindparam("oldest"))


@query("history.set_kept_from")
def set_kept_from():
    """Set the oldest kept revision of mesh ``:m`` to ``:oldest``."""
    return _M.update().where(_M.c.id == sa.bindparam("m")).values(kept_from=sa.bindparam("oldest"))


# The checks of `hestore.validation`'s ``HISTORY``: each reads at most 100 offending rows of mesh ``:m``, whose
# revision is ``:current``; a row is its element's key (for a value row, the element and the property), then revisions.


def _key(table: sa.Table) -> list:
    """The primary key of a versioned table but ``mesh_id``."""
    return [c for c in table.primary_key if c.name != "mesh_id"]


@query("history.newer", prepare=False)
def newer(table: sa.Table):
    """The current rows of ``table`` written by a revision after ``:current``: their key and ``rev``."""
    return sa.select(*_key(table), table.c.rev).where(
        table.c.mesh_id == sa.bindparam("m"), table.c.rev > sa.bindparam("current")
    ).limit(100)


@query("history.bad_versions", prepare=False)
def bad_versions(table: sa.Table):
    """The kept versions of ``table``'s rows that end after ``:current``, before revision 1, or before they begin."""
    h = schema.HISTORY[table.name]
    bad = (h.c.rev_to > sa.bindparam("current")) | (h.c.rev_to < 1) | (h.c.rev >= h.c.rev_to)
    return sa.select(*(h.c[c.name] for c in _key(table)), h.c.rev, h.c.rev_to).where(
        h.c.mesh_id == sa.bindparam("m"), bad
    ).limit(100)


@query("history.stale", prepare=False)
def stale(table: sa.Table):
    """The current rows of ``table`` older than the last version they superseded: key, ``rev``, that version's end."""
    h, key = schema.HISTORY[table.name], _key(table)
    hkey = [h.c[c.name] for c in key]
    latest = (
        sa.select(*hkey, sa.func.max(h.c.rev_to).label("until"))
        .where(h.c.mesh_id == sa.bindparam("m"))
        .group_by(*hkey)
        .subquery()
    )
    return (
        sa.select(*key, table.c.rev, latest.c.until)
        .join_from(table, latest, sa.and_(*(c == latest.c[c.name] for c in key)))
        .where(table.c.mesh_id == sa.bindparam("m"), table.c.rev < latest.c.until)
        .limit(100)
    )


@query("history.recorded")
def recorded():
    """The numbers of mesh ``:m``'s revision records from ``:first`` to ``:current``."""
    return sa.select(_R.c.number).where(
        _R.c.mesh_id == sa.bindparam("m"), _R.c.number >= sa.bindparam("first"), _R.c.number <= sa.bindparam("current")
    )


def now(sqlite: bool) -> Any:
    """The time a revision is committed, as the driver takes it.

    On SQLite the text sqlite3's datetime adapter wrote (deprecated since
    Python 3.12), without the adapter's call; elsewhere an aware datetime.
    """
    at = datetime.now(timezone.utc)
    return at.isoformat(" ") if sqlite else at


def timestamp(value: Any) -> datetime:
    """A ``committed_at`` as read from the cursor: SQLite gives the text back, in UTC.

    >>> timestamp("2026-11-02 10:00:00.5+00:00"), timestamp("2026-11-02 10:00:00")
    (datetime.datetime(2026, 11, 2, 10, 0, 0, 500000, tzinfo=datetime.timezone.utc), \
datetime.datetime(2026, 11, 2, 10, 0, tzinfo=datetime.timezone.utc))
    """
    at = datetime.fromisoformat(value) if isinstance(value, str) else value
    return at if at.tzinfo is not None else at.replace(tzinfo=timezone.utc)
