"""The SQL of history: reading a mesh as it was, and the row versions between revisions.

This module owns the statements over the history tables of
`hestore.schema` (SPEC §4.1) that are not part of writing a flush (those are
`hestore._persistence`'s): turning any read statement into the same read of
an earlier revision (`as_of`), listing kept revisions, fetching the row
versions that changed between two revisions, and the set-based statements
that make the current rows equal to an earlier revision's
(`restore_statements`). Its builders are compiled as the queries of
`hestore._queries.history` and as a view's reads (`hestore._queries.Executor.as_of`);
`hestore._persistence` records history with `to_history`, and
`hestore._session` reads a view's columns with `request_as_of`.

A row version belongs to revision ``r`` when ``rev <= r < rev_to``: current
rows have no ``rev_to``, history rows have one, and a history row with
``rev`` NULL records that its key did not exist before ``rev_to``.
"""

from __future__ import annotations

import json
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects.postgresql import insert as postgresql_insert
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.sql.util import find_tables
from sqlalchemy.sql import operators, visitors
from sqlalchemy.sql.visitors import replacement_traverse

from hestore import schema
from hestore._statements import indexed_by

__all__ = [
    "to_history", "as_of", "as_of_kept", "request_as_of", "touched", "created", "rows_at", "changed_rows",
    "restore_statements", "created_changes", "COUNTED", "COUNTERS", "restored",
]

#: The element kinds of SPEC §4.1's ``changes``: those of `hestore.schema.KINDS`.
KINDS = tuple(schema.KINDS)


def created_changes(vertices: int, halfedges: int, edges: int, polygons: int) -> str:
    """The ``changes`` JSON of a revision that only created elements (an import, a copy).

    Examples
    --------
    >>> created_changes(3, 6, 3, 1)[:46]
    '{"vertex": {"created": 3, "removed": 0, "chang'
    """
    counts = dict(zip(KINDS, (vertices, halfedges, edges, polygons)))
    return json.dumps({k: {"created": int(n), "removed": 0, "changed": 0} for k, n in counts.items()})


def to_history(table: sa.Table, what: str, dialect: str, *where) -> sa.Insert:
    """Record in ``table``'s history the rows ``where`` picks (with ``mesh_id = :m``), for revision ``:r``.

    ``what="old"``: each row an earlier revision wrote (``rev < :r``) is
    copied as it is, before the statement that changes or deletes it.
    ``what="new"``: each row this revision wrote (``rev = :r``) that has no
    history row for it yet did not exist before: a row of its key alone
    (``rev`` NULL) records that, after the statement that inserted it.
    A key recorded for this revision already is left as it is (a batch may
    name a key twice).
    """
    history = schema.HISTORY[table.name]
    r = sa.bindparam("r", type_=sa.BigInteger())
    if what == "old":
        names = [c.name for c in table.columns]
        rows = sa.select(*table.columns, r).where(table.c.mesh_id == sa.bindparam("m"), table.c.rev < r, *where)
    else:
        key = [c for c in table.primary_key]
        names = [c.name for c in key]
        rows = sa.select(*key, r).where(table.c.mesh_id == sa.bindparam("m"), table.c.rev == r, *where)
    insert = postgresql_insert if dialect == "postgresql" else sqlite_insert
    return insert(history).from_select([*names, "rev_to"], rows).on_conflict_do_nothing()


def _versions_at(source: sa.FromClause, revision: Any, mesh: Any = None, where: Any = None) -> sa.Subquery:
    """The rows of a versioned table (or an alias of one) as they were at ``revision``, same columns.

    With ``mesh``, both halves are narrowed to that mesh inside the union: a database cannot always
    push the outer condition in (SQLite never does for the right side of an outer join). ``where``
    (a condition on ``source`` alone) is copied into both halves the same way.
    """
    table = _versioned(source)
    history = schema.HISTORY[table.name].alias(f"{source.name}_h")
    mine = () if mesh is None else (source.c.mesh_id == mesh,)
    theirs = () if mesh is None else (history.c.mesh_id == mesh,)
    if where is not None:
        mine += (where,)
        theirs += (_moved(where, {source: history}),)
    current = sa.select(*source.c).where(source.c.rev <= revision, *mine)
    if where is not None:
        # SQLite plans without statistics: name the index the condition fixes, as the hot reads do.
        fixed = _fixed(where, source, lists=True) | {"mesh_id"}
        by_key = {c.name for c in table.primary_key} <= fixed
        for index in () if by_key else sorted(table.indexes, key=lambda ix: ix.name):
            if {c.name for c in index.columns} <= fixed:
                current = indexed_by(current, source, index.name)
                break
    old = sa.select(*(history.c[c.name] for c in source.c)).where(
        history.c.rev <= revision, history.c.rev_to > revision, *theirs
    )
    return sa.union_all(current, old).subquery(f"{source.name}_at")


