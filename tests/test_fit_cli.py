"""``carbody fit`` and ``carbody visible-keypoints`` end to end, and their refusals."""
import json
import re
import os

import numpy as np
import pytest

from tests.conftest import run_cli


@pytest.fixture(scope="module")
def photo(tmp_path_factory, library):
    """A drawn (photo-free) picture of the Volvo V60 at front 30°, elevation 5°, and its keypoints."""
    import cv2

    from carbody.camera import View, project
    from carbody.fit.visibility import visible_slots
    from carbody.wireframe import sample_curves

    folder = tmp_path_factory.mktemp("fit")
    cp = library.points(library.original("Volvo V60"))
    view = View(30, 5)
    both = np.concatenate([cp, cp * [-1, 1, 1]])
    p = project(both, view)
    s = 800 / np.ptp(p[:, 0])
    off = (500 - s * p[:, 0].mean(), 300 - s * p[:, 1].mean())
    img = np.full((600, 1000, 3), 235, np.uint8)
    for half in (cp, cp * [-1, 1, 1]):
        for c in sample_curves(half, 20):
            cv2.polylines(img, [np.round(project(c, view, s, off)).astype(np.int32)], False, (60, 60, 60), 2)
    cv2.imwrite(str(folder / "car.png"), img)
    rng = np.random.default_rng(0)
    kp = {sl.name: [float(x) for x in project(cp[sl.point_index] * sl.sign, view, s, off) + rng.normal(0, 1, 2)]
          for sl in visible_slots(view, cp)}
    (folder / "car.json").write_text(json.dumps({"image": "car.png", "keypoints": kp}))
    return folder


def test_fit_turns_to_a_car_off_a_camera_photo_s_centre(tmp_path, library):
    """A JPEG straight from a camera (EXIF: 17 mm equivalent, its own size) with the car 15° off
    its axis: the default principal point takes the axis through the photo's centre, and the
    camera turns to the car by the EXIF focal length."""
    from carbody.camera import View
    from tests.conftest import camera_jpeg, off_centre_photo

    focal = camera_jpeg(tmp_path / "car.jpg", (2000, 1000), 17)
    marks = off_centre_photo(library.points(library.original("Toyota Camry XV70")), View(30, 10), noise=1.0,
                             focal=focal)
    (tmp_path / "car.json").write_text(json.dumps({"image": "car.jpg", "keypoints": marks}))
    proc = run_cli("fit", str(tmp_path / "car.jpg"), "--keypoints", str(tmp_path / "car.json"), "--view", "30",
                   "--exclude-template", "Toyota Camry XV70", "-o", str(tmp_path / "car.step"),
                   "--report", str(tmp_path / "r.json"), check=True)
    assert "EXIF 17 mm" in proc.stdout and "from the photo's axis to the car" in proc.stdout
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["camera_turn_deg"] == pytest.approx(15.0, abs=1.5)
    assert rep["focal_length_px"] == pytest.approx(focal)
    assert rep["residual_px_mean"] < 3


def test_fit_writes_step_overlay_and_report(photo):
    out = photo / "out"
    out.mkdir()
    proc = run_cli("fit", str(photo / "car.png"), "--keypoints", str(photo / "car.json"), "--view", "30",
                   "--exclude-template", "Volvo V60", "--truth", "Volvo V60",
                   "-o", str(out / "car.step"), "--overlay", str(out / "ov.png"), "--report", str(out / "r.json"),
                   "--uncertainty", str(out / "u.png"), check=True)
    assert "fitted" in proc.stdout
    from carbody.view.predict import read_image
    from carbody.occ.step_curves import read_curves_step
    from carbody.wireframe import read_wireframe

    wf = read_wireframe(out / "car.step")
    _, curves = read_curves_step(out / "car.step")
    assert len(curves) > 70 and any(c.name.endswith("_right") for c in curves)  # both halves
    assert 2500 < wf.measure()["wheelbase_mm"] < 3200  # the mix's own wheelbase, mm
    assert read_image(out / "ov.png").shape == (600, 1000, 3)
    rep = json.loads((out / "r.json").read_text())
    assert abs(rep["refined_view"]["azimuth_deg"] - 30) < 10
    assert len(rep["keypoints_mm"]) >= 35 and rep["residual_px_mean"] < 3
    assert rep["top_weights"] and "Volvo V60" not in rep["template_mix"]
    assert len(rep["annotated_but_hidden"]) <= 2 and "nose_centre" in rep["visible_at_refined_view"]
    assert rep["suspect_keypoints"] == [] and "passes far from" not in proc.stdout
    assert rep["error_mm_mean"] < 80 and set(rep["error_mm"]) == {k for k in rep["keypoints_mm"] if not k.endswith("_right")}
    assert rep["error_mm_at_truth_wheelbase_mean"] < 80 and len(rep["error_mm_at_truth_wheelbase"]) == 35
    assert (out / "r.errors.png").is_file()
    expected = rep["expected_error_mm"]
    assert set(expected) == set(rep["keypoints_mm"]) and 0 < rep["expected_error_mm_mean"] < 200
    assert rep["expected_error_mm_mean"] == pytest.approx(np.mean([expected[n] for n in rep["error_mm"]]))
    assert set(rep["keypoint_sd_mm"]) == set(rep["keypoints_mm"])
    assert "expected 3D keypoint error" in proc.stdout
    assert read_image(out / "u.png").shape[0] > 500  # the four-view drawing with expected errors


