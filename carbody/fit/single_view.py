"""Single-view wireframe fitting: keypoints on one photo + a view angle → the car's 3D wireframe.

:func:`fit_wireframe` is the whole stage in one call (the ``carbody fit`` command is a thin layer
over it): check the keypoints, solve the library mix at the given view, refine the view, and
return the new model in millimetres with everything the overlay and the report need.
"""
from __future__ import annotations

from functools import partial

import numpy as np

from carbody.camera import View, apply_homography, degrees_from_axis, look_at_homography, perspective_factors, project
from carbody.errors import AngleError, FitError, SideError
from carbody.fit.keypoints_io import KeypointSlot, check_keypoints, keypoint_slots
from carbody.fit.refine import AZIMUTH_RANGE_DEG, DEFAULT_FREE, PERSPECTIVE_LENGTH, refine_view, view_score
from carbody.fit.result import END_SUSPECT_EVIDENCE, FitResult, at_search_edge
from carbody.fit.shape_prior import implausibility, library_mean, prepared, prepared_field
from carbody.fit.solve import (DEFAULT_PRIOR_WEIGHT, METHODS, PERSPECTIVE_ITERATIONS, MixSolution, ShapeModel,
                               car_centre, keypoint_covariance, keypoint_spread, solve_gauss, solve_simplex)
from carbody.library import Library
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import load_topology
from carbody.view.labels import angular_difference
from carbody.wireframe import MIRROR, RIGHT_SUFFIX, Wireframe

#: A refined view that stopped at the edge of the range searched (:func:`~carbody.fit.result.at_search_edge`)
#: is searched again around, at most this many times (a view given up to ~70° off; no
#: end-to-end benchmark run reaches the edge).
MAX_VIEW_WALKS = 2


def _walked(search_view: View, azimuth: float) -> bool:
    """Whether a fit started at ``azimuth`` searched again around another view (``MAX_VIEW_WALKS``)."""
    return bool(angular_difference(search_view.azimuth, azimuth) > 1e-9)


def fit_wireframe(keypoints: dict[str, tuple[float, float]], view: View | float,
                  library: Library | None = None, *, image_size: tuple[int, int] | None = None,
                  wheelbase_mm: float | None = None, method: str = METHODS[0],
                  prior_weight: float = DEFAULT_PRIOR_WEIGHT, refine: bool = True,
                  deform: bool | None = None, camera_distance_mm: float | str | None = None,
                  principal_point: str | tuple[float, float] = "auto", focal_px: float | None = None,
                  reject_outliers: bool = True, joint_field: bool = True, check_orthographic: bool = False,
                  name: str = "fitted car") -> FitResult:
    """Fit the car's 3D wireframe to keypoints marked on one photo.

    Args:
        keypoints: {name: (u, v)} pixels; any subset of the 35 names and their ``_right`` mirrors.
        view: the view, or its azimuth in degrees (0–360) or name (``"front 30"``,
            :func:`carbody.camera.read_view`).
        library: the model library (default :func:`carbody.library.load_library`).
        image_size: (width, height) px; keypoints off the image are refused.
        wheelbase_mm: real wheelbase; default the fitted mix of the templates' own. Told, the
            Gaussian-prior methods also know the car's width and height in mm
            (:func:`~carbody.fit.shape_prior.sized_shape_model`), so a wrong one bends the shape
            a little, not only its size.
        method: ``"mixture"`` (a Gaussian shape prior around each template, default),
            ``"gauss"`` (one around the library mean) or ``"paper"`` (plain ΣH = 1,
            0 ≤ H ≤ 1); see :mod:`carbody.fit.solve`.
        prior_weight: λ of ``"gauss"`` and ``"mixture"``.
        refine: refine azimuth and elevation around ``view`` (roll stays as given; see
            :mod:`carbody.fit.refine`); off, the view stays as given (a camera distance
            ``"auto"`` is still found).
        deform: after the solve, move the fit onto the annotated keypoints with a smooth
            symmetric field (:mod:`carbody.fit.deform`); default on for ``"gauss"``/``"mixture"``,
            off for ``"paper"`` (the paper's method as published). The Gaussian-prior solve's
            own field (``JOINT_FIELD_AMPLITUDE``) is part of the solve either way, unless
            ``joint_field`` is False.
        camera_distance_mm: None for SPEC's orthographic camera; a number for a pinhole camera
            that far from the car's centre (a photo taken from a few metres shows nearer parts
            larger; without ``wheelbase_mm`` it sizes the car: the fit finds the distance in
            wheelbases from the perspective, and the two give the wheelbase; with too little
            perspective for that, it is read at the fitted car's own wheelbase);
            ``"auto"`` to find the distance (with the view, when it is refined);
            ``"orthographic"`` is None.
        principal_point: where a pinhole camera's optical axis meets the photo: ``"car"``
            (the camera pointed at the car's centre, or the photo cropped around it),
            ``"centre"`` (the image centre of an uncropped photo; needs ``image_size``), (u, v)
            pixels, or ``"auto"`` (default): ``"centre"`` when ``focal_px`` is known (a focal
            length from EXIF or a 35 mm-equivalent one holds for the uncropped frame only),
            else ``"car"``. A car off the axis is seen
            obliquely by the image plane: the fit then turns the camera about its centre to
            look at the car (:func:`~carbody.camera.look_at_homography`) and fits again. The turn needs the
            focal length: ``focal_px``, else the fit's own (scale × distance) until it settles,
            and with the distance ``"auto"`` as well (where the obliquity can pass for a nearer
            camera) then the focal length whose turned fit has the best evidence, a 1-D search
            of about ten refits (~1–2 s; BENCHMARKS.md). Orthographic fits ignore it.
        focal_px: the camera's focal length in pixels, if known (a photo's 35 mm-equivalent
            focal length × its diagonal in pixels / 43.3 mm, :mod:`carbody.fit.focal`): the
            turn toward an off-centre car then uses it, with no search.
        reject_outliers: leave out up to ``MAX_OUTLIERS`` marks the rest of the car says are
            misplaced (:func:`_outliers`), and fit a left/right pair whose names were exchanged
            with them exchanged back (Gaussian-prior methods): named in
            ``FitResult.rejected_px`` and ``FitResult.swapped_names``.
        joint_field: the Gaussian-prior methods solve the mix with the local displacement field
            inside the prior (default); False solves the library's span alone (stiffer: what
            :func:`carbody.reconstruct` falls back to when a fitted region's outline crosses
            itself).
        check_orthographic: with the orthographic camera (``camera_distance_mm`` None), also
            fit the marks with the distance found (``FitResult.orthographic_check``) and say in
            ``FitResult.closer_camera`` when a camera close by fits them far better (a photo from
            a few metres fitted as if from afar gives a distorted car; :func:`_orthographic_check`).
            The fit itself is unchanged.
        name: the car's name (STEP product).
    Raises:
        KeypointError: unknown, too few, NaN, off-image or degenerate keypoints.
        AngleError: a view outside 0–360°.
        SideError: the keypoints' names are of the car's other side (:func:`_check_side`), they
            fit its other end far better (:func:`_check_end`), or a refined view that fits them
            poorly or stopped at the edge of its search is far from one that fits them soundly
            (:func:`_check_elsewhere`); ``azimuth`` names that view.
        FitError: an unknown method or a bad wheelbase, or keypoints no model can match.
    """
    from carbody.camera import MAX_ABS_ROLL_DEG, check_azimuth, read_view

    if not isinstance(view, View):
        view = View(check_azimuth(read_view(view) if isinstance(view, str) else view))
    else:
        check_azimuth(view.azimuth)
    if abs(view.roll) > MAX_ABS_ROLL_DEG:
        raise AngleError(f"view roll {view.roll:g}° is outside ±{MAX_ABS_ROLL_DEG:g}°: turn the photo upright")
    if camera_distance_mm == "orthographic":
        camera_distance_mm = None
    if method not in METHODS:
        raise FitError(f"unknown fit method {method!r} (known: {', '.join(METHODS)})")
    if wheelbase_mm is not None and not (np.isfinite(wheelbase_mm) and MIN_WHEELBASE_MM <= wheelbase_mm <= MAX_WHEELBASE_MM):
        raise FitError(f"wheelbase {wheelbase_mm!r} mm is not a car's ({MIN_WHEELBASE_MM:g}–{MAX_WHEELBASE_MM:g} mm)")
    if library is None:
        from carbody.library import load_library

        library = load_library()
    slots, uv = check_keypoints(keypoints, image_size, load_topology())
    said = _check_side(slots, view, library)
    principal = _principal_point(principal_point, image_size, focal_px)
    if focal_px is not None and not (np.isfinite(focal_px) and focal_px > 0):
        raise FitError(f"focal length {focal_px!r} px is not a positive number")
    deform = (method != "paper") if deform is None else deform
    marks = dict(view=view, library=library, method=method, prior_weight=prior_weight, refine=refine,
                 camera_distance_mm=camera_distance_mm, wheelbase_mm=wheelbase_mm, name=name,
                 principal=principal, focal_px=focal_px, deform=deform, joint_field=joint_field)
    result = _fit_checking_marks(slots, uv, marks, said, reject_outliers and method != "paper")
    if check_orthographic and camera_distance_mm is None:
        result.orthographic_check = _orthographic_check(result, marks)
    return result


