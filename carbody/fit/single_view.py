"""Single-view wireframe fitting: keypoints marked on one photo → the car's 3D wireframe.

The algorithm, in :func:`fit_wireframe`:

1. check the marks (:func:`~carbody.fit.keypoints_io.check_keypoints`) and read what is told: the
   view as a prior (:class:`~carbody.fit.view_prior.ViewPrior`), the camera
   (:class:`~carbody.fit.fit_camera.CameraPlan`), a wheelbase;
2. search every view round the car for the one where the library best explains the marks
   (:func:`~carbody.fit.search.search_views`): each hypothesis is scored by one measure
   (:class:`~carbody.fit.hypothesis.Scorer`), the marks it cannot see and those the others say
   are misplaced left out and charged (:mod:`carbody.fit.robust`); a view kept as given is
   scored alone; read off the marks at the best candidate how far they stray from the library,
   as click noise and as the car's own features (:func:`~carbody.fit.robust.marks_noise`), and
   settle the candidates again at that when it is not what the prior assumed;
3. try the names the marks left out suggest — a left/right pair exchanged, a mark clicked under
   its twin's name — as discrete hypotheses of the same measure (:func:`~carbody.fit.robust.twin_exchanges`);
4. correct the camera where that needs refits (:mod:`carbody.fit.fit_camera`): a told distance
   sizes the car, an off-centre car turns the camera toward it;
5. given the photo, fit the wheels' hubs found in it (:mod:`carbody.fit.wheels`) and the car's
   outline in it (:mod:`carbody.fit.outline`) with the marks at the view found: the shape
   between the marks from what the photo shows there;
6. build the car in mm, move it onto the marks (:mod:`carbody.fit.deform`) and say what the fit
   found (:func:`~carbody.fit.diagnostics.diagnose`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from carbody.camera import MAX_ABS_ROLL_DEG, View, check_azimuth, read_view
from carbody.errors import AngleError, FitError
from carbody.fit.diagnostics import diagnose
from carbody.fit.fit_camera import CameraPlan, Turn, mix_wheelbase_mm, size_from_told_distance, turn_toward_car
from carbody.fit.hypothesis import Hypothesis, Marks, Scorer
from carbody.fit.keypoints_io import check_keypoints
from carbody.fit.options import FitOptions, check_wheelbase
from carbody.fit.result import FitResult
from carbody.fit.robust import explains_poorly, left_out_in_turn, marks_noise, twin_exchanges
from carbody.fit.search import distinct, refine, search_views, view_spread, with_roll
from carbody.fit.shape_prior import prepared_field
from carbody.fit.size import SizeEstimate, car_extents, estimate_size, extent_rows
from carbody.fit.solve import (MixSolution, along_keypoints, along_scale, joint_keypoint_covariance,
                               reaches_camera, scale_spread, scale_trade)
from carbody.fit.view_prior import ViewPrior
from carbody.library import Library, check_library
from carbody.policy import FitPolicy
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import load_topology
from carbody.view.labels import angular_difference
from carbody.wireframe import Wireframe


def fit_wireframe(keypoints: dict[str, tuple[float, float]], view: View | float | str | ViewPrior | None = None,
                  library: Library | None = None, *, image_size: tuple[int, int] | None = None,
                  wheelbase_mm: float | None = None, options: FitOptions | None = None,
                  name: str = "fitted car", photo: "np.ndarray | CarOutline | None" = None,
                  **changes) -> FitResult:
    """Fit the car's 3D wireframe to keypoints marked on one photo.

    Args:
        keypoints: {name: (u, v)} pixels; any subset of the 35 names and their ``_right`` mirrors.
        view: what is known of the view: None (nothing), a view told (a :class:`View`, an
            azimuth in degrees or a name such as ``"front 30"``), or a :class:`ViewPrior` (the
            classifier's probabilities). With ``refine`` (default) it is a prior on the search
            over every view; without, the view kept.
        library: the model library (default the shipped one, :func:`carbody.library.default_library`).
        image_size: (width, height) px; keypoints off the image are refused.
        wheelbase_mm: the real wheelbase, if known (the Gaussian-prior methods then also know
            the car's width and height in mm); default from the fitted car's proportions
            (:mod:`carbody.fit.size`; the paper's method: its mix's own).
        options: how to fit (:class:`FitOptions`); ``changes`` set its fields by keyword.
        name: the car's name (STEP product).
        photo: the photo ((h, w, 3) uint8 RGB) or the car already cut out of it
            (:class:`~carbody.fit.outline.CarOutline`): with ``options.outline``, the car's
            outline is fitted with the marks, and with ``options.wheels`` (the photo itself)
            the wheels' hubs (the Gaussian-prior methods).
    Raises:
        KeypointError: unknown, too few, NaN, off-image or degenerate keypoints.
        AngleError: a view outside 0–360° or rolled past ±90°.
        FitError: a bad option or wheelbase, or marks no view of any car explains.
    """
    if not isinstance(options, (FitOptions, type(None))):
        raise FitError(f"options must be a FitOptions, got a {type(options).__name__}")
    options = (options or FitOptions()).with_changes(**changes)
    wheelbase_mm = check_wheelbase(wheelbase_mm)
    check_library(library)
    prior = _view_prior(view, options)
    if library is None:
        from carbody.library import default_library

        library = default_library()
    slots, uv = check_keypoints(keypoints, image_size, load_topology())
    plan = CameraPlan.of(options.distance, options.principal_point, image_size, options.focal_px)
    told_mm = plan.distance if isinstance(plan.distance, float) else None
    sizes_by_distance = told_mm is not None and wheelbase_mm is None
    # a told distance sizes the car when the wheelbase is not told: the perspective is found first
    search_plan = replace(plan, distance="auto") if sizes_by_distance else plan
    if told_mm is not None:
        plan.scan_cameras(library, wheelbase_mm, options.policy)  # refuses a camera in the car
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):  # small dense algebra: more threads only oversubscribe the cores
        scorer = clicked = Scorer(library, Marks(tuple(slots), uv), options, wheelbase_mm, prior, image_size)
        cameras = search_plan.scan_cameras(library, wheelbase_mm, options.policy)
        cameras = [replace(c, roll=prior.roll_deg) for c in cameras]
        # (an off-centre car's obliquity reads as noise until the camera is turned to it)
        turns = plan.principal is not None and plan.distance is not None
        hypothesis, searched, scorer, alternatives = _located(scorer, cameras, search_plan, prior, options,
                                                              adapt=options.robust_marks and not turns)
        polish = _polisher(options, search_plan)
        if options.robust_marks:  # (every mark fitted as named otherwise)
            hypothesis, scorer = twin_exchanges(scorer, hypothesis, polish, alternatives)
            hypothesis, scorer = left_out_in_turn(scorer, hypothesis, polish)
        unsettled = not hypothesis.kept.all() or explains_poorly(hypothesis, options.policy)
        if (hypothesis.renamed or scorer.excluded is not None) and options.refine and unsettled:
            # the names exchanged or a mark left out, the marks are other marks; where the view
            # found for the marks as clicked leaves marks out (or fits poorly), it is searched again
            again, searched_again, renamed_scorer, _ = _located(scorer, cameras, search_plan, prior, options,
                                                                adapt=options.robust_marks and not turns)
            if again.score < hypothesis.score:
                again.renamed = hypothesis.renamed
                hypothesis, searched, scorer = again, searched_again, renamed_scorer
        by_distance = None
        if sizes_by_distance:
            hypothesis, by_distance = size_from_told_distance(
                hypothesis, told_mm, library, options.policy,
                lambda distance, h: polish(scorer, scorer.hypothesis(replace(h.view, distance=distance)) or h,
                                           free=("azimuth", "elevation")),
                lambda h: _own_wheelbase(scorer, h, library, options))
        photo_uv = hypothesis.marks.uv
        # (a told distance stays as the car was sized by it: the turned refits keep it)
        turn = turn_toward_car(hypothesis, photo_uv, plan, options.policy,
                               _turned_refit(scorer, hypothesis, plan, options, _polisher(options, plan)))
        if turn.to_photo is not None:
            scorer = scorer.with_marks(turn.hypothesis.marks)
        if turns and options.robust_marks:
            adapted = _at_marks_noise(scorer, turn.hypothesis)
            if adapted is not scorer:
                scorer, turn.hypothesis = adapted, polish(adapted, adapted.hypothesis(turn.hypothesis.view)
                                                          or turn.hypothesis, free=_polisher_free(options, plan))
        if options.refine:  # on the marks kept, the camera turned to the car: the roll, where they pay for it
            turn.hypothesis = with_roll(scorer, turn.hypothesis, _polisher_free(options, plan))
        wheels_fit = hubs = None
        if isinstance(photo, np.ndarray) and options.wheels and options.method != "paper":
            from carbody.fit.wheels import follow_wheels

            turn.hypothesis, wheels_fit, hubs = follow_wheels(scorer, turn.hypothesis, photo, turn.to_photo)
        outline_fit = None
        if photo is not None and options.outline and options.method != "paper":
            turn.hypothesis, outline_fit = _with_outline(scorer, turn, photo, uv, options, hubs)
        size = _size(scorer, turn.hypothesis, library, options)
        size_by_mix = None if turn.hypothesis.solution.H is None else mix_wheelbase_mm(turn.hypothesis, library)
        wheelbase, source = (wheelbase_mm, "told") if wheelbase_mm is not None else \
            (by_distance, "camera distance") if by_distance is not None else \
            (size.wheelbase_mm, "proportions") if size is not None else \
            (mix_wheelbase_mm(turn.hypothesis, library), "library mix")
        if source == "proportions":
            turn.hypothesis = _sized(turn.hypothesis, size, options.policy)
        if size is not None and options.policy.size_length_move:
            turn.hypothesis, moved = _lengthened(turn.hypothesis, size, options.policy)
            size = replace(size, length_move=moved)
        result = _result(turn, photo_uv, prior, library, options, wheelbase, source, name)
        result.outline, result.wheels = outline_fit, wheels_fit
        result.size, result.wheelbase_by_mix_mm = size, size_by_mix
        if options.deforms:
            result = _deformed(result)
        closer = None
        if options.check_orthographic and plan.distance is None:
            from carbody.fit.checks import closer_camera
            from carbody.fit.shape_prior import library_mean
            from carbody.fit.solve import car_centre

            # (the marks as clicked: names exchanged to fit a distant camera need not fit a close one)
            closer = closer_camera(scorer.with_marks(clicked.marks), turn.hypothesis, car_centre(library_mean(library)))
        result.diagnostics = diagnose(result, scorer, turn.hypothesis, options.policy, searched, closer, photo_uv)
    return result


def _with_outline(scorer: Scorer, turn: Turn, photo, marks_uv: np.ndarray, options: FitOptions, hubs=None):
    """The found hypothesis fitted to the car's outline in the photo too (cut out here unless
    given cut out), with the hubs found in it if any, and what the outline did
    (:func:`~carbody.fit.outline.follow_outline`)."""
    from carbody.fit.outline import CarOutline, follow_outline, segment_car

    outline = photo if isinstance(photo, CarOutline) else segment_car(photo, marks_uv, options.policy)
    return follow_outline(scorer, turn.hypothesis, outline, turn.to_photo, hubs)


def _view_prior(view, options: FitOptions) -> ViewPrior:
    """The prior the search takes from what is told of the view (``fit_wireframe``'s ``view``)."""
    if isinstance(view, ViewPrior):
        _check_roll(view.roll_deg)
        return replace(view, weight=view.weight * options.view_prior_weight)
    if view is None:
        if not options.refine:
            raise FitError("a view to keep is needed when the view is not searched (refine off)")
        return replace(ViewPrior.uniform(options.policy), weight=options.view_prior_weight)
    if not isinstance(view, View):
        view = View(check_azimuth(read_view(view) if isinstance(view, str) else view))
    else:
        check_azimuth(view.azimuth)
    _check_roll(view.roll)
    return ViewPrior.told(view, options.policy, options.view_prior_weight)


def _check_roll(roll_deg: float) -> None:
    """Refuse a roll told past ±``MAX_ABS_ROLL_DEG`` (a photo on its side or upside down)."""
    if abs(roll_deg) > MAX_ABS_ROLL_DEG:
        raise AngleError(f"view roll {roll_deg:g}° is outside ±{MAX_ABS_ROLL_DEG:g}°: turn the photo upright")


def _located(scorer: Scorer, cameras: list[View], plan: CameraPlan, prior: ViewPrior,
             options: FitOptions, adapt: bool) -> tuple[Hypothesis, dict | None, Scorer, list[Hypothesis]]:
    """The best hypothesis: searched round the car (and what the search saw), or at the view
    kept as given (its distance still found when asked); its scorer, at the marks' own noise
    (:func:`_at_marks_noise`) when ``adapt``; and the search's other candidate views."""
    adapt = _at_marks_noise if adapt else None
    if options.refine:
        best, scanned, scorer = search_views(scorer, cameras, plan.finds_perspective, adapt)
        policy = options.policy
        others = [h for h in distinct(scanned, policy.refined_candidates + 1, policy.candidate_separation_deg)
                  if angular_difference(h.view.azimuth, best.view.azimuth) > policy.candidate_separation_deg]
        return best, _search_summary(scanned, best, prior, scorer, len(cameras)), scorer, others
    start = prior.start
    kept = [scorer.hypothesis(View(start.azimuth, start.elevation, start.roll, c.distance, c.aim)) for c in cameras]
    kept = [h for h in kept if h is not None]
    if not kept:
        raise FitError(f"no library car explains these keypoints from the view given ({start.azimuth:g}°): "
                       "check the view and the keypoints' names")
    best = min(kept, key=lambda h: h.score)
    if adapt is not None:
        adapted = adapt(scorer, best)
        if adapted is not scorer:
            scorer, best = adapted, adapted.hypothesis(best.view) or best
    if plan.finds_perspective:
        best = _polisher(options, plan)(scorer, best)
    return best, None, scorer, []


def _at_marks_noise(scorer: Scorer, hypothesis: Hypothesis, coarse: bool = False) -> Scorer:
    """The scorer at what the marks say of themselves at a hypothesis' view (their click noise,
    the car's own features: :func:`~carbody.fit.robust.marks_noise`, on its coarse grid when
    ``coarse``), or ``scorer`` itself when that is what it already assumes."""
    noise, field = marks_noise(scorer, hypothesis, coarse)
    return scorer if (noise, field) == (scorer.noise_factor, scorer.field_scale) else scorer.with_noise(noise, field)


def _polisher_free(options: FitOptions, plan: CameraPlan) -> tuple[str, ...]:
    """What the fit refines: the angles when the view is searched, the perspective when it is
    found (the roll stays as the search left it: :func:`carbody.fit.search.with_roll`)."""
    return (("azimuth", "elevation") if options.refine else ()) + (("perspective",) if plan.finds_perspective else ())


def _polisher(options: FitOptions, plan: CameraPlan):
    """``polish(scorer, hypothesis[, free])``: a local refinement with the full solve of what the
    fit refines (:func:`_polisher_free`)."""
    default = _polisher_free(options, plan)
    policy = options.policy

    def polish(scorer: Scorer, hypothesis: Hypothesis, free: tuple[str, ...] = default) -> Hypothesis:
        return refine(scorer, hypothesis, free, cheap=False, evaluations=policy.polish_evaluations,
                      tolerance=policy.polish_tolerance_deg)

    return polish


def _turned_refit(scorer: Scorer, hypothesis: Hypothesis, plan: CameraPlan, options: FitOptions, polish):
    """``refit(uv, start, search)`` for :func:`~carbody.fit.fit_camera.turn_toward_car`: the
    marks at a turned camera's pixels fitted again from ``start``'s view, or searched afresh
    at its distance (the view kept as given stays given)."""

    def refit(uv: np.ndarray, start: Hypothesis, search: bool) -> Hypothesis | None:
        turned = scorer.with_marks(hypothesis.marks.at(uv))
        if search and options.refine:
            camera = View(0.0, 0.0, start.view.roll, start.view.distance, start.view.aim)
            return search_views(turned, [camera], plan.finds_perspective)[0]
        # (the turned camera's start need not hold: the refinement's own views must)
        again = turned.hypothesis(start.view, check_camera=False)
        return None if again is None else polish(turned, again)

    return refit


def _search_summary(scanned: list[Hypothesis], best: Hypothesis, prior: ViewPrior, scorer: Scorer,
                    cameras: int) -> dict:
    """What the view search saw, for the diagnostics: the prior, how many views it scanned and
    how many could see the marks (hypotheses), the best few distinct ones and the margin of the
    best over the next."""
    from carbody.fit.search import PERSPECTIVE_LENGTH, distinct

    policy = scorer.policy
    views = cameras * len(policy.scan_elevations_deg) * int(round(360.0 / policy.scan_azimuth_step_deg))
    top = distinct(scanned, policy.refined_candidates, policy.candidate_separation_deg)
    rows = [{"azimuth_deg": float(h.view.azimuth), "elevation_deg": float(h.view.elevation),
             "perspective": 0.0 if h.view.distance is None else PERSPECTIVE_LENGTH / h.view.distance,
             "score_nats": float(h.score)} for h in top]
    return {"prior": prior.as_dict(), "views_scanned": views, "hypotheses": len(scanned), "best_scanned": rows,
            "margin_nats": float(top[1].score - top[0].score) if len(top) > 1 else None,
            "score_nats": float(best.score)}


def _own_wheelbase(scorer: Scorer, hypothesis: Hypothesis, library: Library, options: FitOptions) -> float:
    """The wheelbase the fit gives a car when none is told (mm): its proportions' (:func:`_size`),
    or, for the paper's solve, its mix's own."""
    size = _size(scorer, hypothesis, library, options)
    return mix_wheelbase_mm(hypothesis, library) if size is None else size.wheelbase_mm


def _size(scorer: Scorer, hypothesis: Hypothesis, library: Library, options: FitOptions) -> SizeEstimate | None:
    """The wheelbase the fitted car's proportions give (:mod:`carbody.fit.size`), as sure as the
    solve's posterior says (a searched view's own spread joins it here, for the expected errors
    too); None for the paper's solve, which keeps its mix's own (SPEC)."""
    sol = hypothesis.solution
    if options.method == "paper" or sol.posterior is None:
        return None
    if options.refine and sol.posterior.view_spread is None:
        sol.posterior.view_spread = view_spread(scorer, hypothesis, ("azimuth", "elevation"))
    shape = sol.shape if sol.shape is not None else library.S[:, sol.support] @ sol.H[sol.support]
    move = None
    if sol.posterior.scale_solve is not None:  # at the covariance's own level (its inflation)
        move = scale_spread(sol.posterior) * np.sqrt(sol.posterior.inflation)
    return estimate_size(shape, joint_keypoint_covariance(sol.posterior), options.policy.size_proportion_floor,
                         scale_move=move)


def _sized(hypothesis: Hypothesis, size: SizeEstimate, policy: FitPolicy) -> Hypothesis:
    """The hypothesis moved along the fit's trade with the image scale to where the published
    cars put it (:attr:`SizeEstimate.scale_steps`, :func:`~carbody.fit.solve.along_scale`): a
    level front view shows the width against the height, not against the wheelbase, and the
    mix's width in wheelbases is then the table's to read. The move is made as far as the marks
    let it (:func:`_unseen_move`)."""
    sol = hypothesis.solution
    if not size.scale_steps or sol.posterior is None or sol.posterior.scale_solve is None:
        return hypothesis
    _, sd = scale_trade(sol.posterior)
    kept, uv, view = hypothesis.kept_slots, hypothesis.marks.uv[hypothesis.kept], hypothesis.view
    indices = load_topology().keypoint_point_indices
    moved, _ = _unseen_move(hypothesis, policy, size.scale_steps * sd * np.sqrt(sol.posterior.inflation),
                            lambda log_scale: along_scale(sol, log_scale, kept, uv, view, indices))
    return moved


def _lengthened(hypothesis: Hypothesis, size: SizeEstimate, policy: FitPolicy) -> tuple[Hypothesis, float]:
    """(The hypothesis with its length in wheelbases moved toward the one the published cars
    give it, how far it moved as a fraction.) An end the marks do not show is the library mix's
    guess; the table (:attr:`SizeEstimate.dimensions_mm`) reads it from all the car's
    proportions, each as sure as the fit is of it. The shape moves as its posterior regresses it
    on the length, weighed against the length's variance as the size read it
    (:func:`~carbody.fit.solve.along_keypoints`): marks that pin the length keep it. The move is
    made as far as the marks let it (:func:`_unseen_move`)."""
    sol = hypothesis.solution
    if size.dimensions_mm is None or size.proportion_covariance is None or sol.posterior is None \
            or sol.posterior.scale_solve is None or sol.shape is None:
        return hypothesis, 0.0
    points = sol.shape.reshape(-1, 3)
    length = car_extents(points)[0]
    step = np.log(size.dimensions_mm["length"] / size.dimensions_mm["wheelbase"] * NORMALISED_WHEELBASE / length)
    rows = extent_rows(points)[0] / length  # the log length's change per keypoint coordinate
    variance = float(size.proportion_covariance[0, 0])  # the length's as the size read it
    kept, uv, view = hypothesis.kept_slots, hypothesis.marks.uv[hypothesis.kept], hypothesis.view
    indices = load_topology().keypoint_point_indices
    moved, made = _unseen_move(hypothesis, policy, step,
                               lambda amount: along_keypoints(sol, rows, amount, variance, kept, uv, view, indices))
    if not made:
        return hypothesis, 0.0
    return moved, float(np.log(car_extents(moved.solution.shape.reshape(-1, 3))[0] / length))


def _unseen_move(hypothesis: Hypothesis, policy: FitPolicy, amount: float,
                 moved_by: Callable[[float], MixSolution]) -> tuple[Hypothesis, float]:
    """(The hypothesis with the solution ``moved_by(amount)``, the amount made.) A move that
    raises the marks' mean residual by more than ``size_move_misfit`` × their noise (√λ × their
    spread, px) has left what the marks cannot tell (a close camera, marks no car fits): it is
    halved, at most ``size_move_halvings`` times, and else not made (0). None is made that would
    put part of the car through a close camera."""
    sol = hypothesis.solution
    noise_px = np.sqrt(sol.posterior.lam) * sol.rho
    before = float(np.mean(sol.residual_px))
    for _ in range(policy.size_move_halvings + 1):
        moved = moved_by(amount)
        if float(np.mean(moved.residual_px)) - before <= policy.size_move_misfit * noise_px \
                and not reaches_camera(moved.shape, hypothesis.view):
            return replace(hypothesis, solution=moved), amount
        amount /= 2.0
    return hypothesis, 0.0


def _result(turn: Turn, photo_uv: np.ndarray, prior: ViewPrior, library: Library, options: FitOptions,
            wheelbase_mm: float, wheelbase_from: str, name: str) -> FitResult:
    """The fit in mm: the kept marks in the photo's pixels, the car scaled to ``wheelbase_mm``."""
    h = turn.hypothesis
    sol = h.solution
    if sol.shape is None:
        sol.shape = library.S[:, sol.support] @ sol.H[sol.support]
    view = View(float(h.view.azimuth) % 360.0, float(h.view.elevation), float(h.view.roll), h.view.distance, h.view.aim)
    points = sol.shape.reshape(-1, 3) * (wheelbase_mm / NORMALISED_WHEELBASE)
    result = FitResult(wireframe=Wireframe(name, points), view=view,
                       given_view=None if prior.azimuth_deg is None else prior.start, solution=sol,
                       slots=h.kept_slots, uv=photo_uv[h.kept], wheelbase_mm=float(wheelbase_mm),
                       method=options.method, library=library, to_photo=turn.to_photo,
                       focal_px=turn.focal_px, camera_turn_deg=turn.turn_deg, camera_turn_diverged=turn.diverged,
                       wheelbase_from=wheelbase_from,
                       joint_field=options.joint_field and options.method != "paper")
    if turn.to_photo is not None:  # residuals in the photo's own pixels
        sol.residual_px = np.linalg.norm(result.reprojected() - result.uv, axis=1)
    return result


def _deformed(result: FitResult) -> FitResult:
    """The fit with its mix moved onto the marks by the photo-matching deformation
    (:mod:`carbody.fit.deform`), in the fit's own camera (a turned one's pixels, if turned)."""
    sol, idx = result.solution, load_topology().keypoint_point_indices
    before = sol.shape
    after = prepared_field(result.library).fit_to_keypoints(before, idx, result.slots, result.marks_in_fit_camera(),
                                                            result.view, sol.scale, sol.offset)
    result.solve_residual_px = np.array(sol.residual_px, dtype=float)
    if reaches_camera(after, result.view):  # marks that would pull part of the car through the camera
        return result  # (not followed)
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

