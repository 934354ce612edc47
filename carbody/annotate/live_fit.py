"""The fit behind the page: the marks so far → the car, its wireframe and ghosts in photo pixels.

Two fits, both :func:`carbody.fit.fit_wireframe` through its public options:

- the **quick fit**, after every click: the view searched as ``carbody fit`` does, but with a
  lighter policy (:func:`quick_policy`): the scan round the car every 30° at the last fit's
  elevation and perspective only, the previous view as the prior, three candidates ranked at
  the marks' noise read coarsely, one refined briefly.
  It is what the page draws within the click's 300 ms (``benchmarks/bench_annotate.py``).
- the **full fit**, when the page is idle: the default policy and the photo's own view prior
  (the classifier's, or the view the user picked), the fit ``carbody reconstruct --no-wheels``
  would make of these marks (reconstruct also fits the wheels' hubs it finds in the photo; on the
  page that took more marks to reach the hand fit: docs/annotate.md). It replaces the quick one on
  the page when it lands.

:func:`fit_payload` turns a fit into what the page draws (plain JSON): the projected wireframe
(both halves), the reprojected marks with their residuals, the fit's diagnostics per mark, and a
*ghost* for every keypoint the fitted view can see that is not marked yet — where the car puts it
and how sure the fit is of that (its expected error projected into the photo, pixels).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from carbody.camera import View, project
from carbody.policy import FIT_POLICY, FitPolicy

#: The page starts fitting at this many marks (the fewest :func:`carbody.fit.fit_wireframe`
#: accepts).
MIN_MARKS = 5

#: The quick fit's scan: azimuth step (degrees) and refinement budget (solves). The scan still
#: goes all round the car (a wrong early view is left for the right one), at one elevation and
#: one perspective: the last fit's, which the next click rarely moves by more than the
#: refinement reaches. Against the full fit of the same marks (the example and three real
#: photos, 6 marks to all), polishing with 10 solves instead of 15 took 15 % less processor
#: time and landed as near (3 px in the median); a 45° step lands 9 px off. The benchmark
#: measures how far the quick fit lands from the full one on every click (docs/annotate.md).
QUICK_AZIMUTH_STEP_DEG = 30.0

#: The quick fit ranks the scan's best this many views by the full solve, each at the marks'
#: noise it reads (coarse grid), and keeps that noise (``fine_noise`` off). The full fit's six,
#: each noise read again on the full grid, were half the quick fit's time: ranking three took
#: its processor time from 300 to 145 ms at the median, landing as near the full fit
#: (docs/annotate.md; the same action counts).
QUICK_RANKED_CANDIDATES = 3
QUICK_COARSE_EVALUATIONS = 10
QUICK_POLISH_EVALUATIONS = 10

#: Points per curve of the wireframe the page draws.
CURVE_SAMPLES = 12

#: Pixel precision of what is sent to the page.
PX_DECIMALS = 2


def quick_policy(previous: View | None) -> FitPolicy:
    """The per-click fit's policy (module docstring): the scan at the previous view's elevation
    and perspective, every ``QUICK_AZIMUTH_STEP_DEG``, ``QUICK_RANKED_CANDIDATES`` ranked at
    the marks' noise read coarsely, one refined briefly; the roll kept as told (the full fit
    frees it where the marks pay for it, a second polish the click cannot wait for)."""
    policy = replace(FIT_POLICY, scan_azimuth_step_deg=QUICK_AZIMUTH_STEP_DEG,
                     refined_candidates=1, ranked_candidates=QUICK_RANKED_CANDIDATES, fine_noise=False,
                     coarse_evaluations=QUICK_COARSE_EVALUATIONS, polish_evaluations=QUICK_POLISH_EVALUATIONS,
                     roll_range_deg=0.0)
    if previous is None:
        return policy
    rho = 0.0 if previous.distance is None else 1000.0 / previous.distance
    # the scan's elevation stays inside the refinement's range
    low, high = FIT_POLICY.elevation_range_deg
    return replace(policy, scan_elevations_deg=(float(np.clip(round(previous.elevation), low, high)),),
                   scan_perspectives=(float(rho),))


@dataclass
class LiveFit:
    """One fit of the page's marks.

    Attributes:
        fit: the :class:`carbody.fit.FitResult`, or None when the marks cannot be fitted yet.
        error: why not (too few marks, marks no car explains), else None.
        quick: the quick fit (True) or the full one.
        seconds: how long the fit took (wall clock).
        cpu_seconds: the processor time it took (its thread's): what it costs on an idle
            machine, where a busy one stretches ``seconds``.
        image_size: the photo's (width, height), px.
    """

    fit: object | None
    error: str | None
    quick: bool
    seconds: float
    cpu_seconds: float = 0.0
    image_size: tuple[int, int] | None = None


def fit_marks(marks: dict[str, tuple[float, float]], image_size: tuple[int, int], prior,
              scan_from: View | None = None, quick: bool = True, library=None,
              photo: np.ndarray | None = None, outline: bool = False) -> LiveFit:
    """Fit the marks (camera distance found, marks estimated robustly, as ``carbody fit``).

    Args:
        marks: {name: (u, v)} photo pixels.
        image_size: (width, height) px.
        prior: what the fit is told of the view (a :class:`carbody.fit.ViewPrior`, a
            :class:`View` or None).
        scan_from: the quick fit scans at this view's elevation and perspective (the last
            fit's, or the view guessed before one); None scans them all.
        quick: the quick policy (:func:`quick_policy`) or the full one (the default's).
        photo: the photo, (h, w, 3) uint8 RGB: the wheels' hubs found in it join the marks, as
            ``carbody reconstruct`` fits; None (the page's fits) the marks alone.
        outline: with ``photo``, the car's outline in it fitted too (``reconstruct --outline``).
    """
    from carbody.errors import CarbodyError
    from carbody.fit import FitOptions, fit_wireframe

    start, cpu = time.perf_counter(), time.thread_time()
    if len(marks) < MIN_MARKS:
        return LiveFit(None, f"{MIN_MARKS - len(marks)} more mark(s) and the car is fitted", quick, 0.0)
    policy = quick_policy(scan_from) if quick else FIT_POLICY
    if library is None:
        from carbody.library import default_library

        library = default_library()
    try:
        fit = fit_wireframe(dict(marks), prior, library, image_size=image_size,
                            options=FitOptions(camera_distance_mm="auto", policy=policy, outline=outline),
                            photo=photo)
    except CarbodyError as exc:
        return LiveFit(None, str(exc), quick, time.perf_counter() - start, time.thread_time() - cpu, image_size)
    return LiveFit(fit, None, quick, time.perf_counter() - start, time.thread_time() - cpu, image_size)


def _px(a: np.ndarray) -> list:
    return np.round(np.asarray(a, dtype=float), PX_DECIMALS).tolist()


def projected_wireframe(fit) -> list[list[list[float]]]:
    """The fitted wireframe, both halves, as polylines in photo pixels (curves on the symmetry
    plane once): a list of (``CURVE_SAMPLES``, 2) lists."""
    from carbody.topology import load_topology
    from carbody.wireframe import MIRROR, sample_curves

    topo = load_topology()
    curves = sample_curves(fit.wireframe.control_points, CURVE_SAMPLES)
    central = np.array([c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions
                        for c in topo.curves])
    both = np.concatenate([curves, curves[~central] * MIRROR])
    return _px(fit.project_points(both))


def keypoint_positions(fit) -> dict[str, np.ndarray]:
    """{name: (3,) mm} of every markable name (both halves) on the fitted car."""
    from carbody.fit import keypoint_slots

    cp = fit.wireframe.control_points
    return {name: cp[s.point_index] * s.sign for name, s in keypoint_slots().items()}


def image_uncertainty_px(fit, points_mm: dict[str, np.ndarray]) -> dict[str, float]:
    """{name: px}: how far the fit may be off on each keypoint, in the photo: its expected error
    per axis (:meth:`carbody.fit.FitResult.keypoint_sd_mm`) projected (each axis's 1σ step's
    image length, summed in quadrature). Empty for a fit without a posterior."""
    sd = fit.keypoint_sd_mm()
    if sd is None:
        return {}
    names = list(points_mm)
    p = np.array([points_mm[n] for n in names])
    s = np.array([sd.get(n, sd.get(n.removesuffix("_right"), [0.0, 0.0, 0.0])) for n in names])
    steps = p[:, None, :] + np.eye(3)[None] * s[:, :, None]            # (n, 3 axes, 3)
    moved = fit.project_points(steps) - fit.project_points(p)[:, None, :]
    return {n: float(v) for n, v in zip(names, np.sqrt(np.sum(moved ** 2, axis=(1, 2))))}


def visible_names(fit) -> list[str]:
    """The names the fitted car shows from the fitted view (both halves). Kept per view rounded
    to a degree and 100 mm (:data:`_VISIBLE`): between two clicks the view moves little and the
    car less, and the occlusion test costs more than the rest of the payload."""
    from carbody.fit import visible_keypoints

    view = fit.view
    distance = fit.camera_distance_mm
    key = (round(float(view.azimuth) % 360.0), round(float(view.elevation)),
           None if distance is None else round(distance / 100.0))
    if key not in _VISIBLE:
        if len(_VISIBLE) > 256:
            _VISIBLE.clear()
        _VISIBLE[key] = visible_keypoints(view, fit.wireframe.control_points / fit.mm_per_unit)
    return _VISIBLE[key]


#: {(azimuth, elevation, distance) rounded: names shown}, see :func:`visible_names`.
_VISIBLE: dict[tuple, list[str]] = {}


def fit_payload(live: LiveFit, marks: dict[str, tuple[float, float]]) -> dict:
    """What the page draws of a fit (module docstring), JSON-ready.

    Keys: ``ok``, ``error``, ``quick``, ``seconds``, ``cpu_seconds``; with a fit also ``view`` (azimuth,
    elevation, distance mm), ``wireframe`` (polylines), ``car_length_px`` (its width in the
    photo), ``marks`` ({name: {reprojected, residual_px, status ("kept", "rejected", "renamed",
    "suspect"), note}}), ``ghosts`` ({name: {uv, sd_px, in_photo}} for the unmarked names the
    view shows: where the car puts it, how far off it may be there, whether that is on the
    photo), ``summary`` (mean residual, poor-fit flags, wheelbase).
    """
    out = {"ok": live.fit is not None, "error": live.error, "quick": live.quick,
           "seconds": round(live.seconds, 4), "cpu_seconds": round(live.cpu_seconds, 4)}
    fit = live.fit
    if fit is None:
        return out
    diag = fit.diagnostics
    points = keypoint_positions(fit)
    names = list(points)
    where = dict(zip(names, fit.project_points(np.array([points[n] for n in names]))))
    residual = fit.residuals_px()
    fitted_as = {clicked: fitted for clicked, fitted in diag.renamed.items()}
    per_mark = {}
    for name in marks:
        entry = {"reprojected": _px(where[fitted_as.get(name, name)]), "residual_px": None,
                 "status": "kept", "note": ""}
        if name in diag.rejected:
            r = diag.rejected[name]
            entry.update(status="rejected", residual_px=round(r.px, 1),
                         note=("left out: the view found cannot see it" if r.reason == "hidden" else
                               "left out: the other marks put it elsewhere")
                         + (f"; looks like {r.looks_like}" if r.looks_like else ""))
        elif name in fitted_as:
            entry.update(status="renamed", residual_px=round(residual.get(fitted_as[name], np.nan), 1),
                         note=f"fitted as {fitted_as[name]} (left/right exchanged?)")
        else:
            entry["residual_px"] = round(residual.get(name, np.nan), 1)
            if name in diag.suspect:
                entry.update(status="suspect", note="the car cannot follow this mark")
        per_mark[name] = entry
    shown = set(visible_names(fit))
    taken = set(marks) | set(fitted_as.values())
    wireframe = projected_wireframe(fit)
    length_px = float(np.ptp(np.array(wireframe).reshape(-1, 2)[:, 0]))
    sd_px = image_uncertainty_px(fit, points)
    w, h = live.image_size if live.image_size is not None else (np.inf, np.inf)
    ghosts = {n: {"uv": _px(where[n]), "sd_px": round(sd_px.get(n, 0.0), 1),
                  "in_photo": bool(0.0 <= where[n][0] <= w and 0.0 <= where[n][1] <= h)}
              for n in names if n in shown and n not in taken}
    values = [e["residual_px"] for e in per_mark.values() if e["status"] != "rejected"]
    view = fit.view
    out.update(
        view={"azimuth_deg": round(float(view.azimuth) % 360.0, 2), "elevation_deg": round(float(view.elevation), 2),
              "distance_mm": None if fit.camera_distance_mm is None else round(fit.camera_distance_mm)},
        wireframe=wireframe, car_length_px=round(length_px, 1), marks=per_mark, ghosts=ghosts,
        summary={"mean_residual_px": round(float(np.mean(values)), 2) if values else None,
                 "fits_poorly": bool(diag.fits_poorly), "misses_marks": bool(diag.misses_marks),
                 "wheelbase_mm": round(fit.wheelbase_mm), "swapped": list(diag.swapped) if diag.swapped else None})
    return out


def warm_up(quick: bool = True) -> None:
    """Fit the reference car's own keypoints once, so that the first fit of a photo does not pay
    for building the fit's caches (the shape prior, the facing table): a second or more."""
    from carbody.annotate.guide import reference_keypoints, shown_names

    view = View(30.0, 5.0, 0.0, 2500.0, (0.0, 500.0, 200.0))
    points = reference_keypoints()
    shown = set(shown_names(view))
    uv = project(np.array([p for n, p in points.items() if n in shown]), view)
    uv = 50.0 + 900.0 * (uv - uv.min(axis=0)) / np.ptp(uv, axis=0).max()  # on a 1000 px photo
    marks = {n: (float(u), float(v)) for n, (u, v) in zip([n for n in points if n in shown], uv)}
    fit_marks(marks, (1000, 1000), None, view, quick=quick)


def warm_worker() -> None:
    """Load the library and warm the fit up in a full-fit worker process."""
    warm_up(quick=False)


def full_fit_payload(marks: dict[str, tuple[float, float]], image_size: tuple[int, int], prior) -> dict:
    """The full fit's page payload (run in the worker process: only plain data crosses back)."""
    return fit_payload(fit_marks(marks, image_size, prior, quick=False), marks)