def _fit_checking_marks(slots: list[KeypointSlot], uv: np.ndarray, marks: dict, said: tuple | None,
                        reject_outliers: bool) -> FitResult:
    """:func:`fit_wireframe` on checked input: the fit, the car's other end
    (:func:`_check_end`), and (``reject_outliers``) marks left out or a pair's names exchanged."""
    result = _fit_marks(slots, uv, **marks)
    _check_end(result, said, slots, uv, marks)
    result = _check_elsewhere(result, slots, uv, marks)
    if not reject_outliers:
        return result
    prior_weight = marks["prior_weight"]
    # (a fit of the marks without one, as this one was made: whether leaving it out fits soundly)
    refit = partial(_fit_marks, **{**marks, "deform": False})
    rejected, swapped = _outliers(result, prior_weight, refit), None
    # A mark left out, or standing out, whose left/right twin is marked too: do the two fit with
    # their names exchanged (the car's left is the viewer's right on a front view)? (A pair
    # swapped on a front or rear view bends the whole car, so its marks may not be the ones left
    # out.) Kept when the pair then fits and the marks' median residual falls by SWAP_GAIN. A
    # mark standing out by less than OUTLIER_SPREAD of the marks' spread is a click's error, not
    # a pair seen from the car's other side: no trial (a trial is a whole fit).
    before = float(np.median(_solve_residual(result)))
    far = OUTLIER_SPREAD * keypoint_spread(result.marks_in_fit_camera())
    best = None
    for pair in _twin_pairs(rejected + _candidates(result, far), slots)[:MAX_SWAP_TRIALS]:
        renamed = _swap_names(slots, pair)
        try:
            trial = _fit_marks(renamed, uv, **marks)
            again = _outliers(trial, prior_weight)
        except (FitError, AngleError):  # no car fits them so either
            continue
        after = float(np.median(_solve_residual(trial)))
        if not set(pair) & set(again) and after < SWAP_GAIN * before and (best is None or after < best[0]):
            best = (after, renamed, trial, again, pair)
    if best is not None:
        _, slots, result, rejected, swapped = best
    if rejected:
        keep = [i for i, s in enumerate(slots) if s.name not in rejected]
        try:
            without = _fit_marks([slots[i] for i in keep], uv[keep], **marks)
        except (FitError, AngleError):  # the rest alone pin nothing down: keep every mark
            result.swapped_names = swapped
            return result
        result = without
        result.rejected_px = {n: float(e) for n, e in zip(rejected, _distances_to_marks(result, rejected, slots, uv))}
        result.rejected_uv = {s.name: (float(p[0]), float(p[1])) for s, p in zip(slots, uv) if s.name in rejected}
        result.rejected_looks_like = _looks_like(result, result.rejected_uv)
    result.swapped_names = swapped
    return result


#: An orthographic fit's marks are said to show a camera close by when the fit with the distance
#: found leaves them, before either deformation, at most this fraction of the orthographic
#: mean residual …
CLOSER_CAMERA_GAIN = 0.6

#: … or its −log evidence per marked coordinate is lower by more than this (BENCHMARKS.md: at
#: most 0.32 on the leave-one-out benchmark's orthographic pictures, with 1 or 5 px of noise or a
#: misplaced mark): a level front view from a few metres can be fitted orthographic to about a
#: pixel, but by a car seen steeply from above.
CLOSER_CAMERA_EVIDENCE = 1.0


