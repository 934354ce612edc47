"""How few keypoints the fit needs (issue 3: "the fit works from any subset large enough").

The leave-one-out set-up of ``bench_fit_accuracy.py`` (each template dropped from the library,
viewed, its visible keypoints projected with 1 px noise, fitted with the view known, 3D error of
all 35 keypoints in mm at the true wheelbase), but only a random subset of k of the visible
keypoints is marked, as a user in a hurry would: k = 5 (the least the fit accepts), 8, 12, 17
(the paper's front-30° set) and all. Several random subsets per template and view; a subset the
fit refuses (its points on one line) is counted, not fitted.

Run: python benchmarks/bench_fit_subsets.py [--elevation DEG] [--draws N] [--quick]
"""
from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_fit_accuracy import left_out, synthetic_view  # noqa: E402

ANGLES = (30, 60, 90, 150)
SIZES = (5, 8, 12, 17, None)  # None: every visible keypoint
METHODS = ("mixture", "paper")


def run_template(args) -> list[dict]:
    t, angles, elevation, draws = args
    from carbody.camera import View
    from carbody.errors import KeypointError
    from carbody.fit.single_view import fit_wireframe

    name, loo, truth, wb, idx = left_out(t)
    rng = np.random.default_rng(2000 + t)
    rows = []
    for azimuth in angles:
        kps, size, _ = synthetic_view(truth, azimuth, rng, elevation)
        names = sorted(kps)
        for k in SIZES:
            for draw in range(1 if k is None else draws):
                chosen = names if k is None else list(rng.choice(names, size=min(k, len(names)), replace=False))
                for method in METHODS:
                    row = {"template": name, "azimuth": azimuth, "k": k, "method": method, "marked": len(chosen)}
                    try:
                        res = fit_wireframe({n: kps[n] for n in chosen}, View(azimuth, elevation), loo,
                                            image_size=size, wheelbase_mm=wb, method=method, refine=False,
                                            camera_distance_mm=None)
                    except KeypointError:
                        rows.append({**row, "refused": True})
                        continue
                    err = np.linalg.norm(res.wireframe.control_points[idx] - truth[idx] * wb / 1000, axis=1)
                    rows.append({**row, "refused": False, "mean_mm": float(err.mean()),
                                 "max_mm": float(err.max())})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elevation", type=float, default=0.0, help="camera elevation, degrees")
    ap.add_argument("--draws", type=int, default=5, help="random subsets per template, view and size")
    ap.add_argument("--quick", action="store_true", help="3 templates, 2 draws")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    from carbody.library import load_library

    n_templates = len(load_library().template_names)
    templates = [0, 5, 9] if args.quick else list(range(n_templates))
    draws = 2 if args.quick else args.draws
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = [r for part in pool.map(run_template, [(t, ANGLES, args.elevation, draws) for t in templates])
                for r in part]
    print(f"# Fit from k of the visible keypoints, leave-one-out: {len(templates)} templates x "
          f"{len(ANGLES)} views x {draws} random subsets, elevation {args.elevation:g}°, view known, "
          f"orthographic, 1 px noise ({time.perf_counter() - t0:.0f} s, 2-core machine)\n")
    print("mean 3D keypoint error of all 35 keypoints, mm at the true wheelbase (mixture / paper); "
          "refused: subsets the fit turned down (points on one line)\n")
    print("| keypoints marked | " + " | ".join(f"{a}°" for a in ANGLES) + " | all views | refused |")
    print("|---" * (len(ANGLES) + 3) + "|")
    for k in SIZES:
        cells = []
        for a in list(ANGLES) + [None]:
            parts = []
            for method in METHODS:
                sel = [r for r in rows if r["k"] == k and r["method"] == method and not r["refused"]
                       and (a is None or r["azimuth"] == a)]
                parts.append(f"{np.mean([r['mean_mm'] for r in sel]):.0f}" if sel else "—")
            cells.append(" / ".join(parts))
        kr = [r for r in rows if r["k"] == k and r["method"] == METHODS[0]]
        label = "all visible" if k is None else str(k)
        print(f"| {label} | " + " | ".join(cells) + f" | {sum(r['refused'] for r in kr)} of {len(kr)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
