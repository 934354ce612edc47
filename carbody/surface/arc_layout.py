"""A region laid out from its boundary curves alone: ribs at equal arc-length fractions.

The paper's layout (:mod:`~carbody.surface.regions` -> :mod:`~carbody.surface.skeleton` ->
:mod:`~carbody.surface.control_net`) chooses a region's ribs in 2D, on the boundary projected
onto its best-fit plane. A fitted car can bend a region until that projection folds (a wheel arch
whose top turns back over itself, a hood side that runs back past the belt line seen from above)
or until the ribs it gives cross; no plane then shows the region as a simple polygon, and no
skeleton can be found. Such a region is laid out here instead, with no projection at all:

* its two sides are matched by arc-length fraction, the correspondence of a Coons patch bounded
  by the same four curves: the point a fraction f along side A faces the point f along side B.
  Both fractions grow together, so ribs so placed can neither cross nor share an end, whatever
  the region's shape in 3D;
* every junction of either side gets a rib, to its partner at the same fraction; a junction whose
  partner falls within ``min_gap_mm`` of a junction of the other side is joined to that junction
  instead (consecutive in fraction order, so the order still holds), so each face side lies on
  one wireframe cubic and is an exact sub-arc of it (de Casteljau split);
* where a face's side turns too much (a quarter of a wheel arch) a rib is added at its middle, as
  in the paper's layout (:func:`~carbody.surface.control_net.refine_turns`).

The ribs' control curves and the bicubic faces between them are built exactly as in the paper's
layout (:func:`~carbody.surface.control_net.rib_rows`, :func:`~carbody.surface.control_net.patches`):
the begin and end curves' blended cross-section, and one shared cross-derivative field per rib,
so the region is G1 across its inner ribs wherever its sides are smooth.

Everything here is numpy; no OCCT.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from carbody.errors import SurfaceError
from carbody.surface.control_net import (MonotoneCurve, RegionNet, patches, refine_turns,
                                         rib_rows, side_turn_deg)
from carbody.surface.regions import Chain, RegionOutline
from carbody.topology import load_topology

#: Points of the arc-length correspondence per side curve (for the turn refinement's partners).
CORRESPONDENCE_PER_CURVE = 16


def _fractions(chain: Chain) -> tuple[Callable, Callable]:
    """(s -> arc-length fraction, fraction -> s) of a chain, from its dense arc table."""
    s, arc = chain.arc_table()
    total = arc[-1]
    return (lambda x: np.interp(x, s, arc) / total), (lambda f: np.interp(np.asarray(f) * total, arc, s))


def arc_length_correspondence(outline: RegionOutline) -> np.ndarray:
    """(m, 2) chain parameters (s_A, s_B) at equal arc-length fractions, from (0, 0) to (n_A, n_B)."""
    n = CORRESPONDENCE_PER_CURVE * max(outline.side_a.n, outline.side_b.n)
    f = np.linspace(0.0, 1.0, n + 1)
    _, s_of_a = _fractions(outline.side_a)
    _, s_of_b = _fractions(outline.side_b)
    out = np.stack([s_of_a(f), s_of_b(f)], axis=1)
    out[0], out[-1] = (0.0, 0.0), (outline.side_a.n, outline.side_b.n)
    return out


def arc_length_ribs(outline: RegionOutline, min_gap_mm: float) -> tuple[np.ndarray, list[str]]:
    """The ribs of a region laid out by arc length (see module docstring).

    Args:
        outline: the region.
        min_gap_mm: a junction whose partner lands closer than this (arc length, mm) to a
            junction of the other side is joined to that junction.
    Returns:
        (K, 2) float (s_A, s_B) from (0, 0) to (n_A, n_B), strictly increasing in both, and each
        rib's kind ("end", "junction", "refine").
    """
    na, nb = outline.side_a.n, outline.side_b.n
    frac_a, s_of_a = _fractions(outline.side_a)
    frac_b, s_of_b = _fractions(outline.side_b)
    length_a = outline.side_a.arc_table()[1][-1]
    length_b = outline.side_b.arc_table()[1][-1]
    # every inner junction of either side as (fraction, side 0 = A / 1 = B, junction number)
    events = sorted([(float(frac_a(j)), 0, j) for j in range(1, na)] +
                    [(float(frac_b(k)), 1, k) for k in range(1, nb)])
    inner, k = [], 0
    while k < len(events):
        f, side, j = events[k]
        if k + 1 < len(events) and events[k + 1][1] != side:
            # the partner of either junction falls near the other: one rib joins the two
            if (events[k + 1][0] - f) * min(length_a, length_b) < min_gap_mm:
                other = events[k + 1][2]
                inner.append((float(j), float(other)) if side == 0 else (float(other), float(j)))
                k += 2
                continue
        inner.append((float(j), float(s_of_b(f))) if side == 0 else (float(s_of_a(f)), float(j)))
        k += 1
    ribs = np.array([(0.0, 0.0), *inner, (float(na), float(nb))])
    kinds = ["end"] + ["junction"] * len(inner) + ["end"]
    curve = MonotoneCurve(arc_length_correspondence(outline))
    return refine_turns(outline, None, ribs, kinds, curve)


def arc_length_net(outline: RegionOutline, min_gap_mm: float, reason: str = "") -> RegionNet:
    """Ribs, control curves and faces of one region laid out by arc length.

    Args:
        outline: the region (checked by :func:`~carbody.surface.regions.check_region_geometry`).
        min_gap_mm: see :func:`arc_length_ribs`.
        reason: why the paper's layout was not used (kept in the net's ``layout_note``).
    Raises:
        SurfaceError: a rib of zero length (the two sides touch), naming the region and curves.
    """
    ribs, kinds = arc_length_ribs(outline, min_gap_mm)
    a_pts, b_pts = outline.side_a.points(ribs[:, 0]), outline.side_b.points(ribs[:, 1])
    touch = np.flatnonzero(~(np.linalg.norm(a_pts - b_pts, axis=1)[1:-1] > 0)) + 1
    if len(touch):
        curves = load_topology().curves
        a, b = ribs[touch[0]]
        on_a = curves[outline.side_a.curves[min(int(a), outline.side_a.n - 1)]].name
        on_b = curves[outline.side_b.curves[min(int(b), outline.side_b.n - 1)]].name
        raise SurfaceError(f"region {outline.name}: degenerate: its two sides touch (curves {on_a} and {on_b})")
    rows = rib_rows(outline, ribs)
    turn = np.array([max(side_turn_deg(outline.side_a, a), side_turn_deg(outline.side_b, b)) for a, b in ribs])
    faces = patches(outline, ribs, rows, outward_by_loop=True)
    return RegionNet(outline.name, ribs, rows, kinds, faces, arc_length_correspondence(outline), turn,
                     layout="arc_length", layout_note=reason)
