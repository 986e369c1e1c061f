"""Euler operators: split, join, poke, flip, collapse, heal, fill and triangulate (SPEC §3.1).

Each operator is a pair of free functions on a `hestore._unitofwork.UnitOfWork`:
``check_<op>`` reads what the operator needs and raises a typed
`hestore.errors.TopologyError` (mostly `EulerError`, with a ``reason`` code)
when a precondition fails, and returns what it found; ``<op>`` runs the same
check, then mutates. Nothing is changed before every precondition holds, and
the ``can_<op>`` predicates run only the check, in a dry run without the
writer lock. The preconditions generalise pmp-library's and OpenMesh's
``is_flip_ok`` / ``is_collapse_ok`` from manifold triangle meshes to the
general structure of seed 000 (loops, parallel edges, wire edges, polygons
of any arity): an operator is refused only where its result would not be
representable or would degenerate.

Properties are not handled here. An operator tells the unit of work where
each element it made or changed came from (`UnitOfWork.derive`), and the
unit of work carries the values (SPEC §3.1's last paragraph): a new vertex on
an edge takes the mean of its ends, new polygons copy the polygon they were
cut from, a corner that stays at its vertex in its polygon keeps its value, a
new corner at an old vertex copies the corner it was split from, a new corner
at a new vertex takes the mean of the corners it was made between.

Ids follow SPEC §3.1: ``split_edge``'s edge keeps its id and ends at the new
vertex; ``split_polygon`` and ``triangulate_polygon`` leave ``p`` the part
holding ``p.halfedge``; ``join_polygons`` keeps the polygon left of
``e.halfedge``; ``flip_edge`` keeps every id; ``collapse_edge`` keeps the
target; ``heal_edges`` keeps ``e1``.
"""

from __future__ import annotations

from typing import NamedTuple

from hestore.errors import EulerError, HalfEdgeNotFreeError, InvalidInputError, PolicyError
from hestore._kernel import adjust_outgoing, check_policy, describe, edges_between, fans, polygon_loop, target, unlink
from hestore._unitofwork import EDGE, NEXT, ORIGIN, POLYGON, PREV, TWIN, UnitOfWork

__all__ = [
    "split_edge",
    "check_split_edge",
    "split_polygon",
    "check_split_polygon",
    "join_polygons",
    "check_join_polygons",
    "poke_polygon",
    "check_poke_polygon",
    "flip_edge",
    "check_flip_edge",
    "collapse_edge",
    "check_collapse_edge",
    "heal_edges",
    "check_heal_edges",
    "fill_hole",
    "check_fill_hole",
    "triangulate_polygon",
    "check_triangulate_polygon",
    "separate_fans",
]


def _edge_ends(uow: UnitOfWork, e: int, polygons: bool = False) -> tuple[int, int, int, int]:
    """``(h, t, a, b)``: ``e.halfedge`` (a→b), its twin, and both ends' stars cached.

    With ``polygons``, the polygons on both sides are cached by the same query.
    """
    uow.load(edges=(e,))
    h = uow.edge_he(e)
    t = uow.he(h)[TWIN]
    a, b = uow.he(h)[ORIGIN], uow.he(t)[ORIGIN]
    sides = [p for p in (uow.he(h)[POLYGON], uow.he(t)[POLYGON]) if p is not None] if polygons else ()
    uow.load(stars=(a, b), polygons=sides)
    return h, t, a, b


def _is_triangle(uow: UnitOfWork, h: int) -> bool:
    """Whether the cycle of ``h`` (polygon or free) has three half-edges."""
    x = uow.he(uow.he(h)[NEXT])[NEXT]
    return x != h and uow.he(x)[NEXT] == h


def _degree_at_most(uow: UnitOfWork, h: int, k: int) -> int:
    """The length of ``h``'s cycle, or ``k + 1`` if it is longer than ``k`` (walks at most ``k`` steps)."""
    x, n = uow.he(h)[NEXT], 1
    while x != h and n <= k:
        x, n = uow.he(x)[NEXT], n + 1
    return n


def _refuse(message: str, refs, reason: str) -> EulerError:
    return EulerError(message, refs, reason=reason)


