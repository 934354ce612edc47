"""Leave-one-out accuracy of single-view fitting (issue 3, SPEC "Fitting").

For each template: drop it and its expansions from the library, view it at each of the 13 class
angles (0°–180° by 15°, elevation 0), annotate the keypoints the view can see (from its own
geometry) by projection onto a 1000 px wide image (the car spans 900 px) plus N(0, 1 px) noise,
fit (told the true wheelbase, except in the rows "wheelbase not told", whose fitted car is
rescaled to it), and measure the 3D error of the 35 keypoints in mm at the true wheelbase.

Cases: the view known (no refinement, and refined from the true view), and the given angle off
by +10° without and with the view refinement. Methods: ``paper`` (plain ΣH = 1, 0 ≤ H ≤ 1), ``gauss`` (one Gaussian shape
prior) and ``mixture`` (a Gaussian around each template, the default), the Gaussian-prior cases
with the photo-matching deformation (default) and, where marked "no deform", without it.
``--sweep`` also scans the default method's prior weight λ on the known-view case;
``--elevation`` views from above; ``--distance`` photographs with a pinhole camera;
``--other-end`` runs only the check that a view near the front or rear is not the car's other end;
``--orthographic-check`` only the check that a photo fitted as orthographic was taken from close by;
``--view-off DEG,...`` only views told that far off (what the fit refuses, naming which view);
``--real-marks [DIR]`` only the check of where the view found on the real photos of ``DIR``
(``../shared/realphotos``) leans from their estimates: their own marks fitted as they are, with a
looser shape prior, and from the car's near half alone; then library cars seen from close by and
marked only where each photo was marked, at its estimated view, which must not lean.

Run: python benchmarks/bench_fit_accuracy.py [--quick] [--sweep] [--elevation DEG] [--distance MM]
    [--known-only] [--other-end] [--orthographic-check] [--view-off DEG,...] [--real-marks [DIR]]
    [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from concurrent.futures import ProcessPoolExecutor

import numpy as np


ANGLES = tuple(range(0, 181, 15))
IMAGE_WIDTH = 1000
CAR_SPAN = 900
NOISE_PX = 1.0
OFFSET_DEG = 10.0


def synthetic_view(truth: np.ndarray, azimuth: float, rng: np.random.Generator, elevation: float = 0.0,
                   distance: float | None = None, noise_px: float = NOISE_PX, off_centre_deg: float = 0.0):
    """Keypoints of a normalised (280, 3) car seen at a view: ({name: (u, v)}, (width, height),
    the pinhole camera's focal length in pixels or None).

    Args:
        distance: None for SPEC's orthographic camera (the car centred on a 1000 px wide image,
            900 px wide); else a pinhole camera this far from the car's centre, in the car's own
            units (a real photo's perspective), its optical axis through the image centre.
        noise_px: standard deviation of the marking error, pixels.
        off_centre_deg: the pinhole camera's axis turned this far to the car's right of it, so
            the car sits off the photo's centre (the photo is made wide enough to hold it).
    """
    from carbody.camera import View, project, view_rotation
    from carbody.fit.visibility import visible_slots

    view = View(azimuth, elevation)
    both = np.concatenate([truth, truth * [-1.0, 1.0, 1.0]])
    centre = (both.min(axis=0) + both.max(axis=0)) / 2
    if distance is None:
        scale, offset, size = orthographic_frame(truth, view)

        def camera(points: np.ndarray) -> np.ndarray:
            return offset + scale * project(points, view)
        focal = None
    else:
        d, r, w = view_rotation(view)
        eye = centre + distance * d
        turn = np.radians(off_centre_deg)
        axis = -np.cos(turn) * d + np.sin(turn) * r
        right = np.cos(turn) * r + np.sin(turn) * d

        def image_plane(points: np.ndarray) -> np.ndarray:  # (x right, y down) / depth
            q = points - eye
            return np.stack([q @ right, -(q @ w)], axis=-1) / (q @ axis)[:, None]

        p = image_plane(both)
        focal = CAR_SPAN / np.ptp(p[:, 0])
        half = np.abs(p).max(axis=0) * focal + (IMAGE_WIDTH - CAR_SPAN) / 2
        size = (int(np.ceil(2 * half[0])), int(np.ceil(2 * half[1])))

        def camera(points: np.ndarray) -> np.ndarray:
            return np.array(size) / 2 + focal * image_plane(points)
    # What the camera sees: a close one sees less of the faces turned away.
    eye_view = view if distance is None else View(azimuth, elevation, 0.0, distance, tuple(centre))
    slots = visible_slots(eye_view, truth)
    pts = np.array([truth[s.point_index] * s.sign for s in slots])
    uv = camera(pts) + rng.normal(0.0, noise_px, (len(slots), 2))
    return {s.name: (float(u), float(v)) for s, (u, v) in zip(slots, uv)}, size, focal


def orthographic_frame(truth: np.ndarray, view) -> tuple[float, np.ndarray, tuple[int, int]]:
    """SPEC's orthographic camera of :func:`synthetic_view` for a normalised (280, 3) car: (the
    scale, pixels per normalised unit; the (2,) offset, pixels; the image size): the car, both
    halves, centred and CAR_SPAN px wide on an IMAGE_WIDTH px wide image."""
    from carbody.camera import project

    p = project(np.concatenate([truth, truth * [-1.0, 1.0, 1.0]]), view)
    scale = CAR_SPAN / np.ptp(p[:, 0])
    size = (IMAGE_WIDTH, int(np.ceil(np.ptp(p[:, 1]) * scale + IMAGE_WIDTH - CAR_SPAN)))
    return scale, (np.array(size) - scale * (p.min(axis=0) + p.max(axis=0))) / 2, size


def left_out(t: int):
    """Template t left out: (its name, the library without it, its normalised (280, 3) points,
    its wheelbase mm, the (35,) keypoint rows)."""
    from carbody.library import load_library
    from carbody.topology import load_topology

    lib = load_library()
    name = lib.template_names[t]
    return (name, lib.without(name), lib.points(lib.original(t)), float(lib.template_wheelbase_mm[t]),
            load_topology().keypoint_point_indices)


def set_joint_field(joint: tuple[float, tuple | None, bool] | None,
                    deform_length: tuple[float, float, float] | None = None) -> None:
    """In a worker: the joint field's amplitude and lengths (None: the defaults), whether the
    deformation's broad part joins the prior instead of its local one, and the correlation
    lengths of the post-fit deformation's local part (None: ``LOCAL_LENGTH``)."""
    import carbody.fit.deform as deform

    if deform_length is not None:
        deform.LOCAL_LENGTH = deform_length
    if joint is None:
        return
    import carbody.fit.shape_prior as shape_prior

    shape_prior.JOINT_FIELD_AMPLITUDE = joint[0]
    if joint[1] is not None:
        deform.JOINT_LENGTH = joint[1]
    if joint[2]:
        shape_prior.joint_field_basis = lambda reference, topology: deform._field_basis(
            reference, topology, (deform.FIELD_SIGMA,) * 3, deform.FIELD_LENGTH)


