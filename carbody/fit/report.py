"""The fit report (paper Fig. 12–13): refined view, fitted 3D keypoints, reprojection residuals,
top weights and, against a ground truth, the 3D error per keypoint with a bar chart.

With a truth, ``error_mm`` compares the output as written (its wheelbase included) and
``error_mm_at_truth_wheelbase`` the shape alone at the truth's wheelbase (the benchmark's
measure). With the Gaussian-prior methods the weights are affine (ΣH = 1, some negative).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from carbody.topology import load_topology
from carbody.wireframe import Wireframe


def keypoint_errors_mm(fitted: Wireframe, truth: Wireframe, at_truth_wheelbase: bool = False) -> dict[str, float]:
    """{keypoint: distance mm} between the 35 keypoints of two wireframes (same car frame).

    Args:
        at_truth_wheelbase: compare shapes only: both normalised (wheel centres at (0, 0) and
            (1000, 0)) and scaled to the truth's wheelbase, as the leave-one-out benchmark does;
            otherwise the error includes the fitted wheelbase's.
    """
    from carbody.library import normalise

    topo = load_topology()
    idx = topo.keypoint_point_indices
    a, b = fitted.control_points, truth.control_points
    if at_truth_wheelbase:
        wb = truth.measure()["wheelbase_mm"] / 1000.0
        a, b = normalise(a, topo) * wb, normalise(b, topo) * wb
    d = np.linalg.norm(a[idx] - b[idx], axis=1)
    return {k.name: float(e) for k, e in zip(topo.keypoints, d)}


def build_report(result, truth: Wireframe | None = None, top: int = 10, image: str | Path | None = None) -> dict:
    """The report as a JSON-ready dict (see module docstring); lengths in mm, residuals in px.
    ``image``: the photo's file, to say where it stands lined up with the car (``photo_plane``)."""
    from carbody.fit.photo_plane import fitted_plane
    from carbody.fit.visibility import visible_keypoints

    res = result.residuals_px()
    diagnostics = result.diagnostics
    from carbody.errors import AngleError

    try:
        visible = visible_keypoints(result.view.scaled(result.mm_per_unit), result.wireframe.control_points)
    except AngleError:  # a car bent by marks that contradict each other round the camera: none known
        visible = [s.name for s in result.slots]
    report = {
        "method": result.method,
        "given_view": None if result.given_view is None else result.given_view.as_dict(),
        "refined_view": result.view.as_dict(),
        "image_scale_px_per_mm": result.solution.scale / result.mm_per_unit,
        "camera_distance_mm": result.camera_distance_mm,
        # a car off an uncropped photo's centre: the camera turned to it (scale and offset
        # above are then the turned camera's)
        "camera_turn_deg": result.camera_turn_deg,
        "camera_turn_diverged": result.camera_turn_diverged,
        "focal_length_px": result.focal_px,
        "image_offset_px": [float(v) for v in result.solution.offset],
        # everything needed to project car-frame points (mm) into the photo again
        # (:func:`project_with_camera`): the benchmarks draw regions and wheels with it
        "camera": camera_report(result),
        "wheelbase_mm": result.wheelbase_mm,
        # "told", "camera distance", "proportions" (carbody.fit.size) or "library mix" (paper)
        "wheelbase_from": result.wheelbase_from,
        # what the car's proportions say of its size: the wheelbase and its spread (% one
        # standard deviation); and the fitted mix's own wheelbase
        "size": None if result.size is None else result.size.as_dict(),
        "wheelbase_by_mix_mm": result.wheelbase_by_mix_mm,
        "keypoints_annotated": len(result.slots),
        "keypoints_mm": result.keypoints_mm(),
        "residual_px": res,
        "residual_px_mean": float(np.mean(list(res.values()))),
        "residual_px_max": float(np.max(list(res.values()))),
        # −log evidence per marked coordinate (None: the paper's solve); fits_poorly: above the
        # level no sound fit reaches (marks named wrongly, a view kept far off)
        "evidence_per_coordinate": diagnostics.evidence_per_coordinate,
        "fits_poorly": diagnostics.fits_poorly,
        # the car passes further from the marks, on average, than 5 % of their spread
        "misses_marks": diagnostics.misses_marks,
        "visible_at_refined_view": visible,
        "annotated_but_hidden": [s.name for s in result.slots if s.name not in visible],
        "suspect_keypoints": list(diagnostics.suspect),
        # marks left out: {name: px the fitted car passes from it}, why ("hidden": the view found
        # cannot see it; "misplaced": the other marks put it elsewhere), and the keypoint the car
        # puts where one was clicked, when one is near
        "rejected_keypoints": {n: m.px for n, m in diagnostics.rejected.items()},
        "rejected_reasons": {n: m.reason for n, m in diagnostics.rejected.items()},
        "rejected_looks_like": {n: m.looks_like for n, m in diagnostics.rejected.items() if m.looks_like},
        # marks read under another name ({as clicked: as fitted}): a left/right pair exchanged, or
        # a mark read under its twin's name; the exchanged pair, or None
        "renamed_keypoints": dict(diagnostics.renamed),
        "swapped_keypoints": None if diagnostics.swapped is None else list(diagnostics.swapped),
        "deformation_mm_max": result.deformation_mm,
        # the car's outline in the photo fitted with the marks: used or why not, how many outline
        # points the last solve used, their median distance to the car's edge before and after
        "outline": None if result.outline is None else result.outline.as_dict(),
        # the wheels' hubs found in the photo and fitted with the marks: each hub's pixel, score,
        # robust weight, and the fitted hub's distance from it before and after
        "wheels": None if result.wheels is None else result.wheels.as_dict(),
        "top_weights": result.top_weights(top),
        "template_mix": result.template_mix(),
        # the templates the fit mixed (fewer than 14 when some were excluded)
        "library_templates": list(result.library.template_names),
        # the photo as an image plane behind the car, square to the fitted camera (mm; a CAD
        # viewer looking along the camera sees the wireframe on it)
        "photo_plane": None if image is None else fitted_plane(result, image).as_dict(),
        # an orthographic fit asked to check: its marks fitted with the camera's distance found
        # (closer_camera: that camera fits them far better), or None
        "orthographic_check": diagnostics.closer_camera,
        # what the view search saw (the prior, the best views scanned, the best one's margin over
        # the next, nats), or None for a view kept as given; the solves the fit took
        "view_search": diagnostics.view_search,
        "solves": diagnostics.solves,
    }
    sd = result.keypoint_sd_mm()
    if sd is not None:
        # the fit's own estimate of how far each keypoint may be off (posterior standard
        # deviations per axis, and their 3D root sum of squares); docs/fit_accuracy.md compares it
        # with the leave-one-out errors
        expected = result.expected_error_mm(sd)
        report["keypoint_sd_mm"] = sd
        # (a marked right-half keypoint has its left twin's)
        report["expected_error_mm"] = {**expected, **{n: float(np.linalg.norm(v)) for n, v in sd.items()
                                                      if n not in expected}}
        report["expected_error_mm_mean"] = float(np.mean(list(expected.values())))  # over the 35
    if truth is not None:
        err = keypoint_errors_mm(result.wireframe, truth)
        report["truth"] = truth.name
        report["error_mm"] = err
        report["error_mm_mean"] = float(np.mean(list(err.values())))
        report["error_mm_max"] = float(np.max(list(err.values())))
        annotated = {s.name.removesuffix("_right") for s in result.slots}
        report["error_mm_annotated_mean"] = float(np.mean([err[n] for n in annotated]))
        shape_err = keypoint_errors_mm(result.wireframe, truth, at_truth_wheelbase=True)
        report["truth_wheelbase_mm"] = float(truth.measure()["wheelbase_mm"])
        report["error_mm_at_truth_wheelbase"] = shape_err
        report["error_mm_at_truth_wheelbase_mean"] = float(np.mean(list(shape_err.values())))
        report["error_mm_at_truth_wheelbase_max"] = float(np.max(list(shape_err.values())))
    return report


