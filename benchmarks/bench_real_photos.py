"""Real photos: ``carbody reconstruct`` as a user runs it on the Car Parts photos, measured
against what the data set's people drew.

Reads ``../shared/realphotos`` (from the repository's root; ``--data``): ``images/cps_*.jpg``,
their hand-marked ``keypoints/cps_*.json`` (with ``car``, ``published_mm``,
``view_estimate_deg``) and ``parts.json`` (the data set's own COCO part polygons, drawn
independently of the marks). Every photo is reconstructed in a fresh process
(``python -m carbody reconstruct IMAGE -k MARKS -o OUT/<photo>``: no ``--view``, no
``--wheelbase``, imports included in the time), one at a time unless ``--workers`` says
otherwise, into ``out/bench_real_photos/`` (git-ignored; ``--out``), never into the tracked
tree: these are third-party photos. Each run's exit code, times and last stderr lines are kept
beside its folder (``OUT/<photo>.run.json``; its output in ``OUT/<photo>.stdout.txt`` /
``.stderr.txt``), so ``--reuse`` re-measures without re-running.

    python benchmarks/bench_real_photos.py [--photos N | NAME ...] [--workers 1] [--out DIR]
                                           [--data DIR] [--json FILE] [--reuse] [--blas-threads N]
                                           [--timeout S] [--no-sheet] [--outline] [--[no-]wheels]
                                           [--principal-point auto|car|centre]

Outcomes: ``body`` (exit 0 and a ``body.step``), ``refused`` (exit 2 with one line
``carbody reconstruct: error: ...`` and no traceback: the table shows the line), ``error``
(a traceback, another exit code, a time-out or missing outputs).

Definitions (per photo):

- **Time**: wall-clock seconds of the whole process (imports, classifier, fit, surfaces, writing),
  and in brackets its CPU seconds (user + system over all its threads, from ``wait4``). The
  machine is shared: the load averages printed with the tables say how busy it was. Neither
  time is immune: with OpenBLAS's default threads a reconstruct on a busy machine spins, its CPU
  time growing with its wall time (``--blas-threads 1`` shows the work itself; the default,
  unset, is what a user gets).
- **Car's image size** S: the larger side of the bounding box of the union of all the photo's
  part polygons in ``parts.json`` (the data set's outline of the car, independent of the fit);
  for a photo without polygons, of its marks. Every pixel distance is given as % of S.
- **View**: the fitted azimuth (``report.json["view"]["azimuth_deg"]``) against the file's
  ``view_estimate_deg`` (by eye, ±10°); Δ is the angular difference, 0–180°.
- **Residual**: ``report["fit"]["residual_px_mean"]`` (mean distance of the marks kept from
  their reprojection) as % of S.
- **Length / width / wheelbase**: of the fitted wireframe (``wireframe.step``): length and
  wheelbase from ``Wireframe.measure()`` (extent in y of the sampled curves; distance between
  the wheel centres), width 2 · max |x| of the sampled curves (both halves; door mirrors are not
  modelled), against ``published_mm``: signed % (+ = fitted too large); blank where the figure
  is not published. A fit whose "left" half lies at x ≤ 0 is flagged ``mirrored_half``.
  The height stands on the ground: the top of the sampled curves above the wheel centres plus
  a tyre's radius, 0.12 wheelbase (:data:`carbody.fit.size.TYRE_RADIUS_NORM`, as the size's
  proportions take it). The summary gives the height ÷ width error apart for views within
  :data:`END_ON_DEG` of an end: such a view mixes the car's height with its depth.
  Beside the wheelbase, the spread the report gives it when its proportions sized it
  (``report["fit"]["size"]["spread_pct"]``, of its logarithm); the summary counts the published
  wheelbases within one and two of it.
- **IoU** of the projected windshield, rear window and hood (topology regions ``windshield``,
  ``rear_window``, ``hood``) against the human polygons ``front_glass``, ``back_glass``,
  ``hood``: each region's loop of curves is sampled on the fitted left half and on its mirror
  (x → −x), both are projected with the fitted camera (``report["fit"]["camera"]``,
  :func:`carbody.fit.report.project_with_camera`) and their union is the region's outline
  (shapely; a self-crossing outline is made valid first). Measured only where the data set
  annotated the part for that photo (blank otherwise). The two hoods are not quite one thing:
  the template's hood region runs out to the fender's crest (``hood_side``) and back to the
  windshield's lower corners (``a_pillar_base``); the people outlined the bonnet panel, whose
  shut lines lie inboard of both. On the near side ours then reaches a little past theirs.
  Between the marked nose and front corners the hood's front edge is the prior's (it sags over
  the headlamps, as a shut line does); the people's also takes in the bonnet's lip down to the
  grille, past the marked nose.
- **How the hoods miss** (:func:`hood_offset`): the share of our projected hood inside the human
  one, the share of theirs ours covers, and how far our outline's centroid lies from theirs
  along the car's length as the photo shows it at the hood (+: toward the windshield), % of S.
- **Wheel centres**: the fitted car's four wheel centres at (±x, y, z) with (y, z) the
  wireframe's own wheel centres (:func:`carbody.wireframe.wheel_centre`: ≈ (0, 0) and
  (wheelbase, 0)) and x that of the fitted ``front_arch_top`` / ``rear_arch_top`` keypoint (the
  body side at the arch, about the tyre's outer face, which the people outlined), projected
  with the fitted camera. Each polygon of a ``wheel`` annotation is one wheel (the data set
  puts several wheels in one annotation); its centre is the polygon's centroid. Annotated
  wheels are assigned one-to-one to projected centres minimising the total distance (the
  nearest, without two wheels taking the same centre); the photo's figure is the mean distance
  over its annotated wheels, % of S. Beside it, the mean signed vertical offset (annotated −
  projected, + down: the projected centre above the annotated one). The polygon is the visible
  tyre, whose top the fender hides, so its centroid lies somewhat below the hub. How far: the
  centroids' mean distance from the hubs the fit found in the photo and trusted (weight over
  0.6), % of S — the measure's own error, independent of the fit's wheel centres.
- **Wheel centres, like for like** (:func:`visible_tyre_centres`): the polygon is the tyre the
  photo shows, so its centroid is set against the centroid of the tyre our fitted car shows.
  Each wheel is a tyre cylinder on the fitted hub, its radius ``wheel_tyre_share`` of the arch's
  (the hub search's), its width :data:`TYRE_WIDTH_SHARE` of that, its outer face at the arch
  top's x. The fitted body (``body.step``, tessellated) and the four tyres are drawn in the
  fitted camera, far triangles first (painter's order by the triangle centroid's distance from
  the camera), each pixel keeping the nearest one's owner. The photo's figure is the mean
  distance of each annotated wheel's centroid from its matched tyre's visible centroid (matched
  as above, but to the visible centroids: a near hub can project onto a hidden far one), % of
  S. Its own error: the same with our visible tyre moved onto the hub the fit found and trusted
  (the centroid less our tyre's offset from its hub, against that hub).
- **Wheels placed apart from the body**: would tyres of their own, each moved from the fitted
  hub onto the hub the fit found and trusted, meet the target? Both wheel measures again with
  every such hub (and its visible tyre) moved so and the wheels matched again; the others stay.
- **Summary**: outcome counts; the view within 15° of the estimate counted over all photos (one
  without a body is not within); on three-quarter views (the estimate 15–75° from both ends),
  the **lean**: how much nearer the car's end (−) or side (+) the view found is than the
  estimate; medians over the photos where a figure is defined (the count in brackets); wall
  time median and max; the fit and surface stages' wall times (``report["timings_s"]``), and
  before them the load stage's: OCCT and scipy loaded once per process, which a warm process
  (batch, the marking page) no longer pays.
- **Rims' view**: the view read a second way, from the photo's rear wheels alone, to check the
  estimates by eye. A wheel's rim is a circle in the car's side plane. The photo round each rear
  hub the fit found and trusted (weight over 0.6) is warped onto that plane, as the fitted
  camera turned to some azimuth sees it (the hub kept in place). The azimuth at which the rim's
  ellipse there turns round is the rim's view (:func:`rims_view`). A front wheel may be steered,
  so it is not read. Each rear wheel is read from 5° either side of the view found and from it;
  readings that agree within 2° count. On renders at known views (``bench_rims.py``) it is
  0.3° off the truth at the median. Per photo the rims' mean; in summary, over the photos with
  one: how many lie within 15° of the estimate, against the view found on the same photos; the
  median differences rims − estimate and view found − rims; the rims' lean from the estimate.
- **Arches** (:func:`arches_per_wheelbase`): each fitted wheel arch's radius (its top above the
  hub, tyre and clearance) over the fitted wheelbase, front and rear. The library's templates,
  sized to published cars, span a range of it (:func:`library_arch_range`); in summary, the
  fitted range and the photos with an arch outside the templates'. The scalings that expand the
  library stretch the arches with the body, so a fit can leave that range.
- **Hubs found**: the wheels' hubs the fit found in the photo (``report["fit"]["wheels"]``),
  counted per photo and in all.
- **Fallback**: the run needed a stiffer fit to surface its body (``report["fit_fallback"]``
  not null).
- **Targets** (issue 24's, :data:`TARGETS`): each measured, and how often a new set of photos
  like these would meet it. The photos are drawn again with replacement as many times
  (``TARGET_DRAWS``, seeded) and the figure is recomputed on each draw; the share of draws that
  meet the target. A share near 50 % means the target sits on the figure: another set of such
  photos could go either way. Per-photo time limits are counted photo by photo instead.
- **Camera check**: the marks kept by the fit, reprojected here from ``keypoints_mm`` with the
  report's camera, must land ``residual_px_mean`` from the marks on average (in the JSON rows as
  ``camera_check_px``: the difference; a large one means the instrument and the fit disagree on
  the camera).

The contact sheet (``OUT/contact_sheet.png``) tiles every photo's ``overlay.png`` (the photo
with its marks when there is no body), desaturated, with the human polygons filled and the
projected regions outlined in the same colour per part (windshield yellow, rear window green,
hood magenta), the annotated wheel centres as white dots joined to their projected centres
(orange crosses), and the photo's name, outcome, view found / estimated and IoUs written above.
The wheel sheet (``OUT/wheel_sheet.png``) has a tile per annotated wheel of a photo with a body:
the photo round the people's polygon, its centroid, the fitted hub matched to it, the hub the fit
found there and trusted, and the centroid's distance from both. It shows a person where the hub
lies against the centroid the wheel measure takes.
"""
from __future__ import annotations

import argparse
import functools
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "realphotos"
OUT = REPO / "out" / "bench_real_photos"

OUTCOMES = ("body", "refused", "error")

#: (topology region, data-set part) pairs measured by IoU, with the tile colours (BGR).
REGION_PARTS = (("windshield", "front_glass"), ("rear_window", "back_glass"), ("hood", "hood"))
REGION_COLOURS = {"windshield": (0, 230, 255), "rear_window": (60, 255, 60), "hood": (255, 60, 255)}
WHEEL_ANNOTATED, WHEEL_PROJECTED = (255, 255, 255), (0, 140, 255)
#: The wheel sheet's hub found and trusted by the fit (BGR).
WHEEL_FOUND = (60, 60, 255)