def _cut(uow: UnitOfWork, ha: int, hb: int, keep_first: bool | None = None) -> tuple[int, int, int, int]:
    """Cut the polygon of ``ha`` and ``hb`` with a new edge between their origins.

    The part ``ha … prev(hb)`` is closed by the new half-edge ``b→a``, the
    part ``hb … prev(ha)`` by ``a→b``. The polygon keeps the first part
    (``keep_first``), the second, or (None) the one holding its
    ``halfedge``; the other part is a new polygon, pointed at its first
    half-edge. Returns ``(edge, a→b, b→a, new polygon)``.
    """
    p = uow.he(ha)[POLYGON]
    first = [ha]
    while uow.he(first[-1])[NEXT] != hb:
        first.append(uow.he(first[-1])[NEXT])
    second = [hb]
    while uow.he(second[-1])[NEXT] != ha:
        second.append(uow.he(second[-1])[NEXT])
    if keep_first is None:
        keep_first = uow.polygon_he(p) in first
    pa, pb = uow.he(ha)[PREV], uow.he(hb)[PREV]
    e, x, y = uow.new_edge(uow.he(ha)[ORIGIN], uow.he(hb)[ORIGIN])
    uow.link(pb, y)
    uow.link(y, ha)
    uow.link(pa, x)
    uow.link(x, hb)
    kept, moved = (first + [y], second + [x]) if keep_first else (second + [x], first + [y])
    q = uow.new_polygon(moved[0])
    for h in moved:
        uow.set_polygon(h, q)
    uow.set_polygon(kept[-1], p)
    if uow.polygon_he(p) not in kept:
        uow.set_polygon_he(p, kept[0])
    return e, x, y, q


# -- split_edge -------------------------------------------------------------


def check_split_edge(uow: UnitOfWork, e: int, triangulate: bool = False) -> tuple[int, int, int, int]:
    """``(h, t, a, b)`` of `split_edge`.

    Refused only where the mesh forbids parallel edges and ``e`` is a loop,
    or (``triangulate``) a cut would join the new vertex to a vertex it is
    joined to already: the triangles beside ``e`` share their third corner,
    or a triangle's third corner is an end of ``e``.
    """
    h, t, a, b = _edge_ends(uow, e, polygons=True)
    if uow.allow_multi_edges:
        return h, t, a, b
    if a == b:
        raise PolicyError(
            f"edge {e} is a self-loop at vertex {a}: splitting it makes two parallel edges, which this mesh forbids",
            (("edge", e), ("vertex", a)),
        )
    if triangulate:
        joined = {a, b}
        for x in (h, t):
            if uow.he(x)[POLYGON] is None or not _is_triangle(uow, x):
                continue
            far = uow.he(uow.he(x)[PREV])[ORIGIN]
            if far in joined:
                raise PolicyError(
                    f"splitting edge {e} with triangulate=True would join the new vertex to vertex {far} by two "
                    f"edges, which this mesh forbids",
                    (("edge", e), ("vertex", far), ("polygon", uow.he(x)[POLYGON])),
                )
            joined.add(far)
    return h, t, a, b


def split_edge(uow: UnitOfWork, e: int, position: tuple | None = None, triangulate: bool = False) -> int:
    """Put a new vertex on edge ``e`` and return it.

    ``e`` keeps its id and now ends at the new vertex ``v``; a new edge runs
    from ``v`` to the old end. The polygon on each side gains the corner
    ``v``. A self-loop becomes two parallel edges between its vertex and
    ``v``. Position: ``position``, else the midpoint of the ends when both
    have one. With ``triangulate``, each triangle beside ``e`` is then cut
    from ``v`` to its opposite corner (pmp's and OpenMesh's triangle
    ``split``).
    """
    h, t, a, b = check_split_edge(uow, e, triangulate)
    hr, tr = uow.he(h), uow.he(t)
    triangles = [x for x in (h, t) if uow.he(x)[POLYGON] is not None and _is_triangle(uow, x)] if triangulate else []
    if triangles:
        # the far corners, whose stars the cuts change, in one query
        far = [uow.he(uow.he(x)[PREV])[ORIGIN] for x in triangles]
        uow.load(stars=far, polygons=[uow.he(x)[POLYGON] for x in triangles])
    after_h, before_t, after_t = hr[NEXT], tr[PREV], tr[NEXT]
    v = uow.new_vertex(position if position is not None else uow.values.mean_position((a, b)))
    e2, h2, t2 = uow.new_edge(v, b)
    # t2 takes t's place at b; where h and t were consecutive there, so are h2 and t2.
    uow.set_origin(t, v)
    uow.link(h, h2)
    uow.link(h2, t2 if after_h == t else after_h)
    uow.link(h2 if before_t == h else before_t, t2)
    uow.link(t2, t)
    uow.set_polygon(h2, hr[POLYGON])
    uow.set_polygon(t2, tr[POLYGON])
    if tr[POLYGON] is not None and uow.polygon_he(tr[POLYGON]) == t:
        uow.set_polygon_he(tr[POLYGON], t2)  # the polygon's first corner stays at b
    if uow.vhe(b) == t:
        uow.set_vhe(b, t2)
    uow.set_vhe(v, t if hr[POLYGON] is not None and tr[POLYGON] is None else h2)
    uow.values.derive("vertex", [(v, "mean", (a, b))])
    uow.values.derive("edge", [(e2, "copy", (e,))])
    # t2 is now the corner at b on t's side; h2 and t are the new corners at v.
    uow.values.derive("halfedge", [(t2, "copy", (t,)), (h2, "corner", (h, after_h)), (t, "corner", (t, after_t))])
    for corner in (h2 if x == h else t for x in triangles):
        # The quad (v, …) is cut from v to the corner across from it.
        opposite = uow.he(uow.he(corner)[NEXT])[NEXT]
        p = uow.he(corner)[POLYGON]
        _e, x, y, q = _cut(uow, corner, opposite)
        uow.values.derive("polygon", [(q, "copy", (p,))])
        uow.values.derive("halfedge", [(x, "copy", (corner,)), (y, "copy", (opposite,))])
    return v


