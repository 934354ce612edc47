"""The photo's own evidence at the wheels: each visible wheel's hub, found and fitted with the marks.

No keypoint sits on a hub, and people seldom mark the arch points level with it: the hub then
lies where the library puts it below the marked arch tops, at the library's arch clearance,
while real cars (a lifted pickup, a van on small wheels, a lowered coupe) differ a lot. The
photo shows the wheels. Three steps:

1. :func:`find_wheels` looks for each wheel where the fitted car puts it. A wheel is a circle in
   the car's side plane about its hub ((±x, 0, 0) and (±x, L_wb, 0), SPEC), so the fitted camera
   maps that plane onto the photo by a homography: the photo round the predicted hub is warped
   back onto the plane (:func:`wheel_patch`), where the wheel is a circle again whatever the
   view. There the tyre's outline, the rim's edge and the arcs of the spokes' openings are
   circles about the hub. Every edge pixel (Canny) votes along its gradient, both ways, for the
   centres at every radius (a circular Hough transform, :func:`hough_centres`); its best peaks
   are then scored exactly (:func:`circle_support`): for each radius, the share of equal
   sectors round the centre where an edge of one polarity lies on the circle across it. A
   circle adds its share above a floor, up to a cap (:func:`concentric_score`), so the hub,
   where several concentric circles meet, stands out from a single round thing (a lamp, a
   badge), from spokes' and panels' straight edges, and from clutter. The view found is a few
   degrees off, and a parked car's front wheels are often turned, which stretch and shear the
   wheel in the patch: the patch is tried undistorted by each way they can
   (:func:`wheel_distortions`), and the hub is finally the centre of the ellipse
   that the edges along the strongest circle, the rim's, follow (:func:`rim_ellipse_centre`).
   A hub is found when its score is high (``wheel_min_score``). Centres elsewhere in the window
   that score nearly as well (within ``wheel_min_margin``) are its rivals: a small move of the
   fit can change which of them scores best, so all are carried into the fit (step 3); more
   than ``wheel_rivals`` of them is clutter, no hub. A wheel the camera sees nearly edge-on,
   one too small, cut off by the frame or in a patch with no clear circles gives no hub, and
   no rows.
2. :class:`HubTargets`: each hub found is a pseudo-observation of the same linear solve as the
   marks (:func:`carbody.fit.solve.solve_gauss`'s ``hubs``). The hub is a fixed point of every
   library model: its x is the arch top's (the tyre's outer face, which the photo shows), its
   (y, z) the midpoint of the arch's points level with it. So its projection is linear in the
   shape like a keypoint's, and its rows bind the camera and the car's track. The templates
   share one arch clearance, so the library cannot move a hub against the body round it: with
   hubs found, the solve's prior gains the body's height on its wheels
   (:func:`ride_height_direction`, ``wheel_ride_height_sd``).
3. :func:`follow_wheels` solves with them at the view found, a few times: a hub the marks and
   the prior put far from where it was found is weighted down (Cauchy), so one wrong find
   cannot bend the car. A hub with rivals shares one hub's weight among its centres, by score
   times that fit: the car the marks make picks among them (:func:`_with_hubs`). The view's
   score stays the marks' own (the wheels shape the car, they do not choose the view).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from carbody.camera import View, apply_homography, camera_direction, perspective_factors, project
from carbody.errors import AngleError
from carbody.fit.solve import MAX_PERSPECTIVE_FACTOR, reaches_camera
from carbody.policy import FitPolicy
from carbody.wireframe import POINTS_PER_CURVE

#: The four wheels, in :func:`hub_map`'s order: front then rear, the car's left (x > 0) first.
WHEELS = ("front_left", "front_right", "rear_left", "rear_right")

#: The turns of a front wheel that :func:`wheel_distortions` reads its stretches and shears at
#: lie this many degrees apart (only the range and the shears come from them).
STEER_STEP_DEG = 5.0

#: Side length of the warped patch per arch radius, and the arch radius in patch pixels: the
#: circles' votes need a few tens of pixels of radius, and more only costs time.
PATCH_ARCH_PX = 40.0


def hub_map() -> np.ndarray:
    """(4, 280, 3) float: hub i's coordinate c is Σ_j map[i, j, c] · P[j, c] over a wireframe's
    280 control points P (its left half): x that of the arch top (negated for the right
    wheels), (y, z) the midpoint of the arch's two points level with the wheel centre
    (:func:`carbody.wireframe.wheel_centre`). Units follow P."""
    from carbody.topology import load_topology

    topo = load_topology()
    out = np.zeros((4, topo.n_curves * POINTS_PER_CURVE, 3))
    for k, side in enumerate(("front", "rear")):
        top = topo.junction_point_index(f"{side}_arch_top")
        level = [topo.junction_point_index(j) for j in topo.wheel_centres[side]]
        for i, sign in ((2 * k, 1.0), (2 * k + 1, -1.0)):
            out[i, top, 0] = sign
            for j in level:
                out[i, j, 1:] += 0.5
    return out


def ride_height_direction() -> np.ndarray:
    """(840,) float: the body one unit higher on its wheels. Every control point rises but the
    arch's points level with the hubs and the poles that carry their curves' ends there, so
    the hubs (their midpoints) stay at z = 0, SPEC's frame, while the arches round them, the
    sills and the rest of the body rise: a larger arch clearance, a lifted pickup (negative: a
    lowered car). The library has none of it: its templates share one arch clearance."""
    from carbody.topology import load_topology

    topo = load_topology()
    level = {j for pair in topo.wheel_centres.values() for j in pair}
    z = np.ones((topo.n_curves, POINTS_PER_CURVE))
    for c in topo.curves:
        if c.start in level:
            z[c.index, :2] = 0.0
        if c.end in level:
            z[c.index, 2:] = 0.0
    out = np.zeros((topo.n_points, 3))
    out[:, 2] = z.ravel()
    return out.ravel()


def hub_points(shape: np.ndarray) -> np.ndarray:
    """(4, 3) the hubs of a shape vector (840,) (or control points (280, 3)), in :data:`WHEELS`
    order, its units."""
    return np.einsum("ijc,jc->ic", hub_map(), np.asarray(shape, dtype=float).reshape(-1, 3))


def arch_radii(shape: np.ndarray) -> np.ndarray:
    """(4,) each wheel's arch top above its hub (the arch's radius: tyre and clearance), the
    shape's units."""
    from carbody.topology import load_topology

    topo = load_topology()
    points = np.asarray(shape, dtype=float).reshape(-1, 3)
    hubs = hub_points(points)
    tops = [points[topo.junction_point_index(f"{side}_arch_top"), 2] for side in ("front", "front", "rear", "rear")]
    return np.asarray(tops) - hubs[:, 2]


