"""Pictures of a mesh: `plot` draws it on a matplotlib Axes, `render` writes a PNG or SVG.

This module owns what a picture of a mesh shows and how it is drawn
(`Mesh.plot` and `Mesh.render` only delegate here, and ``hestore render``
calls them):

- polygons, flat-shaded by their normal against a fixed light (a planar mesh
  gets one uniform colour), their edges thin;
- the boundary loops as coloured polylines, one colour per loop;
- wire edges (no polygon on either side), isolated vertices as dots, and
  pinched vertices (where more than one polygon fan meets) as markers;
- the elements that `Mesh.check` names, in red, with a legend entry per
  picture naming the violated invariants;
- a note in the corner for what could not be drawn (vertices without a
  position, a skipped check, a rasterised mesh).

A 3-D mesh is seen orthographically from ``view`` (``"iso"`` by default;
``"top"``, ``"front"``, ... or ``(azimuth, elevation)`` in degrees), its
polygons sorted back to front (the painter's algorithm); a planar mesh is
seen straight on. Everything is set-based: the mesh is read in one snapshot
through its session, projected, shaded and sorted with numpy, and each layer
is one matplotlib artist (a `PolyCollection`, a `LineCollection`, a scatter),
never one artist per element. Above ``max_polygons`` polygons (200,000 by
default) the polygons are rasterised instead: triangulated into fans, every
pixel centre of the Axes inside a triangle is found with numpy, the nearest
triangle per pixel wins (a z-buffer), and the shaded image is shown with
``imshow`` — time and memory grow with the mesh plus the pixels, not with
what a vector backend would have to draw; the edges are then not drawn. The
highlights stay vectors on top.

matplotlib is optional (``pip install "hestore[plot]"``); without it these
calls raise `MissingDependencyError`. It is imported when a picture is
drawn, never by ``import hestore``.

Examples
--------
>>> from hestore._session import identity
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> import hestore
>>> store = hestore.open("sqlite://")
>>> square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
>>> mesh = store.import_arrays("square", square, [[0, 1, 2], [0, 2, 3]]).mesh
>>> ax = plot(identity(mesh))
>>> sorted(c.get_gid() for c in ax.collections)
['boundary_loops', 'polygons']
>>> len(ax.collections[0].get_paths())
2
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from hestore import schema, summary, validation
from hestore.arrays import Index, dense, polygon_halfedges, positions as position_array, restricted_cycles
from hestore._columns import position_request, request
from hestore.errors import InvalidInputError, Violation, require, shown
from hestore.io import file_errors
from hestore.progress import check_progress
from hestore.urls import check_path
from hestore._values import check_choice, check_flag, check_integer, check_items, check_real
from hestore._session import MeshRef

__all__ = [
    "VIEWS", "FORMATS", "MAX_POLYGONS", "CHECK_POLYGONS", "MAX_SIDE", "MAX_PIXELS", "DPI", "LABEL_VERTICES", "LAYERS",
    "plot", "render",
]

#: Named views: the direction from the mesh towards the viewer.
VIEWS = {
    "iso": (1.0, -1.0, 1.0),
    "top": (0.0, 0.0, 1.0),
    "bottom": (0.0, 0.0, -1.0),
    "front": (0.0, -1.0, 0.0),
    "back": (0.0, 1.0, 0.0),
    "right": (1.0, 0.0, 0.0),
    "left": (-1.0, 0.0, 0.0),
}

#: File formats `render` writes, by suffix.
FORMATS = {".png": "png", ".svg": "svg"}

#: Above this many polygons `plot` rasterises them (see the module docstring).
MAX_POLYGONS = 200_000

#: ``check=None`` runs `Mesh.check` up to this many polygons (it reads the whole mesh a second time).
CHECK_POLYGONS = 200_000

#: The longest side of a picture `render` draws, in pixels.
MAX_SIDE = 10_000

#: The most pixels a picture `render` draws has (40 Mpx: 160 MB of RGBA for matplotlib to draw into, and
#: several times that while it encodes a PNG), refused before anything is drawn or allocated.
MAX_PIXELS = 40_000_000

#: The dots per inch `render` takes, least and most: below, matplotlib cannot draw small text.
DPI = (10, 10_000)

#: ``labels=True`` labels at most this many vertices (one text artist each); above, a note says so.
LABEL_VERTICES = 2_000

#: The ``gid`` of each artist `plot` may draw, one artist per layer.
LAYERS = (
    "polygons",
    "raster",
    "wire_edges",
    "boundary_loops",
    "isolated_vertices",
    "pinched_vertices",
    "violations",
    "labels",
    "halfedge_labels",
    "notes",
)

#: ``progress(stage, done, total)``; stages ``"read"``, ``"check"``, ``"draw"``, ``"write"``.
Progress = Callable[[str, int, int], None]

_FACE = np.array([0.70, 0.77, 0.87])
_EDGE = (0.18, 0.20, 0.25, 1.0)
_WIRE = (0.90, 0.45, 0.00, 1.0)
_PINCHED = (0.80, 0.00, 0.80, 1.0)
_ISOLATED = (0.10, 0.10, 0.10, 1.0)
_VIOLATION = (1.0, 0.0, 0.0, 1.0)
#: tab10 colours for boundary loops: not the orange, red and pink of the other highlights.
_LOOP_COLOURS = (0, 2, 4, 9, 5, 7, 8)
#: Candidate pixels tested per rasterisation step: bounds the memory of a large picture.
_RASTER_CHUNK = 1_000_000
#: Largest raster side, in pixels, whatever the Axes' size.
_RASTER_SIDE = 4096


def _require() -> Any:
    """matplotlib (with the parts drawing uses), or `MissingDependencyError` saying how to install it."""
    mpl = require("matplotlib", "plot")
    for part in ("matplotlib.collections", "matplotlib.axes"):
        require(part, "plot")
    return mpl


# --------------------------------------------------------------------------
# Reading


@dataclass(frozen=True)
class _Scene:
    """What a picture needs, read in one snapshot; references as rows, -1 where they name nothing."""

    v_id: np.ndarray
    xyz: np.ndarray  # (V, 3), NaN rows for vertices without a position
    he_id: np.ndarray
    origin: np.ndarray  # vertex row of each half-edge's origin
    target: np.ndarray  # vertex row of each half-edge's target (its twin's origin)
    free: np.ndarray
    next: np.ndarray  # half-edge row
    twin: np.ndarray  # half-edge row
    p_id: np.ndarray
    corners: np.ndarray  # vertex rows of each polygon's corners, polygon after polygon
    offsets: np.ndarray  # polygon i's corners are corners[offsets[i]:offsets[i + 1]]
    revision: int  # the revision the snapshot read


def _read(ref: MeshRef) -> _Scene:
    # The half-edges' polygon column is not read: the polygon loops walked from the polygons' half-edges
    # are exactly the half-edges that have one (on a valid mesh; `check` reports any other), and reading a
    # column of a few million rows costs more than the walk. The edges table is read only for violations.
    with ref.session.snapshot(ref) as snap:
        (v_id, x, y, z, missing), (he_id, origin, nxt, twin), (p_id, p_he) = snap.columns(
            [position_request(), request("halfedges", "origin", "next", "twin"), request("polygons", "halfedge")]
        )
        revision = snap.revision
    vertices, halfedges = Index(v_id), Index(he_id)
    origin_row = vertices.get(origin)
    twin_row = halfedges.get(twin)
    next_row = halfedges.get(nxt)
    # A dangling reference (a corrupted table, which `check` reports) must not stop the picture.
    target_row = np.where(twin_row >= 0, origin_row[np.maximum(twin_row, 0)], -1)
    loops = polygon_halfedges(he_id, nxt, p_he) if len(p_id) else None
    corners = origin_row[loops.indices] if loops is not None else np.zeros(0, dtype=np.int64)
    offsets = loops.offsets if loops is not None else np.zeros(1, dtype=np.int64)
    free = np.ones(len(he_id), dtype=bool)
    if loops is not None:
        free[loops.indices] = False
    return _Scene(
        v_id, position_array(x, y, z, missing), he_id, origin_row, target_row, free, next_row, twin_row,
        p_id, corners, offsets, revision,
    )


# --------------------------------------------------------------------------
# Geometry


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _toward(view: object) -> np.ndarray:
    """The unit direction from the mesh towards the viewer."""
    if isinstance(view, str):
        if view not in VIEWS:
            raise InvalidInputError(f"unknown view {view!r}: use one of {', '.join(VIEWS)} or (azimuth, elevation)")
        return _unit(np.array(VIEWS[view]))
    expected = f"view must be one of {', '.join(VIEWS)} or (azimuth, elevation) in degrees"
    angles = check_items(view, expected)
    if len(angles) != 2:
        raise InvalidInputError(f"{expected}, not {shown(view)}")
    azimuth, elevation = (check_real(a, "a view angle") for a in angles)
    if not (math.isfinite(azimuth) and math.isfinite(elevation)):
        raise InvalidInputError(f"view angles must be finite, not {shown(view)}")
    a, e = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def _camera(toward: np.ndarray) -> np.ndarray:
    """Rows: screen right, screen up, toward the viewer (world z stays up unless looking along it)."""
    hint = np.array([0.0, 1.0, 0.0]) if abs(toward[2]) > 0.999 else np.array([0.0, 0.0, 1.0])
    right = _unit(np.cross(hint, toward))
    return np.stack([right, np.cross(toward, right), toward])


def _plane_normal(placed: np.ndarray) -> np.ndarray | None:
    """The normal of the plane every placed vertex lies in, or None when they do not lie in one."""
    if len(placed) < 3:
        return None
    centred = placed - placed.mean(axis=0)
    values, vectors = np.linalg.eigh(centred.T @ centred)
    if values[-1] <= 0 or values[0] > 1e-12 * values[-1]:
        return None
    normal = vectors[:, 0]
    # Seen from the side the normal's largest component points to, so z-up planes are seen from above.
    return normal if normal[np.argmax(np.abs(normal))] > 0 else -normal


def _normals(xyz: np.ndarray, corners: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Each polygon's area vector (Newell's method), from its corner loop."""
    if len(offsets) < 2:
        return np.zeros((0, 3))
    degree = np.diff(offsets)
    owner = np.repeat(np.arange(len(degree)), degree)
    step = np.arange(len(corners)) + 1
    last = offsets[1:] - 1
    step[last] = offsets[:-1]
    a, b = xyz[corners], xyz[corners[step]]
    return np.stack([np.bincount(owner, weights=w, minlength=len(degree)) for w in np.cross(a, b).T], axis=1)


