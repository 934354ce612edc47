"""The real-photo benchmark measures what it says: run as a user would on three photos of
``../shared/realphotos`` (skipped where that data is absent), every row has an allowed outcome,
every metric is finite where it is defined, and the contact sheet is written outside the
repository's tracked tree."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import REPO

DATA = REPO.parent / "shared" / "realphotos"

#: Quick, typical photos: a hatchback from the side (rear window), a sedan from the front
#: three-quarter (windshield, hood, wheels), an SUV from the front three-quarter (today refused:
#: a wheel arch that cannot be surfaced, the commonest failure). Outcomes are not pinned: the
#: fit is changing, the instrument must measure whatever comes.
PHOTOS = ("cps_te24", "cps_te47", "cps_te12")

needs_data = pytest.mark.skipif(not (DATA / "parts.json").exists(),
                                reason=f"no real-photo data at {DATA} (kept outside the repository)")


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_real_photos

    return bench_real_photos


def test_a_self_crossing_outline_counts_its_two_lobes_once(bench):
    bow_tie = bench.polygon(np.array([[0, 0], [2, 2], [2, 0], [0, 2]], dtype=float))
    assert bow_tie.is_valid and bow_tie.area == pytest.approx(2.0)


def test_each_annotated_wheel_takes_its_own_projected_centre(bench):
    """Two wheels both nearest one centre: the one-to-one match gives the second its own."""
    annotated = np.array([[0.0, 0.0], [3.0, 0.0]])
    projected = np.array([[1.0, 0.0], [10.0, 0.0], [-20.0, 0.0], [-30.0, 0.0]])
    assert sorted((i, j) for i, j, _ in bench.wheel_matches(annotated, projected)) == [(0, 0), (1, 1)]


def test_a_wheel_placed_on_its_trusted_hub_moves_with_it_and_an_untrusted_one_stays(bench):
    hubs = np.array([[10.0, 50.0], [30.0, 50.0], [80.0, 40.0], [95.0, 40.0]])
    seen = hubs + [0.0, 4.0]  # visible tyres a little below their hubs
    wheels = {"wheels": [{"wheel": "front_left", "found_px": [12.0, 47.0], "weight": 0.9},
                         {"wheel": "rear_left", "found_px": [70.0, 45.0], "weight": 0.3}]}
    moved = bench.on_found_hubs(seen, hubs, bench.trusted_hubs(wheels))
    assert moved[0] == pytest.approx([12.0, 51.0])  # the tyre keeps its offset from the hub
    assert moved[1:] == pytest.approx(seen[1:])     # the rear hub's weight is too low to trust


def test_the_lean_is_signed_toward_the_cars_nearer_end_on_three_quarter_views_only(bench):
    assert bench.view_lean_deg(35.0, 50.0) == pytest.approx(-15.0)      # front-left, found nearer the front
    assert bench.view_lean_deg(305.0, 290.0) == pytest.approx(-15.0)    # front-right, found nearer the front
    assert bench.view_lean_deg(140.0, 150.0) == pytest.approx(+10.0)    # rear-left, found nearer the side
    assert bench.view_lean_deg(5.0, 0.0) is None and bench.view_lean_deg(85.0, 90.0) is None


def _row(wheel_pct: float, fit_s: float = 1.0) -> dict:
    return {"outcome": "body", "view_diff_deg": 5.0, "length_err_pct": 1.0, "wheelbase_err_pct": -1.0,
            "iou": {"windshield": 0.9, "hood": 0.8}, "wheel_dist_pct": wheel_pct,
            "stage_s": {"fit": fit_s, "surfaces": 0.5}, "seconds": 5.0}


def test_a_target_met_by_every_photo_holds_on_every_draw_and_one_on_the_median_on_about_half(bench):
    """The targets' odds: the photos drawn again with replacement, each figure recomputed."""
    clear = {t["target"]: t for t in bench.target_odds([_row(1.0) for _ in range(20)], draws=400)}
    wheels = next(k for k in clear if k.startswith("median wheel-centre"))
    assert clear[wheels]["met"] and clear[wheels]["draws_met"] == 1.0
    # half the photos at 1 %, half at 3 %: the median sits on the 2 % target
    split = {t["target"]: t for t in bench.target_odds([_row(1.0) for _ in range(10)] + [_row(3.0)] * 10,
                                                       draws=400)}
    assert 0.3 < split[wheels]["draws_met"] < 0.7
    slow = {t["target"]: t for t in bench.target_odds([_row(1.0)] * 9 + [_row(1.0, fit_s=2.9)], draws=50)}
    timed = next(t for k, t in slow.items() if k.startswith("fit + surfaces"))
    assert (timed["within"], timed["of"], timed["met"]) == (9, 10, False)  # 2.9 + 0.5 s is over 3 s
    assert "| median IoU hood (≥ 0.70) | 0.80 | yes | 100 % |" in bench.targets_table(list(clear.values()))


