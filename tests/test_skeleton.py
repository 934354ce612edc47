"""The Skeleton Generation Algorithm (paper IV.C) on shapes whose answer is known."""
from __future__ import annotations

import numpy as np
import pytest
import shapely

from carbody.surface.regions import outward_normals_2d
from carbody.surface.skeleton import (AREA_MIN_FRACTION, AREA_RATIO_MAX, AREA_SUM_TOL, FOLD_RATIO_MIN,
                                      NORMAL_COS_MIN, optimal_pair, optimal_pairs, skeleton_line)

SPACING = 20.0


def clockwise_samples(corners, spacing=SPACING) -> np.ndarray:
    """Points every ~``spacing`` along a polygon given by its corners in clockwise order."""
    c = np.asarray(corners, float)
    pts = []
    for a, b in zip(c, np.roll(c, -1, axis=0)):
        k = max(1, int(round(np.linalg.norm(b - a) / spacing)))
        pts.append(a + (b - a) * np.linspace(0, 1, k + 1)[:-1, None])
    return np.concatenate(pts)


def shoelace(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def test_samples_are_clockwise_with_outward_normals():
    pts = clockwise_samples([(0, 0), (0, 100), (300, 100), (300, 0)])
    x, y = pts[:, 0], pts[:, 1]
    assert np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) < 0  # clockwise
    poly = shapely.Polygon(pts)
    n = outward_normals_2d(pts)
    assert not shapely.contains_xy(poly, *(pts + 5 * n).T).any()
    assert shapely.contains_xy(poly, *(pts - 5 * n).T).all()


def test_parallelogram_first_pair_is_figure_16_case_1():
    # Fig. 16: the optimal pair of a parallelogram joins its two long sides through the centre,
    # halving it (not a diagonal, not a chord between the short sides).
    corners = [(0, 0), (100, 200), (400, 200), (300, 0)]
    pts = clockwise_samples(corners)
    pair = optimal_pair(pts, outward_normals_2d(pts))
    a, b = pts[pair.i], pts[pair.j]
    assert {a[1], b[1]} == {0.0, 200.0}  # one end on each long side
    assert np.allclose((a + b) / 2, [200, 100], atol=SPACING)
    assert pair.area1 == pytest.approx(pair.area2, rel=0.05)
    assert pair.area1 + pair.area2 == pytest.approx(shoelace(pts), rel=1e-9)
    assert pair.arearatio > FOLD_RATIO_MIN


def test_rectangle_ribs_cross_it_and_skeleton_is_its_centre_line():
    w, h = 400.0, 100.0
    pts = clockwise_samples([(0, 0), (0, h), (w, h), (w, 0)])
    n = outward_normals_2d(pts)
    pairs = optimal_pairs(pts, n, min_height=2 * SPACING)
    assert len(pairs) >= 3
    first = pairs[0]
    assert abs((pts[first.i][0] + pts[first.j][0]) / 2 - w / 2) <= SPACING / 2
    for p in pairs:  # every rib runs from the bottom side to the top side
        assert {pts[p.i][1], pts[p.j][1]} == {0.0, h}
    start = int(np.argmin(np.linalg.norm(pts - [0, h / 2], axis=1)))
    end = int(np.argmin(np.linalg.norm(pts - [w, h / 2], axis=1)))
    line = skeleton_line(pts, pairs, start, end)
    assert np.allclose(line[1:-1, 1], h / 2)
    assert np.all(np.diff(line[:, 0]) > 0)  # ordered along the rectangle
    assert line[0][0] == 0 and line[-1][0] == w  # ends on the boundary


def test_l_shape_is_first_cut_at_its_elbow():
    corners = [(0, 0), (0, 300), (100, 300), (100, 100), (300, 100), (300, 0)]
    pts = clockwise_samples(corners)
    pairs = optimal_pairs(pts, outward_normals_2d(pts), min_height=2 * SPACING)
    first = pairs[0]
    assert {tuple(pts[first.i]), tuple(pts[first.j])} == {(0.0, 0.0), (100.0, 100.0)}
    # the two arms are then cut across, each rib staying inside the L
    poly = shapely.Polygon(pts)
    for p in pairs:
        chord = shapely.LineString([pts[p.i], pts[p.j]])
        assert poly.buffer(1e-6).covers(chord)