# --------------------------------------------------------------------------
# Drawing


def plot(
    ref: MeshRef,
    ax: Any = None,
    *,
    view: object = None,
    labels: bool | str = False,
    check: bool | None = None,
    max_polygons: int = MAX_POLYGONS,
    progress: Progress | None = None,
) -> Any:
    """Draw a mesh on a matplotlib Axes: shaded polygons, edges, boundary loops and every problem.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh, or a view of a past revision (`Mesh.at`): its identity (`hestore._session.identity`).
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new figure's Axes (through ``pyplot``) when None.
    view : str or (float, float), optional
        ``"iso"``, ``"top"``, ``"bottom"``, ``"front"``, ``"back"``,
        ``"left"``, ``"right"`` (see `VIEWS`), or ``(azimuth, elevation)`` in
        degrees as in matplotlib's 3-D Axes. Default: straight on for a
        planar mesh, else ``"iso"``.
    labels : bool or {"vertices", "halfedges", "all"}
        Write ids: each vertex's beside it (True or ``"vertices"``), each
        half-edge's on an arrow from its origin to its target along its left
        side, where its polygon is (``"halfedges"``), or both (``"all"``); up
        to `LABEL_VERTICES` of each.
    check : bool or None
        Run `Mesh.check` and draw what it names in red; None (the default)
        checks meshes of up to `CHECK_POLYGONS` polygons and notes the skip
        above.
    max_polygons : int
        Above this many polygons they are rasterised, and their edges are not drawn.
    progress : callable, optional
        ``progress(stage, done, total)``, as in `hestore.progress.ProgressBar`.

    Returns
    -------
    matplotlib.axes.Axes
        The Axes, with one artist per layer, each with its `LAYERS` name as
        ``gid`` and the highlights in the legend.

    Raises
    ------
    MissingDependencyError
        matplotlib is not installed.
    InvalidInputError
        ``ax`` is not an Axes, or ``view``, ``labels``, ``check``, ``max_polygons`` or ``progress`` is malformed.
    RevisionNotFoundError, MeshNotFoundError
        The mesh (or the revision it shows) is gone.

    Examples
    --------
    A triangle with a wire edge hanging off a corner:

    >>> from hestore._session import identity
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    >>> _ = mesh.add_edge(mesh.vertex(1), mesh.add_vertex((2, 0, 0)))
    >>> ax = plot(identity(mesh), labels=True)
    >>> sorted(c.get_gid() for c in ax.collections)
    ['boundary_loops', 'polygons', 'wire_edges']
    >>> sorted(t.get_text() for t in ax.texts if t.get_gid() == "labels")
    ['0', '1', '2', '3']
    """
    return _draw(ref, ax, view=view, labels=labels, check=check, max_polygons=max_polygons, progress=progress)[0]