def _versioned(source: Any) -> sa.Table | None:
    """The versioned table ``source`` is or aliases, else None."""
    table = source if isinstance(source, sa.Table) else getattr(source, "element", None)
    if isinstance(table, sa.Table) and table.name in schema.HISTORY and schema.metadata.tables.get(table.name) is table:
        return table
    return None


def _column(to: Any, name: str) -> Any:
    """Column ``name`` of a replacement: a from clause's, or a mapping's (merged columns)."""
    return to.c[name] if hasattr(to, "c") else to[name]


def _moved(expr: Any, columns: dict) -> Any:
    """``expr`` with the columns of each ``{from: to}`` read from ``to`` (a from clause or a column mapping)."""

    def replace(element):
        owner = getattr(element, "table", None)
        if isinstance(element, sa.ColumnClause) and owner is not None:
            to = columns.get(owner)
            if to is not None:
                return _column(to, element.name)
        return None

    return replacement_traverse(expr, {}, replace)


def _fixed(condition: Any, source: Any, *, lists: bool = False) -> set[str]:
    """The columns of ``source`` that the terms of ``condition`` (a conjunction) set equal to something.

    With ``lists``, also those it sets to one of a list (``IN``): an index
    on them is searched once per value, as for an equality.
    """
    fixed = set()
    kinds = (operators.eq, operators.in_op) if lists else (operators.eq,)
    for term in _conjuncts(condition):
        if getattr(term, "operator", None) in kinds:
            for side in (term.left, term.right):
                if isinstance(side, sa.ColumnClause) and getattr(side, "table", None) is source:
                    fixed.add(side.name)
    return fixed


def _on_key(join: sa.Join) -> bool:
    """Whether ``join``'s condition fixes every primary-key column of its right side (at most one row matches)."""
    return {c.name for c in _versioned(join.right).primary_key} <= _fixed(join.onclause, join.right)


