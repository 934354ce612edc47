"""The photo's own evidence between the marks: the car's outline.

Twelve to twenty marks leave the shape between them to the library prior; the photo shows it.
Two steps:

1. :func:`segment_car` cuts the car out of the photo (OpenCV's GrabCut on a downscaled copy,
   seeded by the marks' convex hull: sure car well inside it, probably car just round it,
   probably background further out, background beyond), and :func:`check_segmentation` says
   whether the cut is one to trust (a mask far larger or smaller than the hull, one that runs
   off the photo's frame all round, is not: the fit then goes on with the marks alone).
2. :func:`outline_targets` reads, at a fitted car, where its projected outline should be: points
   sampled on the wireframe's curves that lie on the projected body's outer outline (the
   silhouette of its regions, both halves), each matched along the outline's normal to the
   nearest edge of the car's mask (ICP point-to-line). The lower outline is not used (tyres,
   shadow and ground lie there, and the body's sill is not its silhouette), nor matches further
   than ``outline_search_spread`` of the marks' spread, nor points whose edge is the photo's
   frame. The matches are soft pseudo-observations of the same linear solve as the marks
   (:func:`carbody.fit.solve.solve_gauss`'s ``outline``): a curve point is linear in the
   control points, so the mix solve extends to them. :func:`follow_outline` alternates match and
   solve a few times at the view found: the outline shapes and sizes the car, it does not
   choose the view (measured: it does not tell views apart).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from carbody.camera import View, apply_homography, project
from carbody.fit.solve import reaches_camera
from carbody.policy import FitPolicy
from carbody.wireframe import MIRROR, POINTS_PER_CURVE


@dataclass(frozen=True)
class CarOutline:
    """The car cut out of a photo.

    Attributes:
        mask: (h', w') bool, the car's pixels on the downscaled photo.
        soft: (h', w') float, the mask smoothed over a pixel: its 0.5 level is the car's edge
            to a fraction of a pixel.
        scale: mask pixels per photo pixel (≤ 1).
        image_size: (width, height) of the photo, px.
        usable: whether the cut is trusted (:func:`check_segmentation`); ``reason`` says why not.
        hull_ratio: the mask's area over the marks' convex hull's.
        seconds: the segmentation's wall time.
    """

    mask: np.ndarray
    soft: np.ndarray
    scale: float
    image_size: tuple[int, int]
    usable: bool = True
    reason: str = ""
    hull_ratio: float = 1.0
    seconds: float = 0.0

    def carness(self, uv: np.ndarray) -> np.ndarray:
        """(n,) float in [0, 1]: the smoothed mask at photo pixels (n, 2), bilinear (off the
        photo: 0); 0.5 is the car's edge."""
        from scipy.ndimage import map_coordinates

        p = np.asarray(uv, dtype=float) * self.scale - 0.5  # pixel centres
        return map_coordinates(self.soft, [p[:, 1], p[:, 0]], order=1, mode="constant", cval=0.0)