def _draw(
    ref: MeshRef, ax: Any = None, *, view: object = None, labels: bool | str = False, check: bool | None = None,
    max_polygons: int = MAX_POLYGONS, progress: Progress | None = None,
) -> tuple[Any, _Scene]:
    """`plot`, returning the Axes and the scene it drew (what `render`'s title counts)."""
    mpl = _require()
    from matplotlib.axes import Axes

    if ax is not None and not isinstance(ax, Axes):
        raise InvalidInputError(f"ax must be a matplotlib Axes, not {type(ax).__name__}")
    if check_integer(max_polygons, "max_polygons") < 0:
        raise InvalidInputError(f"max_polygons must be an int of at least 0, not {shown(max_polygons)}")
    if isinstance(labels, str):
        labels = check_choice(labels, [k for k in _LABELS if isinstance(k, str)], "labels (or True, False)")
    else:
        labels = check_flag(labels, "labels (or 'vertices', 'halfedges', 'all')")
    if check is not None:
        check = check_flag(check, "check (or None)")
    toward = None if view is None else _toward(view)
    report = check_progress(progress)
    report("read", 0, 1)
    scene = _read(ref)
    report("read", 1, 1)
    notes: list[str] = []
    violations: list[Violation] = []
    if check is None:
        check = len(scene.p_id) <= CHECK_POLYGONS
        if not check:
            notes.append(f"not checked ({len(scene.p_id):,} polygons; check=True checks)")
    if check:
        report("check", 0, 1)
        violations = validation.check(ref)
        report("check", 1, 1)

    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(8, 6))
    placed = ~np.isnan(scene.xyz).any(axis=1)
    if not placed.all():
        notes.append(f"{int((~placed).sum()):,} of {len(placed):,} vertices have no position: not drawn")
    planar = None
    if toward is None:
        planar = _plane_normal(scene.xyz[placed])
        toward = _unit(np.array(VIEWS["iso"])) if planar is None else planar
    elif placed.any():
        planar = _plane_normal(scene.xyz[placed])
    camera = _camera(toward)
    screen = scene.xyz @ camera.T  # x, y on screen, depth (larger is nearer)
    light = _unit(camera[2] + 0.6 * camera[1] - 0.4 * camera[0])

    pixels_per_unit = 1.0
    if placed.any():
        lo, hi = screen[placed, :2].min(axis=0), screen[placed, :2].max(axis=0)
        pad = 0.04 * max(float((hi - lo).max()), 1e-9)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        # What one unit of the mesh spans on the Axes once its aspect is equal: the raster's resolution.
        box = ax.get_window_extent()
        pixels_per_unit = min(box.width / (hi[0] - lo[0] + 2 * pad), box.height / (hi[1] - lo[1] + 2 * pad))
    elif not len(scene.v_id):
        notes.append("the mesh is empty")
    _polygons(mpl, ax, scene, screen, placed, light, planar is not None, max_polygons, pixels_per_unit, notes, report)
    handles = _highlights(mpl, ax, ref, scene, screen, placed, violations)
    if _LABELS[labels] & {"vertices"}:
        _labels(ax, scene, screen, placed, notes)
    if _LABELS[labels] & {"halfedges"}:
        _halfedge_labels(ax, scene, screen, placed, notes)
    ax.set_aspect("equal")
    ax.set_axis_off()
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize="small", framealpha=0.8)
    if notes:
        ax.text(0.01, 0.01, "\n".join(notes), transform=ax.transAxes, fontsize="x-small", va="bottom",
                color="0.3", gid="notes")
    return ax, scene


