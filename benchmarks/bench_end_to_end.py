"""End to end over the library, each template left out: photo → view → fit → body, at every view.

For each template: drop it (with its expansions) from the library; surface its own
wireframe and render it (VTK, off-screen) as the shipped example is rendered — a street photo,
1000 × 640 px, from a pinhole camera 7 m from the car's centre at 6° elevation — at each of the
24 view classes (0°–345° by 15°: the right side too); mark the keypoints that camera sees by
projecting the wireframe through it with 1 px of noise; and run ``carbody.reconstruct`` on the
picture and marks as a user would: the view told by the shipped classifier (``--view-known``:
told the truth), the camera distance found, the wheelbase not told. Measured: the 3D keypoint
error at the true wheelbase (the benchmark's measure) and at the fitted one (what the STEP
holds), whether the classifier's class was right, and whether the body came out (one valid
sewn shell) or the run stopped with an error line. The classifier was trained on renders of
some templates (not these photos): rows are split by whether it ever saw the car.

Run: python benchmarks/bench_end_to_end.py [--quick] [--view-known] [--loose-fields] [--no-blend] [--workers 2]
    [--[no-]wheels] [--json out.json]
     python benchmarks/bench_end_to_end.py --tables out.json [--first N]   (a run's tables again; with --first,
         only the runs of the library's first N templates: the cars of a smaller library, left out of this one)
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

VIEWS = tuple(range(0, 360, 15))
ELEVATION_DEG = 6.0
CAMERA_DISTANCE_MM = 7000.0
SIZE = (1000, 640)
NOISE_PX = 1.0


def photograph(truth, view_deg: float, rng: np.random.Generator):
    """(RGB picture, {keypoint: (u, v)}) of a wireframe (mm) seen as the shipped example is."""
    from carbody.fit import View, visible_keypoints
    from carbody.fit.keypoints_io import keypoint_slots
    from carbody.fit.solve import car_centre
    from carbody.render.mesh import tessellate
    from carbody.render.scene import Look, Scene
    from carbody.surface import build_body
    from carbody.view.dataset import FIXED_DETAIL_COLOURS, detail_meshes, wheel_meshes

    meshes = tessellate(build_body(truth, check=False))
    radius = 0.115 * truth.measure()["wheelbase_mm"]
    meshes += wheel_meshes(truth.control_points, radius) + detail_meshes(meshes)
    scene = Scene(meshes, size=SIZE, antialias=2)
    look = Look(paint=(0.55, 0.07, 0.06), glass=(0.12, 0.15, 0.18), background=(0.90, 0.91, 0.93),
                colours=dict(FIXED_DETAIL_COLOURS))
    image = scene.render(view_deg, ELEVATION_DEG, look=look, distance=CAMERA_DISTANCE_MM, fill=0.82)
    camera = View(view_deg, ELEVATION_DEG, 0.0, CAMERA_DISTANCE_MM, car_centre(truth.control_points))
    slots = keypoint_slots()
    marks = {}
    for name in visible_keypoints(camera, truth.control_points):
        slot = slots[name]
        u, v = scene.project(truth.control_points[slot.point_index][None] * slot.sign)[0] + rng.normal(0, NOISE_PX, 2)
        marks[name] = (float(u), float(v))
    return image, marks


def set_up_worker(loose: bool, blend: bool) -> None:
    """In a worker: ``--loose-fields`` lets the fit's smooth fields move each curve's inner
    poles on their own again (``carried_by_curve_ends`` off), as before they kept the curves'
    end tangents: how many bodies that costs; ``--no-blend`` keeps a stiffer refit as it is
    (``BLEND_HALVINGS`` 0), as before it was blended back toward the fit."""
    if not blend:
        import carbody.pipeline as pipeline

        pipeline.BLEND_HALVINGS = 0
    if loose:
        import carbody.fit.deform as deform

        deform.carried_by_curve_ends = lambda basis: basis


def run_template(args) -> list[dict]:
    t, views, view_known, wheels = args
    import torch

    torch.set_num_threads(1)
    from carbody import reconstruct
    from carbody.errors import CarbodyError
    from carbody.fit.report import keypoint_errors_mm
    from carbody.library import load_library
    from carbody.view.labels import angular_difference
    from carbody.wireframe import Wireframe

    library = load_library()
    name = library.template_names[t]
    wb = float(library.template_wheelbase_mm[t])
    truth = Wireframe(name, library.points(library.original(t)) * wb / 1000.0)
    loo = library.without(name)
    rng = np.random.default_rng(3000 + t)
    rows = []
    for view in views:
        image, marks = photograph(truth, view, rng)
        row = {"template": name, "view": view, "keypoints": len(marks), "error": None}
        start = time.perf_counter()
        try:
            result = reconstruct(image, marks, view=view if view_known else None, library=loo, name=name,
                                 **({} if wheels is None else {"wheels": wheels}))
        except CarbodyError as exc:
            row["error"] = str(exc)
            rows.append(row)
            continue
        row["seconds"] = time.perf_counter() - start
        shape = keypoint_errors_mm(result.fit.wireframe, truth, at_truth_wheelbase=True)
        written = keypoint_errors_mm(result.fit.wireframe, truth)
        shell = result.body.report.get("shell", {})
        pred = result.view_prediction
        row.update(mean_mm=float(np.mean(list(shape.values()))), max_mm=float(np.max(list(shape.values()))),
                   written_mean_mm=float(np.mean(list(written.values()))),
                   class_deg=None if pred is None else float(pred.class_deg),
                   class_right=None if pred is None else bool(pred.class_deg == view),
                   class_off_deg=None if pred is None else float(angular_difference(pred.class_deg, view)),
                   azimuth_off_deg=float(angular_difference(result.fit.view.azimuth, view)),
                   wheelbase_pct=100.0 * (result.fit.wheelbase_mm / wb - 1.0),
                   camera_mm=result.fit.camera_distance_mm,
                   shell_valid=bool(shell.get("valid", False)), faces=len(result.body.faces),
                   fallback=None if result.fallback is None else result.fallback["fit"],
                   share_of_fit=None if result.fallback is None else result.fallback["share_of_fit"],
                   evidence_per_coordinate=result.fit.diagnostics.evidence_per_coordinate,
                   fits_poorly=result.fit.diagnostics.fits_poorly, misses_marks=result.fit.diagnostics.misses_marks,
                   rejected=sorted(result.fit.diagnostics.rejected), solves=result.fit.diagnostics.solves,
                   view_source=result.view_source)
        rows.append(row)
    return rows


def summary(rows: list[dict], seen: set[str]) -> str:
    out = ["| cars | runs | body out (valid shell) | of them by a stiffer fit | stopped with an error "
           "| classifier class right | within ±15° | azimuth within 5° | mean 3D error at the true wheelbase (mm) "
           "| median of the runs' means | at the fitted wheelbase | wheelbase error, median abs. | s/run |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    groups = [("all", rows), ("the classifier never saw", [r for r in rows if r["template"] not in seen]),
              ("the classifier trained on", [r for r in rows if r["template"] in seen])]
    for label, rs in groups:
        if not rs:
            continue
        ok = [r for r in rs if r["error"] is None]
        right = [r for r in ok if r.get("class_right") is not None]
        cell = (lambda k: f"{sum(r[k] for r in right)} of {len(right)}") if right else (lambda k: "told")
        within = f"{sum(r['class_off_deg'] <= 15 for r in right)} of {len(right)}" if right else "told"
        out.append(f"| {label} | {len(rs)} | {sum(r['shell_valid'] for r in ok)} "
                   f"| {sum(r['fallback'] is not None for r in ok)} | {len(rs) - len(ok)} "
                   f"| {cell('class_right')} | {within} | {sum(r['azimuth_off_deg'] <= 5 for r in ok)} of {len(ok)} "
                   f"| {np.mean([r['mean_mm'] for r in ok]):.1f} | {np.median([r['mean_mm'] for r in ok]):.1f} "
                   f"| {np.mean([r['written_mean_mm'] for r in ok]):.1f} "
                   f"| {np.median(np.abs([r['wheelbase_pct'] for r in ok])):.1f} % "
                   f"| {np.mean([r['seconds'] for r in ok]):.2f} |")
    return "\n".join(out)


def by_view(rows: list[dict]) -> str:
    views = sorted({r["view"] for r in rows})
    ok = [r for r in rows if r["error"] is None]
    head = "| | " + " | ".join(f"{v}°" for v in views) + " |"
    lines = [head, "|---|" + "---|" * len(views),
             "| mean 3D error (mm) | " + " | ".join(
                 f"{np.mean([r['mean_mm'] for r in ok if r['view'] == v]):.0f}" if any(r["view"] == v for r in ok)
                 else "—" for v in views) + " |",
             "| body out | " + " | ".join(
                 f"{sum(r['view'] == v and r['error'] is None and r['shell_valid'] for r in rows)}/"
                 f"{sum(r['view'] == v for r in rows)}" for v in views) + " |"]
    if any(r.get("class_right") is not None for r in ok):
        lines.append("| class right | " + " | ".join(
            f"{sum(r['class_right'] for r in ok if r['view'] == v)}/{sum(r['view'] == v for r in rows)}"
            for v in views) + " |")
    return "\n".join(lines)


def by_car(rows: list[dict]) -> str:
    """Each left-out car's mean 3D error over its views, worst first."""
    ok = [r for r in rows if r["error"] is None]
    cars = {r["template"] for r in ok}
    errors = {c: [r["mean_mm"] for r in ok if r["template"] == c] for c in cars}
    lines = ["| car left out | views | mean 3D error (mm) | median | worst view |", "|---|---|---|---|---|"]
    for c in sorted(cars, key=lambda c: -np.mean(errors[c])):
        e = errors[c]
        lines.append(f"| {c} | {len(e)} | {np.mean(e):.1f} | {np.median(e):.1f} | {max(e):.1f} |")
    return "\n".join(lines)


