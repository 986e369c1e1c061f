"""Positions and properties of a stored mesh: declaring, reading and writing them.

This module owns the mesh-level algorithms of SPEC §3 "Geometry" and §3.2:
declaring and removing properties, reading and writing one element's value,
reading and writing whole columns as numpy arrays, and moving vertices. They
are free functions of a `hestore.Mesh`; `Mesh` methods and the handles'
``v["name"]`` delegate here. The value rules and the row layout are
`hestore._values`'; every write is an edit of the mesh's unit of work
(`hestore._session.Session.editing`), so it is atomic, transactional, undone
with its block, counted in the revision, and written by the same flush as
every other change.

Set-based writes (`set_property_array`, `set_positions`) check everything
first — dtype, shape, values, duplicate ids, and that every id is a live
element, against the mesh locked for the transaction — and then stage one
write that the flush turns into one statement per batch.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hestore import schema
from hestore import _values as values
from hestore.arrays import Index
from hestore._columns import request
from hestore.errors import ElementNotFoundError, InvalidInputError, PropertyNotFoundError, shown
from hestore._queries import catalogue as catalogue_q
from hestore._queries import values as value_rows
from hestore._unitofwork import UNSET, BulkValues
from hestore._values import KINDS, Property
from hestore._session import MeshRef

__all__ = [
    "add_property",
    "remove_property",
    "properties",
    "value",
    "set_value",
    "property_array",
    "set_property_array",
    "set_position",
    "set_positions",
    "check_position",
    "element_table",
    "catalogue_in",
    "array_in",
]


def element_table(kind: str):
    """The table of an element kind (`hestore.schema.KINDS`)."""
    return schema.KINDS[kind].table


def _kind(kind: object) -> str:
    return values.check_choice(kind, KINDS, "an element kind")


def _missing(ref: MeshRef, kind: str, name: object) -> PropertyNotFoundError:
    return PropertyNotFoundError(f"mesh {ref.name!r} has no {kind} property named {shown(name)}")


def _declared(ref: MeshRef, catalogue: dict, kind: str, name: object) -> Property:
    prop = catalogue.get((kind, name)) if isinstance(name, str) else None
    if prop is None:
        raise _missing(ref, kind, name)
    return prop


# --------------------------------------------------------------------------
# Declaring


def add_property(
    ref: MeshRef, kind: str, name: str, dtype: str, *, shape: tuple = (), default: Any = None
) -> Property:
    """Declare a property on every element of a kind, present and future.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    kind : {"vertex", "halfedge", "edge", "polygon"}
        ``"halfedge"`` properties are per corner: a corner's value lives on
        the half-edge of the polygon whose origin is that corner.
    name : str
        Unique per kind.
    dtype : {"float64", "int64", "bool", "str"}, or a numpy dtype or type
        The name, or what numpy users write for it: ``np.dtype("float64")``,
        ``np.float64`` or ``float`` for ``"float64"``; ``np.dtype("int64")``,
        ``np.int64`` or ``int`` for ``"int64"``; ``np.dtype(bool)``,
        ``np.bool_`` or ``bool`` for ``"bool"``; ``str``, ``np.str_`` or a
        numpy unicode dtype for ``"str"``. Other widths (``float32``),
        ``object`` and the rest are refused. The returned `Property` (and
        `properties`) always has the name.
    shape : tuple, default ()
        ``()`` or ``(k,)`` (``float64`` and ``int64`` only).
    default : optional
        The value of every element without one set; None: no default
        (reads give None, arrays are masked there).

    Returns
    -------
    Property

    Raises
    ------
    InvalidInputError
        A bad kind, name, dtype, shape or default, or a name already used
        for this kind.

    Examples
    --------
    >>> import hestore, numpy as np
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> v = mesh.add_vertex((0, 0, 0))
    >>> mesh.add_property("vertex", "temperature", "float64", default=0.0)
    Property(kind='vertex', name='temperature', dtype='float64', shape=(), default=0.0)
    >>> v["temperature"]
    0.0
    >>> mesh.add_property("vertex", "count", np.int64).dtype, mesh.add_property("edge", "seam", bool).dtype
    ('int64', 'bool')
    """
    kind, name, dtype, shape = values.check_spec(kind, name, dtype, shape)
    spec = Property(kind, name, dtype, shape, None)
    default = values.check_value(spec, default, "the default")
    with ref.session.editing(ref) as uow:
        return uow.values.add_property(Property(kind, name, dtype, shape, default))


def remove_property(ref: MeshRef, kind: str, name: str) -> None:
    """Remove a property and all its values.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = mesh.add_property("edge", "weight", "float64")
    >>> mesh.remove_property("edge", "weight")
    >>> mesh.properties("edge")
    {}
    """
    kind = _kind(kind)
    with ref.session.editing(ref) as uow:
        uow.values.remove_property(_declared(ref, uow.values.catalogue(), kind, name))


def properties(ref: MeshRef, kind: str) -> dict[str, Property]:
    """The properties declared on a kind, by name, in the order they were declared.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = mesh.add_property("halfedge", "uv", "float64", shape=(2,))
    >>> mesh.properties("halfedge")
    {'uv': Property(kind='halfedge', name='uv', dtype='float64', shape=(2,), default=None)}
    """
    kind = _kind(kind)
    rows = ref.session.fetch(ref, catalogue_q.properties_of_kind(kind), {})
    found = {row[2]: values.property_of(*row) for row in rows}
    if not found:
        ref.session.require(ref)  # a deleted mesh is MeshNotFoundError, not an empty catalogue
    return found


# --------------------------------------------------------------------------
# One element


def value(ref: MeshRef, kind: str, i: int, name: str) -> Any:
    """Element ``i``'s value of a property: what ``handle[name]`` returns.

    A tuple for shaped properties; the default where none is set (None
    without a default).

    Raises
    ------
    PropertyNotFoundError
        No such property on this kind.
    ElementNotFoundError
        The element does not exist.
    """
    session = ref.session
    try:
        values.check_text(name, "a property name")  # what reaches SQL: no name holds a NUL or a lone surrogate
    except InvalidInputError:
        raise _missing(ref, kind, name) from None
    found = session.fetch(ref, catalogue_q.property_named(kind, element_table(kind)), {"i": i, "n": name})
    if not found:
        ref.session.require(ref)  # a deleted mesh is MeshNotFoundError, not this
        raise _missing(ref, kind, name)
    *row, exists = found[0]
    if not exists:
        raise ElementNotFoundError(f"{schema.KINDS[kind].label} {i} does not exist in mesh {ref.name!r}")
    prop = values.property_of(*row)
    table = values.table_of(prop.dtype)
    rows = session.fetch(ref, value_rows.value(table), {"q": prop.id, "i": i})
    return values.value_of(prop, rows)


def set_value(ref: MeshRef, kind: str, i: int, name: str, new: Any) -> None:
    """Set element ``i``'s value of a property (None: unset, back to the default).

    An edit like any other: atomic, transactional, counted in the revision.

    Raises
    ------
    PropertyNotFoundError
        No such property on this kind.
    ElementNotFoundError
        The element does not exist.
    InvalidInputError
        The value does not fit the property's dtype or shape; the message
        names the property and the element.
    """
    with ref.session.editing(ref) as uow:
        prop = _declared(ref, uow.values.catalogue(), kind, name)
        checked = values.check_value(prop, new, f"{schema.KINDS[kind].label} {i}")
        uow.values.set_value(prop, i, UNSET if checked is None else values.rows(prop, checked))


# --------------------------------------------------------------------------
# Whole columns


def catalogue_in(snap) -> dict[tuple[str, str], Property]:
    """Every property of a mesh by ``(kind, name)``, as a `hestore._session.Snapshot` of it sees them."""
    found = (values.property_of(*row) for row in snap.rows(catalogue_q.properties_of))
    return {(prop.kind, prop.name): prop for prop in found}


def array_in(snap, ref: MeshRef, prop: Property, ids: np.ndarray):
    """The values of ``prop`` for the live elements ``ids`` (sorted), read set-based in a snapshot.

    What `property_array` returns for them (masked where unset without a
    default); graph views call it in their own snapshot, so that their
    attributes are of the same state as their connectivity.
    """
    return _values_in(snap, ref, prop, ids)[1]


def _values_in(snap, ref: MeshRef, prop: Property, ids: np.ndarray | None) -> tuple[np.ndarray, Any]:
    """``(ids, values)`` of `array_in`; without ``ids``, every live element's, read in the same statement."""
    own_ids = [] if ids is not None else [request(element_table(prop.kind).name)]
    table = values.table_of(prop.dtype)
    if prop.dtype == "str":
        if ids is None:
            [[ids]] = snap.columns(own_ids)
        rows = snap.rows(value_rows.texts(table), {"q": prop.id})
        row_ids = np.fromiter((r[0] for r in rows), dtype=np.int64, count=len(rows))
        row_parts = np.zeros(len(rows), dtype=np.int64)
        components = [np.array([r[2] for r in rows], dtype=object)]
    else:
        # Only what is needed: `part` for values of several rows, NULL flags
        # for floats on SQLite (which stores NaN as NULL and cannot write NaN
        # in SQL; PostgreSQL reads NULL as NaN with coalesce).
        width = min(prop.size or 1, values.WIDTH)
        several = values.parts(prop) > 1
        flags = prop.dtype == "float64" and ref.session.is_sqlite
        floats = None if prop.dtype != "float64" else "flags" if flags else "nan"
        *read, [row_ids, *rest] = snap.columns([*own_ids, value_rows.request(table, prop.id, width, several, floats)])
        if read:
            [[ids]] = read
        row_parts = rest.pop(0) if several else np.zeros(len(row_ids), dtype=np.int64)
        components = rest[:width]
        if flags:
            for c, column in enumerate(components):
                column[(rest[width] >> c) & 1 == 1] = np.nan
    # Rows of elements that are not live (only in a corrupt mesh: check() says PROPERTY_REF) are dropped.
    return ids, values.array_of(prop, len(ids), Index(ids).get(row_ids), row_parts, components)