def _orthographic_check(result: FitResult, marks: dict) -> dict | None:
    """Fit an orthographic result's marks (those it kept) with the camera's distance found, from
    the given view (as ``camera_distance_mm="auto"`` would): that camera's distance (None: far
    away), both mean residuals (before the deformation), how much likelier its fit is (−log
    evidence per coordinate; None for the paper's solve) and whether it fits them far better
    (``CLOSER_CAMERA_GAIN``, ``CLOSER_CAMERA_EVIDENCE``); None when no car fits them so. A photo
    from a few metres shows the car's near end larger than its far end, which no orthographic
    view of any car does: fitted as if from afar, its marks stay pixels off, or the view runs
    tens of degrees astray to bend a car onto them, and the car comes out distorted
    (BENCHMARKS.md: ``--orthographic-check``)."""
    fit = dict(slots=result.slots, uv=result.uv, view=marks["view"], library=marks["library"], method=marks["method"],
               prior_weight=marks["prior_weight"], refine=marks["refine"], camera_distance_mm="auto",
               wheelbase_mm=marks["wheelbase_mm"], name=marks["name"], joint_field=marks["joint_field"])
    try:
        near = _fit_checked(**fit, distance_wheelbase_mm=marks["wheelbase_mm"])
    except (FitError, AngleError):
        return None
    far, close = float(np.mean(_solve_residual(result))), float(np.mean(near.solution.residual_px))
    gain = None
    if result.solution.evidence is not None and near.solution.evidence is not None:
        gain = float(result.solution.evidence - near.solution.evidence) / (2 * len(result.slots))
    closer = near.view.distance is not None and (
        close < CLOSER_CAMERA_GAIN * far or (gain is not None and gain > CLOSER_CAMERA_EVIDENCE))
    return {"camera_distance_mm": near.camera_distance_mm, "residual_px_mean": close,
            "orthographic_residual_px_mean": far, "evidence_gain_per_coordinate": gain,
            "closer_camera": bool(closer)}


#: Left/right pairs of marks tried with their names exchanged, at most …
MAX_SWAP_TRIALS = 3

#: … and one is kept when the marks' median residual before the deformation falls below this
#: fraction of what it was.
SWAP_GAIN = 0.5


def _twin_pairs(names: list[str], slots: list[KeypointSlot]) -> list[tuple[str, str]]:
    """(left name, right name) of each of ``names`` whose mirror twin (``x`` / ``x_right``) is
    marked too, in order, once each."""
    marked = {s.name for s in slots}
    pairs = []
    for n in names:
        left = n.removesuffix(RIGHT_SUFFIX)
        pair = (left, left + RIGHT_SUFFIX)
        if set(pair) <= marked and pair not in pairs:
            pairs.append(pair)
    return pairs


def _solve_residual(result: FitResult) -> np.ndarray:
    """(k,) the marks' residuals before the deformation, px."""
    r = result.solve_residual_px if result.solve_residual_px is not None else result.solution.residual_px
    return np.asarray(r, dtype=float)


def _swap_names(slots: list[KeypointSlot], pair: tuple[str, str]) -> list[KeypointSlot]:
    """``slots`` with the two named marks' names exchanged."""
    named = keypoint_slots()
    a, b = pair
    return [named[b] if s.name == a else named[a] if s.name == b else s for s in slots]


#: A mark left out "looks like" another keypoint when the fitted car puts that one within this
#: fraction of the marks' RMS spread of it (≈ 6 px for a car 900 px wide).
LOOKS_LIKE_SPREAD = 0.02


def _looks_like(result: FitResult, marks: dict[str, tuple[float, float]]) -> dict[str, str]:
    """{mark left out: the keypoint the fitted car puts where it was clicked}, for those near
    one (``LOOKS_LIKE_SPREAD``): a click meant for another name."""
    spread = keypoint_spread(result.uv)
    cp = result.wireframe.control_points
    named = keypoint_slots()
    names = list(named)
    where = result.project_points(np.array([cp[named[n].point_index] * named[n].sign for n in names]))
    out = {}
    for mark, uv in marks.items():
        d = np.linalg.norm(where - np.asarray(uv), axis=1)
        d[names.index(mark)] = np.inf
        j = int(np.argmin(d))
        if d[j] < LOOKS_LIKE_SPREAD * spread:
            out[mark] = names[j]
    return out


#: A mark is tested as misplaced when its residual before the deformation exceeds this many
#: times the median …
OUTLIER_CANDIDATE_RATIO = 4.0

#: … and left out when the car fitted without it passes further from it than this many standard
#: deviations of where that fit expects it (the keypoint's posterior spread seen in the photo,
#: and the marks' noise, ``KEYPOINT_NOISE``) …
OUTLIER_SIGMAS = 5.0

#: … and further than this fraction of the marks' RMS spread (≈ 9 px for a car 900 px wide).
OUTLIER_SPREAD = 0.03

#: At most this many marks are left out.
MAX_OUTLIERS = 2

#: A fit that fits poorly tries this many of its most influential marks (:func:`_influential`:
#: a whole fit each, only for such fits).
INFLUENTIAL_TRIALS = 1


def _candidates(result: FitResult, floor_px: float = 0.0) -> list[str]:
    """Names of marks whose residual before the deformation exceeds
    ``OUTLIER_CANDIDATE_RATIO`` × the median (and ``floor_px``), worst first."""
    residual = _solve_residual(result)
    order = np.argsort(-residual)
    limit = max(OUTLIER_CANDIDATE_RATIO * float(np.median(residual)), floor_px)
    return [result.slots[i].name for i in order if residual[i] > limit]


