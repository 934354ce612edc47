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
from carbody.fit.search import PERSPECTIVE_LENGTH, refine


def closer_camera(scorer: Scorer, hypothesis: Hypothesis, aim: tuple[float, float, float]) -> dict | None:
    """Fit an orthographic hypothesis' marks with the camera's distance found, from its view: that
    camera's distance (normalised units; None: far away), both mean residuals (before the
    deformation), how much likelier it is (−log evidence per coordinate; None for the paper's
    solve) and whether it fits far better (``closer_camera_gain``, ``closer_camera_evidence``).
    A photo from a few metres shows the car's near end larger than its far end, which no
    orthographic view of any car does: fitted as if from afar, its marks stay pixels off, or the
    view runs astray to bend a car onto them (BENCHMARKS.md: ``--orthographic-check``).

    Returns:
        the check as a dict (distance in normalised units under ``distance``), or None when no
        car fits the marks with a camera close by.
    """
    policy = scorer.policy
    view = hypothesis.view
    starts = [scorer.hypothesis(View(view.azimuth, view.elevation, view.roll, PERSPECTIVE_LENGTH / rho, aim),
                                kept=hypothesis.kept)
              for rho in policy.scan_perspectives if rho > 0]
    near = [refine(scorer, s, ("azimuth", "elevation", "perspective"), cheap=False,
                   evaluations=policy.polish_evaluations, tolerance=policy.polish_tolerance_deg)
            for s in starts if s is not None]
    if not near:
        return None
    near_fit = min(near, key=lambda h: h.score)
    far, close = float(np.mean(hypothesis.solution.residual_px)), float(np.mean(near_fit.solution.residual_px))
    gain = None
    if hypothesis.solution.evidence is not None and near_fit.solution.evidence is not None:
        # (the scores, not the solves' evidence: the two may leave out different marks)
        gain = float((hypothesis.score - hypothesis.prior) - (near_fit.score - near_fit.prior)) / (2 * int(hypothesis.kept.sum()))
    closer = near_fit.view.distance is not None and (
        close < policy.closer_camera_gain * far or (gain is not None and gain > policy.closer_camera_evidence))
    return {"distance": near_fit.view.distance, "residual_px_mean": close, "orthographic_residual_px_mean": far,
            "evidence_gain_per_coordinate": gain, "closer_camera": bool(closer)}
