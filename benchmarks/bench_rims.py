"""How well the rear wheels' rims read a car's view: renders of library cars at known views.

``bench_real_photos.py`` checks the real photos' views, estimated by eye, against a second
reading taken from the photo's rear wheels alone (:func:`bench_real_photos.rims_view`). This is
that reading's own check. Each chosen template is left out of the library, surfaced, rendered
as the shipped example is (``bench_end_to_end.photograph``: a pinhole 7 m from the car at 6°
elevation, tyres and rims in the wheel wells), marked by projecting its keypoints with 1 px of
noise, and reconstructed with the view searched. The rims are then read from every rear wheel
the fit found, however much the fit weighed it. Per view and in all: the rims' error and the
view found's error against the view rendered, in degrees.

    python benchmarks/bench_rims.py [--templates 4] [--views 30 45 60 135 150 210 300 320] [--json FILE]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_end_to_end as e2e  # noqa: E402  (the renders)
import bench_real_photos as real  # noqa: E402  (the rims' reading)

#: Three-quarter views on both sides, near the front and near the rear.
VIEWS = (30, 45, 60, 135, 150, 210, 300, 320)


def run(template_count: int, views: tuple[int, ...]) -> list[dict]:
    """One row per (template, view): the rims' readings and the view found, degrees off the truth."""
    import carbody
    from carbody.fit.report import camera_report
    from carbody.library import load_library
    from carbody.wireframe import Wireframe

    library = load_library()
    picks = np.linspace(0, len(library.template_names) - 1, template_count).round().astype(int)
    rows = []
    for t in picks:
        name = library.template_names[t]
        wb = float(library.template_wheelbase_mm[t])
        truth = Wireframe(name, library.points(library.original(t)) * wb / 1000.0)
        rng = np.random.default_rng(3000 + int(t))
        for view in views:
            image, marks = e2e.photograph(truth, view, rng)
            start = time.perf_counter()
            result = carbody.reconstruct(image, marks, library=library.without(name), name=name)
            fit = result.fit
            wheels = fit.wheels.as_dict() if fit.wheels is not None else None
            rims = real.rims_view(image, camera_report(fit), fit.wireframe.control_points, wheels, min_weight=0.0)
            rows.append({"template": name, "view": view, "view_off_deg": real.angular_offset(fit.view.azimuth, view),
                         "rims_off_deg": {w: real.angular_offset(a, view) for w, a in rims.items()},
                         "rear_hubs_found": sum(w["wheel"].startswith("rear")
                                                for w in (wheels or {}).get("wheels", [])),
                         "seconds": time.perf_counter() - start})
            print(f"{name} at {view}°: view found {rows[-1]['view_off_deg']:+.1f}°, rims "
                  f"{ {w: round(d, 2) for w, d in rows[-1]['rims_off_deg'].items()} }", file=sys.stderr, flush=True)
    return rows


def table(rows: list[dict], views: tuple[int, ...]) -> str:
    lines = ["| view rendered | cars | rear hubs found | rims read | rims' error, median / max \\|°\\| "
             "| view found's error, median / max \\|°\\| |", "|---|---|---|---|---|---|"]

    def line(label: str, rs: list[dict]) -> str:
        rims = [abs(d) for r in rs for d in r["rims_off_deg"].values()]
        found = [abs(r["view_off_deg"]) for r in rs]
        pair = (lambda v: f"{statistics.median(v):.2f} / {max(v):.2f}" if v else "–")
        return (f"| {label} | {len(rs)} | {sum(r['rear_hubs_found'] for r in rs)} | {len(rims)} | {pair(rims)} "
                f"| {pair(found)} |")
    lines += [line(f"{v}°", [r for r in rows if r["view"] == v]) for v in views]
    lines.append(line("all", rows))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--templates", type=int, default=4, help="templates, spread over the library (default 4)")
    ap.add_argument("--views", type=int, nargs="+", default=list(VIEWS), help="azimuths rendered, degrees")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = ap.parse_args(argv)
    if args.templates < 1:
        print("bench_rims: --templates must be at least 1", file=sys.stderr)
        return 2
    from threadpoolctl import threadpool_limits

    load_start = os.getloadavg()
    with threadpool_limits(1):
        rows = run(args.templates, tuple(args.views))
    print(real.machine_line(load_start, 1, False, 1) + "\n")
    print(table(rows, tuple(args.views)))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
