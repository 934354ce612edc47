"""The fit's camera: orthographic, a pinhole at a told or found distance, and a pinhole turned to
look at a car off the photo's centre.

SPEC's camera is orthographic; a photo taken from a few metres shows the car's near parts larger
(:class:`carbody.camera.View` with a distance, aimed at the car's centre). What is known before
the fit (:class:`CameraPlan`) decides the cameras the view search starts from
(:meth:`CameraPlan.scan_cameras`); after it, two corrections need whole refits:

- a told distance without a told wheelbase sizes the car (:func:`size_from_told_distance`): the
  perspective gives the distance in wheelbases, the told one in mm;
- an uncropped photo's optical axis goes through its centre, not the car's
  (:func:`turn_toward_car`): the car is seen obliquely, so the camera is turned about its centre
  to look at it (a homography) and the marks fitted again, by a known focal length or the fit's
  own (scale × distance), and with the distance found as well by the focal length whose turned
  fit has the best evidence.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from carbody.camera import View, apply_homography, look_at_homography, project
from carbody.errors import AngleError, FitError
from carbody.fit.hypothesis import Hypothesis
from carbody.fit.search import PERSPECTIVE_LENGTH
from carbody.fit.shape_prior import library_mean
from carbody.fit.solve import car_centre
from carbody.library import Library
from carbody.policy import FitPolicy
from carbody.tolerances import NORMALISED_WHEELBASE

@dataclass(frozen=True)
class CameraPlan:
    """What is known of the camera before the fit.

    Attributes:
        distance: None (orthographic), ``"auto"`` (to be found) or the told distance in mm.
        principal: (2,) pixels where the optical axis meets the photo, or None (aimed at the car).
        focal_px: the focal length, px, if known.
    """

    distance: float | str | None
    principal: np.ndarray | None
    focal_px: float | None

    @classmethod
    def of(cls, distance, principal_point, image_size, focal_px) -> "CameraPlan":
        return cls(distance, principal_point_px(principal_point, image_size, focal_px), focal_px)

    @property
    def finds_perspective(self) -> bool:
        """Whether the search refines the pinhole's distance."""
        return self.distance == "auto"

    def scan_cameras(self, library: Library, wheelbase_mm: float | None, policy: FitPolicy) -> list[View]:
        """The cameras the view search starts from, at azimuth 0: orthographic; pinholes at the
        scan's perspectives when the distance is to be found; the told distance (read at the told
        wheelbase, else the library's mean) when told. A pinhole aims at the library's mean car's
        centre (normalised units); its solve moves the aim onto the fitted car.

        Raises:
            FitError: a told distance that puts the camera inside the car.
        """
        if self.distance is None:
            return [View(0.0)]
        aim = car_centre(library_mean(library))
        if self.distance == "auto":
            return [View(0.0) if rho == 0 else View(0.0, 0.0, 0.0, PERSPECTIVE_LENGTH / rho, aim)
                    for rho in policy.scan_perspectives]
        wheelbase = wheelbase_mm if wheelbase_mm is not None else float(np.mean(library.template_wheelbase_mm))
        return [View(0.0, 0.0, 0.0, told_distance(self.distance, wheelbase, library), aim)]


def told_distance(distance_mm: float, wheelbase_mm: float, library: Library) -> float:
    """A told camera distance (mm) in the fit's normalised units, read at ``wheelbase_mm``.

    Raises:
        FitError: the camera would stand inside or at the car.
    """
    distance = float(distance_mm) / (wheelbase_mm / NORMALISED_WHEELBASE)
    half_length = float(np.ptp(library_mean(library).reshape(-1, 3)[:, 1])) / 2
    if not (np.isfinite(distance) and distance > 1.2 * half_length):
        raise FitError(f"camera distance {distance_mm!r} mm is inside or at the car")
    return distance