def camera_report(result) -> dict:
    """The fitted camera as JSON-ready data: the view (degrees), the pinhole's distance and aim
    (mm; None for the orthographic camera), the image scale (px per mm) and offset (px), and the
    homography from the fitted camera's pixels to the photo's (None: no turn)."""
    view, unit = result.view, result.mm_per_unit
    return {"azimuth_deg": float(view.azimuth), "elevation_deg": float(view.elevation),
            "roll_deg": float(view.roll),
            "distance_mm": None if view.distance is None else float(view.distance * unit),
            "aim_mm": [float(a * unit) for a in view.aim],
            "scale_px_per_mm": float(result.solution.scale / unit),
            "offset_px": [float(v) for v in result.solution.offset],
            "to_photo": None if result.to_photo is None else np.asarray(result.to_photo).tolist()}


def camera_view(camera: dict):
    """The :class:`~carbody.camera.View` of a report's ``camera`` (:func:`camera_report`)."""
    from carbody.camera import View

    return View(camera["azimuth_deg"], camera["elevation_deg"], camera["roll_deg"], camera["distance_mm"],
                tuple(camera["aim_mm"]))


def project_with_camera(camera: dict, points_mm: np.ndarray) -> np.ndarray:
    """(..., 2) photo pixels of car-frame points (mm) under a report's ``camera``
    (:func:`camera_report`): what :meth:`carbody.fit.FitResult.project_points` gives."""
    from carbody.camera import apply_homography, project

    uv = project(np.asarray(points_mm, dtype=float), camera_view(camera), camera["scale_px_per_mm"],
                 camera["offset_px"])
    return uv if camera["to_photo"] is None else apply_homography(np.asarray(camera["to_photo"]), uv)