# -- split_polygon ------------------------------------------------------------


def _corner(uow: UnitOfWork, p: int, loop: list[int], kind: str, x: int, name: str) -> int:
    """The half-edge of ``p`` whose origin is the corner given by vertex or half-edge ``x``."""
    if kind == "halfedge":
        uow.he(x)
        if x not in loop:
            raise _refuse(
                f"{describe(uow, x)} is not a half-edge of polygon {p}, so it names no corner of it ({name})",
                (("halfedge", x), ("polygon", p)),
                "not-corner",
            )
        return x
    uow.vhe(x)
    found = [h for h in loop if uow.he(h)[ORIGIN] == x]
    if not found:
        refs = (("vertex", x), ("polygon", p))
        raise _refuse(f"vertex {x} is not a corner of polygon {p} ({name})", refs, "not-corner")
    if len(found) > 1:
        raise InvalidInputError(
            f"vertex {x} is {len(found)} corners of polygon {p} ({name}); name the corner by its half-edge "
            f"({', '.join(map(str, found))})"
        )
    return found[0]


def check_split_polygon(uow: UnitOfWork, p: int, a: tuple[str, int], b: tuple[str, int]) -> tuple[int, int]:
    """The corner half-edges ``(ha, hb)`` of `split_polygon`."""
    uow.load(polygons=(p,))
    loop = polygon_loop(uow, p)
    ha = _corner(uow, p, loop, *a, "a")
    hb = _corner(uow, p, loop, *b, "b")
    refs = (("polygon", p), ("halfedge", ha), ("halfedge", hb))
    if ha == hb:
        raise _refuse(f"a and b are the same corner of polygon {p}", refs, "same-corner")
    if uow.he(ha)[NEXT] == hb or uow.he(hb)[NEXT] == ha:
        va, vb = uow.he(ha)[ORIGIN], uow.he(hb)[ORIGIN]
        raise _refuse(
            f"corners {va} and {vb} are adjacent in polygon {p}: an edge between them would cut off a 2-gon",
            refs,
            "adjacent-corners",
        )
    va, vb = uow.he(ha)[ORIGIN], uow.he(hb)[ORIGIN]
    uow.load(stars=(va, vb))
    check_policy(uow, va, vb)
    return ha, hb


def split_polygon(uow: UnitOfWork, p: int, a: tuple[str, int], b: tuple[str, int]) -> int:
    """Cut polygon ``p`` with a new edge between corners ``a`` and ``b``; return the edge.

    ``a`` and ``b`` are ``("vertex", id)`` or ``("halfedge", id)``. ``p``
    keeps the part holding ``p.halfedge``; the other part is a new polygon.
    """
    ha, hb = check_split_polygon(uow, p, a, b)
    e, x, y, q = _cut(uow, ha, hb)
    uow.values.derive("polygon", [(q, "copy", (p,))])
    uow.values.derive("halfedge", [(x, "copy", (ha,)), (y, "copy", (hb,))])
    return e


# -- join_polygons ------------------------------------------------------------


def _two_polygons(uow: UnitOfWork, e: int, h: int, t: int, what: str) -> tuple[int, int]:
    p, q = uow.he(h)[POLYGON], uow.he(t)[POLYGON]
    if p is None or q is None:
        free = h if p is None else t
        raise _refuse(
            f"edge {e} is on the boundary ({describe(uow, free)} is free): {what} needs a polygon on both sides",
            (("edge", e), ("halfedge", free)),
            "boundary",
        )
    if p == q:
        raise _refuse(f"both sides of edge {e} are polygon {p}", (("edge", e), ("polygon", p)), "same-polygon")
    return p, q


