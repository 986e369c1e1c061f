"""The storage schema: the only place hestore's tables are defined.

Every element table is keyed ``(mesh_id, id)`` and every query filters by
``mesh_id``, so one database holds many meshes and a mesh can later be the
distribution key of a sharded PostgreSQL. Ids are allocated from the per-mesh
counters in ``meshes`` and never reused.

There are deliberately no foreign keys between element tables: references
form cycles (half-edge ↔ twin, next ↔ prev), and dangling references are an
invariant (``REF``) that `hestore.validation` reports rather than one the
database enforces row by row during bulk writes.

The element kinds are named here too, once (`KINDS`): each kind's key
(``"halfedge"``, the one spelling every module uses), the label messages
show (``"half-edge"``), its table and its id column in
`hestore.arrays.TopologyArrays`.

Changes to these tables go through an Alembic revision in ``migrations/``;
`SCHEMA_REVISION` names the revision this module corresponds to, and a test
checks that the two agree.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import sqlalchemy as sa

__all__ = [
    "SCHEMA_REVISION",
    "metadata",
    "meshes",
    "vertices",
    "halfedges",
    "edges",
    "polygons",
    "Kind",
    "KINDS",
    "KIND_OF_TABLE",
    "properties",
    "property_reals",
    "property_integers",
    "property_texts",
    "revisions",
    "VERSIONED",
    "HISTORY",
]

#: The Alembic revision that creates exactly the tables below.
SCHEMA_REVISION = "0005"

metadata = sa.MetaData()

_ID = sa.BigInteger()


class NoAffinity(sa.types.UserDefinedType):
    """A SQLite column declared without a type, so without a type affinity.

    A ``REAL`` column stores a float with no fractional part as an integer,
    and ``-0.0`` comes back as ``0.0``; a column without affinity keeps the
    REAL value it is given, bit for bit (``typeof()`` still says ``real``).
    """

    cache_ok = True

    def get_col_spec(self, **kw) -> str:
        return ""


#: A float64 column: ``double precision`` on PostgreSQL, exact REALs on SQLite.
_FLOAT = sa.Float(53).with_variant(NoAffinity(), "sqlite")

def _rev() -> sa.Column:
    """The revision that wrote a row (SPEC §4.1): a row is part of revision ``r`` when ``rev <= r``."""
    return sa.Column("rev", _ID, nullable=False, server_default="0")


meshes = sa.Table(
    "meshes",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("name", sa.String(255), nullable=False, unique=True),
    sa.Column("allow_loops", sa.Boolean, nullable=False),
    sa.Column("allow_multi_edges", sa.Boolean, nullable=False),
    # One more per committed transaction that changed the mesh.
    sa.Column("revision", _ID, nullable=False),
    # Id counters: the next id to hand out. Half-edges take 2e and 2e+1.
    sa.Column("next_vertex", _ID, nullable=False),
    sa.Column("next_edge", _ID, nullable=False),
    sa.Column("next_polygon", _ID, nullable=False),
    sa.Column("next_property", _ID, nullable=False, server_default="0"),
    # History (SPEC §4.1): whether it is kept, and the oldest revision still viewable.
    sa.Column("history", sa.Boolean, nullable=False, server_default=sa.true()),
    sa.Column("kept_from", _ID, nullable=False, server_default="0"),
    # Never hand out a deleted mesh's id again (SQLite would reuse the top rowid).
    sqlite_autoincrement=True,
)

vertices = sa.Table(
    "vertices",
    metadata,
    sa.Column("mesh_id", sa.Integer, primary_key=True),
    sa.Column("id", _ID, primary_key=True),
    sa.Column("halfedge", _ID, nullable=True),
    sa.Column("x", _FLOAT, nullable=True),
    sa.Column("y", _FLOAT, nullable=True),
    sa.Column("z", _FLOAT, nullable=True),
    _rev(),
    sqlite_with_rowid=False,
)

halfedges = sa.Table(
    "halfedges",
    metadata,
    sa.Column("mesh_id", sa.Integer, primary_key=True),
    sa.Column("id", _ID, primary_key=True),
    sa.Column("origin", _ID, nullable=False),
    sa.Column("next", _ID, nullable=False),
    sa.Column("prev", _ID, nullable=False),
    sa.Column("twin", _ID, nullable=False),
    sa.Column("edge", _ID, nullable=False),
    sa.Column("polygon", _ID, nullable=True),
    _rev(),
    sa.Index("ix_halfedges_origin", "mesh_id", "origin"),
    sa.Index("ix_halfedges_polygon", "mesh_id", "polygon"),
    sqlite_with_rowid=False,
)

edges = sa.Table(
    "edges",
    metadata,
    sa.Column("mesh_id", sa.Integer, primary_key=True),
    sa.Column("id", _ID, primary_key=True),
    sa.Column("halfedge", _ID, nullable=False),
    _rev(),
    sqlite_with_rowid=False,
)

polygons = sa.Table(
    "polygons",
    metadata,
    sa.Column("mesh_id", sa.Integer, primary_key=True),
    sa.Column("id", _ID, primary_key=True),
    sa.Column("halfedge", _ID, nullable=False),
    _rev(),
    sqlite_with_rowid=False,
)


@dataclass(frozen=True)
class Kind:
    """One element kind: the vocabulary every module takes from `KINDS`.

    Attributes
    ----------
    name : str
        The key code uses: ``"vertex"``, ``"halfedge"``, ``"edge"``, ``"polygon"``.
    label : str
        The word messages show (``"half-edge"`` for ``"halfedge"``).
    table : sqlalchemy.Table
        The table of its elements.
    id_column : str
        Its id column in `hestore.arrays.TopologyArrays` (``"he_id"``).

    Examples
    --------
    >>> KINDS["halfedge"].label, KINDS["halfedge"].table.name, KINDS["halfedge"].id_column
    ('half-edge', 'halfedges', 'he_id')
    >>> list(KINDS)
    ['vertex', 'halfedge', 'edge', 'polygon']
    """

    name: str
    label: str
    table: sa.Table = field(repr=False)
    id_column: str


#: The element kinds by name, in the order vertex, halfedge, edge, polygon.
KINDS = MappingProxyType({
    kind.name: kind
    for kind in (
        Kind("vertex", "vertex", vertices, "v_id"),
        Kind("halfedge", "half-edge", halfedges, "he_id"),
        Kind("edge", "edge", edges, "e_id"),
        Kind("polygon", "polygon", polygons, "p_id"),
    )
})

#: The element kind of each element table, by the table's name.
KIND_OF_TABLE = MappingProxyType({kind.table.name: kind.name for kind in KINDS.values()})

# Properties (SPEC §3.2): a catalogue, and the set values in one table per
# SQL type. A value row holds up to four components of one element's value
# (``part`` numbers the rows of a longer vector); elements without a row
# have the property's default. See `hestore._values` for the layout.

properties = sa.Table(
    "properties",
    metadata,
    sa.Column("mesh_id", sa.Integer, primary_key=True),
    sa.Column("id", _ID, primary_key=True),
    sa.Column("kind", sa.String(16), nullable=False),
    sa.Column("name", sa.String(255), nullable=False),
    sa.Column("dtype", sa.String(16), nullable=False),
    # NULL: one value per element; k: shape (k,).
    sa.Column("size", sa.Integer, nullable=True),
    # The default as JSON text; NULL: no default.
    sa.Column("default_value", sa.Text, nullable=True),
    _rev(),
    sa.UniqueConstraint("mesh_id", "kind", "name", name="uq_properties_name"),
    sqlite_with_rowid=False,
)


def _value_table(name: str, type_: sa.types.TypeEngine, width: int) -> sa.Table:
    return sa.Table(
        name,
        metadata,
        sa.Column("mesh_id", sa.Integer, primary_key=True),
        sa.Column("property", _ID, primary_key=True),
        sa.Column("id", _ID, primary_key=True),
        sa.Column("part", sa.Integer, primary_key=True),
        *(sa.Column(f"v{k}", type_, nullable=True) for k in range(width)),
        _rev(),
        sqlite_with_rowid=False,
    )


property_reals = _value_table("property_reals", _FLOAT, 4)
property_integers = _value_table("property_integers", sa.BigInteger(), 4)
property_texts = _value_table("property_texts", sa.Text(), 1)

#: Value tables of properties.
VALUE_TABLES = (property_reals, property_integers, property_texts)

#: Tables whose rows are versioned: each row says which revision wrote it (``rev``).
VERSIONED = (vertices, halfedges, edges, polygons, properties, *VALUE_TABLES)

# History (SPEC §4.1). When a revision changes or deletes a row that an
# earlier revision wrote, the row as it was moves to the table's history
# twin, with ``rev_to``, the revision that superseded it: a row version
# belongs to revision ``r`` when ``rev <= r < rev_to``. Rows made and changed
# within one revision leave nothing behind, so history is net; a bulk import
# writes no history at all (its rows have ``rev = 1``, and revision 0 is empty).


def _history_of(table: sa.Table) -> sa.Table:
    key = [c.name for c in table.primary_key]
    return sa.Table(
        f"{table.name}_history",
        metadata,
        *(sa.Column(c.name, c.type, nullable=not c.primary_key) for c in table.columns),
        sa.Column("rev_to", _ID, nullable=False),
        # Clustered by the revision that superseded the row: a revision's records are one range, written
        # at the end of the mesh's part (one page) and read back as one range by undo, diff and prune.
        # No second index: a view's reads scan the records since its revision, in proportion to the
        # changes since then, as SPEC §9 asks, and every edit writes one B-tree per table, not two.
        sa.PrimaryKeyConstraint("mesh_id", "rev_to", *(k for k in key if k != "mesh_id")),
        sqlite_with_rowid=False,
        info={"versions": table.name, "key": key},
    )


#: Each versioned table's history twin, by the versioned table's name.
HISTORY = {t.name: _history_of(t) for t in VERSIONED}

revisions = sa.Table(
    "revisions",
    metadata,
    sa.Column("mesh_id", sa.Integer, primary_key=True),
    sa.Column("number", _ID, primary_key=True),
    sa.Column("committed_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("message", sa.Text, nullable=True),
    # JSON of SPEC's `changes` where a revision wrote no history (a bulk import, a copy); else NULL.
    sa.Column("changes", sa.Text, nullable=True),
    # The id counters when the revision began: the elements it created have ids from there.
    sa.Column("next_vertex", _ID, nullable=False, server_default="0"),
    sa.Column("next_edge", _ID, nullable=False, server_default="0"),
    sa.Column("next_polygon", _ID, nullable=False, server_default="0"),
    sa.Column("next_property", _ID, nullable=False, server_default="0"),
    # "undo" / "redo" / "revert" and the revision it acted on; NULL for an ordinary revision.
    sa.Column("action", sa.String(8), nullable=True),
    sa.Column("target", _ID, nullable=True),
    sqlite_with_rowid=False,
)

#: Tables of a mesh's rows, in the order they are deleted when a mesh is dropped.
MESH_TABLES = (*VALUE_TABLES, properties, polygons, edges, halfedges, vertices, revisions, *HISTORY.values())


# Scratch tables: temporary, one per connection, emptied at commit, and not
# part of the stored schema (a separate MetaData, so neither migrations nor
# checks of the schema see them). PostgreSQL updates many rows fastest as a
# join with a table filled by binary COPY.

scratch = sa.MetaData()

position_updates = sa.Table(
    "hestore_position_updates",
    scratch,
    sa.Column("mesh_id", sa.Integer, nullable=False),
    sa.Column("id", _ID, nullable=False),
    sa.Column("x", sa.Float(53), nullable=False),
    sa.Column("y", sa.Float(53), nullable=False),
    sa.Column("z", sa.Float(53), nullable=False),
    prefixes=["TEMPORARY"],
    postgresql_on_commit="DELETE ROWS",
)