def test_a_region_of_a_template_seen_from_the_front_is_the_union_of_its_halves(bench, templates):
    """The windshield's left loop and its mirror, projected, make one symmetric outline whose
    width is the template's windshield base (a_pillar_base on both sides)."""
    from carbody.fit.report import project_with_camera

    wireframe = templates[0][1]
    cp = wireframe.control_points
    camera = {"azimuth_deg": 0.0, "elevation_deg": 0.0, "roll_deg": 0.0, "distance_mm": None,
              "aim_mm": [0.0, 0.0, 0.0], "scale_px_per_mm": 0.1, "offset_px": [500.0, 500.0], "to_photo": None}
    shield = bench.projected_region(camera, cp, "windshield")
    assert shield.geom_type == "Polygon"
    u = project_with_camera(camera, np.array([wireframe.keypoints()["a_pillar_base"]]))[0, 0]
    lo, _, hi, _ = shield.bounds
    assert hi - lo == pytest.approx(2 * abs(u - 500.0), rel=0.05)
    assert (lo + hi) / 2 == pytest.approx(500.0, abs=0.5)


def test_a_hood_drawn_forward_of_ours_reads_as_ours_lying_back(bench, templates, tmp_path):
    """The people's hood is ours moved 20 px toward the nose: ours lies 20 px back (toward the
    windshield), and each covers the same share of the other."""
    import shapely

    from carbody.fit.report import project_with_camera

    wireframe = templates[0][1]
    cp = wireframe.control_points
    camera = {"azimuth_deg": 60.0, "elevation_deg": 10.0, "roll_deg": 0.0, "distance_mm": None,
              "aim_mm": [0.0, 0.0, 0.0], "scale_px_per_mm": 0.1, "offset_px": [500.0, 500.0], "to_photo": None}
    ours = bench.projected_region(camera, cp, "hood")
    nose, cowl = project_with_camera(camera, np.array([wireframe.keypoints()[n] for n in ("nose_centre", "cowl_centre")]))
    forward = (nose - cowl) / np.linalg.norm(nose - cowl)
    theirs = shapely.affinity.translate(ours, *(20.0 * forward))
    photo = bench.Photo("made_up", tmp_path / "x.jpg", tmp_path / "x.json", {},
                        {"hood": [np.asarray(theirs.exterior.coords)]})
    got = bench.hood_offset(photo, camera, cp)
    assert got["back_px"] == pytest.approx(20.0, abs=3.0)
    assert got["inside"] == pytest.approx(got["covered"], abs=0.02) and 0.2 < got["inside"] < 0.95
    assert bench.hood_offset(bench.Photo("no_hood", tmp_path / "x.jpg", tmp_path / "x.json", {}, {}), camera, cp) is None


def test_a_template_stands_as_high_as_it_was_built(bench, templates):
    """The height on the ground the benchmark reads (a tyre's radius of 0.12 wheelbase under the
    wheel centres) is each template's own within 4 %: its tyres are 0.11–0.14 wheelbase."""
    for row, wireframe in templates:
        assert bench.fitted_height_mm(wireframe.measure()) == pytest.approx(row["height_mm"], rel=0.04), row["name"]


def test_the_nearer_triangle_owns_the_pixel_whichever_is_listed_first(bench):
    camera = {"azimuth_deg": 90.0, "elevation_deg": 0.0, "roll_deg": 0.0, "distance_mm": 5000.0,
              "aim_mm": [0.0, 0.0, 0.0], "scale_px_per_mm": 0.1, "offset_px": [100.0, 100.0], "to_photo": None}

    def square(x: float) -> np.ndarray:  # at x (the camera at +x), 400 mm across
        c = np.array([[x, -200, -200], [x, 200, -200], [x, 200, 200], [x, -200, 200]], dtype=float)
        return np.stack([c[[0, 1, 2]], c[[0, 2, 3]]])

    for layers, near in (([square(0.0), square(300.0)], 1), ([square(300.0), square(0.0)], 0)):
        image = bench.owner_image(camera, layers, (200, 200))
        assert image[100, 100] == near and image[5, 5] == -1