def misplace(kps: dict, size: tuple[int, int], n: int, px: float, rng: np.random.Generator) -> tuple[dict, list[str]]:
    """``n`` random marks moved ``px`` pixels in a random direction (kept on the image): a
    click on the wrong feature. Returns (the marks, the names moved)."""
    names = list(rng.choice(sorted(kps), size=min(n, len(kps)), replace=False)) if n else []
    out = dict(kps)
    for name in names:
        a = rng.uniform(0.0, 2.0 * np.pi)
        u, v = np.array(out[name]) + px * np.array([np.cos(a), np.sin(a)])
        out[name] = (float(np.clip(u, 0, size[0])), float(np.clip(v, 0, size[1])))
    return out, names


def swap_pair(kps: dict, rng: np.random.Generator) -> tuple[dict, list[str]]:
    """One random left/right pair of marks (both marked) with their names exchanged: the car's
    left taken for the viewer's. Returns (the marks, the two names; none when no pair is)."""
    pairs = sorted(n for n in kps if n + "_right" in kps)
    if not pairs:
        return kps, []
    a = str(rng.choice(pairs))
    b = a + "_right"
    return {**kps, a: kps[b], b: kps[a]}, [a, b]


#: --twin-slip: how far (px) from a mark its twin is clicked, at least (and twice the
#: separation the input check refuses as one spot, MIN_TWIN_SEPARATION of the marks' spread).
TWIN_SLIP_PX = 4.0


def twin_slip(kps: dict, rng: np.random.Generator) -> tuple[dict, list[str]]:
    """One random mark of the car's left half also clicked, ``TWIN_SLIP_PX`` off it (or further,
    past the input check), under its right twin's name (replacing that mark when it was there):
    one point marked under both names, as the fit sees it. Returns (the marks, the twin's name;
    none when no mark has a twin)."""
    import carbody.fit.keypoints_io as keypoints_io
    from carbody.fit.solve import keypoint_spread

    slots = keypoints_io.keypoint_slots()
    least = getattr(keypoints_io, "MIN_TWIN_SEPARATION", 0.01)  # (a fit from before the check: its value)
    left = sorted(n for n in kps if not n.endswith("_right") and n + "_right" in slots)
    if not left:
        return kps, []
    n = str(rng.choice(left))
    a = rng.uniform(0.0, 2.0 * np.pi)
    px = max(TWIN_SLIP_PX, 2.0 * least * keypoint_spread(np.array(list(kps.values()))))
    u, v = np.array(kps[n]) + px * np.array([np.cos(a), np.sin(a)])
    return {**kps, n + "_right": (float(u), float(v))}, [n + "_right"]


def run_template(args) -> list[dict]:
    t, cases, lambdas, angles, elevation, distance_mm, noise_px, off_centre, outliers, reject, swap = args
    from carbody.errors import FitError
    from carbody.fit import fit_wireframe
    from carbody.topology import load_topology

    name, loo, truth, wb, idx = left_out(t)
    rng = np.random.default_rng(1000 + t)
    rows = []
    for azimuth in angles:
        distance = None if distance_mm is None else distance_mm * 1000.0 / wb  # normalised units
        kps, size, focal = synthetic_view(truth, azimuth, rng, elevation, distance, noise_px, off_centre)
        kps, moved = misplace(kps, size, *outliers, rng) if outliers else (kps, [])
        if swap == "twin":
            kps, moved = twin_slip(kps, rng)
        elif swap:
            kps, moved = swap_pair(kps, rng)
        annotated = sorted({n.removesuffix("_right") for n in kps})
        ann_idx = [k for k, kp in enumerate(load_topology().keypoints) if kp.name in annotated]
        for method, lam, offset, refine, deform, *extra in cases + [("mixture", l, 0.0, False, True) for l in lambdas]:
            level, camera, principal, known_focal, wb_told = list(extra) + [False, None, "car", None, True][len(extra):]
            given_elevation = 0.0 if level else elevation
            kw_camera = {}
            if camera == "told":
                kw_camera["camera_distance_mm"] = distance_mm
            elif camera == "auto":
                kw_camera["camera_distance_mm"] = "auto"
            t0 = time.perf_counter()
            kw = {"prior_weight": lam} if lam is not None else {}
            from carbody.camera import View

            res = fit_wireframe(kps, View((azimuth + offset) % 360, given_elevation), loo, image_size=size,
                                wheelbase_mm=wb if wb_told else None, method=method, refine=refine,
                                deform=deform and method != "paper", principal_point=principal,
                                focal_px=focal if known_focal else None, robust=reject,
                                **kw, **kw_camera)
            dt = time.perf_counter() - t0
            estimate = by_mix = spread = None
            if not refine and not offset and lam is None and deform == (method != "paper") and wb_told:
                # the wheelbase the fit uses when none is given (the proportions' for the
                # Gaussian-prior methods, the mix's own for the paper's; told one, the shape prior
                # is sized by it, so this is a fit of its own)
                try:
                    alone = fit_wireframe(kps, View(azimuth % 360, given_elevation), loo, image_size=size,
                                          method=method, refine=False, deform=False, principal_point=principal,
                                          focal_px=focal if known_focal else None, **kw_camera)
                    estimate = 100.0 * (alone.wheelbase_mm / wb - 1.0)
                    by_mix = 100.0 * (alone.wheelbase_by_mix_mm / wb - 1.0)
                    spread = None if alone.size is None else 100.0 * alone.size.spread
                except FitError:  # a told distance read at a wheelbase that puts the camera in the car
                    estimate = float("nan")
            at_truth = wb / res.wheelbase_mm  # 1 when told; else the fit's own size read at the true one
            diff = res.wireframe.control_points[idx] * at_truth - truth[idx] * wb / 1000
            err = np.linalg.norm(diff, axis=1)
            expected = res.expected_error_mm()
            expected = None if expected is None else [expected[k.name] * at_truth for k in load_topology().keypoints]
            rows.append({"template": name, "azimuth": azimuth, "method": method, "lambda": lam,
                         "offset": offset, "refine": refine, "deform": deform and method != "paper",
                         "given_elevation": given_elevation, "elevation": elevation, "camera": camera,
                         "principal": principal, "off_centre_deg": off_centre,
                         "focal_known": bool(known_focal), "wheelbase_told": bool(wb_told),
                         "refined_distance_mm": None if res.view.distance is None
                         else res.view.distance * wb / 1000.0,
                         "k": len(kps),
                         "mean_mm": float(err.mean()), "max_mm": float(err.max()),
                         "along_mm": float(np.abs(diff[:, 1]).mean()),
                         "annotated_mean_mm": float(err[ann_idx].mean()),
                         "annotated_max_mm": float(err[ann_idx].max()),
                         "refined_azimuth": res.view.azimuth, "refined_elevation": res.view.elevation,
                         # the wheelbase the fit uses when none is given, vs the truth
                         "wheelbase_estimate_pct": estimate,
                         "wheelbase_by_mix_pct": by_mix, "wheelbase_spread_pct": spread,
                         "residual_px": float(res.solution.residual_px.mean()),
                         "moved": moved, "rejected": sorted(res.diagnostics.rejected),
                         "swapped": sorted(res.diagnostics.swapped or ()),
                         "renamed": res.diagnostics.renamed, "solves": res.diagnostics.solves,
                         # the fit's own estimate of each keypoint's error, against the error
                         "expected_mm": expected, "error_mm": err.tolist(),
                         "seconds": dt})
    return rows


#: ``--other-end``: views this near (degrees) the front or rear are told the car's other end.
OTHER_END_RANGE_DEG = 60.0


