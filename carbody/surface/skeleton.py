"""The Skeleton Generation Algorithm for Complex Shape (paper IV.C, eq. 5–6, Algorithm 1).

Read as SPEC "Reading the paper's surface section" says: recursive bisection. The optimal pair
(P_i, P_j) of a polygon is the chord that maximises

    ijvalue = arearatio · min(a1, a2)/max(a1, a2) · min(H1, H2)/max(H1, H2) · (H1 + H2)/|P_i P_j|

under eq. 6:

    |a1 + a2 − allarea| / allarea < 0.1      (the chord stays inside)
    max(a1, a2) / min(a1, a2)     < 1.5
    min(a1, a2) / allarea         > 0.3
    arearatio                     > 0.2      (folded overlap / allarea)
    cos(PN_i, −PN_j)              > 0.7      (outward normals face opposite ways)

where a1, a2 are the areas of the two parts the chord cuts the polygon into, H1, H2 the largest
distance of each part's boundary points from the chord, and arearatio the area where the two
parts overlap when one is folded about the chord, over allarea. Each part is cut again the same
way until no chord satisfies eq. 6; a boundary point already used by a pair is not reused.

Two readings are ours and argued here:

* eq. 6 is scale-free, so on a finely sampled boundary it would bisect down to single samples.
  A part is therefore not cut when either side would be thinner than ``min_height`` (default two
  sample spacings, about 100 mm on a car): the ribs then end up a few spacings apart, as in the
  paper's Fig. 17.
* Areas come from shapely (vectorised over all candidate chords: rings built with
  ``shapely.linearrings(..., indices=...)``), after a cheap prefix-sum shoelace pre-filter that
  gives the same |signed area|; a chord that leaves the region makes a1 + a2 exceed allarea and
  fails the first constraint, as the paper intends. A chord that only grazes outside passes
  that test, so chords are also required to lie inside the region (``shapely.covers``): the
  constraint's intent, tested exactly.

Everything works on 2D points in normalised units; no OCCT.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

#: eq. 6 thresholds.
AREA_SUM_TOL = 0.1
AREA_RATIO_MAX = 1.5
AREA_MIN_FRACTION = 0.3
FOLD_RATIO_MIN = 0.2
NORMAL_COS_MIN = 0.7


@dataclass
class OptimalPair:
    """One optimal pair: boundary sample indices i < j, its ijvalue and eq. 6 quantities."""

    i: int
    j: int
    value: float
    area1: float
    area2: float
    arearatio: float
    h1: float
    h2: float
    depth: int


def _ragged_index(starts: np.ndarray, lengths: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat cyclic positions start, start+1, ... (mod m) of several runs, and each run's id."""
    total = int(lengths.sum())
    run = np.repeat(np.arange(len(starts)), lengths)
    offset = np.arange(total) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return (np.repeat(starts, lengths) + offset) % m, run


def _fold_overlap(c1, run1, pi, unit, poly2, sel) -> np.ndarray:
    """Area where part 1 of each selected chord, folded about the chord, overlaps part 2."""
    in1 = np.isin(run1, sel)
    rel = c1[in1] - pi[run1[in1]]
    u = unit[run1[in1]]
    along = (rel * u).sum(axis=1, keepdims=True) * u
    folded = pi[run1[in1]] + 2 * along - rel
    _, run_sel = np.unique(run1[in1], return_inverse=True)
    f1 = shapely.polygons(shapely.linearrings(folded, indices=run_sel))
    p2 = poly2[sel]
    bad = ~(shapely.is_valid(f1) & shapely.is_valid(p2))
    if bad.any():
        f1[bad] = shapely.make_valid(f1[bad])
        p2[bad] = shapely.make_valid(p2[bad])
    return shapely.area(shapely.intersection(f1, p2))


