"""The whole job in one call: photo + keypoints -> view -> wireframe fit -> surfaces -> files.

    import carbody
    result = carbody.reconstruct("car.png", "car_keypoints.json")      # view from the classifier
    result.body_cadquery()          # cadquery.Shell of the sewn body, mm
    result.wireframe_build123d()    # build123d.Compound of the 125 Bezier edges
    result.write("out/")            # wireframe.step, body.step, car.step, pictures, report

The CLI ``carbody reconstruct`` is a thin layer over :func:`reconstruct` and
:meth:`Reconstruction.write`.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from carbody.errors import CarbodyError, KeypointError, OutputError, SurfaceError

#: The stages, in order, as the progress display names them.
STAGES = ("view", "fit", "surfaces")

#: Stiffer fits tried in turn when a region of the fitted wireframe cannot be surfaced (its
#: outline crosses itself: a car far from every template, as the leave-one-out pickup seen from
#: behind; BENCHMARKS.md "End to end"): the library's span without the local field and the
#: deformation, then the paper's plain mix of library cars; the first that surfaces is blended
#: back toward the fit as far as its body still surfaces (:func:`_blended_toward`).
SURFACE_FALLBACKS = (
    ("the library's span alone (no local field, no deformation)", {"joint_field": False, "deform": False}),
    ("the paper's plain mix of library cars", {"method": "paper"}),
)

#: A stiffer fit that surfaces is then blended back toward the fit (control points in the car
#: frame): the largest share of the fit whose body still surfaces, found by this many halvings
#: (a share to 1/8; each a body build).
BLEND_HALVINGS = 3


@dataclass
class Reconstruction:
    """The result of :func:`reconstruct`.

    Attributes:
        name: the car (STEP product name).
        image: (h, w, 3) uint8 RGB photo.
        image_path: where the photo came from, if a file.
        view_source: where the search's prior came from: ``"given"`` (a view told) or
            ``"classifier"`` (its probabilities); the search looks at every view either way.
        view_prediction: the classifier's answer (:class:`carbody.view.predict.ViewPrediction`) or None.
        fit: the wireframe fit (:class:`carbody.fit.FitResult`).
        body: the surfaced body (:class:`carbody.surface.Body`).
        timings_s: seconds per stage.
        fallback: None, or why and how the fit was made stiffer to surface the body
            (``SURFACE_FALLBACKS``): {"reason": the first fit's surface error, "fit": which
            stiffer fit, "share_of_fit": how much of the first fit is blended back into it,
            0–1 (``BLEND_HALVINGS``)}.
    """

    name: str
    image: np.ndarray
    image_path: Path | None
    view_source: str
    view_prediction: Any
    fit: Any
    body: Any
    timings_s: dict[str, float] = field(default_factory=dict)
    fallback: dict[str, str] | None = None

    @property
    def wireframe(self):
        """The fitted :class:`carbody.wireframe.Wireframe` (left half, mm)."""
        return self.fit.wireframe

    def wireframe_shape(self):
        """TopoDS_Compound of the wireframe's Bezier edges, both halves, mm."""
        from carbody.occ.shapes import curves_compound

        return curves_compound(self.wireframe.named_curves(both_halves=True))

    def body_shape(self):
        """The sewn TopoDS_Shell of the body, both halves, mm."""
        return self.body.shape

    def wireframe_cadquery(self):
        from carbody.occ.shapes import as_cadquery

        return as_cadquery(self.wireframe_shape())

    def body_cadquery(self):
        from carbody.occ.shapes import as_cadquery

        return as_cadquery(self.body_shape())

    def wireframe_build123d(self):
        from carbody.occ.shapes import as_build123d

        return as_build123d(self.wireframe_shape())

    def body_build123d(self):
        from carbody.occ.shapes import as_build123d

        return as_build123d(self.body_shape())

    def report(self, truth=None) -> dict:
        """Everything measured, as JSON-ready data (see README)."""
        from carbody.fit.report import build_report

        v = self.fit.view
        given = self.fit.given_view
        view: dict[str, Any] = {"source": self.view_source, "azimuth_deg": v.azimuth,
                                "elevation_deg": v.elevation, "roll_deg": v.roll,
                                "camera_distance_mm": self.fit.camera_distance_mm,
                                "given_azimuth_deg": None if given is None else given.azimuth}
        if self.view_prediction is not None:
            p = self.view_prediction
            view["classifier"] = {"class_deg": p.class_deg, "theta_deg": p.theta_deg, "confidence": p.confidence}
        shell = self.body.report.get("shell", {})
        return {
            "car": self.name,
            "image": str(self.image_path) if self.image_path else None,
            "view": view,
            "fit": build_report(self.fit, truth, image=self.image_path),
            "surfaces": {"faces": len(self.body.faces), **shell},
            # None, or why the fit was made stiffer and which fit the outputs are of
            "fit_fallback": self.fallback,
            "timings_s": self.timings_s,
        }

    def summary(self, report: dict) -> str:
        """A few lines for a person: view, residual, accuracy when known, body checks, times."""
        fit, view = report["fit"], report["view"]
        source = view["source"]
        if source == "given":
            source = f"searched, given {view['given_azimuth_deg']:g} deg"
        elif "classifier" in view:
            source = f"searched, classifier said {view['classifier']['class_deg']:.0f} deg"
        lines = [
            f"car: {self.name}",
            f"view: {view['azimuth_deg']:.1f} deg azimuth, {view['elevation_deg']:.1f} deg elevation ({source})",
            "camera: " + ("orthographic (far away)" if view["camera_distance_mm"] is None
                          else f"{view['camera_distance_mm']:.0f} mm from the car's centre")
            + (f", turned {fit['camera_turn_deg']:.1f} deg from the photo's axis to the car "
               f"(focal length {fit['focal_length_px']:.0f} px)" if fit["camera_turn_deg"] else ""),
            f"keypoints: {fit['keypoints_annotated']}, reprojection residual mean "
            f"{fit['residual_px_mean']:.2f} px, max {fit['residual_px_max']:.2f} px",
            f"wheelbase: {fit['wheelbase_mm']:.0f} mm ({fit['wheelbase_from']})",
        ]
        from carbody.fit.report import fit_notes

        lines += fit_notes(fit)
        if "error_mm_mean" in fit:
            lines.append(f"3D keypoint error vs truth: mean {fit['error_mm_mean']:.1f} mm, "
                         f"max {fit['error_mm_max']:.1f} mm at the fitted wheelbase; "
                         f"mean {fit['error_mm_at_truth_wheelbase_mean']:.1f} mm, "
                         f"max {fit['error_mm_at_truth_wheelbase_max']:.1f} mm at the true one "
                         f"({fit['truth_wheelbase_mm']:.0f} mm)")
        if report["fit_fallback"]:
            fallback = report["fit_fallback"]
            lines.append(f"note: the fitted wireframe could not be surfaced ({fallback['reason']}); the wireframe "
                         f"and body are {fallback['share_of_fit']:.0%} of it blended with a stiffer fit: {fallback['fit']}")
        s = report["surfaces"]
        lines.append(f"body: {s['faces']} Bezier faces in one shell, valid={s.get('valid')}, "
                     f"open only at {s.get('free_closed_loops')} closed bottom loop(s)")
        lines.append("times: " + ", ".join(f"{k} {v:.2f} s" for k, v in report["timings_s"].items()))
        return "\n".join(lines) + "\n"

    def write(self, out_dir: str | Path, truth=None) -> dict[str, Path]:
        """Write every output into ``out_dir`` (created if needed); all or nothing.

        Files: ``wireframe.step`` (both halves, named B-spline edges), ``body.step`` (one shell,
        faces named and coloured by region), ``car.step`` (one AP214 assembly with the parts
        ``wireframe`` and ``body``), ``overlay.png`` (photo, annotated red and reprojected green
        keypoints, projected wireframe), ``body.png`` (shaded body, three views),
        ``report.json`` and ``summary.txt``.

        Raises:
            OutputError: the folder cannot be created or written.
        """
        out = prepare_output_dir(out_dir)
        staging = Path(tempfile.mkdtemp(prefix=".carbody-", dir=out))
        try:
            paths = self._write_all(staging, truth)
            final = {}
            for key, path in paths.items():
                final[key] = out / path.name
                os.replace(path, final[key])
            return final
        finally:
            shutil.rmtree(staging, ignore_errors=True)

    def _write_all(self, folder: Path, truth) -> dict[str, Path]:
        from carbody.fit.overlay import draw_overlay, write_image
        from carbody.render import render_views
        from carbody.surface.body import write_body
        from carbody.wireframe import write_wireframe

        start = time.perf_counter()
        paths = {
            "wireframe": write_wireframe(folder / "wireframe.step", self.wireframe, both_halves=True),
            "body": write_body(folder / "body.step", self.body),
            "assembly": write_assembly(folder / "car.step", self),
            # the overlay is drawn with OpenCV, which works in BGR
            "overlay": write_image(folder / "overlay.png", draw_overlay(self.image[..., ::-1].copy(), self.fit)),
        }
        render_views(self.body, folder / "body.png", size=(480, 340))
        paths["render"] = folder / "body.png"
        self.timings_s["write"] = time.perf_counter() - start
        report = self.report(truth)
        report["files"] = sorted(p.name for p in paths.values()) + ["report.json", "summary.txt"]
        (folder / "report.json").write_text(json.dumps(report, indent=1))
        (folder / "summary.txt").write_text(self.summary(report))
        paths["report"] = folder / "report.json"
        paths["summary"] = folder / "summary.txt"
        return paths


