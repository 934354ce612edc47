"""How to fit: :class:`FitOptions`, one frozen object instead of keyword dicts passed along.

    from carbody.fit import FitOptions, fit_wireframe
    fit_wireframe(marks, 30, options=FitOptions(camera_distance_mm="auto"))
    fit_wireframe(marks, 30, camera_distance_mm="auto")      # the same: fields as keywords

What the photo is (the marks, the image size, a told wheelbase, the view prior) are the
function's arguments; how to fit it is here.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass, field, fields, replace

import numpy as np

from carbody.errors import FitError
from carbody.fit.solve import DEFAULT_PRIOR_WEIGHT, METHODS
from carbody.policy import FIT_POLICY, FitPolicy

#: The wheelbases (mm) the fit accepts when told.
MIN_WHEELBASE_MM, MAX_WHEELBASE_MM = 500.0, 10_000.0


def _finite(value) -> bool:
    """Whether ``value`` is a finite number (a string or a boolean is none)."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)) and bool(np.isfinite(value))


@dataclass(frozen=True)
class FitOptions:
    """How :func:`carbody.fit.fit_wireframe` fits.

    Attributes:
        method: ``"mixture"`` (a Gaussian shape prior around each template, default),
            ``"gauss"`` (one around the library mean) or ``"paper"`` (plain ΣH = 1, 0 ≤ H ≤ 1).
        prior_weight: λ of the Gaussian-prior methods: the marks' noise variance relative to
            the shape prior's, in units of the marks' spread.
        refine: search the view (every azimuth and elevation, the given view a prior); False
            keeps the view as given (a camera distance ``"auto"`` is still found).
        deform: move the fit onto the marks with a smooth symmetric field after the solve
            (:mod:`carbody.fit.deform`); None: on for the Gaussian-prior methods, off for the
            paper's.
        joint_field: the Gaussian-prior solve carries the deformation's local part in its prior;
            False solves the library's span alone (stiffer).
        camera_distance_mm: None or ``"orthographic"`` for SPEC's far camera; a number (mm from
            the car's centre) for a pinhole camera; ``"auto"`` to find the distance.
        principal_point: where a pinhole camera's axis meets the photo: ``"car"``, ``"centre"``,
            (u, v) pixels, or ``"auto"`` (``"centre"`` when ``focal_px`` is known).
        focal_px: the camera's focal length in pixels, if known.
        robust: estimate the marks robustly (:mod:`carbody.fit.robust`): leave out misplaced
            ones and try the names of those left out exchanged with their twins; False fits
            every mark as named.
        check_orthographic: with the orthographic camera, also fit the distance and say when a
            camera close by fits far better (``diagnostics.closer_camera``).
        view_prior_weight: how strongly the given view (or the classifier's probabilities)
            counts in the search: a factor on its −log prior (0: not at all, the search alone).
        outline: given the photo, fit the car's outline in it too, beside the marks
            (:mod:`carbody.fit.outline`; the Gaussian-prior methods). Off by default: on the
            real-photo benchmark it narrows the width and wheelbase errors but widens the
            length's (docs/outline.md).
        wheels: given the photo, find the wheels' hubs in it and fit them too, beside the
            marks (:mod:`carbody.fit.wheels`; the Gaussian-prior methods). On by default: on
            the real-photo benchmark the wheel centres come nearer (3.4 → 2.8 % of the car's
            size) and nothing else moves (docs/wheels.md); no hub found, the fit is the marks'.
        policy: the thresholds (:class:`carbody.policy.FitPolicy`).
    """

    method: str = METHODS[0]
    prior_weight: float = DEFAULT_PRIOR_WEIGHT
    refine: bool = True
    deform: bool | None = None
    joint_field: bool = True
    camera_distance_mm: float | str | None = None
    principal_point: str | tuple[float, float] = "auto"
    focal_px: float | None = None
    robust: bool = True
    check_orthographic: bool = False
    view_prior_weight: float = 1.0
    outline: bool = False
    wheels: bool = True
    policy: FitPolicy = field(default=FIT_POLICY, repr=False)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise FitError(f"unknown fit method {self.method!r} (known: {', '.join(METHODS)})")
        if not (_finite(self.prior_weight) and self.prior_weight > 0):
            raise FitError(f"prior weight {self.prior_weight!r} is not a positive number")
        if not (_finite(self.view_prior_weight) and self.view_prior_weight >= 0):
            raise FitError(f"view prior weight {self.view_prior_weight!r} is not a number ≥ 0")
        for flag in ("wheels", "outline"):
            if not isinstance(getattr(self, flag), (bool, np.bool_)):
                raise FitError(f"{flag} must be True or False, got {getattr(self, flag)!r}")
        if self.focal_px is not None and not (_finite(self.focal_px) and self.focal_px > 0):
            raise FitError(f"focal length {self.focal_px!r} px is not a positive number")
        distance = self.camera_distance_mm
        if isinstance(distance, str) and distance not in ("auto", "orthographic"):
            raise FitError(f"camera distance {distance!r} is not a number, 'auto' or 'orthographic'")
        if distance is not None and not isinstance(distance, str):
            try:
                value = float(distance)
            except (TypeError, ValueError):
                raise FitError(f"camera distance {distance!r} is not a number or 'auto'") from None
            if not (np.isfinite(value) and value > 0):
                raise FitError(f"camera distance {distance!r} mm is not a positive distance")

    @property
    def deforms(self) -> bool:
        """Whether the deformation runs (the default: the Gaussian-prior methods)."""
        return (self.method != "paper") if self.deform is None else bool(self.deform)

    @property
    def robust_marks(self) -> bool:
        """Whether the marks are estimated robustly (the paper's solve fits every mark as named)."""
        return self.robust and self.method != "paper"

    @property
    def distance(self) -> float | str | None:
        """The camera distance as the fit reads it: None (orthographic), ``"auto"`` or mm."""
        d = self.camera_distance_mm
        return None if d == "orthographic" else d if d is None or d == "auto" else float(d)

    def with_changes(self, **changes) -> "FitOptions":
        """A copy with some fields changed (unknown names refused in one line)."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise FitError(f"unknown fit option {unknown[0]!r} (known: {', '.join(sorted(known))})")
        return replace(self, **changes)


def check_wheelbase(wheelbase_mm: float | None) -> float | None:
    """A told wheelbase as a float, or None; one that is no car's is refused."""
    if wheelbase_mm is None:
        return None
    try:
        value = float(wheelbase_mm)
    except (TypeError, ValueError):
        raise FitError(f"wheelbase {wheelbase_mm!r} is not a number") from None
    if not (np.isfinite(value) and MIN_WHEELBASE_MM <= value <= MAX_WHEELBASE_MM):
        raise FitError(f"wheelbase {wheelbase_mm!r} mm is not a car's ({MIN_WHEELBASE_MM:g}–{MAX_WHEELBASE_MM:g} mm)")
    return value