@dataclass(frozen=True)
class WheelFound:
    """A hub found in the photo.

    Attributes:
        wheel: its name (:data:`WHEELS`).
        uv: (2,) float, the hub, photo pixels.
        score: the concentric circles' score at the hub (:func:`concentric_score`).
        runner_up: the best score more than ``wheel_separation`` arch radii away.
        rivals: ((2,) photo px, score) of the other centres that score too near the hub's to
            tell them apart (within ``wheel_min_margin``; at most ``wheel_rivals``): the fit
            carries them all and weighs each by how well the car fits it (:func:`_with_hubs`).
            Empty for a clear hub.
    """

    wheel: str
    uv: np.ndarray
    score: float
    runner_up: float
    rivals: tuple = ()

    def candidates(self) -> list[tuple[np.ndarray, float]]:
        """[((2,) photo px, score)]: the hub found, then its rivals."""
        return [(np.asarray(self.uv, float), float(self.score))] + [(np.asarray(uv, float), float(sc))
                                                                      for uv, sc in self.rivals]


def grey_photo(image: np.ndarray) -> np.ndarray:
    """(h, w) float32 luminance of an (h, w, 3) RGB (or (h, w) grey) uint8 photo."""
    import cv2

    rgb = np.asarray(image)
    if rgb.ndim == 2:
        return rgb.astype(np.float32)
    return cv2.cvtColor(np.ascontiguousarray(rgb[..., :3], dtype=np.uint8), cv2.COLOR_RGB2GRAY).astype(np.float32)


def find_wheels(image: np.ndarray, shape: np.ndarray, view: View, scale: float, offset: np.ndarray,
                policy: FitPolicy, to_photo: np.ndarray | None = None,
                wheels: tuple[str, ...] = WHEELS) -> list[WheelFound]:
    """The hubs the photo shows where a fitted car puts its wheels (module docstring, step 1).

    Args:
        image: the photo, (h, w, 3) uint8 RGB or (h, w) grey (uint8 or float).
        shape: (840,) the fitted car, normalised units; view, scale, offset: its camera.
        policy: the ``wheel_*`` thresholds.
        to_photo: (3, 3) from the fit camera's pixels to the photo's (a turned camera), or None.
        wheels: the wheels to look for (names of :data:`WHEELS`).
    Returns:
        the hubs found, at most one per wheel (each with its rivals, if any).
    """
    grey = image if image.ndim == 2 and image.dtype == np.float32 else grey_photo(image)
    h, w = grey.shape
    hubs, radii = hub_points(shape), arch_radii(shape)
    d = camera_direction(view)

    def to_px(points: np.ndarray) -> np.ndarray:
        uv = project(points, view, scale, offset)
        return uv if to_photo is None else apply_homography(to_photo, uv)

    found = []
    for name, hub, radius in zip(WHEELS, hubs, radii):
        if name not in wheels or not radius > 0:
            continue
        toward = d if view.distance is None else \
            np.asarray(view.aim) + view.distance * d - hub  # a pinhole sees each hub from its own side
        distortions = wheel_distortions(toward, np.sign(hub[0]), name.startswith("front"), policy)
        if not distortions:
            continue  # edge-on, or its inner side: the body and the tyre's tread hide the hub
        centre = to_px(hub)
        if not (0 <= centre[0] < w and 0 <= centre[1] < h):
            continue
        k = 1.0 if view.distance is None else float(perspective_factors(hub, view, MAX_PERSPECTIVE_FACTOR))
        radius_px = radius * scale * k
        if radius_px * policy.wheel_tyre_share < policy.wheel_min_radius_px:
            continue
        hit = _find_hub(grey, to_px, hub, radius, radius_px, policy, distortions)
        if hit is not None:
            found.append(WheelFound(name, *hit))
    return found


