"""The real photos under the options a user may give: does every one still give a body?

``bench_real_photos.py`` runs ``carbody reconstruct`` as a user runs it first: no option. Users
then tell what they know, or think they know: the view, the wheelbase, the camera's distance or
focal length, where its axis meets the photo. This benchmark runs ``carbody reconstruct`` on
every photo of ``../shared/realphotos`` under each such option (:func:`variants`) and counts
the outcomes: a body, a one-line refusal (exit 2), anything else (a traceback, a crash). For a
body it prints the view found against the run without options; for a refusal, its line.

Some options are wrong for some photos, and the fit may refuse them, but its one line must then
name what is wrong. A photo taken from 3 m told ``--distance orthographic`` is refused saying a
close camera fits; ``--focal-35mm 26`` (a phone's main camera) on a photo cropped or taken
zoomed is fitted unturned, saying so.

Run: python benchmarks/bench_real_options.py [--variants NAME ...] [--photos N | NAME ...]
     [--workers 2] [--out DIR] [--json OUT.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real_photos import DATA, REPO, Photo, load_photos, outcome_of, run_photo, select  # noqa: E402

OUT = REPO / "out" / "bench_real_options"

#: Views within this many degrees of the run without options count as the same.
SAME_VIEW_DEG = 15.0


def variants(photo: Photo) -> dict[str, list[str]]:
    """{name: reconstruct's extra arguments} for one photo: its estimated view told, the other
    end told, its published wheelbase told, a distant camera, a camera 4 m away, the axis through
    the photo's centre, a phone's focal length, every mark kept as named, 10° of elevation told,
    and no wheels; the first three only where the data has the figure."""
    estimate = photo.meta.get("view_estimate_deg")
    wheelbase = (photo.meta.get("published_mm") or {}).get("wheelbase")
    out = {"none": []}
    if estimate is not None:
        out["view"] = ["--view", f"{estimate:g}"]
        out["other end"] = ["--view", f"{(estimate + 180) % 360:g}"]
    if wheelbase:
        out["wheelbase"] = ["--wheelbase", f"{wheelbase:g}"]
    out.update({"orthographic": ["--distance", "orthographic"], "4 m": ["--distance", "4000"],
                "axis centre": ["--principal-point", "centre"], "focal 26 mm": ["--focal-35mm", "26"],
                "keep marks": ["--keep-marks"], "elevation 10": ["--elevation", "10"],
                "no wheels": ["--no-wheels"]})
    return out


def run(photo: Photo, name: str, extra: list[str], out: Path) -> dict:
    """One ``carbody reconstruct`` in a fresh process, one BLAS thread (:func:`run_photo`, into
    ``out/<variant>/<photo>``): outcome (:func:`outcome_of`), its line, the view found, seconds."""
    folder = out / name.replace(" ", "_")
    folder.mkdir(parents=True, exist_ok=True)
    done = run_photo(photo, folder, blas_threads=1, extra=tuple(extra))
    outcome, line = outcome_of(done, folder / photo.name)
    view = None
    if outcome == "body":
        view = float(json.loads((folder / photo.name / "report.json").read_text())["view"]["azimuth_deg"])
    return {"photo": photo.name, "variant": name, "args": extra, "outcome": outcome, "exit_code": done["exit_code"],
            "line": line, "view_deg": view, "seconds": done["seconds"]}


def summarise(rows: list[dict]) -> list[dict]:
    """Per variant: runs, bodies, refusals, errors, and views within :data:`SAME_VIEW_DEG` of the
    photo's run without options (of the photos where both gave a body), and the refusals whose line
    points at the marks (the others name the option)."""
    from carbody.view.labels import angular_difference

    plain = {r["photo"]: r["view_deg"] for r in rows if r["variant"] == "none"}
    out = []
    for name in dict.fromkeys(r["variant"] for r in rows):
        mine = [r for r in rows if r["variant"] == name]
        both = [r for r in mine if r["view_deg"] is not None and plain.get(r["photo"]) is not None]
        out.append({"variant": name, "runs": len(mine),
                    **{k: sum(r["outcome"] == k for r in mine) for k in ("body", "refused", "error")},
                    "blaming_marks": sum(r["outcome"] == "refused" and "check those marks" in r["line"] for r in mine),
                    "same_view": int(sum(angular_difference(r["view_deg"], plain[r["photo"]]) <= SAME_VIEW_DEG
                                         for r in both)), "compared": len(both)})
    return out


def table(summary: list[dict]) -> str:
    head = ["| option | runs | body / refused / error | refusals naming marks | view within 15° of the run "
            "without options |", "|---|---|---|---|---|"]
    return "\n".join(head + [f"| {s['variant']} | {s['runs']} | {s['body']} / {s['refused']} / {s['error']} | "
                             f"{s['blaming_marks']} | {s['same_view']} of {s['compared']} |" for s in summary])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--photos", nargs="+", metavar="N|NAME", help="the first N photos, or these")
    ap.add_argument("--variants", nargs="+", metavar="NAME", help="only these options (names as in the table)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    if not (args.data / "parts.json").exists():
        print(f"no real-photo data at {args.data} (kept outside the repository)")
        return 0
    photos = select(load_photos(args.data), args.photos)
    wanted = set(args.variants or [])
    jobs = [(p, n, a) for p in photos for n, a in variants(p).items() if not wanted or n in wanted or n == "none"]
    args.out.mkdir(parents=True, exist_ok=True)
    with ThreadPoolExecutor(args.workers) as pool:
        rows = list(pool.map(lambda job: run(*job, args.out), jobs))
    for r in rows:
        if r["outcome"] != "body":
            print(f"{r['photo']} {r['variant']}: {r['outcome']} (exit {r['exit_code']}): {r['line']}")
    summary = summarise(rows)
    print(table(summary))
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