def fit_notes(report: dict) -> list[str]:
    """The lines a person reads after a fit, from its report (:func:`build_report`): the fit's
    own expected error, then notes on marks left out or renamed, marks no car fits, a photo
    taken from close by, a camera not turned to an off-centre car, marks the fitted car passes
    far from, and marks the fitted geometry hides. ``carbody fit`` prints them; ``carbody
    reconstruct``'s summary carries them."""
    lines = []
    if "expected_error_mm" in report:
        lines.append(expected_error_line(report["expected_error_mm"]))
    notes = marks_notes(report["rejected_keypoints"], report["rejected_looks_like"], report["renamed_keypoints"],
                        report.get("rejected_reasons", {}))
    if report["fits_poorly"]:
        notes.append(poor_fit_line(report["evidence_per_coordinate"], report["residual_px_mean"]))
    elif report["misses_marks"]:
        notes.append(f"the fitted car misses the marks by {report['residual_px_mean']:.0f} px on average: "
                     "the wireframe is not to be trusted; check the marks' names and places, and the view given")
    if (report["orthographic_check"] or {}).get("closer_camera"):
        notes.append(closer_camera_line(report["orthographic_check"]))
    if report.get("camera_turn_diverged"):
        notes.append("the camera was not turned to the car off the photo's centre: each turn aimed further off "
                     "it, as with a focal length the photo's camera did not have (a cropped, resized or zoomed "
                     "photo); fitted as if the camera looked at the car")
    if report["suspect_keypoints"]:
        notes.append("the fitted car passes far from " + ", ".join(
            f"{n} ({report['residual_px'][n]:.0f} px)" for n in report["suspect_keypoints"])
            + ": check those marks (place, left/right name)")
    if report["annotated_but_hidden"]:
        notes.append(f"by the fitted geometry {', '.join(report['annotated_but_hidden'])} may be hidden at this "
                     "view (check the left/right names)")
    return lines + ["note: " + n for n in notes]


