"""A fitted car: :class:`FitResult`, what :func:`carbody.fit.single_view.fit_wireframe`
returns — the wireframe in mm, the camera found, the mix, and what the report, the overlay and
the uncertainty picture read from them; what the fit says about the marks is its
``diagnostics`` (:mod:`carbody.fit.diagnostics`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from carbody.camera import View, apply_homography, project
from carbody.errors import FitError
from carbody.fit.keypoints_io import KeypointSlot
from carbody.fit.diagnostics import FitDiagnostics
from carbody.fit.size import SizeEstimate
from carbody.fit.solve import MixSolution, keypoint_covariance
from carbody.library import Library
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import load_topology
from carbody.wireframe import Wireframe


@dataclass
class FitResult:
    """A fitted car.

    Attributes:
        wireframe: the new model, left half, mm (car frame).
        view: the view found (or kept); ``given_view`` the one told (None: none was).
        solution: the mix at the refined view (normalised units).
        slots: the annotated keypoints; ``uv`` their pixels (k, 2).
        wheelbase_mm: the wheelbase the model was scaled to.
        method: ``"mixture"``, ``"gauss"`` or ``"paper"``.
        library: the library used (names for the report).
        deformation_mm: largest control-point move of the photo-matching deformation, mm
            (0 when it is off); the weights describe the mix before it.
        to_photo: (3, 3) homography from the fitted camera's pixels to the photo's, when the
            camera was turned to look at an off-centre car (see :func:`~carbody.fit.single_view.fit_wireframe`); the
            solution's scale and offset are in the turned camera's pixels.
        focal_px: the focal length that turn used, pixels (the known one, or the fit's).
        camera_turn_deg: how far that turn swung the camera from the photo's optical axis to
            the car's centre, degrees (0: no turn).
        camera_turn_diverged: the turns toward the car moved the camera further each pass (a
            focal length the photo's camera did not have), so it was not turned.
        wheelbase_from: where ``wheelbase_mm`` came from: ``"told"``, ``"camera distance"``
            (a told distance against the perspective's), ``"proportions"`` (the fitted car's
            proportions read against published cars: ``size``) or ``"library mix"`` (the
            fitted mix of the templates' own wheelbases: the paper's solve).
        size: what the car's proportions say of its size
            (:class:`~carbody.fit.size.SizeEstimate`), or None (the paper's solve).
        wheelbase_by_mix_mm: the fitted mix's own wheelbase (the templates', weighted), mm.
        solve_residual_px: (k,) the marks' residuals before the deformation (None: no
            deformation, see ``solution.residual_px``).
        joint_field: whether the solve had the local displacement field in its prior.
        outline: what the car's outline in the photo did to the fit
            (:class:`~carbody.fit.outline.OutlineFit`), or None when it was not asked.
        wheels: what the wheels' hubs found in the photo did to the fit
            (:class:`~carbody.fit.wheels.WheelsFit`), or None when it was not asked.
        diagnostics: what the fit says about the marks and the view
            (:class:`~carbody.fit.diagnostics.FitDiagnostics`: marks left out and why, names
            read exchanged, suspect marks, how well the car explains the marks, the search).
    """

    wireframe: Wireframe
    view: View
    given_view: View | None
    solution: MixSolution
    slots: list[KeypointSlot]
    uv: np.ndarray
    wheelbase_mm: float
    method: str
    library: Library = field(repr=False)
    deformation_mm: float = 0.0
    to_photo: np.ndarray | None = None
    focal_px: float | None = None
    camera_turn_deg: float = 0.0
    camera_turn_diverged: bool = False
    wheelbase_from: str = "library mix"
    size: SizeEstimate | None = None
    wheelbase_by_mix_mm: float | None = None
    solve_residual_px: np.ndarray | None = field(default=None, repr=False)
    joint_field: bool = True
    outline: "OutlineFit | None" = None
    wheels: "WheelsFit | None" = None
    diagnostics: FitDiagnostics = field(default_factory=FitDiagnostics)

    @property
    def mm_per_unit(self) -> float:
        return self.wheelbase_mm / NORMALISED_WHEELBASE

    @property
    def camera_distance_mm(self) -> float | None:
        """A pinhole view's camera distance from the car's centre, mm (None: orthographic)."""
        return None if self.view.distance is None else float(self.view.distance * self.mm_per_unit)

    def keypoints_mm(self) -> dict[str, list[float]]:
        """{name: [x, y, z] mm} of the 35 left keypoints and the mirrors of those annotated."""
        out = self.wireframe.keypoints()
        for s in self.slots:
            if s.is_mirror:
                out[s.name] = [float(v) for v in self.wireframe.control_points[s.point_index] * s.sign]
        return out

    def keypoint_sd_mm(self) -> dict[str, list[float]] | None:
        """{name: [σx, σy, σz] mm}: how far each keypoint of :meth:`keypoints_mm` may be off,
        one standard deviation per axis, from the Gaussian-prior solve's posterior
        (:func:`~carbody.fit.solve.keypoint_covariance`): small where the marks pin a
        keypoint, the library's spread where the view cannot see it (the length on a front
        view, the width on a level side view). None for the ``"paper"`` method."""
        post = self.solution.posterior
        if post is None:
            return None
        cov = keypoint_covariance(post)
        sd = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None)) * self.mm_per_unit
        names = [k.name for k in load_topology().keypoints]
        out = {n: [float(v) for v in row] for n, row in zip(names, sd)}
        for s in self.slots:
            if s.is_mirror:
                out[s.name] = out[s.name.removesuffix("_right")]
        return out

    def expected_error_mm(self, keypoint_sd_mm: dict[str, list[float]] | None = None) -> dict[str, float] | None:
        """{name: √(σx² + σy² + σz²) mm} of the 35 left keypoints: the fit's own estimate of
        each keypoint's 3D error (from ``keypoint_sd_mm``, default :meth:`keypoint_sd_mm`);
        None for ``"paper"``."""
        sd = self.keypoint_sd_mm() if keypoint_sd_mm is None else keypoint_sd_mm
        if sd is None:
            return None
        return {k.name: float(np.linalg.norm(sd[k.name])) for k in load_topology().keypoints}

    def draw_expected_errors(self, path: str | Path) -> Path:
        """Write a PNG of the fitted car in four views, each keypoint coloured by its expected
        error with its 1σ ellipse (:func:`carbody.templates.drawing.draw_four_views`).

        Raises:
            FitError: the ``"paper"`` method, which has no posterior.
        """
        from carbody.templates.drawing import draw_four_views

        sd = self.keypoint_sd_mm()
        if sd is None:
            raise FitError("expected errors need a Gaussian-prior method (mixture or gauss): "
                           "the paper's solve has no posterior")
        return draw_four_views(self.wireframe.control_points, path, self.wireframe.name,
                               keypoint_sd_mm=np.array([sd[k.name] for k in load_topology().keypoints]))

    def reprojected(self) -> np.ndarray:
        """(k, 2) float, pixels of the fitted annotated keypoints under the refined camera."""
        pts = np.array([self.wireframe.control_points[s.point_index] * s.sign for s in self.slots])
        return self.project_points(pts)

    def residuals_px(self) -> dict[str, float]:
        """{name: reprojection distance, px} per annotated keypoint."""
        d = np.linalg.norm(self.reprojected() - self.uv, axis=1)
        return {s.name: float(e) for s, e in zip(self.slots, d)}

    def marks_in_fit_camera(self) -> np.ndarray:
        """(k, 2) the marks in the fitted camera's pixels: ``uv``, or, when the camera was turned
        toward an off-centre car, ``uv`` taken back through the turn."""
        return self.uv if self.to_photo is None else apply_homography(np.linalg.inv(self.to_photo), self.uv)

    def project_points(self, points_mm: np.ndarray) -> np.ndarray:
        """(..., 2) pixels of car-frame points (mm) under the fitted camera (a point at or behind
        a pinhole camera, as a car bent by marks that contradict each other can have, far off
        the photo: its perspective factor clamped as the solve clamps it)."""
        from carbody.fit.solve import MAX_PERSPECTIVE_FACTOR

        uv = project(np.asarray(points_mm) / self.mm_per_unit, self.view, self.solution.scale,
                     self.solution.offset, max_factor=MAX_PERSPECTIVE_FACTOR)
        return uv if self.to_photo is None else apply_homography(self.to_photo, uv)

    def top_weights(self, n: int = 10) -> list[dict]:
        """The n library models of largest |weight|: template, expansion factors, weight."""
        H = self.solution.H
        if H is None:
            return []
        order = np.argsort(-np.abs(H))[:n]
        lib = self.library
        return [{"model": int(j), "template": lib.template_names[lib.template_index[j]],
                 "factors": dict(zip(("height", "front_overhang", "rear_overhang", "width"),
                                     (float(f) for f in lib.factors[j]))),
                 "weight": float(H[j])} for j in order if H[j] != 0]

    def template_mix(self) -> dict[str, float]:
        """{template: summed weight of its models}; sums to 1."""
        H = self.solution.H
        if H is None:
            return {}
        sums = np.bincount(self.library.template_index, weights=H, minlength=len(self.library.template_names))
        return {n: float(w) for n, w in zip(self.library.template_names, sums)}
