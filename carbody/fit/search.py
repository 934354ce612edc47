"""One view search: every azimuth and elevation scored, the best few refined, the best kept.

The scan puts a camera at every ``scan_azimuth_step_deg`` round the car (both sides: the 24
classes) at each of ``scan_elevations_deg`` (and, when the camera's distance is to be found, both
orthographic and at 2.5 wheelbases), and scores each by :class:`~carbody.fit.hypothesis.Scorer`
with its cheap solve (the library's span alone, one Newton round, at most ``scan_rejections``
marks left out). Its ``ranked_candidates`` best, ``candidate_separation_deg`` apart, are scored
again with the full solve, each at the marks' noise it reads itself (the cheap solve knows only
the library's cars; a real car's few marks can fit one of them best at the wrong view). The
``refined_candidates`` best of those are refined (Nelder–Mead over azimuth, elevation and a
pinhole's perspective, the cheap solve), ranked by the full solve at the better of where each
started and where it settled, and the best polished with it from both, under the marks' noise
read once more (on the full grid) at the better of the two. (The roll is the cameras'; the fit
frees it once the marks it keeps are settled: :func:`with_roll`.) A view told, or the classifier's,
enters only as the prior in the score, so a view told 90° or 180° off, the car's other side or
end, and a view far from a start all come out of the same search. What the scan costs does not
depend on the marks: every fit costs about the same.
"""
from __future__ import annotations

import numpy as np

from carbody.camera import View
from carbody.fit.hypothesis import Hypothesis, Scorer
from carbody.view.labels import angular_difference

#: A pinhole view's perspective is searched as ρ = PERSPECTIVE_LENGTH / distance (distance in the
#: fit's normalised units: ρ is wheelbases per distance), within 0 (orthographic) … 1 (a camera a
#: wheelbase from the car's centre).
PERSPECTIVE_LENGTH = 1000.0
PERSPECTIVE_RANGE = (0.0, 1.0)

#: Below this ρ (a camera over 1000 wheelbases, ~3 km, away) the view is orthographic.
PERSPECTIVE_FAR = 1e-3

#: Initial simplex steps of the local search: degrees of azimuth and elevation; ρ; degrees of roll.
SIMPLEX_STEPS = (2.0, 2.0, 0.1, 2.0)

#: The local search stays this far (degrees) in azimuth from where it starts: past the scan's
#: neighbouring azimuths another candidate's valley begins.
LOCAL_AZIMUTH_RANGE_DEG = 25.0


def perspective_of(view: View) -> float:
    """ρ of a view (0: orthographic)."""
    return 0.0 if view.distance is None else PERSPECTIVE_LENGTH / view.distance


def with_perspective(view: View, rho: float, aim: tuple[float, float, float]) -> View:
    """The view with perspective ρ (orthographic below ``PERSPECTIVE_FAR``), aimed at ``aim``."""
    far = rho <= PERSPECTIVE_FAR
    return View(view.azimuth % 360.0, view.elevation, view.roll, None if far else PERSPECTIVE_LENGTH / rho,
                (0.0, 0.0, 0.0) if far else aim)


