"""One robust estimate of the marks: how noisy they are, which to leave out, and which to read
under their twin's name.

A person's marks are mostly right, a few not: a click on the wrong feature, a left/right pair
whose names were exchanged (the car's left is the viewer's right from the front), a mark clicked
under its twin's name. All of them are one thing to the fit: a mark whose density under the car
the other marks give is lower than that of a click anywhere on the photo times the prior chance
of a mistake. The score of a hypothesis (:mod:`carbody.fit.hypothesis`) counts each mark at the
lower of the two, so

- :func:`leave_out_misplaced` leaves out, one at a time, the mark the others explain worst while
  it is worse explained than a misplaced one: its density given the others comes in closed form
  from the solve's leave-one-out residual and leverage (no refit per mark), with the marks'
  noise read from the others' residuals, so a car unlike every template, which misses all its
  genuine marks by a few pixels, keeps them; and only a mark the fit cannot follow either (its
  own residual stands out), so a feature of this car the library bends to stays;
- :func:`marks_noise` reads the marks' noise off them, and how far the car strays from the
  library in a way the joint field can follow (a person's clicks on a real photo are several
  times the prior's noise level, and followed at that level they bend the car far outside the
  library; a car unlike every template shifts its features together);
- :func:`twin_exchanges` tries the discrete hypotheses a mark left out suggests — the pair's names
  exchanged, or the mark read under its twin's name when that one is not marked — each scored as
  the view search scores any hypothesis, and keeps the one that explains the marks clearly better.
"""
from __future__ import annotations

import numpy as np

from carbody.camera import View
from carbody.errors import AngleError, FitError
from carbody.policy import FitPolicy
from carbody.wireframe import RIGHT_SUFFIX

#: The median of a χ² variable with two degrees of freedom is 2·ln 2; its mean is 2.
CHI2_2_MEAN = 2.0


def conditional_costs(solution, prior_weight: float, floor_px: float, residual_ratio: float) -> np.ndarray:
    """(k,) −log density (nats, pixels) of each mark under the car the other marks give, at the
    same camera; −inf for a mark never to be left out: the others place it within ``floor_px``
    of where it was clicked, or the fit follows it to within ``residual_ratio`` × the marks'
    median residual (a feature of this car the library can bend to, not a misplaced click).

    Closed form from the solve's hat matrix: the leave-one-out residual is (I − Hᵢᵢ)⁻¹·eᵢ with
    covariance σ²·(I − Hᵢᵢ)⁻¹ (exact for the linear Gaussian solve at its scale; the mixture's
    weights and the scale move a little). σ² is λ's noise, inflated by the other marks' own
    standardised residuals when they fit worse than λ allows (a car unlike the library, careless
    clicks): a mark is judged against the noise the rest show, not the prior's.
    """
    k = len(solution.residual_px)
    e = solution.residual_vector[:2 * k].reshape(k, 2)
    inverse = np.linalg.inv(np.eye(2) - solution.leverage)
    t2 = np.einsum("ka,kab,kb->k", e, inverse, e) / prior_weight
    others = np.maximum(1.0, (t2.sum() - t2) / (CHI2_2_MEAN * max(k - 1, 1)))
    covariance = (prior_weight * others)[:, None, None] * inverse * solution.rho ** 2  # px²
    nats = 0.5 * t2 / others + 0.5 * np.log(np.linalg.det(2.0 * np.pi * covariance))
    apart = np.linalg.norm(np.einsum("kab,kb->ka", inverse, e), axis=1) * solution.rho
    residual = np.asarray(solution.residual_px, dtype=float)
    stands_out = residual > residual_ratio * float(np.median(residual))
    return np.where((apart > floor_px) & stands_out, nats, -np.inf)


def most_rejected(marked: int, visible: int, policy: FitPolicy) -> int:
    """How many marks a hypothesis may leave out as misplaced (``max_rejected_fraction`` of the
    marks, keeping ``min_kept``)."""
    return max(0, min(int(policy.max_rejected_fraction * marked), visible - policy.min_kept))