def as_of(statement, revision: Any, mesh: Any = None):
    """``statement`` reading every versioned table as it was at ``revision`` (a bind parameter or a literal).

    ``mesh`` (the mesh's id, or its bind parameter) narrows every table read to that mesh.

    A versioned table (or alias of one) read on its own is replaced by the
    union of its current rows written by ``revision`` at the latest and its
    history rows that were current then; a condition on the mesh or the key
    reaches both halves, so a point read stays two index probes. The right
    side of an outer join needs more, since no database pushes a join
    condition into a union there: a condition on that table alone (and
    parameters) is copied into both halves; a condition that fixes its key
    becomes two outer joins, one to the current rows and one to history,
    whose columns are merged (at most one of them matches). So the cost of a
    view grows with what changed since, not with the mesh.

    Examples
    --------
    >>> e = schema.edges
    >>> sql = str(as_of(sa.select(e.c.id).where(e.c.mesh_id == 1), 4))
    >>> "edges_history" in sql and "rev_to" in sql
    True
    """
    sources = [s for s in find_tables(statement, include_aliases=True) if _versioned(s) is not None]
    if not sources:
        return statement
    # Where each source is read: a source read in one place only can be narrowed or joined anew.
    reads: dict[int, int] = {}
    joins: list[sa.Join] = []
    nullable: set[int] = set()  # right sides of outer joins: a WHERE condition on them is not theirs to take
    pushed: dict[int, list] = {id(source): [] for source in sources}

    def parts(f):
        if isinstance(f, sa.Join):
            joins.append(f)
            if f.isouter:
                nullable.add(id(f.right))
            return [*parts(f.left), *parts(f.right)]
        return [f]

    selects = [e for e in visitors.iterate(statement) if isinstance(e, sa.Select)]
    own = {}
    for select in selects:
        own[id(select)] = {id(part) for f in select.get_final_froms() for part in parts(f)}
        for i in own[id(select)]:
            reads[i] = reads.get(i, 0) + 1
    where_of: dict[int, Any] = {}  # a WHERE term taken into a union -> its select
    for select in selects:
        for term in _conjuncts(select.whereclause):
            source = _single_source(term)
            if source is not None and id(source) in own[id(select)] and id(source) not in nullable:
                pushed[id(source)].append(term)
                where_of[id(term)] = select
    merged: dict[int, tuple] = {}  # an outer join on the key of its right side -> (current, history)
    columns: dict = {}  # a source -> the subquery replacing it, or a mapping of its columns
    for join in joins:
        right = join.right
        if not (join.isouter and _versioned(right) is not None and reads.get(id(right)) == 1):
            continue
        if _single_source(join.onclause) is right:
            pushed[id(right)].extend(_conjuncts(join.onclause))
        elif _on_key(join):
            table = _versioned(right)
            current, history = table.alias(f"{right.name}_c"), schema.HISTORY[table.name].alias(f"{right.name}_h")
            merged[id(join)] = (current, history)
            columns[right] = {
                c.name: sa.case((current.c.id.is_not(None), current.c[c.name]), else_=history.c[c.name])
                for c in right.c
            }
    # A WHERE term taken into a union leaves its place outside to TRUE: kept, it would be a second
    # join with the same keys, and a planner misjudging one of them loops over the other. Its select
    # names its tables itself then, so that none goes missing with its terms.
    moved: set[int] = set()
    explicit: dict[int, sa.Select] = {}
    for source in sources:
        if source not in columns:
            terms = pushed[id(source)] if reads.get(id(source)) == 1 else []
            columns[source] = _versions_at(source, revision, mesh, sa.and_(*terms) if terms else None)
            for term in terms:
                select = where_of.get(id(term))
                if select is not None:
                    moved.add(id(term))
                    explicit.setdefault(id(select), select.select_from(*select.get_final_froms()))

    def replace(element, keep=None):
        if id(element) in moved:
            return sa.true()
        if id(element) in explicit:
            return replacement_traverse(explicit.pop(id(element)), {}, replace)
        if isinstance(element, sa.Join):
            return rebuilt(element)
        if isinstance(element, sa.FromClause):
            to = columns.get(element)
            return to if hasattr(to, "c") else None
        owner = getattr(element, "table", None)
        if isinstance(element, sa.ColumnClause) and owner is not None and owner is not keep and owner in columns:
            return _column(columns[owner], element.name)
        return None

    def side(f):
        if isinstance(f, sa.Join):
            return rebuilt(f)
        to = replace(f)
        return f if to is None else to

    done: dict[int, sa.Join] = {}

    def rebuilt(join: sa.Join) -> sa.Join:
        # The same join object, wherever it appears (an explicit FROM names it again), gives one new join.
        if id(join) not in done:
            done[id(join)] = rejoined(join)
        return done[id(join)]

    def rejoined(join: sa.Join) -> sa.Join:
        left, right = side(join.left), join.right
        plan = merged.get(id(join))
        if plan is None:
            on = replacement_traverse(join.onclause, {}, replace)
            return sa.join(left, side(right), on, isouter=join.isouter, full=join.full)
        current, history = plan
        mine, theirs = (
            replacement_traverse(_moved(join.onclause, {right: to}), {}, lambda e: replace(e, keep=right))
            for to in (current, history)
        )
        narrow = (current.c.mesh_id == mesh,) if mesh is not None else ()
        out = left.outerjoin(current, sa.and_(mine, current.c.rev <= revision, *narrow))
        narrow = (history.c.mesh_id == mesh,) if mesh is not None else ()
        valid = sa.and_(theirs, history.c.rev <= revision, history.c.rev_to > revision, *narrow)
        return out.outerjoin(history, valid)

    return replacement_traverse(statement, {}, replace)


def as_of_kept(statement: sa.Select, revision: Any, mesh: Any) -> sa.Select:
    """`as_of`, reading no rows unless ``revision`` of ``mesh`` is still kept in the state it reads.

    A view's single statement then never mixes the rows a prune (or an edit
    of a mesh without history) left with the rows it took away: it reads the
    revision whole, or nothing, and the caller asks why.

    Examples
    --------
    >>> v = schema.vertices
    >>> "kept_from" in str(as_of_kept(sa.select(v.c.id).where(v.c.mesh_id == 1), 4, 1))
    True
    """
    m = schema.meshes.alias("kept")
    kept = sa.exists().where(
        m.c.id == mesh, sa.or_(m.c.revision == revision, sa.and_(m.c.history, m.c.kept_from <= revision))
    )
    return as_of(statement, revision, mesh).where(kept)