def run_other_end(args) -> list[dict]:
    """Template t's views within ``OTHER_END_RANGE_DEG`` of the front or rear, each fitted told its
    true view and told the car's other end (180° − θ): the view the search lands on, and the
    fit's −log evidence per coordinate there (what ``poor_fit_evidence`` is set against)."""
    t, angles, elevation, noise_px = args
    from carbody.camera import View, degrees_from_axis
    from carbody.errors import FitError
    from carbody.fit import fit_wireframe

    name, loo, truth, wb, idx = left_out(t)
    rng = np.random.default_rng(2000 + t)
    rows = []
    for azimuth in angles:
        if degrees_from_axis(azimuth) > OTHER_END_RANGE_DEG:
            continue
        kps, size, _ = synthetic_view(truth, azimuth, rng, elevation, noise_px=noise_px)
        for told in (azimuth, (180.0 - azimuth) % 360.0):
            row = {"template": name, "azimuth": azimuth, "told": "true view" if told == azimuth else "other end",
                   "view": None, "failed": None}
            t0 = time.perf_counter()
            try:
                fit = fit_wireframe(kps, View(told, elevation), loo, image_size=size, wheelbase_mm=wb)
                err = np.linalg.norm(fit.wireframe.control_points[idx] - truth[idx] * wb / 1000, axis=1)
                row.update(view=fit.view.azimuth, evidence_per_coordinate=fit.diagnostics.evidence_per_coordinate,
                           mean_mm=float(err.mean()), rejected=sorted(fit.diagnostics.rejected))
            except FitError as e:
                row["failed"] = str(e)
            row["seconds"] = time.perf_counter() - t0
            rows.append(row)
    return rows


def other_end_table(rows: list[dict]) -> str:
    """``--other-end``: where fits told the true view or the other end land, and their −log
    evidence per coordinate there."""
    from carbody.policy import FIT_POLICY
    from carbody.view.labels import angular_difference

    out = ["| told | fits | lands within 5° of the photo's view | mean 3D error, mm | −log evidence per "
           f"coordinate there: min / median / max | above {FIT_POLICY.poor_fit_evidence:g} | failed | s/fit |",
           "|---|---|---|---|---|---|---|---|"]
    for told in ("true view", "other end"):
        rs = [r for r in rows if r["told"] == told]
        ok = [r for r in rs if r["view"] is not None]
        landed = [r for r in ok if angular_difference(r["view"], r["azimuth"]) <= 5.0]
        ev = np.array([r["evidence_per_coordinate"] for r in ok])
        out.append(f"| {told} | {len(rs)} | {len(landed)} | {np.mean([r['mean_mm'] for r in ok]):.1f} "
                   f"| {ev.min():.1f} / {np.median(ev):.1f} / {ev.max():.1f} "
                   f"| {int(np.sum(ev > FIT_POLICY.poor_fit_evidence))} | {len(rs) - len(ok)} "
                   f"| {np.median([r['seconds'] for r in rs]):.2f} |")
    return "\n".join(out)


#: ``--orthographic-check``: the cameras the photos are taken with (mm from the car's centre;
#: None: orthographic, SPEC's camera).
CHECK_DISTANCES_MM = (None, 20000.0, 10000.0, 6000.0, 4000.0)


def run_orthographic_check(args) -> list[dict]:
    """Template t photographed from each of ``CHECK_DISTANCES_MM`` at each angle, fitted as
    ``carbody reconstruct --distance orthographic`` does (view given, refined; wheelbase not
    told; asked to check) and as by default (distance found): whether the orthographic fit says
    a camera close by fits far better, the distance it names, and both fits' 3D error at the
    true wheelbase. ``outliers``: (n, px) marks moved per photo (a click on the wrong feature),
    or None."""
    t, angles, elevation, noise_px, outliers = args
    from carbody.camera import View
    from carbody.fit import fit_wireframe

    name, loo, truth, wb, idx = left_out(t)
    rng = np.random.default_rng(3000 + t)
    rows = []
    for distance_mm in CHECK_DISTANCES_MM:
        for azimuth in angles:
            distance = None if distance_mm is None else distance_mm * 1000.0 / wb
            kps, size, _ = synthetic_view(truth, azimuth, rng, elevation, distance, noise_px)
            kps, moved = misplace(kps, size, *outliers, rng) if outliers else (kps, [])
            row = {"template": name, "azimuth": azimuth, "distance_mm": distance_mm, "moved": moved}
            for camera, kw in (("orthographic", {"check_orthographic": True}), ("auto", {"camera_distance_mm": "auto"})):
                t0 = time.perf_counter()
                res = fit_wireframe(kps, View(azimuth, elevation), loo, image_size=size, **kw)
                row[f"{camera}_seconds"] = time.perf_counter() - t0
                err = np.linalg.norm(res.wireframe.control_points[idx] * wb / res.wheelbase_mm
                                     - truth[idx] * wb / 1000, axis=1)
                row[f"{camera}_mean_mm"] = float(err.mean())
                if camera == "orthographic":
                    row["closer_camera"] = res.diagnostics.closer_camera if res.diagnostics.camera_closer else None
                    row["check"] = res.diagnostics.closer_camera
            rows.append(row)
    return rows


def orthographic_check_table(rows: list[dict]) -> str:
    """``--orthographic-check``: per camera, how many orthographic fits said a camera close by,
    the distances they named, and the two fits' mean 3D error."""
    out = ["| photo taken from | fits | said a camera close by fits far better | distance it named: median "
           "(5–95 %) | 3D error fitted as orthographic, mm: said / not said | distance found (default), mm "
           "| −log evidence gained per coordinate, max when not said | not said, by view | s/fit orthographic + check |",
           "|---|---|---|---|---|---|---|---|---|"]
    for distance_mm in CHECK_DISTANCES_MM:
        rs = [r for r in rows if r["distance_mm"] == distance_mm]
        said = [r for r in rs if r["closer_camera"]]
        quiet = [r for r in rs if not r["closer_camera"]]
        named = np.array([r["closer_camera"]["camera_distance_mm"] for r in said]) / 1000
        where = (f"{np.median(named):.1f} m ({np.percentile(named, 5):.1f}–{np.percentile(named, 95):.1f})"
                 if len(said) else "–")

        def mean(group: list[dict], key: str) -> str:
            return f"{np.mean([r[key] for r in group]):.1f}" if group else "–"

        def by_view(group: list[dict]) -> str:
            views = sorted({r["azimuth"] for r in group})
            return ", ".join(f"{v}° ×{sum(r['azimuth'] == v for r in group)}" for v in views) or "–"

        def max_gain(group: list[dict]) -> str:
            gains = [r["check"]["evidence_gain_per_coordinate"] for r in group if r["check"]]
            return f"{max(gains):.2f}" if gains else "–"

        label = "far away (orthographic)" if distance_mm is None else f"{distance_mm / 1000:g} m"
        out.append(f"| {label} | {len(rs)} | {len(said)} | {where} | {mean(said, 'orthographic_mean_mm')} / "
                   f"{mean(quiet, 'orthographic_mean_mm')} | {mean(rs, 'auto_mean_mm')} "
                   f"| {max_gain(quiet)} | {by_view(quiet)} "
                   f"| {np.median([r['orthographic_seconds'] for r in rs]):.3f} |")
    return "\n".join(out)