def leave_out_misplaced(scorer, view: View, kept: np.ndarray, solution, limit: int, cheap: bool = False):
    """(kept, solution): the marks the others explain worse than a misplaced click left out, one
    at a time (each a solve of the rest), at most ``limit`` (module docstring)."""
    if solution.leverage is None:
        return kept, solution
    floor = scorer.policy.outlier_floor_spread * scorer.marks.spread
    for _ in range(limit):
        nats = conditional_costs(solution, scorer.lam, floor, scorer.policy.outlier_residual_ratio)
        worst = int(np.argmax(nats))
        if not nats[worst] > scorer.outlier_nats:
            break
        trial = kept.copy()
        trial[np.flatnonzero(kept)[worst]] = False
        try:
            solution = scorer.solve(view, trial, cheap)
        except (FitError, AngleError):
            break
        kept = trial
    return kept, solution


def marks_noise(scorer, hypothesis, coarse: bool = False) -> tuple[float, float]:
    """How far the marks stray from the library, and how: (the noise factor on λ's standard
    deviation, ``noise_factors``; the joint field's scale on its amplitude, ``field_scales``)
    under which the marks a hypothesis explains are likeliest at its view (type-II maximum
    likelihood: the evidence in pixels, normalised for the noise, compares them). A car unlike
    every template misses its marks in a pattern the field follows (features shifted along the
    car together); a person's clicks stray one by one, as noise. ``coarse``: every other value
    of each list (ends kept), a third of the solves, to compare views by."""
    best, choice = None, (1.0, 1.0)
    scales = scorer.policy.field_scales if scorer.options.joint_field and scorer.options.method != "paper" else (1.0,)
    factors = scorer.policy.noise_factors
    if coarse:
        scales, factors = scales[::2], factors[::2]
    for c in scales:
        for f in factors:
            try:
                sol = scorer.with_noise(f, c).solve(hypothesis.view, hypothesis.kept)
            except (FitError, AngleError):
                continue
            if best is None or sol.evidence_px < best:
                best, choice = sol.evidence_px, (f, c)
    return choice


def twin_name(name: str) -> str:
    """The mirror twin's name of a keypoint (``x`` ↔ ``x_right``)."""
    return name.removesuffix(RIGHT_SUFFIX) if name.endswith(RIGHT_SUFFIX) else name + RIGHT_SUFFIX


def evidence_per_coordinate(hypothesis) -> float | None:
    """−log evidence per coordinate of the marks a hypothesis keeps (None for the paper's solve,
    which has no evidence)."""
    evidence = hypothesis.solution.evidence
    return None if evidence is None else evidence / (2 * int(hypothesis.kept.sum()))


def explains_poorly(hypothesis, policy: FitPolicy) -> bool:
    """The marks a hypothesis keeps are explained poorly: −log evidence per coordinate above
    ``poor_fit_evidence``."""
    per_coordinate = evidence_per_coordinate(hypothesis)
    return per_coordinate is not None and per_coordinate > policy.poor_fit_evidence


def twin_renames(hypothesis, policy: FitPolicy) -> list[dict[str, str]]:
    """The discrete hypotheses the marks suggest, at most ``twin_hypotheses``: for a mark left
    out (misplaced or hidden) whose twin is marked too, the pair's names exchanged; whose twin is
    not marked, the mark read under the twin's name. When the marks kept are explained poorly
    (−log evidence per coordinate above ``poor_fit_evidence``) and none left out says which, the
    pairs marked whole whose marks the car misses most are tried exchanged too: straight from
    the front or rear an exchanged pair is a mirror image of itself, so no single mark of it
    stands out enough to be left out.
    """
    from carbody.fit.keypoints_io import keypoint_slots

    names = hypothesis.marks.names
    named = keypoint_slots()
    out: list[dict[str, str]] = []

    for name, kept in zip(names, hypothesis.kept):
        twin = twin_name(name)
        if kept or twin not in named:
            continue
        change = {name: twin, twin: name} if twin in names else {name: twin}
        if change not in out:
            out.append(change)
    if not explains_poorly(hypothesis, policy):
        return out
    kept_names = [n for n, k in zip(names, hypothesis.kept) if k]
    residual = dict(zip(kept_names, np.asarray(hypothesis.solution.residual_px, dtype=float)))
    pairs = sorted((n for n in residual if not n.endswith(RIGHT_SUFFIX) and twin_name(n) in residual),
                   key=lambda n: -(residual[n] + residual[twin_name(n)]))
    changes = [{n: twin_name(n), twin_name(n): n} for n in pairs]
    return out + [c for c in changes if c not in out]


