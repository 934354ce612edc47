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
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from carbody.errors import CarbodyError, FitRefused, KeypointError, OutputError, SurfaceError

#: The stages, in order, as the progress display names them.
STAGES = ("view", "fit", "surfaces")

#: Stiffer fits tried in turn when a region of the fitted wireframe cannot be surfaced (its
#: outline crosses itself: a car far from every template, as the leave-one-out pickup seen from
#: behind; docs/end_to_end.md): the library's span without the local field and the
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
        body: the surfaced body (:class:`carbody.surface.Body`); None in the ``partial`` of a
            run that failed after the fit (:meth:`write_failed`).
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
    #: why a run that failed after the fit gave no body (one line), else None
    error: str | None = None

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
        shell = None if self.body is None else self.body.report.get("shell", {})
        return {
            "car": self.name,
            # "body", or "failed" (no body: ``error`` says why, in the line the command printed)
            "outcome": "body" if self.body is not None else "failed",
            "error": self.error,
            "image": str(self.image_path) if self.image_path else None,
            "view": view,
            "fit": build_report(self.fit, truth, image=self.image_path),
            "surfaces": None if self.body is None else {"faces": len(self.body.faces), **shell},
            # None, or why the fit was made stiffer and which fit the outputs are of
            "fit_fallback": self.fallback,
            "timings_s": self.timings_s,
        }

    def summary(self, report: dict) -> str:
        """A few lines for a person: view, residual, accuracy when known, body checks, times."""
        from carbody.fit.report import fit_notes, wheelbase_source

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
            f"wheelbase: {fit['wheelbase_mm']:.0f} mm ({wheelbase_source(fit)})",
        ]
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
        if s is None:
            lines.append(f"no body: {report['error']}")
        else:
            lines.append(f"body: {s['faces']} Bezier faces in one shell, valid={s.get('valid')}, "
                         f"open only at {s.get('free_closed_loops')} closed bottom loop(s)")
        lines.append("times: " + ", ".join(f"{k} {v:.2f} s" for k, v in report["timings_s"].items()))
        return "\n".join(lines) + "\n"

    def write(self, out_dir: str | Path, truth=None) -> dict[str, Path]:
        """Write every output into ``out_dir`` (created if needed); all or nothing.

        Files (:data:`OUTPUT_FILES`): ``wireframe.step`` (both halves, named B-spline edges),
        ``body.step`` (one shell, faces named and coloured by region), ``car.step`` (one AP214
        assembly with the parts ``wireframe`` and ``body``), ``overlay.png`` (photo, annotated red
        and reprojected green keypoints, projected wireframe), ``body.png`` (shaded body, three
        views), ``report.json`` and ``summary.txt``. They are written into a staging folder in
        ``out_dir`` and moved into place together (:func:`carbody.outputs.staged`): on a full
        disk or any failure the folder's earlier files stay as they were, and a folder this call
        created is removed again if nothing else is in it.

        Raises:
            OutputError: the folder or one of the files in it cannot be written, or one of them
                is the photo or the keypoint file.
        """
        out = self._write_files(out_dir, truth, OUTPUT_FILES)
        keys = ("wireframe", "body", "assembly", "overlay", "render", "report", "summary")
        return {key: out / name for key, name in zip(keys, OUTPUT_FILES)}

    def write_failed(self, out_dir: str | Path, truth=None) -> list[Path]:
        """Write what shows why a run failed after its fit (``body`` None): ``overlay.png``,
        ``report.json`` (``outcome`` "failed", ``error``) and ``summary.txt``, all or nothing;
        the other :data:`OUTPUT_FILES` an earlier run left in the folder are taken away with it,
        so that none is taken for this run's. Returns the files written."""
        out = self._write_files(out_dir, truth, FAILED_FILES)
        return [out / name for name in FAILED_FILES]

    def _write_files(self, out_dir: str | Path, truth, names: tuple[str, ...]) -> Path:
        """Write ``names`` (of :data:`OUTPUT_FILES`) into ``out_dir`` through one staging folder,
        taking away the folder's other outputs; returns the folder."""
        from carbody.outputs import output_folder, staged

        with output_folder(out_dir) as out:
            check_output_dir(out, inputs={"the photo": self.image_path})
            with staged([out / n for n in names], remove=[out / n for n in OUTPUT_FILES if n not in names]) as at:
                self._write_all(lambda name: at(out / name), truth, names)
        return out

    def _write_all(self, at: Callable[[str], Path], truth, names: tuple[str, ...]) -> None:
        """Write ``names``, each where ``at(its name)`` says."""
        from carbody.fit.overlay import draw_overlay, write_image

        start = time.perf_counter()
        if "body.step" in names:
            from carbody.render import render_views
            from carbody.surface.body import write_body
            from carbody.wireframe import write_wireframe

            write_wireframe(at("wireframe.step"), self.wireframe, both_halves=True)
            write_body(at("body.step"), self.body)
            write_assembly(at("car.step"), self)
            render_views(self.body, at("body.png"), size=(480, 340))
        # the overlay is drawn with OpenCV, which works in BGR
        write_image(at("overlay.png"), draw_overlay(self.image[..., ::-1].copy(), self.fit))
        self.timings_s["write"] = time.perf_counter() - start
        report = self.report(truth)
        report["files"] = sorted(names)
        at("report.json").write_text(json.dumps(report, indent=1))
        at("summary.txt").write_text(self.summary(report))


