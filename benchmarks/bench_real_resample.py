"""The real photos marked by another hand: how much the outcome hangs on which marks were clicked.

Issue 24 is measured on other photos like ``../shared/realphotos``, marked by other people. This
benchmark asks what another careful annotator would change. Each photo is reconstructed (as
``carbody reconstruct`` does: no view, no wheelbase, the classifier's prior, the photo's
wheels) from its own marks, and then from ``--draws`` re-markings of them. A re-marking keeps
each mark with probability ``--keep`` (at least :data:`MIN_MARKS`), and moves each kept mark
by Gaussian noise of ``--noise`` % of the car's image size per coordinate (the data's own
clicks err by 1-1.5 %). A photo's re-markings are drawn from ``--seed`` and its place among the
data's photos, so ``--photos NAME`` redraws what the full run drew for it.

Per photo and in summary it prints the outcomes (a body, a one-line refusal, anything else), how
many views found lie within 15° of the estimate, how far the re-markings' views lie from the
photo's own fit, and |length| and |wheelbase| errors against the published figures. Fits run
in a pool of warm processes (one BLAS thread each), so the times are not a fresh process's.

Most of these photos' cars are rows of the table of published cars the fit sizes a car by.
``--table-without-car`` leaves each photo's rows out of it for its runs (those with its published
length and wheelbase), so the size is read as it is for a car the table lacks.

Run: python benchmarks/bench_real_resample.py [--draws 4] [--keep 0.8] [--noise 0.5] [--seed 0]
     [--workers 2] [--photos N | NAME ...] [--table-without-car] [--json OUT.json]
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
from bench_real_photos import (DATA, VIEW_OK_DEG, Photo, car_image_size, fmt, load_photos,  # noqa: E402
                               median_or_none, pct_error, select)

#: A re-marking keeps at least this many marks (or all the photo has, when fewer).
MIN_MARKS = 6



def remarked(marks: dict[str, list[float]], rng: np.random.Generator, keep: float, noise_px: float,
             image_size: tuple[int, int] | None = None) -> dict:
    """A re-marking of ``marks`` (module docstring): each kept with probability ``keep``, at least
    :data:`MIN_MARKS`, each kept one moved by N(0, noise_px) per coordinate; given the image's
    (width, height), a mark moved off it is clicked at its edge."""
    names = sorted(marks)
    kept = [n for n in names if rng.random() < keep]
    if len(kept) < min(MIN_MARKS, len(names)):
        kept = sorted(str(n) for n in rng.choice(names, size=min(MIN_MARKS, len(names)), replace=False))
    moved = {n: (float(marks[n][0] + rng.normal(0, noise_px)), float(marks[n][1] + rng.normal(0, noise_px)))
             for n in kept}
    if image_size is None:
        return moved
    w, h = image_size
    return {n: (float(np.clip(u, 0, w - 1)), float(np.clip(v, 0, h - 1))) for n, (u, v) in moved.items()}


def _init_worker() -> None:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def same_car_rows(photo: Photo) -> tuple[str, ...]:
    """The rows of the size table (``carbody/data/car_dimensions.csv``) that are the photo's car,
    or read as it: those with its published length and wheelbase (to 1 mm)."""
    from carbody.fit.size import DIMENSIONS, published_cars

    published = photo.meta.get("published_mm") or {}
    if "length" not in published or "wheelbase" not in published:
        return ()
    table = published_cars()
    length, wheelbase = DIMENSIONS.index("length_mm"), DIMENSIONS.index("wheelbase_mm")
    return tuple(n for n, d in zip(table.names, table.dimensions)
                 if abs(d[length] - published["length"]) <= 1 and abs(d[wheelbase] - published["wheelbase"]) <= 1)


def run_one(task: tuple) -> dict:
    """Reconstruct one (photo, draw, marks, size-table rows to leave out); draw 0 is the photo's
    own marks. Rows left out are taken out of the table the fit sizes the car by, in this worker
    process, for this run only."""
    import carbody.fit.size as size
    from carbody.errors import CarbodyError, FitRefused
    from carbody.pipeline import reconstruct

    photo, draw, marks, left_out = task
    shipped = size.published_cars
    if left_out:
        without = shipped().without(*left_out)
        size.published_cars = lambda: without
    row = {"photo": photo.name, "draw": draw, "marks": len(marks), "outcome": None, "message": None,
           "view_deg": None, "length_mm": None, "wheelbase_mm": None, "seconds": None,
           "table_left_out": list(left_out)}
    start = time.perf_counter()
    try:
        rec = reconstruct(str(photo.image), marks)
    except FitRefused as exc:
        row.update(outcome="refused", message=str(exc))
    except CarbodyError as exc:
        row.update(outcome="error", message=str(exc))
    except Exception as exc:  # noqa: BLE001 - a traceback is what this benchmark counts
        row.update(outcome="traceback", message=f"{type(exc).__name__}: {exc}")
    else:
        sizes = rec.wireframe.measure()
        row.update(outcome="body", view_deg=float(rec.fit.view.azimuth) % 360.0,
                   length_mm=sizes["length_mm"], wheelbase_mm=sizes["wheelbase_mm"])
    finally:
        size.published_cars = shipped
    row["seconds"] = time.perf_counter() - start
    return row


def tasks(photos: list[Photo], draws: int, keep: float, noise_pct: float, seed: int,
          order: list[str] | None = None, table_without_car: bool = False) -> list[tuple]:
    """(photo, draw, marks, size-table rows to leave out) to run: each photo's own marks (draw
    0), then its re-markings. Each photo's draws are seeded by ``seed`` and its place in
    ``order`` (the data's photo names, in the order the full run takes them; default
    ``photos``), so a run of some photos draws what the full run drew for them. With
    ``table_without_car`` each photo's car is left out of the size table (:func:`same_car_rows`)."""
    order = [p.name for p in photos] if order is None else order
    out = []
    for photo in photos:
        marks = photo.meta["keypoints"]
        size, _ = car_image_size(photo)
        left_out = same_car_rows(photo) if table_without_car else ()
        out.append((photo, 0, {k: tuple(v) for k, v in marks.items()}, left_out))
        rng = np.random.default_rng([seed, order.index(photo.name)])
        out += [(photo, d, remarked(marks, rng, keep, noise_pct / 100.0 * size, tuple(photo.meta["image_size"])),
                 left_out) for d in range(1, draws + 1)]
    return out