def failures(rows: list[dict]) -> str:
    bad = [r for r in rows if r["error"] is not None]
    return "\n".join(f"- {r['template']} at {r['view']}°: {r['error']}" for r in bad) or "- none"


def poor_fits(rows: list[dict]) -> str:
    ok = [r for r in rows if r["error"] is None]
    evidence = np.array([r["evidence_per_coordinate"] for r in ok])
    poor = [r for r in ok if r["fits_poorly"]]
    head = (f"−log evidence per coordinate over the runs: median {np.median(evidence):.1f}, 99th percentile "
            f"{np.percentile(evidence, 99):.1f}, max {evidence.max():.1f}; said to fit poorly: {len(poor)} of {len(ok)}; "
            f"car missing the marks by over 5 % of their spread: {sum(r['misses_marks'] for r in ok)} of {len(ok)}; "
            f"marks left out as misplaced: {sum(len(r['rejected']) for r in ok)} in {sum(bool(r['rejected']) for r in ok)} runs")
    return "\n".join([head] + [f"- {r['template']} at {r['view']}°: {r['evidence_per_coordinate']:.0f} per coordinate "
                               f"({r['mean_mm']:.0f} mm)" for r in poor])


def fallbacks(rows: list[dict]) -> str:
    made = [r for r in rows if r.get("fallback")]
    return "\n".join(f"- {r['template']} at {r['view']}°: {r['fallback']}, {r['share_of_fit']:.0%} of the fit "
                     f"blended back ({r['mean_mm']:.0f} mm)" for r in made) or "- none"