def _polygons(
    mpl, ax, scene: _Scene, screen, placed, light, planar: bool, max_polygons: int, pixels_per_unit: float, notes,
    report,
) -> None:
    """The polygons, shaded, as one PolyCollection (their edges its edges) or one raster image."""
    degree = np.diff(scene.offsets)
    if not len(degree):
        return
    corner_placed = placed[scene.corners] if len(scene.corners) else np.zeros(0, dtype=bool)
    whole = np.bincount(np.repeat(np.arange(len(degree)), degree), weights=~corner_placed, minlength=len(degree)) == 0
    shown = np.flatnonzero(whole)
    if not len(shown):
        return
    if planar:
        shade = np.ones(len(degree))
    else:
        normals = _normals(np.where(placed[:, None], scene.xyz, 0.0), scene.corners, scene.offsets)
        length = np.linalg.norm(normals, axis=1)
        # Two-sided: an open mesh shows its back faces, lit like its front.
        cosine = np.abs(normals @ light) / np.where(length > 0, length, 1.0)
        shade = np.where(length > 0, 0.3 + 0.7 * cosine, 0.6)
    colours = np.column_stack([np.clip(shade[:, None] * _FACE, 0, 1), np.ones(len(degree))])
    if len(shown) > max_polygons:
        _raster(ax, scene, screen, shown, colours, pixels_per_unit, report)
        notes.append(f"{len(shown):,} polygons drawn as a raster (more than max_polygons={max_polygons:,}); "
                     "edges not drawn")
        return
    report("draw", 0, 1)
    depth = np.bincount(np.repeat(np.arange(len(degree)), degree), weights=screen[scene.corners, 2],
                        minlength=len(degree)) / np.maximum(degree, 1)
    order = shown[np.argsort(depth[shown], kind="stable")]  # far first: the painter's algorithm
    sizes = degree[order]
    if (sizes == sizes[0]).all():
        starts = scene.offsets[order]
        verts = screen[scene.corners[starts[:, None] + np.arange(sizes[0])], :2]
    else:
        xy = screen[scene.corners, :2]
        verts = [xy[a:a + k] for a, k in zip(scene.offsets[order].tolist(), sizes.tolist())]
    width = 0.6 if len(order) <= 2_000 else 0.3 if len(order) <= 20_000 else 0.0
    collection = mpl.collections.PolyCollection(
        verts, facecolors=colours[order], edgecolors=_EDGE, linewidths=width, gid="polygons", zorder=1
    )
    ax.add_collection(collection)
    report("draw", 1, 1)


