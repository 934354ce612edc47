"""The length move on renders-free cars: does the table's length help where an end is unmarked?

The fit moves the car's length in wheelbases toward the one the table of published cars reads
from its proportions (``FitPolicy.size_length_move``, :func:`carbody.fit.single_view._lengthened`).
This runs it on and off side by side. Each of the library's templates is left out of the library
and, where it is a row, of the table too (in the worker, for its own fits). It is seen from the
four three-quarter views at 10° elevation (where one end recedes) and its visible keypoints are
projected with 1 px of noise (``bench_fit_accuracy.synthetic_view``). Three sets of marks:

- ``all``: every visible keypoint;
- ``keep80``: each kept with chance 0.8, as ``bench_real_resample`` re-marks a photo;
- ``far_end_out``: the keypoints more than a quarter wheelbase past the far wheel's arch left
  out, as people leave a receding end unmarked.

No wheelbase is told and the view is known. Per set and setting: the length in wheelbases
against the truth, the length in mm (with the wheelbase the proportions give), and the mean 3D
error of the 35 keypoints at the true wheelbase.

Run: python benchmarks/bench_length_move.py [--templates N] [--workers 2] [--json OUT.json]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_fit_accuracy import left_out, synthetic_view  # noqa: E402

VIEWS = (30, 150, 210, 330)
ELEVATION = 10.0
MODES = ("all", "keep80", "far_end_out")


def chosen_marks(kps: dict, truth: np.ndarray, azimuth: float, mode: str, rng: np.random.Generator) -> dict:
    """The marks of ``mode`` (module docstring) from the visible ones ``kps``."""
    from carbody.fit.keypoints_io import keypoint_slots
    from carbody.topology import load_topology

    if mode == "all":
        return dict(kps)
    if mode == "keep80":
        return {n: p for n, p in sorted(kps.items()) if rng.random() < 0.8}
    topo = load_topology()
    slots = keypoint_slots(topo)
    front = truth[topo.junction_point_index("front_arch_top"), 1]
    rear = truth[topo.junction_point_index("rear_arch_top"), 1]
    reach = 0.25 * (rear - front)
    front_view = azimuth < 90 or azimuth > 270  # the rear recedes
    return {n: p for n, p in kps.items()
            if not (truth[slots[n].point_index, 1] > rear + reach if front_view
                    else truth[slots[n].point_index, 1] < front - reach)}


def run_template(t: int) -> list[dict]:
    """Every view, set of marks and setting of template ``t``, left out (module docstring)."""
    from dataclasses import replace

    from threadpoolctl import threadpool_limits

    import carbody.fit.size as size
    from carbody.camera import View
    from carbody.errors import CarbodyError
    from carbody.fit.options import FitOptions
    from carbody.fit.single_view import fit_wireframe
    from carbody.policy import FIT_POLICY

    threadpool_limits(1)
    name, loo, truth, wb, idx = left_out(t)
    shipped = size.published_cars
    table = shipped()
    if name in table.names:
        without = table.without(name)
        size.published_cars = lambda: without
    rows = []
    try:
        for azimuth in VIEWS:
            rng = np.random.default_rng([3000, t, azimuth])
            kps, image_size, _ = synthetic_view(truth, azimuth, rng, ELEVATION)
            true_ratio = np.ptp(truth[:, 1]) / 1000.0
            for mode in MODES:
                marks = chosen_marks(kps, truth, azimuth, mode, rng)
                for move in (False, True):
                    row = {"template": name, "azimuth": azimuth, "mode": mode, "move": move, "marks": len(marks),
                           "table_left_out": name in table.names}
                    options = FitOptions(policy=replace(FIT_POLICY, size_length_move=move))
                    try:
                        res = fit_wireframe(marks, View(azimuth, ELEVATION), loo, image_size=image_size,
                                            refine=False, camera_distance_mm=None, options=options)
                    except CarbodyError as exc:
                        rows.append({**row, "refused": str(exc)})
                        continue
                    cp = res.wireframe.control_points
                    length = float(np.ptp(cp[:, 1]))
                    at_true = cp[idx] / res.wheelbase_mm * wb
                    rows.append({**row, "refused": None,
                                 "ratio_err_pct": 100.0 * (length / res.wheelbase_mm / true_ratio - 1.0),
                                 "length_err_pct": 100.0 * (length / (true_ratio * wb) - 1.0),
                                 "mean_mm": float(np.linalg.norm(at_true - truth[idx] * wb / 1000.0, axis=1).mean()),
                                 "length_move_pct": 100.0 * res.size.length_move})
    finally:
        size.published_cars = shipped
    return rows


def summary_table(rows: list[dict]) -> str:
    lines = ["| marks | length move | fits | \\|length ÷ wheelbase\\| %: median / mean | \\|length\\| %: median / mean "
             "| 3D mean mm | moved more than 1 % |",
             "|---|---|---|---|---|---|---|"]
    for mode in MODES:
        for move in (False, True):
            rs = [r for r in rows if r["mode"] == mode and r["move"] == move and not r["refused"]]
            if not rs:
                continue
            ratio = np.abs([r["ratio_err_pct"] for r in rs])
            length = np.abs([r["length_err_pct"] for r in rs])
            moved = sum(abs(r["length_move_pct"]) > 1.0 for r in rs)
            lines.append(f"| {mode} | {'on' if move else 'off'} | {len(rs)} | {np.median(ratio):.2f} / "
                         f"{ratio.mean():.2f} | {np.median(length):.2f} / {length.mean():.2f} | "
                         f"{np.mean([r['mean_mm'] for r in rs]):.1f} | {moved} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from carbody.library import load_library

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--templates", type=int, default=None, help="the first N templates (default all)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = ap.parse_args(argv)
    count = len(load_library().template_names)
    templates = range(count if args.templates is None else min(args.templates, count))
    load, start = os.getloadavg(), time.perf_counter()
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        rows = [r for rs in pool.map(run_template, templates) for r in rs]
    print(f"machine: {os.cpu_count()} cores, load {load[0]:.1f} at the start; {args.workers} workers; "
          f"{time.perf_counter() - start:.0f} s in all; {len(templates)} templates, views {VIEWS} at "
          f"{ELEVATION:.0f}°\n")
    print(summary_table(rows))
    refused = [r for r in rows if r["refused"]]
    if refused:
        print(f"\n{len(refused)} fits refused: " + "; ".join(f"{r['template']} {r['azimuth']} {r['mode']}"
                                                          for r in refused[:5]))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
