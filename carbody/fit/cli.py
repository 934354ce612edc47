"""``carbody fit`` (photo + keypoints + view → wireframe STEP, overlay, report) and
``carbody visible-keypoints`` (which keypoints a view can see)."""
from __future__ import annotations

import argparse
from pathlib import Path

from carbody.fit.solve import METHODS


def add_marks_argument(p: argparse.ArgumentParser) -> None:
    """``--keep-marks``, ``--view-weight``, ``--outline``, ``--wheels`` and ``--force``, shared by ``fit`` and
    ``reconstruct``."""
    p.add_argument("--force", action="store_true",
                   help="give the car even when it explains the marks badly (by default such a fit "
                        "exits 2 naming the marks and writes only what shows why: overlay, report, summary)")
    p.add_argument("--keep-marks", action="store_true",
                   help="fit every mark as named: do not leave out marks the others say are "
                        "misplaced, nor read a mark left out under its left/right twin's name")
    p.add_argument("--view-weight", type=float, default=1.0, metavar="W",
                   help="how strongly the view given (or the classifier's) counts in the search over "
                        "every view: a factor on its prior (default 1; 0: the marks alone decide)")
    p.add_argument("--outline", action=argparse.BooleanOptionalAction, default=False,
                   help="also cut the car out of the photo and fit its outline with the marks "
                        "(default off, --no-outline: the marks alone; docs/outline.md)")
    p.add_argument("--wheels", action=argparse.BooleanOptionalAction, default=True,
                   help="find the wheels' hubs in the photo and fit them with the marks (default "
                        "on; --no-wheels: the marks alone; docs/wheels.md)")


def add_camera_arguments(p: argparse.ArgumentParser) -> None:
    """The photo's camera options, shared by ``fit`` and ``reconstruct``."""
    p.add_argument("--distance", default="auto", metavar="MM|auto|orthographic",
                   help="how far the camera stood from the car's centre, mm (a photo from a few "
                        "metres shows nearer parts larger; without --wheelbase it also gives the "
                        "car's size), 'auto' to find it (default), or 'orthographic' for a "
                        "distant camera (SPEC's)")
    p.add_argument("--principal-point", default="auto", choices=("auto", "car", "centre"),
                   help="where the camera's optical axis meets the photo: 'car' (the camera "
                        "pointed at the car, or the photo cropped around it), 'centre' (an "
                        "uncropped photo with the car off its centre: the fit corrects the "
                        "obliquity; fastest with --distance MM or a focal length), or 'auto' "
                        "(default): 'centre' when the focal length is known, else 'car'")
    p.add_argument("--focal-35mm", type=float, default=None, metavar="MM",
                   help="the camera's focal length, 35 mm-equivalent mm (a phone's main camera: "
                        "about 26), for the uncropped photo: the camera turns to an off-centre "
                        "car by it. Default: the photo's EXIF, when it has one and the photo is "
                        "not cropped or resized")


