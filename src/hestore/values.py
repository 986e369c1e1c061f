"""Property values: their types, their checks, and their rows in SQL.

This module owns the vocabulary of element properties (SPEC §3.2) below the
mesh: what a `Property` is, which dtypes and shapes exist, how a value or an
array is checked against a property (strictly: never coerced loosely), and
how values are laid out as rows of `hestore.schema`'s value tables. It knows
no database connection; `hestore.persistence` writes the rows it makes and
`hestore.properties` reads them back through the session.

The layout, one table per stored SQL type::

    property_reals     (mesh_id, property, id, part, v0, v1, v2, v3)   float64
    property_integers  (mesh_id, property, id, part, v0, v1, v2, v3)   int64, bool (0/1)
    property_texts     (mesh_id, property, id, part, v0)               str

A row holds up to `WIDTH` components of one element's value: a scalar or a
shape-``(k,)`` value with ``k <= 4`` (a uv, a normal, an RGBA colour) is one
row, ``part`` 0; a longer vector continues in rows ``part`` 1, 2, … Only set
values have rows: an element without one has the property's default. A NaN
float is stored as SQL NULL (SQLite cannot store NaN), and read back as NaN.

Examples
--------
>>> p = Property("vertex", "normal", "float64", (3,), None)
>>> rows(p, check_value(p, [0, 0, 1], "vertex 7"))
[(0, 0.0, 0.0, 1.0)]
>>> check_value(p, [0, 0], "vertex 7")
Traceback (most recent call last):
...
hestore.errors.InvalidInputError: property 'normal' of vertex 7 takes 3 values, not 2: [0, 0]
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from hestore import schema
from hestore.errors import InvalidInputError

__all__ = [
    "KINDS",
    "DTYPES",
    "WIDTH",
    "Property",
    "table_of",
    "parts",
    "check_spec",
    "check_value",
    "check_array",
    "rows",
    "value_of",
    "mean",
    "columns_of",
    "array_of",
    "dump_default",
    "load_default",
    "property_of",
    "catalogue_columns",
]

#: Element kinds a property can be declared on.
KINDS = ("vertex", "halfedge", "edge", "polygon")
#: Property dtypes.
DTYPES = ("float64", "int64", "bool", "str")
#: Components per value row.
WIDTH = 4

_I64_MIN, _I64_MAX = -(2**63), 2**63 - 1
_TABLES = {
    "float64": schema.property_reals,
    "int64": schema.property_integers,
    "bool": schema.property_integers,
    "str": schema.property_texts,
}
_NUMPY = {"float64": np.float64, "int64": np.int64, "bool": np.bool_, "str": object}


@dataclass(frozen=True)
class Property:
    """A declared property: what `Mesh.properties` lists.

    Attributes
    ----------
    kind : {"vertex", "halfedge", "edge", "polygon"}
    name : str
    dtype : {"float64", "int64", "bool", "str"}
    shape : tuple
        ``()`` for one value per element, ``(k,)`` for ``k`` values.
    default : object
        The value of elements that have none set (a tuple for shaped
        properties), or None.
    id : int
        Its id among the mesh's properties (the ``property`` column of the
        value tables); not part of equality.
    """

    kind: str
    name: str
    dtype: str
    shape: tuple
    default: Any
    id: int = field(default=-1, repr=False, compare=False)

    @property
    def size(self) -> int | None:
        """``k`` for shape ``(k,)``, None for a scalar property."""
        return self.shape[0] if self.shape else None


def table_of(dtype: str):
    """The value table of a dtype."""
    return _TABLES[dtype]


def parts(prop: Property) -> int:
    """How many rows one element's value takes."""
    return 1 if not prop.shape else -(-prop.shape[0] // WIDTH)


def _width(prop: Property) -> int:
    """Components in the rows of one element (the last row may be shorter)."""
    return 1 if prop.dtype == "str" else min(prop.size or 1, WIDTH)


# --------------------------------------------------------------------------
# Checking


def check_spec(kind: object, name: object, dtype: object, shape: object) -> tuple[str, str, str, tuple]:
    """Check a property declaration; return ``(kind, name, dtype, shape)`` normalised.

    Examples
    --------
    >>> check_spec("halfedge", "uv", "float64", (2,))
    ('halfedge', 'uv', 'float64', (2,))
    >>> check_spec("vertex", "label", "str", (2,))
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: property 'label': only float64 and int64 properties take a shape, not str
    """
    if kind not in KINDS:
        raise InvalidInputError(f"property kinds are {', '.join(KINDS)}, not {kind!r}")
    if not isinstance(name, str) or not name.strip() or len(name) > 255:
        raise InvalidInputError(f"a property name is a non-blank string of at most 255 characters, not {name!r}")
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise InvalidInputError(f"property name {name!r} contains a control character")
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        raise InvalidInputError(f"property name {name!r} is not valid Unicode text") from None
    if dtype not in DTYPES:
        raise InvalidInputError(f"property {name!r}: dtypes are {', '.join(DTYPES)}, not {dtype!r}")
    if shape is None or shape == ():
        return kind, name, dtype, ()
    if dtype not in ("float64", "int64"):
        raise InvalidInputError(f"property {name!r}: only float64 and int64 properties take a shape, not {dtype}")
    ok = isinstance(shape, tuple) and len(shape) == 1 and type(shape[0]) is int and 1 <= shape[0] <= 1024
    if not ok:
        raise InvalidInputError(f"property {name!r}: shape is () or (k,) with 1 <= k <= 1024, not {shape!r}")
    return kind, name, dtype, shape


def _scalar(prop: Property, value: object, where: str) -> Any:
    """One component, checked and converted to its Python type."""
    dtype = prop.dtype

    def refuse(why: str = "") -> InvalidInputError:
        return InvalidInputError(
            f"property {prop.name!r} of {where} is {dtype}, not {type(value).__name__} {value!r}{why}"
        )

    if dtype == "bool":
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        raise refuse()
    if dtype == "str":
        if not isinstance(value, str):
            raise refuse()
        if "\x00" in value:
            raise refuse(": text may not contain NUL characters")
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            raise refuse(": not valid Unicode text") from None
        return value
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise refuse()
    if dtype == "float64":
        return float(value)
    if isinstance(value, numbers.Integral):
        i = int(value)
    else:
        f = float(value)
        if not f.is_integer():
            raise refuse(": not an integer")
        i = int(f)
    if not _I64_MIN <= i <= _I64_MAX:
        raise refuse(": out of the 64-bit range")
    return i


def check_value(prop: Property, value: object, where: str) -> Any:
    """``value`` checked for ``prop``: a Python scalar, a tuple for shaped properties, or None (unset).

    ``where`` names the element in messages (``"vertex 7"``).
    """
    if value is None:
        return None
    if not prop.shape:
        if isinstance(value, np.ndarray) and value.shape == ():
            value = value[()]
        return _scalar(prop, value, where)
    k = prop.shape[0]
    if isinstance(value, (str, bytes, dict, set)) or not hasattr(value, "__len__"):
        raise InvalidInputError(
            f"property {prop.name!r} of {where} takes {k} values, not {type(value).__name__} {value!r}"
        )
    items = value.tolist() if isinstance(value, np.ndarray) else list(value)
    if len(items) != k or (isinstance(value, np.ndarray) and value.ndim != 1):
        raise InvalidInputError(f"property {prop.name!r} of {where} takes {k} values, not {len(items)}: {value!r}")
    return tuple(_scalar(prop, x, where) for x in items)


def check_array(prop: Property, values: object, n: int) -> tuple[np.ndarray, np.ndarray | None]:
    """An array of ``n`` values for ``prop``: ``(data, unset)``.

    ``data`` has the property's numpy dtype (object for ``str``) and shape
    ``(n,) + prop.shape``; ``unset`` is a boolean mask of the rows to unset
    (from a masked array's mask, or ``None`` entries of a ``str`` array), or
    None.
    """
    what = f"values of property {prop.name!r} ({prop.dtype}{'' if not prop.shape else f', shape {prop.shape}'})"
    unset = None
    if isinstance(values, np.ma.MaskedArray):
        mask = np.ma.getmaskarray(values)
        unset = mask.reshape(len(mask), -1).any(axis=1) if mask.ndim else None
        values = values.data
    if isinstance(values, (str, bytes, dict, set)) or not hasattr(values, "__len__"):
        raise InvalidInputError(f"{what} must be an array, not {type(values).__name__}")
    try:
        arr = np.asarray(values) if prop.dtype != "str" else np.asarray(values, dtype=object)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{what} must be a regular array; these are not") from None
    want = (n,) + prop.shape
    if arr.shape != want and not (n == 0 and arr.size == 0):
        raise InvalidInputError(f"{what} must have shape {want}, not {arr.shape}")
    arr = arr.reshape(want)
    kind = arr.dtype.kind
    if prop.dtype == "str":
        flat = arr.reshape(-1)
        nones = np.fromiter((x is None for x in flat), dtype=bool, count=len(flat))
        if nones.any():
            unset = nones if unset is None else unset | nones
        for i in np.flatnonzero(~nones if unset is None else ~unset).tolist():
            _scalar(prop, flat[i], f"row {i}")
        return arr, unset
    if prop.dtype == "bool":
        if kind != "b":
            raise InvalidInputError(f"{what} must be booleans, not {arr.dtype} values")
        return arr.astype(np.bool_, copy=False), unset
    if kind not in "iuf":
        raise InvalidInputError(f"{what} must be numbers, not {arr.dtype} values")
    if prop.dtype == "float64":
        return arr.astype(np.float64, copy=False), unset
    if kind == "f":
        live = arr if unset is None else arr[~unset]
        bad = ~np.isfinite(live) | (live != np.round(live)) | (live < -(2.0**63)) | (live >= 2.0**63)
        if bad.any():
            raise InvalidInputError(f"{what} must be integers; {live[bad].reshape(-1)[0]!r} is not one")
    elif kind == "u" and arr.size and arr.max() > _I64_MAX:
        raise InvalidInputError(f"{what} must fit in 64-bit signed integers; {arr.max()} does not")
    return arr.astype(np.int64), unset


# --------------------------------------------------------------------------
# Rows


def _sql(prop: Property, x: Any) -> Any:
    if prop.dtype == "bool":
        return int(x)
    if prop.dtype == "float64" and x != x:  # NaN: SQLite cannot store it
        return None
    return x


def rows(prop: Property, value: Any) -> list[tuple]:
    """The ``(part, v0, …)`` rows of one checked, non-None value."""
    flat = (value,) if not prop.shape else value
    w = _width(prop)
    out = []
    for part in range(parts(prop)):
        chunk = [_sql(prop, x) for x in flat[part * WIDTH : part * WIDTH + w]]
        out.append((part, *chunk, *([None] * (w - len(chunk)))))
    return out


def value_of(prop: Property, found: list[tuple]) -> Any:
    """The value stored in ``(part, v0, …)`` rows (any order), or the default when there are none."""
    if not found:
        return prop.default
    found = sorted(found, key=lambda r: r[0])
    flat = [x for r in found for x in r[1:]]
    if prop.dtype == "float64":
        flat = [math.nan if x is None else float(x) for x in flat]
    elif prop.dtype == "bool":
        flat = [bool(x) for x in flat]
    if not prop.shape:
        return flat[0]
    return tuple(flat[: prop.shape[0]])


def columns_of(prop: Property, ids: np.ndarray, data: np.ndarray) -> dict[str, np.ndarray]:
    """Whole value rows of many elements as columns: ``id``, ``part``, ``v0``, …

    ``data`` is `check_array`'s (without unset rows); NaN floats stay NaN
    (the writer stores them as NULL).
    """
    n = len(ids)
    if prop.dtype == "str":
        return {"id": ids, "part": np.zeros(n, dtype=np.int64), "v0": data}
    flat = data.reshape(n, prop.size or 1)
    if prop.dtype == "bool":
        flat = flat.astype(np.int64)
    k = flat.shape[1]
    w = _width(prop)
    count = parts(prop)
    out = {
        "id": np.repeat(ids, count),
        "part": np.tile(np.arange(count, dtype=np.int64), n),
    }
    padded = np.full((n, count * WIDTH), np.nan if prop.dtype == "float64" else 0, dtype=flat.dtype)
    padded[:, :k] = flat
    padded = padded.reshape(n * count, WIDTH)
    for c in range(w):
        out[f"v{c}"] = np.ascontiguousarray(padded[:, c])
    return out


def array_of(prop: Property, n: int, positions: np.ndarray, parts_: np.ndarray, components: list[np.ndarray]):
    """The ``(n,) + shape`` array of a property from its value rows.

    ``positions`` are the rows' element positions in ``range(n)`` (-1: an
    element that is not live; dropped), ``parts_`` their ``part``, and
    ``components`` the ``v0…`` columns (NaN where NULL). Elements without a
    row get the default; without a default the result is a masked array
    whose unset entries are masked.
    """
    shape = (n,) + prop.shape
    dtype = _NUMPY[prop.dtype]
    default = prop.default
    if prop.dtype == "str":
        out = np.empty(shape, dtype=object)
        out[...] = default
    else:
        fill = default if default is not None else (np.nan if prop.dtype == "float64" else 0)
        out = np.empty(shape, dtype=dtype)
        out[...] = fill
    keep = positions >= 0
    positions, parts_ = positions[keep], parts_[keep]
    components = [c[keep] for c in components]
    have = np.zeros(n, dtype=bool)
    have[positions] = True
    if prop.shape:
        k = prop.shape[0]
        for c, column in enumerate(components):
            index = parts_ * WIDTH + c
            ok = index < k
            out[positions[ok], index[ok]] = column[ok].astype(dtype, copy=False)
    elif components:
        out[positions] = components[0].astype(dtype, copy=False) if prop.dtype != "str" else components[0]
    if default is None:
        mask = np.broadcast_to(~have.reshape((n,) + (1,) * len(prop.shape)), shape)
        return np.ma.MaskedArray(out, mask=mask.copy())
    return out


# --------------------------------------------------------------------------
# Defaults, stored as JSON text in the catalogue


def mean(values: Sequence[float]) -> float:
    """The mean of floats: exactly rounded, and finite whenever they all are (the sum cannot overflow).

    Examples
    --------
    >>> mean([1.5e308, 1.5e308]), mean([1.0, 2.0, 6.0]), mean([1.0, float("inf")])
    (1.5e+308, 3.0, inf)
    """
    n = len(values)
    if all(math.isfinite(x) for x in values):
        try:
            return math.fsum(values) / n
        except OverflowError:
            return math.fsum(x / n for x in values)
    return sum(values) / n  # infinities and NaN as IEEE 754 has them


def dump_default(value: Any) -> str | None:
    """A checked default as the catalogue's JSON text (None: no default)."""
    return None if value is None else json.dumps(value)


def load_default(prop_shape: tuple, text: str | None) -> Any:
    """The default from the catalogue's JSON text."""
    if text is None:
        return None
    value = json.loads(text)
    return tuple(value) if prop_shape else value


def catalogue_columns() -> tuple:
    """The ``properties`` columns `property_of` takes, in its order."""
    p = schema.properties
    return (p.c.id, p.c.kind, p.c.name, p.c.dtype, p.c.size, p.c.default_value)


def property_of(id: int, kind: str, name: str, dtype: str, size: int | None, default_text: str | None) -> Property:
    """A `Property` from its catalogue row (`catalogue_columns`)."""
    shape = () if size is None else (int(size),)
    return Property(kind, name, dtype, shape, load_default(shape, default_text), int(id))