def within(r: dict, key: str) -> bool:
    """The row's view lies within ``VIEW_OK_DEG`` of the estimate (``view_off_estimate``) or of
    the own fit's (``view_off_own``)."""
    return r[key] is not None and r[key] <= VIEW_OK_DEG


def photo_summary(photo: Photo, rows: list[dict]) -> dict:
    from carbody.view.labels import angular_difference

    own = next(r for r in rows if r["draw"] == 0)
    again = [r for r in rows if r["draw"] > 0]
    estimate = photo.meta.get("view_estimate_deg")
    published = photo.meta.get("published_mm") or {}
    bodies = [r for r in again if r["outcome"] == "body"]
    for r in rows:
        r["view_off_estimate"] = None if r["view_deg"] is None or estimate is None else float(angular_difference(r["view_deg"], estimate))
        r["view_off_own"] = None if r["view_deg"] is None or own["view_deg"] is None else float(angular_difference(r["view_deg"], own["view_deg"]))
        r["length_err_pct"] = None if r["length_mm"] is None else pct_error(r["length_mm"], published.get("length"))
        r["wheelbase_err_pct"] = None if r["wheelbase_mm"] is None else pct_error(r["wheelbase_mm"], published.get("wheelbase"))
    return {"photo": photo.name, "own": own, "draws": len(again), "bodies": len(bodies),
            "within15": sum(within(r, "view_off_estimate") for r in again),
            "max_off_own": max((r["view_off_own"] for r in bodies if r["view_off_own"] is not None), default=None),
            "others": sorted({r["outcome"] for r in again} - {"body"})}