#: The size's summary names the class of car its proportions read as when it weighs this much,
#: else the two likeliest when together they do.
READ_AS_SHARE = 0.5


def wheelbase_source(report: dict) -> str:
    """Where the report's wheelbase came from, for a person: ``"told"``, ``"camera distance"``,
    ``"library mix"``, or from the proportions with the estimate's spread and the classes of car
    the table reads them as (``READ_AS_SHARE``)."""
    size = report.get("size")
    if report["wheelbase_from"] == "proportions" and size is not None:
        top = list((size.get("classes") or {}).items())[:2]
        if top and top[0][1] >= READ_AS_SHARE:
            top = top[:1]
        read_as = ", read as " + " or ".join(f"{k.replace('_', ' ')} {100 * v:.0f} %" for k, v in top) \
            if top and sum(v for _, v in top) >= READ_AS_SHARE else ""
        return f"from its proportions, ±{size['spread_pct']:.0f} %{read_as}; give --wheelbase if known"
    return report["wheelbase_from"]


def marks_notes(rejected_px: dict[str, float], looks_like: dict[str, str], renamed: dict[str, str],
                reasons: dict[str, str] | None = None) -> list[str]:
    """Lines for a person about marks the fit left out or read under another name (the report's
    ``rejected_keypoints``, ``rejected_looks_like``, ``renamed_keypoints``, ``rejected_reasons``)."""
    from carbody.fit.diagnostics import HIDDEN

    reasons = reasons or {}
    lines = []
    swapped = sorted(a for a, b in renamed.items() if renamed.get(b) == a)
    if len(swapped) == 2:
        lines.append(f"{swapped[0]} and {swapped[1]} fit with their names exchanged (the car's left is "
                     "the viewer's right seen from the front): fitted so")
    for a, b in renamed.items():
        if renamed.get(b) != a:
            lines.append(f"{a} fits as {b}, its left/right twin: fitted so (check its name)")

    def listed(names):
        return ", ".join(f"{n} ({rejected_px[n]:.0f} px from the car the other marks give"
                         + (f"; where it puts {looks_like[n]}" if n in looks_like else "") + ")" for n in names)

    hidden = [n for n in rejected_px if reasons.get(n) == HIDDEN]
    misplaced = [n for n in rejected_px if n not in hidden]
    if misplaced:
        lines.append("left out as misplaced: " + listed(misplaced) + ": check those marks")
    if hidden:
        lines.append("left out, the view found cannot see them: " + listed(hidden)
                     + ": check their left/right names")
    return lines


def refusal_line(result) -> str | None:
    """One line saying why a fit is not to be given out, naming the marks the car passes
    furthest from, or, told a distant camera, the close one that fits them (``closer_camera``);
    None unless the marks contradict each other (``contradicts`` of
    :class:`~carbody.fit.diagnostics.FitDiagnostics`: a fit that merely fits poorly, a car the
    library lacks, is given out with a note)."""
    from carbody.fit.solve import keypoint_spread

    diagnostics = result.diagnostics
    if diagnostics is None or not diagnostics.contradicts:
        return None
    evidence = diagnostics.evidence_per_coordinate
    if diagnostics.camera_closer:  # told a distant camera, the marks show one close by
        return (f"no distant camera fits the marks (−log evidence {evidence:.0f} per coordinate, where a photo's "
                f"own marks stay under 10): the photo looks taken from close by, a camera "
                f"{diagnostics.closer_camera['camera_distance_mm'] / 1000:.1f} m from the car fits them: "
                "--distance auto finds it (--force gives the car anyway)")
    residual = result.residuals_px()
    mean = float(np.mean(list(residual.values())))
    worst = sorted(residual, key=lambda n: -residual[n])[:3]
    why = (f"the marks contradict each other: no car fits them (−log evidence {evidence:.0f} per coordinate, "
           f"where a photo's own marks stay under 10)" if diagnostics.fits_poorly
           else f"the fitted car misses the marks by {mean:.0f} px on average "
                f"({100 * mean / keypoint_spread(result.uv):.0f} % of their spread)")
    return (f"{why}; furthest: " + ", ".join(f"{n} ({residual[n]:.0f} px)" for n in worst)
            + ": check those marks' names and places (--force gives the car anyway)")