def parse_distance(text: str | None) -> float | str | None:
    """``--distance``: None or "orthographic" (orthographic), "auto" or a positive number of mm."""
    from carbody.errors import FitError

    if text is None or text == "orthographic":
        return None
    if text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        raise FitError(f"--distance {text!r} is neither a number of mm, 'auto' nor 'orthographic'") from None
    if not (value > 0 and value < float("inf")):
        raise FitError(f"--distance {text!r} is not a positive number of mm")
    return value


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit", help="fit the car's 3D wireframe to keypoints marked on one photo",
        description="Mix the library's models into the car seen on IMAGE (paper III.D): solve the "
                    "weights and the image's scale and offset at the given view, refine the view, "
                    "and write the wireframe (both halves, named B-spline edges, mm) as STEP.")
    p.add_argument("image", help="the photo (PNG, JPEG, ...)")
    p.add_argument("--keypoints", "-k", required=True,
                   help="keypoint file: project JSON, COCO keypoints or labelme")
    p.add_argument("--view", default=None,
                   help="view azimuth, degrees 0–360 (0 front, 90 left side), or a name: 'front 30', "
                        "'side', 'rear 30', 'front 30 right'; a prior on the search over every view "
                        "(default: none, the marks alone decide); needed with --no-refine")
    p.add_argument("--elevation", type=float, default=0.0,
                   help="camera elevation told, degrees (default 0: a prior, searched unless --no-refine)")
    p.add_argument("--roll", type=float, default=0.0,
                   help="camera roll of a tilted photo, degrees within ±90 (default 0: a prior of ±2°, "
                        "refined with the view unless --no-refine)")
    p.add_argument("--wheelbase", type=float, default=None,
                   help="real wheelbase, mm (default: from the fitted car's proportions); "
                        "told, the fit also knows the car's width and height in mm")
    p.add_argument("--exclude-template", action="append", default=[], metavar="NAME",
                   help="drop a template and its expansions from the library (repeatable)")
    p.add_argument("--method", choices=METHODS, default=METHODS[0],
                   help="mixture: Gaussian shape prior around each template (default); gauss: one "
                        "Gaussian around the library mean; paper: the paper's plain ΣH=1, 0≤H≤1")
    add_camera_arguments(p)
    p.add_argument("--no-refine", action="store_true",
                   help="keep the given view as it is, no search (an 'auto' distance is still found)")
    p.add_argument("--no-deform", action="store_true",
                   help="skip the smooth move onto the marked keypoints after the solve (the "
                        "solve's own along-the-car field stays)")
    add_marks_argument(p)
    p.add_argument("--output", "-o", required=True, help="wireframe STEP file to write")
    p.add_argument("--overlay", help="PNG: photo + annotated (red) / reprojected (green) keypoints + wireframe")
    p.add_argument("--report", help="JSON report: view, 3D keypoints, residuals, weights, errors")
    p.add_argument("--uncertainty", metavar="PNG",
                   help="four-view drawing of the fitted wireframe with each keypoint's expected "
                        "error as a 1σ ellipse (not with --method paper)")
    p.add_argument("--truth", help="ground truth (template name or wireframe STEP), with --report: adds the 3D "
                                   "error per keypoint to the report and an error bar chart (REPORT.errors.png)")
    p.add_argument("--name", default=None, help="product name in the STEP file (default: image stem)")
    p.set_defaults(func=run_fit)

    pp = sub.add_parser("photo-plane", help="where a photo stands in the car's frame, as JSON (for a CAD viewer)",
                        description="The photo upright in the car's side plane, seen from the car's "
                                    "left, as an image plane: centre, the stored picture's axes and "
                                    "size in mm (EXIF-turned photos included). A fit's report gives "
                                    "the plane lined up with the fitted camera (photo_plane).")
    pp.add_argument("image", help="the photo (PNG or JPEG)")
    pp.add_argument("--width", type=float, default=5000.0, help="the upright picture's width, mm (default 5000)")
    pp.set_defaults(func=run_photo_plane)

    v = sub.add_parser("visible-keypoints", help="list the keypoints a view can see",
                       description="Keypoints visible at a view, from the wireframe geometry "
                                   "(region normals and occlusion) of the library's mean car.")
    v.add_argument("--view", required=True, help="view azimuth, degrees 0–360, or a name ('rear 30')")
    v.add_argument("--elevation", type=float, default=0.0, help="camera elevation, degrees")
    v.add_argument("--template", default=None, help="use this template's geometry instead of the mean")
    v.add_argument("--distance", default="orthographic", metavar="MM|orthographic",
                   help="a photo's camera distance from the car's centre, mm (a close camera sees "
                        "less of the faces turned away); default SPEC's orthographic camera")
    v.set_defaults(func=run_visible)


def load_truth(spec: str):
    """``--truth``: a ground-truth wireframe from a STEP file (``.step``/``.stp``) or a template name."""
    from carbody.templates import load_template
    from carbody.wireframe import read_wireframe

    return read_wireframe(spec) if Path(spec).suffix.lower() in (".step", ".stp") else load_template(spec)


def run_photo_plane(args: argparse.Namespace) -> int:
    import json
    import math

    from carbody.errors import FitError
    from carbody.fit.photo_plane import side_plane

    if not (math.isfinite(args.width) and args.width > 0):
        raise FitError(f"--width {args.width:g} mm is not a positive size")
    print(json.dumps(side_plane(args.image, args.width).as_dict()))
    return 0