def check_join_polygons(uow: UnitOfWork, e: int) -> tuple[int, int, int, int]:
    """``(h, t, kept polygon, removed polygon)`` of `join_polygons`."""
    h, t, a, b = _edge_ends(uow, e, polygons=True)
    p, q = _two_polygons(uow, e, h, t, "a join")
    if uow.he(h)[NEXT] == h and uow.he(t)[NEXT] == t:
        raise _refuse(
            f"polygons {p} and {q} are 1-gons on both sides of loop edge {e}: joining them leaves an empty polygon",
            (("edge", e), ("polygon", p), ("polygon", q)),
            "degenerate",
        )
    return h, t, p, q


def join_polygons(uow: UnitOfWork, e: int) -> int:
    """Remove edge ``e`` and merge the polygons beside it; return the survivor (left of ``e.halfedge``)."""
    h, t, p, q = check_join_polygons(uow, e)
    for x in polygon_loop(uow, q):
        if x != t:
            uow.set_polygon(x, p)
    if uow.polygon_he(p) == h:
        after = uow.he(h)[NEXT]
        uow.set_polygon_he(p, after if after != h else uow.he(t)[NEXT])
    unlink(uow, h)
    unlink(uow, t)
    uow.delete_edge(e)
    uow.delete_polygon(q)
    return p


# -- poke_polygon -------------------------------------------------------------


def check_poke_polygon(uow: UnitOfWork, p: int) -> list[int]:
    """The loop of `poke_polygon`'s polygon.

    Refused only for a polygon through a vertex twice in a mesh without parallel edges.
    """
    uow.load(polygons=(p,))
    loop = polygon_loop(uow, p)
    corners = [uow.he(h)[ORIGIN] for h in loop]
    if not uow.allow_multi_edges and len(set(corners)) < len(corners):
        v = next(c for c in corners if corners.count(c) > 1)
        raise PolicyError(
            f"polygon {p} passes vertex {v} more than once: poking it joins the new vertex to {v} by parallel "
            f"edges, which this mesh forbids",
            (("polygon", p), ("vertex", v)),
        )
    return loop


def poke_polygon(uow: UnitOfWork, p: int, position: tuple | None = None) -> int:
    """Put a new vertex inside ``p``, joined to every corner; return it.

    ``p`` becomes ``p.degree`` triangles; it keeps the one on
    ``p.halfedge``. Position: ``position``, else the centroid of the
    corners when all have positions.
    """
    loop = check_poke_polygon(uow, p)
    corners = [uow.he(h)[ORIGIN] for h in loop]
    uow.load(stars=corners)
    c = uow.new_vertex(position if position is not None else uow.values.mean_position(corners))
    k = len(loop)
    spokes = [uow.new_edge(c, v) for v in corners]  # (edge, c→v, v→c)
    triangles = [p] + [uow.new_polygon(loop[i]) for i in range(1, k)]
    for i, h in enumerate(loop):
        down, up = spokes[i][1], spokes[(i + 1) % k][2]
        uow.link(h, up)
        uow.link(up, down)
        uow.link(down, h)
        for x in (h, up, down):
            uow.set_polygon(x, triangles[i])
    uow.set_vhe(c, spokes[0][1])
    uow.values.derive("vertex", [(c, "mean", corners)])
    uow.values.derive("polygon", [(q, "copy", (p,)) for q in triangles[1:]])
    plan = [(spokes[i][1], "corner", loop) for i in range(k)]
    plan += [(spokes[(i + 1) % k][2], "copy", (loop[(i + 1) % k],)) for i in range(k)]
    uow.values.derive("halfedge", plan)
    return c


# -- flip_edge ----------------------------------------------------------------


def check_flip_edge(uow: UnitOfWork, e: int) -> tuple[int, int, int, int]:
    """``(h, t, c, d)`` of `flip_edge`: the edge's half-edges and the new diagonal's ends."""
    h, t, a, b = _edge_ends(uow, e)
    p, q = _two_polygons(uow, e, h, t, "a flip")
    for x, poly in ((h, p), (t, q)):
        if not _is_triangle(uow, x):
            n = _degree_at_most(uow, x, 3)
            what = f"{n} corners" if n <= 3 else "more than 3 corners"
            raise _refuse(
                f"polygon {poly} beside edge {e} has {what}: only the diagonal of two triangles can be flipped",
                (("edge", e), ("polygon", poly)),
                "not-triangle",
            )
    c, d = uow.he(uow.he(h)[PREV])[ORIGIN], uow.he(uow.he(t)[PREV])[ORIGIN]
    if c == d:
        raise _refuse(
            f"the triangles beside edge {e} share their third vertex {c}: the flipped edge would be a self-loop",
            (("edge", e), ("vertex", c)),
            "degenerate",
        )
    uow.load(stars=(c, d), polygons=(p, q))
    joined = edges_between(uow, c, d)
    if joined:
        f = uow.he(joined[0])[EDGE]
        raise _refuse(
            f"vertices {c} and {d} are already joined by edge {f}: flipping edge {e} would duplicate it",
            (("edge", e), ("edge", f), ("vertex", c), ("vertex", d)),
            "duplicate-edge",
        )
    return h, t, c, d