def poor_fit_line(evidence_per_coordinate: float, residual_px_mean: float) -> str:
    """One line for a person: no car near the view found fits the marks (the report's ``fits_poorly``)."""
    return (f"no car fits the marks (mean residual {residual_px_mean:.1f} px, −log evidence "
            f"{evidence_per_coordinate:.0f} per coordinate, where fits at a photo's own view stay under 10): the "
            "wireframe is not to be trusted; check the marks' names and places")


def closer_camera_line(closer: dict) -> str:
    """One line for a person: an orthographic fit's marks show a camera close by (the
    report's ``orthographic_check`` when its ``closer_camera`` is true)."""
    return (f"the photo looks taken from close by: a camera {closer['camera_distance_mm'] / 1000:.1f} m from the "
            f"car fits the marks far better than a distant one (the library's mix misses them by "
            f"{closer['residual_px_mean']:.1f} px on average against {closer['orthographic_residual_px_mean']:.1f} px, "
            "with a likelier car and view); fitted as orthographic the car comes out distorted: "
            "--distance auto finds the camera")


def expected_error_line(expected_mm: dict[str, float]) -> str:
    """One line for a person: the mean of the fit's expected keypoint errors and the three
    keypoints it is least sure of (``FitResult.expected_error_mm``, the report's
    ``expected_error_mm``)."""
    from carbody.wireframe import RIGHT_SUFFIX

    expected_mm = {n: e for n, e in expected_mm.items() if not n.endswith(RIGHT_SUFFIX)}  # the 35
    least = sorted(expected_mm, key=lambda n: -expected_mm[n])[:3]
    return (f"expected 3D keypoint error (the fit's own estimate): mean "
            f"{np.mean(list(expected_mm.values())):.0f} mm; least sure: "
            + ", ".join(f"{n} ({expected_mm[n]:.0f} mm)" for n in least))


def write_json(path: str | Path, data: dict) -> Path:
    """Write JSON atomically."""
    from carbody.occ.step_curves import atomic_write

    text = json.dumps(data, indent=1)
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def draw_error_chart(errors_mm: dict[str, float], path: str | Path, title: str = "",
                     annotated: set[str] | None = None, expected_mm: dict[str, float] | None = None) -> Path:
    """Bar chart of the 3D error per keypoint (paper Fig. 12–13); annotated keypoints dark;
    the fit's own expected error, when given, as a marker on each bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from carbody.occ.step_curves import atomic_write

    topo = load_topology()
    names = [k.name for k in topo.keypoints]
    vals = [errors_mm[n] for n in names]
    colours = ["#1f4e9c" if annotated is None or n in annotated else "#9fb3d6" for n in names]
    fig, ax = plt.subplots(figsize=(11, 4))
    ax.bar([k.id for k in topo.keypoints], vals, color=colours, label="error vs truth")
    if expected_mm is not None:
        ax.plot([k.id for k in topo.keypoints], [expected_mm[n] for n in names], "_", color="#d62728",
                markersize=14, markeredgewidth=2.5, label="expected by the fit")
        ax.legend(loc="upper right")
    ax.set_xticks([k.id for k in topo.keypoints])
    ax.set_xlabel("keypoint (Fig. 6 number; dark = annotated)")
    ax.set_ylabel("3D error (mm)")
    ax.set_title(title or f"keypoint error: mean {np.mean(vals):.1f} mm, max {np.max(vals):.1f} mm")
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110))
    finally:
        plt.close(fig)