def _outliers(result: FitResult, prior_weight: float, refit=None) -> list[str]:
    """Names of marks the rest of the car says are misplaced, worst first.

    A misplaced mark (a click on the wrong feature, two names swapped) bends the fitted car
    toward it, so its residual after the fit understates it. Each candidate (the largest
    residual before the deformation, ``OUTLIER_CANDIDATE_RATIO``) is tested against the car
    fitted without it at the same camera: how many of that fit's standard deviations it lies
    from where that fit puts its keypoint (``OUTLIER_SIGMAS``, ``OUTLIER_SPREAD``). A mark
    the other marks predict, however far from the library, stays. A mark bent far enough can
    spread its misfit over all the others (the right twin of a point clicked on the left one's
    spot: the car narrows and turns to reach it), so when the fit fits poorly
    (:attr:`~carbody.fit.result.FitResult.fits_poorly`) a mark whose leaving out makes the solve
    likeliest is a candidate too, whatever its residual, when the rest, fitted as this fit was
    (``refit(slots, uv)``, view refined as it was), fit soundly (:func:`_influential`): a
    photo no car fits as a whole — a view kept far off, a close photo fitted as if from afar —
    loses no mark to it.
    """
    from carbody.fit.deform import KEYPOINT_NOISE
    from carbody.fit.keypoints_io import MIN_KEYPOINTS

    slots = list(result.slots)
    uv = result.marks_in_fit_camera()
    residual = _solve_residual(result)
    spread = keypoint_spread(uv)
    told = result.wheelbase_mm if result.wheelbase_from == "told" else None

    def at_camera(some: list[KeypointSlot], at: np.ndarray) -> FitResult:  # fitted at the same camera
        return _fit_checked(some, at, view=result.view, library=result.library, method=result.method,
                            prior_weight=prior_weight, refine=False,
                            camera_distance_mm=None if result.view.distance is None else "kept",
                            wheelbase_mm=told, distance_wheelbase_mm=told, name=result.wireframe.name,
                            joint_field=result.joint_field)

    def fitted_without(i: int) -> FitResult:  # the others (of those still kept), at the same camera
        keep = [j for j in range(len(slots)) if j != i]
        return at_camera([slots[j] for j in keep], uv[keep])

    influential = None if result.fits_poorly and refit else []  # found when the residuals name none
    tried: set[str] = set()
    rejected: list[str] = []
    while len(rejected) < MAX_OUTLIERS and len(slots) > MIN_KEYPOINTS:
        i = _next_candidate(slots, residual, influential or [], tried)
        if i is None and influential is None:
            influential = _influential(result, at_camera, refit)
            i = _next_candidate(slots, residual, influential, tried)
        if i is None:
            break
        tried.add(slots[i].name)
        keep = [j for j in range(len(slots)) if j != i]
        slot = slots[i]
        try:
            without = fitted_without(i)
            sol = without.solution
            point = sol.shape.reshape(-1, 3)[slot.point_index] * slot.sign
            miss = uv[i] - project(point, without.view, sol.scale, sol.offset)
            jac = np.stack([project(point + d, without.view, sol.scale, sol.offset)
                            - project(point - d, without.view, sol.scale, sol.offset) for d in np.eye(3)],
                           axis=1) / 2.0
        except (FitError, AngleError):  # the car without it puts the camera inside: no verdict
            break
        cov = keypoint_covariance(sol.posterior)[slot.keypoint_id - 1] * np.outer(slot.sign, slot.sign)
        spread_seen = jac @ cov @ jac.T + (KEYPOINT_NOISE * sol.scale) ** 2 * np.eye(2)
        sigmas = float(np.sqrt(miss @ np.linalg.solve(spread_seen, miss)))
        if sigmas <= OUTLIER_SIGMAS or np.linalg.norm(miss) <= OUTLIER_SPREAD * spread:
            continue  # the rest predict it: it stays (an influential one may be tried next)
        rejected.append(slot.name)
        slots, uv, residual = [slots[j] for j in keep], uv[keep], np.asarray(sol.residual_px, dtype=float)
    return rejected


def _influential(result: FitResult, at_camera, refit) -> list[str]:
    """Names of marks whose leaving out turns ``result`` (a fit that fits poorly) sound: of the
    ``INFLUENTIAL_TRIALS`` whose leaving out makes its solve likeliest (−log evidence falls most;
    each the others' solve at the same camera, ``at_camera(slots, uv)`` in its pixels,
    unrefined: a few ms a mark), those whose leaving out ``refit`` (photo pixels) fits soundly
    (a whole fit each), most first; [] for the paper's solve, which has no evidence."""
    if result.solution.evidence is None:
        return []
    slots, uv, seen = result.slots, result.uv, result.marks_in_fit_camera()
    gains = []
    for i in range(len(slots)):
        keep = [j for j in range(len(slots)) if j != i]
        try:
            without = at_camera([slots[j] for j in keep], seen[keep])
        except (FitError, AngleError):
            continue
        gains.append((float(result.solution.evidence - without.solution.evidence), i))
    sound = []
    for _, i in sorted(gains, reverse=True)[:INFLUENTIAL_TRIALS]:
        keep = [j for j in range(len(slots)) if j != i]
        try:
            if not refit([slots[j] for j in keep], uv[keep]).fits_poorly:
                sound.append(slots[i].name)
        except (FitError, AngleError):
            continue
    return sound


def _next_candidate(slots: list[KeypointSlot], residual: np.ndarray, influential: list[str],
                    tried: set[str]) -> int | None:
    """The next mark :func:`_outliers` tests: the largest residual when it exceeds
    ``OUTLIER_CANDIDATE_RATIO`` × the median, else the next of ``influential``; one not tried
    yet, or None."""
    top = int(np.argmax(residual))
    if residual[top] > OUTLIER_CANDIDATE_RATIO * float(np.median(residual)) and slots[top].name not in tried:
        return top
    names = [s.name for s in slots]
    return next((names.index(n) for n in influential if n in names and n not in tried), None)


def _distances_to_marks(result: FitResult, names: list[str], slots: list[KeypointSlot],
                        uv: np.ndarray) -> list[float]:
    """How far (px) the fitted car passes from each named mark of ``slots`` / ``uv``."""
    by_name = {s.name: (s, p) for s, p in zip(slots, uv)}
    out = []
    for n in names:
        slot, mark = by_name[n]
        point = result.wireframe.control_points[slot.point_index] * slot.sign
        out.append(float(np.linalg.norm(result.project_points(point) - mark)))
    return out


