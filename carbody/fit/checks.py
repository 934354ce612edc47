"""The fit's one remaining check: told the orthographic camera, would a camera close by fit far better?

Everything else the old fit checked in turn (the car's other side or end, a view far from the one
told, a mark misplaced or a pair exchanged) is now one search and one robust estimate
(:mod:`carbody.fit.search`, :mod:`carbody.fit.robust`). A camera told to be orthographic is the
user's word, so the search keeps it; this check only says when the marks disagree.
"""
from __future__ import annotations

import numpy as np

from carbody.camera import View
from carbody.fit.hypothesis import Hypothesis, Scorer
from carbody.fit.search import PERSPECTIVE_LENGTH, search_views
from carbody.tolerances import NORMALISED_WHEELBASE


def closer_camera(scorer: Scorer, hypothesis: Hypothesis, aim: tuple[float, float, float]) -> dict | None:
    """Fit an orthographic hypothesis' marks with the camera's distance found (the search as
    ``camera_distance_mm="auto"`` runs it: an orthographic fit of a close photo can settle
    degrees off, so not from its view): that camera's distance (normalised units; None: far
    away), both mean residuals (before the
    deformation), how much likelier it is (−log evidence per coordinate; None for the paper's
    solve) and whether it fits far better (``closer_camera_gain``, ``closer_camera_evidence``).
    A photo from a few metres shows the car's near end larger than its far end, which no
    orthographic view of any car does: fitted as if from afar, its marks stay pixels off, or the
    view runs astray to bend a car onto them (docs/fit_accuracy.md: ``--orthographic-check``).

    Returns:
        the check as a dict (``camera_distance_mm`` at that fit's wheelbase: the told one, else
        its own mix's), or None when no car fits the marks with a camera close by.
    """
    from carbody.fit.fit_camera import mix_wheelbase_mm

    from carbody.errors import FitError

    policy = scorer.policy
    roll = hypothesis.view.roll
    cameras = [View(0.0, 0.0, roll) if rho == 0 else View(0.0, 0.0, roll, PERSPECTIVE_LENGTH / rho, aim)
               for rho in policy.scan_perspectives]
    try:
        near_fit = search_views(scorer, cameras, find_perspective=True)[0]
    except FitError:
        return None
    far, close = float(np.mean(hypothesis.solution.residual_px)), float(np.mean(near_fit.solution.residual_px))
    gain = None
    if hypothesis.solution.evidence is not None and near_fit.solution.evidence is not None:
        # (the scores, not the solves' evidence: the two may leave out different marks)
        gain = float((hypothesis.score - hypothesis.prior) - (near_fit.score - near_fit.prior)) / (2 * int(hypothesis.kept.sum()))
    closer = near_fit.view.distance is not None and (
        close < policy.closer_camera_gain * far or (gain is not None and gain > policy.closer_camera_evidence))
    wheelbase = scorer.wheelbase_mm if scorer.wheelbase_mm is not None else mix_wheelbase_mm(near_fit, scorer.library)
    distance = None if near_fit.view.distance is None else float(near_fit.view.distance * wheelbase / NORMALISED_WHEELBASE)
    return {"camera_distance_mm": distance, "residual_px_mean": close, "orthographic_residual_px_mean": far,
            "evidence_gain_per_coordinate": gain, "closer_camera": bool(closer)}