def run_view_off(args) -> list[dict]:
    """Template t at each angle, fitted (wheelbase not told, the view searched, as ``carbody
    reconstruct`` does) told its view off by each of ``offsets`` degrees: the view it lands on,
    its 3D error, whether it says it fits poorly, and what the fit cost."""
    t, angles, elevation, noise_px, offsets = args
    from carbody.camera import View
    from carbody.errors import FitError
    from carbody.fit import fit_wireframe

    name, loo, truth, wb, idx = left_out(t)
    rng = np.random.default_rng(4000 + t)
    rows = []
    for azimuth in angles:
        kps, size, _ = synthetic_view(truth, azimuth, rng, elevation, noise_px=noise_px)
        for off in offsets:
            told = (azimuth + off) % 360.0
            row = {"template": name, "azimuth": azimuth, "offset": off, "told": told,
                   "failed": None, "view": None, "mean_mm": None, "fits_poorly": None}
            t0 = time.perf_counter()
            try:
                res = fit_wireframe(kps, View(told, elevation), loo, image_size=size)
                err = np.linalg.norm(res.wireframe.control_points[idx] * wb / res.wheelbase_mm
                                     - truth[idx] * wb / 1000, axis=1)
                row.update(view=res.view.azimuth, mean_mm=float(err.mean()),
                           fits_poorly=res.diagnostics.fits_poorly, solves=res.diagnostics.solves)
            except FitError as e:
                row["failed"] = str(e)
            row["seconds"] = time.perf_counter() - t0
            rows.append(row)
    return rows


def view_off_table(rows: list[dict]) -> str:
    """``--view-off``: per offset, where the fits land."""
    from carbody.view.labels import angular_difference

    out = ["| told off by | fits | lands within 5° of the truth | mean 3D error there, mm | lands elsewhere: "
           "said to fit poorly / quiet | failed | s/fit median (max) | solves median (max) |",
           "|---|---|---|---|---|---|---|---|"]
    for off in dict.fromkeys(r["offset"] for r in rows):
        rs = [r for r in rows if r["offset"] == off]
        landed = [r for r in rs if r["view"] is not None]
        right = [r for r in landed if angular_difference(r["view"], r["azimuth"]) <= 5.0]
        wrong = [r for r in landed if angular_difference(r["view"], r["azimuth"]) > 5.0]
        poor = sum(bool(r["fits_poorly"]) for r in wrong)
        sec = [r["seconds"] for r in rs]
        solves = [r["solves"] for r in landed]
        out.append(f"| {off:g}° | {len(rs)} | {len(right)} | "
                   f"{np.mean([r['mean_mm'] for r in right]) if right else float('nan'):.1f} | "
                   f"{poor} / {len(wrong) - poor} | {len(rs) - len(landed)} | {np.median(sec):.2f} ({max(sec):.1f}) "
                   f"| {np.median(solves):.0f} ({max(solves)}) |")
    return "\n".join(out)


def rejections(rows: list[dict]) -> str:
    """Marks the fits left out as misplaced, per case: how many fits left any out, how many marks,
    and how many of those were the ones moved (``--outliers``)."""
    lines = ["Marks left out as misplaced (fits that left any out; marks left out, of them moved by "
             "--outliers, swapped by --swap-pair or added by --twin-slip; moved marks kept; fits that exchanged a pair's "
             "names, of them the pair --swap-pair swapped):", "",
             "| case | fits | marks left out | of them moved | moved, kept | pairs exchanged (the swapped) |",
             "|---|---|---|---|---|---|"]
    for label, group in _by_case(rows):
        fits = sum(bool(r["rejected"]) for r in group)
        marks = sum(len(r["rejected"]) for r in group)
        right = sum(len(set(r["rejected"]) & set(r["moved"])) for r in group)
        kept = sum(len(set(r["moved"]) - set(r["rejected"]) - set(r["swapped"])) for r in group)
        swaps = sum(bool(r["swapped"]) for r in group)
        back = sum(bool(r["swapped"]) and set(r["swapped"]) == set(r["moved"]) for r in group)
        lines.append(f"| {label} | {fits} of {len(group)} | {marks} | {right} | {kept} | {swaps} ({back}) |")
    return "\n".join(lines)


def _by_case(rows: list[dict]) -> list[tuple[str, list[dict]]]:
    out: dict[str, list[dict]] = {}
    for r in rows:
        out.setdefault(case_label(r), []).append(r)
    return list(out.items())


def _default_case(rows: list[dict]) -> tuple[str | None, list[dict]]:
    """The default method's view-known case (its label, its rows), or (None, [])."""
    return next(((lab, rs) for lab, rs in _by_case(rows)
                 if lab.startswith("mixture, view known") and "λ=" not in lab), (None, []))


def case_label(r: dict) -> str:
    lab = r["method"] + ("" if r["lambda"] is None else f" λ={r['lambda']:g}")
    if r["method"] != "paper" and not r.get("deform", True):
        lab += " no deform"
    if r["offset"]:
        lab += f", given +{r['offset']:g}°" + (", refined" if r["refine"] else ", not refined")
        if r.get("given_elevation", 0.0) != r.get("elevation", 0.0):
            lab += f", elevation given as {r['given_elevation']:g}°"
    else:
        lab += ", view known" + (", refined" if r["refine"] else "")
    if r.get("camera") == "told":
        lab += ", fit told the distance"
    elif r.get("camera") == "auto":
        lab += ", distance found by the fit"
    if r.get("principal") == "centre" and r.get("camera"):
        lab += ", axis through the photo's centre"
    if r.get("focal_known"):
        lab += ", focal length known"
    if not r.get("wheelbase_told", True):
        lab += ", wheelbase not told"
    return lab


