"""How steady the wheels' hubs found in a real photo are when the marks move by a careful click.

A person marking the same photo again clicks each keypoint a little elsewhere. The hubs
(:mod:`carbody.fit.wheels`) are looked for where the fit of the marks puts the wheels, so they
can move with the marks too: another hub candidate wins, or none clears the bar. This measures
that on the real photos of ``../shared/realphotos``.

For each photo with hubs found: the fit of its hand marks given the photo (the view searched,
no prior, the camera distance found, as ``carbody fit --wheels`` on a photo without EXIF), then
``--draws`` re-markings, each mark moved by isotropic noise of ``--click`` (1 %) of the car's
size in the photo (RMS radius; S as in ``bench_real_photos.py``: the part polygons' box).
Per photo and in summary:

- **kept**: of the hubs the hand marks' fit found, the share found again within 1 % of S of it;
  **lost**: not found at all; **moved**: found more than 1 % of S away; **new**: a hub the hand
  marks' fit did not find.
- **hub shift**: the median distance of a hub found again from where the hand marks' fit found
  it, % of S.
- **fit spread with / without wheels**: the mean 3D keypoint distance (mm, each car at the hand
  fit's wheelbase) of the re-marked fits from the hand marks' fit, with the photo's wheels and
  with the marks alone: what the hubs add to (or take from) the click noise's effect.

    python benchmarks/bench_wheel_stability.py [--photos cps_te20 ...] [--draws 6] [--click 0.01]
                                               [--data DIR] [--json FILE]

Skips with a note when the photos are not there (a user's clone has no ``../shared``).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_real_photos as real  # noqa: E402  (the photos, their polygons and S)

#: A hub found again within this share of S of the hand marks' hub is "kept".
SAME_HUB = 0.01


def hubs_of(fit) -> dict[str, np.ndarray]:
    """{wheel: (2,) photo px} the hubs a fit found (empty when none)."""
    return {w["wheel"]: np.array(w["found_px"]) for w in (fit.wheels.wheels or [])} if fit.wheels else {}


def keypoints_at(fit, wheelbase_mm: float) -> np.ndarray:
    """(35, 3) mm: the fit's left keypoints, the car scaled to ``wheelbase_mm``."""
    return np.array(list(fit.wireframe.keypoints().values())) * (wheelbase_mm / fit.wheelbase_mm)


def photo_stability(photo, draws: int, click: float, seed: int = 0) -> dict | None:
    """The figures of one photo (module docstring), or None when its hand marks' fit finds no hub."""
    from carbody.fit import FitOptions, fit_wireframe, read_keypoints
    from carbody.library import default_library
    from carbody.view.predict import read_image

    rgb = read_image(photo.image)
    marks = read_keypoints(photo.marks).points
    h, w = rgb.shape[:2]
    library = default_library()
    size = real.car_image_size(photo)[0]

    def fit(m: dict, wheels: bool):
        return fit_wireframe(dict(m), None, library, image_size=(w, h), photo=rgb,
                             options=FitOptions(camera_distance_mm="auto", wheels=wheels))

    with_wheels, marks_only = fit(marks, True), fit(marks, False)
    hand_hubs = hubs_of(with_wheels)
    if not hand_hubs:
        return None
    k_with = keypoints_at(with_wheels, with_wheels.wheelbase_mm)
    k_only = keypoints_at(marks_only, marks_only.wheelbase_mm)
    rng = np.random.default_rng(seed)
    sigma = click * size / np.sqrt(2.0)  # per coordinate: RMS radius click × S
    counts = {"kept": 0, "lost": 0, "moved": 0, "new": 0}
    shifts, spread_with, spread_only = [], [], []
    for _ in range(draws):
        noisy = {n: tuple(np.clip(np.add(uv, rng.normal(0.0, sigma, 2)), 0, [w - 1, h - 1])) for n, uv in marks.items()}
        a, b = fit(noisy, True), fit(noisy, False)
        spread_with.append(float(np.linalg.norm(keypoints_at(a, with_wheels.wheelbase_mm) - k_with, axis=1).mean()))
        spread_only.append(float(np.linalg.norm(keypoints_at(b, marks_only.wheelbase_mm) - k_only, axis=1).mean()))
        again = hubs_of(a)
        counts["new"] += len(set(again) - set(hand_hubs))
        for wheel, uv in hand_hubs.items():
            if wheel not in again:
                counts["lost"] += 1
                continue
            shift = float(np.linalg.norm(again[wheel] - uv))
            shifts.append(100.0 * shift / size)
            counts["kept" if shift <= SAME_HUB * size else "moved"] += 1
    tries = draws * len(hand_hubs)
    return {"photo": photo.name, "hubs": sorted(hand_hubs), "draws": draws, "tries": tries, **counts,
            "kept_share": counts["kept"] / tries, "median_shift_pct": float(np.median(shifts)) if shifts else None,
            "spread_with_wheels_mm": float(np.mean(spread_with)), "spread_marks_only_mm": float(np.mean(spread_only))}


