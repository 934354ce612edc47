"""What the fit says about the marks and the view: :class:`FitDiagnostics`, in one place.

The fit (:func:`carbody.fit.fit_wireframe`) returns the car (:class:`~carbody.fit.result.FitResult`)
and, as its ``diagnostics``, what a person should know about how it got there: which marks it left
out and why (a mark the view found cannot see; a mark the others put far from where it was
clicked, and the keypoint the car puts there if one is near), names it read exchanged, marks it
kept but cannot follow, how well the car explains the marks, and what the view search saw.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from carbody.policy import FitPolicy

#: Why a mark was left out.
HIDDEN, MISPLACED = "hidden", "misplaced"


@dataclass
class RejectedMark:
    """A mark the fit left out.

    Attributes:
        uv: where it was clicked, photo pixels.
        px: how far the fitted car passes from it, px.
        reason: ``"hidden"`` (no region at it faces the view found: a left/right name or a view
            slip) or ``"misplaced"`` (the other marks put it far from where it was clicked).
        looks_like: the keypoint the fitted car puts where it was clicked, when one is near (a
            click meant for another name), else None.
    """

    uv: tuple[float, float]
    px: float
    reason: str
    looks_like: str | None = None


@dataclass
class FitDiagnostics:
    """What the fit says about the marks and the view (module docstring).

    Attributes:
        rejected: {name: :class:`RejectedMark`} of the marks left out.
        renamed: {name as clicked: name fitted}: a left/right pair read exchanged, or a mark read
            under its twin's name; empty when every mark was fitted as named.
        suspect: kept marks the car passes far from (``suspect_ratio`` × the median residual and
            ``suspect_spread`` of the marks' spread), worst first.
        evidence_per_coordinate: −log evidence per marked coordinate (None: the paper's solve).
        fits_poorly: above ``poor_fit_evidence``: no car near the view found explains the marks.
        misses_marks: the car's mean residual exceeds ``misses_marks_spread`` of the marks' spread.
        contradicts: far past both (``refuse_evidence``, ``refuse_misses_spread``): the marks
            contradict each other, and the fit is not given out unless forced.
        view_search: what the search saw: the prior, the views scanned and how many of them see
            the marks (``hypotheses``), the best few distinct ones scanned ({azimuth_deg,
            elevation_deg, perspective, score_nats}), the margin (nats) of the best over the next
            and the score of the view found; None for a view kept as given.
        closer_camera: told the orthographic camera and asked to check, the fit with the distance
            found (its distance, both residuals, the evidence gained, and ``closer_camera``:
            whether it fits far better); else None.
        solves: how many library solves the fit took (its cost).
    """

    rejected: dict[str, RejectedMark] = field(default_factory=dict)
    renamed: dict[str, str] = field(default_factory=dict)
    suspect: list[str] = field(default_factory=list)
    evidence_per_coordinate: float | None = None
    fits_poorly: bool = False
    misses_marks: bool = False
    contradicts: bool = False
    view_search: dict | None = None
    closer_camera: dict | None = None
    solves: int = 0

    @property
    def swapped(self) -> tuple[str, str] | None:
        """The left/right pair read with its names exchanged, or None."""
        pairs = sorted(a for a, b in self.renamed.items() if self.renamed.get(b) == a)
        return (pairs[0], pairs[1]) if len(pairs) == 2 else None

    @property
    def camera_closer(self) -> bool:
        """The orthographic check says a camera close by fits the marks far better."""
        return bool(self.closer_camera and self.closer_camera["closer_camera"])

    def as_dict(self) -> dict:
        """JSON-ready (the report's ``diagnostics``)."""
        out = asdict(self)
        out["swapped"] = None if self.swapped is None else list(self.swapped)
        return out


def diagnose(result, scorer, hypothesis, policy: FitPolicy, view_search: dict | None,
             closer_camera: dict | None, photo_uv: np.ndarray) -> FitDiagnostics:
    """The diagnostics of a finished fit.

    Args:
        result: the :class:`~carbody.fit.result.FitResult` (its car in mm, its camera).
        scorer: the scorer of the marks as fitted (its solve count).
        hypothesis: the hypothesis kept (which marks it left out, which it renamed).
        photo_uv: (k, 2) every mark as clicked, photo pixels, in ``hypothesis.marks`` order.
    """
    from carbody.fit.solve import keypoint_spread

    rejected = {}
    marks = hypothesis.marks
    for slot, uv, kept, hidden in zip(marks.slots, photo_uv, hypothesis.kept, hypothesis.hidden):
        if kept:
            continue
        point = result.wireframe.control_points[slot.point_index] * slot.sign
        px = float(np.linalg.norm(result.project_points(point) - uv))
        rejected[clicked_name(slot.name, hypothesis.renamed)] = RejectedMark(
            (float(uv[0]), float(uv[1])), px, HIDDEN if hidden else MISPLACED,
            looks_like(result, slot.name, uv, policy))
    residual = result.residuals_px()
    values = np.array(list(residual.values()))
    spread = keypoint_spread(result.uv)
    limit = max(policy.suspect_ratio * float(np.median(values)), policy.suspect_spread * spread)
    suspect = sorted((n for n, r in residual.items() if r > limit), key=lambda n: -residual[n])
    evidence = result.solution.evidence
    per_coordinate = None if evidence is None else float(evidence) / (2 * len(result.slots))
    return FitDiagnostics(
        rejected=rejected, renamed=dict(hypothesis.renamed), suspect=suspect,
        evidence_per_coordinate=per_coordinate,
        fits_poorly=per_coordinate is not None and per_coordinate > policy.poor_fit_evidence,
        misses_marks=bool(values.mean() > policy.misses_marks_spread * spread),
        contradicts=bool((per_coordinate is not None and per_coordinate > policy.refuse_evidence)
                         or values.mean() > policy.refuse_misses_spread * spread),
        view_search=view_search, closer_camera=closer_camera, solves=scorer.solves)


def clicked_name(name: str, renamed: dict[str, str]) -> str:
    """The name a mark was clicked under, given the fit's renames ({clicked: fitted})."""
    return next((a for a, b in renamed.items() if b == name), name)


def looks_like(result, name: str, uv: np.ndarray, policy: FitPolicy) -> str | None:
    """The keypoint the fitted car puts within ``looks_like_spread`` of the marks' spread of a
    mark left out (other than its own name), or None."""
    from carbody.fit.keypoints_io import keypoint_slots
    from carbody.fit.solve import keypoint_spread

    named = keypoint_slots()
    names = [n for n in named if n != name]
    cp = result.wireframe.control_points
    where = result.project_points(np.array([cp[named[n].point_index] * named[n].sign for n in names]))
    d = np.linalg.norm(where - np.asarray(uv, dtype=float), axis=1)
    j = int(np.argmin(d))
    return names[j] if d[j] < policy.looks_like_spread * keypoint_spread(result.uv) else None