def summarise(rows: list[dict]) -> str:
    out = []
    out.append("| case | mean (mm) | mean 15°–165° | max 30° | max 150° | max all | annotated: max 30° | max 150° | azimuth within 2° | residual px | s/fit |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for lab, rs in _by_case(rows):
        mean = np.mean([r["mean_mm"] for r in rs])
        mid = np.mean([r["mean_mm"] for r in rs if 0 < r["azimuth"] < 180])
        m30 = max([r["max_mm"] for r in rs if r["azimuth"] == 30], default=np.nan)
        m150 = max([r["max_mm"] for r in rs if r["azimuth"] == 150], default=np.nan)
        a30 = max([r["annotated_max_mm"] for r in rs if r["azimuth"] == 30], default=np.nan)
        a150 = max([r["annotated_max_mm"] for r in rs if r["azimuth"] == 150], default=np.nan)
        mx = max(r["max_mm"] for r in rs)
        sec = np.mean([r["seconds"] for r in rs])
        near = sum(abs((r["refined_azimuth"] - r["azimuth"] + 180) % 360 - 180) <= 2 for r in rs)
        out.append(f"| {lab} | {mean:.1f} | {mid:.1f} | {m30:.1f} | {m150:.1f} | {mx:.1f} | {a30:.1f} | {a150:.1f} "
                   f"| {near}/{len(rs)} | {np.mean([r['residual_px'] for r in rs]):.2f} | {sec:.3f} |")
    return "\n".join(out)


def size_table(rows: list[dict], distance_told: bool) -> str:
    """The size the fit gives when no wheelbase is told (``FitResult.wheelbase_mm``: from the
    proportions, :mod:`carbody.fit.size`) against the library mix's own
    (``wheelbase_by_mix_mm``), and how often the truth lies within one and two of the
    estimate's own spreads."""
    out = ["", "The proportions' wheelbase against the mix's own, and the proportions' spread "
           "against their error (view known):", "",
           "| method | proportions: mean abs. | median abs. | max abs. | mix's own: mean abs. | median abs. "
           "| max abs. | within 1 / 2 spreads | median spread |", "|---|---|---|---|---|---|---|---|---|"]
    for method in dict.fromkeys(r["method"] for r in rows):
        rs = [r for r in rows if r["method"] == method and r.get("wheelbase_spread_pct") is not None
              and not np.isnan(r["wheelbase_estimate_pct"]) and r["deform"] == (method != "paper")
              and r.get("camera") == ("told" if distance_told else None)]
        if not rs:
            continue
        e, m = np.abs([r["wheelbase_estimate_pct"] for r in rs]), np.abs([r["wheelbase_by_mix_pct"] for r in rs])
        spread = np.array([r["wheelbase_spread_pct"] for r in rs])
        out.append(f"| {method} | {e.mean():.1f} % | {np.median(e):.1f} % | {e.max():.1f} % | {m.mean():.1f} % "
                   f"| {np.median(m):.1f} % | {m.max():.1f} % | {np.mean(e <= spread):.0%} / {np.mean(e <= 2 * spread):.0%} "
                   f"| {np.median(spread):.1f} % |")
    return "\n".join(out)


def per_car(rows: list[dict]) -> str:
    """The paper's bound, car by car: how many left-out cars keep every keypoint within 60 mm at
    front 30° and within 55 mm at rear 30° (150°), and the median over cars of that max."""
    out = ["", "The paper's max (≤ 60 mm at front 30°, ≤ 55 mm at rear 30°), car by car:", "",
           "| case | cars under it at 30° | at 150° | median over cars of the max at 30° / 150° (mm) |",
           "|---|---|---|---|"]
    for lab, rs in _by_case(rows):
        m30 = [r["max_mm"] for r in rs if r["azimuth"] == 30]
        m150 = [r["max_mm"] for r in rs if r["azimuth"] == 150]
        if not m30 or not m150 or "λ=" in lab:
            continue
        out.append(f"| {lab} | {sum(m < 60 for m in m30)} of {len(m30)} | {sum(m < 55 for m in m150)} of {len(m150)} "
                   f"| {np.median(m30):.0f} / {np.median(m150):.0f} |")
    return "\n".join(out)


def calibration(rows: list[dict]) -> str:
    """How the fit's own expected error per keypoint (``FitResult.expected_error_mm``) compares
    with the real one: the median ratio, the share of keypoints within 1× and 2× of their
    expected error, and the rank correlation of expected and real mean error across cases."""
    from scipy.stats import spearmanr

    out = ["", "Expected error (the fit's own estimate, `expected_error_mm` in the report) against the "
           "real one, per keypoint:", "",
           "| case | mean real (mm) | mean expected (mm) | median real / expected | within 1× | within 2× "
           "| rank correlation over cases |", "|---|---|---|---|---|---|---|"]
    for lab, rs in _by_case(rows):
        rs = [r for r in rs if r.get("expected_mm") is not None]
        if not rs or "λ=" in lab:
            continue
        err = np.concatenate([r["error_mm"] for r in rs])
        exp = np.concatenate([r["expected_mm"] for r in rs])
        keep = exp > 0  # the wheel centres sit on the wheelbase exactly
        ratio = err[keep] / exp[keep]
        rho = spearmanr([r["mean_mm"] for r in rs], [np.mean(r["expected_mm"]) for r in rs])[0]
        out.append(f"| {lab} | {err.mean():.1f} | {exp.mean():.1f} | {np.median(ratio):.2f} "
                   f"| {100 * np.mean(ratio <= 1):.0f} % | {100 * np.mean(ratio <= 2):.0f} % | {rho:.2f} |")
    if len(out) <= 5:
        return ""
    # where the estimate is too high or too low: the default case, view by view
    lab, rs = _default_case(rows)
    rs = [r for r in rs if r.get("expected_mm") is not None]
    if rs:
        angles = sorted({r["azimuth"] for r in rs})
        out += ["", f"{lab}, mean real / mean expected error (mm) by view:", "",
                "| " + " | ".join(f"{a}°" for a in angles) + " |", "|" + "---|" * len(angles),
                "| " + " | ".join(f"{np.mean([r['mean_mm'] for r in rs if r['azimuth'] == a]):.0f} / "
                                  f"{np.mean([np.mean(r['expected_mm']) for r in rs if r['azimuth'] == a]):.0f}"
                                  for a in angles) + " |"]
    return "\n".join(out)


def library_mean_along_errors() -> dict[str, float]:
    """{template: mean error (mm) along the car of its keypoints placed where the other
    templates' mean puts them (normalised, read at its wheelbase)}: what the library alone knows
    of the length of a car it has never seen."""
    from carbody.library import load_library
    from carbody.topology import load_topology

    lib = load_library()
    idx = load_topology().keypoint_point_indices
    along = np.array([lib.points(lib.original(t))[idx, 1] for t in range(len(lib.template_names))])
    return {name: float(np.abs(np.delete(along, t, axis=0).mean(axis=0) - along[t]).mean()
                        * lib.template_wheelbase_mm[t] / 1000.0)
            for t, name in enumerate(lib.template_names)}


def length_reference(rows: list[dict], target_mm: float = 25.0) -> str:
    """Pure front and rear views show no length: the default fit's error along the car on them,
    against the other templates' mean position along the car (what the library says with no
    photo), and what these two views alone leave the others of the issue's mean target."""
    lab, rs = _default_case(rows)
    rs = [r for r in rs if "along_mm" in r]
    views = {r["azimuth"] for r in rs}
    if not {0, 180} <= views:
        return ""
    reference = library_mean_along_errors()
    out = ["", f"Pure front and rear views ({lab}): mean error (mm), and along the car the fit's "
           "against the other templates' mean position (no photo):", "",
           "| view | 3D error | along the car: fit | library's mean |", "|---|---|---|---|"]
    both = 0.0
    for a in (0, 180):
        ra = [r for r in rs if r["azimuth"] == a]
        both += np.mean([r["mean_mm"] for r in ra])
        out.append(f"| {a}° | {np.mean([r['mean_mm'] for r in ra]):.1f} "
                   f"| {np.mean([r['along_mm'] for r in ra]):.1f} "
                   f"| {np.mean([reference[r['template']] for r in ra]):.1f} |")
    n, others = len(views), np.mean([r["mean_mm"] for r in rs if r["azimuth"] not in (0, 180)])
    need = (target_mm * n - both) / (n - 2)
    asks = (f"asks the other {n - 2} for {need:.1f} mm on average" if need > 0 else
            f"is out of reach whatever the other {n - 2} give")
    out += ["", f"The front and rear alone put {both / n:.1f} mm on the mean over the {n} views: a mean of "
            f"{target_mm:g} mm {asks} (they give {others:.1f})."]
    return "\n".join(out)


def table(label: str, rs: list[dict]) -> str:
    names = list(dict.fromkeys(r["template"] for r in rs))
    angles = sorted({r["azimuth"] for r in rs})
    out = [f"mean / max 3D keypoint error (mm), {label}", "",
           "| template | " + " | ".join(f"{a}°" for a in angles) + " | mean |",
           "|---|" + "---|" * (len(angles) + 1)]
    for n in names:
        cells = {r["azimuth"]: r for r in rs if r["template"] == n}
        out.append(f"| {n} | " + " | ".join(f"{cells[a]['mean_mm']:.0f} / {cells[a]['max_mm']:.0f}" for a in angles)
                   + f" | {np.mean([c['mean_mm'] for c in cells.values()]):.1f} |")
    out.append("| **mean / max** | " + " | ".join(
        f"{np.mean([r['mean_mm'] for r in rs if r['azimuth'] == a]):.0f} / "
        f"{max(r['max_mm'] for r in rs if r['azimuth'] == a):.0f}" for a in angles)
        + f" | {np.mean([r['mean_mm'] for r in rs]):.1f} |")
    return "\n".join(out)


#: ``--real-marks``: the synthetic camera's distance in car lengths, its elevation (degrees) and
#: the marking error (px on a 900 px car: 1 %), as a close photo taken at a person's height.
REAL_MARKS_DISTANCE, REAL_MARKS_ELEVATION, REAL_MARKS_NOISE = 1.0, 6.0, 9.0


def real_mark_sets(data: Path) -> list[tuple[str, float, list[str]]]:
    """[(photo, estimated view, the names its annotator marked)] for the real photos in ``data``
    whose estimate is a three-quarter view (``bench_real_photos.view_lean_deg``)."""
    from bench_real_photos import view_lean_deg

    sets = []
    for f in sorted(Path(data, "keypoints").glob("*.json")):
        meta = json.loads(f.read_text())
        est = meta.get("view_estimate_deg")
        if est is not None and view_lean_deg(est, est) is not None:
            sets.append((f.stem, float(est), sorted(meta["keypoints"])))
    return sets


def run_real_marks(args) -> list[dict]:
    """Template t, left out, seen from close by (:data:`REAL_MARKS_DISTANCE`) at each real photo's
    estimated view and marked only where that photo's annotator marked, fitted as a user's photo
    (no view told, the camera's distance found): how far the view found leans toward the car's end
    (−) or side (+) of the true one (``bench_real_photos.view_lean_deg``)."""
    t, sets = args
    from bench_real_photos import view_lean_deg

    from carbody.errors import CarbodyError
    from carbody.fit import fit_wireframe

    name, loo, truth, wb, _ = left_out(t)
    rng = np.random.default_rng(3000 + t)
    length = float(np.ptp(truth[:, 1]))
    rows = []
    for photo, est, names in sets:
        kps, size, _ = synthetic_view(truth, est, rng, REAL_MARKS_ELEVATION, REAL_MARKS_DISTANCE * length,
                                      noise_px=REAL_MARKS_NOISE)
        marks = {n: uv for n, uv in kps.items() if n in names}
        row = {"template": name, "photo": photo, "estimate": est, "marks": len(marks), "lean": None, "failed": None}
        try:
            fit = fit_wireframe(marks, None, loo, image_size=size, camera_distance_mm="auto")
            row.update(view=fit.view.azimuth, lean=view_lean_deg(fit.view.azimuth, est))
        except CarbodyError as e:
            row["failed"] = str(e)
        rows.append(row)
    return rows


#: ``--real-marks``: the real photos' own marks fitted again with the shape prior this many times
#: weaker (its λ over the default's, ×10).
REAL_MARKS_LOOSE_PRIOR = 0.1


def far_side(name: str, estimate: float) -> bool:
    """Whether keypoint ``name`` lies on the car's half turned away from a camera at azimuth
    ``estimate`` (0–180°: the left half faces it, so the ``_right`` names are far)."""
    return not name.endswith("_centre") and name.endswith("_right") == (estimate % 360.0 < 180.0)


def run_real_marks_own(args) -> list[dict]:
    """One real photo's own marks (three-quarter estimate): the view's lean fitted as a user's photo
    (no view told, the distance found), with the shape prior :data:`REAL_MARKS_LOOSE_PRIOR` times
    its weight, and without the marks on the car's far half."""
    data, photo = args
    from bench_real_photos import view_lean_deg

    from carbody.errors import CarbodyError
    from carbody.fit import fit_wireframe
    from carbody.fit.options import DEFAULT_PRIOR_WEIGHT
    from carbody.library import load_library

    meta = json.loads((Path(data) / "keypoints" / f"{photo}.json").read_text())
    est, size = float(meta["view_estimate_deg"]), tuple(meta["image_size"])
    marks = {n: tuple(uv) for n, uv in meta["keypoints"].items()}
    near = {n: uv for n, uv in marks.items() if not far_side(n, est)}
    row = {"photo": photo, "estimate": est, "marks": len(marks), "near_marks": len(near)}
    for key, m, weight in (("lean", marks, 1.0), ("lean_loose_prior", marks, REAL_MARKS_LOOSE_PRIOR),
                           ("lean_near_half", near, 1.0)):
        try:
            fit = fit_wireframe(m, None, load_library(), image_size=size, camera_distance_mm="auto",
                                prior_weight=DEFAULT_PRIOR_WEIGHT * weight)
            row[key] = view_lean_deg(fit.view.azimuth, est)
        except CarbodyError as e:
            row[key] = None
            row[f"{key}_failed"] = str(e)
    return [row]


def real_marks_own_table(rows: list[dict]) -> str:
    """The photos' own marks: the lean as fitted, with the looser prior, and from the near half."""
    fmt = lambda v: "failed" if v is None else f"{v:+.1f}"  # noqa: E731
    lines = ["| photo | estimate ° | marks (near half) | lean ° | prior ×0.1 | near half and centre only |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['photo'].removeprefix('cps_')} | {r['estimate']:g} | {r['marks']} ({r['near_marks']}) | "
                     f"{fmt(r['lean'])} | {fmt(r['lean_loose_prior'])} | {fmt(r['lean_near_half'])} |")
    med = {k: np.median([r[k] for r in rows if r[k] is not None]) for k in ("lean", "lean_loose_prior",
                                                                            "lean_near_half")}
    lines.append(f"\n{len(rows)} photos: median lean {med['lean']:+.1f}° as fitted, {med['lean_loose_prior']:+.1f}° "
                 f"with the prior ×{REAL_MARKS_LOOSE_PRIOR:g}, {med['lean_near_half']:+.1f}° from the near half")
    return "\n".join(lines)


def real_marks_table(rows: list[dict]) -> str:
    """Per photo the median lean over the templates, then the whole check's summary."""
    photos = sorted({r["photo"] for r in rows}, key=lambda p: [r["photo"] for r in rows].index(p))
    lines = ["| photo | estimate ° | marks | median lean ° | leans beyond 5° to the end / side | failed |",
             "|---|---|---|---|---|---|"]
    for p in photos:
        rs = [r for r in rows if r["photo"] == p]
        lean = [r["lean"] for r in rs if r["lean"] is not None]
        lines.append(f"| {p.removeprefix('cps_')} | {rs[0]['estimate']:g} | {rs[0]['marks']} | "
                     f"{np.median(lean):+.1f} | {sum(v < -5 for v in lean)} / {sum(v > 5 for v in lean)} | "
                     f"{sum(r['failed'] is not None for r in rs)} |")
    lean = np.array([r["lean"] for r in rows if r["lean"] is not None])
    lines.append(f"\n{len(rows)} fits ({len(photos)} mark sets × {len(rows) // max(len(photos), 1)} templates): "
                 f"median lean {np.median(lean):+.1f}°, mean {lean.mean():+.1f}°; beyond 5° toward the end "
                 f"{int((lean < -5).sum())}, toward the side {int((lean > 5).sum())}; beyond 15° "
                 f"{int((np.abs(lean) > 15).sum())}; failed {sum(r['failed'] is not None for r in rows)}")
    return "\n".join(lines)


def run_check(run, jobs: list, title: str, table, args) -> int:
    """A check's runs over the templates (``--other-end``, ``--orthographic-check``): its table
    under a title with the time taken, and every row as JSON with ``--json``."""
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = [r for part in pool.map(run, jobs) for r in part]
    print(f"# {title} ({time.perf_counter() - t0:.0f} s)\n")
    print(table(rows))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 templates, 5 angles")
    ap.add_argument("--sweep", action="store_true", help="also scan the prior weight λ of the default method")
    ap.add_argument("--json", help="write every row as JSON")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--elevation", type=float, default=0.0,
                    help="camera elevation of the synthetic views (degrees; given to the fit)")
    ap.add_argument("--known-only", action="store_true", help="only the view-known cases")
    ap.add_argument("--noise", type=float, default=NOISE_PX,
                    help="marking error, pixels (standard deviation on a 1000 px wide image)")
    ap.add_argument("--distance", type=float, default=None,
                    help="photograph with a pinhole camera this far from the car's centre (mm) "
                         "instead of SPEC's orthographic one, and fit it as orthographic, told the "
                         "distance, or finding it")
    ap.add_argument("--off-centre", type=float, default=0.0, metavar="DEG",
                    help="with --distance: turn the camera's axis this far off the car (the car "
                         "off the photo's centre), and compare the fit taking the camera to point "
                         "at the car (the default) with one told the axis (--principal-point centre)")
    ap.add_argument("--joint-field", metavar="AMPLITUDE[,LX,LY,LZ]",
                    help="the local deformation field inside the shape prior: its amplitude (0: "
                         "none; default JOINT_FIELD_AMPLITUDE) and correlation lengths across, "
                         "along the car and up (normalised units; default JOINT_LENGTH), to rerun "
                         "the choice")
    ap.add_argument("--broad-joint-field", action="store_true",
                    help="the deformation's broad part (FIELD_SIGMA, FIELD_LENGTH) inside the "
                         "shape prior instead of its local one, at --joint-field's amplitude")
    ap.add_argument("--outliers", metavar="N,PX",
                    help="move N random marks of each view PX pixels in a random direction (a click "
                         "on the wrong feature)")
    ap.add_argument("--swap-pair", action="store_true",
                    help="exchange the names of one random left/right pair of marks a view (the car's "
                         "left taken for the viewer's)")
    ap.add_argument("--twin-slip", action="store_true",
                    help=f"one random mark of each view also clicked {TWIN_SLIP_PX:g} px off it under its "
                         "right twin's name (one point marked under both names)")
    ap.add_argument("--no-reject", action="store_true",
                    help="keep every mark (FitOptions.robust=False)")
    ap.add_argument("--deform-length", metavar="LX,LY,LZ",
                    help="correlation lengths across, along the car and up (normalised units) of "
                         "the local part of the deformation after the fit (default LOCAL_LENGTH in "
                         "every direction); e.g. 800,120,120 correlates it across the car like the "
                         "joint field")
    ap.add_argument("--other-end", action="store_true",
                    help="only the other end: each view within OTHER_END_RANGE_DEG of the front or "
                         "rear fitted told its true view and told the car's other end (180° − θ)")
    ap.add_argument("--orthographic-check", action="store_true",
                    help="only the check that a photo fitted as orthographic was taken from close by: "
                         "each car photographed from afar and from 20, 10, 6 and 4 m, fitted as "
                         "orthographic (asked to check) and finding the distance")
    ap.add_argument("--view-off", metavar="DEG,...",
                    help="only views told this far off (e.g. 0,45,90,135): where the search lands")
    from bench_real_photos import DATA as real_photos

    ap.add_argument("--real-marks", type=Path, nargs="?", const=real_photos, default=None, metavar="DIR",
                    help="only the check of the view's lean on the real photos' three-quarter views: their own "
                         "marks fitted three ways, then library cars marked as they were (default DIR "
                         f"{real_photos})")
    ap.add_argument("--real-marks-templates", type=int, default=6, metavar="N",
                    help="--real-marks: how many left-out templates, spread over the library (default 6)")
    args = ap.parse_args(argv)
    from carbody.library import load_library

    outliers = None
    if args.outliers:
        try:
            n, px = args.outliers.split(",")
            outliers = (int(n), float(px))
        except ValueError:
            ap.error("--outliers takes N,PX (e.g. 1,40)")
    deform_length = None
    if args.deform_length:
        deform_length = tuple(float(v) for v in args.deform_length.split(","))
        if len(deform_length) != 3 or min(deform_length) <= 0:
            ap.error("--deform-length takes three lengths > 0")

    joint = None
    if args.joint_field:
        values = [float(v) for v in args.joint_field.split(",")]
        if len(values) not in (1, 4) or values[0] < 0:
            ap.error("--joint-field takes an amplitude ≥ 0, optionally followed by three lengths")
        joint = (values[0], tuple(values[1:]) or None, args.broad_joint_field)
    elif args.broad_joint_field:
        from carbody.fit.shape_prior import JOINT_FIELD_AMPLITUDE

        joint = (JOINT_FIELD_AMPLITUDE, None, True)

    n_templates = len(load_library().template_names)
    templates = [0, 5, 9] if args.quick else list(range(n_templates))
    angles = (0, 30, 90, 150, 180) if args.quick else ANGLES
    if args.other_end:
        return run_check(run_other_end, [(t, angles, args.elevation, args.noise) for t in templates],
                         f"The car's other end, leave-one-out: {len(templates)} templates, views within the "
                         f"check's range of the front or rear, elevation {args.elevation:g}°, {args.noise:g} px noise",
                         other_end_table, args)
    if args.real_marks:
        if not (args.real_marks / "keypoints").is_dir():
            print(f"bench_fit_accuracy: no real-photo marks at {args.real_marks}", file=sys.stderr)
            return 2
        sets = real_mark_sets(args.real_marks)
        picked = templates[::max(1, len(templates) // args.real_marks_templates)][:args.real_marks_templates]
        no_json = argparse.Namespace(**{**vars(args), "json": None})  # --json holds the library check's rows
        run_check(run_real_marks_own, [(args.real_marks, photo) for photo, _, _ in sets],
                  f"The real photos' own marks ({len(sets)} three-quarter views): the lean as fitted, with the shape "
                  f"prior ×{REAL_MARKS_LOOSE_PRIOR:g}, and from the marks on the car's near half and centre only",
                  real_marks_own_table, no_json)
        print()
        return run_check(run_real_marks, [(t, sets) for t in picked],
                         f"Real photos' marks on library cars, leave-one-out: {len(picked)} templates × {len(sets)} "
                         f"three-quarter mark sets, each at its photo's estimated view, camera "
                         f"{REAL_MARKS_DISTANCE:g} car length away at {REAL_MARKS_ELEVATION:g}° elevation, "
                         f"{REAL_MARKS_NOISE:g} px noise on a {CAR_SPAN} px car, no view told, distance found",
                         real_marks_table, args)
    if args.view_off:
        try:
            offsets = tuple(float(v) for v in args.view_off.split(","))
        except ValueError:
            ap.error("--view-off takes degrees separated by commas (e.g. 0,45,90)")
        return run_check(run_view_off, [(t, angles, args.elevation, args.noise, offsets) for t in templates],
                         f"Views told off, leave-one-out: {len(templates)} templates x {len(angles)} angles, "
                         f"elevation {args.elevation:g}° (given, refined), wheelbase not told, {args.noise:g} px noise",
                         view_off_table, args)
    if args.orthographic_check:
        return run_check(run_orthographic_check,
                         [(t, angles, args.elevation, args.noise, outliers) for t in templates],
                         f"Photos fitted as orthographic, leave-one-out: {len(templates)} templates x "
                         f"{len(angles)} angles, elevation {args.elevation:g}° (given, refined), wheelbase not "
                         f"told, {args.noise:g} px noise"
                         f"{f', {outliers[0]} mark(s) a view moved {outliers[1]:g} px' if outliers else ''}",
                         orthographic_check_table, args)
    cases = [("paper", None, 0.0, False, False), ("gauss", None, 0.0, False, True),
             ("gauss", None, 0.0, False, False), ("mixture", None, 0.0, False, True),
             # a user who does not know the wheelbase: the plain shape model, the error at the
             # fit's own size rescaled to the true wheelbase (its size error apart)
             ("mixture", None, 0.0, False, True, False, None, "car", None, False),
             ("mixture", None, OFFSET_DEG, True, True, True, None, "car", None, False),
             # what refining a known view costs: the image, not the start, sets where it settles
             ("mixture", None, 0.0, True, True),
             ("mixture", None, OFFSET_DEG, True, True),
             ("paper", None, OFFSET_DEG, False, False), ("paper", None, OFFSET_DEG, True, False),
             ("gauss", None, OFFSET_DEG, False, True), ("gauss", None, OFFSET_DEG, True, True),
             ("gauss", None, OFFSET_DEG, True, False)]
    if args.elevation:
        # A photo's elevation is rarely known: start the refinement level, as `carbody reconstruct` does.
        cases += [("gauss", None, OFFSET_DEG, True, True, True), ("mixture", None, OFFSET_DEG, True, True, True),
                  # does looking for a pinhole camera cost anything on an orthographic image?
                  ("mixture", None, 0.0, True, True, False, "auto"),
                  ("mixture", None, OFFSET_DEG, True, True, True, "auto")]
    if args.distance is not None:
        # A pinhole photo: the orthographic fit against one told the distance and one finding it.
        cases = [("mixture", None, 0.0, False, True), ("mixture", None, 0.0, False, True, False, "told"),
                 ("paper", None, 0.0, False, False, False, "told"),
                 ("mixture", None, 0.0, True, True), ("mixture", None, 0.0, True, True, False, "auto"),
                 ("mixture", None, OFFSET_DEG, True, True, False, "auto"),
                 # as a photo comes: azimuth 10° off, elevation and distance unknown
                 ("mixture", None, OFFSET_DEG, True, True, True, "auto"),
                 # the same with its EXIF focal length: the default then takes the axis through
                 # the photo's centre (here, through the car's) and turns by that focal length
                 ("mixture", None, OFFSET_DEG, True, True, True, "auto", "centre", "focal")]
    if args.distance is not None and args.off_centre:
        cases = [("mixture", None, 0.0, False, True, False, "told"),
                 ("mixture", None, 0.0, False, True, False, "told", "centre"),
                 ("mixture", None, 0.0, True, True, False, "auto"),
                 ("mixture", None, 0.0, True, True, False, "auto", "centre"),
                 ("mixture", None, OFFSET_DEG, True, True, True, "auto"),
                 ("mixture", None, OFFSET_DEG, True, True, True, "auto", "centre"),
                 ("mixture", None, 0.0, True, True, False, "auto", "centre", "focal"),
                 ("mixture", None, OFFSET_DEG, True, True, True, "auto", "centre", "focal")]
    if not args.elevation:
        # a level start is then the true elevation: a case so marked repeats its twin (one label)
        cases = [c for c in cases if not (len(c) > 5 and c[5] and (*c[:5], False, *c[6:]) in cases)]
    if args.known_only:
        cases = [c for c in cases if not c[2]]
    lambdas = [1e-2, 1e-3, 1e-5, 1e-6] if args.sweep else []
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers, initializer=set_joint_field, initargs=(joint, deform_length)) as pool:
        rows = [r for part in pool.map(run_template, [(t, cases, lambdas, angles, args.elevation, args.distance,
                                                          args.noise, args.off_centre, outliers, not args.no_reject,
                                                          "twin" if args.twin_slip else args.swap_pair)
                                                         for t in templates]) for r in part]
    print(f"# Single-view fit, leave-one-out: {len(templates)} templates x {len(angles)} angles, "
          f"elevation {args.elevation:g}°, "
          f"{'orthographic' if args.distance is None else f'pinhole camera at {args.distance:g} mm'}"
          f"{f', its axis {args.off_centre:g}° off the car' if args.off_centre else ''}, {args.noise:g} px noise on a {IMAGE_WIDTH} px wide image"
          f"{'' if joint is None else f', joint field {args.joint_field or joint[0]}'}"
          f"{' (the broad part)' if args.broad_joint_field else ''}"
          f"{f', deformation lengths {args.deform_length}' if deform_length else ''}"
          f"{f', {outliers[0]} mark(s) a view moved {outliers[1]:g} px' if outliers else ''}"
          f"{', one left/right pair of names exchanged' if args.swap_pair else ''}"
          f"{f', one mark a view also clicked {TWIN_SLIP_PX:g} px off under its twin' + chr(39) + 's name' if args.twin_slip else ''}"
          f"{', every mark kept' if args.no_reject else ''} "
          f"({time.perf_counter() - t0:.0f} s)\n")
    print(summarise(rows))
    print("\n" + rejections(rows))
    found = [r for r in rows if r.get("camera") == "auto" and not r.get("focal_known")
             and args.distance is not None]
    if found:
        d = np.array([np.inf if r["refined_distance_mm"] is None else r["refined_distance_mm"] for r in found])
        print(f"\nCamera distance found by the fit: median {np.median(d):.0f} mm for {args.distance:g} mm; "
              f"within 10 % in {int(np.sum(np.abs(d / args.distance - 1) < 0.1))} of {len(d)} cases.")
    print("\nWheelbase the fit estimates when none is given (the proportions'; the paper's solve: the mix's "
          "own; told the camera distance, from the perspective), error vs the truth, view known:\n")
    print("| method | mean abs. | median abs. | max abs. |")
    print("|---|---|---|---|")
    for method in dict.fromkeys(r["method"] for r in rows):
        # the fit with the right camera: SPEC's orthographic one, or the pinhole told its distance
        e = np.abs([r["wheelbase_estimate_pct"] for r in rows if r["method"] == method
                    and r["wheelbase_estimate_pct"] is not None and r["deform"] == (method != "paper")
                    and r.get("camera") == ("told" if args.distance is not None else None)])
        if len(e):
            failed = f" ({int(np.sum(np.isnan(e)))} refused: camera inside the car)" if np.isnan(e).any() else ""
            e = e[~np.isnan(e)]
            print(f"| {method} | {e.mean():.1f} % | {np.median(e):.1f} % | {e.max():.1f} %{failed} |")
    print(size_table(rows, args.distance is not None))
    print(per_car(rows))
    print(calibration(rows))
    print(length_reference(rows))
    for label, rs in _by_case(rows):
        if "λ=" in label:
            continue
        print()
        print(table(label, rs))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
