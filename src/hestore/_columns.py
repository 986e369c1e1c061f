"""Whole columns between SQL tables and numpy arrays.

This module owns the set-based transfer of one mesh's rows: reading chosen
columns of several tables as numpy arrays in one consistent snapshot
(`read_columns`), and writing numpy columns as rows in large batches
(`write_columns`). Validation, bulk export and the graph views read through
it; bulk import writes through it. Nothing here builds a Python object per
row except what the DBAPI driver itself demands.

- PostgreSQL (psycopg 3): reads are one ``COPY (SELECT array_agg(...)) TO
  STDOUT (FORMAT BINARY)`` statement decoded with `numpy.frombuffer`; writes
  are binary ``COPY ... FROM STDIN`` buffers assembled with numpy structured
  arrays.
- SQLite and other drivers: reads fetch the DBAPI cursor in chunks into
  `numpy.fromiter`; writes are the driver's ``executemany``.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterator, Mapping, Sequence

import numpy as np
import sqlalchemy as sa

from hestore import schema
from hestore._statements import Prepared

__all__ = [
    "Connection", "read_columns", "read_snapshot", "write_columns", "uses_copy", "position_request", "request",
    "sides_request",
]

#: What `read_columns` reads through: a SQLAlchemy connection (named here for the modules above the session).
Connection = sa.Connection

_FETCH_ROWS = 65536
_WRITE_ROWS = 131072


def uses_copy(dialect: sa.engine.Dialect) -> bool:
    """Whether the binary ``COPY`` paths apply (PostgreSQL through psycopg 3)."""
    return dialect.name == "postgresql" and dialect.driver == "psycopg"


def _is_float(column) -> bool:
    return isinstance(column.type, sa.Float)


# --------------------------------------------------------------------------
# Reading


def position_request() -> tuple:
    """The `read_columns` request for vertex positions: ``id, x, y, z, missing``.

    Coordinates of a vertex without a position read as 0 with ``missing``
    1; `hestore.arrays.positions` turns the five columns into a ``(V, 3)``
    array with NaN rows there.
    """
    v = schema.vertices
    missing = sa.case((v.c.x.is_(None) | v.c.y.is_(None) | v.c.z.is_(None), 1), else_=0)
    return (v, [v.c.id, *(sa.func.coalesce(v.c[k], 0.0) for k in "xyz"), missing])


def request(table: str, *names: str) -> tuple:
    """The `read_columns` request for columns of one of `hestore.schema`'s tables, by name; ``id`` comes first.

    A column that may be NULL (a free half-edge's ``polygon``, an isolated
    vertex's ``halfedge``) reads as -1 there.

    >>> table, cols = request("halfedges", "origin", "polygon")
    >>> table.name, [str(c) for c in cols]
    ('halfedges', ['halfedges.id', 'halfedges.origin', 'coalesce(halfedges.polygon, :coalesce_1)'])
    """
    t = schema.metadata.tables[table]
    return (t, [t.c.id, *(sa.func.coalesce(t.c[n], -1) if t.c[n].nullable else t.c[n] for n in names)])


def sides_request(*names: str) -> tuple:
    """The `read_columns` request for half-edge ids, each one's side, then the columns ``names``.

    Only free half-edges need ``next`` (for boundary cycles), and only
    others a polygon: one column carries both, ``polygon`` or ``-1 - next``
    (ids are >= 0), which saves reading a whole column row by row.

    >>> table, cols = sides_request("origin")
    >>> table.name, len(cols), str(cols[-1])
    ('halfedges', 3, 'halfedges.origin')
    """
    h = schema.halfedges
    side = sa.cast(sa.case((h.c.polygon.is_(None), -1 - h.c.next), else_=h.c.polygon), sa.BigInteger)
    return (h, [h.c.id, side, *(h.c[n] for n in names)])


@contextmanager
def read_snapshot(connection: sa.Connection) -> Iterator[None]:
    """Make the statements run inside the block see one committed state.

    A connection already in a transaction is used as it is (its reads see its
    own writes). An idle SQLite connection gets a deferred ``BEGIN`` (a read
    snapshot in WAL mode), an idle autocommit psycopg connection ``BEGIN
    ISOLATION LEVEL REPEATABLE READ READ ONLY``; both are rolled back after,
    leaving the connection as it was (on a cursor of their own: a trace of
    the session's statements sees the reads, not this transaction control).

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> engine = sa.create_engine("sqlite://", isolation_level="AUTOCOMMIT")
    >>> with engine.connect() as conn, read_snapshot(conn):
    ...     conn.connection.dbapi_connection.in_transaction
    True
    """
    dbapi = connection.connection.dbapi_connection
    begin = None
    if connection.dialect.name == "sqlite":
        if not getattr(dbapi, "in_transaction", True):
            begin = "BEGIN"
    elif uses_copy(connection.dialect):
        if dbapi.autocommit and dbapi.info.transaction_status == 0:  # pq.TransactionStatus.IDLE
            begin = "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"
    if begin is None:
        yield
        return
    with _cursor_of(connection) as cursor:
        cursor.execute(begin)
        try:
            yield
        finally:
            cursor.execute("ROLLBACK")


@contextmanager
def _cursor_of(connection: sa.Connection, cursor=None) -> Iterator:
    """``cursor``, or a new cursor of the connection's closed afterwards."""
    if cursor is not None:
        yield cursor
        return
    cursor = connection.connection.dbapi_connection.cursor()
    try:
        yield cursor
    finally:
        cursor.close()


def _fetch_cursor(
    connection: sa.Connection, cursor, table: sa.Table, columns: Sequence, mesh_id: int, where: Sequence = ()
) -> list[np.ndarray]:
    """``SELECT columns ... WHERE mesh_id = ... ORDER BY id``, read from the DBAPI cursor in chunks.

    On ``cursor`` if given (compiled here), else through the connection.
    Each chunk of rows becomes one structured array with `numpy.fromiter`
    (no SQLAlchemy ``Row`` objects) and is split into columns at once, so the
    peak memory is about one copy of the result.
    """
    dtype = np.dtype([(f"c{k}", np.float64 if _is_float(c) else np.int64) for k, c in enumerate(columns)])
    stmt = sa.select(*columns).where(table.c.mesh_id == mesh_id, *where).order_by(table.c.id)
    result = None
    if cursor is None:
        result = connection.execute(stmt)
        cursor = result.cursor
    else:
        prepared = Prepared(stmt, connection.dialect, prepare=False)
        prepared.execute(cursor, prepared.params({}))
    parts: list[np.ndarray] = []
    try:
        while True:
            rows = cursor.fetchmany(_FETCH_ROWS)
            if not rows:
                break
            parts.append(np.fromiter(rows, dtype=dtype, count=len(rows)))
            del rows
    finally:
        if result is not None:
            result.close()
    block = np.concatenate(parts) if parts else np.empty(0, dtype=dtype)
    del parts
    return [np.ascontiguousarray(block[name]) for name in dtype.names]


_PGCOPY_SIGNATURE = b"PGCOPY\n\xff\r\n\x00"
_ELEMENT = {20: (">i8", np.int64), 701: (">f8", np.float64)}  # int8, float8 OIDs


class _CopyFormatError(RuntimeError):
    """The binary COPY stream is not laid out as expected."""


def _decode_arrays(view: memoryview, dtypes: Sequence[type]) -> list[np.ndarray]:
    """Decode a binary COPY stream of one row of non-NULL-element ``bigint[]`` / ``float8[]``."""

    def int_at(offset: int, size: int) -> int:
        if offset + size > len(view):
            raise _CopyFormatError("truncated COPY stream")
        return int.from_bytes(view[offset : offset + size], "big", signed=True)

    if bytes(view[:11]) != _PGCOPY_SIGNATURE:
        raise _CopyFormatError("not a binary COPY stream")
    pos = 19 + int_at(15, 4)
    if int_at(pos, 2) != len(dtypes):
        raise _CopyFormatError("unexpected number of fields")
    pos += 2
    out = []
    for want in dtypes:
        length = int_at(pos, 4)
        pos += 4
        if length == -1:  # array_agg over no rows is NULL
            out.append(np.empty(0, dtype=want))
            continue
        ndim, flags, elemtype = int_at(pos, 4), int_at(pos + 4, 4), int_at(pos + 8, 4)
        if ndim == 0:
            out.append(np.empty(0, dtype=want))
        elif ndim == 1 and flags == 0 and _ELEMENT.get(elemtype, (None, None))[1] is want:
            count = int_at(pos + 12, 4)
            item = np.dtype([("length", ">i4"), ("value", _ELEMENT[elemtype][0])])
            if 20 + count * item.itemsize != length:
                raise _CopyFormatError("unexpected array layout")
            items = np.frombuffer(view, dtype=item, count=count, offset=pos + 20)
            if not (items["length"] == 8).all():
                raise _CopyFormatError("unexpected array element")
            out.append(items["value"].astype(want))
            del items
        else:
            raise _CopyFormatError("unexpected array header")
        pos += length
    if bytes(view[pos:]) != b"\xff\xff":
        raise _CopyFormatError("unexpected end of COPY stream")
    return out


def _as_8_bytes(column):
    """The column as ``bigint`` or ``double precision``, the two element types `_decode_arrays` reads."""
    return sa.cast(column, sa.Float(53) if _is_float(column) else sa.BigInteger)


def _fetch_pg_copy(cursor, dialect: sa.engine.Dialect, mesh_id: int, requests: Sequence) -> list[np.ndarray]:
    """All requested tables in one statement, through binary ``COPY`` (psycopg 3).

    ``SELECT`` of one ``array_agg`` per column per table, the one-row
    aggregates joined into one row: a single statement, so one snapshot even
    in autocommit mode, and one protocol message decoded with one
    `numpy.frombuffer` per column. The aggregates of one table see its rows in
    the same (storage) order; the caller sorts them by id.
    """
    from_ = None
    columns = []
    dtypes = []
    for k, (table, cols, *where) in enumerate(requests):
        aggregated = (
            sa.select(*(sa.func.array_agg(_as_8_bytes(c)).label(f"c{i}") for i, c in enumerate(cols)))
            .where(table.c.mesh_id == mesh_id, *(where[0] if where else ()))
            .subquery(f"t{k}")
        )
        columns.extend(aggregated.c)
        dtypes.extend(np.float64 if _is_float(c) else np.int64 for c in cols)
        from_ = aggregated if from_ is None else from_.join(aggregated, sa.true())
    stmt = sa.select(*columns).select_from(from_)
    sql = str(stmt.compile(dialect=dialect, compile_kwargs={"literal_binds": True}))
    chunks = []
    with cursor.copy(f"COPY ({sql}) TO STDOUT (FORMAT BINARY)") as copy:
        for data in copy:
            chunks.append(data)
    buf = chunks[0] if len(chunks) == 1 else b"".join(chunks)
    del chunks
    with memoryview(buf) as view:
        return _decode_arrays(view, dtypes)


def read_columns(
    connection: sa.Connection,
    mesh_id: int,
    requests: Sequence[tuple[sa.Table, Sequence]],
    *,
    use_copy: bool | None = None,
    cursor=None,
) -> list[list[np.ndarray]]:
    """Read columns of several tables for one mesh, as one consistent state.

    Parameters
    ----------
    connection : sqlalchemy.Connection
        An open connection to a database holding `hestore.schema`'s tables.
    mesh_id : int
        The ``meshes.id`` whose rows are read.
    requests : sequence of (Table, sequence of column expressions[, conditions])
        For each table, the expressions to read; the first must be the
        table's ``id``; optional conditions narrow the rows beyond the mesh.
        Expressions must not be NULL (use ``coalesce``); ``Float`` ones come
        back as float64, the others as int64.
    use_copy : bool or None, optional
        Force (True) or forbid (False) the PostgreSQL ``COPY`` path; by
        default it is used on PostgreSQL with psycopg 3.
    cursor : DBAPI cursor, optional
        A cursor of the connection's to send the statements on (a session's,
        which a trace sees); by default the connection's own path.

    Returns
    -------
    list of list of ndarray
        Per request, its columns, sorted by id.

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore import schema
    >>> engine = sa.create_engine("sqlite://")
    >>> schema.metadata.create_all(engine)
    >>> v = schema.vertices
    >>> with engine.begin() as conn:
    ...     _ = conn.execute(v.insert(), [{"mesh_id": 1, "id": i, "x": i / 2, "y": 0.0, "z": 0.0} for i in (2, 0, 1)])
    ...     [[ids, xs]] = read_columns(conn, 1, [(v, [v.c.id, v.c.x])])
    >>> ids.tolist(), xs.tolist()
    ([0, 1, 2], [0.0, 0.5, 1.0])
    """
    mesh_id = int(mesh_id)
    if use_copy is None:
        use_copy = uses_copy(connection.dialect)
    if use_copy:
        with _cursor_of(connection, cursor) as copying:
            flat = _fetch_pg_copy(copying, connection.dialect, mesh_id, requests)
    else:
        flat = []
        with read_snapshot(connection):
            for table, cols, *where in requests:
                flat.extend(_fetch_cursor(connection, cursor, table, cols, mesh_id, where[0] if where else ()))
    out = []
    start = 0
    for _, cols, *_where in requests:
        group = flat[start : start + len(cols)]
        start += len(cols)
        ids = group[0]
        if len(ids) > 1 and not (ids[1:] > ids[:-1]).all():
            order = np.argsort(ids, kind="stable")
            group = [c[order] for c in group]
        out.append(group)
    return out


# --------------------------------------------------------------------------
# Writing


def _is_null(values: np.ndarray) -> np.ndarray:
    return np.isnan(values) if values.dtype.kind == "f" else values < 0


def write_columns(
    cursor,
    dialect: sa.engine.Dialect,
    table: sa.Table,
    mesh_id: int,
    columns: Mapping[str, np.ndarray],
    *,
    progress: Callable[[int], None] | None = None,
    nulls: bool = True,
) -> None:
    """Insert one row per array element: ``mesh_id`` and the given columns.

    Parameters
    ----------
    cursor
        A DBAPI cursor of the connection, inside the caller's transaction.
    dialect : sqlalchemy.engine.Dialect
        The connection's dialect.
    table : sqlalchemy.Table
        One of `hestore.schema`'s element tables.
    mesh_id : int
        Written into every row.
    columns : mapping of column name to ndarray
        Equal-length arrays. In a nullable column, ``-1`` (integers) or NaN
        (floats) is written as NULL; with ``nulls=False`` only NaN is (-1 is a
        value: property values are written so).
    progress : callable, optional
        Called with the number of rows written after each batch.

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore import schema
    >>> engine = sa.create_engine("sqlite://")
    >>> schema.metadata.create_all(engine)
    >>> with engine.begin() as conn:
    ...     cur = conn.connection.dbapi_connection.cursor()
    ...     write_columns(cur, engine.dialect, schema.edges, 3, {"id": np.arange(2), "halfedge": np.array([0, 2])})
    ...     print(conn.execute(sa.select(schema.edges)).all())
    [(3, 0, 0, 0), (3, 1, 2, 0)]
    """
    names = list(columns)
    arrays = [np.asarray(columns[n]) for n in names]
    nullable = [table.c[n].nullable and (nulls or a.dtype.kind == "f") for n, a in zip(names, arrays)]
    n_rows = len(arrays[0]) if arrays else 0
    if uses_copy(dialect):
        _write_pg_copy(cursor, table, mesh_id, names, arrays, nullable, n_rows, progress)
        return
    _write_multirow(cursor, dialect, table, int(mesh_id), names, arrays, nullable, n_rows, progress)


#: Rows per multi-row ``INSERT``: SQLite parses one statement for a thousand
#: rows instead of stepping one statement per row, which nearly halves the time.
_ROWS_PER_INSERT = 1000


def _variable_limit(cursor) -> int:
    """How many parameters one statement may take (999, SQLite's limit before 3.32, if unknown)."""
    try:
        import sqlite3

        return cursor.connection.getlimit(sqlite3.SQLITE_LIMIT_VARIABLE_NUMBER)
    except (AttributeError, ImportError):
        return 999


def _write_multirow(cursor, dialect, table, mesh_id, names, arrays, nullable, n_rows, progress) -> None:
    """Multi-row ``INSERT ... VALUES (...), (...)``, the rest of a batch by ``executemany``."""
    mark = "?" if dialect.paramstyle == "qmark" else "%s"
    # mesh_id is an int, inlined so that it does not take a parameter slot per row.
    row = f"({mesh_id}, {', '.join([mark] * len(names))})"
    head = f"INSERT INTO {table.name} (mesh_id, {', '.join(names)}) VALUES "
    limit = _variable_limit(cursor)
    per = max(1, min(_ROWS_PER_INSERT, limit // max(len(names), 1)))
    many = head + ", ".join([row] * per)
    for start in range(0, n_rows, _WRITE_ROWS):
        stop = min(start + _WRITE_ROWS, n_rows)
        block = np.empty((stop - start, len(names)), dtype=object)
        for k, (values, null_ok) in enumerate(zip(arrays, nullable)):
            chunk = values[start:stop]
            block[:, k] = chunk.tolist()
            if null_ok:
                block[_is_null(chunk), k] = None
        full = (len(block) // per) * per
        for params in block[:full].reshape(-1, per * len(names)).tolist():
            cursor.execute(many, params)
        if full < len(block):
            cursor.executemany(head + row, block[full:].tolist())
        if progress is not None:
            progress(stop)


_PG_TYPE = {sa.Integer: ">i4", sa.BigInteger: ">i8", sa.Float: ">f8"}


def _pg_dtype(column: sa.Column) -> str:
    for kind in (sa.BigInteger, sa.Float, sa.Integer):  # BigInteger is an Integer: ask it first
        if isinstance(column.type, kind):
            return _PG_TYPE[kind]
    raise TypeError(f"no binary COPY layout for {column}")  # pragma: no cover - schema has no other types


def _write_pg_copy(cursor, table, mesh_id, names, arrays, nullable, n_rows, progress) -> None:
    """Binary ``COPY FROM STDIN``, one fixed row layout per pattern of NULLs.

    A binary COPY row is its field count, then each field as a 4-byte length
    and the big-endian value, or length -1 for NULL. Rows with the same NULL
    columns share one layout, so each such group is one numpy structured
    array written as raw bytes.
    """
    cols = [table.c.mesh_id] + [table.c[n] for n in names]
    values = [np.full(n_rows, mesh_id, dtype=np.int64)] + arrays
    nulls = [np.zeros(n_rows, dtype=bool)] + [
        _is_null(a) if ok else np.zeros(n_rows, dtype=bool) for a, ok in zip(arrays, nullable)
    ]
    pattern = np.zeros(n_rows, dtype=np.int64)
    for k, mask in enumerate(nulls):
        pattern |= mask.astype(np.int64) << k
    done = 0
    with cursor.copy(f"COPY {table.name} ({', '.join(c.name for c in cols)}) FROM STDIN (FORMAT BINARY)") as copy:
        copy.write(_PGCOPY_SIGNATURE + b"\x00\x00\x00\x00\x00\x00\x00\x00")
        patterns = np.unique(pattern).tolist()
        for pat in patterns:
            rows = np.flatnonzero(pattern == pat) if len(patterns) > 1 else None
            fields = [("count", ">i2")]
            for k, col in enumerate(cols):
                fields.append((f"l{k}", ">i4"))
                if not (pat >> k) & 1:
                    fields.append((f"v{k}", _pg_dtype(col)))
            layout = np.dtype(fields)
            total = n_rows if rows is None else len(rows)
            for start in range(0, total, _WRITE_ROWS):
                stop = min(start + _WRITE_ROWS, total)
                take = slice(start, stop) if rows is None else rows[start:stop]
                block = np.empty(stop - start, dtype=layout)
                block["count"] = len(cols)
                for k in range(len(cols)):
                    if (pat >> k) & 1:
                        block[f"l{k}"] = -1
                    else:
                        block[f"l{k}"] = 8 if layout[f"v{k}"].itemsize == 8 else 4
                        block[f"v{k}"] = values[k][take]
                copy.write(block.tobytes())
                done += stop - start
                if progress is not None:
                    progress(done)
        copy.write(b"\xff\xff")