def print_tables(rows: list[dict], seen: set[str]) -> None:
    print(summary(rows, seen))
    print("\nBy view (all cars):\n")
    print(by_view(rows))
    print("\nBy car (every view):\n")
    print(by_car(rows))
    print("\nRuns that stopped:\n")
    print(failures(rows))
    print("\nThe fit's own verdict (a note when no car fits the marks):\n")
    print(poor_fits(rows))
    print("\nRuns surfaced from a stiffer fit (the first fit's wireframe had a region crossing itself):\n")
    print(fallbacks(rows))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 templates, 6 views")
    ap.add_argument("--view-known", action="store_true", help="tell the fit the true view instead of the classifier's")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", help="write every run as JSON")
    ap.add_argument("--loose-fields", action="store_true",
                    help="the fit's fields move each curve's inner poles on their own (not with its ends)")
    ap.add_argument("--no-blend", action="store_true",
                    help="a stiffer refit is not blended back toward the fit")
    ap.add_argument("--wheels", action=argparse.BooleanOptionalAction, default=None,
                    help="find the wheels' hubs in the picture and fit them (default: as reconstruct's default)")
    ap.add_argument("--tables", metavar="JSON", help="print the tables of a run's --json file, running nothing")
    ap.add_argument("--first", type=int, metavar="N", help="with --tables: only the library's first N templates' runs")
    args = ap.parse_args(argv)
    from carbody.library import load_library
    from carbody.view.predict import load_classifier

    names = load_library().template_names
    _, meta = load_classifier(None)
    seen = set(names) - set(meta["dataset"]["validation_templates"])
    if args.tables:
        with open(args.tables) as f:
            rows = json.load(f)
        if args.first:
            first = set(names[:args.first])
            rows = [r for r in rows if r["template"] in first]
        print_tables(rows, seen)
        return 0

    templates = [0, 5, 9] if args.quick else list(range(len(names)))
    views = (0, 30, 90, 150, 210, 300) if args.quick else VIEWS
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers, initializer=set_up_worker, initargs=(args.loose_fields, not args.no_blend)) as pool:
        rows = [r for part in pool.map(run_template, [(t, views, args.view_known, args.wheels) for t in templates]) for r in part]
    print(f"# End to end, each template left out of the library: {len(templates)} cars x {len(views)} views, "
          f"street photos ({SIZE[0]} x {SIZE[1]} px, camera {CAMERA_DISTANCE_MM / 1000:g} m away, "
          f"{ELEVATION_DEG:g}° up), {NOISE_PX:g} px marks, view "
          f"{'told' if args.view_known else 'by the classifier'}, distance found, wheelbase not told"
          f"{'; fields moving inner poles on their own' if args.loose_fields else ''}"
          f"{'; stiffer refits not blended back' if args.no_blend else ''}"
          f"{'' if args.wheels is None else '; wheels ' + ('on' if args.wheels else 'off')}; "
          f"{os.cpu_count()} cores, {args.workers} workers ({time.perf_counter() - start:.0f} s)\n")
    print_tables(rows, seen)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
