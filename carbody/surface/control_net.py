"""Control curves, DTW-refined correspondences and the quad net of a region (paper V).

A region's net is a sequence of *ribs*, cubic control curves from side B to side A:

* rib 0 and the last rib are the region's begin and end curves;
* the skeleton's optimal pairs that join side A to side B give inner ribs;
* every junction between two curves of a side gets a rib too, so that each face edge on a side
  lies on one wireframe cubic and is an exact sub-arc of it (de Casteljau split); its partner on
  the other side comes from the DTW correspondence (dtaidistance, C) between the boundary
  samples of the two sides between consecutive skeleton ribs (the paper's refinement).

Inner control points of a rib are the blend of the begin and end curves' shapes, each
normalised to a chord from (0, 0) to (1, 0) in its own frame, by the arc-length ratio of the
rib's ends along the two sides (P1 by the ratio along the P0 side B, P2 by the ratio along the P3
side A), mapped back between the rib's own end points (SPEC "Reading the paper's surface
section").

Between consecutive ribs k, k+1 one bicubic Bezier patch: rows rib k, rib k + f_k⁺/3,
rib k+1 − f_{k+1}⁻/3, rib k+1, where the cross-derivative f = σ(u)·E(u) is the product of a
linear scale σ (fixed at the two columns by the side sub-arcs) and a quadratic direction field
E_k shared by both patches meeting at rib k. Both patches' cross-derivatives at rib k are then
positive multiples of the same E_k(u), so their normals agree all along the rib: G1 inside a
region wherever the wireframe sides themselves are G1.

Our readings where the paper is silent (each a named constant below):

* the DTW path is blended (:data:`DTW_BLEND`) towards the arc-length-proportional match so it
  is strictly monotone and two junctions never share a partner;
* an optimal pair that cuts a square-ish part diagonally (its ends at arc-length fractions more
  than :data:`MAX_RIB_SKEW` apart) or that fans strongly against a neighbouring rib
  (:data:`MAX_FAN`) stays in the skeleton but is not made a rib;
* ribs leave the symmetry plane square (along x), with the E field in the plane of x and the
  centre line, so each region meets its mirror G1;
* where a side turns a corner (:data:`CORNER_DEG`) each patch follows its own side's tangent:
  no layout is G1 across such a rib, and the report lists those ribs apart.

Everything here is numpy; no OCCT.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from carbody.errors import RegionLayoutError
from carbody.surface.regions import (SIDE_A, SIDE_B, BoundarySamples, Chain, RegionOutline,
                                     bezier_derivs, bezier_points, split_bezier)
from carbody.surface.skeleton import OptimalPair
from carbody.topology import load_topology

#: An optimal pair cutting a square-ish part can be a diagonal; as a rib it would shear the net.
#: Pairs whose ends sit at arc-length fractions further apart than this along the two sides stay
#: in the skeleton but are not used as ribs.
MAX_RIB_SKEW = 0.2

#: A side turning by more than this (degrees) at a rib's end is a corner.
CORNER_DEG = 0.5

#: A face side may turn at most this much (degrees); more gets an extra rib at its middle.
MAX_SIDE_TURN_DEG = 50.0

#: A rib chord may run outside its (projected) region for at most this fraction of its length
#: (end points on a curved side sit a hair outside the polygon through the side's samples).
MAX_OUTSIDE = 0.01

#: Largest factor by which a face's side lengths ratio (A over B) may differ from the region's.
MAX_FAN = 2.5

#: Weight of the arc-length-proportional match blended into the DTW correspondence.
DTW_BLEND = 0.3

@dataclass
class SideRef:
    """A face side lying on a wireframe curve: side parameter p in [0, 1] is curve parameter
    ``t0 + p (t1 - t0)`` of curve ``curve`` (index; ``mirror`` for the right-half copy)."""

    curve: int
    t0: float
    t1: float
    mirror: bool = False

    @property
    def key(self) -> tuple[int, bool]:
        return self.curve, self.mirror


@dataclass
class FacePatch:
    """One bicubic Bezier face of a region.

    Attributes:
        region: region name.
        index: face number inside the region (0 at the begin curve).
        net: (4, 4, 3) float, mm; ``net[i, j]`` is pole (u_i, v_j); u runs across the region
            (rib direction), v along it. Normal S_u x S_v points out of the body.
        sides: {"v0", "u1", "v1", "u0"} -> SideRef for sides on a wireframe curve, else None.
        mirror: True for the right half.
    """

    region: str
    index: int
    net: np.ndarray
    sides: dict[str, SideRef | None] = field(default_factory=dict)
    mirror: bool = False

    def mirrored(self, symmetric_curves: set[int]) -> "FacePatch":
        """The right-half twin: x negated, u reversed so the normal still points outwards."""
        net = self.net[::-1] * np.array([-1.0, 1.0, 1.0])

        def m(ref: SideRef | None, flip: bool) -> SideRef | None:
            if ref is None:
                return None
            t0, t1 = (ref.t1, ref.t0) if flip else (ref.t0, ref.t1)
            return SideRef(ref.curve, t0, t1, ref.curve not in symmetric_curves)

        s = self.sides
        sides = {"v0": m(s["v0"], True), "v1": m(s["v1"], True), "u0": m(s["u1"], False),
                 "u1": m(s["u0"], False)}
        return FacePatch(self.region, self.index, net, sides, True)


@dataclass
class RegionNet:
    """A region's ribs and faces.

    Attributes:
        ribs: (K, 2) float, chain parameters (s_A, s_B) of each rib's ends.
        rows: (K, 4, 3) float, mm, rib control curves from side B to side A.
        kinds: (K,) str: "end", "skeleton", "junction" or "refine".
        faces: K - 1 patches.
        correspondence: (m, 2) float, DTW correspondence (s_A, s_B) samples.
        side_turn_deg: (K,) float, how sharply the sides turn at each rib's ends (degrees; 0
            inside a cubic): no patch layout can be G1 across a rib ending at a side corner.
        layout: how the ribs were chosen: "skeleton" (the paper's, from the projected outline)
            or "arc_length" (:mod:`carbody.surface.arc_layout`, when the paper's fails).
        layout_note: why the paper's layout was not used ("" when it was).
    """

    name: str
    ribs: np.ndarray
    rows: np.ndarray
    kinds: list[str]
    faces: list[FacePatch]
    correspondence: np.ndarray
    side_turn_deg: np.ndarray
    layout: str = "skeleton"
    layout_note: str = ""


# --------------------------------------------------------------------------- correspondences


def skeleton_ribs(samples: BoundarySamples, pairs: list[OptimalPair]) -> np.ndarray:
    """(k, 2) chain parameters (s_A, s_B) of the optimal pairs that join side A to side B."""
    out = []
    for p in pairs:
        sides = samples.side[[p.i, p.j]]
        if set(sides.tolist()) == {SIDE_A, SIDE_B}:
            a, b = (p.i, p.j) if sides[0] == SIDE_A else (p.j, p.i)
            out.append((samples.s[a], samples.s[b]))
    return np.array(out).reshape(-1, 2)


def _monotone(ribs: np.ndarray, na: int, nb: int, eps: float = 1e-6) -> np.ndarray:
    """Ribs sorted along side A, strictly inside both sides, crossing-free (greedy)."""
    ribs = ribs[(ribs[:, 0] > eps) & (ribs[:, 0] < na - eps) & (ribs[:, 1] > eps) & (ribs[:, 1] < nb - eps)]
    ribs = ribs[np.argsort(ribs[:, 0], kind="stable")]
    out, last = [], (0.0, 0.0)
    for a, b in ribs:
        if a > last[0] + eps and b > last[1] + eps:
            out.append((a, b))
            last = (a, b)
    return np.array(out).reshape(-1, 2)


def dtw_correspondence(outline: RegionOutline, samples: BoundarySamples, ribs: np.ndarray) -> np.ndarray:
    """Refine the correspondence between the two sides by DTW between consecutive ribs.

    Between ribs k and k+1 the boundary samples of side A and of side B (3D points, mm, with the
    ribs' own end points) are aligned by dynamic time warping on point-to-point distance
    (``dtaidistance.dtw_ndim``, C implementation).

    Args:
        ribs: (k, 2) monotone inner ribs (s_A, s_B); the begin and end curves are added here.
    Returns:
        (m, 2) float, (s_A, s_B) pairs of the warping paths, sorted, first (0, 0), last (n_A, n_B).
    """
    from dtaidistance import dtw_ndim

    na, nb = outline.side_a.n, outline.side_b.n
    sa_t, la_t = outline.side_a.arc_table()
    sb_t, lb_t = outline.side_b.arc_table()
    arc_a = lambda s: np.interp(s, sa_t, la_t)  # noqa: E731
    arc_b = lambda s: np.interp(s, sb_t, lb_t)  # noqa: E731
    s_of_a = lambda L: np.interp(L, la_t, sa_t)  # noqa: E731
    s_of_b = lambda L: np.interp(L, lb_t, sb_t)  # noqa: E731
    bounds = np.vstack([[0.0, 0.0], ribs, [na, nb]])
    sa_all = np.unique(np.r_[samples.s[samples.side == SIDE_A], np.arange(na + 1)])
    sb_all = np.unique(np.r_[samples.s[samples.side == SIDE_B], np.arange(nb + 1)])
    out = []
    for (a0, b0), (a1, b1) in zip(bounds[:-1], bounds[1:]):
        sa = np.unique(np.r_[a0, sa_all[(sa_all > a0) & (sa_all < a1)], a1])
        sb = np.unique(np.r_[b0, sb_all[(sb_all > b0) & (sb_all < b1)], b1])
        pa, pb = outline.side_a.points(sa), outline.side_b.points(sb)
        path = np.array(dtw_ndim.warping_path(pa, pb, use_c=True))
        a, b = sa[path[:, 0]], sb[path[:, 1]]
        # blend towards the arc-length-proportional match: strictly monotone (no many-to-one)
        la0, la1, lb0, lb1 = arc_a(a0), arc_a(a1), arc_b(b0), arc_b(b1)
        a_lin = s_of_a(la0 + (arc_b(b) - lb0) / max(lb1 - lb0, 1e-12) * (la1 - la0))
        b_lin = s_of_b(lb0 + (arc_a(a) - la0) / max(la1 - la0, 1e-12) * (lb1 - lb0))
        out += list(zip((1 - DTW_BLEND) * a + DTW_BLEND * a_lin, (1 - DTW_BLEND) * b + DTW_BLEND * b_lin))
    return np.array(sorted(set(out)))


class MonotoneCurve:
    """The correspondence as one monotone polyline in (s_A, s_B): partners of A points and of
    B points read off the same curve never cross each other."""

    def __init__(self, corr: np.ndarray):
        pts = corr[np.lexsort((corr[:, 1], corr[:, 0]))]
        pts[:, 1] = np.maximum.accumulate(pts[:, 1])
        self.pts = pts
        self.w = np.r_[0.0, np.cumsum(np.abs(np.diff(pts, axis=0)).sum(axis=1))]

    def _at(self, axis: int, value: float) -> np.ndarray:
        x = self.pts[:, axis]
        lo, hi = np.searchsorted(x, value, "left"), np.searchsorted(x, value, "right")
        if hi > lo:  # the path runs along x = value: take the middle of that run
            w = self.w[lo:hi].mean()
        else:
            w = float(np.interp(value, x, self.w))
        return np.array([np.interp(w, self.w, self.pts[:, 0]), np.interp(w, self.w, self.pts[:, 1])])

    def partner_of_a(self, s_a: float) -> float:
        return float(self._at(0, s_a)[1])

    def partner_of_b(self, s_b: float) -> float:
        return float(self._at(1, s_b)[0])


def _strictly_ordered(r: np.ndarray, fixed: np.ndarray, eps: float = 1e-6) -> bool:
    """True when rib r crosses none of ``fixed`` and shares no end with them."""
    before = (r[0] < fixed[:, 0] - eps) & (r[1] < fixed[:, 1] - eps)
    after = (r[0] > fixed[:, 0] + eps) & (r[1] > fixed[:, 1] + eps)
    return bool(np.all(before | after))


def _keep_inside(outline: RegionOutline, samples: BoundarySamples, junc: np.ndarray,
                 lo_all: np.ndarray | None = None, hi_all: np.ndarray | None = None,
                 fixed_side: int | None = None) -> np.ndarray:
    """Slide the partner end of junction ribs whose chord leaves the (projected) region.

    Near a spike of the outline the correspondence can pair a junction with a point whose chord
    cuts outside; the partner then moves along its side, between the neighbouring ribs, to the
    nearest parameter whose chord stays inside.
    """
    import shapely

    region = shapely.buffer(shapely.polygons(samples.dense2d), 1e-6 * np.sqrt(shapely.area(shapely.polygons(samples.dense2d))))
    shapely.prepare(region)
    na, nb = outline.side_a.n, outline.side_b.n
    junc = junc.copy()

    def inside(a, b):
        pts = samples.project(np.vstack([outline.side_a.points(np.atleast_1d(a)), outline.side_b.points(np.atleast_1d(b))]))
        k = len(np.atleast_1d(a))
        lines = shapely.linestrings(np.stack([pts[:k], pts[k:]], axis=1))
        outside = shapely.length(shapely.difference(lines, region)) / np.maximum(shapely.length(lines), 1e-12)
        return outside <= MAX_OUTSIDE

    for i, (a, b) in enumerate(junc):
        # a rib joining a junction of each side cannot slide: both of its ends must stay put
        if inside(a, b)[0] or (fixed_side is None and float(a).is_integer() and float(b).is_integer()):
            continue
        lo = junc[i - 1] if i > 0 else (np.array([0.0, 0.0]) if lo_all is None else lo_all)
        hi = junc[i + 1] if i + 1 < len(junc) else (np.array([na, nb]) if hi_all is None else hi_all)
        a_fixed = float(a).is_integer() if fixed_side is None else fixed_side == 0
        if a_fixed:  # the partner is on side B
            cand = np.linspace(lo[1], hi[1], 42)[1:-1]
            ok = inside(np.full_like(cand, a), cand)
            if ok.any():
                junc[i, 1] = cand[ok][np.argmin(np.abs(cand[ok] - b))]
        else:
            cand = np.linspace(lo[0], hi[0], 42)[1:-1]
            ok = inside(cand, np.full_like(cand, b))
            if ok.any():
                junc[i, 0] = cand[ok][np.argmin(np.abs(cand[ok] - a))]
    return junc


def net_ribs(outline: RegionOutline, skeleton: np.ndarray, correspondence: np.ndarray,
             min_gap_mm: float, samples: BoundarySamples | None = None) -> tuple[np.ndarray, list[str]]:
    """All ribs of the net: ends, junction ribs (partners from the correspondence), skeleton ribs.

    A junction rib whose partner falls within ``min_gap_mm`` (arc length) of a junction of the
    other side joins the two junctions; a skeleton rib closer than ``min_gap_mm`` to another rib
    on either side, or crossing a junction rib, is dropped (junction ribs are needed: a face
    edge must lie on one cubic).

    Returns:
        (K, 2) (s_A, s_B) from (0, 0) to (n_A, n_B), and each rib's kind.
    """
    na, nb = outline.side_a.n, outline.side_b.n
    sa_t, la_t = outline.side_a.arc_table()
    sb_t, lb_t = outline.side_b.arc_table()
    arc_a = lambda s: np.interp(s, sa_t, la_t)  # noqa: E731
    arc_b = lambda s: np.interp(s, sb_t, lb_t)  # noqa: E731
    curve = MonotoneCurve(correspondence)

    on_a: dict[int, float] = {}  # A junction -> partner on B
    free_b: list[tuple[float, int]] = []
    used_b: set[int] = set()
    for j in range(1, na):
        b = curve.partner_of_a(j)
        if not 0 < b < nb:
            continue
        near = [k for k in range(1, nb) if abs(arc_b(k) - arc_b(b)) < min_gap_mm]
        if near:
            k = min(near, key=lambda k: abs(arc_b(k) - arc_b(b)))
            used_b.add(k)
            b = float(k)
        on_a[j] = b
    for k in range(1, nb):
        if k in used_b:
            continue
        a = curve.partner_of_b(k)
        if not 0 < a < na:
            continue
        near = [j for j in range(1, na) if abs(arc_a(j) - arc_a(a)) < min_gap_mm]
        if near:
            on_a[min(near, key=lambda j: abs(arc_a(j) - arc_a(a)))] = float(k)
        else:
            free_b.append((a, float(k)))
    junctions = [(float(j), b) for j, b in on_a.items()] + free_b
    junc = np.unique(np.array(junctions).reshape(-1, 2), axis=0)
    junc = junc[np.lexsort((junc[:, 1], junc[:, 0]))]
    if samples is not None and len(junc):
        junc = _keep_inside(outline, samples, junc)
    if len(junc) and (np.any(np.diff(junc[:, 0]) <= 0) or np.any(np.diff(junc[:, 1]) <= 0)):
        raise RegionLayoutError(f"region {outline.name}: its junction ribs cross or share an end")

    fixed = np.vstack([[0.0, 0.0], junc, [na, nb]])
    keep = []
    for a, b in skeleton:
        da = np.abs(arc_a(fixed[:, 0]) - arc_a(a)).min()
        db = np.abs(arc_b(fixed[:, 1]) - arc_b(b)).min()
        if da >= min_gap_mm and db >= min_gap_mm and _strictly_ordered(np.array([a, b]), fixed):
            keep.append((a, b))
    skel = _monotone(np.array(keep).reshape(-1, 2), na, nb)
    # a skeleton rib that makes a strong fan with a neighbour (spacing ratio along A vs B far
    # from the region's) is dropped: such faces are wedges whose control nets fold
    ratio = la_t[-1] / lb_t[-1]
    while len(skel):
        allr = np.vstack([fixed, skel])
        order = np.argsort(allr[:, 0], kind="stable")
        allr, is_skel = allr[order], (np.arange(len(allr)) >= len(fixed))[order]
        da, db = np.diff(arc_a(allr[:, 0])), np.diff(arc_b(allr[:, 1]))
        fan = np.abs(np.log(np.maximum(da, 1e-9) / np.maximum(db, 1e-9) / ratio))
        bad = [k for k in np.argsort(-fan) if fan[k] > np.log(MAX_FAN)]
        drop = next((j for k in bad for j in (k, k + 1) if is_skel[j]), None)
        if drop is None:
            break
        skel = np.array([r for r in skel if not np.array_equal(r, allr[drop])]).reshape(-1, 2)
    inner = np.vstack([junc, skel])
    kinds = ["junction"] * len(junc) + ["skeleton"] * len(skel)
    order = np.argsort(inner[:, 0], kind="stable")
    ribs = np.vstack([[0.0, 0.0], inner[order], [na, nb]])
    kinds = ["end"] + [kinds[i] for i in order] + ["end"]
    return refine_turns(outline, samples, ribs, kinds, curve)


def _turn(chain: Chain, s0: float, s1: float) -> float:
    """Angle (degrees) the chain's tangent turns between s0 and s1 inside one piece."""
    i = min(int(np.floor(s0 + 1e-12)), chain.n - 1)
    d = bezier_derivs(chain.poles[i], np.linspace(s0 - i, min(s1 - i, 1.0), 5))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return float(np.degrees(np.arccos(np.clip((d[:-1] * d[1:]).sum(axis=1), -1, 1))).sum())


def refine_turns(outline: RegionOutline, samples: BoundarySamples | None, ribs: np.ndarray,
                 kinds: list[str], curve: "MonotoneCurve") -> tuple[np.ndarray, list[str]]:
    """Add ribs where a face's side turns more than :data:`MAX_SIDE_TURN_DEG` (a quarter of a
    wheel arch in one face bulges into it), at the middle of that side, partner from the
    correspondence (kept strictly between the neighbouring ribs, and inside the projected region
    when there are ``samples``; a region laid out by arc length has none)."""
    ribs, kinds = [tuple(r) for r in ribs], list(kinds)
    turns: dict[tuple[int, float, float], float] = {}  # each face side's turn, measured once

    def turn_of(side: int, s0: float, s1: float) -> float:
        if (side, s0, s1) not in turns:
            turns[side, s0, s1] = _turn(outline.side_b if side else outline.side_a, s0, s1)
        return turns[side, s0, s1]

    for _ in range(4 * len(ribs)):
        worst, where = MAX_SIDE_TURN_DEG, None
        for k in range(len(ribs) - 1):
            (a0, b0), (a1, b1) = ribs[k], ribs[k + 1]
            for side, turn in ((0, turn_of(0, a0, a1)), (1, turn_of(1, b0, b1))):
                if turn > worst:
                    worst, where = turn, (k, side)
        if where is None:
            break
        k, side = where
        (a0, b0), (a1, b1) = ribs[k], ribs[k + 1]
        if side == 0:
            a = (a0 + a1) / 2
            b = curve.partner_of_a(a)
            b = b if b0 < b < b1 else (b0 + b1) / 2
        else:
            b = (b0 + b1) / 2
            a = curve.partner_of_b(b)
            a = a if a0 < a < a1 else (a0 + a1) / 2
        new = np.array([[a, b]])
        if samples is not None:
            lo, hi = np.array([a0, b0]), np.array([a1, b1])
            moved = _keep_inside(outline, samples, new, lo, hi, fixed_side=side)
            new = moved
        ribs.insert(k + 1, tuple(new[0]))
        kinds.insert(k + 1, "refine")
    return np.array(ribs), kinds


# --------------------------------------------------------------------------- rib control curves


def _side_tangent(chain: Chain, s: float) -> np.ndarray:
    """Unit tangent of a chain at s, direction of increasing s (mean of both sides at a junction)."""
    i = min(int(s), chain.n - 1)
    t = s - i
    d = bezier_derivs(chain.poles[i], [t])[0]
    d = d / np.linalg.norm(d)
    if t == 0 and i > 0:
        e = bezier_derivs(chain.poles[i - 1], [1.0])[0]
        d = d + e / np.linalg.norm(e)
    elif s >= chain.n and chain.n > 0:
        d = bezier_derivs(chain.poles[-1], [1.0])[0]
    return d / np.linalg.norm(d)


def _one_sided_tangent(chain: Chain, s: float, after: bool) -> np.ndarray:
    """Unit tangent of a chain at s from the piece after (or before) s."""
    j = int(round(s))
    if abs(s - j) < 1e-9 and 0 < j < chain.n:
        d = bezier_derivs(chain.poles[j], [0.0])[0] if after else bezier_derivs(chain.poles[j - 1], [1.0])[0]
        return d / np.linalg.norm(d)
    return _side_tangent(chain, s)


def _rib_frame(p0: np.ndarray, p3: np.ndarray, along: np.ndarray, outward: np.ndarray):
    """(length, (3, 3) rows x̂ chord, ŵ out of the surface, ŷ = ŵ × x̂) of a rib."""
    chord = p3 - p0
    length = float(np.linalg.norm(chord))
    x = chord / length
    w = np.cross(x, along)
    if np.linalg.norm(w) < 1e-9:
        w = outward - (outward @ x) * x
    w /= np.linalg.norm(w)
    if w @ outward < 0:
        w = -w
    return length, np.array([x, w, np.cross(w, x)])


def rib_rows(outline: RegionOutline, ribs: np.ndarray) -> np.ndarray:
    """Control curves of all ribs (paper V): (K, 4, 3) float, mm, from side B to side A.

    Rib 0 and rib K-1 are the begin and end curves themselves.
    """
    a_pts = outline.side_a.points(ribs[:, 0])
    b_pts = outline.side_b.points(ribs[:, 1])
    sa_t, la_t = outline.side_a.arc_table()
    sb_t, lb_t = outline.side_b.arc_table()
    ratio_a = np.interp(ribs[:, 0], sa_t, la_t) / la_t[-1]  # along the P3 side
    ratio_b = np.interp(ribs[:, 1], sb_t, lb_t) / lb_t[-1]  # along the P0 side

    def along(k):
        return _side_tangent(outline.side_a, ribs[k, 0]) + _side_tangent(outline.side_b, ribs[k, 1])

    def normalised(poles, k):
        length, frame = _rib_frame(poles[0], poles[3], along(k), outline.outward)
        return (poles[1:3] - poles[0]) @ frame.T / length

    begin_n = normalised(outline.begin, 0)
    end_n = normalised(outline.end, len(ribs) - 1)
    rows = np.empty((len(ribs), 4, 3))
    for k in range(len(ribs)):
        p0, p3 = b_pts[k], a_pts[k]
        length, frame = _rib_frame(p0, p3, along(k), outline.outward)
        n1 = (1 - ratio_b[k]) * begin_n[0] + ratio_b[k] * end_n[0]
        n2 = (1 - ratio_a[k]) * begin_n[1] + ratio_a[k] * end_n[1]
        rows[k] = [p0, p0 + length * n1 @ frame, p0 + length * n2 @ frame, p3]
    rows[0], rows[-1] = outline.begin, outline.end
    # A rib leaving the symmetry plane leaves it square (as the transverse wireframe curves do),
    # so the body is smooth across the plane where it meets its mirror.
    for k in range(1, len(ribs) - 1):
        if on_symmetry_plane(outline.side_b, ribs[k, 1]):
            rows[k, 1] = rows[k, 0] + _lateral(rows[k, 1] - rows[k, 0])
        if on_symmetry_plane(outline.side_a, ribs[k, 0]):
            rows[k, 2] = rows[k, 3] + _lateral(rows[k, 2] - rows[k, 3])
    return rows


def on_symmetry_plane(chain: Chain, s: float, tol: float = 1e-6) -> bool:
    """True when the chain piece at s lies in the symmetry plane x = 0."""
    i = min(int(s), chain.n - 1)
    return bool(np.abs(chain.poles[i][:, 0]).max() < tol)


def _lateral(d: np.ndarray) -> np.ndarray:
    """The vector d turned to point straight across the symmetry plane (along ±x), same length."""
    return np.array([np.sign(d[0]) * np.linalg.norm(d) if d[0] != 0 else np.linalg.norm(d), 0.0, 0.0])


# --------------------------------------------------------------------------- patches


def _sub_arc(chain: Chain, s0: float, s1: float) -> tuple[np.ndarray, int, float, float]:
    """Exact sub-arc of a chain between s0 < s1 lying on one piece: (poles, piece, t0, t1)."""
    i = min(int(np.floor(s0 + 1e-12)), chain.n - 1)
    t0, t1 = s0 - i, s1 - i
    if t1 > 1 + 1e-9:
        raise AssertionError(f"sub-arc [{s0}, {s1}] spans a junction")
    t0, t1 = max(t0, 0.0), min(t1, 1.0)
    return split_bezier(chain.poles[i], t0, t1), i, t0, t1


def _cross(sigma0: float, sigma3: float, e: np.ndarray) -> np.ndarray:
    """Bezier coefficients (4, 3) of the cubic σ(u)·E(u): σ linear (σ0, σ3), E quadratic e (3, 3)."""
    return np.array([sigma0 * e[0], (2 * sigma0 * e[1] + sigma3 * e[0]) / 3,
                     (sigma0 * e[2] + 2 * sigma3 * e[1]) / 3, sigma3 * e[2]])


def _side_ref(chain: Chain, piece: int, t0: float, t1: float) -> SideRef:
    c, rev = chain.curves[piece], chain.reversed[piece]
    return SideRef(c, 1 - t0, 1 - t1) if rev else SideRef(c, t0, t1)


def patches(outline: RegionOutline, ribs: np.ndarray, rows: np.ndarray,
            outward_by_loop: bool = False) -> list[FacePatch]:
    """Bicubic Bezier patches between consecutive ribs (G1 across inner ribs; see module doc).

    Args:
        outward_by_loop: orient the faces (S_u x S_v out of the body) by the loop's direction
            instead of by the middle face's normal: the same on any region whose faces do not
            fold, and still right on one whose faces do.
    """
    K = len(ribs)
    mids = np.array([bezier_points(r, [0.5])[0] for r in rows])
    subs = [(_sub_arc(outline.side_b, ribs[k, 1], ribs[k + 1, 1]), _sub_arc(outline.side_a, ribs[k, 0], ribs[k + 1, 0]))
            for k in range(K - 1)]
    # cross-derivative lengths of the side sub-arcs at each rib, after (+) and before (-) it
    after = [(np.linalg.norm(3 * (b[0][1] - b[0][0])), np.linalg.norm(3 * (a[0][1] - a[0][0]))) for b, a in subs]
    before = [(np.linalg.norm(3 * (b[0][3] - b[0][2])), np.linalg.norm(3 * (a[0][3] - a[0][2]))) for b, a in subs]
    fields = []
    x = np.array([1.0, 0.0, 0.0])
    for k in range(K):
        # E_k's end lengths: geometric mean of the two patches' side lengths at the rib, so that
        # σ(u) stays near 1 and a patch with one short side does not fold its control net
        near = after[k:k + 1] + before[k - 1:k] if k else after[:1]
        lb = float(np.prod([v[0] for v in near]) ** (1 / len(near)))
        la = float(np.prod([v[1] for v in near]) ** (1 / len(near)))
        e0 = lb * _side_tangent(outline.side_b, ribs[k, 1])
        e2 = la * _side_tangent(outline.side_a, ribs[k, 0])
        # where a side turns a corner no layout is G1 across the rib: each patch then follows
        # its own side's tangent (its exact sub-arc) instead of the bisector
        b_turn = side_turn_deg(outline.side_b, ribs[k, 1]) >= CORNER_DEG
        a_turn = side_turn_deg(outline.side_a, ribs[k, 0]) >= CORNER_DEG
        one_sided = {}
        for tag, side in (("after", 0), ("before", 1)):
            if b_turn or a_turn:
                tb = _one_sided_tangent(outline.side_b, ribs[k, 1], side == 0) if b_turn else e0 / lb
                ta = _one_sided_tangent(outline.side_a, ribs[k, 0], side == 0) if a_turn else e2 / la
                one_sided[tag] = (lb * tb, la * ta)
        m = mids[min(k + 1, K - 1)] - mids[max(k - 1, 0)]
        # E_k(1/2)'s length: the ribs' spacing at their inner control points (geometric mean of
        # the two neighbours), so the inner rows share out the real distance between ribs
        m *= (la + lb) / 2 / np.linalg.norm(m)
        e1 = 2 * m - (e0 + e2) / 2
        if k in (0, K - 1) and np.abs(rows[k][:, 0]).max() < 1e-6 and abs(e0[0]) > 0.999 * lb \
                and abs(e2[0]) > 0.999 * la:
            e1 = (e0 + e2) / 2  # an end curve on the symmetry plane: cross it square
        elif on_symmetry_plane(outline.side_b, ribs[k, 1]) or on_symmetry_plane(outline.side_a, ribs[k, 0]):
            # stay in the plane of x and the centre line; along the centre line keep the centre
            # line's own spacing, as the rib's first control point sits square across from it
            t = e0 if on_symmetry_plane(outline.side_b, ribs[k, 1]) else e2
            e1 = (e1 @ x) * x + t
        field_k = {"after": (np.array([e0, e1, e2]), lb, la), "before": (np.array([e0, e1, e2]), lb, la)}
        for tag, (f0, f2) in one_sided.items():
            field_k[tag] = (np.array([f0, e1, f2]), lb, la)
        fields.append(field_k)
    faces = []
    for k in range(K - 1):
        (sub_b, ib, tb0, tb1), (sub_a, ia, ta0, ta1) = subs[k]
        e, lb, la = fields[k]["after"]
        plus = _cross(after[k][0] / lb, after[k][1] / la, e)
        e, lb, la = fields[k + 1]["before"]
        minus = _cross(before[k][0] / lb, before[k][1] / la, e)
        grid = np.array([rows[k], rows[k] + plus / 3, rows[k + 1] - minus / 3, rows[k + 1]])  # [v, u]
        grid[:, 0] = sub_b
        grid[:, 3] = sub_a
        net = grid.transpose(1, 0, 2).copy()  # [u, v]
        sides = {
            "u0": _side_ref(outline.side_b, ib, tb0, tb1),
            "u1": _side_ref(outline.side_a, ia, ta0, ta1),
            "v0": None, "v1": None,
        }
        if k == 0:
            c, rev = outline.begin_curve
            sides["v0"] = SideRef(c, 1.0, 0.0) if rev else SideRef(c, 0.0, 1.0)
        if k == K - 2:
            c, rev = outline.end_curve
            sides["v1"] = SideRef(c, 1.0, 0.0) if rev else SideRef(c, 0.0, 1.0)
        faces.append(FacePatch(outline.name, k, net, sides))
    # make S_u x S_v point outwards (u reversed if needed)
    if outward_by_loop:
        inward = not faces_follow_loop(outline)
    else:
        mid = faces[len(faces) // 2].net
        n = np.cross(mid[3, 1] + mid[3, 2] - mid[0, 1] - mid[0, 2], mid[1, 3] + mid[2, 3] - mid[1, 0] - mid[2, 0])
        inward = n @ outline.outward < 0
    if inward:
        for f in faces:
            f.net = f.net[::-1].copy()
            s = f.sides
            flip = lambda r: None if r is None else SideRef(r.curve, r.t1, r.t0, r.mirror)  # noqa: E731
            f.sides = {"v0": flip(s["v0"]), "v1": flip(s["v1"]), "u0": s["u1"], "u1": s["u0"]}
    return faces


def faces_follow_loop(outline: RegionOutline) -> bool:
    """True when a face's (u, v) boundary, walked counter-clockwise (begin curve B -> A, side A,
    end curve, side B), runs round the region as its loop does, counter-clockwise seen from
    outside: S_u x S_v then points out of the body."""
    c, rev = outline.begin_curve
    return next(r for ci, r in outline.loop if ci == c) == rev


def check_ribs(outline: RegionOutline, ribs: np.ndarray) -> None:
    """Ribs must run from (0, 0) to (n_A, n_B), strictly increasing on both sides, with a rib at
    every junction of either side (each face side then lies on one wireframe cubic).

    Raises:
        RegionLayoutError: naming the region and the side curve a face would span past its end.
    """
    na, nb = outline.side_a.n, outline.side_b.n
    ok = len(ribs) >= 2 and np.allclose(ribs[0], 0) and np.allclose(ribs[-1], (na, nb))
    ok = ok and bool(np.all(np.diff(ribs[:, 0]) > 0) and np.all(np.diff(ribs[:, 1]) > 0))
    if not ok:
        raise RegionLayoutError(f"region {outline.name}: its ribs cross or share an end")
    curves = load_topology().curves
    for chain, col, label in ((outline.side_a, 0, "A"), (outline.side_b, 1, "B")):
        missing = [j for j in range(1, chain.n) if not np.any(np.abs(ribs[:, col] - j) < 1e-9)]
        if missing:
            raise RegionLayoutError(f"region {outline.name}: no rib ends where side {label}'s curve "
                                    f"{curves[chain.curves[missing[0] - 1]].name} ends")


def region_net(outline: RegionOutline, samples: BoundarySamples, pairs: list[OptimalPair],
               min_gap_mm: float) -> RegionNet:
    """Ribs, control curves and faces of one region from its skeleton's optimal pairs.

    Raises:
        RegionLayoutError: the ribs cross or miss a junction of a side (:func:`check_ribs`).
    """
    na, nb = outline.side_a.n, outline.side_b.n
    skel = skeleton_ribs(samples, pairs)
    if len(skel):
        sa_t, la_t = outline.side_a.arc_table()
        sb_t, lb_t = outline.side_b.arc_table()
        skew = np.abs(np.interp(skel[:, 0], sa_t, la_t) / la_t[-1] - np.interp(skel[:, 1], sb_t, lb_t) / lb_t[-1])
        skel = skel[skew <= MAX_RIB_SKEW]
    skel = _monotone(skel, na, nb)
    corr = dtw_correspondence(outline, samples, skel)
    ribs, kinds = net_ribs(outline, skel, corr, min_gap_mm, samples)
    check_ribs(outline, ribs)
    rows = rib_rows(outline, ribs)
    turn = np.array([max(side_turn_deg(outline.side_a, a), side_turn_deg(outline.side_b, b)) for a, b in ribs])
    return RegionNet(outline.name, ribs, rows, kinds, patches(outline, ribs, rows), corr, turn)


def side_turn_deg(chain: Chain, s: float) -> float:
    """Angle (degrees) between the incoming and outgoing tangents of a chain at parameter s."""
    j = int(round(s))
    if abs(s - j) > 1e-9 or j <= 0 or j >= chain.n:
        return 0.0
    a = bezier_derivs(chain.poles[j - 1], [1.0])[0]
    b = bezier_derivs(chain.poles[j], [0.0])[0]
    c = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))