def table(rows: list[dict]) -> str:
    lines = ["| photo | hubs | kept / lost / moved (new) of tries | median hub shift, % of S "
             "| fit spread with / without wheels, mm |", "|---|---|---|---|---|"]
    for r in rows:
        shift = "" if r["median_shift_pct"] is None else f"{r['median_shift_pct']:.2f}"
        lines.append(f"| {r['photo'].removeprefix('cps_')} | {len(r['hubs'])} "
                     f"| {r['kept']} / {r['lost']} / {r['moved']} ({r['new']}) of {r['tries']} | {shift} "
                     f"| {r['spread_with_wheels_mm']:.0f} / {r['spread_marks_only_mm']:.0f} |")
    return "\n".join(lines)


def summary(rows: list[dict]) -> dict:
    tries = sum(r["tries"] for r in rows)
    return {"photos": len(rows), "tries": tries,
            **{k: sum(r[k] for r in rows) for k in ("kept", "lost", "moved", "new")},
            "kept_share": sum(r["kept"] for r in rows) / tries if tries else None,
            "median_spread_with_wheels_mm": real.median_or_none(r["spread_with_wheels_mm"] for r in rows),
            "median_spread_marks_only_mm": real.median_or_none(r["spread_marks_only_mm"] for r in rows)}


def main(argv: list[str] | None = None) -> int:
    from threadpoolctl import threadpool_limits

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "realphotos")
    parser.add_argument("--photos", nargs="*", default=None, help="photos by name (default: all)")
    parser.add_argument("--draws", type=int, default=6, help="re-markings per photo")
    parser.add_argument("--click", type=float, default=0.01, help="click noise, share of the car's size in the photo")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    if not (args.data / "keypoints").is_dir():
        print(f"note: {args.data} is not here: nothing to measure")
        return 0
    photos = real.select(real.load_photos(args.data), args.photos)
    load = os.getloadavg()
    rows = []
    with threadpool_limits(1):
        for photo in photos:
            row = photo_stability(photo, args.draws, args.click)
            if row is not None:
                rows.append(row)
                print(f"{photo.name}: {row['kept']} kept, {row['lost']} lost, {row['moved']} moved, {row['new']} new "
                      f"of {row['tries']}", flush=True)
    load_end = os.getloadavg()
    s = summary(rows)
    print(f"\nmachine: {os.cpu_count()} cores, 1 BLAS thread; load average {load[0]:.1f} at the start, "
          f"{load_end[0]:.1f} at the end\n")
    print(table(rows))
    if rows:
        print(f"\n{s['photos']} photos with hubs; of {s['tries']} tries {s['kept']} kept ({s['kept_share']:.0%}), "
              f"{s['lost']} lost, {s['moved']} moved, {s['new']} new; median fit spread "
              f"{s['median_spread_with_wheels_mm']:.0f} mm with wheels, "
              f"{s['median_spread_marks_only_mm']:.0f} mm without")
    if args.json:
        args.json.write_text(json.dumps({"load_start": load, "load_end": load_end, "rows": rows, "summary": s},
                                        indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
