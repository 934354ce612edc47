"""A tilted photo: the fit that finds the camera's roll against one that keeps it level.

Each of the library's cars (every ``--every``-th) is left out and photographed (orthographic,
SPEC's camera) at each of ``--azimuths`` from ``--elevation`` with the camera rolled by each of
``--rolls``. Its visible keypoints (the car 900 px wide, or 500 px high, on a 1000 × 600 px
photo) get ``--noise`` px of click noise. They are fitted with nothing told but the true
wheelbase, twice: as ``carbody fit`` does (the roll refined where the marks pay for it,
:func:`carbody.fit.search.with_roll`) and with the roll kept level (``FitPolicy.roll_range_deg``
0, the fit before). Per roll it prints the mean
3D keypoint error (mm), the median azimuth error and the median roll found; per roll and
azimuth the mean error of both fits.

Run: python benchmarks/bench_roll.py [--every 3] [--rolls 0,2,4,6] [--workers 2]
"""
from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np


def run_template(args: tuple) -> list[dict]:
    """Rows of one left-out template (module docstring)."""
    from threadpoolctl import threadpool_limits

    from carbody.camera import View, project
    from carbody.fit import fit_wireframe
    from carbody.fit.visibility import visible_slots
    from carbody.library import default_library
    from carbody.policy import FIT_POLICY
    from carbody.topology import load_topology

    t, azimuths, rolls, elevation, noise = args
    library = default_library()
    name = library.template_names[t]
    loo, truth = library.without(name), library.points(library.original(t))
    wb = library.template_wheelbase_mm[t]
    kp = load_topology().keypoint_point_indices
    level = replace(FIT_POLICY, roll_range_deg=0.0)
    rows = []
    with threadpool_limits(1):
        for azimuth in azimuths:
            for roll in rolls:
                view = View(azimuth, elevation, roll)
                slots = visible_slots(view, truth)
                points = np.array([truth[s.point_index] * s.sign for s in slots])
                uv = project(points, view)
                scale = min(900.0 / max(np.ptp(uv[:, 0]), 1e-9), 500.0 / max(np.ptp(uv[:, 1]), 1e-9))
                uv = (uv - (uv.min(axis=0) + uv.max(axis=0)) / 2) * scale + [500.0, 300.0]
                rng = np.random.default_rng([t, int(azimuth), int(round(roll * 10))])
                marks = {s.name: tuple(p) for s, p in zip(slots, uv + rng.normal(0.0, noise, uv.shape))}
                for fit_name, policy in (("found", FIT_POLICY), ("level", level)):
                    res = fit_wireframe(marks, None, loo, image_size=(1000, 600), wheelbase_mm=wb, policy=policy)
                    cp = res.wireframe.control_points / res.mm_per_unit
                    error = float(np.linalg.norm(cp[kp] - truth[kp], axis=1).mean()) * res.mm_per_unit
                    rows.append({"template": name, "azimuth": azimuth, "roll": roll, "fit": fit_name,
                                 "error_mm": error, "roll_found": float(res.view.roll),
                                 "azimuth_error": float(abs((res.view.azimuth - azimuth + 180.0) % 360.0 - 180.0))})
    return rows


def _mean(rows: list[dict], key: str) -> float:
    return float(np.mean([r[key] for r in rows]))


def _median(rows: list[dict], key: str) -> float:
    return float(np.median([r[key] for r in rows]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=int, default=3, help="every N-th template of the library (default 3)")
    ap.add_argument("--azimuths", default="30,60,90,135", help="views, degrees (default 30,60,90,135)")
    ap.add_argument("--rolls", default="0,2,4,6", help="camera rolls, degrees (default 0,2,4,6)")
    ap.add_argument("--elevation", type=float, default=10.0, help="camera elevation, degrees (default 10)")
    ap.add_argument("--noise", type=float, default=1.0, help="click noise, px on a 1000 px wide image (default 1)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    from carbody.library import default_library

    azimuths = [float(a) for a in args.azimuths.split(",")]
    rolls = [float(r) for r in args.rolls.split(",")]
    templates = list(range(0, len(default_library().template_names), args.every))
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = [r for part in pool.map(run_template, [(t, azimuths, rolls, args.elevation, args.noise)
                                                       for t in templates]) for r in part]
    print(f"# A tilted photo: {len(templates)} cars left out x {len(azimuths)} views x {len(rolls)} rolls, "
          f"elevation {args.elevation:g}°, {args.noise:g} px noise, wheelbase told "
          f"({time.perf_counter() - start:.0f} s)\n")
    print("| camera roll | mean error, roll found / kept level (mm) | median azimuth error, found / level (°) "
          "| median roll found (°) | fits that kept it level |")
    print("|---|---|---|---|---|")
    for roll in rolls:
        found = [r for r in rows if r["roll"] == roll and r["fit"] == "found"]
        level = [r for r in rows if r["roll"] == roll and r["fit"] == "level"]
        print(f"| {roll:g}° | {_mean(found, 'error_mm'):.1f} / {_mean(level, 'error_mm'):.1f} "
              f"| {_median(found, 'azimuth_error'):.1f} / {_median(level, 'azimuth_error'):.1f} "
              f"| {_median(found, 'roll_found'):.1f} "
              f"| {sum(r['roll_found'] == 0.0 for r in found)} of {len(found)} |")
    print("\n| camera roll | " + " | ".join(f"{a:g}°: found / level (mm)" for a in azimuths) + " |")
    print("|---|" + "---|" * len(azimuths))
    for roll in rolls:
        cells = []
        for a in azimuths:
            pair = [np.mean([r["error_mm"] for r in rows if r["roll"] == roll and r["azimuth"] == a and r["fit"] == f])
                    for f in ("found", "level")]
            cells.append(f"{pair[0]:.1f} / {pair[1]:.1f}")
        print(f"| {roll:g}° | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