def _fit_marks(slots: list[KeypointSlot], uv: np.ndarray, view: View, library: Library, method: str,
               prior_weight: float, refine: bool, camera_distance_mm, wheelbase_mm: float | None,
               name: str, principal: np.ndarray | None, focal_px: float | None, deform: bool,
               joint_field: bool = True) -> FitResult:
    """:func:`fit_wireframe` on checked marks: the solve, the view, the camera (its distance,
    its turn toward an off-centre car), the wheelbase, and the deformation."""
    # Passes that may be refitted skip the deformation; the fit kept gets it (_deformed) at the end.
    fit = dict(slots=slots, uv=uv, view=view, library=library, method=method,
               prior_weight=prior_weight, refine=refine, camera_distance_mm=camera_distance_mm,
               wheelbase_mm=wheelbase_mm, name=name, joint_field=joint_field)
    by_distance = None  # the wheelbase a told distance and the perspective give
    if wheelbase_mm is not None or camera_distance_mm in (None, "auto"):
        result = _fit_checked(**fit, distance_wheelbase_mm=wheelbase_mm)
    else:
        # A distance told in mm without the wheelbase: the perspective gives the distance in
        # wheelbases, so the two give the car's size (BENCHMARKS.md: closer than the mix's own) …
        _pinhole(view, camera_distance_mm, None, library)  # refuses a camera in the car
        result = _fit_checked(**{**fit, "camera_distance_mm": "auto"}, distance_wheelbase_mm=None)
        if result.view.distance is not None:
            by_distance = float(camera_distance_mm) * NORMALISED_WHEELBASE / result.view.distance
            lo, hi = np.min(library.template_wheelbase_mm), np.max(library.template_wheelbase_mm)
            if not lo / PERSPECTIVE_SIZE_RANGE <= by_distance <= hi * PERSPECTIVE_SIZE_RANGE:
                by_distance = None
        if by_distance is not None:
            result = _at_wheelbase(result, by_distance)
        else:
            # … unless it shows too little perspective for that (a distant camera): then the
            # told distance is read at the car's own wheelbase, which the fit gives; a pass or
            # two more agree to DISTANCE_WHEELBASE_AGREEMENT.
            read_at = result.wheelbase_mm
            for _ in range(DISTANCE_PASSES):
                result = _fit_checked(**fit, distance_wheelbase_mm=read_at)
                if abs(result.wheelbase_mm / read_at - 1.0) < DISTANCE_WHEELBASE_AGREEMENT:
                    break
                read_at = result.wheelbase_mm
    if principal is None or result.view.distance is None:
        return _deformed(result) if deform else result
    # Turn the camera to look at the car's centre and refit: by the known focal length, else the
    # fit's own (f = s·D) until the turn settles, then, when the distance is found too, the focal
    # length whose fit has the best evidence (an oblique image plane passes for a nearer camera,
    # and the turn by that camera's focal length can settle far off).
    turn = dict(fit=fit, uv=uv, principal=principal, given=view)
    if focal_px is not None or camera_distance_mm != "auto":
        result = _looking_at_car(result, focal_px, **turn, rescan=True)
        if by_distance is not None:  # the turned fit read the told distance at that size
            result = _at_wheelbase(result, by_distance)
    else:
        unturned, result = result, _looking_at_car(result, None, **turn)
        if result.focal_px is not None:  # turned: now the focal length with the best evidence
            result = _looking_at_car(unturned, _best_focal(result, unturned, turn), **turn, rescan=True)
    return _deformed(result) if deform else result


def _check_side(slots: list[KeypointSlot], view: View, library: Library) -> tuple | None:
    """Refuse a view from which many marks cannot be seen but from its mirror can
    (:func:`carbody.fit.visibility.view_the_marks_say`): the photo shows the car's other side
    (a classifier's left/right mistake, 30° given for 330°) or the marks' left/right names are
    swapped. The refinement stays near the given view, so it could only bend the car through
    itself to fit them. When the marks say the car's other end instead (30° given for 150°),
    the names alone are not enough (a deck seen over the roof from a little above): returns
    what they say, for :func:`_check_end`'s message.

    Raises:
        SideError: naming the mirror view.
    """
    from carbody.fit.visibility import view_the_marks_say

    said = view_the_marks_say([s.name for s in slots], view, library_mean(library).reshape(-1, 3))
    if said is None or said[1] == "end":
        return said
    azimuth, _, hidden = said
    raise SideError(f"{len(hidden)} of the {len(slots)} keypoints ({', '.join(hidden[:3])}, …) cannot be seen "
                    f"from a view of {view.azimuth:g}° but can from one of {azimuth:g}°: the photo shows "
                    "the car's other side, or the marks' left/right names are swapped", azimuth)


#: Within this many degrees of the front or rear, a fit is checked against the car's other end
#: (θ ↔ 180° − θ) when the marks' names say so or its −log evidence exceeds this per coordinate
#: (``END_SUSPECT_EVIDENCE``, Gaussian-prior methods) …
END_CHECK_DEG = 60.0

#: … and the other end is taken for the photo's when the fit there is sound (within
#: ``END_SUSPECT_EVIDENCE``) and beats the given view's by this much −log evidence (on those
#: templates the two differ by far more, one way or the other) …
END_EVIDENCE_MARGIN = 20.0

#: … or this factor on the cost (the paper's solve, checked only when the names say so).
END_COST_FACTOR = 0.5


def _check_end(result: FitResult, said: tuple | None, slots: list[KeypointSlot], uv: np.ndarray,
               marks: dict) -> None:
    """Refuse a view near the front or rear when the marks fit the car's other end far better.
    A front three-quarter photo told the rear three-quarter view fits, bent, with a few pixels
    of residual; its evidence gives it away. The other end is fitted (as the given view was) —
    and, when the names say nothing, the other end seen from the car's other side too (a half
    turn: 195° for 15°) — only when the marks' names say so (``said``, from
    :func:`carbody.fit.visibility.view_the_marks_say`) or the fit's evidence is poor
    (``END_SUSPECT_EVIDENCE``), so a sound fit costs nothing more.

    Raises:
        SideError: naming that view.
    """
    given = marks["view"]
    if degrees_from_axis(given.azimuth) > END_CHECK_DEG:
        return
    here = view_score(result.solution)
    paper = result.method == "paper"
    if said is None and (paper or here <= END_SUSPECT_EVIDENCE * 2 * len(slots)):
        return
    # The other end (θ ↔ 180° − θ) and, when the names did not say which, the other end seen from
    # the car's other side (θ ↔ 180° + θ: a view told a half turn off, whose few side marks near
    # the front or rear need not give the side away)
    ends = [(180.0 - given.azimuth) % 360.0]
    if said is None and degrees_from_axis(given.azimuth) > 1.0:
        ends.append((180.0 + given.azimuth) % 360.0)
    best = None
    for azimuth in ends:
        try:
            other = _fit_marks(slots, uv, **{**marks, "view": View(azimuth, given.elevation, given.roll), "deform": False})
        except (FitError, AngleError):
            continue
        if other.search_view is not None and _walked(other.search_view, azimuth):
            continue  # its view walked off toward another (the given end's, from the mirror)
        there = view_score(other.solution)
        if best is None or there < best[1]:
            best = (azimuth, there)
    if best is None:
        return
    azimuth, there = best
    # (a sound fit there, not merely a less bad one: a left/right pair swapped on a front view
    # fits both ends badly, and is for the rejection to mend)
    sound = paper or there <= END_SUSPECT_EVIDENCE * 2 * len(slots)
    if not (sound and (there < here * END_COST_FACTOR if paper else there < here - END_EVIDENCE_MARGIN)):
        return
    names = "" if said is None else (f"; {len(said[2])} of the {len(slots)} keypoints ({', '.join(said[2][:3])}, …) "
                                     "cannot be seen from the view given")
    side = "" if azimuth == ends[0] else ", seen from its other side"
    raise SideError(f"the marks fit a view of {azimuth:g}° far better than the {given.azimuth:g}° given "
                    f"(−log evidence {there:.0f} against {here:.0f}{names}): the photo shows the car's other "
                    f"end (front for rear{side}), or the marks' front/rear names are swapped", azimuth)


