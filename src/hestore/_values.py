"""A caller's values and property values: their checks, and their rows in SQL.

This module owns two things below the mesh.

The checks of every value a caller hands a public entry point (SPEC §10):
`check_real`, `check_integer`, `check_revision`, `check_flag`,
`check_choice`, `check_text`, `check_name`, `check_items`,
`check_arraylike` and `check_dtype` turn a number, a revision, a flag, an
option, a text, a name, a sequence, an array or a dtype into what hestore
works with — or raise `~hestore.errors.InvalidInputError`, before anything
is read or written. The caller's own conversions (a ``__float__``,
``__index__`` or ``__iter__`` that raises, an int too large for a float)
run inside them, so nothing but a typed error leaves, and messages quote
values with `hestore.errors.shown`, which never fails. (File paths are
`hestore.urls.check_path`'s: a bare database path is one.)

The vocabulary of element properties (SPEC §3.2): what a `Property` is,
which dtypes and shapes exist, how a value or an array is checked against a
property (strictly: never coerced loosely), and how values are laid out as
rows of `hestore.schema`'s value tables. It knows no database connection;
`hestore._persistence` writes the rows it makes and `hestore.properties`
reads them back through the session.

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
import operator
import unicodedata
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from hestore import schema
from hestore.errors import InvalidInputError, RevisionNotFoundError, shown

__all__ = [
    "check_real",
    "check_seconds",
    "check_integer",
    "check_revision",
    "check_flag",
    "check_choice",
    "check_text",
    "check_name",
    "check_items",
    "check_arraylike",
    "check_dtype",
    "MAX_NAME",
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

#: Element kinds a property can be declared on: every kind of `hestore.schema.KINDS`.
KINDS = tuple(schema.KINDS)
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

#: The longest mesh or property name, in characters.
MAX_NAME = 255
#: The numpy scalar types and Python types that name a dtype (`check_dtype`).
_DTYPE_OF_TYPE = {
    float: "float64", np.float64: "float64",
    int: "int64", np.int64: "int64",
    bool: "bool", np.bool_: "bool",
    str: "str", np.str_: "str",
}


# --------------------------------------------------------------------------
# A caller's values


def _failed(what: str, value: object, exc: Exception) -> InvalidInputError:
    """The refusal of a value whose own conversion raised ``exc`` (chain it as the cause)."""
    return InvalidInputError(f"{what}: converting the {type(value).__name__} given raised {type(exc).__name__}: {exc}")


def check_real(value: object, what: str) -> float:
    """``value`` as a float: a real number, never a bool, text, a complex number or a `decimal.Decimal`.

    Ints of any size, floats, `fractions.Fraction` and numpy's integer and
    floating scalars are real numbers. NaN and the infinities pass (callers
    that need finite numbers say so); a number beyond the float64 range does
    not. ``what`` names the value in the message.

    Raises
    ------
    InvalidInputError
        Not a real number, beyond the float64 range, or its ``__float__`` raised.

    Examples
    --------
    >>> check_real(3, "x"), check_real(np.float32(0.5), "x")
    (3.0, 0.5)
    >>> check_real(10**400, "x")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: x is beyond the float64 range: an int of 1329 bits
    >>> check_real(True, "x")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: x is a real number, not bool True
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InvalidInputError(f"{what} is a real number, not {type(value).__name__} {shown(value)}")
    try:
        return float(value)
    except OverflowError:
        raise InvalidInputError(f"{what} is beyond the float64 range: {shown(value)}") from None
    except Exception as exc:  # noqa: BLE001 - the caller's __float__ may raise anything
        raise _failed(what, value, exc) from exc


def check_seconds(value: object, what: str) -> float:
    """``value`` as a time to wait, in seconds: a real number, finite and ≥ 0 (`check_real`).

    Raises
    ------
    InvalidInputError
        Not a real number, negative, NaN or infinite.

    Examples
    --------
    >>> check_seconds(2, "busy_timeout")
    2.0
    >>> check_seconds(-1, "busy_timeout")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: busy_timeout must be a number of seconds ≥ 0, not -1
    """
    seconds = check_real(value, f"{what} (seconds)")
    if not 0 <= seconds < math.inf:
        raise InvalidInputError(f"{what} must be a number of seconds ≥ 0, not {shown(value)}")
    return seconds


def check_integer(value: object, what: str) -> int:
    """``value`` as an int: an integer of any size (numpy's too), never a bool, a float or text.

    Callers bound it: an id beyond 64 bits is no element's, a revision
    beyond them no revision.

    Raises
    ------
    InvalidInputError
        Not an integer, or its ``__index__`` raised.

    Examples
    --------
    >>> check_integer(np.uint64(2**64 - 1), "k")
    18446744073709551615
    >>> check_integer(2.0, "k")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: k is an integer, not float 2.0
    """
    if isinstance(value, (bool, np.bool_)):
        raise InvalidInputError(f"{what} is an integer, not {type(value).__name__} {shown(value)}")
    try:
        return operator.index(value)
    except TypeError:
        raise InvalidInputError(f"{what} is an integer, not {type(value).__name__} {shown(value)}") from None
    except Exception as exc:  # noqa: BLE001 - the caller's __index__ may raise anything
        raise _failed(what, value, exc) from exc