def test_a_phone_photo_stored_on_its_side_is_read_upright(photo, tmp_path):
    """A phone stores a photo as its sensor read it and tags the turn in EXIF (orientation 6:
    turn 90° clockwise); the keypoints were marked on the upright picture, as labelme shows it.
    The fit reads it upright: same size, the same wheels found (the JPEG's pixels move them by
    less than one), the same fit to a tenth of a millimetre (a pixel is about 5 mm), overlay
    upright."""
    import cv2
    from PIL import Image

    from carbody.view.predict import read_image

    upright = cv2.imread(str(photo / "car.png"))[..., ::-1]
    stored = Image.fromarray(np.ascontiguousarray(np.rot90(upright, 1)))   # on its side
    exif = Image.Exif()
    exif[0x0112] = 6
    stored.save(tmp_path / "car.jpg", exif=exif, quality=95)
    assert np.abs(read_image(tmp_path / "car.jpg").astype(int) - upright).mean() < 3
    marks = json.loads((photo / "car.json").read_text())
    marks.update(image="car.jpg", image_size=[1000, 600])
    (tmp_path / "car.json").write_text(json.dumps(marks))
    runs = {}
    for name in ("car.jpg", "car.png"):
        folder = photo if name == "car.png" else tmp_path
        report = tmp_path / f"{name}.json"
        run_cli("fit", str(folder / name), "--keypoints", str(tmp_path / "car.json"), "--view", "30",
                "--exclude-template", "Volvo V60", "-o", str(tmp_path / f"{name}.step"),
                "--overlay", str(tmp_path / f"{name}.png"), "--report", str(report), check=True)
        runs[name] = json.loads(report.read_text())
    assert read_image(tmp_path / "car.jpg.png").shape == (600, 1000, 3)
    jpg, png = runs["car.jpg"]["keypoints_mm"], runs["car.png"]["keypoints_mm"]
    assert jpg.keys() == png.keys()
    assert np.allclose([jpg[k] for k in jpg], [png[k] for k in jpg], atol=0.1)
    hubs = [{w["wheel"]: w["found_px"] for w in runs[name]["wheels"]["wheels"]} for name in ("car.jpg", "car.png")]
    assert hubs[0].keys() == hubs[1].keys() and hubs[0]
    assert np.allclose([hubs[0][w] for w in hubs[0]], [hubs[1][w] for w in hubs[0]], atol=1.0)


def test_a_misplaced_mark_is_left_out_and_named(photo, tmp_path):
    """One mark clicked 60 px off: the command says it left it out, the report lists it, and the
    overlay crosses it out (magenta) where it was clicked."""
    from carbody.view.predict import read_image

    marks = json.loads((photo / "car.json").read_text())
    u, v = marks["keypoints"]["b_pillar_top"]
    marks["keypoints"]["b_pillar_top"] = [u, v + 60.0]
    (tmp_path / "car.json").write_text(json.dumps(marks))
    proc = run_cli("fit", str(photo / "car.png"), "--keypoints", str(tmp_path / "car.json"), "--view", "30",
                   "--exclude-template", "Volvo V60", "-o", str(tmp_path / "car.step"),
                   "--overlay", str(tmp_path / "ov.png"), "--report", str(tmp_path / "r.json"), check=True)
    assert "left out as misplaced: b_pillar_top" in proc.stdout
    report = json.loads((tmp_path / "r.json").read_text())
    assert list(report["rejected_keypoints"]) == ["b_pillar_top"] and "b_pillar_top" not in report["residual_px"]
    overlay = read_image(tmp_path / "ov.png")
    near = overlay[round(v + 60) - 6:round(v + 60) + 7, round(u) - 6:round(u) + 7].reshape(-1, 3).astype(int)
    assert np.any((near[:, 0] > 200) & (near[:, 1] < 80) & (near[:, 2] > 200))  # magenta (RGB)
    # told to keep every mark, it does
    run_cli("fit", str(photo / "car.png"), "--keypoints", str(tmp_path / "car.json"), "--view", "30",
            "--exclude-template", "Volvo V60", "-o", str(tmp_path / "kept.step"), "--keep-marks",
            "--report", str(tmp_path / "kept.json"), check=True)
    kept = json.loads((tmp_path / "kept.json").read_text())
    assert kept["rejected_keypoints"] == {} and "b_pillar_top" in kept["residual_px"]