def test_every_pair_satisfies_equation_6():
    corners = [(0, 0), (40, 180), (260, 230), (420, 120), (380, -20)]
    pts = clockwise_samples(corners, 10)
    n = outward_normals_2d(pts)
    pairs = optimal_pairs(pts, n, min_height=20)
    assert pairs
    p = pairs[0]  # the first pair is evaluated on the whole polygon: recompute eq. 6 by hand
    a1 = shoelace(pts[p.i:p.j + 1])
    a2 = shoelace(np.r_[pts[p.j:], pts[:p.i + 1]])
    whole = shoelace(pts)
    assert abs(a1 + a2 - whole) / whole < AREA_SUM_TOL
    assert max(a1, a2) / min(a1, a2) < AREA_RATIO_MAX
    assert min(a1, a2) / whole > AREA_MIN_FRACTION
    assert -np.dot(n[p.i], n[p.j]) > NORMAL_COS_MIN
    assert p.arearatio > FOLD_RATIO_MIN
    assert (p.area1, p.area2) in ((pytest.approx(a1), pytest.approx(a2)), (pytest.approx(a2), pytest.approx(a1)))


def test_wheel_arch_skeleton_follows_the_mid_radius():
    # a fender round a wheel: the region between two concentric half circles (Fig. 15, 17)
    r_in, r_out = 300.0, 450.0
    t_out = np.linspace(np.pi, 0, 60)  # clockwise: outer arc left -> right over the top
    t_in = np.linspace(0, np.pi, 40)
    outer = np.c_[r_out * np.cos(t_out), r_out * np.sin(t_out)]
    inner = np.c_[r_in * np.cos(t_in), r_in * np.sin(t_in)]
    corners = np.r_[outer, inner]
    pts = clockwise_samples(corners)
    pairs = optimal_pairs(pts, outward_normals_2d(pts), min_height=2 * SPACING)
    assert len(pairs) >= 4
    radius = np.hypot(*pts.T)
    for p in pairs:  # every rib joins the inner arc to the outer arc
        assert sorted(radius[[p.i, p.j]]) == [pytest.approx(r_in, abs=1), pytest.approx(r_out, abs=1)]
    start = int(np.argmin(np.linalg.norm(pts - [-(r_in + r_out) / 2, 0], axis=1)))
    end = int(np.argmin(np.linalg.norm(pts - [(r_in + r_out) / 2, 0], axis=1)))
    line = skeleton_line(pts, pairs, start, end)
    mid = np.hypot(*line[1:-1].T)
    assert np.all(np.abs(mid - (r_in + r_out) / 2) < 0.08 * (r_in + r_out) / 2)
    angle = np.arctan2(line[:, 1], line[:, 0])
    assert np.all(np.diff(angle) < 0)  # in order round the arch


def test_no_pair_in_a_shape_too_thin_to_cut():
    pts = clockwise_samples([(0, 0), (0, 30), (60, 30), (60, 0)], 10)
    assert optimal_pairs(pts, outward_normals_2d(pts), min_height=40) == []


def test_skeleton_of_every_template_region_is_found(templates):
    # its speed (budget 0.1 s a region) is measured in benchmarks/bench_surface.py, not here
    from carbody.surface.body import region_skeleton, wheelbase_of
    from carbody.surface.regions import region_outlines

    row, wf = templates[0]
    wb = wheelbase_of(wf.control_points)
    for outline in region_outlines(wf.control_points):
        sk = region_skeleton(outline, wb)
        assert len(sk.line) == len(sk.pairs) + 2
        spacing = np.linalg.norm(np.diff(np.r_[sk.samples.points2d, sk.samples.points2d[:1]], axis=0), axis=1)
        assert np.median(spacing) == pytest.approx(20.0, rel=0.15)