def report(photos: list[Photo], rows: list[dict], args) -> dict:
    per = [photo_summary(p, [r for r in rows if r["photo"] == p.name]) for p in photos]
    print(f"\n{len(photos)} photos x {args.draws} re-markings (keep {args.keep:.0%} of the marks, at least "
          f"{MIN_MARKS}; noise {args.noise} % of the car's image size); the photo's own marks first\n")
    print("| photo | marks | own view ° (off the estimate) | re-markings: bodies | views within 15° of the estimate "
          "| farthest view from the own fit's ° | other outcomes |")
    print("|---|---|---|---|---|---|---|")
    for s in per:
        own = s["own"]
        print(f"| {s['photo'][4:]} | {own['marks']} | {fmt(own['view_deg'])} ({fmt(own['view_off_estimate'])}) | "
              f"{s['bodies']} of {s['draws']} | {s['within15']} of {s['draws']} | {fmt(s['max_off_own'])} | "
              f"{', '.join(s['others'])} |")
    again = [r for r in rows if r["draw"] > 0]
    own = [r for r in rows if r["draw"] == 0]

    def med(key, rs):
        v = [abs(r[key]) for r in rs if r[key] is not None]
        return median_or_none(v), len(v)

    summary = {}
    for label, rs in (("own marks", own), ("re-markings", again)):
        outcomes = {o: sum(r["outcome"] == o for r in rs) for o in ("body", "refused", "error", "traceback")}
        near_estimate = sum(within(r, "view_off_estimate") for r in rs)
        same = sum(within(r, "view_off_own") for r in rs)
        length, nl = med("length_err_pct", rs)
        wb, nw = med("wheelbase_err_pct", rs)
        summary[label] = {"runs": len(rs), "outcomes": outcomes, "view_within15": near_estimate, "same_view": same,
                          "median_length_err_pct": length, "length_n": nl, "median_wheelbase_err_pct": wb,
                          "wheelbase_n": nw, "median_seconds": float(np.median([r["seconds"] for r in rs]))}
    print("\n| marks | runs | body / refused / error / traceback | view within 15° of the estimate "
          f"| view within {VIEW_OK_DEG:.0f}° of the own fit's | median \\|length\\| % | median \\|wheelbase\\| % "
          "| median s (warm) |")
    print("|---|---|---|---|---|---|---|---|")
    for label, s in summary.items():
        o = s["outcomes"]
        print(f"| {label} | {s['runs']} | {o['body']} / {o['refused']} / {o['error']} / {o['traceback']} | "
              f"{s['view_within15']} ({100 * s['view_within15'] / s['runs']:.0f} %) | "
              f"{s['same_view']} ({100 * s['same_view'] / s['runs']:.0f} %) | "
              f"{fmt(s['median_length_err_pct'], '.1f')} (of {s['length_n']}) | "
              f"{fmt(s['median_wheelbase_err_pct'], '.1f')} (of {s['wheelbase_n']}) | {s['median_seconds']:.1f} |")
    for r in rows:
        if r["outcome"] != "body":
            print(f"{r['photo']} draw {r['draw']} ({r['marks']} marks): {r['outcome']}: {r['message']}")
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DATA, help=f"the real-photo data (default {DATA})")
    ap.add_argument("--photos", nargs="+", default=None, metavar="N|NAME", help="the first N photos, or these")
    ap.add_argument("--draws", type=int, default=4, help="re-markings per photo (default 4)")
    ap.add_argument("--keep", type=float, default=0.8, help="each mark's chance to be kept (default 0.8)")
    ap.add_argument("--noise", type=float, default=0.5,
                    help="click noise added, %% of the car's image size per coordinate (default 0.5)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None, help="also write the rows and summary here")
    ap.add_argument("--table-without-car", action="store_true",
                    help="size each photo's car with its own rows left out of the table of published cars "
                         "(those with its published length and wheelbase), as a car not in the table is")
    args = ap.parse_args(argv)
    if not (0 < args.keep <= 1) or args.draws < 0 or args.noise < 0 or args.workers < 1:
        ap.error("--keep must be in (0, 1], --draws and --noise at least 0, --workers at least 1")
    if not (args.data / "keypoints").is_dir():
        print(f"skipped: no real photos at {args.data} (the shared folder is not here)")
        return 0
    every = load_photos(args.data)
    photos = select(every, args.photos)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    load = os.getloadavg()
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers, initializer=_init_worker) as pool:
        rows = list(pool.map(run_one, tasks(photos, args.draws, args.keep, args.noise, args.seed,
                                            [p.name for p in every], args.table_without_car)))
    print(f"machine: {os.cpu_count()} cores, load {load[0]:.1f} at the start; {args.workers} workers; "
          f"{time.perf_counter() - start:.0f} s in all")
    summary = report(photos, rows, args)
    if args.json:
        args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                         "rows": rows, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