def flip_edge(uow: UnitOfWork, e: int) -> int:
    """Turn edge ``e``, the diagonal of the two triangles beside it; return it.

    As OpenMesh's ``flip``: with ``e.halfedge`` a→b in triangle (a, b, c)
    and its twin in (b, a, d), ``e.halfedge`` becomes d→c in the first
    polygon, now (d, c, a), and its twin c→d in the second, now (c, d, b).
    Every id is kept.
    """
    h, t, c, d = check_flip_edge(uow, e)
    p, q = uow.he(h)[POLYGON], uow.he(t)[POLYGON]
    h1, t1 = uow.he(h)[NEXT], uow.he(t)[NEXT]
    h2, t2 = uow.he(h1)[NEXT], uow.he(t1)[NEXT]
    a, b = uow.he(h)[ORIGIN], uow.he(t)[ORIGIN]
    uow.set_origin(h, d)
    uow.set_origin(t, c)
    for x, y, z, poly in ((h, h2, t1, p), (t, t2, h1, q)):
        uow.link(x, y)
        uow.link(y, z)
        uow.link(z, x)
        uow.set_polygon(z, poly)
        uow.set_polygon_he(poly, x)
    if uow.vhe(a) == h:
        uow.set_vhe(a, t1)
    if uow.vhe(b) == t:
        uow.set_vhe(b, h1)
    # Each polygon keeps its corner at a (resp. b) on another half-edge, and
    # its new corner copies the other polygon's corner at that vertex.
    uow.values.derive("halfedge", [(t1, "copy", (h,)), (h1, "copy", (t,)), (h, "copy", (t2,)), (t, "copy", (h2,))])
    return e


# -- collapse_edge ------------------------------------------------------------


class _Collapse(NamedTuple):
    h: int
    t: int
    u: int
    w: int
    # per vanishing triangle: (kept half-edge, dropped half-edge), the 2-gon after the collapse
    dissolve: tuple