def wheel_distortions(toward: np.ndarray, side: float, steers: bool, policy: FitPolicy) -> list[tuple[float, float]]:
    """The (aspect, shear) pairs of :func:`wheel_patch` that a wheel's search tries: those that
    turn the wheel, as the photo shows it, back into a circle in the warped patch.

    The patch is the photo warped onto the car's side plane through the hub, seen along
    ``toward`` (3,) (the way to the camera, car frame). A front wheel may be steered by δ (up to
    ``wheel_max_steer_deg`` either way; a rear wheel by none): its circle then lies in a plane
    turned by δ about the vertical, and the warp shows it stretched along the car by
    f = cos δ − sin δ · t_y/t_x and sheared by sin δ · t_z/t_x (t = ``toward``). Near a front
    view, t_y/t_x is large: 20° of steering stretches the wheel by half or more. Each δ whose
    wheel shows its outer face (``side``: +1 the car's left, −1 its right) at least
    ``wheel_min_facing`` gives aspect 1/f; the view found a few degrees off stretches it by each
    of ``wheel_aspects`` more. The aspects are taken a factor ``wheel_aspect_step`` apart over
    that whole range, each with the shear of the steering nearest it. An empty list: the wheel
    shows no face to the camera whichever way it is steered."""
    t = np.asarray(toward, float) / np.linalg.norm(toward)
    if not t[0] * side > 0:
        return []  # the side plane is seen from inside: the warp would mirror it
    limit = np.radians(policy.wheel_max_steer_deg) if steers else 0.0
    steer = np.linspace(-limit, limit, 2 * int(np.ceil(np.degrees(limit) / STEER_STEP_DEG)) + 1)
    facing = side * (np.cos(steer) * t[0] - np.sin(steer) * t[1])
    keep = facing >= policy.wheel_min_facing
    if not keep.any():
        return []
    steer, f = steer[keep], facing[keep] / (side * t[0])  # f = cos δ − sin δ · t_y / t_x
    aspect = 1.0 / f
    shear = np.sin(steer) * t[2] / t[0] / f
    factors = np.asarray(policy.wheel_aspects, float)
    low, high = np.log(aspect.min() * factors.min()), np.log(aspect.max() * factors.max())
    count = int(np.ceil((high - low) / np.log(policy.wheel_aspect_step))) + 1
    grid = np.exp(np.linspace(low, high, count))
    nearest = np.abs(np.log(grid)[:, None] - np.log(aspect)[None]).argmin(axis=1)
    return [(float(a), float(shear[i])) for a, i in zip(grid, nearest)]