def _read(ref: MeshRef, kind: str, name: str) -> tuple[Property, np.ndarray, Any]:
    """The property, the live ids of its kind and the array of its values, read in one state."""
    kind = _kind(kind)
    if not isinstance(name, str):
        raise _missing(ref, kind, name)
    with ref.session.snapshot(ref) as snap:
        prop = catalogue_in(snap).get((kind, name))
        if prop is None:
            raise _missing(ref, kind, name)
        return (prop, *_values_in(snap, ref, prop, None))


def property_array(ref: MeshRef, kind: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Every live element's value of a property: ``(ids, values)`` in id order.

    ``values`` has shape ``(n,) + shape`` and the property's dtype (object
    for ``str``), with the default where nothing is set; a property without
    a default gives a `numpy.ma.MaskedArray` whose unset entries are masked.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> vs = [mesh.add_vertex() for _ in range(3)]
    >>> _ = mesh.add_property("vertex", "t", "float64", default=-1.0)
    >>> vs[1]["t"] = 21.5
    >>> ids, t = mesh.property_array("vertex", "t")
    >>> ids.tolist(), t.tolist()
    ([0, 1, 2], [-1.0, 21.5, -1.0])
    """
    _, ids, array = _read(ref, kind, name)
    return ids, array


def _ids(ids: object, kind: str) -> np.ndarray:
    """Element ids from an array of ints, checked: 1-D, int64, no duplicates."""
    label = schema.KINDS[kind].label
    what = f"{label} ids"
    arr = values.check_arraylike(ids, f"{what} must be an array of ids or a sequence of handles")
    if arr.size == 0:
        return np.zeros(0, dtype=np.int64)
    if arr.ndim != 1 or arr.dtype.kind not in "iu":
        raise InvalidInputError(f"{what} must be a 1-D array of integers, not {arr.dtype} of shape {arr.shape}")
    if arr.dtype.kind == "u" and arr.max() > 2**63 - 1:
        raise ElementNotFoundError(f"there is no {label} {int(arr.max())}: ids are 64-bit integers")
    arr = arr.astype(np.int64)
    uniq, counts = np.unique(arr, return_counts=True)
    if (counts > 1).any():
        raise InvalidInputError(f"{what} must not repeat; {int(uniq[counts > 1][0])} appears more than once")
    return arr


def _live_check(ref: MeshRef, kind: str, ids: np.ndarray) -> bool:
    """Raise unless every id is a live element of ``kind``; return whether they are all of them."""
    with ref.session.snapshot(ref) as snap:
        [[live]] = snap.columns([request(element_table(kind).name)])
    _, ok = Index(live).find(ids)
    if not ok.all():
        raise ElementNotFoundError(
            f"{schema.KINDS[kind].label} {int(ids[~ok][0])} does not exist in mesh {ref.name!r} "
            f"({int((~ok).sum())} of the {len(ids)} ids do not)"
        )
    return len(ids) == len(live)


def set_property_array(ref: MeshRef, kind: str, name: str, ids: object, new: object) -> None:
    """Set many elements' values of a property in one set-based write.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    kind, name
        The property.
    ids : array_like of int
        Live elements of ``kind``, each at most once (`hestore.Mesh`
        also takes handles).
    new : array_like, shape ``(len(ids),) + shape``
        Their values. Entries masked in a `numpy.ma.MaskedArray` (or None in
        a ``str`` array) are unset (back to the default).

    Raises
    ------
    PropertyNotFoundError, ElementNotFoundError, InvalidInputError
        Before anything is written.

    Examples
    --------
    >>> import hestore, numpy as np
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> vs = [mesh.add_vertex() for _ in range(4)]
    >>> _ = mesh.add_property("vertex", "rgb", "int64", shape=(3,), default=(0, 0, 0))
    >>> mesh.set_property_array("vertex", "rgb", [1, 3], np.array([[255, 0, 0], [0, 0, 255]]))
    >>> vs[3]["rgb"], vs[0]["rgb"]
    ((0, 0, 255), (0, 0, 0))
    """
    kind = _kind(kind)
    ids = _ids(ids, kind)
    session = ref.session
    with session.scope():
        session.lock(ref)
        prop = _read_spec(ref, kind, name)
        data, unset = values.check_array(prop, new, len(ids))
        if not len(ids):
            return  # nothing to write is no change: the revision stays
        every = _live_check(ref, kind, ids)
        keep = slice(None) if unset is None else ~unset
        columns = values.columns_of(prop, ids[keep], data[keep])
        gone = None if unset is None else ids[unset]
        with session.editing(ref) as uow:
            current = _declared(ref, uow.values.catalogue(), kind, name)
            uow.values.stage(BulkValues(current, ids, columns, gone, every and gone is None))


def _read_spec(ref: MeshRef, kind: str, name: object) -> Property:
    found = properties(ref, kind).get(name) if isinstance(name, str) else None
    if found is None:
        raise _missing(ref, kind, name)
    return found


# --------------------------------------------------------------------------
# Positions


def check_position(position: object) -> tuple[float, float, float] | None:
    """A position checked: three finite real numbers as floats, or None.

    Examples
    --------
    >>> check_position((1, 2, 3))
    (1.0, 2.0, 3.0)
    >>> check_position((0, float("nan"), 0))
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: a position is three finite numbers (x, y, z), not (0, nan, 0)
    """
    if position is None:
        return None
    what = "a position is three finite numbers (x, y, z)"
    items = values.check_items(position, what)
    if len(items) != 3:
        raise InvalidInputError(f"{what}, not {len(items)} values: {shown(position)}")
    xyz = tuple(values.check_real(c, f"coordinate {axis} of a position") for axis, c in zip("xyz", items))
    if not all(math.isfinite(c) for c in xyz):
        raise InvalidInputError(f"{what}, not {shown(position)}")
    return xyz  # type: ignore[return-value]


def set_position(ref: MeshRef, v: int, position: object) -> None:
    """Move vertex ``v`` to ``position`` (None: it has no position).

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> v = mesh.add_vertex()
    >>> mesh.set_position(v, (1, 2, 3)); v.position
    (1.0, 2.0, 3.0)
    """
    xyz = check_position(position)
    with ref.session.editing(ref) as uow:
        uow.values.set_position(v, xyz)


def set_positions(ref: MeshRef, vertices: object, positions: object) -> None:
    """Move many vertices in one set-based write.

    Parameters
    ----------
    vertices : array_like of int
        Live vertices, each at most once (`hestore.Mesh` also takes handles).
    positions : array_like, shape (n, 3)
        Finite coordinates (NaN is an error, not "no position").

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> vs = [mesh.add_vertex() for _ in range(2)]
    >>> mesh.set_positions(vs, [[0, 0, 0], [1, 0, 0]])
    >>> vs[1].position
    (1.0, 0.0, 0.0)
    """
    ids = _ids(vertices, "vertex")
    what = "positions must be an (n, 3) array of finite numbers"
    xyz = values.check_arraylike(positions, what)
    if xyz.size == 0 and len(ids) == 0:
        xyz = np.zeros((0, 3))
    if xyz.dtype.kind not in "iuf" or xyz.shape != (len(ids), 3):
        raise InvalidInputError(f"{what} matching {len(ids)} vertices, not {xyz.dtype} of shape {xyz.shape}")
    xyz = xyz.astype(np.float64)
    bad = ~np.isfinite(xyz).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"position of vertex {int(ids[row])} is {xyz[row].tolist()}: {what}")
    if not len(ids):
        ref.session.require(ref)  # still raises for a deleted mesh; nothing to write is no change
        return
    session = ref.session
    with session.scope():
        session.lock(ref)
        _live_check(ref, "vertex", ids)
        columns = {"id": ids, "x": xyz[:, 0].copy(), "y": xyz[:, 1].copy(), "z": xyz[:, 2].copy()}
        with session.editing(ref) as uow:
            uow.values.stage(BulkValues(None, ids, columns, None))
