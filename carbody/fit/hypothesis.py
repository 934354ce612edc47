"""One measure of how well the library explains the marks at a view: :class:`Scorer`.

A hypothesis is a camera (a view and, for a pinhole, its distance) and which marks it explains.
Its score is −log of how likely the marks are under it (nats, the marks' pixels), the sum of

- the density of the marks it explains under the library's shape prior at that camera (the
  solve's evidence, :mod:`carbody.fit.solve`, taken in the photo's pixels, so hypotheses
  explaining different marks compare), with the charge on a car wider, longer or taller than
  any template (:func:`~carbody.fit.shape_prior.implausibility`);
- for each mark it leaves out, the density of a click anywhere on the photo times the prior
  chance of a misplaced mark: a mark the camera cannot see (no region at it faces a camera near
  this one — the names decide what is visible) and a mark the others put far from where it was
  clicked (:mod:`carbody.fit.robust`) are left out alike;
- the view prior (:class:`~carbody.fit.view_prior.ViewPrior`).

The view search (:mod:`carbody.fit.search`) minimises it over every view; the twin hypotheses
(:mod:`carbody.fit.robust`) compare names by it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from carbody.camera import View
from carbody.errors import AngleError, FitError
from carbody.fit.keypoints_io import KeypointSlot, keypoint_slots
from carbody.fit.options import FitOptions
from carbody.fit.shape_prior import implausibility, library_mean, prepared
from carbody.fit.solve import MixSolution, camera_excess_px, keypoint_spread, solve_gauss, solve_simplex
from carbody.fit.view_prior import ViewPrior
from carbody.fit.visibility import FacingTable
from carbody.library import Library
from carbody.topology import load_topology


@dataclass(frozen=True)
class Marks:
    """The marks as the fit reads them: their keypoint slots and (k, 2) pixels, in the camera
    the solve works in (the photo's, or a camera turned toward an off-centre car)."""

    slots: tuple[KeypointSlot, ...]
    uv: np.ndarray

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.slots]

    @property
    def spread(self) -> float:
        """The marks' RMS distance from their centre, px."""
        return keypoint_spread(self.uv)

    def renamed(self, names: dict[str, str]) -> "Marks":
        """The marks with some renamed ({name as clicked: name fitted})."""
        slots = keypoint_slots()
        return Marks(tuple(slots[names.get(s.name, s.name)] for s in self.slots), self.uv)

    def at(self, uv: np.ndarray) -> "Marks":
        """The same names at other pixels (the marks seen by a turned camera)."""
        return Marks(self.slots, np.asarray(uv, dtype=float))


@dataclass
class Hypothesis:
    """A camera and the marks it explains, scored (:class:`Scorer`).

    Attributes:
        view: the camera (normalised units; a pinhole's aim settled on the fitted car).
        marks: the marks, as named under this hypothesis (a twin exchange renames some).
        kept: (k,) bool, the marks in the solve; hidden: (k,) bool, those the view cannot see.
        solution: the solve of the kept marks.
        score: −log p of all the marks and the view, nats (module docstring).
        prior: the view prior's share of it.
        renamed: {name as clicked: name fitted} of a twin exchange, or empty.
    """

    view: View
    marks: Marks
    kept: np.ndarray
    hidden: np.ndarray
    solution: MixSolution
    score: float
    prior: float
    renamed: dict[str, str]

    @property
    def rejected(self) -> list[str]:
        """Names of the marks left out as misplaced (kept out though the view sees them)."""
        return [n for n, k, h in zip(self.marks.names, self.kept, self.hidden) if not k and not h]

    @property
    def hidden_names(self) -> list[str]:
        return [n for n, h in zip(self.marks.names, self.hidden) if h]

    @property
    def kept_slots(self) -> list[KeypointSlot]:
        return [s for s, k in zip(self.marks.slots, self.kept) if k]

    @property
    def kept_uv(self) -> np.ndarray:
        return self.marks.uv[self.kept]