def test_the_tyres_are_cylinders_on_the_fitted_hubs(bench, templates):
    from carbody.fit.report import project_with_camera

    cp = templates[0][1].control_points
    camera = {"azimuth_deg": 90.0, "elevation_deg": 0.0, "roll_deg": 0.0, "distance_mm": None,
              "aim_mm": [0.0, 0.0, 0.0], "scale_px_per_mm": 0.1, "offset_px": [500.0, 500.0], "to_photo": None}
    hubs = bench.projected_wheel_centres(camera, cp)
    for tyre, hub in zip(bench.tyre_triangles(cp), hubs):
        uv = project_with_camera(camera, tyre.reshape(-1, 3))
        assert np.allclose((uv.min(axis=0) + uv.max(axis=0)) / 2, hub, atol=0.5)  # round the hub, seen side on
        assert 25.0 < np.ptp(uv[:, 1]) / 2 < 40.0                                   # a tyre's radius, 250–400 mm


def test_an_arch_grows_with_the_ride_height_and_the_templates_span_a_real_range(bench, templates):
    from carbody.fit.wheels import hub_points, ride_height_direction

    cp = templates[0][1].control_points
    front, rear = bench.arches_per_wheelbase(cp)
    low, high = bench.library_arch_range()
    assert 0.1 < low <= min(front, rear) and max(front, rear) <= high < 0.2  # 300–450 mm at a 2.7 m wheelbase
    hubs = hub_points(cp)
    wheelbase_mm = float(np.linalg.norm(hubs[2, 1:] - hubs[0, 1:]))
    raised = bench.arches_per_wheelbase(cp + 50.0 * ride_height_direction().reshape(-1, 3))  # 50 mm higher
    assert raised == pytest.approx([front + 50.0 / wheelbase_mm, rear + 50.0 / wheelbase_mm], rel=1e-6)


def test_a_rear_wheels_rim_reads_the_view_the_example_was_rendered_at(bench, example_reconstruction):
    """The example was rendered at 30°: its rear wheel's rim, read from views 5° and 10° off
    the one found (the hub kept where it was found), comes back to 30°; and a view turned by
    the instrument keeps the hub in place."""
    from carbody.fit.report import camera_report
    from carbody.fit.wheels import WHEELS, arch_radii, grey_photo, hub_points
    from carbody.policy import FitPolicy
    from carbody.view.predict import read_image

    fit = example_reconstruction.fit
    camera, cp = camera_report(fit), fit.wireframe.control_points
    rear = next(w for w in fit.wheels.as_dict()["wheels"] if w["wheel"] == "rear_left")
    hub, radius = hub_points(cp)[WHEELS.index("rear_left")], float(arch_radii(cp)[WHEELS.index("rear_left")])
    grey = grey_photo(read_image(REPO / "examples" / "car.png"))
    for start in (camera["azimuth_deg"] - 5.0, camera["azimuth_deg"] + 5.0, camera["azimuth_deg"] + 10.0):
        assert bench.rim_view_deg(grey, camera, hub, radius, rear["found_px"], start, FitPolicy()) == \
            pytest.approx(30.0, abs=1.0)
    from carbody.fit.report import project_with_camera
    assert bench.camera_turned(camera, hub, 50.0)(hub[None])[0] == pytest.approx(project_with_camera(camera, hub[None])[0])


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench_real_photos")
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / "bench_real_photos.py"), "--data", str(DATA),
                           "--out", str(out), "--photos", *PHOTOS, "--json", str(out / "rows.json"),
                           "--check-estimates",
                           # one BLAS thread: the test checks the instrument, not a user's times, and
                           # OpenBLAS's own threads make a fit several times slower on a busy machine
                           "--blas-threads", "1"],
                          capture_output=True, text=True, cwd=REPO, env={**os.environ}, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out, proc.stdout, json.loads((out / "rows.json").read_text())


@needs_data
def test_every_photo_has_a_row_with_an_allowed_outcome(bench_run):
    _, stdout, data = bench_run
    assert [r["photo"] for r in data["rows"]] == list(PHOTOS)
    for r in data["rows"]:
        assert r["outcome"] in ("body", "refused", "error")
        assert (r["message"] is None) == (r["outcome"] == "body")
        if r["outcome"] == "refused":
            assert r["exit_code"] == 2 and r["message"].startswith("carbody reconstruct: error: ")
        assert r["photo"].removeprefix("cps_") in stdout
    # the Markdown tables and the machine it ran on
    assert stdout.startswith("machine: ") and "| photo | outcome |" in stdout and "| measure | value |" in stdout
    assert data["summary"]["photos"] == 3 and sum(data["summary"]["outcomes"].values()) == 3