def check_collapse_edge(uow: UnitOfWork, h: int) -> _Collapse:
    """The plan of `collapse_edge`, after the generalised link condition."""
    uow.load(halfedges=(h, h ^ 1))  # edge e owns half-edges 2e and 2e + 1
    e, t = uow.he(h)[EDGE], uow.he(h)[TWIN]
    u, w = uow.he(h)[ORIGIN], uow.he(t)[ORIGIN]
    if u == w:
        raise _refuse(f"edge {e} is a self-loop at vertex {u}: there is nothing to collapse", (("edge", e),), "loop")
    sides = [uow.he(x)[POLYGON] for x in (h, t)]
    uow.load(stars=(u, w), polygons=[p for p in sides if p is not None], edges=(e,))
    refs = (("halfedge", h), ("edge", e), ("vertex", u), ("vertex", w))
    if sides[0] is not None and sides[0] == sides[1]:
        raise _refuse(f"both sides of edge {e} are polygon {sides[0]}", refs + (("polygon", sides[0]),), "same-polygon")
    opposite, dissolve = [], []
    for x, p in zip((h, t), sides):
        if p is None:
            continue
        n = _degree_at_most(uow, x, 3)
        if n < 3:
            raise _refuse(
                f"polygon {p} beside edge {e} is a {n}-gon: collapsing the edge would leave a 1-gon",
                refs + (("polygon", p),),
                "degenerate",
            )
        if n > 3:
            continue
        x1 = uow.he(x)[NEXT]
        x2 = uow.he(x1)[NEXT]
        # After the collapse (x1, x2) is a 2-gon between the same two vertices:
        # the edge at w stays, the edge at u goes.
        keep, drop = (x1, x2) if x == h else (x2, x1)
        outer = (uow.he(keep)[TWIN], uow.he(drop)[TWIN])
        outside = [uow.he(o)[POLYGON] for o in outer]
        if outside[0] is None and outside[1] is None:
            raise _refuse(
                f"triangle {p} beside edge {e} has both other edges on the boundary: it would collapse into a "
                f"dangling edge",
                refs + (("polygon", p),),
                "degenerate",
            )
        if outside[0] == outside[1]:
            raise _refuse(
                f"polygon {outside[0]} lies on both other edges of triangle {p}: the collapse would fold it onto "
                f"itself",
                refs + (("polygon", p), ("polygon", outside[0])),
                "degenerate",
            )
        opposite.append(uow.he(x2)[ORIGIN])
        dissolve.append((keep, drop))
    if len(opposite) == 2 and opposite[0] == opposite[1]:
        raise _refuse(
            f"both triangles beside edge {e} have their third corner at vertex {opposite[0]}: the collapse would "
            f"flatten them onto one edge",
            refs + (("vertex", opposite[0]),),
            "link-condition",
        )
    out_u, out_w = uow.outgoing(u), uow.outgoing(w)
    free_u = any(uow.he(x)[POLYGON] is None for x in out_u)
    free_w = any(uow.he(x)[POLYGON] is None for x in out_w)
    if free_u and free_w and None not in sides:
        raise _refuse(
            f"vertices {u} and {w} are both on the boundary but edge {e} is not: the collapse would pinch the surface",
            refs,
            "link-condition",
        )
    to_u: dict[int, int] = {}
    for x in out_u:
        to_u[target(uow, x)] = to_u.get(target(uow, x), 0) + 1
    to_w: dict[int, int] = {}
    for x in out_w:
        to_w[target(uow, x)] = to_w.get(target(uow, x), 0) + 1
    if to_u.get(u) and to_w.get(w) and not uow.allow_multi_edges:
        raise PolicyError(
            f"vertices {u} and {w} both have a self-loop: collapsing edge {e} would put two loops, parallel edges, "
            f"at vertex {w}, which this mesh forbids",
            refs,
        )
    if to_u[w] > 1:
        raise _refuse(
            f"vertices {u} and {w} are joined by {to_u[w]} edges: collapsing edge {e} would make the others "
            f"self-loops",
            refs,
            "link-condition",
        )
    for x in sorted(set(to_u) & set(to_w) - {u, w}):
        if x not in opposite or to_u[x] > 1 or to_w[x] > 1:
            raise _refuse(
                f"vertex {x} is joined to both {u} and {w} but not through a triangle beside edge {e}: the collapse "
                f"would make parallel edges",
                refs + (("vertex", x),),
                "link-condition",
            )
    at_u: dict[int, int] = {}
    for x in out_u:
        at_u[uow.he(x)[POLYGON]] = at_u.get(uow.he(x)[POLYGON], 0) + 1
    for x in out_w:
        p = uow.he(x)[POLYGON]
        if p is not None and p in at_u and (p not in sides or at_u[p] > 1):
            raise _refuse(
                f"polygon {p} has corners at both {u} and {w} away from edge {e}: the collapse would make it pass "
                f"vertex {w} twice",
                refs + (("polygon", p),),
                "link-condition",
            )
    return _Collapse(h, t, u, w, tuple(dissolve))


def _skip(uow: UnitOfWork, x: int, gone: set[int]) -> int:
    y = uow.he(x)[NEXT]
    while y in gone:
        y = uow.he(y)[NEXT]
    return y


def _dissolve(uow: UnitOfWork, keep: int, drop: int) -> tuple[int, int]:
    """Remove the 2-gon ``(keep, drop)``: ``keep`` takes the place of ``twin(drop)``; return ``(twin(drop), keep)``."""
    outer = uow.he(drop)[TWIN]
    x = uow.he(drop)[ORIGIN]
    q = uow.he(outer)[POLYGON]
    before, after = uow.he(outer)[PREV], uow.he(outer)[NEXT]
    uow.link(before, keep)
    uow.link(keep, after)
    if q is not None and uow.polygon_he(q) == outer:
        uow.set_polygon_he(q, keep)
    if uow.vhe(x) == drop:
        uow.set_vhe(x, uow.he(keep)[TWIN])
    y = uow.he(keep)[ORIGIN]
    if uow.vhe(y) == outer:
        uow.set_vhe(y, keep)
    p = uow.he(keep)[POLYGON]
    uow.set_polygon(keep, q)
    uow.delete_polygon(p)
    uow.delete_edge(uow.he(drop)[EDGE])
    return outer, keep


