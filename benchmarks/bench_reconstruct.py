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
    from carbody.fit.report import keypoint_errors_mm
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
    errors = keypoint_errors_mm(result.wireframe, truth)
    scaled = result.wireframe.control_points * truth.measure()["wheelbase_mm"] / result.fit.wheelbase_mm
    from carbody.wireframe import Wireframe

    errors_true_wb = keypoint_errors_mm(Wireframe("scaled", scaled), truth)
    print("| measure | value |\n|---|---|")
    print(f"| `carbody reconstruct` (view by classifier), fresh process, median of {runs} | {statistics.median(walls):.2f} s |")
    for key in stages[0]:
        print(f"| stage `{key}`, warm process, median of {runs} | {statistics.median(s[key] for s in stages):.3f} s |")
    print(f"| view found | {result.fit.view.azimuth:.1f}° (true 30°), classifier {result.view_prediction.class_deg:.0f}° |")
    print(f"| wheelbase fitted / true | {result.fit.wheelbase_mm:.0f} / {truth.measure()['wheelbase_mm']:.0f} mm |")
    print(f"| 3D keypoint error, fitted wheelbase: mean / max | {statistics.mean(errors.values()):.1f} / {max(errors.values()):.1f} mm |")
    print(f"| 3D keypoint error, true wheelbase: mean / max | {statistics.mean(errors_true_wb.values()):.1f} / {max(errors_true_wb.values()):.1f} mm |")


if __name__ == "__main__":
    main()
