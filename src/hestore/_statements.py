"""Compiled SQL for the hot paths.

SQLAlchemy Core builds every statement from the tables in `hestore.schema`
(the statements themselves are `hestore._queries`'); this module compiles
one for one dialect (`Prepared`) and runs it on the driver's own cursor. A
point query through ``Connection.execute`` costs about 50 µs of Python
here, the same query on the cursor about 10 µs, and navigation and editing
issue thousands of them, so the difference is the product.

Statements with an ``IN`` list are compiled per list length, rounded up to a
power of two (the list is padded with its last value), so a few compiled
variants serve every call.
"""

from __future__ import annotations

import itertools
import operator
from typing import Any, Callable, Iterable, Iterator, Sequence

import sqlalchemy as sa

__all__ = [
    "Prepared", "in_list_bucket", "in_chunks", "in_keys", "indexed_by", "padded", "padded_values",
]

#: Longest ``IN`` list compiled; longer lists are sent in chunks of this size.
MAX_IN = 512


def _compiler_for(dialect: sa.engine.Dialect):
    """The dialect's statement compiler, rendering ``with_hint`` on SQLite too.

    Without statistics SQLite's planner scans a WITHOUT ROWID table's primary
    key rather than use a secondary index (1.5 ms instead of 15 µs for one
    vertex star), so hot statements name their index with ``INDEXED BY``.
    SQLAlchemy's SQLite compiler drops table hints; this one renders them.
    """
    base = dialect.statement_compiler
    if dialect.name != "sqlite":
        return base
    cls = _HINTING.get(base)
    if cls is None:
        hint = {"get_from_hint_text": lambda self, table, text: text}
        cls = _HINTING[base] = type("HintingSQLiteCompiler", (base,), hint)
    return cls


_HINTING: dict = {}


def indexed_by(stmt: Any, table: Any, index: str) -> Any:
    """``stmt`` with ``table INDEXED BY index`` on SQLite (no-op elsewhere)."""
    return stmt.with_hint(table, f"INDEXED BY {index}", dialect_name="sqlite")


class Prepared:
    """One statement compiled for one dialect, run on a DBAPI cursor.

    Parameters
    ----------
    stmt : sqlalchemy.sql.ClauseElement
        The Core statement, with named ``bindparam`` placeholders.
    dialect : sqlalchemy.engine.Dialect
        The dialect to compile for.
    prepare : bool
        Whether PostgreSQL may keep one plan for every call (a server-side
        prepared statement, psycopg's choice); False plans each call for its values.
    """

    __slots__ = ("sql", "bind", "order", "_pick", "_fixed", "_options", "_arranged")

    def __init__(self, stmt: Any, dialect: sa.engine.Dialect, *, prepare: bool = True) -> None:
        compiled = _compiler_for(dialect)(dialect, stmt)
        self.sql: str = compiled.string
        # psycopg prepares a statement run five times, and PostgreSQL may then
        # plan it once for any values: right for a point read, ruinous for a
        # read whose best plan depends on its values (a view of the past, the
        # rows between two revisions). Those are planned for every call.
        self._options = {"prepare": False} if not prepare and dialect.name == "postgresql" else {}
        # Positional drivers (sqlite3's qmark) need the parameters in the
        # order they appear; named ones (psycopg's pyformat) take the dict.
        order = tuple(compiled.positiontup) if dialect.positional else None
        #: Parameter names in the order a positional driver takes them (None: named parameters).
        self.order = order
        if order is None:
            self._pick = None
        elif len(order) == 1:
            name = order[0]
            self._pick = lambda values: (values[name],)
        else:
            # A C-level getter: point reads run this once per query.
            self._pick = operator.itemgetter(*order) if order else lambda values: ()
        # Literals the statement carries itself (a LIMIT, a CASE's constants).
        self._fixed = {k: v for k, v in compiled.params.items() if v is not None}
        #: ``bind(values)``: the driver's parameters for named values (`params`, one call less when it can).
        self.bind = self._pick if self._pick is not None and not self._fixed else self.params
        self._arranged: dict[tuple, Callable[[Sequence], Any]] = {}

    def params(self, values: dict[str, Any]) -> Any:
        """Arrange named values the way the driver wants them."""
        if self._fixed:
            values = {**self._fixed, **values}
        if self._pick is None:
            return values
        return self._pick(values)

    def execute(self, cursor: Any, params: Any) -> None:
        """Execute with the driver's parameters (`bind`'s or `params`')."""
        cursor.execute(self.sql, params, **self._options)

    def rows(self, cursor: Any, values: dict[str, Any]) -> list[tuple]:
        """Execute with ``values`` and return all rows."""
        self.execute(cursor, self.params(values))
        return cursor.fetchall()

    def run(self, cursor: Any, values: dict[str, Any]) -> None:
        """Execute with ``values``, discarding any result."""
        self.execute(cursor, self.params(values))

    def run_ordered(self, cursor: Any, names: tuple, values: Sequence) -> None:
        """Execute with ``values`` given in the order of ``names``, discarding any result.

        For the hottest writes, whose callers hold their values in a known
        order: no dict is built per call, the values are rearranged for the
        driver by a getter made once per ``names``.
        """
        arrange = self._arranged.get(names)
        if arrange is None:
            arrange = self._arranged[names] = self._arranger(names)
        cursor.execute(self.sql, arrange(values), **self._options)

    def _arranger(self, names: tuple) -> Callable[[Sequence], Any]:
        if self.order is None or self._fixed or len(self.order) < 2:
            return lambda values: self.params(dict(zip(names, values)))
        index = {name: k for k, name in enumerate(names)}
        return operator.itemgetter(*(index[name] for name in self.order))

    def run_columns(self, cursor: Any, fixed: dict[str, Any], columns: dict[str, Sequence]) -> None:
        """Execute once per row of equal-length ``columns``, in one driver call; ``fixed`` values repeat.

        No dict is built per row for positional drivers: the parameter tuples
        are zipped straight from the columns.
        """
        values = {**self._fixed, **fixed}
        if self.order is None:
            names = list(columns)
            seq: Iterable = ({**values, **dict(zip(names, row))} for row in zip(*columns.values()))
        else:
            seq = zip(*(columns[n] if n in columns else itertools.repeat(values[n]) for n in self.order))
        cursor.executemany(self.sql, seq)