def collapse_edge(uow: UnitOfWork, h: int) -> int:
    """Merge ``h.origin`` into ``h.target``; return the target, which keeps its position.

    Polygons beside the edge lose a corner; a triangle beside it vanishes
    and its two other edges become one (the one at the target stays).
    """
    plan = check_collapse_edge(uow, h)
    t, u, w = plan.t, plan.u, plan.w
    # On t's side the corner at w moves from t to the half-edge after it: it keeps t's value.
    after_t = uow.he(t)[NEXT]
    moves = uow.he(t)[POLYGON] is not None and after_t not in (h, t)
    corners = [(after_t, "copy", (t,))] if moves and not any(after_t in pair for pair in plan.dissolve) else []
    if plan.dissolve:
        # What the dissolving touches, in one query: the far corners' stars, the outer polygons, the dropped edges.
        outer = [uow.he(drop)[TWIN] for _keep, drop in plan.dissolve]
        uow.load(
            stars=[v for pair in plan.dissolve for v in (uow.he(x)[ORIGIN] for x in pair) if v not in (u, w)],
            polygons=[p for p in (uow.he(o)[POLYGON] for o in outer) if p is not None],
            edges=[uow.he(drop)[EDGE] for _keep, drop in plan.dissolve],
        )
    gone = {h, t}
    for x in sorted(uow.outgoing(u) - gone):
        uow.set_origin(x, w)
    for x in dict.fromkeys((uow.he(h)[PREV], uow.he(t)[PREV])):
        if x not in gone:
            uow.link(x, _skip(uow, x, gone))
    for x in (h, t):
        p = uow.he(x)[POLYGON]
        if p is not None and uow.polygon_he(p) == x:
            uow.set_polygon_he(p, _skip(uow, x, gone))
    uow.delete_edge(uow.he(h)[EDGE])
    uow.delete_vertex(u)
    moved = [_dissolve(uow, keep, drop) for keep, drop in plan.dissolve]
    rest = uow.outgoing(w)
    if not rest:
        uow.set_vhe(w, None)
    else:
        if uow.vhe(w) not in rest:
            uow.set_vhe(w, min(rest))
        adjust_outgoing(uow, w)  # u's free half-edges are w's now
    uow.values.derive("halfedge", corners + [(keep, "copy", (outer,)) for outer, keep in moved])
    return w


# -- heal_edges ---------------------------------------------------------------


def check_heal_edges(uow: UnitOfWork, e1: int, e2: int) -> tuple[int, int, int, int, int]:
    """``(x1, y1, x2, y2, v)`` of `heal_edges`: x1 arrives at the shared vertex ``v``, x2 leaves it."""
    uow.load(edges=(e1, e2))
    uow.edge_he(e1)
    uow.edge_he(e2)
    if e1 == e2:
        raise _refuse(f"edge {e1} cannot be healed with itself", (("edge", e1),), "same-edge")
    ends = []
    for e in (e1, e2):
        h = uow.edge_he(e)
        a, b = uow.he(h)[ORIGIN], target(uow, h)
        if a == b:
            raise _refuse(f"edge {e} is a self-loop at vertex {a}: it cannot be healed", (("edge", e),), "loop")
        ends.append((a, b))
    shared = [v for v in (ends[0][1], ends[0][0]) if v in ends[1]]
    refs = (("edge", e1), ("edge", e2))
    if not shared:
        raise _refuse(f"edges {e1} and {e2} share no vertex", refs, "not-adjacent")
    uow.load(stars=shared + [v for pair in ends for v in pair])
    mine = {2 * e1, 2 * e1 + 1, 2 * e2, 2 * e2 + 1}
    for v in shared:
        if uow.outgoing(v) <= mine:
            break
    else:
        v = shared[0]
        raise _refuse(
            f"vertex {v}, where edges {e1} and {e2} meet, has degree {len(uow.outgoing(v))}: other edges meet there",
            refs + (("vertex", v),),
            "degree",
        )
    h1, h2 = uow.edge_he(e1), uow.edge_he(e2)
    x1 = h1 if target(uow, h1) == v else uow.he(h1)[TWIN]
    x2 = h2 if uow.he(h2)[ORIGIN] == v else uow.he(h2)[TWIN]
    y1, y2 = uow.he(x1)[TWIN], uow.he(x2)[TWIN]
    check_policy(uow, uow.he(x1)[ORIGIN], target(uow, x2), frozenset((e1, e2)))
    return x1, y1, x2, y2, v


def heal_edges(uow: UnitOfWork, e1: int, e2: int) -> int:
    """Merge two edges through a vertex of degree 2 into ``e1``; the vertex is removed."""
    x1, y1, x2, y2, v = check_heal_edges(uow, e1, e2)
    b = target(uow, x2)
    gone = {x2, y2}
    after = _skip(uow, x2, gone)
    before = uow.he(y2)[PREV]
    while before in gone:
        before = uow.he(before)[PREV]
    uow.set_origin(y1, b)
    uow.link(x1, after)
    uow.link(before, y1)
    for x, y in ((x2, x1), (y2, y1)):
        p = uow.he(x)[POLYGON]
        if p is not None and uow.polygon_he(p) == x:
            uow.set_polygon_he(p, y)
    if uow.vhe(b) == y2:
        uow.set_vhe(b, y1)
    uow.delete_edge(e2)
    uow.delete_vertex(v)
    uow.values.derive("halfedge", [(y1, "copy", (y2,))])
    return e1