def _raster(ax, scene: _Scene, screen, shown, colours, pixels_per_unit: float, report) -> None:
    """Rasterise the polygons (fans of triangles) with a z-buffer at the Axes' pixel size; show the image."""
    degree = np.diff(scene.offsets)[shown]
    first = scene.offsets[shown]
    # Triangle j of a polygon: its first corner, corner j + 1, corner j + 2.
    fans = np.maximum(degree - 2, 0)
    owner = np.repeat(np.arange(len(shown)), fans)
    j = np.arange(len(owner)) - np.repeat(np.cumsum(fans) - fans, fans)
    base = first[owner]
    tri = np.stack([scene.corners[base], scene.corners[base + j + 1], scene.corners[base + j + 2]], axis=1)
    colour = colours[shown[owner]]
    if not len(tri):  # only 1-gons and 2-gons: nothing has an area
        return
    xy = screen[:, :2]
    lo, hi = xy[tri].min(axis=(0, 1)), xy[tri].max(axis=(0, 1))
    span = np.maximum(hi - lo, 1e-12)
    scale = min(pixels_per_unit, _RASTER_SIDE / span.max())
    width, height = (max(int(math.ceil(s * scale)), 1) for s in span)
    px = (xy - lo) * scale  # pixel (i, j) covers [i, i + 1) x [j, j + 1)
    depth_buffer = np.full(width * height, -np.inf)
    winner = np.full(width * height, -1, dtype=np.int64)
    a, b, c = px[tri[:, 0]], px[tri[:, 1]], px[tri[:, 2]]
    x0 = np.clip(np.ceil(np.minimum(np.minimum(a[:, 0], b[:, 0]), c[:, 0]) - 0.5), 0, width).astype(np.int64)
    x1 = np.clip(np.floor(np.maximum(np.maximum(a[:, 0], b[:, 0]), c[:, 0]) - 0.5), -1, width - 1).astype(np.int64)
    y0 = np.clip(np.ceil(np.minimum(np.minimum(a[:, 1], b[:, 1]), c[:, 1]) - 0.5), 0, height).astype(np.int64)
    y1 = np.clip(np.floor(np.maximum(np.maximum(a[:, 1], b[:, 1]), c[:, 1]) - 0.5), -1, height - 1).astype(np.int64)
    w, h = np.maximum(x1 - x0 + 1, 0), np.maximum(y1 - y0 + 1, 0)
    count = w * h
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    todo = np.flatnonzero((count > 0) & (area != 0))
    ends = np.cumsum(count[todo])
    # Chunks of triangles with at most _RASTER_CHUNK candidate pixels each (a bigger triangle alone).
    cuts = np.unique(np.r_[0, np.searchsorted(ends, np.arange(_RASTER_CHUNK, ends[-1] if len(ends) else 0,
                                                                   _RASTER_CHUNK), side="right"), len(todo)])
    depth = screen[:, 2]
    for k, (s, t) in enumerate(zip(cuts[:-1].tolist(), cuts[1:].tolist())):
        report("draw", k, len(cuts) - 1)
        part = todo[s:t]
        n = count[part]
        which = np.repeat(part, n)
        local = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        ix = x0[which] + local % w[which]
        iy = y0[which] + local // w[which]
        cx, cy = ix + 0.5, iy + 0.5
        pa, pb, pc = a[which], b[which], c[which]
        # Barycentric weights of the pixel centre; inside when all are >= 0 (either winding).
        wa = ((pb[:, 0] - cx) * (pc[:, 1] - cy) - (pb[:, 1] - cy) * (pc[:, 0] - cx)) / area[which]
        wb = ((pc[:, 0] - cx) * (pa[:, 1] - cy) - (pc[:, 1] - cy) * (pa[:, 0] - cx)) / area[which]
        wc = 1.0 - wa - wb
        inside = (wa >= 0) & (wb >= 0) & (wc >= 0)
        which, wa, wb, wc = which[inside], wa[inside], wb[inside], wc[inside]
        pixel = (iy[inside] * width + ix[inside]).astype(np.int64)
        z = wa * depth[tri[which, 0]] + wb * depth[tri[which, 1]] + wc * depth[tri[which, 2]]
        np.maximum.at(depth_buffer, pixel, z)
        win = z >= depth_buffer[pixel]
        winner[pixel[win]] = which[win]
    report("draw", len(cuts) - 1, len(cuts) - 1)
    image = np.zeros((width * height, 4))
    hit = winner >= 0
    image[hit] = colour[winner[hit]]
    ax.imshow(image.reshape(height, width, 4), origin="lower", interpolation="nearest", zorder=1,
              extent=(lo[0], lo[0] + width / scale, lo[1], lo[1] + height / scale), gid="raster")