def search_views(scorer: Scorer, cameras: list[View], find_perspective: bool,
                 adapt=None) -> tuple[Hypothesis, list[Hypothesis], Scorer]:
    """The best hypothesis round the car, the scan's hypotheses best first, and the scorer of
    the best.

    Args:
        cameras: the scan's cameras at azimuth 0 (orthographic, and pinholes at the distances
            to start from: their distance and aim), turned round the car and raised to each
            scan elevation here.
        find_perspective: refine the pinholes' perspective too (the distance is to be found).
        adapt: ``adapt(scorer, hypothesis, coarse=False) -> scorer``: a scorer for what a
            hypothesis says of the marks (:func:`carbody.fit.robust.marks_noise`), called with
            each of the scan's ``ranked_candidates`` best (:func:`ranked_fully`); the candidates
            settle and are polished under what the chosen one says itself (on the full grid
            unless the policy's ``fine_noise`` is off).
    """
    policy = scorer.policy
    scanned = []
    for camera in cameras:
        for elevation in policy.scan_elevations_deg:
            for azimuth in np.arange(0.0, 360.0, policy.scan_azimuth_step_deg):
                view = View(float(azimuth), elevation, camera.roll, camera.distance, camera.aim)
                hypothesis = scorer.hypothesis(view, cheap=True, rejections=policy.scan_rejections)
                if hypothesis is not None:
                    scanned.append(hypothesis)
    if not scanned:
        from carbody.errors import FitError

        raise FitError("no view of any library car explains these keypoints (check their names and places)")
    scanned.sort(key=lambda h: h.score)
    free = ("azimuth", "elevation") + (("perspective",) if find_perspective else ())
    pool = distinct(scanned, max(policy.ranked_candidates, policy.refined_candidates), policy.candidate_separation_deg)

    scorer, order = ranked_fully(scorer, pool, adapt)
    candidates = [pool[i] for i in order[:policy.refined_candidates]]
    coarse = [refine(scorer, c, free, cheap=True, evaluations=policy.coarse_evaluations, tolerance=0.5)
              for c in candidates]
    # each candidate ranked by the full solve at the better of where it started and where the
    # cheap solve settled it (the two starts it is polished from): the cheap solve's optimum
    # can sit where the full model fits worse than at the start
    def full_score(view: View) -> float:
        h = scorer.hypothesis(view, cheap=False)
        return np.inf if h is None else h.score

    scores = [(full_score(c.view), full_score(s.view)) for c, s in zip(coarse, candidates)]
    k = int(np.argmin([min(pair) for pair in scores]))
    if adapt is not None:
        # the marks' noise read again, on the full grid, where the chosen candidate fits best:
        # at the scan's coarse view the marks fit worse and read noisier, and a car fitted to
        # noisier marks keeps less of them
        scorer = adapt(scorer, coarse[k] if scores[k][0] <= scores[k][1] else candidates[k],
                       coarse=not policy.fine_noise)
    # polished from where the cheap solve settled and from the scan's view: the full solve's
    # evidence has its own small valleys, and the cheap one's optimum can sit in another
    starts = [coarse[k], candidates[k]] + _prior_start(scorer, cameras, (coarse[k], candidates[k]))
    polished = [refine(scorer, start, free, cheap=False, evaluations=policy.polish_evaluations,
                       tolerance=policy.polish_tolerance_deg) for start in starts]
    return min(polished, key=lambda h: h.score), scanned, scorer


def with_roll(scorer: Scorer, level: Hypothesis, free: tuple[str, ...]) -> Hypothesis:
    """``level`` (the best view at the roll told) polished again with the roll free too, when the
    marks pay for the extra angle; else ``level``.

    A photo taken by hand is seldom level, and a tilt left to the other angles turns the view and
    bends the car (``benchmarks/bench_roll.py``). But the marks of a level photo also fit a roll
    of a tenth of a degree a little better, and the view and the car's width trade with it: a
    trial with the roll free in every refinement (not committed) put level renders 37 mm off, not
    25 (``bench_fit_accuracy.py --elevation 10 --known-only``, the refined rows). So the roll is kept only when its evidence
    beats the level view's with the roll integrated out (a Laplace approximation). The score is
    read at the level view and a step either side of it (the car solved afresh at each, the
    roll's prior in); a parabola through them gives the roll's best value, what it gains there,
    and its spread σ_roll. The gain must exceed the Occam factor log(σ_prior / σ_roll). Then
    every angle is polished from that roll; the better of that and ``level`` is kept."""
    from dataclasses import replace

    from carbody.errors import AngleError, FitError

    policy = scorer.policy
    sd = policy.roll_prior_sd_deg
    if policy.roll_range_deg <= 0 or sd <= 0:
        return level
    rolling = scorer.with_prior(replace(scorer.prior, roll_deg=level.view.roll, roll_sd_deg=sd))
    view, kept = level.view, level.kept
    try:
        steps = (0.0, ROLL_STEP_DEG, -ROLL_STEP_DEG)
        centre, plus, minus = (rolling.score(v, kept, rolling.solve(v, kept))[0]
                               for v in (replace(view, roll=view.roll + step) for step in steps))
    except (FitError, AngleError):
        return level
    slope = (plus - minus) / (2.0 * ROLL_STEP_DEG)
    curvature = max((plus + minus - 2.0 * centre) / ROLL_STEP_DEG ** 2, 1.0 / sd ** 2)  # (at least the prior's)
    gain = slope ** 2 / (2.0 * curvature)
    if not gain > np.log(sd * np.sqrt(curvature)):
        return level
    reach = policy.roll_range_deg
    roll = float(np.clip(view.roll - slope / curvature, view.roll - reach, view.roll + reach))
    start = rolling.hypothesis(replace(view, roll=roll))
    if start is None:
        return level
    rolled = refine(rolling, start, free + ("roll",), cheap=False, evaluations=policy.polish_evaluations,
                    tolerance=policy.polish_tolerance_deg)
    return rolled if rolled.score < level.score else level