def check_revision(value: object, what: str = "revision") -> int:
    """``value`` as a revision number (`check_integer`); beyond 64 bits it is no revision there can be.

    Raises
    ------
    InvalidInputError
        Not an integer.
    RevisionNotFoundError
        Beyond the 64-bit range revisions are stored in.

    Examples
    --------
    >>> check_revision(np.int64(3))
    3
    >>> check_revision(2**64)
    Traceback (most recent call last):
    ...
    hestore.errors.RevisionNotFoundError: there is no revision 18446744073709551616: revisions are 64-bit integers
    """
    number = check_integer(value, f"a {what}")
    if not _I64_MIN <= number <= _I64_MAX:
        raise RevisionNotFoundError(f"there is no {what} {shown(number)}: revisions are 64-bit integers")
    return number


def check_flag(value: object, what: str) -> bool:
    """``value`` as a bool: True or False (numpy's too), never a number, text or None standing for one.

    Examples
    --------
    >>> check_flag(np.True_, "binary")
    True
    >>> check_flag(1, "binary")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: binary is True or False, not int 1
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise InvalidInputError(f"{what} is True or False, not {type(value).__name__} {shown(value)}")


def check_choice(value: object, options: Sequence[str], what: str) -> str:
    """The one of the strings ``options`` that ``value`` is (itself: a str subclass comes back a plain str).

    Only a str is compared with them: no caller's ``__eq__`` or
    ``__hash__`` runs.

    Examples
    --------
    >>> check_choice("skip", ("raise", "skip"), "on_error")
    'skip'
    >>> check_choice(["skip"], ("raise", "skip"), "on_error")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: on_error is one of 'raise', 'skip', not list ['skip']
    """
    if isinstance(value, str) and value in options:
        return options[list(options).index(value)]
    raise InvalidInputError(
        f"{what} is one of {', '.join(map(repr, options))}, not {type(value).__name__} {shown(value)}"
    )


def check_text(value: object, what: str) -> str:
    """``value`` if it is text SQL can hold: a str, valid Unicode (no lone surrogates), without NUL characters.

    Examples
    --------
    >>> check_text("été", "label")
    'été'
    >>> check_text("a\\x00b", "label")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: label cannot contain NUL characters: 'a\\x00b'
    """
    if not isinstance(value, str):
        raise InvalidInputError(f"{what} is text, not {type(value).__name__} {shown(value)}")
    if "\x00" in value:
        raise InvalidInputError(f"{what} cannot contain NUL characters: {shown(value)}")
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        raise InvalidInputError(f"{what} must be valid Unicode text (no lone surrogates): {shown(value)}") from None
    return value


def check_name(value: object, what: str) -> str:
    """``value`` if it can name a mesh or a property: text (`check_text`) with a visible character, at most
    `MAX_NAME` characters, and no control characters (newline, tab, …).

    Examples
    --------
    >>> check_name("bracket", "a mesh name")
    'bracket'
    >>> check_name("two\\nlines", "a mesh name")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: a mesh name cannot contain control characters (NUL, newline, ...): 'two\\nlines'
    """
    value = check_text(value, what)
    if not value.strip():
        raise InvalidInputError(f"{what} needs a visible character, not {shown(value)}")
    if len(value) > MAX_NAME:
        raise InvalidInputError(f"{what} has at most {MAX_NAME} characters, not {len(value)}")
    if any(unicodedata.category(c) == "Cc" for c in value):
        raise InvalidInputError(f"{what} cannot contain control characters (NUL, newline, ...): {shown(value)}")
    return value


def check_items(value: object, expected: str, *, ordered: bool = True) -> list:
    """The items of an iterable ``value``, as a list: never text, bytes or a mapping (nor a set, if ``ordered``).

    ``expected`` says what the value should be; the message is
    ``"{expected}, not …"``.

    Raises
    ------
    InvalidInputError
        ``value`` is not such an iterable, or iterating over it raised.

    Examples
    --------
    >>> check_items((1, 2, 3), "a position is three numbers")
    [1, 2, 3]
    >>> check_items("xyz", "a position is three numbers")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: a position is three numbers, not str 'xyz'
    """
    refused = (str, bytes, dict, set, frozenset) if ordered else (str, bytes, dict)
    if isinstance(value, refused) or not hasattr(value, "__iter__"):
        raise InvalidInputError(f"{expected}, not {type(value).__name__} {shown(value)}")
    try:
        return list(value)
    except Exception as exc:  # noqa: BLE001 - a 0-d array, or the caller's __iter__, may raise anything
        raise _failed(expected, value, exc) from exc


def check_arraylike(value: object, expected: str, dtype: Any = None) -> np.ndarray:
    """``value`` as a numpy array (of ``dtype``, if given): an array or a sequence, never text, bytes, a mapping
    or a set.

    The array is not checked further: its shape and dtype are the caller's
    to judge. ``expected`` says what the value should be.

    Raises
    ------
    InvalidInputError
        ``value`` is not array-like, or numpy could not make an array of it
        (ragged rows, items whose conversions raise).

    Examples
    --------
    >>> check_arraylike([[1, 2], [3, 4]], "positions must be an array").shape
    (2, 2)
    >>> check_arraylike([[1, 2], [3]], "positions must be an array", float)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: positions must be an array: converting the list given raised ValueError: ...
    """
    if isinstance(value, (str, bytes, dict, set, frozenset)) or not hasattr(value, "__len__"):
        raise InvalidInputError(f"{expected}, not {type(value).__name__}")
    try:
        return np.asarray(value, dtype=dtype)
    except Exception as exc:  # noqa: BLE001 - numpy runs the items' own conversions, which may raise anything
        raise _failed(expected, value, exc) from exc


def check_dtype(dtype: object, what: str = "a property") -> str:
    """A property dtype as its name in `DTYPES`, from the name itself or a numpy dtype or type numpy users write.

    ``np.dtype("float64")``, ``np.float64`` and ``float`` are ``"float64"``;
    ``np.dtype("int64")``, ``np.int64`` and ``int`` are ``"int64"``;
    ``np.dtype(bool)``, ``np.bool_`` and ``bool`` are ``"bool"``; ``str``,
    ``np.str_`` and a numpy unicode dtype (``np.dtype("U")``) are ``"str"``.
    Anything else — another width (``float32``), ``object``, ``complex``, an
    alias such as ``"f8"`` — is refused.

    Examples
    --------
    >>> check_dtype(np.dtype("float64")), check_dtype(np.int64), check_dtype(bool), check_dtype(np.dtype("U5"))
    ('float64', 'int64', 'bool', 'str')
    >>> check_dtype(np.float32)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: a property: dtypes are float64, int64, bool, str (or their numpy ...
    """
    if isinstance(dtype, str):
        found = DTYPES[DTYPES.index(dtype)] if dtype in DTYPES else None  # the plain str, not a subclass
    elif isinstance(dtype, np.dtype):
        found = _DTYPE_OF_TYPE.get(dtype.type)
    elif isinstance(dtype, type):
        found = _DTYPE_OF_TYPE.get(dtype)
    else:
        found = None
    if found is None:
        raise InvalidInputError(
            f"{what}: dtypes are {', '.join(DTYPES)} (or their numpy dtypes and Python types), "
            f"not {type(dtype).__name__} {shown(dtype)}"
        )
    return found


@dataclass(frozen=True)
class Property:
    """A declared property: what `Mesh.properties` lists.

    Attributes
    ----------
    kind : {"vertex", "halfedge", "edge", "polygon"}
    name : str
    dtype : {"float64", "int64", "bool", "str"}
        Always the name, whatever numpy dtype or type declared it (`check_dtype`).
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
    kind = check_choice(kind, KINDS, "a property's kind")
    name = check_name(name, "a property name")
    dtype = check_dtype(dtype, f"property {name!r}")
    if shape is None or (isinstance(shape, tuple) and not shape):
        return kind, name, dtype, ()
    if dtype not in ("float64", "int64"):
        raise InvalidInputError(f"property {name!r}: only float64 and int64 properties take a shape, not {dtype}")
    one = isinstance(shape, tuple) and len(shape) == 1
    k = check_integer(shape[0], f"property {name!r}: the k of shape (k,)") if one else 0
    if not 1 <= k <= 1024:
        raise InvalidInputError(f"property {name!r}: shape is () or (k,) with 1 <= k <= 1024, not {shown(shape)}")
    return kind, name, dtype, (k,)


def _scalar(prop: Property, value: object, where: str) -> Any:
    """One component, checked and converted to its Python type."""
    what = f"property {prop.name!r} of {where}"
    if prop.dtype == "bool":
        return check_flag(value, what)
    if prop.dtype == "str":
        return check_text(value, what)
    if prop.dtype == "float64":
        return check_real(value, what)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InvalidInputError(f"{what} is int64, not {type(value).__name__} {shown(value)}")
    if isinstance(value, numbers.Integral):
        i = check_integer(value, what)
    else:
        # A real number equal to an integer (3.0) is one: compared exactly, never through a float that
        # would round a large one (a Fraction) to a neighbour.
        try:
            i = int(value)
            exact = i == value
        except (ValueError, OverflowError):  # NaN, the infinities
            exact = False
        except Exception as exc:  # noqa: BLE001 - the caller's __int__ or __eq__ may raise anything
            raise _failed(what, value, exc) from exc
        if not exact:
            raise InvalidInputError(f"{what} is int64, not {type(value).__name__} {shown(value)}: not an integer")
    if not _I64_MIN <= i <= _I64_MAX:
        raise InvalidInputError(f"{what} is int64, not {shown(value)}: out of the 64-bit range")
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
    expected = f"property {prop.name!r} of {where} takes {prop.shape[0]} values"
    items = check_items(value, expected)
    if len(items) != prop.shape[0] or (isinstance(value, np.ndarray) and value.ndim != 1):
        raise InvalidInputError(f"{expected}, not {len(items)}: {shown(value)}")
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
    arr = check_arraylike(values, f"{what} must be an array", object if prop.dtype == "str" else None)
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