def principal_point_px(principal_point, image_size, focal_px: float | None) -> np.ndarray | None:
    """(2,) pixels where the optical axis meets the photo, or None (aimed at the car); "auto" is
    "centre" with a known focal length (the photo is its camera's whole frame), else "car"."""
    if isinstance(principal_point, str) and principal_point == "auto":
        principal_point = "centre" if focal_px is not None else "car"
    if principal_point is None or (isinstance(principal_point, str) and principal_point == "car"):
        return None
    if isinstance(principal_point, str) and principal_point == "centre":
        return None if image_size is None else np.asarray(image_size, dtype=float) / 2.0
    try:
        point = np.asarray(principal_point, dtype=float).reshape(2)
    except (TypeError, ValueError):
        raise FitError(f"principal point {principal_point!r} is not 'auto', 'centre', 'car' or (u, v) pixels") from None
    if not np.all(np.isfinite(point)):
        raise FitError(f"principal point {principal_point!r} is not finite")
    return point


def size_from_told_distance(hypothesis: Hypothesis, distance_mm: float, library: Library, policy: FitPolicy,
                            refit_at, own_wheelbase) -> tuple[Hypothesis, float | None]:
    """A told distance without a told wheelbase: (the hypothesis, the wheelbase the two give).

    ``hypothesis`` was fitted with the distance found; its perspective gives the distance in
    wheelbases, so the told distance in mm gives the car's size, when that lies within
    ``perspective_size_range`` of the library's wheelbases. Otherwise (a distant camera, too
    little perspective) the told distance is read at the fitted car's own wheelbase
    (``own_wheelbase(hypothesis)``, mm: what the fit gives a car when none is told) by
    ``refit_at(distance_norm, hypothesis)`` (a fit at that fixed distance), until the two agree
    (``distance_passes``, ``distance_agreement``); the wheelbase is then the car's own (None).
    """
    if hypothesis.view.distance is not None:
        by_distance = float(distance_mm) * NORMALISED_WHEELBASE / hypothesis.view.distance
        lo, hi = np.min(library.template_wheelbase_mm), np.max(library.template_wheelbase_mm)
        if lo / policy.perspective_size_range <= by_distance <= hi * policy.perspective_size_range:
            return hypothesis, by_distance
    read_at = own_wheelbase(hypothesis)
    for _ in range(policy.distance_passes):
        hypothesis = refit_at(told_distance(distance_mm, read_at, library), hypothesis)
        fitted = own_wheelbase(hypothesis)
        if abs(fitted / read_at - 1.0) < policy.distance_agreement:
            break
        read_at = fitted
    return hypothesis, None


def mix_wheelbase_mm(hypothesis: Hypothesis, library: Library) -> float:
    """The wheelbase of the hypothesis' library mix (the templates' own, weighted), mm."""
    H = hypothesis.solution.H
    if H is None:
        raise FitError("no wheelbase given and the mix's weights are unknown")
    return float(H @ library.model_wheelbase_mm)


@dataclass
class Turn:
    """A fit made in the pixels of a camera turned toward the car.

    Attributes:
        hypothesis: the fit, in the turned camera's pixels.
        to_photo: (3, 3) homography from those pixels to the photo's, or None (no turn).
        focal_px: the focal length the turn used; turn_deg: how far it swung the camera.
        diverged: the turns toward the car moved the camera further each pass, so it was not
            turned (:func:`_looking_at_car`).
    """

    hypothesis: Hypothesis
    to_photo: np.ndarray | None = None
    focal_px: float | None = None
    turn_deg: float = 0.0
    diverged: bool = False

    def aim_in_photo(self) -> np.ndarray:
        """(2,) photo pixels of the car's centre (the pinhole's aim)."""
        sol, view = self.hypothesis.solution, self.hypothesis.view
        uv = project(np.asarray(view.aim, dtype=float), view, sol.scale, sol.offset)
        return uv if self.to_photo is None else apply_homography(self.to_photo, uv)


def turn_toward_car(hypothesis: Hypothesis, photo_uv: np.ndarray, plan: CameraPlan, policy: FitPolicy,
                    refit) -> Turn:
    """The fit with the camera turned to look at the car (module docstring), or as it was when
    the camera already looks at it, is orthographic, or has no principal point.

    Args:
        photo_uv: (k, 2) the marks in the photo's pixels.
        refit: ``refit(uv, start: Hypothesis, search: bool) -> Hypothesis``: the marks at ``uv``
            (a turned camera's pixels) fitted again from ``start``'s view, or searched afresh.
    """
    unturned = Turn(hypothesis)
    if plan.principal is None or hypothesis.view.distance is None:
        return unturned
    if plan.focal_px is not None or plan.distance != "auto":
        return _looking_at_car(unturned, plan.focal_px, photo_uv, plan.principal, policy, refit, search=True)
    settled = _looking_at_car(unturned, None, photo_uv, plan.principal, policy, refit)
    if settled.focal_px is None:
        return settled
    focal = _best_focal(settled, unturned, photo_uv, plan.principal, policy, refit)
    return _looking_at_car(unturned, focal, photo_uv, plan.principal, policy, refit, search=True)