def candidate_values(points: np.ndarray, normals: np.ndarray, part: np.ndarray, free: np.ndarray,
                     min_height: float = 0.0, best_only: bool = False) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """ijvalue of every chord of one polygon that satisfies eq. 6.

    Args:
        points: (n, 2) float, all boundary samples (clockwise).
        normals: (n, 2) float, unit outward normals of the samples.
        part: (m,) int, the polygon's sample indices in boundary order (a part of the region).
        free: (n,) bool, samples not yet used by a pair.
        min_height: smallest H1, H2 allowed (normalised units).
        best_only: fold only as many chords as needed to be sure of the best one (the others
            are left out of the result).
    Returns:
        (k, 2) positions (p, q) into ``part`` of the admissible chords, and a dict of (k,) arrays
        value, area1, area2, arearatio, h1, h2.
    """
    m = len(part)
    empty = np.zeros((0, 2), int), {k: np.zeros(0) for k in ("value", "area1", "area2", "arearatio", "h1", "h2")}
    if m < 4:
        return empty
    pp, qq = np.triu_indices(m, k=2)
    keep = (qq - pp <= m - 2) & free[part[pp]] & free[part[qq]]
    pp, qq = pp[keep], qq[keep]
    ni, nj = normals[part[pp]], normals[part[qq]]
    keep = -(ni * nj).sum(axis=1) > NORMAL_COS_MIN
    pp, qq = pp[keep], qq[keep]
    if len(pp) == 0:
        return empty
    xy = points[part]
    allarea = float(shapely.area(shapely.polygons(xy)))
    if allarea <= 0:
        return empty

    # cheap pre-filter on eq. 6's area conditions: shoelace sums by prefix sums (the same
    # |signed area| shapely gives a ring); the survivors are measured with shapely below
    x, y = xy[:, 0], xy[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    prefix = np.r_[0.0, np.cumsum(cross)]
    chord_term = x[qq] * y[pp] - x[pp] * y[qq]
    s1 = prefix[qq] - prefix[pp] + chord_term
    s2 = prefix[-1] - s1
    b1, b2 = 0.5 * np.abs(s1), 0.5 * np.abs(s2)
    lo, hi = np.minimum(b1, b2), np.maximum(b1, b2)
    with np.errstate(divide="ignore", invalid="ignore"):
        keep = (np.abs(b1 + b2 - allarea) / allarea < AREA_SUM_TOL) & (hi / lo < AREA_RATIO_MAX) \
            & (lo / allarea > AREA_MIN_FRACTION)
    pp, qq = pp[keep], qq[keep]
    if len(pp) == 0:
        return empty

    # the two parts of every chord as ragged rings: part[p..q] and part[q..p] (cyclic)
    len1, len2 = qq - pp + 1, m - (qq - pp) + 1
    idx1, run1 = _ragged_index(pp, len1, m)
    idx2, run2 = _ragged_index(qq, len2, m)
    c1, c2 = xy[idx1], xy[idx2]
    poly1 = shapely.polygons(shapely.linearrings(c1, indices=run1))
    poly2 = shapely.polygons(shapely.linearrings(c2, indices=run2))
    a1, a2 = shapely.area(poly1), shapely.area(poly2)
    lo, hi = np.minimum(a1, a2), np.maximum(a1, a2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = (np.abs(a1 + a2 - allarea) / allarea < AREA_SUM_TOL) & (hi / lo < AREA_RATIO_MAX) \
            & (lo / allarea > AREA_MIN_FRACTION)

    # largest distance of each part's points from its chord
    pi, pj = xy[pp], xy[qq]
    chord = pj - pi
    length = np.linalg.norm(chord, axis=1)
    unit = chord / np.maximum(length, 1e-300)[:, None]

    def heights(coords, run, starts_len):
        rel = coords - pi[run]
        d = np.abs(rel[:, 0] * unit[run, 1] - rel[:, 1] * unit[run, 0])
        return np.maximum.reduceat(d, np.r_[0, np.cumsum(starts_len)[:-1]])

    h1, h2 = heights(c1, run1, len1), heights(c2, run2, len2)
    ok &= (np.minimum(h1, h2) >= min_height) & (length > 0)
    sel = np.flatnonzero(ok)
    if len(sel) == 0:
        return empty
    # a chord must stay inside the region (what the first condition of eq. 6 approximates);
    # testing it exactly also keeps both parts simple polygons for the fold below
    region = shapely.buffer(shapely.polygons(xy), 1e-9 * np.sqrt(allarea))
    shapely.prepare(region)
    inside = shapely.covers(region, shapely.linestrings(np.stack([pi[sel], pj[sel]], axis=1)))
    ok[sel[~inside]] = False
    sel = sel[inside]
    if len(sel) == 0:
        return empty

    # fold part 1 about its chord and overlap it with part 2. The overlap is at most the smaller
    # part, which bounds ijvalue; with ``best_only`` chords are folded in order of that bound
    # and the search stops once no unfolded chord can beat the best folded one.
    with np.errstate(divide="ignore", invalid="ignore"):
        shape_factor = lo / hi * np.minimum(h1, h2) / np.maximum(h1, h2) * (h1 + h2) / length
    bound = np.minimum(lo / allarea, 0.5) * shape_factor
    sel = sel[np.argsort(-bound[sel], kind="stable")]
    arearatio = np.zeros(len(pp))
    evaluated = np.zeros(len(pp), bool)
    best = -np.inf
    chunk = 24 if best_only else len(sel)
    for start in range(0, len(sel), chunk):
        part_sel = np.sort(sel[start:start + chunk])
        if bound[part_sel].max() <= best:
            break
        arearatio[part_sel] = _fold_overlap(c1, run1, pi, unit, poly2, part_sel) / allarea
        evaluated[part_sel] = True
        good = part_sel[arearatio[part_sel] > FOLD_RATIO_MIN]
        if len(good):
            best = max(best, float((arearatio[good] * shape_factor[good]).max()))
    ok &= evaluated
    ok &= arearatio > FOLD_RATIO_MIN
    sel = np.flatnonzero(ok)
    value = arearatio * shape_factor
    out = {"value": value[sel], "area1": a1[sel], "area2": a2[sel], "arearatio": arearatio[sel],
           "h1": h1[sel], "h2": h2[sel]}
    return np.stack([pp[sel], qq[sel]], axis=1), out


def optimal_pair(points: np.ndarray, normals: np.ndarray, part: np.ndarray | None = None,
                 free: np.ndarray | None = None, min_height: float = 0.0) -> OptimalPair | None:
    """The optimal pair of one polygon (max ijvalue under eq. 6), or None if no chord qualifies.

    Args:
        points: (n, 2) clockwise boundary samples; normals (n, 2) their unit outward normals.
        part: (m,) sample indices of the polygon in boundary order; all samples by default.
        free: (n,) bool, samples a pair may use; all by default.
    """
    part = np.arange(len(points)) if part is None else np.asarray(part)
    free = np.ones(len(points), bool) if free is None else free
    pq, q = candidate_values(points, normals, part, free, min_height, best_only=True)
    if len(pq) == 0:
        return None
    k = int(np.argmax(q["value"]))
    i, j = sorted((int(part[pq[k, 0]]), int(part[pq[k, 1]])))
    return OptimalPair(i, j, float(q["value"][k]), float(q["area1"][k]), float(q["area2"][k]),
                       float(q["arearatio"][k]), float(q["h1"][k]), float(q["h2"][k]), 0)


def optimal_pairs(points: np.ndarray, normals: np.ndarray, min_height: float = 0.0,
                  max_pairs: int = 200) -> list[OptimalPair]:
    """Algorithm 1: the optimal pair of the whole boundary, then of each part, recursively.

    Args:
        points: (n, 2) float, clockwise boundary samples (normalised units).
        normals: (n, 2) float, unit outward normals.
        min_height: a part is not cut when either side would be thinner than this.
        max_pairs: safety stop.
    Returns:
        the pairs in the order found (breadth first: the first pair halves the whole region).
    """
    free = np.ones(len(points), bool)
    queue: list[tuple[np.ndarray, int]] = [(np.arange(len(points)), 0)]
    pairs: list[OptimalPair] = []
    while queue and len(pairs) < max_pairs:
        part, depth = queue.pop(0)
        pair = optimal_pair(points, normals, part, free, min_height)
        if pair is None:
            continue
        pair.depth = depth
        pairs.append(pair)
        free[[pair.i, pair.j]] = False
        p, q = sorted((int(np.flatnonzero(part == pair.i)[0]), int(np.flatnonzero(part == pair.j)[0])))
        queue.append((part[p:q + 1], depth + 1))
        queue.append((np.r_[part[q:], part[:p + 1]], depth + 1))
    return pairs


def skeleton_line(points: np.ndarray, pairs: list[OptimalPair], start: int, end: int) -> np.ndarray:
    """The skeleton: pair midpoints in order along the region, ends on the boundary.

    Pairs are ordered by how far along the boundary they sit from ``start`` towards ``end``
    (the mean of the arc positions of their two ends, one counted each way round).

    Args:
        points: (n, 2) boundary samples.
        pairs: optimal pairs.
        start, end: sample indices of the skeleton's two ends on the boundary.
    Returns:
        (len(pairs) + 2, 2) float.
    """
    seg = np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = arc[-1]

    def fwd(a, b):  # arc length from a to b walking forward
        d = arc[b] - arc[a]
        return d if d >= 0 else d + total

    span = fwd(start, end)
    keys = []
    for p in pairs:
        # one end is reached walking forward from start before the end point, the other after
        ti, tj = fwd(start, p.i), fwd(start, p.j)
        first, second = (ti, tj) if ti <= tj else (tj, ti)
        progress_a = first / span if span > 0 else 0.0
        progress_b = (total - second) / (total - span) if total > span else 0.0
        keys.append((progress_a + progress_b) / 2)
    order = np.argsort(keys, kind="stable")
    mids = [(points[pairs[k].i] + points[pairs[k].j]) / 2 for k in order]
    return np.array([points[start], *mids, points[end]]).reshape(-1, 2)