#: A fit that fits poorly (``END_SUSPECT_EVIDENCE``) or stopped at the edge of its search is
#: checked against views all round the car, this far apart, unrefined; the best
#: ``ELSEWHERE_REFINED`` of them are refined (BENCHMARKS.md, ``bench_fit_accuracy.py --view-off``).
ELSEWHERE_STEP_DEG = 15.0
ELSEWHERE_REFINED = 2


def _check_elsewhere(result: FitResult, slots: list[KeypointSlot], uv: np.ndarray, marks: dict) -> FitResult:
    """Check a refined fit that fits the marks poorly, or whose refinement stopped at the edge of
    its search (``view_at_search_edge``), against views all round the car: a front
    three-quarter photo told the side view refines to a car that misses the marks by pixels,
    and the refinement searches only around the view given (``MAX_VIEW_WALKS``). Views every
    ``ELSEWHERE_STEP_DEG`` are fitted unrefined, the best ``ELSEWHERE_REFINED`` refined. One
    that beats the fit by ``END_EVIDENCE_MARGIN`` −log evidence within the range searched
    around the view given (its refinement settled in a worse place, as a pinhole photo fitted
    as orthographic can) is taken instead (deformed as the fit would have been); one further off that also fits
    soundly (``END_SUSPECT_EVIDENCE``) is refused. A sound fit costs nothing more, and a view
    not to be refined (``refine`` False) is the user's: not checked.

    Returns:
        ``result``, or the better fit near the view given.
    Raises:
        SideError: naming the view further off.
    """
    if result.method == "paper" or not marks["refine"] or not (result.fits_poorly or result.view_at_search_edge):
        return result
    given = marks["view"]
    fitted = (given.azimuth, result.view.azimuth)
    scanned = []
    for azimuth in np.arange(0.0, 360.0, ELSEWHERE_STEP_DEG):
        if min(angular_difference(azimuth, a) for a in fitted) < ELSEWHERE_STEP_DEG / 2:
            continue
        view = View(float(azimuth), given.elevation, given.roll)
        try:
            fit = _fit_marks(slots, uv, **{**marks, "view": view, "refine": False, "deform": False})
        except (FitError, AngleError):
            continue
        scanned.append((view_score(fit.solution), view))
    best = None
    for _, view in sorted(scanned, key=lambda c: c[0])[:ELSEWHERE_REFINED]:
        try:
            fit = _fit_marks(slots, uv, **{**marks, "view": view, "deform": False})
        except (FitError, AngleError):
            continue
        if best is None or view_score(fit.solution) < view_score(best.solution):
            best = fit
    here, there = view_score(result.solution), None if best is None else view_score(best.solution)
    if there is None or not there < here - END_EVIDENCE_MARGIN:
        return result
    if angular_difference(best.view.azimuth, given.azimuth) <= AZIMUTH_RANGE_DEG:
        near = _deformed(best) if marks["deform"] else best  # the candidate's own fit, finished
        near.given_view = given
        return near
    if best.fits_poorly:
        return result
    azimuth = round(best.view.azimuth) % 360
    raise SideError(f"the marks fit a view of {azimuth:g}° far better than the {given.azimuth:g}° given "
                    f"(−log evidence {there:.0f} against {here:.0f}): give that view, or leave it to "
                    "the view classifier (`carbody reconstruct` without --view)", float(azimuth))


#: A focal length (pixels) under this fraction of the photo's diagonal (taken as twice the
#: principal point's distance from the corner) is no camera's: 10 mm in 35 mm-equivalent terms,
#: wider than the widest phone lens. A fit bent to the wrong end, or a turn that crushes the
#: marks together, drifts there (a focal length collapsing toward 0; a camera turned 90°): the
#: fit's own focal length is taken no shorter, a searched or told one that short is not turned by.
MIN_FOCAL_DIAGONAL = 10.0 / 43.3


def _looking_at_car(result: FitResult, focal_px: float | None, fit: dict, uv: np.ndarray,
                    principal: np.ndarray, given: View, passes: int | None = None,
                    rescan: bool = False) -> FitResult:
    """Refit ``result`` (a pinhole fit made as if the camera looked at the car) with the camera
    turned about its centre to look at the car. ``focal_px`` None: the fit's own, f = s·D.
    ``rescan``: the first refit starts again from the given view with the refinement's coarse
    scan (an oblique image plane can have pulled the unturned fit's view degrees off), the
    later ones from the previous refit's view."""
    looking = np.array([0.0, 0.0, 1.0])
    for _ in range(passes or PRINCIPAL_PASSES):
        aim_px = result.project_points(np.asarray(result.view.aim) * result.mm_per_unit)
        least = MIN_FOCAL_DIAGONAL * 2.0 * float(np.hypot(*principal))
        focal = focal_px if focal_px is not None else max(result.solution.scale * result.view.distance, least)
        if not (np.isfinite(focal) and focal >= least):
            break  # no camera's focal length: keep the last fit
        to_car = np.append((aim_px - principal) / focal, 1.0)
        to_car /= np.linalg.norm(to_car)
        if np.degrees(np.arccos(min(1.0, float(to_car @ looking)))) < PRINCIPAL_TOLERANCE_DEG:
            break  # the camera already looks at the car
        looking, to_turned = to_car, look_at_homography(aim_px, principal, focal)
        try:
            turned = _fit_checked(**{**fit, "uv": apply_homography(to_turned, uv),
                                     "view": fit["view"] if rescan else result.view},
                                  distance_wheelbase_mm=result.wheelbase_mm, scan=rescan)
            _in_photo(turned, to_turned, uv, given)
        except AngleError:
            break  # this turn's best camera sits in the car (a wild focal length): keep the last fit
        result, rescan = turned, False
        result.focal_px, result.camera_turn_deg = focal, float(np.degrees(np.arccos(looking[2])))
    return result