def wheel_patch(grey: np.ndarray, to_px, hub: np.ndarray, radius: float, half: float, aspect: float,
                reduce: float = 1.0, shear: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The photo warped onto the wheel's side plane round its hub.

    Args:
        grey: (h, w) float32 photo (already reduced by ``reduce`` from the photo ``to_px`` maps to).
        to_px: car-frame points (n, 3) → photo pixels (n, 2).
        hub: (3,) the hub; radius: the arch's radius (its units; the patch has ``PATCH_ARCH_PX``
            pixels per radius); half: the patch's half side, arch radii.
        aspect: the patch's stretch along the car (y); shear: how far the plane's z moves down
            per unit along the car, undoing a steered wheel's tilt (:func:`wheel_distortions`).
    Returns:
        (patch (n, n) float32, valid (n, n) bool: inside the photo, H (3, 3): patch pixels →
        photo pixels).
    """
    import cv2

    n = int(round(2 * half * PATCH_ARCH_PX))
    unit = radius / PATCH_ARCH_PX  # car units per patch pixel, up the plane

    def plane(c: np.ndarray, r: np.ndarray) -> np.ndarray:
        along = (c - n / 2) * unit / aspect
        return np.stack([np.full(len(c), hub[0]), hub[1] + along, hub[2] - (r - n / 2) * unit - shear * along], 1)

    corners = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    photo = to_px(plane(corners[:, 0], corners[:, 1]))
    H = cv2.getPerspectiveTransform(corners.astype(np.float32), photo.astype(np.float32))
    reduced = np.diag([reduce, reduce, 1.0]) @ H
    patch = cv2.warpPerspective(grey, reduced, (n, n), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    inside = np.isfinite(patch)  # (off the photo: NaN, and the pixels that blend with it)
    return np.where(inside, patch, 0.0).astype(np.float32), inside, H


@dataclass(frozen=True)
class PatchEdges:
    """A patch's edge pixels (Canny) and their unit gradients (toward the brighter side).

    Attributes:
        xy: (e, 2) float, patch pixels (column, row).
        g: (e, 2) float, unit gradient at each.
        size: the patch's side, pixels.
    """

    xy: np.ndarray
    g: np.ndarray
    size: int


def patch_edges(patch: np.ndarray, valid: np.ndarray) -> PatchEdges:
    """The edges of a warped patch (n, n) float32 inside the photo (``valid`` (n, n) bool); the
    photo's frame is no edge. Canny's thresholds come from the patch's own contrast: a dim
    photo's wheel is a wheel too."""
    import cv2

    n = patch.shape[0]
    none = PatchEdges(np.zeros((0, 2)), np.zeros((0, 2)), n)
    inner = cv2.erode(valid.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    if not inner.any():
        return none
    smooth = cv2.GaussianBlur(np.where(valid, patch, float(np.median(patch[valid]))).astype(np.float32), (0, 0), 1.0)
    gx, gy = cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1)
    magnitude = np.hypot(gx, gy)
    high = float(np.percentile(magnitude[inner], 90))
    if not high > 0:
        return none
    edges = cv2.Canny(np.clip(smooth, 0, 255).astype(np.uint8), 0.4 * high, high, L2gradient=True) > 0
    ys, xs = np.nonzero(edges & inner & (magnitude > 0))
    g = np.stack([gx[ys, xs], gy[ys, xs]], axis=1) / magnitude[ys, xs, None]
    return PatchEdges(np.stack([xs, ys], axis=1).astype(float), g.astype(float), n)


def hough_centres(edges: PatchEdges, radii_px: np.ndarray, floor: float, cap: float, reach: float) -> np.ndarray:
    """(n, n) float: a fast first score of the patch pixels within ``reach`` px of its centre
    (0 elsewhere) as the centre of concentric circles (a circular Hough transform): each edge
    pixel votes along its gradient, both ways, for the centres at every radius (``radii_px``,
    1 px apart); a circle adds the share of its circumference voting (within a pixel of
    centre and radius, one polarity) less ``floor``, up to ``cap`` less ``floor`` (module
    docstring). Candidates for :func:`circle_support`."""
    n, m = edges.size, len(radii_px)
    score = np.zeros((n, n))
    if not len(edges.xy):
        return score
    lo, hi = max(0, int(n / 2 - reach) - 1), min(n, int(np.ceil(n / 2 + reach)) + 2)  # the window's square
    w = hi - lo
    # every (polarity, radius, edge) vote at once: the centre on the brighter side, or the darker
    step = np.array([1.0, -1.0])[:, None, None, None] * radii_px[None, :, None, None] * edges.g[None, None]
    at = np.round(edges.xy + step).astype(np.int64) - lo  # (2, m, e, 2)
    ok = (at >= 0).all(axis=-1) & (at < w).all(axis=-1)
    layer = np.arange(2 * m).reshape(2, m, 1)
    index = (layer * w + at[..., 1]) * w + at[..., 0]
    votes = np.bincount(index[ok], minlength=2 * m * w * w).reshape(2, m, w, w).astype(np.float32)
    padded = np.pad(votes, ((0, 0), (0, 0), (1, 1), (1, 1)))
    rows = padded[:, :, :-2] + padded[:, :, 1:-1] + padded[:, :, 2:]
    box = rows[..., :-2] + rows[..., 1:-1] + rows[..., 2:]  # votes within a pixel of each centre
    share = box.max(axis=0) / (2 * np.pi * radii_px)[:, None, None]
    padded = np.pad(share, ((1, 1), (0, 0), (0, 0)))
    share = np.maximum(share, np.maximum(padded[:-2], padded[2:]))  # a circle a pixel off its radius
    score[lo:hi, lo:hi] = concentric_score(np.moveaxis(share, 0, -1), floor, cap)
    return score