def _segments(screen, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    return np.stack([screen[start, :2], screen[end, :2]], axis=1)


def _highlights(mpl, ax, ref: MeshRef, scene: _Scene, screen, placed, violations: list[Violation]) -> list:
    """Boundary loops, wire edges, isolated and pinched vertices, violations: one artist each; legend handles."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = []
    LineCollection = mpl.collections.LineCollection
    ends_ok = (scene.origin >= 0) & (scene.target >= 0)
    ends_placed = ends_ok.copy()
    ends_placed[ends_ok] = placed[scene.origin[ends_ok]] & placed[scene.target[ends_ok]]
    twin_free = np.zeros(len(scene.free), dtype=bool)
    twin_ok = scene.twin >= 0
    twin_free[twin_ok] = scene.free[scene.twin[twin_ok]]
    rows = np.arange(len(scene.free))

    wire = np.flatnonzero(scene.free & twin_free & (rows < scene.twin) & ends_placed)
    if len(wire):
        ax.add_collection(LineCollection(_segments(screen, scene.origin[wire], scene.target[wire]), colors=[_WIRE],
                                         linewidths=1.5, gid="wire_edges", zorder=3))
        handles.append(Line2D([], [], color=_WIRE, lw=1.5, label=f"wire edges ({len(wire):,})"))

    boundary = scene.free & ~twin_free & twin_ok
    if boundary.any():
        loop = _loop_labels(scene.free, scene.next)
        shown = np.flatnonzero(boundary & ends_placed)
        loops = dense(loop[np.flatnonzero(boundary)])[1]
        palette = [mpl.colormaps["tab10"].colors[i] for i in _LOOP_COLOURS]
        colour_of = dense(loop[shown])[0] % len(palette)
        ax.add_collection(LineCollection(_segments(screen, scene.origin[shown], scene.target[shown]),
                                         colors=np.asarray(palette)[colour_of], linewidths=2.0,
                                         gid="boundary_loops", zorder=3))
        handles.append(Line2D([], [], color=palette[0], lw=2.0, label=f"boundary loops ({loops:,})"))

    valid_origin = scene.origin[scene.origin >= 0]
    out_degree = np.bincount(valid_origin, minlength=len(scene.v_id))
    isolated = np.flatnonzero((out_degree == 0) & placed)
    if len(isolated):
        ax.scatter(screen[isolated, 0], screen[isolated, 1], s=12, color=[_ISOLATED], gid="isolated_vertices",
                   zorder=4)
        handles.append(Line2D([], [], color=_ISOLATED, marker="o", ls="", ms=4,
                              label=f"isolated vertices ({len(isolated):,})"))

    if ends_ok.all() and twin_ok.all():  # fan counting needs every reference; check() says what is wrong
        pinched = np.flatnonzero(summary.fan_counts(scene.origin, scene.twin, scene.free, out_degree) > 1)
        shown = pinched[placed[pinched]]
        if len(pinched):
            ax.scatter(screen[shown, 0], screen[shown, 1], s=50, marker="D", facecolors="none",
                       edgecolors=[_PINCHED], linewidths=1.5, gid="pinched_vertices", zorder=5)
            handles.append(Line2D([], [], color=_PINCHED, marker="D", ls="", ms=6, mfc="none",
                                  label=f"pinched vertices ({len(pinched):,})"))

    if violations:
        _violations(mpl, ax, ref, scene, screen, placed, ends_placed, violations)
        codes = sorted({v.code for v in violations})
        handles.append(Patch(color=_VIOLATION, label=f"check(): {len(violations):,} violation(s): {', '.join(codes)}"))
    return handles


def _loop_labels(free: np.ndarray, nxt: np.ndarray) -> np.ndarray:
    """For each half-edge, the smallest free half-edge row on its cycle of ``next`` (meaningful for free ones).

    A free half-edge whose ``next`` is missing or not free (only in a corrupted table) ends its walk there.
    """
    label = np.full(len(free), -1, dtype=np.int64)
    rows, _, smallest, _, _ = restricted_cycles(np.where(nxt >= 0, nxt, np.arange(len(nxt))), np.where(free, 0, -1))
    label[rows] = rows[smallest]
    return label


def _violations(
    mpl, ax, ref: MeshRef, scene: _Scene, screen, placed, ends_placed, violations: list[Violation]
) -> None:
    """The elements the violations name, in red, as one collection (polygons, lines and points in one path set)."""
    ids: dict[str, list[int]] = {kind: [] for kind in schema.KINDS}
    for v in violations:
        if v.kind in ids and v.ids:
            ids[v.kind].append(v.ids[0])

    def found(table_ids: np.ndarray, wanted: list[int]) -> np.ndarray:
        rows = Index(table_ids).get(np.array(wanted, dtype=np.int64))
        return np.unique(rows[rows >= 0])

    halfedges = found(scene.he_id, ids["halfedge"])
    edge_halfedges = np.zeros(0, dtype=np.int64)
    if ids["edge"]:
        with ref.session.snapshot(ref) as snap:
            [(e_id, e_halfedge)] = snap.columns([request("edges", "halfedge")])
        edge_halfedges = Index(scene.he_id).get(e_halfedge[found(e_id, ids["edge"])])
    lines = np.unique(np.r_[halfedges, edge_halfedges[edge_halfedges >= 0]]).astype(np.int64)
    lines = lines[ends_placed[lines]]
    paths = list(_segments(screen, scene.origin[lines], scene.target[lines]))
    for p in found(scene.p_id, ids["polygon"]).tolist():
        corners = scene.corners[scene.offsets[p]:scene.offsets[p + 1]]
        if len(corners) and placed[corners].all():
            paths.append(screen[np.r_[corners, corners[:1]], :2])
    vertices = found(scene.v_id, ids["vertex"])
    vertices = vertices[placed[vertices]]
    if paths:
        ax.add_collection(mpl.collections.LineCollection(paths, colors=[_VIOLATION], linewidths=2.5,
                                                         gid="violations", zorder=6))
    if len(vertices):
        ax.scatter(screen[vertices, 0], screen[vertices, 1], s=80, marker="X", color=[_VIOLATION],
                   gid="violations", zorder=6)


#: What each value of ``labels`` writes.
_LABELS = {False: frozenset(), True: frozenset({"vertices"}), "vertices": frozenset({"vertices"}),
           "halfedges": frozenset({"halfedges"}), "all": frozenset({"vertices", "halfedges"})}


def _halfedge_labels(ax, scene: _Scene, screen, placed, notes: list[str]) -> None:
    """An arrow per half-edge, origin to target, beside its edge on its left (its polygon's side), with its id."""
    rows = np.flatnonzero(placed[scene.origin] & placed[scene.target] & (scene.origin != scene.target))
    if len(rows) > LABEL_VERTICES:
        notes.append(f"half-edge labels left out: {len(rows):,} half-edges (at most {LABEL_VERTICES:,})")
        return
    a, b = screen[scene.origin[rows], :2], screen[scene.target[rows], :2]
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])[:, None]
    keep = length[:, 0] > 0
    rows, a, d, length = rows[keep], a[keep], d[keep], length[keep]
    left = np.column_stack([-d[:, 1], d[:, 0]]) / length
    # A fixed share of each edge: the twins' arrows sit on either side, apart, and clear of the corners.
    shift = left * (0.07 * length)
    start, end = a + 0.2 * d + shift, a + 0.8 * d + shift
    arrows = ax.quiver(start[:, 0], start[:, 1], (end - start)[:, 0], (end - start)[:, 1], angles="xy",
                       scale_units="xy", scale=1, width=0.003, headwidth=4, headlength=5, color="0.25", zorder=7)
    arrows.set_gid("halfedge_labels")
    middle = a + 0.5 * d + 2.2 * shift
    for r, m in zip(rows.tolist(), middle):
        ax.text(m[0], m[1], str(int(scene.he_id[r])), fontsize="xx-small", color="0.25", ha="center",
                va="center", gid="halfedge_labels", zorder=7)


