"""Region boundaries: a region's loop of wireframe curves as a four-sided patch outline, its
outward normal, and its boundary projected onto its best-fit plane (paper IV.A–B).

A region's loop (``carbody/data/topology.json``) is its begin curve, side A (a chain of curves),
its end curve and side B. Here both sides run from the begin curve to the end curve, and the
begin and end curves run from side B to side A, so they are the first and last *ribs* of the
region's control net (:mod:`carbody.surface.control_net`).

Everything here is numpy/shapely; no OCCT.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from carbody.errors import RegionLayoutError, SurfaceError
from carbody.tolerances import (DEGENERATE_AREA_REL, DEGENERATE_LENGTH_REL, LOOP_CLOSE_TOL_MM,
                                NORMALISED_WHEELBASE, SKELETON_SPACING_NORM)
from carbody.topology import POINTS_PER_CURVE, Region, Topology, load_topology

#: Side labels of a boundary sample.
BEGIN, SIDE_A, END, SIDE_B = 0, 1, 2, 3

#: Dense samples per curve for arc length, projection and crossing tests.
DENSE = 48


# --------------------------------------------------------------------------- Bezier arithmetic


def bezier_points(poles: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points of a cubic Bezier. poles (4, d); t (n,) -> (n, d)."""
    t = np.asarray(t, float)[:, None]
    b = np.concatenate([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3], axis=1)
    return b @ poles


def bezier_derivs(poles: np.ndarray, t: np.ndarray) -> np.ndarray:
    """First derivatives d/dt of a cubic Bezier. poles (4, d); t (n,) -> (n, d)."""
    t = np.asarray(t, float)[:, None]
    d = 3 * np.diff(poles, axis=0)
    b = np.concatenate([(1 - t) ** 2, 2 * (1 - t) * t, t**2], axis=1)
    return b @ d