def _looking_at_car(turn: Turn, focal_px: float | None, photo_uv: np.ndarray, principal: np.ndarray,
                    policy: FitPolicy, refit, passes: int | None = None, search: bool = False) -> Turn:
    """Refit with the camera turned about its centre to look at the car's centre, each pass from
    the last one's aim, until the direction to the car moves less than ``turn_tolerance_deg``.
    ``focal_px`` None: the fit's own, f = s·D. ``search``: the first refit searches the view
    afresh (an oblique image plane can have pulled the unturned fit's view degrees off).

    Each pass should move the camera less than the one before. When a pass would move it more,
    the passes diverge (a focal length the photo's camera did not have: a cropped or zoomed
    photo told a phone's, each fit aiming further off the car): the fit is not turned at all
    (``turn`` is returned, marked :attr:`Turn.diverged`)."""
    start, looking, moved = turn, np.array([0.0, 0.0, 1.0]), np.inf
    least = policy.min_focal_diagonal * 2.0 * float(np.hypot(*principal))
    for _ in range(passes or policy.turn_passes):
        sol, view = turn.hypothesis.solution, turn.hypothesis.view
        focal = focal_px if focal_px is not None else max(sol.scale * view.distance, least)
        if not (np.isfinite(focal) and focal >= least):
            break  # no camera's focal length: keep the last fit
        aim_px = turn.aim_in_photo()
        to_car = np.append((aim_px - principal) / focal, 1.0)
        to_car /= np.linalg.norm(to_car)
        step = float(np.degrees(np.arccos(min(1.0, float(to_car @ looking)))))
        if step < policy.turn_tolerance_deg:
            break  # the camera already looks at the car
        if step > moved:
            return replace(start, diverged=True)
        to_turned = look_at_homography(aim_px, principal, focal)
        try:
            turned = refit(apply_homography(to_turned, photo_uv), turn.hypothesis, search)
        except (AngleError, FitError):
            break  # this turn's best camera sits in the car (a wild focal length): keep the last fit
        if turned is None:
            break
        looking, search, moved = to_car, False, step
        turn = Turn(turned, np.linalg.inv(to_turned), float(focal), float(np.degrees(np.arccos(to_car[2]))))
    return turn


def _best_focal(settled: Turn, unturned: Turn, photo_uv: np.ndarray, principal: np.ndarray,
                policy: FitPolicy, refit) -> float:
    """The focal length (px) whose turn toward the car fits the marks with the best evidence:
    searched on a log scale within ``focal_search_range`` of the one ``settled`` used, each
    candidate one turn of the ``unturned`` fit and a refit from its view. The evidence is rugged
    in the focal length (each refit settles in its own view), so a grid first, then a bounded
    search between the best one's neighbours."""
    from scipy.optimize import minimize_scalar

    scores: dict[float, float] = {}

    def score(log_f: float) -> float:
        turn = _looking_at_car(unturned, float(np.exp(log_f)), photo_uv, principal, policy, refit, passes=1)
        scores[log_f] = np.inf if turn.to_photo is None else float(turn.hypothesis.solution.evidence)
        return scores[log_f]

    centre, span = float(np.log(settled.focal_px)), float(np.log(policy.focal_search_range))
    grid = np.linspace(centre - span, centre + span, policy.focal_search_grid)
    values = [score(x) for x in grid]
    k = int(np.argmin(values))
    if np.isfinite(values[k]):
        minimize_scalar(score, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
                        method="bounded", options={"xatol": policy.focal_search_tolerance})
    best = min(scores, key=scores.get)
    return float(np.exp(best if scores[best] < settled.hypothesis.solution.evidence else centre))