def test_visible_keypoints_command():
    proc = run_cli("visible-keypoints", "--view", "90", check=True)
    assert "rear_arch_top" in proc.stdout and "_right" not in proc.stdout
    ortho = run_cli("visible-keypoints", "--view", "60", check=True).stdout
    close = run_cli("visible-keypoints", "--view", "60", "--distance", "4000", check=True).stdout
    assert "front_top_corner_right" in ortho and "front_top_corner_right" not in close
    assert "4000 mm away" in close
    inside = run_cli("visible-keypoints", "--view", "60", "--distance", "300")
    assert inside.returncode == 2 and "inside the car" in inside.stderr
    # a view as a person names it: rear 30 is 150°, front 30 right is 330°
    assert run_cli("visible-keypoints", "--view", "rear 30", check=True).stdout == \
        run_cli("visible-keypoints", "--view", "150", check=True).stdout
    assert "330°" in run_cli("visible-keypoints", "--view", "front 30 right", check=True).stdout
    for bad in ("abc", "400", "nan"):
        refused = run_cli("visible-keypoints", "--view", bad)
        assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1


def test_output_into_a_closed_pipe_ends_quietly():
    """``carbody visible-keypoints --view 30 | head -1``: the reader leaves early; no traceback."""
    import subprocess
    import sys

    from tests.conftest import REPO

    read, write = os.pipe()
    os.close(read)  # the reader is gone before the first line
    try:
        proc = subprocess.run([sys.executable, "-m", "carbody", "visible-keypoints", "--view", "30"],
                              stdout=write, stderr=subprocess.PIPE, text=True, cwd=REPO)
    finally:
        os.close(write)
    assert proc.returncode == 141 and proc.stderr == ""


def _bad(photo, tmp_path, keypoints=None, view="30", image=None, extra=(), text=None):
    kfile = photo / "car.json"
    if keypoints is not None or text is not None:
        kfile = tmp_path / "k.json"
        kfile.write_text(text if text is not None else json.dumps({"keypoints": keypoints}))
    out = tmp_path / "x.step"
    proc = run_cli("fit", str(image or photo / "car.png"), "--keypoints", str(kfile), "--view", view,
                   "-o", str(out), "--overlay", str(tmp_path / "x.png"), *extra)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not out.exists() and not (tmp_path / "x.png").exists()
    return proc.stderr


def test_bad_inputs_exit_2_with_one_line_and_no_output(photo, tmp_path):
    good = json.loads((photo / "car.json").read_text())["keypoints"]
    assert "unknown keypoint name" in _bad(photo, tmp_path, {**good, "wing_mirror": [10, 10]})
    assert "at least" in _bad(photo, tmp_path, dict(list(good.items())[:3]))
    assert "NaN" in _bad(photo, tmp_path, {**good, "nose_centre": [float("nan"), 3.0]})
    assert "outside" in _bad(photo, tmp_path, {**good, "nose_centre": [5000, 3.0]})
    assert "one line" in _bad(photo, tmp_path, {n: [100 + i, 50 + i] for i, n in enumerate(good)})
    assert "0–360" in _bad(photo, tmp_path, view="400")
    # marked on a copy of the photo at half size; a name given twice; a pair clicked on one spot
    half = {n: [u / 2, v / 2] for n, (u, v) in good.items()}
    assert "marked on a 400 x 200 image but the photo is" in _bad(
        photo, tmp_path, text=json.dumps({"image_size": [400, 200], "keypoints": half}))
    twice = json.dumps({"keypoints": good})[:-2] + ', "nose_centre": [1, 2]}}'
    assert "'nose_centre' is given twice" in _bad(photo, tmp_path, text=twice)
    u, v = good["a_pillar_base"]
    assert "marked on one spot" in _bad(photo, tmp_path, {**good, "a_pillar_base_right": [u + 1, v]})
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not an image")
    assert "not an image" in _bad(photo, tmp_path, image=junk)
    assert "neither a number" in _bad(photo, tmp_path, extra=("--distance", "far"))
    assert "positive" in _bad(photo, tmp_path, extra=("--distance", "-3"))
    assert "inside or at the car" in _bad(photo, tmp_path, extra=("--distance", "900"))
    drawing = tmp_path / "u.png"
    assert "no posterior" in _bad(photo, tmp_path, extra=("--method", "paper", "--uncertainty", str(drawing)))
    assert not drawing.exists()