def segment_car(image: np.ndarray, marks_uv: np.ndarray, policy: FitPolicy) -> CarOutline:
    """The car's mask by GrabCut seeded by the marks' convex hull (module docstring).

    Args:
        image: (h, w, 3) uint8 RGB (or (h, w) grey) photo.
        marks_uv: (k, 2) float, the marks, photo pixels.
        policy: ``outline_*`` thresholds (the hull's growth for each seed, the working size).
    """
    import cv2

    start = time.perf_counter()
    rgb = np.asarray(image)
    if rgb.ndim == 2:
        rgb = np.repeat(rgb[..., None], 3, axis=2)
    rgb = np.ascontiguousarray(rgb[..., :3], dtype=np.uint8)
    h, w = rgb.shape[:2]
    scale = min(1.0, policy.outline_working_px / max(h, w))
    small = cv2.resize(rgb, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    hull = cv2.convexHull(np.asarray(marks_uv, dtype=np.float32) * scale).reshape(-1, 2)
    centre = hull.mean(axis=0)

    def grown(factor: float) -> np.ndarray:
        return np.round(centre + (hull - centre) * factor).astype(np.int32)

    seeds = np.full(small.shape[:2], cv2.GC_BGD, np.uint8)
    cv2.fillPoly(seeds, [grown(policy.outline_background_growth)], cv2.GC_PR_BGD)
    cv2.fillPoly(seeds, [grown(policy.outline_probable_growth)], cv2.GC_PR_FGD)
    cv2.fillPoly(seeds, [grown(policy.outline_sure_shrink)], cv2.GC_FGD)
    background, foreground = np.zeros((1, 65)), np.zeros((1, 65))
    cv2.grabCut(small, seeds, None, background, foreground, policy.outline_iterations, cv2.GC_INIT_WITH_MASK)
    car = ((seeds == cv2.GC_FGD) | (seeds == cv2.GC_PR_FGD)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(car)
    if count > 1:  # the car is one piece: stray patches of background colour are not
        car = labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    car = _filled(car.astype(np.uint8))
    soft = cv2.GaussianBlur(car.astype(np.float32), (0, 0), 0.7)
    hull_area = float(cv2.contourArea(hull.astype(np.float32)))
    usable, reason, ratio = check_segmentation(car, hull_area, policy)
    return CarOutline(car, soft, scale, (w, h), usable, reason, ratio, time.perf_counter() - start)


def _filled(mask: np.ndarray) -> np.ndarray:
    """(h, w) bool: the mask with its holes filled (windows seen through, shadows on the car)."""
    import cv2

    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    out = np.zeros_like(mask)
    cv2.drawContours(out, contours, -1, 1, thickness=cv2.FILLED)
    return out.astype(bool)


def check_segmentation(mask: np.ndarray, hull_area: float, policy: FitPolicy) -> tuple[bool, str, float]:
    """Whether a car's mask is one to trust: (usable, why not, its area over the marks' hull's).

    The marks lie on the car's body, so its outline encloses their hull and not much more: a
    mask much larger took the background in, a smaller one lost the car; one that runs along
    the photo's frame on three sides or more is the background.
    """
    area = float(mask.sum())
    ratio = area / max(hull_area, 1.0)
    if not area:
        return False, "the segmentation found no car", 0.0
    lo, hi = policy.outline_hull_ratio
    if not lo <= ratio <= hi:
        return False, f"the car's mask is {ratio:.2f}× the marks' hull (trusted: {lo:g}–{hi:g}×)", ratio
    sides = [mask[0].mean(), mask[-1].mean(), mask[:, 0].mean(), mask[:, -1].mean()]
    framed = sum(s > policy.outline_frame_fraction for s in sides)
    if framed >= 3:
        return False, f"the car's mask runs along {framed} sides of the photo", ratio
    return True, "", ratio


@dataclass
class OutlineTargets:
    """Where points of the wireframe's curves should project: the solve's pseudo-observations.

    Attributes:
        weights: (n, 280) float, each point's Bézier weights over the left half's control points.
        mirror: (n, 3) float, (±1, 1, 1): the point on the left half or its mirror.
        normals: (n, 2) float, unit outward normal of the projected outline at the point (the
            one direction the outline pins it in).
        targets: (n, 2) float, the mask's edge it is matched to, the fit camera's pixels.
        noise_ratio: the matches' noise standard deviation over the marks'.
    """

    weights: np.ndarray
    mirror: np.ndarray
    normals: np.ndarray
    targets: np.ndarray
    noise_ratio: float

    def __len__(self) -> int:
        return len(self.targets)

    def points(self, shape: np.ndarray) -> np.ndarray:
        """(n, 3) the points on a shape vector (840,)."""
        return (self.weights @ np.asarray(shape).reshape(-1, 3)) * self.mirror


@dataclass
class OutlineFit:
    """What the outline did to a fit (the report's ``outline``).

    Attributes:
        used: whether the outline term entered the fit; ``reason`` why not.
        points: outline points matched in the last solve.
        median_px_before, median_px_after: their median distance along the normal to the mask's
            edge at the fit before the outline and after it, photo px.
        hull_ratio: the mask's area over the marks' hull's; seconds: the segmentation's time.
    """

    used: bool
    reason: str = ""
    points: int = 0
    median_px_before: float | None = None
    median_px_after: float | None = None
    hull_ratio: float | None = None
    seconds: float | None = None

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def outline_targets(shape: np.ndarray, view: View, scale: float, offset: np.ndarray, outline: CarOutline,
                    spread_px: float, policy: FitPolicy, to_photo: np.ndarray | None = None) -> OutlineTargets:
    """The matches of a fitted car's projected outline to the car's mask (module docstring).

    Args:
        shape: (840,) the car, normalised units; view, scale, offset: its camera (the fit's).
        outline: the car's mask (photo pixels).
        spread_px: the marks' spread, px (the unit of the search's reach).
        to_photo: (3, 3) from the fit camera's pixels to the photo's (a turned camera), or None.
    """
    from carbody.topology import load_topology

    topo = load_topology()
    t = np.linspace(0.0, 1.0, policy.outline_samples_per_curve + 2)[1:-1]  # curve ends are junctions, often marks
    bern = np.stack([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t ** 2, t ** 3], axis=1)  # (s, 4)
    n_curves = topo.n_curves
    weights = np.zeros((n_curves, len(t), n_curves * POINTS_PER_CURVE))
    for c in range(n_curves):
        weights[c, :, c * POINTS_PER_CURVE:(c + 1) * POINTS_PER_CURVE] = bern
    weights = weights.reshape(-1, n_curves * POINTS_PER_CURVE)
    weights = np.concatenate([weights, weights])
    mirror = np.concatenate([np.ones((len(weights) // 2, 3)), np.tile(MIRROR, (len(weights) // 2, 1))])
    points = (weights @ np.asarray(shape).reshape(-1, 3)) * mirror
    uv = project(points, view, scale, offset)
    silhouette = _silhouette(shape, view, scale, offset)
    on, normals = _on_outline(uv, silhouette, policy.outline_on_px)
    # the lower outline is tyres, shadow and ground in the photo: not the body's
    keep = on & (normals[:, 1] < policy.outline_max_downward)
    targets = np.full((len(uv), 2), np.nan)
    reach = policy.outline_search_spread * spread_px
    for i in np.flatnonzero(keep):
        targets[i] = _edge_along(uv[i], normals[i], outline, reach, to_photo)
    found = keep & np.isfinite(targets[:, 0])
    return OutlineTargets(weights[found], mirror[found], normals[found], targets[found], policy.outline_noise_ratio)


def _silhouette(shape: np.ndarray, view: View, scale: float, offset: np.ndarray):
    """The projected body's outer outline: the union of its regions' projections (both halves),
    a shapely polygon in the fit camera's pixels."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    from carbody.topology import load_topology
    from carbody.wireframe import sample_curves

    topo = load_topology()
    curves = sample_curves(np.asarray(shape).reshape(-1, 3), 12)
    polygons = []
    for side in (np.ones(3), MIRROR):
        for region in topo.regions:
            loop = np.concatenate([(curves[c][::-1] if rev else curves[c])[:-1] for c, rev in region.loop]) * side
            polygon = Polygon(project(loop, view, scale, offset)).buffer(0)
            if polygon.area > 0:
                polygons.append(polygon)
    body = unary_union(polygons)
    if body.geom_type == "MultiPolygon":
        body = max(body.geoms, key=lambda g: g.area)
    return Polygon(body.exterior)


def _on_outline(uv: np.ndarray, silhouette, tolerance_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(n,) bool: which projected points lie on the silhouette's outline (within
    ``tolerance_px``), and (n, 2) the outline's unit outward normal at each."""
    import shapely

    ring = silhouette.exterior
    pts = shapely.points(uv)
    on = shapely.distance(pts, ring) <= tolerance_px
    along = shapely.line_locate_point(ring, pts)
    step = 1.0
    ahead = shapely.get_coordinates(shapely.line_interpolate_point(ring, along + step))
    behind = shapely.get_coordinates(shapely.line_interpolate_point(ring, np.maximum(along - step, 0.0)))
    tangent = ahead - behind
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    probe = shapely.points(uv + 2.0 * normal)
    inward = shapely.contains(silhouette, probe)
    normal[inward] *= -1.0
    return on, normal


def _edge_along(uv: np.ndarray, normal: np.ndarray, outline: CarOutline, reach_px: float,
                to_photo: np.ndarray | None) -> np.ndarray:
    """(2,) the mask's edge nearest ``uv`` along ``normal`` (car inside, background outside,
    going outward), fit camera's pixels; NaN when there is none within ``reach_px`` or it is
    the photo's frame."""
    step = 0.5 / outline.scale  # half a mask pixel, in photo pixels
    t = np.arange(-reach_px, reach_px + step, step)
    line = uv + t[:, None] * normal
    photo = line if to_photo is None else apply_homography(to_photo, line)
    value = outline.carness(photo) - 0.5
    crossing = np.flatnonzero((value[:-1] >= 0) & (value[1:] < 0))
    if not len(crossing):
        return np.full(2, np.nan)
    i = crossing[np.argmin(np.abs(t[crossing]))]
    share = value[i] / (value[i] - value[i + 1])  # the 0.5 level between the two samples
    w, h = outline.image_size
    edge = photo[i] + share * (photo[i + 1] - photo[i])
    margin = 2.0 / outline.scale
    if not (margin <= edge[0] <= w - 1 - margin and margin <= edge[1] <= h - 1 - margin):
        return np.full(2, np.nan)  # the car runs off the photo there: its frame is no outline
    return line[i] + share * (line[i + 1] - line[i])


def follow_outline(scorer, hypothesis, outline: CarOutline, to_photo: np.ndarray | None = None, hubs=None):
    """The hypothesis' car fitted to its marks and the car's outline together (module
    docstring): (the hypothesis with the new solution, :class:`OutlineFit`). Its score stays
    the marks' (the outline does not choose the view). ``hubs``: the wheels' hubs found in the
    photo (:class:`~carbody.fit.wheels.HubTargets`), kept in every solve."""
    policy = scorer.policy
    if not outline.usable:
        return hypothesis, OutlineFit(False, outline.reason, hull_ratio=outline.hull_ratio, seconds=outline.seconds)
    spread = hypothesis.marks.spread
    h, before, matched, through = hypothesis, None, None, False
    for _ in range(policy.outline_passes):
        sol = h.solution
        matched = outline_targets(sol.shape, sol.view or h.view, sol.scale, sol.offset, outline, spread, policy,
                                  to_photo)
        if before is None:
            before = _median_px(matched, sol.shape, sol.view or h.view, sol.scale, sol.offset)
        if len(matched) < policy.outline_min_points:
            break
        new = scorer.solve(h.view, h.kept, outline=matched, hubs=hubs)
        through = reaches_camera(new.shape, new.view or h.view)
        if through:
            break  # an outline that would pull the car through a close camera is not followed
        new.evidence, new.evidence_px = sol.evidence, sol.evidence_px  # the marks' own: the view's score
        h = replace(h, solution=new, view=new.view or h.view)
    if h is hypothesis:
        reason = "the outline would pull the car through the camera" if through else \
            f"{len(matched)} outline points matched (fewest used: {policy.outline_min_points})"
        return hypothesis, OutlineFit(False, reason, len(matched), before, hull_ratio=outline.hull_ratio,
                                      seconds=outline.seconds)
    sol = h.solution
    after = outline_targets(sol.shape, sol.view or h.view, sol.scale, sol.offset, outline, spread, policy, to_photo)
    return h, OutlineFit(True, "", len(matched), before, _median_px(after, sol.shape, sol.view or h.view, sol.scale,
                                                                    sol.offset), outline.hull_ratio, outline.seconds)


def _median_px(matched: OutlineTargets, shape: np.ndarray, view: View, scale: float, offset: np.ndarray) -> float | None:
    """The matched points' median distance along the normal to their edge, px (None: no match)."""
    if not len(matched):
        return None
    uv = project(matched.points(shape), view, scale, offset)
    return float(np.median(np.abs(np.einsum("ij,ij->i", uv - matched.targets, matched.normals))))