#: The files :meth:`Reconstruction.write` puts into its folder.
OUTPUT_FILES = ("wireframe.step", "body.step", "car.step", "overlay.png", "body.png", "report.json", "summary.txt")
#: What :meth:`Reconstruction.write_failed` puts there: what shows why a run failed after its fit.
FAILED_FILES = ("overlay.png", "report.json", "summary.txt")


def prepare_output_dir(out_dir: str | Path) -> Path:
    """Create ``out_dir`` (and its parents) if needed and make sure it can be written, before
    any long work (a batch's folder, whose photos each get a folder of their own).

    Raises:
        OutputError: the folder cannot be created or written.
    """
    import tempfile

    from carbody.outputs import STAGING_PREFIX

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=STAGING_PREFIX, suffix=".probe"):
            pass
    except OSError as exc:
        raise OutputError(f"{out}: cannot write the output folder ({exc.strerror or exc})") from None
    return out


def check_output_dir(out_dir: str | Path, inputs: dict[str, str | Path | None] | None = None) -> Path:
    """Check, before any long work, that the folder ``out_dir`` and each of
    :data:`OUTPUT_FILES` in it can be written, and that none of them is one of ``inputs``
    ({what: path}: the photo, the keypoint file, the ground truth).

    Raises:
        OutputError: naming the folder or the file.
    """
    from carbody.outputs import check_not_inputs, check_output_file

    out = Path(out_dir)
    if not out.is_dir():
        raise OutputError(f"{out}: the output folder does not exist" if not out.exists()
                          else f"{out}: not a folder")
    targets = {f"the output {name}": out / name for name in OUTPUT_FILES}
    for path in targets.values():
        check_output_file(path)
    check_not_inputs(targets, inputs or {})
    return out


def write_assembly(path: Path, result: Reconstruction) -> Path:
    """One AP214 file holding the wireframe and the body as named parts of an assembly: every
    curve and face named as in wireframe.step and body.step (``carbody parts`` lists them)."""
    from carbody.occ.shapes import sub_shapes
    from carbody.occ.step_assembly import AssemblyPart, write_assembly_step
    from carbody.surface.body import face_names, region_colour

    curves = result.wireframe.named_curves(both_halves=True)
    wire_shape = result.wireframe_shape()
    wire = AssemblyPart("wireframe", wire_shape, (0.1, 0.2, 0.6),
                        [(name, edge, None) for (name, _), edge in zip(curves, sub_shapes(wire_shape, "edge"))])
    body = AssemblyPart("body", result.body_shape(), (0.7, 0.7, 0.72),
                        [(name, face, region_colour(patch.region))
                         for name, patch, (_, face) in zip(face_names(result.body), result.body.patches,
                                                           result.body.faces)])
    return write_assembly_step(path, result.name, [wire, body], OutputError)


def _read_inputs(image, keypoints):
    """(RGB image, its path or None, annotation) with sizes checked against each other."""
    from carbody.fit.keypoints_io import Annotation, check_image_size, check_keypoints, read_keypoints
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
    check_keypoints(ann.points, (w, h))  # as the fit will, but before the classifier crops to them
    return rgb, image_path, ann


def _check_arguments(wheelbase_mm, name, library, reject_outliers, force=False, on_stage=None) -> None:
    """Refuse, before any work, the arguments of :func:`reconstruct` its stages would only meet
    later (the view, the camera and the fit options are checked where they are read, also first)."""
    from carbody.fit.options import check_wheelbase
    from carbody.library import check_library

    check_wheelbase(wheelbase_mm)
    check_library(library)
    if name is not None and not isinstance(name, str):
        raise CarbodyError(f"the car's name must be a string, got {name!r}")
    if not isinstance(reject_outliers, (bool, np.bool_)):
        raise CarbodyError(f"reject_outliers must be True or False, got {reject_outliers!r}")
    if not isinstance(force, bool):
        raise CarbodyError(f"force must be True or False, got {force!r}")
    if on_stage is not None and not callable(on_stage):
        raise CarbodyError(f"on_stage must be a function of the stage's name, got {on_stage!r}")