def _conjuncts(condition: Any) -> list:
    """The terms of a conjunction (a single condition is one term; None none)."""
    if condition is None:
        return []
    if isinstance(condition, sa.sql.elements.BooleanClauseList) and condition.operator is operators.and_:
        return [t for c in condition.clauses for t in _conjuncts(c)]
    return [condition]


def _single_source(term: Any) -> Any:
    """The one versioned table or alias ``term`` reads, if it reads no other table; else None.

    The tables a subquery of ``term`` reads from are its own: they do not count.
    """
    inner = {id(f) for e in visitors.iterate(term) if isinstance(e, sa.Select) for f in e.get_final_froms()}
    tables = [t for t in find_tables(term, include_aliases=True, check_columns=True) if id(t) not in inner]
    if tables and all(t is tables[0] for t in tables) and _versioned(tables[0]) is not None:
        return tables[0]
    return None


def request_as_of(request: tuple, revision: int) -> tuple:
    """A `hestore._columns.read_columns` request reading its table as it was at ``revision``.

    Examples
    --------
    >>> v = schema.vertices
    >>> source, cols = request_as_of((v, [v.c.id, v.c.x]), 3)
    >>> source.name, [c.name for c in cols]
    ('vertices_at', ['id', 'x'])
    """
    table, cols, *where = request
    source = _versions_at(table, sa.literal(revision))

    def replace(element):
        if isinstance(element, sa.ColumnClause) and getattr(element, "table", None) is table:
            return source.c[element.name]
        return None

    def moved(expr):
        return replacement_traverse(expr, {}, replace)

    return (source, [moved(c) for c in cols], *([[moved(w) for w in where[0]]] if where else []))


def touched(table: sa.Table, after: Any, until: Any) -> sa.Select:
    """The keys of ``table`` whose row changed in a revision in ``(after, until]``: ``SELECT DISTINCT key``.

    One range of the history twin, which is keyed ``(mesh_id, rev_to, key)``:
    its size is the number of changes, whatever the size of the mesh.
    """
    history = schema.HISTORY[table.name]
    key = [history.c[c.name] for c in table.primary_key if c.name != "mesh_id"]
    return (
        sa.select(*key)
        .where(history.c.mesh_id == sa.bindparam("m"), history.c.rev_to > after, history.c.rev_to <= until)
        .distinct()
    )


#: The tables whose new rows take ids from a counter of ``meshes`` (and ``revisions``): that counter, and
#: how many ids each of its steps gives (an edge's two half-edges).
COUNTED = {"vertices": ("next_vertex", 1), "halfedges": ("next_edge", 2), "edges": ("next_edge", 1),
           "polygons": ("next_polygon", 1), "properties": ("next_property", 1)}


def created(table: sa.Table, start: dict, end: dict):
    """The condition "``table``'s row was created between two points", from the id counters at both.

    Ids are handed out in order and never reused, so what a run of
    revisions created is a range of ids: no history row is needed for it.
    None for a table whose rows have no counter (property values).
    """
    if table.name not in COUNTED:
        return None
    name, step = COUNTED[table.name]
    return (table.c.id >= step * start[name]) & (table.c.id < step * end[name])


def rows_at(table: sa.Table, revision: Any) -> sa.Select | sa.CompoundSelect:
    """The rows of ``table`` at ``revision`` (without ``mesh_id`` and ``rev``), of the mesh ``:m``."""
    cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
    return as_of(sa.select(*cols).where(table.c.mesh_id == sa.bindparam("m")), revision)


#: The id counters of `COUNTED`, as ``changed_rows`` binds them (``:s_<name>`` at the start, ``:e_<name>`` after).
COUNTERS = tuple(dict.fromkeys(name for name, _step in COUNTED.values()))


