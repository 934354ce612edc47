"""End to end: the shipped example photo -> all output files, and its accuracy against the truth.

Times `carbody reconstruct` in fresh processes (imports included, as a user runs it) and the
stages in one warm process; prints Markdown. Run: .venv/bin/python benchmarks/bench_reconstruct.py
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EX = REPO / "examples"


def main(runs: int = 3) -> None:
    import carbody
    from carbody.wireframe import read_wireframe

    print(f"machine: {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}")
    walls = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "carbody", "reconstruct", str(EX / "car.png"), "-k",
                            str(EX / "car_keypoints.json"), "-o", out], check=True, capture_output=True)
            walls.append(time.perf_counter() - start)
    stages = []
    for _ in range(runs):
        result = carbody.reconstruct(EX / "car.png", EX / "car_keypoints.json")
        with tempfile.TemporaryDirectory() as out:
            result.write(out)
        stages.append(result.timings_s)
    truth = read_wireframe(EX / "car_truth.step")
    fit = result.report(truth)["fit"]
    print("| measure | value |\n|---|---|")
    print(f"| `carbody reconstruct` (view by classifier), fresh process, median of {runs} | {statistics.median(walls):.2f} s |")
    for key in stages[0]:
        print(f"| stage `{key}`, warm process, median of {runs} | {statistics.median(s[key] for s in stages):.3f} s |")
    print(f"| view found | {result.fit.view.azimuth:.1f}° (true 30°), classifier {result.view_prediction.class_deg:.0f}° |")
    print(f"| wheelbase fitted / true | {fit['wheelbase_mm']:.0f} / {fit['truth_wheelbase_mm']:.0f} mm |")
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_example", EX / "make_example.py")
    make_example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_example)
    CAMERA_DISTANCE_MM = make_example.CAMERA_DISTANCE_MM
    found = result.fit.camera_distance_mm
    print(f"| camera distance found / true | {'orthographic' if found is None else f'{found:.0f}'} / "
          f"{CAMERA_DISTANCE_MM:.0f} mm |")
    print(f"| 3D keypoint error, fitted wheelbase: mean / max | {fit['error_mm_mean']:.1f} / {fit['error_mm_max']:.1f} mm |")
    print(f"| 3D keypoint error, true wheelbase: mean / max | {fit['error_mm_at_truth_wheelbase_mean']:.1f} / "
          f"{fit['error_mm_at_truth_wheelbase_max']:.1f} mm |")


if __name__ == "__main__":
    main()