def _labels(ax, scene: _Scene, screen, placed, notes: list[str]) -> None:
    rows = np.flatnonzero(placed)
    if len(rows) > LABEL_VERTICES:
        notes.append(f"vertex labels left out: {len(rows):,} vertices (at most {LABEL_VERTICES:,})")
        return
    for r in rows.tolist():
        ax.annotate(str(int(scene.v_id[r])), screen[r, :2], xytext=(3, 3), textcoords="offset points",
                    fontsize="x-small", color="0.1", gid="labels", zorder=7)


# --------------------------------------------------------------------------
# Files


def _format(path: str) -> str:
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in FORMATS:
        raise InvalidInputError(f"cannot render to {path!r}: the file name must end in {' or '.join(FORMATS)}")
    return FORMATS[suffix]


def _pixels(size: object, dpi: object) -> tuple[int, int, int]:
    """``(width, height, dpi)`` checked: whole pixels, at most `MAX_SIDE` a side and `MAX_PIXELS` in all, and a
    dpi at which matplotlib can draw text."""
    sides = [check_integer(side, "a side of size") for side in check_items(size, "size is (width, height) in pixels")]
    dots = check_integer(dpi, "dpi")
    if (
        len(sides) != 2
        or not all(1 <= side <= MAX_SIDE for side in sides)
        or sides[0] * sides[1] > MAX_PIXELS
        or not DPI[0] <= dots <= DPI[1]
    ):
        raise InvalidInputError(
            f"size must be (width, height) with each side 1 to {MAX_SIDE:,} pixels and at most {MAX_PIXELS:,} "
            f"pixels in all, and dpi {DPI[0]} to {DPI[1]:,}; not size={shown(size)}, dpi={shown(dpi)}"
        )
    return sides[0], sides[1], dots


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def render(
    ref: MeshRef,
    path,
    *,
    size: tuple[int, int] = (1200, 900),
    dpi: int = 100,
    title: bool = True,
    progress: Progress | None = None,
    **options: Any,
) -> None:
    """Write a picture of a mesh (`plot`) to a PNG or SVG file, chosen by the suffix.

    The picture is written to a temporary file beside ``path`` and renamed
    over it, so ``path`` is either the whole new picture or as it was.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh, or a view of a past revision (`Mesh.at`): its identity (`hestore._session.identity`).
    path : str or os.PathLike
        Ends in ``.png`` or ``.svg``; its folder must exist.
    size : (int, int)
        Width and height in pixels (at ``dpi``), each 1 to `MAX_SIDE` (10,000), and at most `MAX_PIXELS`
        (40,000,000) in all.
    dpi : int
        Dots per inch of the figure, within `DPI`.
    title : bool
        Name the mesh, its revision and its counts above the picture.
    progress : callable, optional
        ``progress(stage, done, total)``; stages ``read``, ``check``, ``draw``, ``write``.
    **options
        `plot`'s ``view``, ``labels``, ``check``, ``max_polygons``.

    Raises
    ------
    InvalidInputError
        The suffix is neither ``.png`` nor ``.svg``, the folder does not
        exist, the file cannot be written, or an option is malformed.
    MissingDependencyError
        matplotlib is not installed.

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore, os, tempfile
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    >>> path = os.path.join(tempfile.mkdtemp(), "t.png")
    >>> render(identity(mesh), path, size=(200, 150))
    >>> open(path, "rb").read(8) == b"\\x89PNG\\r\\n\\x1a\\n"
    True
    >>> render(identity(mesh), path[:-4] + ".jpg")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: cannot render to '...t.jpg': the file name must end in .png or .svg
    """
    path = check_path(path)
    fmt = _format(path)
    target = os.path.abspath(path)
    folder = os.path.dirname(target)
    if not os.path.isdir(folder):
        raise InvalidInputError(f"cannot write {target}: the folder {folder} does not exist")
    if os.path.isdir(target):
        raise InvalidInputError(f"cannot write {target}: it is a folder")
    width, height, dpi = _pixels(size, dpi)
    title = check_flag(title, "title")
    report = check_progress(progress)
    _require()
    from matplotlib.figure import Figure

    # A Figure without pyplot: no global state, no GUI backend, nothing left open.
    figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    ax = figure.add_axes((0.01, 0.01, 0.98, 0.92 if title else 0.98))
    _, scene = _draw(ref, ax, progress=progress, **options)
    if title:
        # On the figure, not the Axes: an equal-aspect Axes shrinks to the mesh, and its title with it.
        figure.suptitle(f"{ref.name} (revision {scene.revision}): {len(scene.v_id):,} vertices, "
                        f"{len(scene.he_id) // 2:,} edges, {len(scene.p_id):,} polygons", fontsize="small")
    report("write", 0, 1)
    fd, temporary = -1, None
    try:
        with file_errors(target, "write"):
            fd, temporary = tempfile.mkstemp(prefix=".hestore-render-", suffix=os.path.splitext(target)[1], dir=folder)
            # mkstemp makes the file private; the picture gets the mode any new file would get.
            os.chmod(temporary, 0o666 & ~_umask())
            with os.fdopen(fd, "wb") as out:
                fd = -1
                figure.savefig(out, format=fmt, dpi=dpi)
            os.replace(temporary, target)
            temporary = None
    finally:
        if fd >= 0:
            os.close(fd)
        if temporary is not None and os.path.exists(temporary):
            os.unlink(temporary)
    report("write", 1, 1)
