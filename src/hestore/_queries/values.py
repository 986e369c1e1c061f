"""The statements of property values: one element's, a batch's, and a whole property's columns.

The rows' layout (``property, id, part, v0 …``, one table per dtype) and
what they mean are `hestore._values`'; `hestore.properties` reads one value
(`value`) and whole properties (`texts`, `request`), `hestore._persistence`
the values of the elements a unit of work loads (`of_elements`), and
`hestore.traversal` the values that weigh a search's edges (`of_edges`), and `hestore.validation`
which element and property every value belongs to (`owners`).
"""

from __future__ import annotations

import sqlalchemy as sa

from hestore import schema
from hestore._queries import query
from hestore._statements import in_keys

__all__ = ["value", "of_elements", "of_edges", "texts", "request", "owners"]


def _parts(table: sa.Table) -> list:
    """The value columns ``v0 …`` of a value table."""
    return [c for c in table.c if c.name.startswith("v")]


@query("values.value")
def value(table: sa.Table):
    """``(part, v0, …)`` of element ``:i``'s value of property ``:q``: its rows, none if it has no value."""
    return sa.select(table.c.part, *_parts(table)).where(
        table.c.mesh_id == sa.bindparam("m"), table.c.property == sa.bindparam("q"), table.c.id == sa.bindparam("i")
    )


@query("values.of_elements")
def of_elements(table: sa.Table, size: int, psize: int):
    """``(property, id, part, v0, …)`` of the properties ``:q0 … :q{psize-1}`` of elements ``:i0 … :i{size-1}``."""
    return sa.select(table.c.property, table.c.id, table.c.part, *_parts(table)).where(
        table.c.mesh_id == sa.bindparam("m"),
        table.c.property.in_(in_keys(psize, "q")),
        table.c.id.in_(in_keys(size)),
    )


@query("values.of_edges")
def of_edges(table: sa.Table, size: int):
    """``(id, v0)`` of the value rows of the scalar property ``:q`` of the elements ``:i0 …`` that have one.

    A statement of its own, after the star, rather than a join in it: its
    every plan is a probe of the value table's key per edge, where
    PostgreSQL, planning a join to a value table it has no statistics of
    yet (values written since its last ``ANALYZE``), read the property's
    whole column for every batch (13 s instead of 16 ms for a path on a
    90,601-vertex grid).
    """
    # No condition on ``part``: a scalar's one row is part 0, and a planner without statistics probes the key
    # prefix it names, skipping ``id`` (reading the property's whole column) if it names ``part`` too.
    return sa.select(table.c.id, table.c.v0).where(
        table.c.mesh_id == sa.bindparam("m"), table.c.property == sa.bindparam("q"), table.c.id.in_(in_keys(size))
    )


@query("values.texts")
def texts(table: sa.Table):
    """``(id, part, v0)`` of every value row of property ``:q`` (text values: read as rows, not as columns)."""
    return sa.select(table.c.id, table.c.part, table.c.v0).where(
        table.c.mesh_id == sa.bindparam("m"), table.c.property == sa.bindparam("q")
    )


def request(table: sa.Table, prop: int, width: int, several: bool, floats: str | None) -> tuple:
    """The `hestore._columns.read_columns` request for the numbers of property ``prop``: only what is needed.

    Columns ``id`` (``part`` if a value has ``several`` rows) and ``v0 …
    v{width-1}``, NULL read as 0 — a float's NaN is stored as NULL:
    ``floats="nan"`` reads it as NaN (PostgreSQL), ``floats="flags"`` adds
    a column whose bit ``c`` says ``v{c}`` is NULL (SQLite, which cannot
    write NaN in SQL); None for integers.
    """
    comps, nulls = [], None
    for c in range(width):
        column = table.c[f"v{c}"]
        if floats is None:
            comps.append(sa.func.coalesce(column, 0))
        elif floats == "flags":
            comps.append(sa.func.coalesce(column, 0.0))
            bit = sa.type_coerce(column.is_(None), sa.Integer) * (1 << c)  # SQLite: a comparison is 0 or 1
            nulls = bit if nulls is None else nulls + bit
        else:
            comps.append(sa.func.coalesce(column, sa.literal_column("'NaN'::float8", sa.Float(53))))
    head = [table.c.id, table.c.part] if several else [table.c.id]
    flags = [] if nulls is None else [nulls]
    return (table, [*head, *comps, *flags], [table.c.property == prop])


def owners() -> list:
    """The `hestore._columns.read_columns` requests of ``(id, property)`` of every value, one per value table.

    One row per value (its part 0): what `hestore.validation` checks
    against the catalogue and the elements.
    """
    return [(t, [t.c.id, t.c.property], [t.c.part == 0]) for t in schema.VALUE_TABLES]