def run_fit(args: argparse.Namespace) -> int:
    from carbody.errors import FitError
    from carbody.camera import View, read_view
    from carbody.fit.keypoints_io import check_image_size, read_keypoints
    from carbody.fit.overlay import draw_overlay, write_image
    from carbody.errors import FitRefused
    from carbody.fit.focal import focal_length_px
    from carbody.fit.report import build_report, draw_error_chart, fit_notes, refusal_line, wheelbase_source, write_json
    from carbody.fit.options import FitOptions
    from carbody.fit.single_view import fit_wireframe
    from carbody.fit.view_prior import ViewPrior
    from carbody.outputs import (JSON, PHOTO, PICTURE, STEP, check_distinct, check_not_inputs, check_output_file,
                                 staged)
    from carbody.progress import progress
    from carbody.view.labels import angular_difference
    from carbody.view.predict import read_image
    from carbody.wireframe import write_wireframe

    # Every input is checked before anything is written.
    if args.view is None and args.no_refine:
        raise FitError("--no-refine keeps the view given: give --view")
    view = ViewPrior.uniform(elevation_deg=args.elevation, roll_deg=args.roll) if args.view is None else \
        View(read_view(args.view), args.elevation, args.roll)
    distance = parse_distance(args.distance)
    with progress(("read", "fit", "write"), args.quiet) as bar:
        bar.start("read")
        image = read_image(args.image)[..., ::-1].copy()  # RGB -> BGR: the overlay is drawn with OpenCV
        ann = read_keypoints(args.keypoints)
        h, w = image.shape[:2]
        check_image_size(ann, (w, h))
        library = library_without(args.exclude_template)
        truth = load_truth(args.truth) if args.truth else None
        chart = Path(args.report).with_suffix(".errors.png") if args.report and truth is not None else None
        if truth is not None and not args.report:
            raise FitError("--truth needs --report: the errors go into the report, and their chart next to it "
                           "(REPORT.errors.png)")
        check_output_file(args.output, STEP)
        if args.overlay:
            check_output_file(args.overlay, PHOTO)
        if args.uncertainty:
            check_output_file(args.uncertainty, PICTURE)
        if args.report:
            check_output_file(args.report, JSON)
        if chart is not None:
            check_output_file(chart, PICTURE)
        outputs = {"--output": args.output, "--overlay": args.overlay, "--uncertainty": args.uncertainty,
                   "--report": args.report, "the error chart": chart}
        check_distinct(outputs)
        check_not_inputs(outputs, {"the photo": args.image, "the keypoint file": args.keypoints,
                                   "the ground truth": args.truth})
        if args.uncertainty and args.method == "paper":
            raise FitError("--uncertainty needs a Gaussian-prior method (mixture or gauss): "
                           "the paper's solve has no posterior")
        focal, focal_source = focal_length_px(args.image, (w, h), args.focal_35mm)
        bar.start("fit")
        options = FitOptions(method=args.method, refine=not args.no_refine, deform=False if args.no_deform else None,
                             robust=not args.keep_marks, camera_distance_mm=distance,
                             principal_point=args.principal_point, focal_px=focal, check_orthographic=True,
                             view_prior_weight=args.view_weight, outline=args.outline, wheels=args.wheels)
        result = fit_wireframe(ann.points, view, library, image_size=(w, h), wheelbase_mm=args.wheelbase,
                               options=options, name=args.name or Path(args.image).stem,
                               photo=image[..., ::-1] if options.outline or options.wheels else None)
        overlay = draw_overlay(image, result) if args.overlay else None
        # (the photo plane reads the photo again: only for a report that is written)
        report = build_report(result, truth, image=args.image if args.report else None)

        refused = None if args.force else refusal_line(result)
        report["refused"] = refused
        bar.start("write")
        if refused:  # what shows why, and nothing that could be taken for a result
            shown = {"--overlay": args.overlay, "--report": args.report}
            # an earlier run's wireframe would be taken for this one's: it goes too
            with staged((p for p in shown.values() if p is not None), remove=[p for p in (args.output, args.uncertainty, chart) if p]) as at:
                if overlay is not None:
                    write_image(at(args.overlay), overlay)
                if args.report:
                    write_json(at(args.report), report)
            written = [str(p) for p in shown.values() if p is not None]
            raise FitRefused(refused + (f"; wrote only {', '.join(written)}" if written else ""))
        with staged(p for p in outputs.values() if p is not None) as at:
            write_wireframe(at(args.output), result.wireframe, both_halves=True)
            if overlay is not None:
                write_image(at(args.overlay), overlay)
            if args.uncertainty:
                result.draw_expected_errors(at(args.uncertainty))
            if args.report:
                write_json(at(args.report), report)
            if chart is not None:
                draw_error_chart(report["error_mm_at_truth_wheelbase"], at(chart),
                                 annotated={s.name.removesuffix("_right") for s in result.slots},
                                 expected_mm=report.get("expected_error_mm"))
    v = result.view
    camera = ("orthographic camera" if result.camera_distance_mm is None
              else f"camera {result.camera_distance_mm:.0f} mm away")
    if focal is not None:
        camera += f", focal length {focal:.0f} px ({focal_source})"
    if result.camera_turn_deg:
        camera += (f", turned {result.camera_turn_deg:.1f}° from the photo's axis to the car"
                   + (f" (focal length {result.focal_px:.0f} px found)" if focal is None else ""))
    given = None if result.given_view is None else result.given_view.azimuth
    told = f"given {given:g}°, " if given is not None and angular_difference(given, v.azimuth) >= 0.05 else ""
    print(f"fitted {len(result.slots)} keypoints: view {v.azimuth:.1f}° ({told}elevation {v.elevation:.1f}°, "
          f"roll {v.roll:.1f}°, {camera}), residual mean {result.solution.residual_px.mean():.2f} px, "
          f"wheelbase {result.wheelbase_mm:.0f} mm ({wheelbase_source(report)}) -> {args.output}")
    for line in fit_notes(report):
        print(line)
    if "error_mm_mean" in report:
        print(f"3D keypoint error vs {report['truth']}: mean {report['error_mm_mean']:.1f} mm, "
              f"max {report['error_mm_max']:.1f} mm (at its wheelbase: mean "
              f"{report['error_mm_at_truth_wheelbase_mean']:.1f} mm, max "
              f"{report['error_mm_at_truth_wheelbase_max']:.1f} mm)")
    return 0