class Scorer:
    """Scores hypotheses of one photo's marks (module docstring).

    Args:
        library: the model library.
        marks: the checked marks.
        options: how to fit (method, λ, the joint field, the policy).
        wheelbase_mm: a told wheelbase (the shape prior is then sized in mm), or None.
        prior: the view prior.
        image_size: (width, height) px: a misplaced click lands anywhere on it (default: twice
            the marks' extent).
        noise_factor: the marks' noise as a multiple of λ's (its standard deviation): λ·factor²
            is the solve's noise variance; field_scale: the joint field's amplitude as a multiple
            of ``JOINT_FIELD_AMPLITUDE`` (:func:`carbody.fit.robust.marks_noise` reads both off
            the marks).
    """

    def __init__(self, library: Library, marks: Marks, options: FitOptions, wheelbase_mm: float | None,
                 prior: ViewPrior, image_size: tuple[int, int] | None = None, noise_factor: float = 1.0,
                 field_scale: float = 1.0):
        self.library, self.marks, self.options, self.prior = library, marks, options, prior
        self.wheelbase_mm = wheelbase_mm
        self.noise_factor = float(noise_factor)
        #: the solve's noise variance relative to the shape prior's (the marks' spread as unit)
        self.lam = options.prior_weight * self.noise_factor ** 2
        self.policy = options.policy
        method = options.method
        self.field_scale = float(field_scale)
        self._model = prepared(library, method, wheelbase_mm, field=options.joint_field, field_scale=self.field_scale)
        # the search's cheap solve: the library's span alone (no joint field), one Newton round
        self._cheap = self._model if method == "paper" else prepared(library, method, wheelbase_mm, field=False)
        self._facing = _facing_table(library)
        row = {n: i for i, n in enumerate(self._facing.names)}
        self._rows = np.array([row[n] for n in marks.names])
        w, h = image_size if image_size is not None else 2.0 * np.ptp(marks.uv, axis=0) + 1.0
        #: −log density of a misplaced mark: a click anywhere on the photo, at the prior chance of one
        self.outlier_nats = float(np.log(float(w) * float(h)) - np.log(self.policy.outlier_probability))
        self._solves = [0]  # shared by the scorer's copies (with_marks, with_noise): the fit's whole cost
        #: (k,) bool: marks every hypothesis leaves out (:meth:`excluding`), or None
        self.excluded: np.ndarray | None = None

    @property
    def fewest_kept(self) -> int:
        """The fewest marks a hypothesis explains: the policy's ``min_kept``, or all of them when
        there are fewer (five marks are a fit's least)."""
        return min(self.policy.min_kept, len(self.marks.slots))

    @property
    def solves(self) -> int:
        """How many solves this scorer and its copies have made."""
        return self._solves[0]

    def _copy(self) -> "Scorer":
        """A shallow copy (the prepared models shared), for the ``with_*`` variants to change."""
        other = object.__new__(Scorer)
        other.__dict__.update(self.__dict__)
        return other

    def with_marks(self, marks: Marks) -> "Scorer":
        """The same scorer for renamed or turned marks (prepared models shared)."""
        other = self._copy()
        other.marks = marks
        row = {n: i for i, n in enumerate(self._facing.names)}
        other._rows = np.array([row[n] for n in marks.names])
        return other

    def with_prior(self, prior: ViewPrior) -> "Scorer":
        """The same scorer under another view prior."""
        other = self._copy()
        other.prior = prior
        return other

    def excluding(self, index: int) -> "Scorer":
        """The same scorer with mark ``index`` left out of every hypothesis too (and those it
        already leaves out): a misplaced click found by trying each mark out
        (:func:`carbody.fit.robust.left_out_in_turn`)."""
        other = self._copy()
        other.excluded = np.zeros(len(self.marks.slots), dtype=bool) if self.excluded is None else self.excluded.copy()
        other.excluded[index] = True
        return other

    def with_noise(self, factor: float, field_scale: float | None = None) -> "Scorer":
        """The same scorer with the marks' noise at ``factor`` × λ's and the joint field at
        ``field_scale`` × its amplitude (default as it is)."""
        other = self._copy()
        other.noise_factor, other.lam = float(factor), self.options.prior_weight * float(factor) ** 2
        if field_scale is not None and self.options.method != "paper" and self.options.joint_field:
            other.field_scale = float(field_scale)
            other._model = prepared(self.library, self.options.method, self.wheelbase_mm, field=True,
                                    field_scale=other.field_scale)
        return other

    def hidden(self, view: View) -> np.ndarray:
        """(k,) bool: the marks no region faces at ``view`` (within the policy's margin)."""
        facing = self._facing.facing(view.azimuth, view.elevation, self.policy.visibility_margin_deg)[:, 0]
        return ~facing[self._rows]

    def solve(self, view: View, kept: np.ndarray, cheap: bool = False, outline=None, hubs=None) -> MixSolution:
        """The mix of the library that best explains the kept marks at ``view``, with its
        evidence in the marks' pixels (``evidence_px``); with ``outline``
        (:class:`~carbody.fit.outline.OutlineTargets`, the Gaussian-prior methods), the car's
        outline in the photo too, and with ``hubs`` (:class:`~carbody.fit.wheels.HubTargets`)
        the wheels' hubs found in it.

        Raises:
            FitError: no car reproduces them at a positive image scale; AngleError: a pinhole
                camera inside the car.
        """
        self._solves[0] += 1
        slots = [s for s, k in zip(self.marks.slots, kept) if k]
        uv = self.marks.uv[kept]
        lam = self.lam
        if self.options.method == "paper":
            sol = solve_simplex(self._model, slots, uv, view, self.library.S, rounds=1 if cheap else 2)
            m = 2 * len(uv) - 2
            rho = float(np.sqrt(np.mean((uv - uv.mean(axis=0)) ** 2)))
            # no posterior: its residual read as noise of λ's variance
            sol.evidence_px = sol.cost / (2 * lam) + 0.5 * m * np.log(2 * np.pi * lam) + m * np.log(rho)
            return sol
        sol = solve_gauss(self._cheap if cheap else self._model, load_topology().keypoint_point_indices, slots, uv,
                          view, lam, mixture=self.options.method == "mixture", rounds=1 if cheap else 2,
                          outline=outline, hubs=hubs)
        charge = implausibility(sol.shape, self.library, self.wheelbase_mm)
        sol.evidence += charge
        sol.evidence_px += charge
        return sol

    def camera_holds(self, view: View, kept: np.ndarray, solution: MixSolution) -> bool:
        """Whether the solve's camera, linearised at the shape it started from, still holds at
        the shape it found: the kept marks' points, projected through the real pinhole camera,
        lie within ``linearised_camera_spread`` of the marks' spread as far from the marks as the
        solve says. A car bent far toward the camera can meet the marks only in the linearised
        camera; its score then describes no car, and such a view could win the search."""
        if view.distance is None or solution.shape is None:
            return True
        slots = [s for s, k in zip(self.marks.slots, kept) if k]
        excess = camera_excess_px(solution, slots, self.marks.uv[kept], view,
                                  load_topology().keypoint_point_indices)
        return excess <= self.policy.linearised_camera_spread * self.marks.spread

    def score(self, view: View, kept: np.ndarray, solution: MixSolution) -> tuple[float, float]:
        """(the hypothesis' score, its view prior's share), nats."""
        prior = self.prior.cost(view)
        return float(solution.evidence_px + (len(kept) - kept.sum()) * self.outlier_nats + prior), prior

    def hypothesis(self, view: View, kept: np.ndarray | None = None, cheap: bool = False,
                   rejections: int | None = None, check_camera: bool = True) -> Hypothesis | None:
        """The hypothesis ``view`` with the marks it can see (of ``kept``, default all), those
        the others say are misplaced left out (up to ``rejections``; default the policy's most,
        :func:`carbody.fit.robust.leave_out_misplaced`); None when the view cannot see more than
        ``max_rejected_fraction`` of the marks (their names say it is not the photo's), too few
        remain, or no car fits them there, or (a full solve, ``check_camera``) the real camera
        does not bear out the solve's (:meth:`camera_holds`). A refinement's start need not."""
        from carbody.fit.robust import leave_out_misplaced, most_rejected

        hidden = self.hidden(view)
        kept = ~hidden if kept is None else (np.asarray(kept, dtype=bool) & ~hidden)
        if self.excluded is not None:
            kept = kept & ~self.excluded
        if kept.sum() < self.fewest_kept or hidden.sum() > self.policy.max_rejected_fraction * len(hidden):
            return None  # the names say the photo is not taken from here
        try:
            sol = self.solve(view, kept, cheap)
            if self.options.robust_marks:
                limit = most_rejected(len(kept), int(kept.sum()), self.policy)
                kept, sol = leave_out_misplaced(self, view, kept, sol, limit if rejections is None else
                                                min(limit, rejections), cheap)
        except (FitError, AngleError):
            return None
        settled = sol.view if sol.view is not None else view
        if check_camera and not cheap and not self.camera_holds(settled, kept, sol):
            return None
        score, prior = self.score(settled, kept, sol)
        return Hypothesis(settled, self.marks, kept, hidden, sol, score, prior, {})


def _facing_table(library: Library) -> FacingTable:
    """The facing table of the library's mean car, built once per library."""
    from carbody.fit.shape_prior import _cached

    return _cached(library, "facing table", lambda: FacingTable(library_mean(library).reshape(-1, 3)))


def with_view(hypothesis: Hypothesis, **changes) -> View:
    """The hypothesis' view with some fields changed."""
    return replace(hypothesis.view, **changes)