def test_fit_with_a_camera_distance_reports_it(photo):
    out = photo / "dist"
    out.mkdir()
    proc = run_cli("fit", str(photo / "car.png"), "--keypoints", str(photo / "car.json"), "--view", "30",
                   "-o", str(out / "car.step"), "--report", str(out / "r.json"), check=True)
    rep = json.loads((out / "r.json").read_text())
    # The distance is found by default; the test photo is orthographic, so the camera is far away.
    assert rep["camera_distance_mm"] is None or rep["camera_distance_mm"] > 30_000
    assert rep["residual_px_mean"] < 3 and "camera" in proc.stdout
    # A told distance (no wheelbase given) comes back: this photo is orthographic, too little
    # perspective to size the car by, so the distance is read at the fitted car's own wheelbase
    # (its proportions').
    proc = run_cli("fit", str(photo / "car.png"), "--keypoints", str(photo / "car.json"), "--view", "30",
                   "--distance", "60000", "-o", str(out / "car.step"), "--report", str(out / "r.json"), check=True)
    assert json.loads((out / "r.json").read_text())["camera_distance_mm"] == pytest.approx(60_000, rel=0.01)
    assert re.search(r"camera (59[4-9]|60[0-6])\d\d mm away", proc.stdout) and "(from its proportions, ±" in proc.stdout


def test_a_close_photo_fitted_as_orthographic_says_so(tmp_path):
    """The shipped example was taken from 7 m: told ``--distance orthographic`` the fit does as
    asked, but the note and the report say a camera ~7 m away fits the marks far better."""
    from tests.conftest import REPO

    proc = run_cli("fit", str(REPO / "examples" / "car.png"), "--keypoints",
                   str(REPO / "examples" / "car_keypoints.json"), "--view", "30", "--distance", "orthographic",
                   "-o", str(tmp_path / "car.step"), "--report", str(tmp_path / "r.json"), check=True)
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["camera_distance_mm"] is None
    check = rep["orthographic_check"]
    assert check["closer_camera"] and check["camera_distance_mm"] == pytest.approx(7000, rel=0.15)
    assert "looks taken from close by" in proc.stdout and "--distance auto" in proc.stdout


def test_any_view_given_lands_on_the_photo_s_and_marks_no_view_fits_are_said_to_fit_poorly(tmp_path):
    """The shipped example (a front three-quarter photo, 30°) told the side view (90°), its other
    end from the other side (210°), 60°, or nothing: the search lands on 30° every time, with no
    note. The same marks with their names shuffled fit no view: the fit exits 2 saying no car
    fits them, writing only the report, whose evidence says how badly."""
    from carbody.policy import FIT_POLICY
    from tests.conftest import REPO

    out = tmp_path / "car.step"
    marks = json.loads((REPO / "examples" / "car_keypoints.json").read_text())
    names = sorted(n for n in marks["keypoints"] if not n.endswith("_right"))
    shuffled = [names[(i * 7 + 3) % len(names)] for i in range(len(names))]
    marks["keypoints"].update({a: marks["keypoints"][b] for a, b in zip(names, shuffled)})
    marks["image"] = str(REPO / "examples" / "car.png")
    (tmp_path / "shuffled.json").write_text(json.dumps(marks))
    for view, keypoints, poor in (("90", REPO / "examples" / "car_keypoints.json", False),
                                  ("210", REPO / "examples" / "car_keypoints.json", False),
                                  (None, REPO / "examples" / "car_keypoints.json", False),
                                  ("30", tmp_path / "shuffled.json", True)):
        told = ("--view", view) if view else ()
        proc = run_cli("fit", str(REPO / "examples" / "car.png"), "--keypoints", str(keypoints), *told,
                       "-o", str(out), "--report", str(tmp_path / "r.json"))
        assert proc.returncode == (2 if poor else 0) and out.exists() is not poor, proc.stderr
        rep = json.loads((tmp_path / "r.json").read_text())
        assert rep["fits_poorly"] is poor and ("contradict each other" in proc.stderr) is poor
        assert (rep["evidence_per_coordinate"] > FIT_POLICY.poor_fit_evidence) is poor
        assert poor or (abs(rep["refined_view"]["azimuth_deg"] - 30) < 2 and not rep["rejected_keypoints"])
    proc = run_cli("fit", str(REPO / "examples" / "car.png"), "--keypoints", str(REPO / "examples" / "car_keypoints.json"),
                   "--no-refine", "-o", str(out))
    assert proc.returncode == 2 and "--no-refine keeps the view given" in proc.stderr