#: A view found within this of the estimate counts as right (the estimate itself is ±10°).
VIEW_OK_DEG = 15.0
#: The estimates counted as three-quarter views by the lean (degrees from the car's nearer end).
THREE_QUARTER_DEG = (15.0, 75.0)
#: A lean counted as one (degrees): half the estimates' ±10°.
LEAN_NOTED_DEG = 5.0
#: A view found within this of the car's nearer end is end-on for the height's row (degrees).
END_ON_DEG = 15.0

#: The rims' view (:func:`rims_view`): each rear wheel is read from these starts, degrees from
#: the view found; a wheel whose readings agree within RIM_AGREE_DEG gives their mean.
RIM_STARTS_DEG = (-5.0, 0.0, 5.0)
RIM_AGREE_DEG = 2.0
#: A reading stops when its step is this small (degrees), or after RIM_ROUNDS.
RIM_CONVERGED_DEG = 0.5
RIM_ROUNDS = 8
#: Refits of a rim's ellipse per look: from a circle guess its turn settles in about five.
RIM_ELLIPSE_ROUNDS = 6

#: A fitted "left" half reaching no further than this (mm) to x > 0, and further to x < 0, lies
#: on the right: flagged (``mirrored_half``).
MIRRORED_MM = 1.0

#: Seconds one reconstruct may take before it counts as an error.
TIMEOUT_S = 900.0

REFUSAL = re.compile(r"^carbody reconstruct: error: .+")


@dataclass
class Photo:
    """One photo of the data: its files, the keypoint file's extra fields and its part polygons.

    Attributes:
        name: the file stem (``cps_te12``).
        image, marks: the JPEG and the keypoint file.
        meta: the keypoint file's contents (``car``, ``published_mm``, ``view_estimate_deg`` …).
        parts: {part name: [(N, 2) float px polygons]}, one entry per polygon of every
            annotation of that part.
    """

    name: str
    image: Path
    marks: Path
    meta: dict
    parts: dict[str, list[np.ndarray]]


def natural_key(name: str) -> tuple:
    """Sort ``cps_te4`` before ``cps_te12``."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def load_photos(data: Path) -> list[Photo]:
    """Every photo of ``data`` with its marks and part polygons, in natural name order."""
    coco = json.loads((data / "parts.json").read_text())
    categories = {c["id"]: c["name"] for c in coco["categories"]}
    by_file: dict[str, dict[str, list[np.ndarray]]] = {i["file_name"]: {} for i in coco["images"]}
    files = {i["id"]: i["file_name"] for i in coco["images"]}
    for a in coco["annotations"]:
        polys = by_file[files[a["image_id"]]].setdefault(categories[a["category_id"]], [])
        polys += [np.asarray(s, dtype=float).reshape(-1, 2) for s in a["segmentation"] if len(s) >= 6]
    photos = []
    for marks in sorted((data / "keypoints").glob("*.json"), key=lambda p: natural_key(p.stem)):
        meta = json.loads(marks.read_text())
        photos.append(Photo(marks.stem, data / "images" / meta["image"], marks, meta,
                            by_file.get(meta["image"], {})))
    return photos


def select(photos: list[Photo], wanted: list[str] | None) -> list[Photo]:
    """``--photos``: None = all; one number N = the first N; else names (``te12``, ``cps_te12``,
    ``cps_te12.jpg``)."""
    if not wanted:
        return photos
    if len(wanted) == 1 and wanted[0].isdigit():
        return photos[:int(wanted[0])]
    by_name = {p.name: p for p in photos}
    out = []
    for w in wanted:
        stem = Path(w).stem
        stem = stem if stem in by_name else f"cps_{stem}"
        if stem not in by_name:
            sys.exit(f"bench_real_photos: no photo {w!r} (have {', '.join(by_name)})")
        out.append(by_name[stem])
    return out


# --- running ---------------------------------------------------------------------------------

def run_photo(photo: Photo, out: Path, timeout_s: float = TIMEOUT_S, blas_threads: int | None = None,
              extra: tuple[str, ...] = ()) -> dict:
    """Reconstruct one photo in a fresh process, as a user would; returns (and stores beside the
    output folder, ``OUT/<photo>.run.json``) {exit_code, seconds (wall), cpu_seconds (the
    process's user + system time over its threads), stderr_tail, load_before, command,
    blas_threads}. Its stdout and stderr go to ``OUT/<photo>.stdout.txt`` / ``.stderr.txt``;
    ``extra``: more arguments for ``carbody reconstruct`` (``--outline``).
    ``blas_threads``: the numerical libraries' thread count set for the run (None: left as a
    user's environment has it)."""
    import threading

    folder = out / photo.name
    shutil.rmtree(folder, ignore_errors=True)  # no stale files survive a refusal
    cmd = [sys.executable, "-m", "carbody", "reconstruct", str(photo.image), "-k", str(photo.marks),
           "-o", str(folder), *extra]
    stdout_path, stderr_path = out / f"{photo.name}.stdout.txt", out / f"{photo.name}.stderr.txt"
    load = os.getloadavg()[0]
    with open(stdout_path, "w") as stdout, open(stderr_path, "w") as stderr:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=stdout, stderr=stderr, stdin=subprocess.DEVNULL, text=True,
                                env={**os.environ, **blas_environment(blas_threads)}, cwd=REPO)
        timer = threading.Timer(timeout_s, proc.kill)
        timer.start()
        # wait4, not Popen.wait: the child's own CPU time, right with several workers
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - start
        timed_out = not timer.is_alive()
        timer.cancel()
    proc.returncode = code = None if timed_out else os.waitstatus_to_exitcode(status)
    tail = stderr_path.read_text(errors="replace").strip().splitlines()[-30:]
    if timed_out:
        tail.append(f"(timed out after {timeout_s:.0f} s)")
    run = {"photo": photo.name, "exit_code": code, "seconds": seconds,
           "cpu_seconds": usage.ru_utime + usage.ru_stime, "stderr_tail": tail, "load_before": load,
           "command": " ".join(cmd[1:]), "blas_threads": blas_threads}
    (out / f"{photo.name}.run.json").write_text(json.dumps(run, indent=1))
    return run


def blas_environment(threads: int | None) -> dict[str, str]:
    """The variables that set numpy's, scipy's and torch's thread pools to ``threads`` ({} for
    None)."""
    if threads is None:
        return {}
    return {k: str(threads) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}


def stored_run(photo: Photo, out: Path) -> dict | None:
    path = out / f"{photo.name}.run.json"
    return json.loads(path.read_text()) if path.exists() else None


def outcome_of(run: dict, folder: Path) -> tuple[str, str | None]:
    """(outcome, the refusal line or the error's last line, None for a body)."""
    tail = run["stderr_tail"]
    traceback = any(line.startswith("Traceback") for line in tail)
    if run["exit_code"] == 0 and not traceback and (folder / "body.step").exists() \
            and (folder / "report.json").exists():
        return "body", None
    lines = [line for line in tail if line.strip()]
    if run["exit_code"] == 2 and not traceback and len(lines) == 1 and REFUSAL.match(lines[0]):
        return "refused", lines[0]
    last = lines[-1] if lines else "(no output)"
    if run["exit_code"] == 0:
        last = "exit 0 without body.step / report.json"
    return "error", f"exit {run['exit_code']}: {last}"


# --- measuring -------------------------------------------------------------------------------

def car_image_size(photo: Photo) -> tuple[float, str]:
    """S px: the larger side of the bounding box of all the photo's part polygons (``"parts"``),
    else of its marks (``"marks"``)."""
    polys = [p for ps in photo.parts.values() for p in ps]
    pts, source = (np.concatenate(polys), "parts") if polys else \
        (np.array(list(photo.meta["keypoints"].values()), dtype=float), "marks")
    return float(np.ptp(pts, axis=0).max()), source


def polygon(points: np.ndarray):
    """A valid shapely (multi)polygon of a possibly self-crossing (N, 2) outline (empty if
    degenerate)."""
    import shapely
    from shapely.geometry import Polygon

    if len(points) < 3 or not np.all(np.isfinite(points)):
        return Polygon()
    poly = shapely.make_valid(Polygon(points))
    # make_valid may leave the crossing's lines beside the areas: keep the areas only
    return shapely.union_all([g for g in getattr(poly, "geoms", [poly]) if g.area > 0]) \
        if poly.geom_type == "GeometryCollection" else poly


def region_outline_3d(control_points: np.ndarray, region_name: str, samples: int = 24) -> np.ndarray:
    """(N, 3) mm: the left half's loop of ``region_name``, sampled in loop order."""
    from carbody.topology import load_topology
    from carbody.wireframe import sample_curves

    topo = load_topology()
    curves = sample_curves(control_points, samples)
    loop = [curves[ci][::-1] if rev else curves[ci] for ci, rev in topo.region(region_name).loop]
    return np.concatenate([c[:-1] for c in loop])  # each curve's end is the next one's start


def projected_region(camera: dict, control_points: np.ndarray, region_name: str):
    """The region's outline in the photo: union of its left loop's and mirror's projections."""
    import shapely

    from carbody.fit.report import project_with_camera
    from carbody.wireframe import MIRROR

    loop = region_outline_3d(control_points, region_name)
    return shapely.union_all([polygon(project_with_camera(camera, half)) for half in (loop, loop * MIRROR)])


def projected_wheel_centres(camera: dict, control_points: np.ndarray) -> np.ndarray:
    """(4, 2) px: front left, front right, rear left, rear right wheel centres (module doc)."""
    from carbody.fit.report import project_with_camera
    from carbody.topology import load_topology
    from carbody.wireframe import wheel_centre

    topo = load_topology()
    centres = []
    for side, arch in (("front", "front_arch_top"), ("rear", "rear_arch_top")):
        x = abs(control_points[topo.junction_point_index(arch), 0])
        y, z = wheel_centre(control_points, topo, side)
        centres += [(x, y, z), (-x, y, z)]
    return project_with_camera(camera, np.array(centres))