#: Step (degrees) of the finite differences that read the roll's slope and spread off the score.
ROLL_STEP_DEG = 0.5


def _prior_start(scorer: Scorer, cameras: list[View], chosen) -> list[Hypothesis]:
    """[the full solve at the prior's own view (the classifier's top class or the view told),
    with the camera of the scan's that scores best there], or [] when the prior says nothing or
    the chosen starts lie within ``candidate_separation_deg`` of it.

    The scan ranks views on a 15° grid by a cheap solve, and the full solve at a grid point can
    sit far up the slope of a valley whose floor is best: a re-marked pickup (eight marks, seven
    on its near side) scored 250 nats at the scan's 315°, 63 polished at 325°, and was fitted from
    its other end (84.5 at 221°). Polishing from the prior's view too costs one refinement and
    finds that floor; the scores still decide."""
    prior = scorer.prior
    if prior.weight == 0 or (prior.azimuth_deg is None and prior.probabilities is None):
        return []
    start = prior.start
    if any(angular_difference(start.azimuth, h.view.azimuth) <= scorer.policy.candidate_separation_deg
           for h in chosen):
        return []
    found = [scorer.hypothesis(View(start.azimuth, start.elevation, camera.roll, camera.distance, camera.aim))
             for camera in cameras]
    found = [h for h in found if h is not None]
    return [min(found, key=lambda h: h.score)] if found else []


def ranked_fully(scorer: Scorer, hypotheses: list[Hypothesis], adapt=None) -> tuple[Scorer, list[int]]:
    """The scorer to go on with, and the order of ``hypotheses``, best first by the full solve's
    score at their views.

    With ``adapt``, each is scored at the marks' noise it reads itself (``adapt``'s coarse
    grid: the noise is read again where the view settles), and the scorer is the best one's:
    the view and the marks' noise are found together (type-II maximum likelihood over both).
    Read at one view, a few marks' noise comes out as small as that view lets them fit, and
    every other view is judged by it."""
    scored = []
    for i, h in enumerate(hypotheses):
        own = scorer if adapt is None else adapt(scorer, h, coarse=True)
        full = own.hypothesis(h.view, cheap=False)
        scored.append((np.inf if full is None else full.score, i, own))
    scored.sort(key=lambda s: (s[0], s[1]))
    best = scored[0][2] if np.isfinite(scored[0][0]) else scorer
    return best, [i for _, i, _ in scored]


def distinct(hypotheses: list[Hypothesis], count: int, separation_deg: float) -> list[Hypothesis]:
    """The first ``count`` hypotheses (best first) each ``separation_deg`` from those before it
    in azimuth or elevation."""
    chosen: list[Hypothesis] = []
    for h in hypotheses:
        if all(angular_difference(h.view.azimuth, c.view.azimuth) > separation_deg
               or abs(h.view.elevation - c.view.elevation) > separation_deg for c in chosen):
            chosen.append(h)
            if len(chosen) == count:
                break
    return chosen