def circle_support(edges: PatchEdges, centres: np.ndarray, radii_px: np.ndarray, sectors: int,
                   alignment: float) -> np.ndarray:
    """(c, m) float: for each circle about each of ``centres`` (c, 2) of radius ``radii_px``
    (m,), 1 px apart, the share of its ``sectors`` equal angular sectors in which an edge pixel
    lies within a pixel of it with its gradient along the radius (cosine above
    ``alignment``), counted for each polarity (brighter inside, brighter outside) and the
    larger taken. A straight edge — a spoke, a panel's line — meets a circle in a few sectors;
    a wheel's circles run all round it, or round its visible part."""
    centres = np.atleast_2d(np.asarray(centres, dtype=float))
    d = edges.xy[None] - centres[:, None]  # (c, e, 2)
    r = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-9)
    cosine = np.einsum("cei,ei->ce", d, edges.g) / r
    sector = ((np.arctan2(d[..., 1], d[..., 0]) + np.pi) / (2 * np.pi) * sectors).astype(np.int64) % sectors
    k = np.round(r - radii_px[0]).astype(np.int64)
    m = len(radii_px)
    hit = np.zeros((len(centres), 2, m + 2, sectors), bool)
    which = np.broadcast_to(np.arange(len(centres))[:, None], k.shape)
    for side, aligned in enumerate((cosine > alignment, cosine < -alignment)):
        for dk in (-1, 0, 1):  # a circle a pixel off its radius
            kk = k + dk + 1
            use = aligned & (kk >= 1) & (kk <= m)
            hit[which[use], side, kk[use], sector[use]] = True
    return hit[:, :, 1:-1].mean(axis=3).max(axis=1)


def concentric_score(support: np.ndarray, floor: float, cap: float) -> np.ndarray:
    """(...) float: centres' scores from their circles' :func:`circle_support` (..., m): each
    circle adds its share less ``floor``, up to ``cap`` less ``floor`` (module docstring)."""
    return np.clip(support - floor, 0.0, cap - floor).sum(axis=-1)


def patch_source(grey: np.ndarray, radius_px: float) -> tuple[np.ndarray, float]:
    """(photo, reduce): what a wheel's patch reads, the photo at about the patch's own resolution
    (a wheel ``radius_px`` large is reduced first: a bilinear warp would alias it), and by how
    much it was reduced (:func:`wheel_patch`'s ``reduce``)."""
    import cv2

    reduce = min(1.0, 1.5 * PATCH_ARCH_PX / radius_px)
    small = grey if reduce == 1.0 else cv2.resize(grey, None, fx=reduce, fy=reduce, interpolation=cv2.INTER_AREA)
    return small, reduce


def patch_radii(policy: FitPolicy) -> np.ndarray:
    """The circles' radii looked for in a wheel's patch, patch pixels."""
    return np.arange(policy.wheel_radii[0] * PATCH_ARCH_PX, policy.wheel_radii[1] * PATCH_ARCH_PX, 1.0)


