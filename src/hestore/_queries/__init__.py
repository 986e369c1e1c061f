"""hestore's SQL statements: one registry of named queries, and the one path every statement runs by.

Every statement hestore sends is built here or in the storage modules
below the session (`hestore._persistence`'s writes, `hestore._journal`'s
history rewrites, `hestore._columns`' whole-column reads and the requests
that name them), never by an algorithm. A statement is a `Query`: a name, registered once, and a function
that builds it from `hestore.schema`'s tables with SQLAlchemy Core and named
``bindparam`` placeholders. A family of statements — an ``IN`` list per
size, one statement per table — is one query with variants:
``stars.batch(16)`` is the batch star for sixteen vertices, compiled once.

The modules, by topic:

- `hestore._queries.elements`: one element's rows (a vertex, a half-edge and
  its target, an edge, a polygon's ring, ids, counts);
- `hestore._queries.stars`: the outgoing half-edges of vertices — one
  vertex's star, a batch's, and the unit of work's loads — written once;
- `hestore._queries.catalogue`: the meshes by name (find, list, create,
  rename, copy) and each mesh's catalogue of properties;
- `hestore._queries.values`: property values, one element's or a batch's;
- `hestore._queries.history`: revisions, a mesh's history row, the rows
  changed between two revisions, restores and prunes, and the checks of
  the kept history against the current state.

`Executor` runs them: each compiled once for the session's dialect
(`hestore._statements.Prepared`) and sent on the session's DBAPI cursor —
the one path of every statement, so that
`hestore._session.Session.traced` sees them all. A read of a view of the
past is the same query rewritten by `hestore._journal.as_of`, compiled once
more. It is used by `hestore._session` and `hestore._persistence`, which own
the cursor; everything above the session hands the session a query and
its values.
"""

from __future__ import annotations

from typing import Any, Callable, Iterable, Sequence

import sqlalchemy as sa

from hestore._journal import as_of, as_of_kept
from hestore._statements import Prepared

__all__ = ["Query", "query", "registered", "Executor"]

_REGISTRY: dict[str, "Query"] = {}


class Query:
    """One statement of hestore's (or a family, one statement per variant), registered once under its name.

    Parameters
    ----------
    name : str
        ``"topic.what"``, unique among all queries.
    build : callable
        Builds the Core statement from the variant's arguments (none for a
        single statement).
    prepare : bool
        Whether PostgreSQL may keep one plan for every call (see `Prepared`).
    cached : bool
        Whether each variant is compiled once (False: its arguments are
        values a plan must see, and it is compiled per call).

    Examples
    --------
    >>> from hestore import schema
    >>> v = schema.vertices
    >>> q = Query("example.ids", lambda: sa.select(v.c.id).where(v.c.mesh_id == sa.bindparam("m")))
    >>> q.name, q.key
    ('example.ids', ('example.ids',))
    >>> _ = registered().pop("example.ids")
    """

    __slots__ = ("name", "args", "prepare", "cached", "_build", "_variants")

    def __init__(
        self, name: str, build: Callable[..., Any], *, prepare: bool = True, cached: bool = True, args: tuple = ()
    ) -> None:
        self.name = name
        self.args = args
        self.prepare = prepare
        self.cached = cached
        self._build = build
        self._variants: dict[tuple, Query] = {}
        if not args:
            if name in _REGISTRY:
                raise ValueError(f"a query named {name!r} is registered already")
            _REGISTRY[name] = self

    def __call__(self, *args: Any) -> "Query":
        """The variant of this family for ``args`` after its own (the same object each time, unless not ``cached``).

        So ``family(a)(b)`` is ``family(a, b)``: a caller can fix the first arguments and leave the rest.
        """
        if not self.cached:
            return Query(self.name, self._build, prepare=self.prepare, cached=False, args=self.args + args)
        variant = self._variants.get(args)
        if variant is None:
            variant = self._variants[args] = Query(self.name, self._build, prepare=self.prepare, args=self.args + args)
        return variant

    @property
    def key(self) -> tuple:
        """The name and the variant's arguments."""
        return (self.name, *self.args)

    def statement(self) -> Any:
        """The Core statement."""
        return self._build(*self.args)

    def __repr__(self) -> str:
        args = ", ".join(map(repr, self.args))
        return f"Query({self.name!r}{', ' if args else ''}{args})"


