"""Continuous view refinement around the given (classified) angle.

The solve gives, at any view, the best library mix and its residual. The view is refined over
azimuth and elevation (roll, and a pinhole camera's distance, on request): a coarse scan of
azimuths × elevations around the given view (the objective is not convex far from the optimum),
then a continuous search, the mix re-solved at every step. The
objective is the solve's evidence (−log marginal likelihood of the view, the shape integrated
out) when it has one (the Gaussian-prior methods; Nelder–Mead), else its residual (the paper's
solve; bounded Gauss–Newton, trust-region reflective least squares). In an orthographic image
the azimuth trades off against the car's depth, so the residual alone prefers views where the
shape can bend to fit; the evidence charges for that freedom. The fit adds a charge for a car
wider, longer or taller than any template (:func:`carbody.fit.shape_prior.implausibility`):
the Gaussian prior alone lets a side view steepen into a car a third as wide.

Roll stays as given (level) by default: one orthographic view of a car whose shape is also being
fitted cannot separate a degree of roll from a slightly different car: with roll free the
refinement trades roll for shape and settles degrees off in azimuth. At elevation 0
even the azimuth is not fixed by the image: a car seen at θ is, keypoint for keypoint, the car
made tan θ'/tan θ as wide and sin θ'/sin θ as tall (same wheelbase) seen at θ', so only the shape
prior chooses between them.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from carbody.camera import View

#: How far (degrees) the refined azimuth may move from the given one.
AZIMUTH_RANGE_DEG = 25.0

#: Range of the refined elevation (degrees), whatever the given one.
ELEVATION_RANGE_DEG = (-20.0, 60.0)

#: How far (degrees) the refined roll may move from the given one.
ROLL_RANGE_DEG = 20.0

#: The angles refined by default (see the module docstring for why not roll). "perspective"
#: (a pinhole view's 1/distance) can be added.
DEFAULT_FREE = ("azimuth", "elevation")

#: A pinhole view's perspective is refined as ρ = PERSPECTIVE_LENGTH / distance (distance in the
#: fit's normalised units, so ρ is wheelbases per distance), within 0 (orthographic) … 1.
PERSPECTIVE_LENGTH = 1000.0
PERSPECTIVE_RANGE = (0.0, 1.0)

#: Below this ρ (a camera over 1000 wheelbases, ~3 km, away) the view is orthographic: the
#: perspective is far below a pixel, and a distance of 10⁷ m is no one's camera.
PERSPECTIVE_FAR = 1e-3

#: Azimuth offsets (degrees) tried before the continuous refinement.
AZIMUTH_SCAN_DEG = (-20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0)

#: Elevation offsets (degrees) tried with each azimuth offset: a photo's elevation is rarely
#: known, and near a side view a wrong elevation passes for a wrong azimuth, so a scan at the
#: given elevation alone can settle at the edge of the azimuth range.
ELEVATION_SCAN_DEG = (-8.0, 0.0, 8.0, 16.0)


def view_score(sol) -> float:
    """What the refinement minimises: a solution's evidence, else (the paper's solve) its cost."""
    return sol.evidence if getattr(sol, "evidence", None) is not None else sol.cost


def refine_view(solve_at: Callable[[View], object], given: View, max_evaluations: int = 60,
                free: tuple[str, ...] = DEFAULT_FREE, scan: bool = True,
                scan_at: Callable[[View], object] | None = None):
    """The view near ``given`` whose solve has the least evidence (or residual).

    Args:
        solve_at: view → a solution with ``residual_vector`` ((m,) float), ``cost`` and
            ``evidence`` (float or None).
        given: the starting view.
        max_evaluations: budget of solves for the continuous stage.
        free: what is refined (the rest stays as given): "azimuth", "elevation", "roll",
            "perspective" (1/distance of a pinhole view; ``given.distance`` None starts it
            orthographic).
        scan: try the coarse grid of views first (off: only the local search, for a start
            known to be close).
        scan_at: a cheaper, rougher ``solve_at`` that ranks the coarse grid (a pinhole view's
            single Newton round); the grid's best view is then solved by ``solve_at``.
    Returns:
        (refined View, its solution).
    """
    from scipy.optimize import least_squares

    from carbody.errors import AngleError, FitError

    def view_at(x) -> View:
        """View from (azimuth, elevation, roll, ρ)."""
        rho = float(x[3])
        return View(float(x[0]), float(x[1]), float(x[2]),
                    None if rho <= PERSPECTIVE_FAR else PERSPECTIVE_LENGTH / rho, given.aim)

    rho0 = 0.0 if given.distance is None else PERSPECTIVE_LENGTH / given.distance
    ranked_by = scan_at if scan and scan_at is not None else solve_at
    best_view, best = given, ranked_by(given)

    azimuths = AZIMUTH_SCAN_DEG if "azimuth" in free else (0.0,)
    elevations = [e for e in ELEVATION_SCAN_DEG if ELEVATION_RANGE_DEG[0] <= given.elevation + e
                  <= ELEVATION_RANGE_DEG[1]] if "elevation" in free else [0.0]

    def try_view(v: View) -> None:
        nonlocal best_view, best
        try:
            sol = ranked_by(v)
        except (FitError, AngleError):
            return
        if view_score(sol) < view_score(best):
            best_view, best = v, sol

    # A free perspective is scanned both ways: a photo from afar looks orthographic, and the two
    # hypotheses' best angles can differ (a level side view seen from below, say).
    rhos = sorted({0.0, rho0}) if "perspective" in free else [rho0]
    if not scan:
        azimuths, elevations, rhos = (0.0,), [0.0], [rho0]
    for d, e, rho in ((d, e, rho) for d in azimuths for e in elevations for rho in rhos):
        if d or e or rho != rho0:
            try_view(view_at((given.azimuth + d, given.elevation + e, given.roll, rho)))
    if ranked_by is not solve_at:
        try:
            best = solve_at(best_view)
        except (FitError, AngleError):
            best_view, best = given, solve_at(given)

    lo = np.array([given.azimuth - AZIMUTH_RANGE_DEG, ELEVATION_RANGE_DEG[0], given.roll - ROLL_RANGE_DEG,
                   min(PERSPECTIVE_RANGE[0], rho0)])
    hi = np.array([given.azimuth + AZIMUTH_RANGE_DEG, ELEVATION_RANGE_DEG[1], given.roll + ROLL_RANGE_DEG,
                   max(PERSPECTIVE_RANGE[1], rho0)])
    lo[1], hi[1] = min(lo[1], given.elevation), max(hi[1], given.elevation)
    cache: dict[tuple, object] = {}

    def solved(x: np.ndarray):
        key = tuple(np.round(x, 12))
        if key not in cache:
            try:
                cache[key] = solve_at(view_at(x))
            except (FitError, AngleError):
                cache[key] = None
        return cache[key]

    mask = np.array([n in free for n in ("azimuth", "elevation", "roll", "perspective")])
    start = np.array([best_view.azimuth, best_view.elevation, best_view.roll,
                      0.0 if best_view.distance is None else PERSPECTIVE_LENGTH / best_view.distance])

    def full(x: np.ndarray) -> np.ndarray:
        out = start.copy()
        out[mask] = x
        return out

    x0 = np.clip(start, lo + 1e-9, hi - 1e-9)[mask]
    if getattr(best, "evidence", None) is not None:
        from scipy.optimize import minimize

        def objective(x: np.ndarray) -> float:
            y = full(x)
            if np.any(y < lo) or np.any(y > hi):
                return np.inf
            sol = solved(y)
            return np.inf if sol is None else sol.evidence

        steps = np.array([2.0, 2.0, 2.0, 0.1])[mask]  # degrees; ρ
        simplex = np.vstack([x0] + [x0 + steps[i] * np.eye(len(x0))[i] for i in range(len(x0))])
        found = minimize(objective, x0, method="Nelder-Mead",
                         options={"initial_simplex": simplex, "xatol": 0.1, "fatol": 1e-2,
                                  "maxfev": 3 * max_evaluations})
        refined = view_at(full(found.x))
    else:
        def residual(x: np.ndarray) -> np.ndarray:
            sol = solved(full(x))
            return best.residual_vector * 10.0 if sol is None else sol.residual_vector

        fit = least_squares(residual, x0, bounds=(lo[mask], hi[mask]), x_scale=1.0,
                            diff_step=1e-4, max_nfev=max_evaluations, method="trf")
        refined = view_at(full(fit.x))
    sol = solve_at(refined)
    if view_score(sol) <= view_score(best):
        return refined, sol
    return best_view, best