@needs_data
def test_metrics_are_finite_where_defined(bench_run):
    _, _, data = bench_run
    for r in data["rows"]:
        assert r["seconds"] > 0 and r["image_size_px"] > 0
        if r["outcome"] != "body":
            assert r["view_found_deg"] is None and all(v is None for v in r["iou"].values())
            continue
        assert 0 <= r["view_diff_deg"] <= 180 and math.isfinite(r["residual_pct"])
        for key in ("length", "width", "height", "wheelbase"):
            assert (r[f"{key}_err_pct"] is None) == (key not in r["published_mm"])
            assert r[f"{key}_err_pct"] is None or math.isfinite(r[f"{key}_err_pct"])
        # no wheelbase told: the report's spread of the one the proportions gave, a few per cent
        assert 2.0 < r["wheelbase_spread_pct"] < 20.0
        for region, part in (("windshield", "front_glass"), ("rear_window", "back_glass"), ("hood", "hood")):
            iou = r["iou"][region]
            assert (iou is None) == (part not in r["parts"])  # only parts the data set drew
            assert iou is None or 0.0 <= iou <= 1.0
        assert (r["wheel_dist_pct"] is None) == (r["wheels_annotated"] == 0)
        assert r["wheel_dist_pct"] is None or math.isfinite(r["wheel_dist_pct"])
        assert all(0.05 < a < 0.3 for a in r["arches_per_wheelbase"])  # an arch, not a point or the whole side
        assert (r["tyre_dist_pct"] is None) == (r["wheels_annotated"] == 0)
        assert r["tyre_dist_pct"] is None or 0.0 <= r["tyre_dist_pct"] < 100.0
        assert (r["wheel_on_hubs_pct"] is None) == (r["wheels_annotated"] == 0)
        # the instrument projects with the fit's own camera: the marks land where the fit says
        assert r["camera_check_px"] < 0.05
        # the rims' view only from rear wheels the fit found and trusted
        trusted = {w["wheel"] for w in (json.loads((bench_run[0] / r["photo"] / "report.json").read_text())
                                        ["fit"]["wheels"] or {}).get("wheels", []) if w["weight"] > 0.6}
        assert set(r["rims"]) <= {w for w in trusted if w.startswith("rear")}
        if r["wheel_on_hubs_pct"] is not None and not trusted:  # wheels on the hubs trusted: none, as fitted
            assert r["wheel_on_hubs_pct"] == pytest.approx(r["wheel_dist_pct"])
        assert (r["rims_view_deg"] is None) == (not r["rims"])


@needs_data
def test_the_contact_sheet_is_written_into_the_output_folder(bench_run):
    import cv2

    out, _, data = bench_run
    sheet = cv2.imread(data["contact_sheet"])
    assert sheet is not None and sheet.shape[1] >= 3 * 300
    assert data["contact_sheet"].startswith(str(out))
    for photo in PHOTOS:  # each run's record beside its folder, for --reuse
        assert (out / f"{photo}.run.json").exists()


@needs_data
def test_the_wheel_sheet_has_a_tile_for_each_annotated_wheel_of_a_body(bench, bench_run):
    import cv2

    out, stdout, data = bench_run
    wheels = sum(r["wheels_annotated"] for r in data["rows"] if r["outcome"] == "body")
    assert wheels and data["wheel_sheet"] == str(out / "wheel_sheet.png") and "wheel sheet: " in stdout
    sheet = cv2.imread(data["wheel_sheet"])
    columns = min(wheels, 8)
    rows = -(-wheels // columns)
    assert sheet.shape == (rows * (bench.WHEEL_TILE + 20), columns * bench.WHEEL_TILE, 3)


@needs_data
def test_a_view_found_far_from_the_estimate_is_measured_at_the_estimate_too(bench_run):
    """Every body whose view lies more than 15° from the estimate has the estimate-kept fit
    beside it, measured the same way (the estimate is by eye: the human polygons arbitrate)."""
    _, stdout, data = bench_run
    off = [r["photo"] for r in data["rows"] if r["outcome"] == "body" and r["view_diff_deg"] > 15]
    checks = data["estimate_checks"] or []
    assert [c["photo"] for c in checks] == off
    for c in checks:
        assert "error" not in c
        for fit in (c["found"], c["at_estimate"]):
            assert math.isfinite(fit["residual_pct"]) and set(fit["iou"]) == {"windshield", "rear_window", "hood"}
    assert bool(off) == ("against the estimate kept" in stdout)