def prepare_output_dir(out_dir: str | Path) -> Path:
    """Create ``out_dir`` if needed and make sure it can be written (before any long work)."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=out, prefix=".carbody-probe-")
        probe.close()
    except OSError as exc:
        raise OutputError(f"{out}: cannot write the output folder ({exc.strerror or exc})") from None
    return out


def write_assembly(path: Path, result: Reconstruction) -> Path:
    """One AP214 file holding the wireframe and the body as named parts of an assembly."""
    import cadquery as cq

    from carbody.occ.step_curves import atomic_write
    from carbody.surface.body import face_names, region_colour

    assy = cq.Assembly(name=result.name)
    assy.add(result.wireframe_cadquery(), name="wireframe", color=cq.Color(0.1, 0.2, 0.6))
    assy.add(result.body_cadquery(), name="body", color=cq.Color(0.7, 0.7, 0.72))
    body_part = assy.children[-1]
    for name, patch, (_, face) in zip(face_names(result.body), result.body.patches, result.body.faces):
        body_part.addSubshape(cq.Face(face), name=name, color=cq.Color(*region_colour(patch.region)))
    return atomic_write(path, lambda tmp: assy.export(tmp, "STEP"))


def _read_inputs(image, keypoints):
    """(RGB image, its path or None, annotation) with sizes checked against each other."""
    from carbody.fit.keypoints_io import Annotation, check_image_size, read_keypoints
    from carbody.view.predict import read_image

    image_path = None
    if isinstance(image, (str, Path)):
        image_path = Path(image)
    rgb = read_image(image)
    if isinstance(keypoints, (str, Path)):
        ann = read_keypoints(keypoints)
    elif hasattr(keypoints, "items"):
        ann = Annotation(dict(keypoints.items()), None, None)
    else:
        raise KeypointError(f"keypoints must be a keypoint file or map names to (u, v) pixels, "
                            f"got a {type(keypoints).__name__}")
    h, w = rgb.shape[:2]
    check_image_size(ann, (w, h))
    return rgb, image_path, ann


def reconstruct(image, keypoints, view: float | str | None = None, wheelbase_mm: float | None = None, *,
                elevation_deg: float = 0.0, camera_distance_mm: float | str | None = "auto",
                principal_point: str | tuple[float, float] = "auto", focal_35mm: float | None = None,
                name: str | None = None, library=None, reject_outliers: bool = True,
                view_prior_weight: float = 1.0,
                on_stage: Callable[[str], None] | None = None) -> Reconstruction:
    """Photo + keypoints -> the car's wireframe and sewn body.

    Args:
        image: photo path or (h, w[, c]) uint8 array (grayscale and RGBA work).
        keypoints: keypoint file (the project's JSON, COCO or labelme) or {name: (u, v)} pixels.
        view: azimuth in degrees (0 front, 90 left side, 180 rear, 270 right side) or a name
            (``"front 30"``, ``"front 30 right"``: :func:`carbody.camera.read_view`): a prior on
            the fit's search over every view; None takes the shipped view classifier's
            probabilities as that prior.
        wheelbase_mm: the car's real wheelbase; None uses the fitted mix of the templates'.
        elevation_deg: the camera elevation told (a prior of the search).
        camera_distance_mm: how far the camera stood from the car's centre (a pinhole camera:
            nearer parts look larger); "auto" (default: photos are taken from a few metres)
            finds it with the view; None (or "orthographic") assumes a distant camera.
        principal_point: where the camera's optical axis meets the photo: "car" (pointed at
            the car, or a photo cropped around it), "centre" (an uncropped photo: a car off
            its centre is then turned to; see :func:`carbody.fit.fit_wireframe`), or "auto"
            (default): "centre" when the focal length is known, else "car".
        focal_35mm: the camera's 35 mm-equivalent focal length, mm; default the photo's EXIF
            when it has one and is not cropped (:mod:`carbody.fit.focal`). The turn toward an
            off-centre car uses it.
        name: the car's name in the STEP files (default: the photo's file stem).
        library: a :class:`carbody.library.Library` (default the shipped one).
        reject_outliers: estimate the marks robustly (leave out misplaced ones, read a mark
            left out under its twin's name: :mod:`carbody.fit.robust`); False fits every mark
            as named.
        view_prior_weight: how strongly the view given, or the classifier's, counts in the
            search (a factor on its −log prior; 0: the marks alone).
        on_stage: called with each stage's name as it starts (progress display).

    Raises:
        carbody.errors.CarbodyError: any bad input, in one line (unreadable image, keypoints that
            do not fit the image, a view outside 0-360, too few or degenerate keypoints, ...).
    """
    from carbody.camera import View, read_view
    from carbody.fit import FitOptions, ViewPrior, fit_wireframe
    from carbody.library import default_library
    from carbody.fit.focal import focal_length_px
    from carbody.surface import build_body

    timings: dict[str, float] = {}
    rgb, image_path, ann = _read_inputs(image, keypoints)
    h, w = rgb.shape[:2]
    name = name or (image_path.stem if image_path else "car")
    options = FitOptions(camera_distance_mm=camera_distance_mm, principal_point=principal_point,
                         robust=reject_outliers, check_orthographic=True, view_prior_weight=view_prior_weight)
    prior = None if view is None else View(read_view(view), elevation_deg)

    def stage(label: str):
        if on_stage:
            on_stage(label)
        return time.perf_counter()

    start = stage("view")
    prediction, source = None, "given"
    if prior is None:
        from carbody.view.labels import CLASS_ANGLES_DEG
        from carbody.view.predict import keypoint_box, predict_view

        prediction = predict_view(rgb, box=keypoint_box(ann.points))   # the car, not the whole photo
        prior, source = ViewPrior.from_classifier(CLASS_ANGLES_DEG, prediction.probabilities,
                                                  elevation_deg=elevation_deg), "classifier"
    timings["view"] = time.perf_counter() - start

    start = stage("fit")
    focal, _ = focal_length_px(image_path, (w, h), focal_35mm)
    options = options.with_changes(focal_px=focal)

    def fit_with(points: dict, **stiffer):
        return fit_wireframe(points, prior, library or default_library(), image_size=(w, h),
                             wheelbase_mm=wheelbase_mm, options=options.with_changes(**stiffer), name=name)

    fit = fit_with(ann.points)
    timings["fit"] = time.perf_counter() - start

    start = stage("surfaces")
    fallback = None
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(1):  # small dense algebra: more threads only oversubscribe the cores
            body = build_body(fit.wireframe)
    except SurfaceError as exc:
        # The stiffer fits take the marks the fit kept, as it named them (a mark it left out as
        # misplaced bends a stiffer car further still).
        kept = {s.name: (float(u), float(v)) for s, (u, v) in zip(fit.slots, fit.uv)}
        for label, stiffer in SURFACE_FALLBACKS:
            try:
                stiff = fit_with(kept, robust=False, **stiffer)
                body = build_body(stiff.wireframe)
            except CarbodyError:
                continue
            stiff.diagnostics = fit.diagnostics
            fit, body, share = _blended_toward(fit, stiff, body)
            fallback = {"reason": str(exc), "fit": label, "share_of_fit": share}
            break
        else:
            raise exc from None
    timings["surfaces"] = time.perf_counter() - start
    return Reconstruction(name, rgb, image_path, source, prediction, fit, body, timings, fallback)


def _blended_toward(fit, stiff, stiff_body):
    """(fit, body, share): the largest share of ``fit`` blended with ``stiff`` (control points in
    the car frame, and wheelbases) whose body still surfaces (``BLEND_HALVINGS``), seen by the
    camera of either that puts it nearer the marks; ``stiff`` itself (share 0) when none does.
    Crossing is gradual in the share, so much of the fit's match to the marks is kept where only
    a corner of it crossed (BENCHMARKS.md "End to end": 12–88 % kept, 70–232 mm against
    117–255 mm for the stiffer fit alone)."""
    from dataclasses import replace

    from carbody.surface import build_body
    from carbody.wireframe import Wireframe

    a = fit.wireframe.control_points / fit.wheelbase_mm
    b = stiff.wireframe.control_points / stiff.wheelbase_mm
    low, high, best = 0.0, 1.0, (stiff, stiff_body)
    for _ in range(BLEND_HALVINGS):
        share = (low + high) / 2
        wheelbase = share * fit.wheelbase_mm + (1.0 - share) * stiff.wheelbase_mm
        wire = Wireframe(fit.wireframe.name, (share * a + (1.0 - share) * b) * wheelbase)
        try:
            body = build_body(wire)
        except SurfaceError:
            high = share
            continue
        # the camera of the fit or the stiffer one, whichever puts the blend nearer the marks
        seen = [replace(f, wireframe=wire, wheelbase_mm=wheelbase, deformation_mm=share * fit.deformation_mm)
                for f in (fit, stiff)]
        low, best = share, (min(seen, key=lambda f: np.mean(list(f.residuals_px().values()))), body)
    return best[0], best[1], low