# -- fill_hole ----------------------------------------------------------------


def check_fill_hole(uow: UnitOfWork, h: int) -> list[int]:
    """The cycle of free half-edges `fill_hole` turns into a polygon."""
    p = uow.he(h)[POLYGON]
    if p is not None:
        raise HalfEdgeNotFreeError(
            f"{describe(uow, h)} already has polygon {p}: there is no hole there to fill",
            (("halfedge", h), ("polygon", p)),
        )
    loop = [h]
    x = uow.he(h)[NEXT]
    while x != h:
        loop.append(x)
        if len(loop) > 2 * uow.next_edge:  # more steps than half-edges were ever made
            raise uow.corrupt("H_NEXT_PREV", "halfedge", h, f"the boundary loop of half-edge {h} does not close")
        x = uow.he(x)[NEXT]
    return loop


def fill_hole(uow: UnitOfWork, h: int) -> int:
    """Give the boundary loop of the free half-edge ``h`` a polygon; return it."""
    loop = check_fill_hole(uow, h)
    corners = list(dict.fromkeys(uow.he(x)[ORIGIN] for x in loop))
    uow.load(stars=corners)
    p = uow.new_polygon(h)
    for x in loop:
        uow.set_polygon(x, p)
    for v in corners:
        adjust_outgoing(uow, v)
    return p


# -- triangulate_polygon ------------------------------------------------------


def check_triangulate_polygon(uow: UnitOfWork, p: int) -> list[int]:
    """The loop of `triangulate_polygon`'s polygon; refused only where the fan's diagonals break the policy."""
    uow.load(polygons=(p,))
    loop = polygon_loop(uow, p)
    if len(loop) <= 3:
        return loop
    corners = [uow.he(h)[ORIGIN] for h in loop]
    uow.load(stars=corners)
    seen: set[int] = set()
    for v in corners[2:-1]:
        check_policy(uow, corners[0], v)
        if v in seen and not uow.allow_multi_edges:
            raise PolicyError(
                f"polygon {p} passes vertex {v} twice: its fan from vertex {corners[0]} would join them by parallel "
                f"edges, which this mesh forbids",
                (("polygon", p), ("vertex", v)),
            )
        seen.add(v)
    return loop


def triangulate_polygon(uow: UnitOfWork, p: int) -> list[int]:
    """Cut ``p`` into a fan of triangles from the corner of ``p.halfedge``; return them, ``p`` first."""
    loop = check_triangulate_polygon(uow, p)
    if len(loop) <= 3:
        return [p]
    triangles = [p]
    corner_plan = []
    ha = loop[0]
    for hb in loop[2:-1]:
        _e, x, y, q = _cut(uow, ha, hb, keep_first=True)
        corner_plan += [(x, "copy", (loop[0],)), (y, "copy", (hb,))]
        triangles.append(q)
        ha = x
    uow.values.derive("polygon", [(q, "copy", (p,)) for q in triangles[1:]])
    uow.values.derive("halfedge", corner_plan)
    return triangles


# -- separate_fans ----------------------------------------------------------------


def separate_fans(uow: UnitOfWork, v: int) -> list[int]:
    """Give every polygon fan at ``v`` but the first a vertex of its own; return the new vertices.

    A fan is a run of outgoing half-edges between two free wedges (`fans`);
    it holds polygons unless it is a lone wire edge, which stays at ``v``.
    Each fan that moves is cut out of ``v``'s rotation at its two free
    wedges and closed on itself, so no polygon changes; the new vertex takes
    ``v``'s position and values. Nothing happens at a vertex with one fan.
    """
    uow.load(stars=(v,))
    if uow.vhe(v) is None:
        return []
    made: list[int] = []
    xyz = None
    while True:
        polygonal = [f for f in fans(uow, v) if any(uow.he(o)[POLYGON] is not None for o in f)]
        if len(polygonal) < 2:
            break
        fan = polygonal[-1]
        # The free wedge before the fan ends the previous one; the one after it starts the next.
        before = uow.he(fan[0])[PREV]
        after_last = uow.he(uow.he(fan[-1])[TWIN])[NEXT]
        if not made:
            xyz = uow.values.positions((v,)).get(v)
        w = uow.new_vertex(xyz)
        uow.link(before, after_last)
        uow.link(uow.he(fan[-1])[TWIN], fan[0])
        for o in fan:
            uow.set_origin(o, w)
        uow.set_vhe(w, fan[0])
        if uow.vhe(v) in fan:
            uow.set_vhe(v, after_last)
        adjust_outgoing(uow, v)
        adjust_outgoing(uow, w)
        made.append(w)
    uow.values.derive("vertex", [(w, "copy", (v,)) for w in made])
    return made