def changed_rows(table: sa.Table, side: str) -> sa.Select | sa.CompoundSelect:
    """The rows of the keys changed in revisions ``(:lo, :hi]``, as they were at ``:lo`` or at ``:hi``.

    ``side`` is ``"before"`` (at ``:lo``), ``"after"`` (at ``:hi``), or
    ``"whole"``: every row of the mesh at ``:r``. Bind parameters only
    (``:m``, ``:lo``, ``:hi``, ``:r`` and the counters of `COUNTERS`), so
    one compiled statement per table and side serves every pair of
    revisions.

    No side joins the history to itself, so no plan can make it quadratic,
    whatever the planner believes about the tables' sizes:

    * before: the version of a key valid at ``:lo`` is the one its first
      change after ``:lo`` superseded, so its ``rev_to`` is in
      ``(:lo, :hi]`` — one range of the history's ``(mesh_id, rev_to)``
      order, the very range that says which keys changed;
    * after: the current rows of the keys changed (each by its key) and of
      the ids created in between (a range of ids), and the versions valid at
      ``:hi`` that a later revision superseded: written in ``(:lo, :hi]``,
      superseded after ``:hi`` — one range again.
    """
    if side == "whole":
        return rows_at(table, sa.bindparam("r"))
    history = schema.HISTORY[table.name]
    lo, hi, m = (sa.bindparam(n, type_=sa.BigInteger()) for n in ("lo", "hi", "m"))
    cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
    old = [history.c[c.name] for c in cols]
    if side == "before":
        return sa.select(*old).where(history.c.mesh_id == m, history.c.rev_to > lo, history.c.rev_to <= hi,
                                     history.c.rev <= lo)
    key = [c for c in table.primary_key if c.name != "mesh_id"]
    current = sa.select(*cols).where(table.c.mesh_id == m, table.c.rev <= hi)
    parts = [current.where(sa.tuple_(*key).in_(touched(table, lo, hi)))]
    start = {n: sa.bindparam(f"s_{n}", type_=sa.BigInteger()) for n in COUNTERS}
    end = {n: sa.bindparam(f"e_{n}", type_=sa.BigInteger()) for n in COUNTERS}
    new = created(table, start, end)
    if new is not None:
        parts.append(current.where(new))
    parts.append(sa.select(*old).where(history.c.mesh_id == m, history.c.rev_to > hi, history.c.rev > lo,
                                       history.c.rev <= hi))
    # UNION, not UNION ALL: a key both changed and created in between is in the first two parts.
    return sa.union(*parts)


def restore_statements(table: sa.Table, target: int, revision: int, since: dict) -> list:
    """The statements that make ``table``'s current rows of a mesh (``:m``) equal to its rows at ``target``.

    Run as ``revision`` (a new revision): the keys changed after
    ``target`` are moved to history as they are, deleted, and their
    versions valid at ``target`` are written back with ``rev = revision``;
    keys that did not exist then stay deleted, and keys that come back get
    their "did not exist" record for this revision. Set-based: one statement
    each, over ranges of the history twin's key; nothing is read into Python.
    ``since`` holds the id counters when revision ``target + 1`` began:
    rows with ids from there on were created after ``target``.
    """
    history = schema.HISTORY[table.name]
    key = [c for c in table.primary_key if c.name != "mesh_id"]
    m = sa.bindparam("m")
    if target == 0:
        changed = sa.true()  # revision 0 is empty: everything goes
    else:
        keys = sa.select(*(history.c[c.name] for c in key)).where(history.c.mesh_id == m, history.c.rev_to > target)
        if table.name in COUNTED:
            # One list of keys, each found by its index: an OR beside the IN would scan the mesh.
            name, step = COUNTED[table.name]
            made = table.alias("made")
            keys = sa.union_all(keys, sa.select(made.c.id).where(made.c.mesh_id == m, made.c.id >= step * since[name]))
        changed = sa.tuple_(*key).in_(keys)
    names = [c.name for c in table.columns]
    copy_old = history.insert().from_select(
        [*names, "rev_to"],
        sa.select(*table.columns, sa.literal(revision, sa.BigInteger)).where(
            table.c.mesh_id == m, table.c.rev < revision, changed
        ),
    )
    delete = table.delete().where(table.c.mesh_id == m, changed)
    statements = [copy_old, delete]
    if target > 0:
        values = [history.c[n] for n in names if n != "rev"]
        back = sa.select(*values, sa.literal(revision, sa.BigInteger)).where(
            history.c.mesh_id == m, history.c.rev <= target, history.c.rev_to > target, history.c.rev_to < revision
        )
        statements.append(table.insert().from_select([n for n in names if n != "rev"] + ["rev"], back))
    return statements


def restored(table: sa.Table, target: int, revision: int):
    """The condition "this row of ``table`` came back from history in `restore_statements`" (by key, indexed)."""
    history = schema.HISTORY[table.name]
    key = [c for c in table.primary_key if c.name != "mesh_id"]
    back = sa.select(*(history.c[c.name] for c in key)).where(
        history.c.mesh_id == sa.bindparam("m"), history.c.rev <= target, history.c.rev_to > target,
        history.c.rev_to < revision,
    )
    return sa.tuple_(*key).in_(back)