def query(name: str, *, prepare: bool = True, cached: bool = True) -> Callable[[Callable[..., Any]], Query]:
    """Register the decorated statement builder as the `Query` ``name``.

    Examples
    --------
    >>> from hestore import schema
    >>> @query("example.named")
    ... def named():
    ...     m = schema.meshes
    ...     return sa.select(m.c.id).where(m.c.name == sa.bindparam("name"))
    >>> named
    Query('example.named')
    >>> _ = registered().pop("example.named")
    """

    def register(build: Callable[..., Any]) -> Query:
        return Query(name, build, prepare=prepare, cached=cached)

    return register


def registered() -> dict[str, Query]:
    """Every query by name."""
    return _REGISTRY


class Executor:
    """Queries compiled for one dialect and run on one cursor: the one path every statement takes.

    Parameters
    ----------
    dialect : sqlalchemy.engine.Dialect
        The dialect every statement is compiled for.
    cursor : callable
        Returns the DBAPI cursor to run on (the session's, which a trace may
        have wrapped).

    Examples
    --------
    >>> import sqlite3
    >>> from sqlalchemy.dialects import sqlite
    >>> from hestore import schema
    >>> from hestore._queries import elements
    >>> connection = sqlite3.connect(":memory:")
    >>> schema.metadata.create_all(sa.create_engine("sqlite://", creator=lambda: connection))
    >>> db = Executor(sqlite.dialect(paramstyle="qmark"), connection.cursor)
    >>> db.rows(elements.revision, {"m": 1}), elements.revision in db.compiled
    ([], True)
    """

    def __init__(self, dialect: sa.engine.Dialect, cursor: Callable[[], Any]) -> None:
        self.dialect = dialect
        self.cursor = cursor
        #: The queries compiled so far (a ``cached`` query is compiled once).
        self.compiled: dict[Query, Prepared] = {}
        self._views: dict[tuple[Query, bool], Prepared] = {}

    def prepared(self, q: Query) -> Prepared:
        """``q`` compiled (once, if it is ``cached``)."""
        stmt = self.compiled.get(q)
        if stmt is None:
            stmt = Prepared(q.statement(), self.dialect, prepare=q.prepare)
            if q.cached:
                self.compiled[q] = stmt
        return stmt

    def as_of(self, q: Query, *, kept: bool) -> Prepared:
        """``q`` reading a mesh ``:m`` as it was at revision ``:asof`` (`hestore._journal.as_of`).

        ``kept``: reading nothing unless that revision is still kept
        (`hestore._journal.as_of_kept`). Planned for each call on
        PostgreSQL: the best plan depends on the revision.
        """
        stmt = self._views.get((q, kept))
        if stmt is None:
            revision = sa.bindparam("asof")
            built = as_of_kept(q.statement(), revision, sa.bindparam("m")) if kept else as_of(q.statement(), revision)
            stmt = self._views[q, kept] = Prepared(built, self.dialect, prepare=False)
        return stmt

    def rows(self, q: Query, values: dict[str, Any] | None = None) -> list[tuple]:
        """Run ``q`` with ``values``; its rows."""
        return self.prepared(q).rows(self.cursor(), values or {})

    def first(self, q: Query, values: dict[str, Any] | None = None) -> tuple | None:
        """The first row of ``q``, or None."""
        rows = self.rows(q, values)
        return rows[0] if rows else None

    def run(self, q: Query, values: dict[str, Any] | None = None) -> None:
        """Run ``q`` with ``values``, discarding any result."""
        self.prepared(q).run(self.cursor(), values or {})

    def run_ordered(self, q: Query, names: tuple, values: Sequence) -> None:
        """`Prepared.run_ordered`: ``values`` in the order of ``names``, no dict built."""
        self.prepared(q).run_ordered(self.cursor(), names, values)

    def run_columns(self, q: Query, fixed: dict[str, Any], columns: dict[str, Iterable]) -> None:
        """`Prepared.run_columns`: once per row of ``columns``, in one driver call."""
        self.prepared(q).run_columns(self.cursor(), fixed, columns)

    def on(self, cursor: Callable[[], Any]) -> "Executor":
        """The same compiled statements, run on another cursor (a second connection's)."""
        other = Executor(self.dialect, cursor)
        other.compiled, other._views = self.compiled, self._views
        return other
