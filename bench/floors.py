"""Pieces of the floors several benchmarks share: reading columns into numpy through PostgreSQL's binary
``COPY``, and putting rows in id order.

A floor is the same work as a hestore figure done with the plain tools (stdlib ``sqlite3``, psycopg, numpy),
measured in the same run; each benchmark keeps its own floors in its file and takes these from here: the
``COPY TO`` reader (``graph.py``, ``import.py``, ``properties.py``), the binary ``COPY FROM`` header and
`by_id` (``import.py``, ``properties.py``).
"""

from __future__ import annotations

import numpy as np

#: The header of PostgreSQL's binary COPY format: its signature, no flags, no header extension.
PGCOPY_HEADER = b"PGCOPY\n\xff\r\n\x00" + b"\x00" * 8


def pg_copy_columns(cursor, exprs: list[str], rest: str, dtypes: list) -> list[np.ndarray]:
    """``SELECT exprs rest`` as numpy columns, through one binary ``COPY TO`` of one row of ``array_agg``s.

    Each expression is cast to int8 or float8 (after its dtype) and aggregated into one array; the single row
    that comes back is decoded with ``np.frombuffer``. (A row-per-row ``COPY TO`` is far slower: the driver
    hands over every row as its own message.) NULL elements are not supported.

    Parameters
    ----------
    cursor : psycopg.Cursor
    exprs : list of str
        The columns' expressions.
    rest : str
        ``FROM ... WHERE ...``.
    dtypes : list
        The numpy dtype of each column.

    Returns
    -------
    list of ndarray
    """
    aggs = ", ".join(f"array_agg(({e})::{'float8' if np.dtype(d).kind == 'f' else 'int8'})"
                     for e, d in zip(exprs, dtypes))
    with cursor.copy(f"COPY (SELECT {aggs} {rest}) TO STDOUT (FORMAT BINARY)") as copy:
        buf = b"".join(copy)
    pos = 19 + 2  # signature, flags, header extension; then the row's field count
    columns = []
    for dtype in dtypes:
        value = ">f8" if np.dtype(dtype).kind == "f" else ">i8"
        item = np.dtype([("length", ">i4"), ("value", value)])
        length = int.from_bytes(buf[pos : pos + 4], "big", signed=True)
        if length < 0:  # array_agg of no rows is NULL
            columns.append(np.empty(0, dtype=dtype))
            pos += 4
            continue
        count = int.from_bytes(buf[pos + 16 : pos + 20], "big")  # after ndim, flags, element type
        columns.append(np.frombuffer(buf, dtype=item, count=count, offset=pos + 24)["value"].astype(dtype))
        pos += 4 + length
    return columns


def by_id(rows: np.ndarray) -> np.ndarray:
    """Rows sorted by their first column (id), as hestore returns them; most often they already are."""
    ids = rows[:, 0]
    if len(ids) > 1 and not (ids[1:] > ids[:-1]).all():
        rows = rows[np.argsort(ids, kind="stable")]
    return rows