def wheel_matches(annotated: np.ndarray, projected: np.ndarray) -> list[tuple[int, int, float]]:
    """[(annotated i, projected j, distance px)]: one-to-one, least total distance."""
    from scipy.optimize import linear_sum_assignment

    d = np.linalg.norm(annotated[:, None, :] - projected[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(d)
    return [(int(i), int(j), float(d[i, j])) for i, j in zip(rows, cols)]


def part_union(photo: Photo, part: str):
    import shapely

    return shapely.union_all([polygon(p) for p in photo.parts.get(part, [])])


def annotated_wheel_centres(photo: Photo) -> np.ndarray:
    """(k, 2) px: centroid of each wheel polygon."""
    cs = [polygon(p).centroid for p in photo.parts.get("wheel", [])]
    return np.array([(c.x, c.y) for c in cs if not c.is_empty]).reshape(-1, 2)


#: A tyre's width over its radius (a 205/55 R16 tyre: 205 mm wide, 316 mm in radius).
TYRE_WIDTH_SHARE = 0.65

#: Segments round a drawn tyre.
TYRE_SEGMENTS = 36


def tyre_triangles(control_points: np.ndarray) -> list[np.ndarray]:
    """[(m, 3, 3) mm] the four tyres' triangles (tread and both faces) on the hubs the fit's wheel
    search uses (:func:`carbody.fit.wheels.hub_points`, :data:`~carbody.fit.wheels.WHEELS`
    order, the order of :func:`projected_wheel_centres`; module doc: wheel centres, like for
    like)."""
    from carbody.fit.wheels import arch_radii, hub_points
    from carbody.policy import FitPolicy

    t = np.linspace(0.0, 2.0 * np.pi, TYRE_SEGMENTS, endpoint=False)
    nxt = np.roll(np.arange(TYRE_SEGMENTS), -1)
    tyres = []
    for (x, y, z), arch in zip(hub_points(control_points), arch_radii(control_points)):
        radius = FitPolicy().wheel_tyre_share * arch
        inner_x = x - np.sign(x) * TYRE_WIDTH_SHARE * radius
        o, i = (np.stack([np.full_like(t, face), y + radius * np.cos(t), z + radius * np.sin(t)], 1)
                for face in (x, inner_x))
        centre_o, centre_i = (np.broadcast_to([face, y, z], o.shape) for face in (x, inner_x))
        tyres.append(np.concatenate([np.stack([o, o[nxt], i[nxt]], 1), np.stack([o, i[nxt], i], 1),
                                     np.stack([centre_o, o, o[nxt]], 1), np.stack([centre_i, i, i[nxt]], 1)]))
    return tyres


def owner_image(camera: dict, layers: list[np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """(h, w) int: at each photo pixel the index in ``layers`` [(m, 3, 3) mm triangles] of the
    nearest one drawn there, −1 where none is: painter's order, far triangles first."""
    import cv2

    from carbody.camera import view_rotation
    from carbody.fit.report import camera_view, project_with_camera

    view = camera_view(camera)
    toward = view_rotation(view)[0]
    tris = np.concatenate(layers)
    owner = np.concatenate([np.full(len(t), k) for k, t in enumerate(layers)])
    centres = tris.mean(axis=1)
    if view.distance is None:
        nearness = centres @ toward
    else:
        nearness = -np.linalg.norm(centres - (np.asarray(view.aim) + view.distance * toward), axis=1)
    uv = project_with_camera(camera, tris.reshape(-1, 3)).reshape(-1, 3, 2)
    image = np.full(shape, -1, dtype=np.int16)
    for j in np.argsort(nearness, kind="stable"):
        if np.all(np.isfinite(uv[j])):
            cv2.fillConvexPoly(image, np.round(uv[j] * 4).astype(np.int32), int(owner[j]), cv2.LINE_8, 2)
    return image


def visible_tyre_centres(camera: dict, control_points: np.ndarray, body_step: Path,
                         shape: tuple[int, int]) -> np.ndarray:
    """(4, 2) px: the centroid of each tyre our fitted car shows in the photo (NaN where none is
    seen), in the order of :func:`projected_wheel_centres` (module doc)."""
    from carbody.occ.step_body import read_body_step
    from carbody.render.mesh import tessellate

    body = np.concatenate([m.vertices[m.triangles] for m in tessellate(read_body_step(body_step).shape)])
    image = owner_image(camera, [body, *tyre_triangles(control_points)], shape)
    centres = np.full((4, 2), np.nan)
    for k in range(4):
        v, u = np.nonzero(image == k + 1)
        if len(u):
            centres[k] = u.mean(), v.mean()
    return centres


def tyres_seen(photo: Photo, camera: dict, control_points: np.ndarray, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """((4, 2) px the fitted hubs, (4, 2) px the centroids of the tyres our fitted car shows,
    :func:`visible_tyre_centres`, a hidden tyre's being its hub) of the run in ``folder``."""
    w, h = photo.meta["image_size"]
    hubs = projected_wheel_centres(camera, control_points)
    seen = visible_tyre_centres(camera, control_points, folder / "body.step", (h, w))
    return hubs, np.where(np.isfinite(seen), seen, hubs)  # a tyre the car hides: its hub


def tyres_like_for_like(photo: Photo, camera: dict, control_points: np.ndarray, folder: Path,
                        wheels: dict | None) -> tuple[float | None, float | None, float | None]:
    """(mean distance px of the annotated wheels' centroids from their matched tyres' visible
    centroids, the same with our tyres moved onto the hubs the fit found and trusted —the
    measure's own error—, and the photo's figure with every such tyre moved so, matched again:
    wheels placed apart from the body): None where not measured (module doc)."""
    from carbody.fit.wheels import WHEELS

    annotated = annotated_wheel_centres(photo)
    if not len(annotated) or not (folder / "body.step").is_file():
        return None, None, None
    hubs, seen = tyres_seen(photo, camera, control_points, folder)
    found = trusted_hubs(wheels)
    # matched to the tyres seen, not to the hubs: a near wheel's hub can project onto a far one's
    # (te32: its front right and rear left hubs 3 px apart), whose tyre the body hides
    pairs = wheel_matches(annotated, seen)
    distance = float(np.mean([np.linalg.norm(annotated[i] - seen[j]) for i, j, _ in pairs]))
    own = [float(np.linalg.norm(annotated[i] - (seen[j] - hubs[j]) - found[WHEELS[j]]))
           for i, j, _ in pairs if WHEELS[j] in found]
    moved = on_found_hubs(seen, hubs, found)
    on_hubs = float(np.mean([d for _, _, d in wheel_matches(annotated, moved)]))
    return distance, (float(np.mean(own)) if own else None), on_hubs


def on_found_hubs(points: np.ndarray, hubs: np.ndarray, found: dict[str, np.ndarray]) -> np.ndarray:
    """(4, 2) px: ``points`` (one per wheel, :data:`WHEELS` order) moved with their hubs ``hubs``
    onto the hubs ``found`` (by wheel name); the others as they are."""
    from carbody.fit.wheels import WHEELS

    shift = np.array([found[w] - hubs[k] if w in found else np.zeros(2) for k, w in enumerate(WHEELS)])
    return np.asarray(points, float) + shift


def wheels_on_hubs_px(photo: Photo, camera: dict, control_points: np.ndarray, wheels: dict | None) -> float:
    """The mean wheel-centre distance (px) with each hub the fit found and trusted in place of the
    fitted car's, matched again: what wheels placed apart from the body, on those hubs, would
    measure (module doc). The photo has annotated wheels."""
    hubs = projected_wheel_centres(camera, control_points)
    moved = on_found_hubs(hubs, hubs, trusted_hubs(wheels))
    return float(np.mean([d for _, _, d in wheel_matches(annotated_wheel_centres(photo), moved)]))


def camera_check_px(report: dict, marks: dict[str, list[float]]) -> float | None:
    """|mean distance of the kept marks from their reprojection by ``project_with_camera`` −
    the report's ``residual_px_mean``| px, or None if no mark can be reprojected here."""
    from carbody.fit.report import project_with_camera

    fit = report["fit"]
    names = [n for n in fit["residual_px"] if n in marks]
    kp = fit["keypoints_mm"]

    def mm(name):  # a right-half mark is its left twin mirrored
        if name in kp:
            return kp[name]
        x, y, z = kp[name.removesuffix("_right")]
        return [-x, y, z]
    if not names:
        return None
    uv = project_with_camera(fit["camera"], np.array([mm(n) for n in names]))
    d = np.linalg.norm(uv - np.array([marks[n] for n in names]), axis=1)
    return float(abs(d.mean() - fit["residual_px_mean"]))


def fitted_width_mm(control_points: np.ndarray, samples: int = 200) -> float:
    """The body's width, both halves: 2 · max |x| over the sampled curves (mm). Unlike
    ``Wireframe.measure()["width_mm"]`` (2 · max x), right also for a fit whose "left" half came
    out at x ≤ 0: the body, a half and its mirror, is the same."""
    from carbody.wireframe import sample_curves

    return float(2.0 * np.abs(sample_curves(control_points, samples)[..., 0]).max())


def fitted_height_mm(sizes: dict[str, float]) -> float:
    """The body's height on the ground (mm) from ``Wireframe.measure()``'s ``sizes``: its top above
    the wheel centres and a tyre's radius, as :func:`carbody.fit.size.estimate_size` takes it."""
    from carbody.fit.size import NORMALISED_WHEELBASE, TYRE_RADIUS_NORM

    return float(sizes["top_z_mm"] + TYRE_RADIUS_NORM / NORMALISED_WHEELBASE * sizes["wheelbase_mm"])


def arches_per_wheelbase(control_points: np.ndarray) -> list[float]:
    """[front, rear]: each wheel arch's radius (its top above the hub) over the wheelbase
    (:func:`carbody.fit.wheels.arch_radii`, the left wheels)."""
    from carbody.fit.wheels import arch_radii, hub_points

    hubs = hub_points(control_points)
    wheelbase = float(np.linalg.norm(hubs[2, 1:] - hubs[0, 1:]))
    return [float(r) / wheelbase for r in arch_radii(control_points)[[0, 2]]]


@functools.lru_cache(maxsize=1)
def library_arch_range() -> tuple[float, float]:
    """(least, most) arch radius over wheelbase among the library's templates, as sized."""
    from carbody.library import load_library

    library = load_library()
    values = [v for t in range(len(library.template_names))
              for v in arches_per_wheelbase(library.S[:, library.original(t)].reshape(-1, 3))]
    return min(values), max(values)


def pct_error(fitted: float, published: float | None) -> float | None:
    return None if not published else 100.0 * (fitted / published - 1.0)


def fitted(folder: Path):
    """(report.json as a dict, the fitted :class:`~carbody.wireframe.Wireframe`) of a body's folder."""
    from carbody.wireframe import read_wireframe

    return json.loads((folder / "report.json").read_text()), read_wireframe(folder / "wireframe.step")


def measure(photo: Photo, run: dict, out: Path) -> dict:
    """One row of the table (module docstring); metrics None where undefined."""
    from carbody.view.labels import angular_difference

    folder = out / photo.name
    outcome, line = outcome_of(run, folder)
    size, size_from = car_image_size(photo)
    published = photo.meta.get("published_mm") or {}
    row = {"photo": photo.name, "car": photo.meta.get("car"), "outcome": outcome, "message": line,
           "exit_code": run["exit_code"], "seconds": run["seconds"], "cpu_seconds": run.get("cpu_seconds"),
           "load_before": run.get("load_before"),
           "view_estimate_deg": photo.meta.get("view_estimate_deg"), "image_size_px": size,
           "image_size_from": size_from, "published_mm": published,
           "parts": sorted(photo.parts), "wheels_annotated": len(photo.parts.get("wheel", [])),
           "view_found_deg": None, "view_diff_deg": None, "view_lean_deg": None, "view_source": None,
           "residual_px_mean": None,
           "residual_pct": None, "fitted_mm": None, "length_err_pct": None, "width_err_pct": None,
           "height_err_pct": None,
           "wheelbase_err_pct": None, "wheelbase_spread_pct": None,
           "iou": {r: None for r, _ in REGION_PARTS}, "wheel_dist_pct": None,
           "hood": None, "wheel_dist_px": None, "wheel_dv_pct": None, "centroid_to_hub_pct": None, "hubs_found": None,
           "tyre_dist_pct": None, "tyre_own_pct": None, "wheel_on_hubs_pct": None, "tyre_on_hubs_pct": None,
           "rims_view_deg": None, "rims": None, "rims_lean_deg": None, "rims_diff_deg": None,
           "fit_rims_diff_deg": None,
           "fallback": None, "camera_check_px": None,
           "mirrored_half": None, "stage_s": None, "arches_per_wheelbase": None}
    if outcome != "body":
        return row
    report, wireframe = fitted(folder)
    fit, camera, cp = report["fit"], report["fit"]["camera"], wireframe.control_points
    found = float(report["view"]["azimuth_deg"])
    sizes = wireframe.measure()
    row.update(view_found_deg=found, view_source=report["view"]["source"],
               residual_px_mean=fit["residual_px_mean"], residual_pct=100.0 * fit["residual_px_mean"] / size,
               fitted_mm={"length": sizes["length_mm"], "width": fitted_width_mm(cp),
                          "height": fitted_height_mm(sizes), "wheelbase": sizes["wheelbase_mm"]},
               mirrored_half=bool(cp[:, 0].max() < MIRRORED_MM < -cp[:, 0].min()),
               fallback=report["fit_fallback"],
               camera_check_px=camera_check_px(report, photo.meta["keypoints"]),
               stage_s=report.get("timings_s"), arches_per_wheelbase=arches_per_wheelbase(cp),
               hubs_found=len((fit.get("wheels") or {}).get("wheels") or []))
    if row["view_estimate_deg"] is not None:
        row["view_diff_deg"] = float(angular_difference(found, row["view_estimate_deg"]))
        row["view_lean_deg"] = view_lean_deg(found, row["view_estimate_deg"])
    for key in ("length", "width", "height", "wheelbase"):
        row[f"{key}_err_pct"] = pct_error(row["fitted_mm"][key], published.get(key))
    if fit["wheelbase_from"] == "proportions" and fit.get("size"):
        row["wheelbase_spread_pct"] = fit["size"]["spread_pct"]
    row["iou"], row["wheel_dist_px"], dv_px = how_it_sits(photo, camera, cp)
    row["hood"] = hood_offset(photo, camera, cp)
    if row["hood"]:
        row["hood"]["back_pct"] = 100.0 * row["hood"]["back_px"] / size
    if row["wheel_dist_px"] is not None:
        row["wheel_dist_pct"] = 100.0 * row["wheel_dist_px"] / size
        row["wheel_dv_pct"] = 100.0 * dv_px / size
        hub_px = centroid_to_hub_px(photo, camera, cp, fit.get("wheels"))
        row["centroid_to_hub_pct"] = None if hub_px is None else 100.0 * hub_px / size
        tyre_px, own_px, on_hubs_px = tyres_like_for_like(photo, camera, cp, folder, fit.get("wheels"))
        row["tyre_dist_pct"] = None if tyre_px is None else 100.0 * tyre_px / size
        row["tyre_own_pct"] = None if own_px is None else 100.0 * own_px / size
        row["tyre_on_hubs_pct"] = None if on_hubs_px is None else 100.0 * on_hubs_px / size
        row["wheel_on_hubs_pct"] = 100.0 * wheels_on_hubs_px(photo, camera, cp, fit.get("wheels")) / size
    row["rims"] = rims_view(photo.image, camera, cp, fit.get("wheels"))
    if row["rims"]:
        row["rims_view_deg"] = float(np.mean([found + angular_offset(a, found) for a in row["rims"].values()])) % 360.0
        row["fit_rims_diff_deg"] = float(angular_difference(found, row["rims_view_deg"]))
        if row["view_estimate_deg"] is not None:
            row["rims_diff_deg"] = float(angular_difference(row["rims_view_deg"], row["view_estimate_deg"]))
            row["rims_lean_deg"] = view_lean_deg(row["rims_view_deg"], row["view_estimate_deg"])
    return row


#: A hub found in the photo counts as the hub's true place when the fit weighed it this much.
SURE_HUB_WEIGHT = 0.6


def trusted_hubs(wheels: dict | None) -> dict[str, np.ndarray]:
    """{wheel name: (2,) px} the hubs the fit found in the photo and trusted
    (``report["fit"]["wheels"]``, weight over :data:`SURE_HUB_WEIGHT`)."""
    return {w["wheel"]: np.array(w["found_px"]) for w in (wheels or {}).get("wheels", [])
            if w["weight"] > SURE_HUB_WEIGHT}


def centroid_to_hub_px(photo: Photo, camera: dict, control_points: np.ndarray, wheels: dict | None) -> float | None:
    """The measure's own error: the mean distance (px) of the annotated wheels' centroids from the
    hubs the fit found in the photo and trusted (``report["fit"]["wheels"]``, weight over
    :data:`SURE_HUB_WEIGHT`), for the wheels matched to them; None without such a wheel."""
    from carbody.fit.wheels import WHEELS

    found = trusted_hubs(wheels)
    annotated = annotated_wheel_centres(photo)
    if not found or not len(annotated):
        return None
    d = [float(np.linalg.norm(annotated[i] - found[WHEELS[j]]))
         for i, j, _ in wheel_matches(annotated, projected_wheel_centres(camera, control_points)) if WHEELS[j] in found]
    return float(np.mean(d)) if d else None


def angular_offset(a: float, b: float) -> float:
    """a − b in degrees, wrapped to [−180, 180)."""
    return (a - b + 180.0) % 360.0 - 180.0


def camera_turned(camera: dict, hub_mm: np.ndarray, azimuth_deg: float):
    """A report's ``camera`` turned to ``azimuth_deg``, as car-frame points (n, 3) mm → photo
    pixels, shifted so that the hub stays where the camera put it."""
    from carbody.fit.report import project_with_camera

    turned = {**camera, "azimuth_deg": float(azimuth_deg)}
    shift = project_with_camera(camera, hub_mm[None])[0] - project_with_camera(turned, hub_mm[None])[0]
    return lambda points: project_with_camera(turned, np.asarray(points, dtype=float)) + shift


def wheel_stretch(camera: dict, hub_mm: np.ndarray, azimuth_deg: float, step_mm: float = 50.0) -> float:
    """How long a step along the car looks in the photo at a hub, over a step up, with the
    report's ``camera`` turned to ``azimuth_deg`` (where the hub lands does not matter)."""
    from carbody.fit.report import project_with_camera

    steps = np.array([[0.0, 0.0, 0.0], [0.0, step_mm, 0.0], [0.0, 0.0, step_mm]])
    uv = project_with_camera({**camera, "azimuth_deg": float(azimuth_deg)}, hub_mm + steps)
    return float(np.linalg.norm(uv[1] - uv[0]) / np.linalg.norm(uv[2] - uv[0]))


def rim_reading(grey: np.ndarray, camera: dict, hub_mm: np.ndarray, radius_mm: float, hub_px, azimuth_deg: float,
                policy) -> float | None:
    """The azimuth (degrees) one look at a wheel's rim points to: the photo round the hub found
    (``hub_px``) warped onto the wheel's plane as ``camera`` turned to ``azimuth_deg`` sees it
    (:func:`carbody.fit.wheels.wheel_patch`), the ellipse its strongest circle makes there
    (:func:`~carbody.fit.wheels.rim_ellipse`), and the azimuth whose stretch along the car over
    up (:func:`wheel_stretch`) turns that ellipse into a circle; None without a clear ellipse."""
    from carbody.camera import apply_homography
    from carbody.errors import AngleError
    from carbody.fit.wheels import circle_support, patch_edges, patch_radii, patch_source, rim_ellipse, wheel_patch

    to_px = camera_turned(camera, hub_mm, azimuth_deg)
    radius_px = np.linalg.norm(np.subtract(*to_px(hub_mm + np.array([[0.0, 0.0, radius_mm], [0.0, 0.0, 0.0]]))))
    small, reduce = patch_source(grey, radius_px)  # as the hub's search reads it
    try:
        patch, valid, H = wheel_patch(small, to_px, hub_mm, radius_mm, policy.wheel_window + policy.wheel_radii[1],
                                      1.0, reduce)
    except AngleError:
        return None
    edges = patch_edges(patch, valid)
    centre = apply_homography(np.linalg.inv(H), np.asarray(hub_px, dtype=float)[None])[0] - 0.5
    radii = patch_radii(policy)
    support = circle_support(edges, centre[None], radii, policy.wheel_sectors, policy.wheel_alignment)[0]
    ellipse = rim_ellipse(edges, centre, float(radii[np.argmax(support)]), policy.wheel_sectors,
                          rounds=RIM_ELLIPSE_ROUNDS)
    if ellipse is None or ellipse.sectors_seen < policy.wheel_sectors / 2:
        return None
    wanted = ellipse.stretch() * wheel_stretch(camera, hub_mm, azimuth_deg)
    turns = azimuth_deg + np.arange(-40.0, 40.01, 0.25)
    stretches = np.array([wheel_stretch(camera, hub_mm, a) for a in turns])
    return float(turns[np.argmin(np.abs(stretches - wanted))])


def rim_view_deg(grey: np.ndarray, camera: dict, hub_mm: np.ndarray, radius_mm: float, hub_px, start_deg: float,
                 policy) -> float | None:
    """The azimuth (degrees) at which a wheel's rim looks round, read again and again from
    ``start_deg`` (:func:`rim_reading`, damped steps) until it settles; None if a look fails."""
    azimuth = float(start_deg)
    for _ in range(RIM_ROUNDS):
        reading = rim_reading(grey, camera, hub_mm, radius_mm, hub_px, azimuth, policy)
        if reading is None:
            return None
        if abs(reading - azimuth) < RIM_CONVERGED_DEG:
            return reading
        azimuth += 0.7 * (reading - azimuth)
    return azimuth


def rims_view(image, camera: dict, control_points: np.ndarray, wheels: dict | None,
              min_weight: float = SURE_HUB_WEIGHT) -> dict[str, float]:
    """{rear wheel: azimuth°} the rims of the rear wheels the fit found in the photo and trusted
    (weight over ``min_weight``) show: each read from :data:`RIM_STARTS_DEG` about the view
    found, and kept when the readings agree within :data:`RIM_AGREE_DEG` (module docstring);
    empty when none."""
    from carbody.fit.wheels import WHEELS, arch_radii, grey_photo, hub_points
    from carbody.policy import FitPolicy
    from carbody.view.predict import read_image

    rear = [w for w in (wheels or {}).get("wheels", []) if w["wheel"].startswith("rear") and w["weight"] > min_weight]
    if not rear:
        return {}
    grey, policy = grey_photo(read_image(image)), FitPolicy()
    hubs, radii = hub_points(control_points), arch_radii(control_points)
    out = {}
    for w in rear:
        i = WHEELS.index(w["wheel"])
        reads = [rim_view_deg(grey, camera, hubs[i], float(radii[i]), w["found_px"],
                              camera["azimuth_deg"] + d, policy) for d in RIM_STARTS_DEG]
        if None not in reads and max(reads) - min(reads) <= RIM_AGREE_DEG:
            out[w["wheel"]] = float(np.mean(reads)) % 360.0
    return out


def how_it_sits(photo: Photo, camera: dict, control_points: np.ndarray) -> tuple[dict, float | None, float | None]:
    """({region: IoU or None}, mean wheel-centre distance px, mean signed vertical offset px —
    annotated below projected positive —; both None without annotated wheels) of a fitted car
    projected with ``camera`` (the report's) against the photo's human polygons (module
    docstring)."""
    iou = {r: None for r, _ in REGION_PARTS}
    for region, part in REGION_PARTS:
        if part in photo.parts:
            human, ours = part_union(photo, part), projected_region(camera, control_points, region)
            union = human.union(ours).area
            iou[region] = float(human.intersection(ours).area / union) if union > 0 else 0.0
    wheels = annotated_wheel_centres(photo)
    if not len(wheels):
        return iou, None, None
    projected = projected_wheel_centres(camera, control_points)
    matches = wheel_matches(wheels, projected)
    return (iou, float(np.mean([m[2] for m in matches])),
            float(np.mean([wheels[i, 1] - projected[j, 1] for i, j, _ in matches])))


def hood_offset(photo: Photo, camera: dict, control_points: np.ndarray) -> dict | None:
    """How the projected hood misses the human one (None where the photo has no hood polygon):
    ``inside``, the share of ours inside theirs; ``covered``, the share of theirs ours covers;
    ``back_px``, how far our outline's centroid lies from theirs toward the windshield, along the
    car's length as the photo shows it at the hood (px; − : toward the nose)."""
    from carbody.fit.report import project_with_camera

    if "hood" not in photo.parts:
        return None
    human, ours = part_union(photo, "hood"), projected_region(camera, control_points, "hood")
    if human.area <= 0 or ours.area <= 0:
        return None
    centre = region_outline_3d(control_points, "hood").mean(axis=0) * np.array([0.0, 1.0, 1.0])
    ends = project_with_camera(camera, np.stack([centre, centre + [0.0, HOOD_STEP_MM, 0.0]]))
    back = (ends[1] - ends[0]) / max(float(np.linalg.norm(ends[1] - ends[0])), 1e-9)
    shift = np.asarray(ours.centroid.coords[0]) - np.asarray(human.centroid.coords[0])
    common = human.intersection(ours).area
    return {"inside": float(common / ours.area), "covered": float(common / human.area),
            "back_px": float(shift @ back)}


#: The summary counts hoods whose centroid lies more than this (% of S) back or forward of the human one.
HOOD_SHIFT_NOTED_PCT = 2.0

#: :func:`hood_offset` reads the car's length direction in the photo over this step (mm).
HOOD_STEP_MM = 300.0


def estimate_check(photos: list[Photo], rows: list[dict], out: Path) -> list[dict]:
    """For each photo whose view was found more than ``VIEW_OK_DEG`` from the estimate: the car
    fitted again with the estimate kept (``carbody fit --view EST --no-refine``, the elevation
    found, ``--force``), and how each sits on the human polygons. The estimate is by eye
    (±10°): where the view kept at it sits worse on what the people drew, the estimate is the
    likelier one to be off."""
    from carbody.wireframe import read_wireframe

    checks = []
    for photo, row in zip(photos, rows):
        if row["outcome"] != "body" or row["view_diff_deg"] is None or row["view_diff_deg"] <= VIEW_OK_DEG:
            continue
        folder = out / f"{photo.name}.at_estimate"
        folder.mkdir(exist_ok=True)
        elevation = json.loads((out / photo.name / "report.json").read_text())["view"]["elevation_deg"]
        cmd = [sys.executable, "-m", "carbody", "fit", str(photo.image), "-k", str(photo.marks),
               "--view", f"{row['view_estimate_deg']:g}", "--elevation", f"{elevation:.2f}", "--no-refine",
               "--force", "-q", "-o", str(folder / "wireframe.step"), "--report", str(folder / "report.json")]
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
        if proc.returncode != 0:
            checks.append({"photo": photo.name, "error": proc.stderr.strip().splitlines()[-1:]})
            continue
        report = json.loads((folder / "report.json").read_text())
        iou, wheels, _ = how_it_sits(photo, report["camera"], read_wireframe(folder / "wireframe.step").control_points)
        size = row["image_size_px"]
        checks.append({"photo": photo.name, "estimate_deg": row["view_estimate_deg"],
                       "found_deg": row["view_found_deg"], "found": {
                           "residual_pct": row["residual_pct"], "iou": row["iou"],
                           "wheel_dist_pct": row["wheel_dist_pct"]},
                       "at_estimate": {"residual_pct": 100.0 * report["residual_px_mean"] / size, "iou": iou,
                                       "wheel_dist_pct": None if wheels is None else 100.0 * wheels / size}})
    return checks


def estimate_table(checks: list[dict]) -> str:
    """The views found off the estimate against the estimate kept (:func:`estimate_check`)."""
    lines = ["| photo | view found / estimate ° | residual % found / at estimate | IoU windshield | IoU rear window "
             "| IoU hood | wheel centres % |", "|---|---|---|---|---|---|---|"]
    for c in checks:
        if "error" in c:
            lines.append(f"| {c['photo'].removeprefix('cps_')} | fit at the estimate failed: {' '.join(c['error'])} "
                         "| | | | | |")
            continue
        f, e = c["found"], c["at_estimate"]
        pair = lambda a, b, spec=".2f": f"{fmt(a, spec)} / {fmt(b, spec)}" if a is not None else ""  # noqa: E731
        lines.append(f"| {c['photo'].removeprefix('cps_')} | {c['found_deg']:.0f} / {c['estimate_deg']:g} "
                     f"| {pair(f['residual_pct'], e['residual_pct'], '.1f')} | "
                     + " | ".join(pair(f["iou"][r], e["iou"][r]) for r, _ in REGION_PARTS)
                     + f" | {pair(f['wheel_dist_pct'], e['wheel_dist_pct'], '.1f')} |")
    return "\n".join(lines)


# --- tables ----------------------------------------------------------------------------------

def fmt(v, spec: str = ".0f", signed: bool = False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return format(v, ("+" if signed else "") + spec)


def photo_table(rows: list[dict]) -> str:
    head = ("| photo | outcome | time s (CPU) | view found / estimate (Δ) ° | rims ° | residual % | length % | width % | "
            "height % | wheelbase % | IoU windshield | IoU rear window | IoU hood | wheel centres % (n) | like for like % | fallback |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for r in rows:
        view = (f"{r['view_found_deg']:.0f} / {r['view_estimate_deg']} ({r['view_diff_deg']:.0f})"
                if r["view_found_deg"] is not None else f"– / {r['view_estimate_deg']}")
        wheel = f"{r['wheel_dist_pct']:.1f} ({r['wheels_annotated']})" if r["wheel_dist_pct"] is not None else ""
        fb = "" if r["outcome"] != "body" else ("yes" if r["fallback"] else "no")
        lines.append(f"| {r['photo'].removeprefix('cps_')} | {r['outcome']} | "
                     f"{r['seconds']:.0f} ({fmt(r['cpu_seconds'])}) | {view} | {fmt(r.get('rims_view_deg'))} | "
                     f"{fmt(r['residual_pct'], '.1f')} | {fmt(r['length_err_pct'], signed=True)} | "
                     f"{fmt(r['width_err_pct'], signed=True)} | {fmt(r.get('height_err_pct'), signed=True)} | "
                     f"{fmt(r['wheelbase_err_pct'], signed=True)} | "
                     + " | ".join(fmt(r["iou"][k], ".2f") for k, _ in REGION_PARTS)
                     + f" | {wheel} | {fmt(r['tyre_dist_pct'], '.1f')} | {fb} |")
    return "\n".join(lines)


def messages_table(rows: list[dict]) -> str:
    """The refusals' lines and errors' last lines, the fallbacks' reasons, mirrored halves."""
    lines = ["| photo | outcome | message |", "|---|---|---|"]
    for r in rows:
        name = r["photo"].removeprefix("cps_")
        if r["message"]:
            lines.append(f"| {name} | {r['outcome']} | `{r['message']}` |")
        if r["fallback"]:
            fb = r["fallback"]
            lines.append(f"| {name} | fallback | {fb.get('fit')} "
                         f"({fb.get('share_of_fit', 0):.0%} of the fit) after `{fb.get('reason')}` |")
        if r["mirrored_half"]:
            lines.append(f"| {name} | mirrored | the fitted left half lies at x ≤ 0 (the body is still a half "
                         "and its mirror: width measured as 2 · max \\|x\\|) |")
    return "\n".join(lines) if len(lines) > 2 else ""


def end_angle_deg(azimuth: float) -> float:
    """How far (degrees, 0–90) a view is from the car's nearer end: 0 a front or rear view, 90 a side view."""
    a = float(azimuth) % 180.0
    return min(a, 180.0 - a)


def view_lean_deg(found: float, estimate: float) -> float | None:
    """For a three-quarter view (the estimate 15–75° from both ends): the view found, signed, from
    the car's nearer end less the estimate's (−: found nearer an end than estimated); else None."""
    if not THREE_QUARTER_DEG[0] <= end_angle_deg(estimate) <= THREE_QUARTER_DEG[1]:
        return None
    return end_angle_deg(found) - end_angle_deg(estimate)


def median_or_none(values) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else None


def _median_abs(rows: list[dict], key: str) -> float | None:
    return median_or_none(abs(r[key]) if r[key] is not None else None for r in rows)


def summarise(rows: list[dict]) -> dict:
    n = len(rows)
    counts = {o: sum(r["outcome"] == o for r in rows) for o in OUTCOMES}
    viewed = [r for r in rows if r["view_diff_deg"] is not None]
    ok = sum(r["view_diff_deg"] <= VIEW_OK_DEG for r in viewed)
    leans = [r["view_lean_deg"] for r in rows if r.get("view_lean_deg") is not None]

    # the length split into the proportions the photo shows (length ÷ wheelbase) and the
    # absolute size (the wheelbase), which one photo cannot show: the library's guess
    sized = [r for r in rows if r["length_err_pct"] is not None and r["wheelbase_err_pct"] is not None]
    proportion = [100.0 * ((1 + r["length_err_pct"] / 100) / (1 + r["wheelbase_err_pct"] / 100) - 1) for r in sized]
    # the car's width against its wheelbase, signed: how narrow or wide the fitted shape is
    widths = [100.0 * ((1 + r["width_err_pct"] / 100) / (1 + r["wheelbase_err_pct"] / 100) - 1) for r in sized
              if r["width_err_pct"] is not None]
    # how often the published wheelbase lies within the spread the report gives (of its logarithm)
    spread = [(abs(math.log1p(r["wheelbase_err_pct"] / 100)), r["wheelbase_spread_pct"] / 100) for r in rows
              if r["wheelbase_err_pct"] is not None and r["wheelbase_spread_pct"] is not None]
    # the height against the width, signed: the shape's own, apart for views near an end
    tall = {end_on: [100.0 * ((1 + r["height_err_pct"] / 100) / (1 + r["width_err_pct"] / 100) - 1) for r in rows
                     if r.get("height_err_pct") is not None and r["width_err_pct"] is not None
                     and (end_angle_deg(r["view_found_deg"]) <= END_ON_DEG) == end_on]
            for end_on in (True, False)}
    times = [r["seconds"] for r in rows]
    arches = [r["arches_per_wheelbase"] for r in rows if r.get("arches_per_wheelbase")]
    low, high = library_arch_range()
    cpu = [r["cpu_seconds"] for r in rows if r["cpu_seconds"] is not None]
    return {
        "photos": n, "outcomes": counts, "body_pct": 100.0 * counts["body"] / n if n else None,
        "view_within_deg": VIEW_OK_DEG, "view_within": ok, "view_measured": len(viewed),
        "view_within_pct_of_photos": 100.0 * ok / n if n else None,
        "median_view_lean_deg": median_or_none(leans), "view_lean_measured": len(leans),
        "view_leans_to_end": sum(v < -LEAN_NOTED_DEG for v in leans),
        "view_leans_to_side": sum(v > LEAN_NOTED_DEG for v in leans),
        "median_abs_length_err_pct": _median_abs(rows, "length_err_pct"),
        "median_abs_width_err_pct": _median_abs(rows, "width_err_pct"),
        "median_abs_wheelbase_err_pct": _median_abs(rows, "wheelbase_err_pct"),
        "median_abs_height_err_pct": _median_abs(rows, "height_err_pct"),
        "height_measured": sum(r.get("height_err_pct") is not None for r in rows),
        **{f"{k}_height_over_width_err_pct": sorted(v) for k, v in (("end_on", tall[True]), ("other", tall[False]))},
        "size_split_measured": len(sized),
        "median_abs_length_over_wheelbase_err_pct": median_or_none(abs(p) for p in proportion),
        "median_signed_wheelbase_err_pct": median_or_none(r["wheelbase_err_pct"] for r in sized),
        "median_signed_width_over_wheelbase_err_pct": median_or_none(widths),
        "wheelbase_spread_measured": len(spread),
        "median_wheelbase_spread_pct": median_or_none(100.0 * sd for _, sd in spread),
        "wheelbase_within_spread": sum(err <= sd for err, sd in spread),
        "wheelbase_within_two_spreads": sum(err <= 2 * sd for err, sd in spread),
        "median_residual_pct": median_or_none(r["residual_pct"] for r in rows),
        **{f"median_iou_{k}": median_or_none(r["iou"][k] for r in rows) for k, _ in REGION_PARTS},
        **{f"iou_{k}_measured": sum(r["iou"][k] is not None for r in rows) for k, _ in REGION_PARTS},
        **{f"median_hood_{k}": median_or_none(r["hood"][k] for r in rows if r.get("hood"))
           for k in ("inside", "covered", "back_pct")},
        "hood_back_measured": sum(bool(r.get("hood")) for r in rows),
        "hood_lies_back": sum(r["hood"]["back_pct"] > HOOD_SHIFT_NOTED_PCT for r in rows if r.get("hood")),
        "hood_lies_forward": sum(r["hood"]["back_pct"] < -HOOD_SHIFT_NOTED_PCT for r in rows if r.get("hood")),
        "median_wheel_dist_pct": median_or_none(r["wheel_dist_pct"] for r in rows),
        "wheel_dist_measured": sum(r["wheel_dist_pct"] is not None for r in rows),
        "median_wheel_dv_pct": median_or_none(r["wheel_dv_pct"] for r in rows),
        "median_centroid_to_hub_pct": median_or_none(r["centroid_to_hub_pct"] for r in rows),
        "median_tyre_dist_pct": median_or_none(r["tyre_dist_pct"] for r in rows),
        "tyre_dist_measured": sum(r["tyre_dist_pct"] is not None for r in rows),
        "median_tyre_own_pct": median_or_none(r["tyre_own_pct"] for r in rows),
        "tyre_own_measured": sum(r["tyre_own_pct"] is not None for r in rows),
        "centroid_to_hub_measured": sum(r["centroid_to_hub_pct"] is not None for r in rows),
        "median_wheel_on_hubs_pct": median_or_none(r.get("wheel_on_hubs_pct") for r in rows),
        "median_tyre_on_hubs_pct": median_or_none(r.get("tyre_on_hubs_pct") for r in rows),
        "photos_with_hubs": sum(bool(r["hubs_found"]) for r in rows),
        "library_arch_range": [low, high], "arches_measured": len(arches),
        "fitted_arch_range": [min(map(min, arches)), max(map(max, arches))] if arches else None,
        "arches_outside_library": sum(min(a) < low or max(a) > high for a in arches),
        "hubs_found": sum(r["hubs_found"] or 0 for r in rows),
        "median_time_s": statistics.median(times) if times else None, "max_time_s": max(times, default=None),
        "median_cpu_s": statistics.median(cpu) if cpu else None, "max_cpu_s": max(cpu, default=None),
        **{f"median_{k}_s": median_or_none((r["stage_s"] or {}).get(k) for r in rows) for k in ("load", "fit", "surfaces")},
        "median_fit_and_surfaces_s": median_or_none(r["stage_s"]["fit"] + r["stage_s"]["surfaces"] for r in rows
                                                    if r["stage_s"] and "surfaces" in r["stage_s"]),
        **rims_summary(rows),
        "fallbacks": sum(bool(r["fallback"]) for r in rows),
        "mirrored_halves": sum(bool(r["mirrored_half"]) for r in rows),
        "max_camera_check_px": max((r["camera_check_px"] for r in rows if r["camera_check_px"] is not None),
                                   default=None),
    }


#: Issue 24's targets on the photos' figures: (label, the statistic of a list of rows, the
#: comparison, the bound, the number's format, its unit).
TARGETS = (
    ("photos with a body", lambda rs: 100.0 * np.mean([r["outcome"] == "body" for r in rs]), ">=", 90.0, ".0f", "%"),
    (f"view within {VIEW_OK_DEG:.0f}° of the estimate",
     lambda rs: 100.0 * np.mean([r["view_diff_deg"] is not None and r["view_diff_deg"] <= VIEW_OK_DEG for r in rs]),
     ">=", 90.0, ".0f", "%"),
    ("median |length| error", lambda rs: _median_abs(rs, "length_err_pct"), "<=", 5.0, ".1f", "%"),
    ("median |wheelbase| error", lambda rs: _median_abs(rs, "wheelbase_err_pct"), "<=", 5.0, ".1f", "%"),
    ("median IoU windshield", lambda rs: median_or_none(r["iou"]["windshield"] for r in rs), ">=", 0.75, ".2f", ""),
    ("median IoU hood", lambda rs: median_or_none(r["iou"]["hood"] for r in rs), ">=", 0.70, ".2f", ""),
    ("median wheel-centre distance", lambda rs: median_or_none(r["wheel_dist_pct"] for r in rs), "<=", 2.0, ".1f", "%"),
)
#: Draws of the photos for the targets' odds (:func:`target_odds`).
TARGET_DRAWS = 2000
#: Per photo: fit plus surfaces (the report's stage times) and the whole fresh process, s.
FIT_AND_SURFACES_LIMIT_S, FRESH_PROCESS_LIMIT_S = 3.0, 8.0


def target_odds(rows: list[dict], draws: int = TARGET_DRAWS, seed: int = 0) -> list[dict]:
    """Each of :data:`TARGETS` on ``rows``: its value, whether it is met, and the share of
    ``draws`` sets of as many photos drawn from them with replacement that meet it. Then the
    per-photo time limits, counted over the photos."""
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(rows), size=(draws, len(rows))) if rows else np.zeros((0, 0), int)
    met = {">=": lambda v, b: v is not None and bool(v >= b), "<=": lambda v, b: v is not None and bool(v <= b)}
    out = []
    for label, stat, op, bound, spec, unit in TARGETS:
        value = stat(rows) if rows else None
        value = None if value is None else float(value)
        odds = float(np.mean([met[op](stat([rows[i] for i in pick]), bound) for pick in picks])) if rows else None
        out.append({"target": label, "value": value, "op": op, "bound": bound, "met": met[op](value, bound),
                    "draws_met": odds, "format": spec, "unit": unit})
    staged = [r["stage_s"]["fit"] + r["stage_s"]["surfaces"] for r in rows
              if r.get("stage_s") and "surfaces" in r["stage_s"]]
    for label, values, bound in ((f"fit + surfaces ≤ {FIT_AND_SURFACES_LIMIT_S:g} s a photo", staged,
                                  FIT_AND_SURFACES_LIMIT_S),
                                 (f"a fresh process ≤ {FRESH_PROCESS_LIMIT_S:g} s a photo",
                                  [r["seconds"] for r in rows], FRESH_PROCESS_LIMIT_S)):
        within = int(sum(v <= bound for v in values))
        out.append({"target": label, "value": max(values, default=None), "op": "<=", "bound": bound,
                    "met": bool(values) and within == len(values), "within": within, "of": len(values),
                    "draws_met": None, "format": ".1f", "unit": " s"})
    return out


def targets_table(targets: list[dict]) -> str:
    lines = ["| target | measured | met | sets of photos like these drawn again: share meeting it |",
             "|---|---|---|---|"]
    for t in targets:
        bound = f"{t['op'].replace('>=', '≥').replace('<=', '≤')} {t['bound']:{t['format']}}{t['unit']}"
        value = "–" if t["value"] is None else f"{t['value']:{t['format']}}{t['unit']}"
        if "within" in t:
            value = f"{t['within']} of {t['of']} within (max {value})"
            odds = "– (per photo)"
        else:
            odds = f"{100 * t['draws_met']:.0f} %" if t["draws_met"] is not None else "–"
        lines.append(f"| {t['target']} ({bound}) | {value} | {'yes' if t['met'] else 'no'} | {odds} |")
    return "\n".join(lines)


def rims_summary(rows: list[dict]) -> dict:
    """The rims' view against the estimate and the view found, over the photos where the rims
    gave one (:func:`rims_view`)."""
    rimmed = [r for r in rows if r["rims_view_deg"] is not None]
    leans = [r["rims_lean_deg"] for r in rimmed if r["rims_lean_deg"] is not None]
    return {"rims_measured": len(rimmed),
            "rims_within": sum(r["rims_diff_deg"] is not None and r["rims_diff_deg"] <= VIEW_OK_DEG for r in rimmed),
            "view_within_where_rims": sum(r["view_diff_deg"] is not None and r["view_diff_deg"] <= VIEW_OK_DEG
                                          for r in rimmed),
            "median_abs_rims_estimate_deg": median_or_none(r["rims_diff_deg"] for r in rimmed),
            "median_abs_view_rims_deg": median_or_none(r["fit_rims_diff_deg"] for r in rimmed),
            "median_rims_lean_deg": median_or_none(leans), "rims_lean_measured": len(leans),
            "rims_lean_to_end": sum(v < -LEAN_NOTED_DEG for v in leans),
            "rims_lean_to_side": sum(v > LEAN_NOTED_DEG for v in leans)}


def summary_table(s: dict) -> str:
    n, c = s["photos"], s["outcomes"]

    def with_n(region: str) -> str:
        return f"{fmt(s[f'median_iou_{region}'], '.2f') or '–'} (of {s[f'iou_{region}_measured']})"

    lines = ["| measure | value |", "|---|---|",
             f"| photos | {n} |",
             f"| outcomes | {c['body']} body, {c['refused']} refused (exit 2), {c['error']} error |",
             f"| with a body | {fmt(s['body_pct'])} % |",
             f"| view within {s['view_within_deg']:.0f}° of the estimate | {s['view_within']} of {n} "
             f"({fmt(s['view_within_pct_of_photos'])} %; {s['view_measured']} with a view found) |",
             f"| three-quarter views ({s['view_lean_measured']}): the view found from the car's nearer end, less "
             f"the estimate's, median (−: nearer the end); more than {LEAN_NOTED_DEG:.0f}° nearer the end / the side | "
             f"{fmt(s['median_view_lean_deg'], '.1f', signed=True) or '–'}°; {s['view_leans_to_end']} / "
             f"{s['view_leans_to_side']} |",
             f"| the rear wheels' rims as a second view (a check of the estimate), on {s['rims_measured']} photos: "
             f"the rims / the view found within {s['view_within_deg']:.0f}° of the estimate | {s['rims_within']} / "
             f"{s['view_within_where_rims']} |",
             f"| on them, median \\|rims − estimate\\| / \\|view found − rims\\| | "
             f"{fmt(s['median_abs_rims_estimate_deg'], '.1f') or '–'}° / {fmt(s['median_abs_view_rims_deg'], '.1f') or '–'}° |",
             f"| on them, three-quarter views ({s['rims_lean_measured']}): the rims from the car's nearer end, less the "
             f"estimate's, median; more than {LEAN_NOTED_DEG:.0f}° nearer the end / the side | "
             f"{fmt(s['median_rims_lean_deg'], '.1f', signed=True) or '–'}°; {s['rims_lean_to_end']} / "
             f"{s['rims_lean_to_side']} |",
             f"| median residual, % of the car's image size | {fmt(s['median_residual_pct'], '.1f')} |",
             "| median \\|length\\| / \\|width\\| / \\|wheelbase\\| error | "
             f"{fmt(s['median_abs_length_err_pct'], '.1f')} / "
             f"{fmt(s['median_abs_width_err_pct'], '.1f')} / {fmt(s['median_abs_wheelbase_err_pct'], '.1f')} "
             "% |",
             f"| of them (the {s['size_split_measured']} with both published): median \\|length ÷ wheelbase\\| "
             f"error / median signed wheelbase error | {fmt(s['median_abs_length_over_wheelbase_err_pct'], '.1f')} / "
             f"{fmt(s['median_signed_wheelbase_err_pct'], '.1f', signed=True)} % |",
             f"| median \\|height\\| error (of {s['height_measured']}) | {fmt(s['median_abs_height_err_pct'], '.1f')} % |",
             f"| height ÷ width error, signed (−: the fitted car too low), views within {END_ON_DEG:.0f}° of an end: "
             f"each / the other views: median and range | "
             + (", ".join(fmt(v, "+.0f") for v in s["end_on_height_over_width_err_pct"]) or "–") + " % / "
             + (f"{fmt(median_or_none(s['other_height_over_width_err_pct']), '+.1f')} % "
                f"({fmt(min(s['other_height_over_width_err_pct']), '+.0f')} … "
                f"{fmt(max(s['other_height_over_width_err_pct']), '+.0f')}, of {len(s['other_height_over_width_err_pct'])})"
                if s["other_height_over_width_err_pct"] else "–") + " |",
             f"| median signed width ÷ wheelbase error (−: the fitted car too narrow) | "
             f"{fmt(s['median_signed_width_over_wheelbase_err_pct'], '.1f', signed=True)} % |",
             f"| the wheelbase's spread the report gives (median), and the published wheelbase within one / two "
             f"of it (of {s['wheelbase_spread_measured']}) | ±{fmt(s['median_wheelbase_spread_pct'], '.1f')} %; "
             f"{s['wheelbase_within_spread']} / {s['wheelbase_within_two_spreads']} |",
             f"| median IoU windshield ↔ front_glass | {with_n('windshield')} |",
             f"| median IoU rear window ↔ back_glass | {with_n('rear_window')} |",
             f"| median IoU hood ↔ hood | {with_n('hood')} |",
             f"| the hoods, median: share of ours inside theirs / of theirs we cover | "
             f"{fmt(s['median_hood_inside'], '.2f') or '–'} / {fmt(s['median_hood_covered'], '.2f') or '–'} |",
             f"| ours from theirs along the car, median (+: toward the windshield), % of the car's image size; "
             f"more than {HOOD_SHIFT_NOTED_PCT:.0f} % back / forward | {fmt(s['median_hood_back_pct'], '+.1f') or '–'}; "
             f"{s['hood_lies_back']} / {s['hood_lies_forward']} (of {s['hood_back_measured']}) |",
             f"| median wheel-centre distance, % of the car's image size | "
             f"{fmt(s['median_wheel_dist_pct'], '.1f') or '–'} (of {s['wheel_dist_measured']}) |",
             f"| median signed vertical offset of those centres, annotated − projected (+: the projected "
             f"centre above), % | {fmt(s['median_wheel_dv_pct'], '.1f', signed=True) or '–'} |",
             f"| the measure's own error: median distance of the annotated wheels' centroids from the hubs "
             f"the fit found, % | {fmt(s['median_centroid_to_hub_pct'], '.1f') or '–'} "
             f"(of {s['centroid_to_hub_measured']}) |",
             f"| like for like: median distance of the annotated wheels' centroids from those of the tyres our car "
             f"shows (fitted body and tyres drawn in the fitted camera), % | "
             f"{fmt(s['median_tyre_dist_pct'], '.1f') or '–'} (of {s['tyre_dist_measured']}) |",
             f"| its own error: the same with our tyres on the hubs the fit found, % | "
             f"{fmt(s['median_tyre_own_pct'], '.1f') or '–'} (of {s['tyre_own_measured']}) |",
             f"| wheels placed apart from the body, on every hub the fit trusted: median wheel-centre distance "
             f"/ like for like, % | {fmt(s['median_wheel_on_hubs_pct'], '.1f') or '–'} / "
             f"{fmt(s['median_tyre_on_hubs_pct'], '.1f') or '–'} |",
             "| wheel arches: radius ÷ wheelbase, fitted range; photos with an arch outside the templates' "
             f"range ({s['library_arch_range'][0]:.3f}–{s['library_arch_range'][1]:.3f}) | "
             + (f"{s['fitted_arch_range'][0]:.3f}–{s['fitted_arch_range'][1]:.3f}; "
                f"{s['arches_outside_library']} of {s['arches_measured']} |" if s["fitted_arch_range"] else "– |"),
             f"| photos with hubs found in them (hubs in all) | {s['photos_with_hubs']} ({s['hubs_found']}) |",
             f"| time per photo (wall), median / max | {fmt(s['median_time_s'], '.1f')} / "
             f"{fmt(s['max_time_s'], '.1f')} s |",
             f"| CPU time per photo (user + system), median / max | {fmt(s['median_cpu_s'], '.1f')} / "
             f"{fmt(s['max_cpu_s'], '.1f')} s |",
             f"| fit + surfaces per photo (wall, the report's stage times), median | "
             f"{fmt(s['median_fit_and_surfaces_s'], '.1f')} s (fit {fmt(s['median_fit_s'], '.1f')}, "
             f"surfaces {fmt(s['median_surfaces_s'], '.1f')}); before them, loading OCCT and scipy once "
             f"per process {fmt(s['median_load_s'], '.1f')} s |",
             f"| stiffer fallback used | {s['fallbacks']} |",
             f"| fitted left half at x ≤ 0 (mirrored) | {s['mirrored_halves']} |"]
    return "\n".join(lines)


def machine_line(load_start: tuple[float, float, float], workers: int, reused: bool,
                 blas_threads: int | str | None = None, rows: list[dict] = ()) -> str:
    """One line: cores, CPU, Python, the load average at start and end, and before the runs
    themselves (the rows' ``load_before``: with ``--reuse`` the runs were earlier)."""
    load_end = os.getloadavg()
    before = [r["load_before"] for r in rows if r.get("load_before") is not None]
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").exists() \
        else platform.processor()
    return (f"machine: {os.cpu_count()} cores ({cpu}), Python {platform.python_version()}; load average "
            f"(1/5/15 min) {'/'.join(f'{v:.2f}' for v in load_start)} at start, "
            f"{'/'.join(f'{v:.2f}' for v in load_end)} at end; {workers} worker(s); BLAS threads "
            + ("as the environment has them (a user's)" if blas_threads is None else f"set to {blas_threads}")
            + (f"; 1-min load average before each run: median {statistics.median(before):.2f}, "
               f"{min(before):.2f}–{max(before):.2f}" if before else "")
            + ("; times from the stored runs (--reuse)" if reused else ""))


# --- contact sheet ---------------------------------------------------------------------------

TILE_W, TILE_H, BAND_H = 400, 280, 76


def draw_tile(photo: Photo, row: dict, out: Path) -> np.ndarray:
    """(BAND_H + TILE_H, TILE_W, 3) uint8 BGR: the overlay (or the photo and its marks), the
    human polygons filled, the projected regions outlined, wheel centres, and the row's text."""
    import cv2

    folder = out / photo.name
    overlay = folder / "overlay.png"
    img = cv2.imread(str(overlay if row["outcome"] == "body" and overlay.exists() else photo.image))
    if img is None:
        img = np.full((TILE_H, TILE_W, 3), 60, np.uint8)
    if row["outcome"] != "body":  # no overlay: the marks as the fit got them
        for u, v in photo.meta["keypoints"].values():
            cv2.circle(img, (round(u), round(v)), max(2, img.shape[1] // 300), (0, 0, 255), -1, cv2.LINE_AA)
    h, w = img.shape[:2]
    k = min(TILE_W / w, TILE_H / h)
    small = cv2.resize(img, (round(w * k), round(h * k)), interpolation=cv2.INTER_AREA)
    grey = cv2.cvtColor(cv2.cvtColor(small, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
    small = cv2.addWeighted(small, 0.45, grey, 0.55, 0)  # muted, so the measured colours stand out
    tile = np.full((TILE_H, TILE_W, 3), 30, np.uint8)
    oy, ox = (TILE_H - small.shape[0]) // 2, (TILE_W - small.shape[1]) // 2
    tile[oy:oy + small.shape[0], ox:ox + small.shape[1]] = small

    def px(points) -> np.ndarray:
        return np.round((np.asarray(points) * k + [ox, oy]) * 16).astype(np.int32)

    def rings(geom):
        for g in getattr(geom, "geoms", [geom]):
            if g.geom_type == "Polygon" and not g.is_empty:
                yield np.asarray(g.exterior.coords)

    fill = tile.copy()
    for region, part in REGION_PARTS:
        for p in photo.parts.get(part, []):
            cv2.fillPoly(fill, [px(p)], REGION_COLOURS[region], cv2.LINE_AA, shift=4)
    tile = cv2.addWeighted(fill, 0.35, tile, 0.65, 0)
    wheels = annotated_wheel_centres(photo)
    if row["outcome"] == "body":
        report, wireframe = fitted(folder)
        camera, cp = report["fit"]["camera"], wireframe.control_points
        for region, part in REGION_PARTS:
            if part in photo.parts:
                for ring in rings(projected_region(camera, cp, region)):
                    cv2.polylines(tile, [px(ring)], True, REGION_COLOURS[region], 2, cv2.LINE_AA, shift=4)
        projected = projected_wheel_centres(camera, cp)
        for c in projected:
            (u, v), s = px(c) // 16, 5
            cv2.line(tile, (u - s, v - s), (u + s, v + s), WHEEL_PROJECTED, 2, cv2.LINE_AA)
            cv2.line(tile, (u - s, v + s), (u + s, v - s), WHEEL_PROJECTED, 2, cv2.LINE_AA)
        if len(wheels):
            for i, j, _ in wheel_matches(wheels, projected):
                cv2.line(tile, tuple(px(wheels[i]) // 16), tuple(px(projected[j]) // 16), WHEEL_PROJECTED, 1,
                         cv2.LINE_AA)
    for c in wheels:
        cv2.circle(tile, tuple(px(c) // 16), 4, WHEEL_ANNOTATED, -1, cv2.LINE_AA)
        cv2.circle(tile, tuple(px(c) // 16), 4, (0, 0, 0), 1, cv2.LINE_AA)

    band = np.full((BAND_H, TILE_W, 3), 15, np.uint8)
    colour = {"body": (120, 230, 120), "refused": (60, 180, 255), "error": (80, 80, 255)}[row["outcome"]]
    found = f"{row['view_found_deg']:.0f}" if row["view_found_deg"] is not None else "-"
    text1 = f"{photo.name.removeprefix('cps_')}  {row['outcome']}  {row['seconds']:.0f} s" \
            + ("  fallback" if row["fallback"] else "")
    text2 = f"view {found} / est {row['view_estimate_deg']}" \
            + (f" (d {row['view_diff_deg']:.0f})" if row["view_diff_deg"] is not None else "") \
            + (f"  wheels {row['wheel_dist_pct']:.1f}%" if row["wheel_dist_pct"] is not None else "")
    ious = [(name, row["iou"][r]) for (r, _), name in zip(REGION_PARTS, ("ws", "rw", "hood"))
            if row["iou"][r] is not None]
    if row["outcome"] == "body":
        texts = ["IoU " + "  ".join(f"{n} {v:.2f}" for n, v in ious) if ious else "no glass or hood annotated"]
    else:  # the refusal's line (or the error's last line) in two
        message = (row["message"] or "").removeprefix("carbody reconstruct: error: ")
        texts = textwrap.wrap(message, 58)[:2]
    for i, (text, col) in enumerate([(text1, colour), (text2, (235, 235, 235))]
                                    + [(t, (235, 235, 235)) for t in texts]):
        cv2.putText(band, text, (6, 17 + 18 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.47, col, 1, cv2.LINE_AA)
    return np.vstack([band, tile])


def legend(width: int) -> np.ndarray:
    import cv2

    band = np.full((34, width, 3), 15, np.uint8)
    x = 8
    items = [(f"{r.replace('_', ' ')}: human filled, projected outline", REGION_COLOURS[r]) for r, _ in REGION_PARTS]
    items += [("wheel centre: annotated (dot)", WHEEL_ANNOTATED), ("projected (cross)", WHEEL_PROJECTED)]
    for text, col in items:
        cv2.rectangle(band, (x, 10), (x + 14, 24), col, -1)
        cv2.putText(band, text, (x + 20, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (235, 235, 235), 1, cv2.LINE_AA)
        x += 30 + cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0]
    return band


def contact_sheet(photos: list[Photo], rows: list[dict], out: Path, columns: int = 6) -> Path:
    """Every photo's tile in one picture, ``OUT/contact_sheet.png``."""
    import cv2

    grid = tiled([draw_tile(p, r, out) for p, r in zip(photos, rows)], columns)
    sheet = np.vstack([legend(grid.shape[1]), grid])
    path = out / "contact_sheet.png"
    if not cv2.imwrite(str(path), sheet):
        raise OSError(f"{path}: cannot write the contact sheet")
    return path


def tiled(tiles: list[np.ndarray], columns: int) -> np.ndarray:
    """Equal tiles in rows of ``columns`` (fewer when there are fewer), the last row filled out
    with black."""
    columns = max(1, min(columns, len(tiles)))
    tiles = tiles + [np.zeros_like(tiles[0])] * (-len(tiles) % columns)
    return np.vstack([np.hstack(tiles[i:i + columns]) for i in range(0, len(tiles), columns)])


#: A wheel sheet tile's side (px) and how far its crop reaches round the polygon (its box's sides).
WHEEL_TILE, WHEEL_CROP = 200, 1.6


def wheel_tiles(photo: Photo, row: dict, out: Path) -> list[np.ndarray]:
    """(WHEEL_TILE + 20, WHEEL_TILE, 3) uint8 BGR per annotated wheel of a photo with a body: the
    photo round the polygon (a square :data:`WHEEL_CROP` times its box's larger side), the polygon
    and its centroid (white), the fitted hub it is matched to (orange cross), the hub the fit found
    there and trusted (red ring), and the two distances in % of S written below."""
    import cv2

    from carbody.fit.wheels import WHEELS

    wheels = annotated_wheel_centres(photo)
    if row["outcome"] != "body" or not len(wheels):
        return []
    report, wireframe = fitted(out / photo.name)
    projected = projected_wheel_centres(report["fit"]["camera"], wireframe.control_points)
    found = trusted_hubs(report["fit"].get("wheels"))
    polygons = [p for p in photo.parts["wheel"] if not polygon(p).centroid.is_empty]
    img = cv2.imread(str(photo.image))
    tiles = []
    for i, j, d in wheel_matches(wheels, projected):
        side = WHEEL_CROP * float(np.ptp(polygons[i], axis=0).max())
        k = WHEEL_TILE / side
        origin = wheels[i] - side / 2
        warp = np.array([[k, 0.0, -k * origin[0]], [0.0, k, -k * origin[1]]])
        tile = cv2.warpAffine(img, warp, (WHEEL_TILE, WHEEL_TILE), flags=cv2.INTER_AREA,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=(30, 30, 30))

        def at(point) -> tuple[int, int]:
            return tuple(int(v) for v in np.round((np.asarray(point) - origin) * k * 16))

        cv2.polylines(tile, [np.array([at(q) for q in polygons[i]])], True, WHEEL_ANNOTATED, 1, cv2.LINE_AA, 4)
        cv2.circle(tile, at(wheels[i]), 4 * 16, WHEEL_ANNOTATED, -1, cv2.LINE_AA, 4)
        cv2.drawMarker(tile, tuple(v // 16 for v in at(projected[j])), WHEEL_PROJECTED, cv2.MARKER_TILTED_CROSS, 12, 2)
        text = f"{photo.name.removeprefix('cps_')} {WHEELS[j]}: {100 * d / row['image_size_px']:.1f}%"
        if WHEELS[j] in found:
            cv2.circle(tile, at(found[WHEELS[j]]), 7 * 16, WHEEL_FOUND, 2, cv2.LINE_AA, 4)
            text += f", found {100 * np.linalg.norm(wheels[i] - found[WHEELS[j]]) / row['image_size_px']:.1f}%"
        band = np.full((20, WHEEL_TILE, 3), 15, np.uint8)
        cv2.putText(band, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.36, (235, 235, 235), 1, cv2.LINE_AA)
        tiles.append(np.vstack([tile, band]))
    return tiles


def wheel_sheet(photos: list[Photo], rows: list[dict], out: Path, columns: int = 8) -> Path | None:
    """Every annotated wheel of the photos with a body in one picture, ``OUT/wheel_sheet.png``
    (:func:`wheel_tiles`), for a person to see where the hub lies against the polygon's centroid
    and the hubs placed; None without such a wheel."""
    import cv2

    tiles = [t for p, r in zip(photos, rows) for t in wheel_tiles(p, r, out)]
    if not tiles:
        return None
    path = out / "wheel_sheet.png"
    if not cv2.imwrite(str(path), tiled(tiles, columns)):
        raise OSError(f"{path}: cannot write the wheel sheet")
    return path


# --- main ------------------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DATA, help=f"the real-photo data (default {DATA})")
    ap.add_argument("--out", type=Path, default=OUT, help=f"output folder (default {OUT})")
    ap.add_argument("--photos", nargs="+", default=None, metavar="N|NAME",
                    help="a number N (the first N photos) or photo names (te12, cps_te12); default all")
    ap.add_argument("--workers", type=int, default=1,
                    help="reconstructs at once (default 1: on a small machine more share the cores and "
                         "the times stop being a user's)")
    ap.add_argument("--reuse", action="store_true",
                    help="re-measure the stored outputs and times without re-running (photos never "
                         "run are run)")
    ap.add_argument("--blas-threads", type=int, default=None, metavar="N",
                    help="set OPENBLAS/OMP/MKL_NUM_THREADS=N for the reconstructs (default: not set, as a "
                         "user runs it; on a loaded machine OpenBLAS's own threads make the fit several "
                         "times slower)")
    ap.add_argument("--timeout", type=float, default=TIMEOUT_S, help="seconds per reconstruct (an error after)")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows and summary as JSON here")
    ap.add_argument("--no-sheet", action="store_true", help="skip the contact sheet and the wheel sheet")
    ap.add_argument("--outline", action="store_true",
                    help="reconstruct with --outline: the car's outline in the photo fitted with the marks")
    ap.add_argument("--check-estimates", action="store_true",
                    help="refit each photo whose view was found more than 15° from the estimate with the "
                         "estimate kept, and compare how the two sit on the human polygons")
    ap.add_argument("--wheels", action=argparse.BooleanOptionalAction, default=None,
                    help="reconstruct with --wheels (or --no-wheels): the wheels' hubs found in the photo "
                         "fitted with the marks (default: as reconstruct's default)")
    ap.add_argument("--principal-point", choices=("auto", "car", "centre"), default=None,
                    help="reconstruct with --principal-point: where the camera's axis meets the photo "
                         "(default: as reconstruct's default, auto)")
    args = ap.parse_args(argv)

    if not (args.data / "parts.json").exists():
        print(f"bench_real_photos: no real-photo data at {args.data}", file=sys.stderr)
        return 2
    photos = select(load_photos(args.data), args.photos)
    args.out.mkdir(parents=True, exist_ok=True)
    load_start = os.getloadavg()

    def run_one(photo: Photo) -> dict:
        run = stored_run(photo, args.out) if args.reuse else None
        if run is None:
            extra = ("--outline",) * args.outline + \
                (() if args.wheels is None else ("--wheels",) if args.wheels else ("--no-wheels",)) + \
                (() if args.principal_point is None else ("--principal-point", args.principal_point))
            run = run_photo(photo, args.out, args.timeout, args.blas_threads, extra)
            print(f"{photo.name}: exit {run['exit_code']} in {run['seconds']:.1f} s", file=sys.stderr, flush=True)
        return run

    with ThreadPoolExecutor(max_workers=max(1, args.workers)) as pool:
        runs = list(pool.map(run_one, photos))
    rows = [measure(p, r, args.out) for p, r in zip(photos, runs)]
    summary = summarise(rows)
    sheet = None if args.no_sheet else contact_sheet(photos, rows, args.out)
    wheel_picture = None if args.no_sheet else wheel_sheet(photos, rows, args.out)

    threads = {r.get("blas_threads") for r in runs}  # the runs', stored ones with --reuse
    machine = machine_line(load_start, args.workers, args.reuse,
                           threads.pop() if len(threads) == 1 else "mixed over the runs", rows)
    print(machine + "\n")
    print(photo_table(rows) + "\n")
    messages = messages_table(rows)
    if messages:
        print(messages + "\n")
    print(summary_table(summary))
    targets = target_odds(rows)
    print(f"\nIssue 24's targets, and how often {TARGET_DRAWS} sets of as many photos drawn from these "
          "(with replacement) meet them:\n")
    print(targets_table(targets))
    checks = estimate_check(photos, rows, args.out) if args.check_estimates else None
    if checks:
        print("\nViews found more than 15° from the estimate, against the estimate kept (found / at the "
              "estimate; the elevation found):\n")
        print(estimate_table(checks))
    if sheet is not None:
        print(f"\ncontact sheet: {sheet}")
    if wheel_picture is not None:
        print(f"wheel sheet: {wheel_picture}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"machine": machine, "rows": rows, "summary": summary, "targets": targets,
                                         "estimate_checks": checks,
                                         "contact_sheet": None if sheet is None else str(sheet),
                                         "wheel_sheet": None if wheel_picture is None else str(wheel_picture)},
                                        indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