def _best_focal(settled: FitResult, unturned: FitResult, turn: dict) -> float:
    """The focal length (px) whose turn toward the car fits the marks with the best evidence:
    searched on a log scale within FOCAL_SEARCH_RANGE of the one ``settled`` (a turned fit)
    used, each candidate one turn of the ``unturned`` fit and a refit from its view (a wrong
    focal length can have turned ``settled``'s view far off). The evidence is rugged in the
    focal length (each refit settles in its own view), so a grid of FOCAL_SEARCH_GRID first,
    then a bounded search between the best one's neighbours."""
    from scipy.optimize import minimize_scalar

    scores = {}

    def score(log_f: float) -> float:
        fit = _looking_at_car(unturned, float(np.exp(log_f)), **turn, passes=1)
        scores[log_f] = np.inf if fit is unturned else view_score(fit.solution)  # a dropped turn
        return scores[log_f]

    centre, span = float(np.log(settled.focal_px)), float(np.log(FOCAL_SEARCH_RANGE))
    grid = np.linspace(centre - span, centre + span, FOCAL_SEARCH_GRID)
    values = [score(x) for x in grid]
    k = int(np.argmin(values))
    if np.isfinite(values[k]):
        minimize_scalar(score, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
                        method="bounded", options={"xatol": FOCAL_SEARCH_TOLERANCE})
    best = min(scores, key=scores.get)
    return float(np.exp(best if scores[best] < view_score(settled.solution) else centre))



#: With the focal length unknown, the turn toward an off-centre car tries focal lengths up to
#: this factor either side of the settled turn's …
FOCAL_SEARCH_RANGE = 3.0

#: … first on a grid of this many (log-spaced, ×/÷ 1.44 apart) …
FOCAL_SEARCH_GRID = 7

#: … then to this precision in log f (5 %).
FOCAL_SEARCH_TOLERANCE = 0.05


def _in_photo(result: FitResult, to_turned: np.ndarray, uv: np.ndarray, given: View) -> None:
    """Point a fit made in a turned camera's pixels back at the photo's marks."""
    result.to_photo, result.uv, result.given_view = np.linalg.inv(to_turned), uv, given
    result.solution.residual_px = np.linalg.norm(result.reprojected() - uv, axis=1)


def _deformed(result: FitResult) -> FitResult:
    """The fit with its mix moved onto the marks by the photo-matching deformation
    (:mod:`carbody.fit.deform`), in the fit's own camera (a turned one's pixels, if turned)."""
    sol, idx = result.solution, load_topology().keypoint_point_indices
    uv = result.marks_in_fit_camera()
    before = sol.shape
    after = prepared_field(result.library).fit_to_keypoints(before, idx, result.slots, uv,
                                                            result.view, sol.scale, sol.offset)
    result.solve_residual_px = np.array(sol.residual_px, dtype=float)
    if result.view.distance is not None:
        try:
            perspective_factors(np.concatenate([after.reshape(-1, 3), after.reshape(-1, 3) * MIRROR]), result.view)
        except AngleError:  # marks that would pull part of the car through the camera: not followed
            return result
    undeformed = result.wireframe
    result.wireframe = Wireframe(undeformed.name, after.reshape(-1, 3) * result.mm_per_unit)
    residual = np.linalg.norm(result.reprojected() - result.uv, axis=1)
    if residual.mean() > np.mean(sol.residual_px):
        # the field is solved through the camera linearised at the mix; a camera close to a car
        # it has bent far can take the marks further away instead (the pickup from 4 m behind)
        result.wireframe = undeformed
        return result
    sol.shape, sol.residual_px = after, residual
    result.deformation_mm = float(np.max(np.linalg.norm((after - before).reshape(-1, 3), axis=1))) * result.mm_per_unit
    return result


#: Refits with the camera turned toward an off-centre car (each from the previous one's aim).
PRINCIPAL_PASSES = 4

#: The camera looks at the car when the direction to the car's centre moves less than this,
#: degrees: left over, such a tilt draws one end of a car spanning 30° of the photo ≈ 0.2 % larger.
PRINCIPAL_TOLERANCE_DEG = 0.25


def _principal_point(principal_point, image_size, focal_px: float | None) -> np.ndarray | None:
    """(2,) pixels where the optical axis meets the photo, or None (aimed at the car); "auto" is
    "centre" with a known focal length (the photo is its camera's whole frame), else "car"."""
    if isinstance(principal_point, str) and principal_point == "auto":
        principal_point = "centre" if focal_px is not None else "car"
    if principal_point == "car" or principal_point is None:
        return None
    if principal_point == "centre":
        return None if image_size is None else np.asarray(image_size, dtype=float) / 2.0
    try:
        point = np.asarray(principal_point, dtype=float).reshape(2)
    except (TypeError, ValueError):
        raise FitError(f"principal point {principal_point!r} is not 'auto', 'centre', 'car' or (u, v) pixels") from None
    if not np.all(np.isfinite(point)):
        raise FitError(f"principal point {principal_point!r} is not finite")
    return point


#: The wheelbases (mm) the fit accepts when told.
MIN_WHEELBASE_MM, MAX_WHEELBASE_MM = 500.0, 10_000.0

#: A car's size read from a told camera distance and the fit's perspective is taken when it
#: lies within this factor of the library's wheelbases (beyond: too little perspective) …
PERSPECTIVE_SIZE_RANGE = 1.5

#: … else the told distance is read at the fitted car's own wheelbase, in at most this many fits
#: until the two agree to this fraction.
DISTANCE_PASSES = 3
DISTANCE_WHEELBASE_AGREEMENT = 0.005


def _at_wheelbase(result: FitResult, wheelbase_mm: float) -> FitResult:
    """``result`` with its car (and camera) read at ``wheelbase_mm``."""
    from dataclasses import replace

    points = result.solution.shape.reshape(-1, 3) * (wheelbase_mm / NORMALISED_WHEELBASE)
    return replace(result, wireframe=Wireframe(result.wireframe.name, points), wheelbase_mm=float(wheelbase_mm),
                   wheelbase_from="camera distance")