def split_bezier(poles: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """Poles (4, d) of the exact sub-arc [t0, t1] of a cubic Bezier (de Casteljau, twice)."""
    def left(p, t):  # poles of [0, t]
        a = (1 - t) * p[:-1] + t * p[1:]
        b = (1 - t) * a[:-1] + t * a[1:]
        c = (1 - t) * b[:-1] + t * b[1:]
        return np.array([p[0], a[0], b[0], c[0]])

    def right(p, t):  # poles of [t, 1]
        return left(p[::-1], 1 - t)[::-1]

    p = np.asarray(poles, float)
    if t1 < 1.0:
        p = left(p, t1)
        t0 = t0 / t1 if t1 > 0 else 0.0
    if t0 > 0.0:
        p = right(p, t0)
    return p


# --------------------------------------------------------------------------- region outline


@dataclass
class Chain:
    """A side of a region: curves joined end to start, all poles in the chain's direction.

    Attributes:
        curves: wireframe curve index of each piece.
        reversed: whether each piece runs against its curve's own direction.
        poles: (n, 4, 3) float, mm; piece i's poles in chain direction.
    """

    curves: tuple[int, ...]
    reversed: tuple[bool, ...]
    poles: np.ndarray

    @property
    def n(self) -> int:
        return len(self.curves)

    def points(self, s: np.ndarray) -> np.ndarray:
        """Points at chain parameters ``s`` in [0, n] (piece index + local t). (m,) -> (m, 3)."""
        s = np.clip(np.asarray(s, float), 0, self.n)
        i = np.minimum(s.astype(int), self.n - 1)
        t = s - i
        out = np.empty((len(s), 3))
        for k in np.unique(i):
            m = i == k
            out[m] = bezier_points(self.poles[k], t[m])
        return out

    def arc_table(self) -> tuple[np.ndarray, np.ndarray]:
        """(s, cumulative arc length mm) on a dense grid of the chain; both (n*DENSE + 1,)."""
        s = np.linspace(0, self.n, self.n * DENSE + 1)
        p = self.points(s)
        return s, np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


@dataclass
class RegionOutline:
    """A region as a four-sided patch outline in 3D (mm, car frame).

    Attributes:
        name: region name.
        begin: (4, 3) poles of the begin curve, from side B to side A.
        end: (4, 3) poles of the end curve, from side B to side A.
        begin_curve, end_curve: (wireframe curve index, reversed w.r.t. B->A).
        side_a, side_b: the two long sides, each from the begin curve to the end curve.
        outward: (3,) unit normal pointing out of the body (from the consistently oriented loop).
        loop: (curve index, reversed) in loop order, turned so the loop runs counter-clockwise
            seen from outside.
    """

    name: str
    begin: np.ndarray
    end: np.ndarray
    begin_curve: tuple[int, bool]
    end_curve: tuple[int, bool]
    side_a: Chain
    side_b: Chain
    outward: np.ndarray
    loop: tuple[tuple[int, bool], ...]


def _poles(cp: np.ndarray, index: int, rev: bool) -> np.ndarray:
    p = cp[POINTS_PER_CURVE * index:POINTS_PER_CURVE * (index + 1)]
    return p[::-1] if rev else p


_FLIPS: dict[int, dict[str, bool]] = {}


def loop_flips(topology: Topology | None = None) -> dict[str, bool]:
    """Whether each region's loop must be reversed so that all loops are oriented alike.

    Two regions sharing a curve must traverse it in opposite directions (a consistently oriented
    surface); solved by a walk over the region adjacency graph from the first region. Which of
    the two global orientations points outward is decided on the geometry
    (:func:`region_outlines`).
    """
    topo = topology or load_topology()
    if id(topo) in _FLIPS:
        return _FLIPS[id(topo)]
    users: dict[int, list[tuple[str, bool]]] = {}
    for r in topo.regions:
        for ci, rev in r.loop:
            users.setdefault(ci, []).append((r.name, rev))
    flips: dict[str, bool] = {topo.regions[0].name: False}
    queue = [topo.regions[0].name]
    while queue:
        name = queue.pop()
        for ci, rev in topo.region(name).loop:
            for other, orev in users[ci]:
                if other == name:
                    continue
                # effective directions rev^flip must differ
                want = (rev ^ flips[name]) ^ orev ^ True
                if other not in flips:
                    flips[other] = want
                    queue.append(other)
                elif flips[other] != want:
                    raise AssertionError(f"regions {name} and {other} cannot be oriented alike")
    for r in topo.regions:  # a region sharing no curve keeps its loop as written
        flips.setdefault(r.name, False)
    _FLIPS[id(topo)] = flips
    return flips


def _newell(points: np.ndarray) -> np.ndarray:
    """Unnormalised Newell normal of a closed polygon (n, 3): counter-clockwise -> towards you."""
    q = np.roll(points, -1, axis=0)
    return 0.5 * np.cross(points, q).sum(axis=0)


def region_outline(control_points: np.ndarray, region: Region, outward_sign: float = 1.0,
                   topology: Topology | None = None) -> RegionOutline:
    """The four-sided outline of one region of a wireframe.

    Args:
        control_points: (280, 3) float, mm.
        region: the topology region.
        outward_sign: +1 when the consistently oriented loops run counter-clockwise seen from
            outside the body, else -1 (see :func:`outward_sign`).
    Raises:
        SurfaceError: the loop does not close, or is degenerate (:func:`check_region_geometry`).
    """
    topo = topology or load_topology()
    loop = list(region.loop)
    n = len(loop)
    for ci, _ in loop:
        poles = _poles(control_points, ci, False)
        if not np.isfinite(poles).all():
            raise SurfaceError(f"region {region.name}: curve {topo.curves[ci].name} has a control "
                               f"point that is not a finite number")
        c = topo.curves[ci]
        off = float(np.abs(poles[:, 0]).max())
        # a curve between two junctions of the symmetry plane is its own mirror: off the plane,
        # the body's two halves would not meet along it
        if c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions and not off <= LOOP_CLOSE_TOL_MM:
            raise SurfaceError(f"region {region.name}: curve {c.name} joins two junctions of the "
                               f"symmetry plane but leaves it (by {off:.3g} mm)")
    for k in range(n):
        ci, rev = loop[k]
        cj, rev2 = loop[(k + 1) % n]
        a = _poles(control_points, ci, rev)[-1]
        b = _poles(control_points, cj, rev2)[0]
        gap = float(np.linalg.norm(a - b))
        if not gap <= LOOP_CLOSE_TOL_MM:  # also catches NaN
            raise SurfaceError(f"region {region.name}: its loop does not close: curve "
                               f"{topo.curves[ci].name} ends {gap:.3g} mm from the start of "
                               f"{topo.curves[cj].name}")
    ib = [k for k, (ci, _) in enumerate(loop) if ci == region.ends[0]][0]
    loop = loop[ib:] + loop[:ib]
    ie = [k for k, (ci, _) in enumerate(loop) if ci == region.ends[1]][0]
    if ie < 2 or ie > n - 2:
        raise SurfaceError(f"region {region.name}: its end curves do not leave two sides between them")
    side_a = loop[1:ie]
    side_b = [(ci, not rev) for ci, rev in loop[ie + 1:]][::-1]

    def chain(items):
        return Chain(tuple(c for c, _ in items), tuple(r for _, r in items),
                     np.array([_poles(control_points, c, r) for c, r in items]))

    begin = loop[0]
    end = (loop[ie][0], not loop[ie][1])
    flip = loop_flips(topo)[region.name]
    eff = [(c, r ^ flip) for c, r in (region.loop[::-1] if flip else region.loop)]
    dense = np.concatenate([bezier_points(_poles(control_points, c, r), np.linspace(0, 1, DENSE, endpoint=False))
                            for c, r in eff])
    normal = _newell(dense) * outward_sign
    norm = np.linalg.norm(normal)
    outward = normal / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    if outward_sign < 0:
        eff = [(c, not r) for c, r in eff[::-1]]
    outline = RegionOutline(region.name, _poles(control_points, *begin), _poles(control_points, *end),
                            begin, end, chain(side_a), chain(side_b), outward, tuple(eff))
    check_region_geometry(outline, topo)
    return outline


def _arc_length(poles: np.ndarray) -> float:
    p = bezier_points(poles, np.linspace(0, 1, DENSE + 1))
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def strip_area(outline: RegionOutline, n: int = 4 * DENSE) -> float:
    """Area (mm²) of the ruled strip joining the two sides at equal arc-length fractions: what
    the region covers in 3D, whatever plane it would be seen in."""
    def at_fractions(chain: Chain) -> np.ndarray:
        s, arc = chain.arc_table()
        return chain.points(np.interp(np.linspace(0, arc[-1], n + 1), arc, s))

    a, b = at_fractions(outline.side_a), at_fractions(outline.side_b)
    tri1 = np.cross(a[1:] - b[:-1], a[:-1] - b[:-1])
    tri2 = np.cross(b[1:] - b[:-1], a[1:] - b[:-1])
    return 0.5 * float(np.linalg.norm(tri1, axis=1).sum() + np.linalg.norm(tri2, axis=1).sum())


def check_region_geometry(outline: RegionOutline, topology: Topology | None = None) -> None:
    """Refuse a region that no layout can surface: a curve of (near) zero length, two junctions
    of its loop on one spot, or a loop that covers no area in 3D (``DEGENERATE_LENGTH_REL``,
    ``DEGENERATE_AREA_REL`` of the region's perimeter).

    Raises:
        SurfaceError: one line naming the region and the curves (or junctions).
    """
    topo = topology or load_topology()
    curves = topo.curves

    def ends(c: int, rev: bool) -> tuple[str, str]:  # (start, end) junction in poles' direction
        return (curves[c].end, curves[c].start) if rev else (curves[c].start, curves[c].end)

    # the loop walked begin (B -> A), side A, end (A -> B), side B (end -> begin): (name, poles)
    walk = [(outline.begin_curve[0], ends(*outline.begin_curve)[0], outline.begin)]
    walk += [(c, ends(c, r)[0], p) for c, r, p in zip(outline.side_a.curves, outline.side_a.reversed,
                                                     outline.side_a.poles)]
    walk.append((outline.end_curve[0], ends(*outline.end_curve)[1], outline.end[::-1]))
    walk += [(c, ends(c, r)[1], p[::-1]) for c, r, p in zip(outline.side_b.curves[::-1], outline.side_b.reversed[::-1],
                                                           outline.side_b.poles[::-1])]
    names = [curves[c].name for c, _, _ in walk]
    lengths = np.array([_arc_length(p) for _, _, p in walk])
    perimeter = float(lengths.sum())
    tol = DEGENERATE_LENGTH_REL * perimeter
    short = [n for n, L in zip(names, lengths) if not L > tol]
    if short or not perimeter > 0:
        raise SurfaceError(f"region {outline.name}: degenerate: curve{'s' if len(short) > 1 else ''} "
                           f"{', '.join(short or names)} of zero length")
    starts = np.array([p[0] for _, _, p in walk])
    close = np.triu(np.linalg.norm(starts[:, None] - starts[None], axis=-1) <= tol, k=1)
    if close.any():
        i, j = np.argwhere(close)[0]
        raise SurfaceError(f"region {outline.name}: degenerate: junctions {walk[i][1]} and "
                           f"{walk[j][1]} coincide (curves {names[i]}, {names[j]} start there)")
    side_a = ", ".join(curves[c].name for c in outline.side_a.curves)
    side_b = ", ".join(curves[c].name for c in outline.side_b.curves)
    if not strip_area(outline) > DEGENERATE_AREA_REL * perimeter**2:
        raise SurfaceError(f"region {outline.name}: degenerate: its sides ({side_a}) and ({side_b}) "
                           f"enclose no area")


def outward_sign(control_points: np.ndarray, topology: Topology | None = None) -> float:
    """+1 if the consistently oriented loops run counter-clockwise seen from outside, else -1.

    Decided on the region whose boundary sits highest (the roof): its outward normal points up.
    """
    topo = topology or load_topology()
    flips = loop_flips(topo)
    best, best_z = None, -np.inf
    for r in topo.regions:
        idx = np.concatenate([np.arange(4 * c, 4 * c + 4) for c, _ in r.loop])
        z = control_points[idx, 2].mean()
        if z > best_z:
            best, best_z = r, z
    loop = best.loop[::-1] if flips[best.name] else best.loop
    dense = np.concatenate([bezier_points(_poles(control_points, c, r ^ flips[best.name]), np.linspace(0, 1, DENSE))
                            for c, r in loop])
    return 1.0 if _newell(dense)[2] >= 0 else -1.0


def region_outlines(control_points: np.ndarray, topology: Topology | None = None) -> list[RegionOutline]:
    """Outlines of every region of a wireframe, in topology order."""
    topo = topology or load_topology()
    sign = outward_sign(control_points, topo)
    return [region_outline(control_points, r, sign, topo) for r in topo.regions]


# --------------------------------------------------------------------------- projection & samples


@dataclass
class BoundarySamples:
    """A region's boundary sampled clockwise at a fixed spacing, projected to its best-fit plane.

    Attributes:
        points3d: (n, 3) float, mm, on the wireframe curves.
        points2d: (n, 2) float, normalised units (mm x 1000 / wheelbase), in the plane frame.
        normals2d: (n, 2) float, unit outward normals in the plane.
        side: (n,) int, BEGIN / SIDE_A / END / SIDE_B.
        s: (n,) float, parameter along the side (chain parameter for sides, t for end curves,
            running from side B to side A).
        origin, axes: plane origin (3,) mm and (3, 3) rows e1, e2, normal (normal = outward).
        dense2d: (m, 2) the projected boundary densely sampled (for drawing and checks).
        scale: normalised units per mm.
    """

    points3d: np.ndarray
    points2d: np.ndarray
    normals2d: np.ndarray
    side: np.ndarray
    s: np.ndarray
    origin: np.ndarray
    axes: np.ndarray
    dense2d: np.ndarray
    scale: float = 1.0

    def project(self, points3d: np.ndarray) -> np.ndarray:
        """(n, 3) mm -> (n, 2) plane coordinates, normalised units."""
        return (np.asarray(points3d) - self.origin) @ self.axes[:2].T * self.scale


def _sample_piece(poles: np.ndarray, spacing: float) -> np.ndarray:
    """Parameters of points at (near) equal arc length ``spacing`` along a cubic, t=0 included,
    t=1 excluded."""
    t = np.linspace(0, 1, DENSE * 4 + 1)
    p = bezier_points(poles, t)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    k = max(1, int(round(arc[-1] / spacing)))
    return np.interp(np.linspace(0, arc[-1], k + 1)[:-1], arc, t)


def boundary_samples(outline: RegionOutline, wheelbase_mm: float,
                     spacing_norm: float = SKELETON_SPACING_NORM) -> BoundarySamples:
    """Sample a region's boundary for the skeleton algorithm (paper IV.B).

    Walks begin curve (B -> A), side A, end curve (A -> B), side B (end -> begin); every curve
    end is a sample. Projects onto the best-fit plane of the boundary, scales to normalised
    units and orders the samples clockwise seen from outside.

    Raises:
        RegionLayoutError: the projected boundary crosses itself or encloses no area (the region
            itself is checked by :func:`check_region_geometry`).
    """
    scale = NORMALISED_WHEELBASE / wheelbase_mm
    spacing = spacing_norm / scale
    pieces = [(outline.begin, BEGIN, lambda t: t)]
    for i in range(outline.side_a.n):
        pieces.append((outline.side_a.poles[i], SIDE_A, lambda t, i=i: i + t))
    pieces.append((outline.end[::-1], END, lambda t: 1 - t))
    nb = outline.side_b.n
    for i in reversed(range(nb)):
        pieces.append((outline.side_b.poles[i][::-1], SIDE_B, lambda t, i=i: i + 1 - t))
    pts, side, s, dense = [], [], [], []
    for poles, label, to_s in pieces:
        t = _sample_piece(poles, spacing)
        pts.append(bezier_points(poles, t))
        side.append(np.full(len(t), label))
        s.append(to_s(t))
        dense.append(bezier_points(poles, np.linspace(0, 1, DENSE, endpoint=False)))
    pts, side, s, dense = map(np.concatenate, (pts, side, s, dense))

    origin = dense.mean(axis=0)
    _, _, vt = np.linalg.svd(dense - origin, full_matrices=False)
    normal = vt[2] if vt[2] @ outline.outward >= 0 else -vt[2]
    e1 = vt[0]
    e2 = np.cross(normal, e1)
    axes = np.array([e1, e2, normal])
    p2 = (pts - origin) @ axes[:2].T * scale
    d2 = (dense - origin) @ axes[:2].T * scale
    ring = shapely.linearrings(d2)
    perimeter = shapely.length(ring)
    area = shapely.area(shapely.polygons(ring))
    if not (perimeter > 0 and area > DEGENERATE_AREA_REL * perimeter**2):
        raise RegionLayoutError(f"region {outline.name}: its boundary projected onto its best-fit "
                                f"plane encloses no area")
    if not shapely.is_simple(ring):
        raise RegionLayoutError(f"region {outline.name}: its boundary projected onto its best-fit "
                                f"plane crosses itself")
    # clockwise seen from outside (normal towards the viewer) = negative signed area
    x, y = d2[:, 0], d2[:, 1]
    signed = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    if signed > 0:
        order = np.r_[0, np.arange(len(pts) - 1, 0, -1)]
        pts, p2, side, s = pts[order], p2[order], side[order], s[order]
        d2 = d2[::-1]
    return BoundarySamples(pts, p2, outward_normals_2d(p2), side, s, origin, axes, d2, scale)


def outward_normals_2d(points2d: np.ndarray) -> np.ndarray:
    """Unit outward normals (n, 2) of a clockwise closed polygon (n, 2), from central differences."""
    tangent = np.roll(points2d, -1, axis=0) - np.roll(points2d, 1, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-300)
    # walking clockwise the inside is on the right, so outward is the left normal
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