def reconstruct(image, keypoints, view: float | str | None = None, wheelbase_mm: float | None = None, *,
                elevation_deg: float = 0.0, camera_distance_mm: float | str | None = "auto",
                principal_point: str | tuple[float, float] = "auto", focal_35mm: float | None = None,
                name: str | None = None, library=None, reject_outliers: bool = True,
                view_prior_weight: float = 1.0, outline: bool = False, wheels: bool = True, force: bool = False,
                on_stage: Callable[[str], None] | None = None) -> Reconstruction:
    """Photo + keypoints -> the car's wireframe and sewn body.

    Args:
        image: photo path or (h, w[, c]) uint8 array (grayscale and RGBA work).
        keypoints: keypoint file (the project's JSON, COCO or labelme) or {name: (u, v)} pixels.
        view: azimuth in degrees (0 front, 90 left side, 180 rear, 270 right side) or a name
            (``"front 30"``, ``"front 30 right"``: :func:`carbody.camera.read_view`): a prior on
            the fit's search over every view; None takes the shipped view classifier's
            probabilities as that prior.
        wheelbase_mm: the car's real wheelbase; None: from the fitted car's proportions.
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
        outline: cut the car out of the photo and fit its outline with the marks
            (:mod:`carbody.fit.outline`); False: the marks alone.
        wheels: find the wheels' hubs in the photo and fit them with the marks
            (:mod:`carbody.fit.wheels`); False: the marks alone.
        force: give the car even when the fit explains the marks badly.
        on_stage: called with each stage's name as it starts (progress display).

    Raises:
        carbody.errors.FitRefused: the fit explains the marks badly
            (:func:`carbody.fit.report.refusal_line`: how, and which marks) and ``force`` is false.
        carbody.errors.CarbodyError: any bad input, in one line (unreadable image, keypoints that
            do not fit the image, a view outside 0-360, too few or degenerate keypoints, ...).
            An error raised after the fit (a refusal, a body that cannot be surfaced) carries
            ``partial``: the :class:`Reconstruction` without a body, whose
            :meth:`~Reconstruction.write_failed` writes its overlay and report.
    """
    from carbody.camera import View, read_view
    from carbody.fit import FitOptions, ViewPrior, fit_wireframe
    from carbody.library import default_library
    from carbody.fit.fit_camera import principal_point_px
    from carbody.fit.focal import focal_length_px
    from carbody.fit.report import refusal_line
    from carbody.surface import build_body

    timings: dict[str, float] = {}
    rgb, image_path, ann = _read_inputs(image, keypoints)
    h, w = rgb.shape[:2]
    _check_arguments(wheelbase_mm, name, library, reject_outliers, force, on_stage)
    name = name or (image_path.stem if image_path else "car")
    options = FitOptions(camera_distance_mm=camera_distance_mm, principal_point=principal_point,
                         robust=reject_outliers, check_orthographic=True, view_prior_weight=view_prior_weight,
                         outline=outline, wheels=wheels)
    View(0.0, elevation_deg)  # an elevation the view's prior cannot take, refused before the classifier runs
    prior = None if view is None else View(read_view(view), elevation_deg)
    focal, _ = focal_length_px(image_path, (w, h), focal_35mm)
    principal_point_px(principal_point, (w, h), focal)  # refused here, not after the classifier ran

    def stage(label: str):
        if on_stage:
            on_stage(label)
        return time.perf_counter()

    start = time.perf_counter()
    _load_libraries()
    timings["load"] = time.perf_counter() - start

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
    options = options.with_changes(focal_px=focal)

    def fit_with(points: dict, **stiffer):
        return fit_wireframe(points, prior, library or default_library(), image_size=(w, h),
                             wheelbase_mm=wheelbase_mm, options=options.with_changes(**stiffer), name=name,
                             photo=rgb)

    fit = fit_with(ann.points)
    timings["fit"] = time.perf_counter() - start

    def failed(exc: CarbodyError) -> CarbodyError:
        """``exc`` carrying what was made before it (``partial``: its overlay and report)."""
        exc.partial = Reconstruction(name, rgb, image_path, source, prediction, fit, None, timings, None, str(exc))
        return exc

    refused = None if force else refusal_line(fit)
    if refused:
        raise failed(FitRefused(refused))

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
            raise failed(exc) from None
    timings["surfaces"] = time.perf_counter() - start
    return Reconstruction(name, rgb, image_path, source, prediction, fit, body, timings, fallback)


def _load_libraries() -> None:
    """Load what the fit and the surfaces use, once per process: OCCT (one large library, loaded
    by its first module) and scipy's optimisers. In a fresh process this costs about 1.1 s of CPU
    (docs/real_photos.md); timed apart, the stages' times are a photo's own work."""
    import OCP.TopoDS  # noqa: F401
    import scipy.optimize  # noqa: F401


def _blended_toward(fit, stiff, stiff_body):
    """(fit, body, share): the largest share of ``fit`` blended with ``stiff`` (control points in
    the car frame, and wheelbases) whose body still surfaces (``BLEND_HALVINGS``), seen by the
    camera of either that puts it nearer the marks; ``stiff`` itself (share 0) when none does.
    Crossing is gradual in the share, so much of the fit's match to the marks is kept where only
    a corner of it crossed (docs/end_to_end.md: 12–88 % kept, 70–232 mm against
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