def _fit_checked(slots: list[KeypointSlot], uv: np.ndarray, view: View, library: Library, method: str,
                 prior_weight: float, refine: bool, camera_distance_mm: float | str | None,
                 wheelbase_mm: float | None, distance_wheelbase_mm: float | None, name: str,
                 scan: bool = True, joint_field: bool = True) -> FitResult:
    """:func:`fit_wireframe` on checked input, without the deformation; a distance in mm is
    read at ``distance_wheelbase_mm`` (default the library's mean wheelbase). A ``view`` that
    already has a distance (a previous fit's) starts the refinement as it is, and ``scan``
    False skips the refinement's coarse scan."""
    model = prepared(library, method, wheelbase_mm, field=joint_field)
    idx = load_topology().keypoint_point_indices

    if method == "paper":
        state = {"support": None}

        def solve_at(v: View, rounds: int = PERSPECTIVE_ITERATIONS) -> MixSolution:
            sol = solve_simplex(model, slots, uv, v, library.S, warm_support=state["support"], rounds=rounds)
            state["support"] = sol.support
            return sol

        # A pinhole camera's coarse scan ranks its views by one Newton round each.
        scan_at = partial(solve_at, rounds=1) if camera_distance_mm is not None else None
    else:
        def solve_at(v: View, rounds: int = PERSPECTIVE_ITERATIONS, model: ShapeModel = model) -> MixSolution:
            sol = solve_gauss(model, idx, slots, uv, v, prior_weight, mixture=method == "mixture",
                              rounds=rounds)
            sol.evidence += implausibility(sol.shape, library, wheelbase_mm)
            return sol

        # The coarse scan ranks its views by the library's span alone (no joint field) and a
        # pinhole camera's single Newton round: 3–4× cheaper per view.
        scan_at = partial(solve_at, rounds=1, model=prepared(library, method, wheelbase_mm, field=False))

    free = DEFAULT_FREE if refine else ()
    if camera_distance_mm is not None:
        if view.distance is None:
            view = _pinhole(view, camera_distance_mm, distance_wheelbase_mm, library)
        if camera_distance_mm == "auto":
            free += ("perspective",)
    centre = view
    if free:
        refined, sol = refine_view(solve_at, view, free=free, scan=scan, scan_at=scan_at)
        # Stopped at the edge of the azimuths searched: the photo's view lies further off (a view
        # given 30° off, a classifier's neighbour's neighbour); search again around it.
        for _ in range(MAX_VIEW_WALKS if "azimuth" in free else 0):
            if not at_search_edge(refined, centre):
                break
            centre = refined if sol.view is None else sol.view
            refined, sol = refine_view(solve_at, centre, free=free, scan=True, scan_at=scan_at)
    else:
        refined, sol = view, solve_at(view)
    if sol.view is not None:
        refined = sol.view  # a pinhole view's aim, settled on the fitted car
    angles = tuple(f for f in free if f in ("azimuth", "elevation", "roll"))
    if angles and sol.posterior is not None:
        sol.posterior.view_spread = _view_spread(solve_at, refined, sol, angles)
    refined = View(float(refined.azimuth) % 360.0, float(refined.elevation), float(refined.roll),
                   refined.distance, refined.aim)
    if sol.shape is None:
        sol.shape = library.S[:, sol.support] @ sol.H[sol.support]
    told = wheelbase_mm
    if wheelbase_mm is None:
        if sol.H is None:
            raise FitError("no wheelbase given and the mix's weights are unknown")
        wheelbase_mm = float(sol.H @ library.model_wheelbase_mm)
    points = sol.shape.reshape(-1, 3) * (wheelbase_mm / NORMALISED_WHEELBASE)
    return FitResult(wireframe=Wireframe(name, points), view=refined, given_view=view, solution=sol,
                     slots=slots, uv=uv, wheelbase_mm=float(wheelbase_mm), method=method,
                     library=library, wheelbase_from="library mix" if told is None else "told",
                     joint_field=joint_field and method != "paper", search_view=centre)


#: Step (degrees) of the finite differences that measure how sharply the evidence pins a
#: refined view angle.
VIEW_STEP_DEG = 0.5

#: Largest standard deviation (degrees) a refined view angle is given where the evidence is flat.
MAX_VIEW_SD_DEG = 10.0


def _view_spread(solve_at, view: View, sol: MixSolution, angles: tuple[str, ...]) -> np.ndarray:
    """(len(angles), 105): the keypoints' move (normalised units) per one standard deviation of
    each refined view angle — a Laplace approximation: the evidence's curvature at the refined
    view (the shape re-solved at every view, so its trade with the angle is in it) gives the
    angle's standard deviation at the prior's noise level λ, rescaled to the marks' own
    (their residual variance, cost / rows); central differences of the solved shape give its
    slope. Near level views the marks hardly tell azimuth from width, and this says so."""
    from dataclasses import replace

    idx = load_topology().keypoint_point_indices
    noise_ratio = sol.cost / (sol.posterior.lam * max(2 * len(sol.residual_px) - 2, 1))
    score = view_score(sol)
    rows = []
    for angle in angles:
        at = getattr(view, angle)
        plus, minus = (solve_at(replace(view, **{angle: at + sign * VIEW_STEP_DEG})) for sign in (1, -1))
        curvature = (view_score(plus) + view_score(minus) - 2.0 * score) / VIEW_STEP_DEG ** 2
        sd = MAX_VIEW_SD_DEG if not curvature > 0 else min(np.sqrt(noise_ratio / curvature), MAX_VIEW_SD_DEG)
        slope = (plus.shape.reshape(-1, 3)[idx] - minus.shape.reshape(-1, 3)[idx]).ravel() / (2 * VIEW_STEP_DEG)
        rows.append(slope * sd)
    return np.array(rows)


#: Where ``camera_distance_mm="auto"`` starts: 2.5 wheelbases (≈ 7 m), a typical photo.
AUTO_START_WHEELBASES = 2.5


def _pinhole(view: View, camera_distance_mm: float | str, wheelbase_mm: float | None,
             library: Library) -> View:
    """The given view as a pinhole camera aimed at the library mean's centre (normalised units)."""
    mean = library_mean(library)
    points = mean.reshape(-1, 3)
    aim = car_centre(mean)  # the solve moves it onto the fitted car
    if camera_distance_mm == "auto":
        distance = AUTO_START_WHEELBASES * PERSPECTIVE_LENGTH
    else:
        try:
            value = float(camera_distance_mm)
        except (TypeError, ValueError):
            raise FitError(f"camera distance {camera_distance_mm!r} is not a number or 'auto'") from None
        if not (np.isfinite(value) and value > 0):
            raise FitError(f"camera distance {camera_distance_mm!r} mm is not a positive distance")
        wb = wheelbase_mm if wheelbase_mm is not None else float(np.mean(library.template_wheelbase_mm))
        distance = value / (wb / NORMALISED_WHEELBASE)
        half_length = float(np.ptp(points[:, 1])) / 2
        if not (np.isfinite(distance) and distance > 1.2 * half_length):
            raise FitError(f"camera distance {camera_distance_mm!r} mm is inside or at the car")
    return View(view.azimuth, view.elevation, view.roll, distance, aim)