def twin_exchanges(scorer, hypothesis, refine, alternatives=()):
    """The hypothesis, or one with a twin exchange (:func:`twin_renames`) that scores better by
    ``twin_margin_nats``: each scored at the hypothesis' view (one solve), the best
    ``twin_hypotheses`` of them refined there (``refine(scorer, hypothesis)``: a short local
    search, as the names can move the view). When the best so far explains the marks poorly,
    the exchanges are tried at the search's other candidate views (``alternatives``) too: an
    exchanged pair can make a wrong view look best.

    Returns:
        (the hypothesis kept, the scorer of its marks).
    """
    best, best_scorer = _exchanged(scorer, hypothesis, refine)
    for start in alternatives:
        if not explains_poorly(best, scorer.policy):
            break
        other = scorer.hypothesis(start.view)
        if other is None:
            continue
        trial, trial_scorer = _exchanged(scorer, other, refine)
        if trial.renamed and trial.score < best.score - scorer.policy.twin_margin_nats:
            best, best_scorer = trial, trial_scorer
    return best, best_scorer


def _exchanged(scorer, hypothesis, refine):
    """:func:`twin_exchanges` at one hypothesis' view."""
    trials = []
    for change in twin_renames(hypothesis, scorer.policy):
        other = scorer.with_marks(hypothesis.marks.renamed(change))
        trial = other.hypothesis(hypothesis.view)
        if trial is not None:
            trials.append((trial.score, len(trials), change, other, trial))
    best, best_scorer = hypothesis, scorer
    for _, _, change, other, trial in sorted(trials, key=lambda t: t[:2])[:scorer.policy.twin_hypotheses]:
        trial = refine(other, trial) or trial
        trial.renamed = change
        if trial.score < best.score - scorer.policy.twin_margin_nats:
            best, best_scorer = trial, other
    return best, best_scorer


def contradicted(hypothesis, policy: FitPolicy) -> bool:
    """The marks a hypothesis keeps are explained so poorly that the fit would be refused as
    contradicting itself: −log evidence per coordinate above ``refuse_evidence``."""
    per_coordinate = evidence_per_coordinate(hypothesis)
    return per_coordinate is not None and per_coordinate > policy.refuse_evidence


def left_out_in_turn(scorer, hypothesis, refine):
    """The hypothesis, or one with one more mark left out, when the marks it keeps would be
    refused as contradicting themselves (:func:`contradicted`): each kept mark left out in turn
    (one solve each at the hypothesis' view, within the policy's most left out), the best
    refined there (which can only lower its score); kept when it scores better by
    ``twin_margin_nats`` (the left-out mark's outlier cost counted). A fit that is merely poor
    (a car the library lacks) keeps its marks and its note: dropping a sound mark would hide
    what the note says.

    The closed-form test (:func:`conditional_costs`) leaves out only a mark whose residual
    stands out. A car can instead bend to follow a stray click where the view cannot see the
    bend (a front view's depth), at a cost only the evidence shows: a real front view re-marked
    (ten marks, one of a pair alone) read 63 nats per coordinate with that mark, 1.3 without.

    Returns:
        (the hypothesis kept, its scorer: :meth:`~carbody.fit.hypothesis.Scorer.excluding`).
    """
    policy = scorer.policy
    if not contradicted(hypothesis, policy):
        return hypothesis, scorer
    if len(hypothesis.rejected) + 1 > most_rejected(len(hypothesis.kept), int((~hypothesis.hidden).sum()), policy):
        return hypothesis, scorer
    trials = []
    for i in np.flatnonzero(hypothesis.kept):
        other = scorer.excluding(int(i))
        trial = other.hypothesis(hypothesis.view)
        if trial is not None:
            trials.append((trial.score, int(i), other, trial))
    if not trials:
        return hypothesis, scorer
    score, _, other, trial = min(trials, key=lambda t: t[:2])
    if not score < hypothesis.score - policy.twin_margin_nats:
        return hypothesis, scorer
    trial = refine(other, trial)
    trial.renamed = hypothesis.renamed
    return trial, other