def refine(scorer: Scorer, start: Hypothesis, free: tuple[str, ...], cheap: bool, evaluations: int,
           tolerance: float) -> Hypothesis:
    """The best hypothesis near ``start``: Nelder–Mead over the ``free`` angles ("azimuth",
    "elevation", "perspective", "roll": within ``roll_range_deg`` of the prior's) with the marks
    ``start`` explains (a mark the view stops seeing is left out and charged), then scored afresh
    there, misplaced marks looked for again; the better of that and ``start`` scored alike."""
    from scipy.optimize import minimize

    from carbody.errors import AngleError, FitError

    policy = scorer.policy
    view0 = start.view
    aim = view0.aim
    x0 = np.array([view0.azimuth, view0.elevation, perspective_of(view0), view0.roll])
    mask = np.array([n in free for n in ("azimuth", "elevation", "perspective", "roll")])
    roll_reach = policy.roll_range_deg if mask[3] else np.inf  # (a roll kept stays as it is)
    lo = np.array([x0[0] - LOCAL_AZIMUTH_RANGE_DEG, policy.elevation_range_deg[0], PERSPECTIVE_RANGE[0],
                   scorer.prior.roll_deg - roll_reach])
    hi = np.array([x0[0] + LOCAL_AZIMUTH_RANGE_DEG, policy.elevation_range_deg[1], PERSPECTIVE_RANGE[1],
                   scorer.prior.roll_deg + roll_reach])

    def view_at(x: np.ndarray) -> View:
        y = x0.copy()
        y[mask] = x
        return with_perspective(View(float(y[0]) % 360.0, float(y[1]), float(y[3])), float(y[2]), aim)

    def objective(x: np.ndarray) -> float:
        y = x0.copy()
        y[mask] = x
        if np.any(y < lo) or np.any(y > hi):
            return np.inf
        view = view_at(x)
        hidden = scorer.hidden(view)
        kept = start.kept & ~hidden
        if kept.sum() < scorer.fewest_kept or hidden.sum() > policy.max_rejected_fraction * len(hidden):
            return np.inf
        try:
            return scorer.score(view, kept, scorer.solve(view, kept, cheap))[0]
        except (FitError, AngleError):
            return np.inf

    if mask.any():
        x = x0[mask]
        steps = np.array(SIMPLEX_STEPS)[mask]
        simplex = np.vstack([x] + [x + steps[i] * np.eye(len(x))[i] for i in range(len(x))])
        found = minimize(objective, x, method="Nelder-Mead",
                         options={"initial_simplex": simplex, "xatol": tolerance, "fatol": 1e-2, "maxfev": evaluations})
        refined = scorer.hypothesis(view_at(found.x), cheap=cheap)
    else:
        refined = None
    again = start if cheap else scorer.hypothesis(start.view, cheap=False)
    options = [h for h in (refined, again) if h is not None]
    return min(options, key=lambda h: h.score) if options else start


#: Step (degrees) of the finite differences that measure how sharply the evidence pins a view angle.
VIEW_STEP_DEG = 0.5

#: Largest standard deviation (degrees) a view angle is given where the evidence is flat.
MAX_VIEW_SD_DEG = 10.0


def view_spread(scorer: Scorer, hypothesis: Hypothesis, angles: tuple[str, ...]) -> np.ndarray:
    """(len(angles), 105): the keypoints' move (normalised units) per one standard deviation of
    each view angle found — a Laplace approximation: the evidence's curvature at the view (the
    shape solved afresh at every view, so its trade with the angle is in it) gives the angle's
    standard deviation at the prior's noise level λ, rescaled to the marks' own (their residual
    variance); central differences of the solved shape give its slope. Near level views the
    marks hardly tell azimuth from width, and this says so."""
    from dataclasses import replace

    from carbody.topology import load_topology

    idx = load_topology().keypoint_point_indices
    sol, view, kept = hypothesis.solution, hypothesis.view, hypothesis.kept
    noise_ratio = sol.cost / (sol.posterior.lam * max(2 * int(kept.sum()) - 2, 1))
    rows = []
    for angle in angles:
        at = getattr(view, angle)
        plus, minus = (scorer.solve(replace(view, **{angle: at + sign * VIEW_STEP_DEG}), kept) for sign in (1, -1))
        curvature = (plus.evidence + minus.evidence - 2.0 * sol.evidence) / VIEW_STEP_DEG ** 2
        sd = MAX_VIEW_SD_DEG if not curvature > 0 else min(np.sqrt(noise_ratio / curvature), MAX_VIEW_SD_DEG)
        slope = (plus.shape.reshape(-1, 3)[idx] - minus.shape.reshape(-1, 3)[idx]).ravel() / (2 * VIEW_STEP_DEG)
        rows.append(slope * sd)
    return np.array(rows)