def in_list_bucket(n: int) -> int:
    """The compiled ``IN`` list length that holds ``n`` values.

    >>> [in_list_bucket(n) for n in (1, 2, 3, 5, 17, 600)]
    [1, 2, 4, 8, 32, 512]
    """
    size = 1
    while size < n and size < MAX_IN:
        size *= 2
    return size


def in_chunks(ids: Sequence, least: int = 1) -> Iterator[tuple[Sequence, int]]:
    """``(chunk, size)`` for each run of at most `MAX_IN` of ``ids``: the chunk and its compiled list length.

    ``size`` is `in_list_bucket`'s, and at least ``least``.

    >>> [(list(c), n) for c, n in in_chunks(list(range(5)))]
    [([0, 1, 2, 3, 4], 8)]
    """
    for start in range(0, len(ids), MAX_IN):
        chunk = ids[start : start + MAX_IN]
        yield chunk, max(least, in_list_bucket(len(chunk)))


def in_keys(size: int, prefix: str = "i") -> list:
    """The bind parameters ``{prefix}0 … {prefix}{size-1}`` of an ``IN`` list `padded` fills.

    >>> [k.key for k in in_keys(3)]
    ['i0', 'i1', 'i2']
    """
    return [sa.bindparam(f"{prefix}{k}") for k in range(size)]


def padded_values(values: Sequence, size: int) -> tuple:
    """The values of an ``IN`` list of ``size``, in order: ``values`` padded with its last value.

    >>> padded_values([7, 9, 4], 4)
    (7, 9, 4, 4)
    """
    return (*values, *(values[-1],) * (size - len(values)))


def padded(values: Sequence, size: int, prefix: str = "i") -> dict[str, Any]:
    """Bind values ``{prefix}0 … {prefix}{size-1}`` for an ``IN`` list of ``size``, padded with the last value.

    >>> padded([7, 9, 4], 4)
    {'i0': 7, 'i1': 9, 'i2': 4, 'i3': 4}
    """
    return {f"{prefix}{k}": v for k, v in enumerate(padded_values(values, size))}