def _find_hub(grey: np.ndarray, to_px, hub: np.ndarray, radius: float, radius_px: float, policy: FitPolicy,
              distortions: list[tuple[float, float]]):
    """(hub (2,) photo px, score, runner-up's score, rivals) of the best concentric circles in the
    window round the predicted hub, the patch warped by each of ``distortions`` ((aspect, shear)
    pairs, :func:`wheel_distortions`), or None when none scores high enough (module docstring).
    Rivals (:attr:`WheelFound.rivals`) are the centres of the hub's patch, apart from it and from
    each other, that score within ``wheel_min_margin`` of it."""
    import cv2

    window = policy.wheel_window  # arch radii round the predicted hub
    half = window + policy.wheel_radii[1]
    small, reduce = patch_source(grey, radius_px)
    radii_px = patch_radii(policy)
    floor, cap = policy.wheel_circle_floor, policy.wheel_circle_cap
    best = None
    for aspect, shear in distortions:
        try:
            patch, valid, H = wheel_patch(small, to_px, hub, radius, half, aspect, reduce, shear)
        except AngleError:  # stretched far along the car, the patch reaches a camera close by
            continue
        if valid.mean() < policy.wheel_min_inside:
            continue  # mostly off the photo: the wheel cut off by its frame, or the patch stretched past it
        edges = patch_edges(patch, valid)
        rough = hough_centres(edges, radii_px, floor, cap, window * PATCH_ARCH_PX).astype(np.float32)
        n = patch.shape[0]
        yy, xx = np.mgrid[0:n, 0:n] - n / 2
        rough[(np.hypot(xx, yy) > window * PATCH_ARCH_PX) | ~valid] = -1.0
        peaks = (rough == cv2.dilate(rough, np.ones((5, 5), np.uint8))) & (rough > 0)
        rows, cols = np.nonzero(peaks)
        order = np.argsort(rough[rows, cols])[::-1][:policy.wheel_candidates]
        if not len(order):
            continue
        # the rough peaks are a pixel or two off: the support is read round each
        shifts = np.stack(np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]), axis=-1).reshape(-1, 2)
        centres = (np.stack([cols[order], rows[order]], axis=1)[:, None] + shifts[None]).reshape(-1, 2)
        support = circle_support(edges, centres, radii_px, policy.wheel_sectors, policy.wheel_alignment)
        values = concentric_score(support, floor, cap).reshape(len(order), len(shifts))
        at = [i * len(shifts) + int(v.argmax()) for i, v in enumerate(values)]  # each peak's best centre
        scored = [(float(v.max()), *map(float, centres[j]), j) for v, j in zip(values, at)]
        top = max(scored)
        if best is not None and top[0] <= best[0][0]:
            continue
        apart = policy.wheel_separation * PATCH_ARCH_PX
        runner = max([s for s, c, r, _ in scored if np.hypot(c - top[1], r - top[2]) > apart], default=0.0)
        near = []  # the centres as clear as the hub, apart from it and from each other
        for candidate in sorted(scored, reverse=True):
            _, c, r, _ = candidate
            if candidate[0] * policy.wheel_min_margin > top[0] and \
                    all(np.hypot(c - c0, r - r0) > apart for _, c0, r0, _ in [top] + near):
                near.append(candidate)
        best = (top, runner, near, H, edges, support)
    if best is None:
        return None
    top, runner, near, H, edges, support = best
    if top[0] < policy.wheel_min_score or len(near) > policy.wheel_rivals:
        return None  # no clear circles, or clutter: too many centres alike

    def hub_px(centre_score) -> np.ndarray:
        _, c, r, j = centre_score
        centre = np.array([c, r])
        ellipse = rim_ellipse_centre(edges, centre, float(radii_px[np.argmax(support[j])]), policy.wheel_sectors)
        if ellipse is not None and np.hypot(*(ellipse - centre)) < policy.wheel_separation * PATCH_ARCH_PX:
            centre = ellipse
        return apply_homography(H, centre + 0.5)  # (pixel centres)

    return hub_px(top), top[0], runner, tuple((hub_px(n), n[0]) for n in near)


@dataclass(frozen=True)
class RimEllipse:
    """The ellipse a wheel's strongest circle makes in a warped patch (:func:`rim_ellipse`).

    Attributes:
        centre: (2,) patch pixels.
        axes: (2,) its semi-axes, patch pixels, along its own frame's x and y.
        angle: the turn of its own frame's x from the patch's, radians.
        sectors_seen: of the ``sectors`` round it, how many hold an edge used.
    """

    centre: np.ndarray
    axes: np.ndarray
    angle: float
    sectors_seen: int

    def stretch(self) -> float:
        """Its extent along the patch's x (the car) over its extent along y (up)."""
        (a, b), c, s = self.axes, np.cos(self.angle), np.sin(self.angle)
        return float(np.hypot(a * c, b * s) / np.hypot(a * s, b * c))


def rim_ellipse(edges: PatchEdges, centre: np.ndarray, radius: float, sectors: int,
                band: float = 0.15, alignment: float = 0.8, rounds: int = 3) -> RimEllipse | None:
    """The ellipse that the edges along a wheel's strongest circle (about ``centre`` (2,),
    ``radius`` px: the rim's edge, mostly) follow in a warped patch, or None.

    The warped patch shows the wheel as a circle only as far as the view found is right: a few
    degrees off in azimuth, elevation or distance, it is an ellipse, stretched and sheared. The
    edges within ``band`` of the circle whose gradient lies along its normal (cosine above
    ``alignment``) are fitted with an ellipse (OpenCV's AMS), and again with the edges along
    that ellipse, ``rounds`` times. None when too few edges lie along it or it is a stretched
    blob (axes more than 1 : 0.6)."""
    import cv2

    c, axes, angle = np.asarray(centre, float), np.array([radius, radius]), 0.0
    for _ in range(rounds):
        rot = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        local = (edges.xy - c) @ rot.T / axes  # the ellipse's own frame, unit circle
        rho = np.hypot(local[:, 0], local[:, 1])
        normal = (local / np.maximum(rho, 1e-9)[:, None] / axes) @ rot  # the ellipse's normal, photo frame
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        along = np.abs(np.einsum("ij,ij->i", normal, edges.g)) > alignment
        near = along & (np.abs(rho - 1.0) < band)
        if near.sum() < 12:
            return None
        (cx, cy), (w, h), degrees = cv2.fitEllipseAMS(edges.xy[near].astype(np.float32))
        if not (w > 0 and h > 0) or not 0.6 < w / h < 1.0 / 0.6:
            return None
        c, axes, angle = np.array([cx, cy]), np.array([w, h]) / 2, np.radians(degrees)
    seen = np.unique(((np.arctan2(*(edges.xy[near] - c).T[::-1]) + np.pi) / (2 * np.pi) * sectors).astype(int))
    return RimEllipse(c, axes, float(angle), len(seen))