def library_without(names: list[str]):
    """The shipped library without the named templates (``--exclude-template``; names matched
    as :func:`carbody.templates.slug` does) and their expansions."""
    from carbody.library import load_library

    library = load_library()
    for name in names:
        library = library.without(_match_template(library, name))
    return library


def _match_template(library, name: str) -> str:
    from carbody.templates import slug

    for t in library.template_names:
        if slug(t) == slug(name):
            return t
    return name  # Library.without names the known templates in its error


def run_visible(args: argparse.Namespace) -> int:
    import numpy as np

    from carbody.camera import View, read_view
    from carbody.errors import FitError
    from carbody.fit.keypoints_io import keypoint_slots
    from carbody.fit.solve import car_centre
    from carbody.fit.visibility import visible_keypoints
    from carbody.library import load_library
    from carbody.tolerances import NORMALISED_WHEELBASE
    from carbody.topology import load_topology

    azimuth = read_view(args.view)
    distance = parse_distance(args.distance)
    if distance == "auto":
        raise FitError("visible-keypoints needs a camera distance in mm or 'orthographic', not 'auto'")
    if args.template:
        from carbody.templates import load_template

        cp = load_template(args.template).control_points
    else:  # the library's mean car at the templates' mean wheelbase, mm
        library = load_library()
        cp = (library.S.mean(axis=1).reshape(-1, 3)
              * float(np.mean(library.template_wheelbase_mm)) / NORMALISED_WHEELBASE)
    view = View(azimuth, args.elevation, 0.0, distance, car_centre(cp) if distance else (0.0, 0.0, 0.0))
    names = visible_keypoints(view, cp)
    topo = load_topology()
    slots = keypoint_slots(topo)
    camera = "" if distance is None else f", camera {distance:g} mm away"
    print(f"{len(names)} keypoints visible at view {view.azimuth:g}° (elevation {view.elevation:g}°{camera}):")
    for n in names:
        k = topo.keypoints[slots[n].keypoint_id - 1]
        print(f"  {k.id:2d}  {n:30s} {k.description}")
    return 0
