"""The fitted car's proportions on renders made like the real photos: is there a bias?

On the real photos the fitted cars come out narrow for their wheelbase (``bench_real_photos.py``,
"median signed width ÷ wheelbase error"). This asks whether the fit itself does that, with
marks as sparse and noisy as a person's: each template left out of the library
(``bench_fit_accuracy.left_out``), photographed by a pinhole camera from ``--distance`` mm at 5°
elevation from the front and rear three-quarters, ``--marks`` of its visible keypoints kept at
random with ``--noise`` px of noise, fitted as ``carbody reconstruct`` fits a photo (no view,
every view searched from a flat prior, the distance found, no wheelbase told). Printed: the
median and mean signed errors of the fitted length and width in wheelbases (the sampled curves'
extents, as :mod:`carbody.fit.size` measures them), of the wheelbase the proportions give, and
of the azimuth toward the side (+: the view found more side-on than the truth), and how many
views were found within 15° of the truth.

``--front`` keeps only the marks a person sees best on the car's front (nose, bonnet and bumper
corners, windshield corners) instead: the photo marked only there.

Run: python benchmarks/bench_proportions.py [--distance 4000] [--marks 12 | --front] [--noise 4] [--every 1]
    [--json OUT.json]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_fit_accuracy import left_out, synthetic_view  # noqa: E402

#: Front and rear three-quarter views, both sides (degrees).
VIEWS = (35, 55, 305, 325, 145, 215)
ELEVATION_DEG = 5.0


#: ``--front``: the marks a person sees best on a car's front (a photo marked only there), by
#: their left names; both twins are kept where the view sees them.
FRONT_MARKS = ("nose_centre", "front_top_corner", "roof_front_corner", "a_pillar_base", "front_bottom_corner")


def fit_rows(t: int, distance_mm: float, marks: int, noise_px: float, only: tuple[str, ...] = ()) -> list[dict]:
    """One left-out template's rows, one per view (``only``: the marks of these left names and
    their twins, at the views that see five of them or more, instead of ``marks`` at random)."""
    from carbody.fit import FitOptions, ViewPrior, fit_wireframe
    from carbody.view.labels import CLASS_ANGLES_DEG
    from carbody.wireframe import sample_curves

    name, loo, truth, wb, _ = left_out(t)
    rng = np.random.default_rng(3000 + t)
    samples = sample_curves(truth, 64).reshape(-1, 3)
    true_length, true_width = np.ptp(samples[:, 1]) / 1000.0, 2.0 * samples[:, 0].max() / 1000.0
    flat = ViewPrior.from_classifier(CLASS_ANGLES_DEG, np.full(len(CLASS_ANGLES_DEG), 1.0 / len(CLASS_ANGLES_DEG)))
    options = FitOptions(camera_distance_mm="auto", check_orthographic=True)
    rows = []
    for azimuth in VIEWS:
        kps, size, _ = synthetic_view(truth, azimuth, rng, ELEVATION_DEG, distance_mm * 1000.0 / wb, noise_px)
        # drawn with ``only`` too, so that every view's noise is the same in both kinds of run
        keep = rng.choice(sorted(kps), size=min(marks, len(kps)), replace=False)
        if only:
            keep = [k for k in sorted(kps) if k.removesuffix("_right") in only]
            if len(keep) < 5:
                continue
        res = fit_wireframe({k: kps[k] for k in keep}, flat, loo, image_size=size, options=options)
        turn = (res.view.azimuth - azimuth + 180.0) % 360.0 - 180.0
        side_on = turn if (azimuth % 180.0) < 90.0 else -turn
        rows.append({"template": name, "azimuth": azimuth, "marks": len(keep),
                     "length_over_wheelbase_pct": 100.0 * (res.size.proportions["length"] / true_length - 1.0),
                     "width_over_wheelbase_pct": 100.0 * (res.size.proportions["width"] / true_width - 1.0),
                     "wheelbase_pct": 100.0 * (res.wheelbase_mm / wb - 1.0),
                     "azimuth_toward_side_deg": float(side_on), "azimuth_error_deg": abs(float(turn))})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--distance", type=float, default=4000.0, help="camera distance from the car's centre, mm")
    ap.add_argument("--marks", type=int, default=12, help="visible keypoints kept at random per view")
    ap.add_argument("--noise", type=float, default=4.0, help="marking noise, px (1000 px wide image)")
    ap.add_argument("--every", type=int, default=1, help="every n-th template (1: all)")
    ap.add_argument("--front", action="store_true",
                    help="instead of --marks at random, only the front's marks (FRONT_MARKS) the view sees")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args(argv)
    from threadpoolctl import threadpool_limits

    from carbody.library import load_library

    start = time.perf_counter()
    rows = []
    with threadpool_limits(1):
        for t in range(0, len(load_library().template_names), args.every):
            rows += fit_rows(t, args.distance, args.marks, args.noise, FRONT_MARKS if args.front else ())
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    marks = "the front's marks only" if args.front else f"{args.marks} marks"
    print(f"# {len(rows)} fits: {len({r['template'] for r in rows})} templates left out x "
          f"{len({r['azimuth'] for r in rows})} views, {marks}, {args.noise:g} px noise, camera {args.distance:.0f} mm away; "
          f"{time.perf_counter() - start:.0f} s\n")
    print("| signed error | median | mean | sd |")
    print("|---|---|---|---|")
    for key, label in (("width_over_wheelbase_pct", "width ÷ wheelbase, %"),
                       ("length_over_wheelbase_pct", "length ÷ wheelbase, %"),
                       ("wheelbase_pct", "wheelbase from the proportions, %"),
                       ("azimuth_toward_side_deg", "view toward the side, °")):
        v = np.array([r[key] for r in rows])
        print(f"| {label} | {np.median(v):+.1f} | {v.mean():+.1f} | {v.std():.1f} |")
    errors = np.array([r["azimuth_error_deg"] for r in rows])
    print(f"\nviews found within 15° of the truth: {int((errors <= 15).sum())} of {len(rows)}; "
          f"over 60° off (the car's other side or end): {int((errors > 60).sum())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