def rim_ellipse_centre(edges: PatchEdges, centre: np.ndarray, radius: float, sectors: int) -> np.ndarray | None:
    """(2,) patch pixels: the centre of the wheel's :func:`rim_ellipse`, kept when the edges used
    run round at least half of it (by ``sectors``); else None."""
    ellipse = rim_ellipse(edges, centre, radius, sectors)
    return ellipse.centre if ellipse is not None and ellipse.sectors_seen >= sectors / 2 else None


@dataclass
class HubTargets:
    """The hubs found as pseudo-observations of the solve (:func:`carbody.fit.solve.solve_gauss`'s
    ``hubs``): two rows per hub, its image u and its image v.

    Attributes:
        weights: (2n, 280, 3) float, each row's point as a linear map of the left half's control
            points, per coordinate (:func:`hub_map`).
        mirror: (2n, 3) ones (the right wheels' sign is in ``weights``).
        normals: (2n, 2) float, (1, 0) then (0, 1) for each hub: the row's image direction.
        targets: (2n, 2) float, the hub found, the fit camera's pixels.
        noise_ratio: (2n,) float, each row's noise standard deviation over the marks'.
        directions: (840, q) float or None, shape directions the solve adds to its prior with
            them (zero mean, each column one standard deviation): what only the hubs can show,
            the body's height on its wheels (:func:`ride_height_direction`).
    """

    weights: np.ndarray
    mirror: np.ndarray
    normals: np.ndarray
    targets: np.ndarray
    noise_ratio: np.ndarray
    directions: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.targets)

    def points(self, shape: np.ndarray) -> np.ndarray:
        """(2n, 3) the rows' hubs on a shape vector (840,)."""
        return np.einsum("njc,jc->nc", self.weights, np.asarray(shape).reshape(-1, 3))

    @classmethod
    def of(cls, found: list[WheelFound], targets_px: np.ndarray, noise_ratio: np.ndarray,
           ride_height_sd: float = 0.0) -> "HubTargets":
        """The rows of hubs ``found`` at ``targets_px`` (n, 2) (the fit camera's pixels), each
        with its noise ratio (n,); with the body's height on its wheels free at
        ``ride_height_sd`` (normalised units) when positive."""
        index = [WHEELS.index(f.wheel) for f in found]
        maps = hub_map()[np.repeat(index, 2)]
        normals = np.tile(np.eye(2), (len(found), 1))
        lift = ride_height_sd * ride_height_direction()[:, None] if ride_height_sd > 0 else None
        return cls(maps, np.ones((2 * len(found), 3)), normals, np.repeat(np.asarray(targets_px, float), 2, axis=0),
                   np.repeat(np.asarray(noise_ratio, float), 2), lift)


@dataclass
class WheelsFit:
    """What the wheels found in the photo did to a fit (the report's ``wheels``).

    Attributes:
        used: whether any hub entered the fit; ``reason`` why not.
        wheels: one dict per hub found: ``wheel``, ``found_px`` [u, v] (photo: of its centres,
            the one the fit gave most weight), ``score``, ``runner_up``, ``weight`` (its weight
            in the last solve, 0–1), ``before_px`` and ``after_px`` (the fitted car's hub's
            distance from it before and after), ``rivals`` (the other centres carried, each
            ``px`` and ``score``; empty for a clear hub).
        seconds: the search's wall time.
    """

    used: bool
    reason: str = ""
    wheels: list[dict] | None = None
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def follow_wheels(scorer, hypothesis, image: np.ndarray, to_photo: np.ndarray | None = None):
    """The hypothesis' car fitted to its marks and the hubs the photo shows (module docstring):
    (the hypothesis with the new solution, :class:`WheelsFit`, the :class:`HubTargets` of the
    last solve or None). Its score stays the marks'.

    The wheels not found are looked for again at the car fitted to those found
    (``wheel_rounds``): a wheel missed at first, its window off it, can then be found."""
    policy = scorer.policy
    start = time.perf_counter()
    grey = grey_photo(image)
    first = hypothesis.solution
    # one standard deviation of a hub found, px: the marks' noise (λ's, in their spread's unit) × the ratio
    sigma = policy.wheel_noise_ratio * np.sqrt(scorer.lam) * (first.rho or hypothesis.marks.spread)
    h, found, hubs, weight = hypothesis, {}, None, None
    for _ in range(policy.wheel_rounds):
        sol = h.solution
        missing = tuple(w for w in WHEELS if w not in found)
        again = find_wheels(grey, sol.shape, sol.view or h.view, sol.scale, sol.offset, policy, to_photo, missing)
        if not again:
            break  # (nothing new: the last solve stands)
        found.update({f.wheel: f for f in again})
        wheels = [found[w] for w in WHEELS if w in found]
        h, hubs, weight, picked, targets = _with_hubs(scorer, hypothesis, wheels, to_photo, sigma)
        if reaches_camera(h.solution.shape, h.view):  # hubs found wrong round a close camera: not followed
            reason = "the hubs found would pull the car through the camera"
            return hypothesis, WheelsFit(False, reason, [], seconds=time.perf_counter() - start), None
    seconds = time.perf_counter() - start
    if hubs is None:
        return hypothesis, WheelsFit(False, "no wheel found in the photo", [], seconds=seconds), None
    index = [WHEELS.index(f.wheel) for f in wheels]
    chosen = [f.candidates()[j] for f, j in zip(wheels, picked)]
    before = np.linalg.norm(_hubs_px(first, first.view or hypothesis.view)[index] - targets, axis=1)
    after = np.linalg.norm(_hubs_px(h.solution, h.view)[index] - targets, axis=1)
    px = lambda uv: [round(float(v), 1) for v in uv]  # noqa: E731
    rows = [{"wheel": f.wheel, "found_px": px(uv), "score": round(score, 2),
             "runner_up": round(f.runner_up, 2), "weight": round(float(wt), 3), "before_px": round(float(b), 1),
             "after_px": round(float(a), 1),
             "rivals": [{"px": px(u), "score": round(sc, 2)} for j, (u, sc) in enumerate(f.candidates()) if j != k]}
            for f, (uv, score), k, wt, b, a in zip(wheels, chosen, picked, weight, before, after)]
    return h, WheelsFit(True, "", rows, seconds=seconds), hubs


def _with_hubs(scorer, hypothesis, wheels: list[WheelFound], to_photo: np.ndarray | None, sigma: float):
    """(the hypothesis solved with the hubs found, the :class:`HubTargets` of its last solve, the
    weight (n,) in it of each wheel's likeliest centre, the index (n,) of that centre in its
    :meth:`WheelFound.candidates`, and where it lies (n, 2) in the fit camera's pixels):
    ``wheel_passes`` solves. Each centre is weighted by how far
    the last solve put its wheel's hub from it (Cauchy, at ``wheel_robust_scale`` × its noise
    ``sigma`` px), so one wrong find cannot bend the car. A wheel with rivals shares one hub's
    worth of weight among its centres, in proportion to their scores times that fit (the first
    solve by their scores alone): the car the marks make picks among centres alike."""
    policy = scorer.policy
    rows = [(i, f.wheel, uv, score) for i, f in enumerate(wheels) for uv, score in f.candidates()]
    owner = np.array([i for i, *_ in rows])
    index = [WHEELS.index(w) for _, w, _, _ in rows]
    photo_px = np.array([uv for *_, uv, _ in rows])
    targets = photo_px if to_photo is None else apply_homography(np.linalg.inv(to_photo), photo_px)
    scores = np.array([score for *_, score in rows])
    fits = np.ones(len(rows))  # each centre's Cauchy weight at the last solve

    def shares() -> np.ndarray:  # each centre's share of its wheel: score × fit, normalised per wheel
        w = scores * fits
        return w / np.bincount(owner, weights=w)[owner]

    marks_own = hypothesis.solution
    found = [WheelFound(w, uv, score, 0.0) for _, w, uv, score in rows]
    for k in range(policy.wheel_passes):
        weight = shares() * fits
        hubs = HubTargets.of(found, targets, policy.wheel_noise_ratio / np.sqrt(np.maximum(weight, 1e-6)),
                             policy.wheel_ride_height_sd)
        new = scorer.solve(hypothesis.view, hypothesis.kept, hubs=hubs)
        new.evidence, new.evidence_px = marks_own.evidence, marks_own.evidence_px  # the marks' own: the view's score
        h = replace(hypothesis, solution=new, view=new.view or hypothesis.view)
        if k + 1 < policy.wheel_passes:
            miss = np.linalg.norm(_hubs_px(new, h.view)[index] - targets, axis=1)
            fits = 1.0 / (1.0 + (miss / (policy.wheel_robust_scale * sigma)) ** 2)
    share = shares()
    likeliest = np.array([int(np.flatnonzero(owner == i)[np.argmax(share[owner == i])]) for i in range(len(wheels))])
    first = np.array([int(np.flatnonzero(owner == i)[0]) for i in range(len(wheels))])
    return h, hubs, weight[likeliest], likeliest - first, targets[likeliest]


def _hubs_px(solution, view: View) -> np.ndarray:
    """(4, 2) a solution's hubs in the fit camera's pixels."""
    return project(hub_points(solution.shape), view, solution.scale, solution.offset)
