"""One command, one Python call: photo + keypoints -> wireframe, body, assembly, pictures, report."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from carbody.errors import CarbodyError
from tests.conftest import REPO, run_cli

EXAMPLES = REPO / "examples"
PHOTO, KEYPOINTS, TRUTH = EXAMPLES / "car.png", EXAMPLES / "car_keypoints.json", EXAMPLES / "car_truth.step"


@pytest.fixture(scope="module")
def result(example_reconstruction):
    return example_reconstruction


@pytest.fixture(scope="module")
def written(result, tmp_path_factory):
    from carbody.wireframe import read_wireframe

    out = tmp_path_factory.mktemp("recon") / "out"
    paths = result.write(out, truth=read_wireframe(TRUTH))
    return out, paths


def test_the_example_car_is_reconstructed_within_the_accuracy_target(result):
    from carbody.fit.report import keypoint_errors_mm
    from carbody.wireframe import read_wireframe

    truth = read_wireframe(TRUTH)
    # The shape, at the car's true wheelbase: the 25 mm mean target (the paper's 60 mm max
    # at front 30° is for cars in the library; this one is not, and the photo is from 7 m).
    shape = np.array(list(keypoint_errors_mm(result.wireframe, truth, at_truth_wheelbase=True).values()))
    assert shape.mean() < 25.0 and shape.max() < 90.0
    # The photo was taken 7 m from the car: the fit finds the distance.
    assert result.fit.camera_distance_mm == pytest.approx(7000.0, rel=0.15)
    # Its size comes from the mix's own wheelbase (leave-one-out: median 2–3 % off, BENCHMARKS.md).
    assert result.fit.wheelbase_mm == pytest.approx(truth.measure()["wheelbase_mm"], rel=0.05)
    assert abs(result.fit.view.azimuth - 30.0) < 5.0


def test_every_output_is_written_and_reads_back(written, topology):
    from carbody.occ.step_body import read_body_step
    from carbody.wireframe import read_wireframe

    out, paths = written
    assert {p.name for p in out.iterdir()} == {"wireframe.step", "body.step", "car.step", "overlay.png",
                                                "body.png", "report.json", "summary.txt"}
    wire = read_wireframe(out / "wireframe.step")
    assert wire.control_points.shape == (280, 3)
    body = read_body_step(out / "body.step")
    regions = {name.rsplit("_", 1)[0].removesuffix("_right") for name, _, _ in body.faces}
    assert regions == {r.name for r in topology.regions}
    report = json.loads((out / "report.json").read_text())
    assert report["surfaces"]["valid"] and report["surfaces"]["free_closed_loops"] == 1
    assert set(report["timings_s"]) >= {"view", "fit", "surfaces", "write"}
    assert report["fit"]["error_mm_at_truth_wheelbase_mean"] < 25.0
    summary = (out / "summary.txt").read_text()
    assert "residual" in summary and "3D keypoint error" in summary and "mm from the car's centre" in summary
    assert "expected 3D keypoint error" in summary and "(from its proportions, ±" in summary


def test_the_assembly_holds_both_named_parts(written, result):
    from OCP.STEPControl import STEPControl_Reader
    from OCP.StepBasic import StepBasic_Product
    from OCP.StepRepr import StepRepr_NextAssemblyUsageOccurrence
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    out, _ = written
    reader = STEPControl_Reader()
    reader.ReadFile(str(out / "car.step"))
    model = reader.StepModel()
    entities = [model.Value(i) for i in range(1, model.NbEntities() + 1)]
    products = {e.Name().ToCString() for e in entities if isinstance(e, StepBasic_Product)}
    assert products == {"car", "wireframe", "body"}
    assert sum(isinstance(e, StepRepr_NextAssemblyUsageOccurrence) for e in entities) == 2
    reader.TransferRoots()
    faces, explorer = 0, TopExp_Explorer(reader.OneShape(), TopAbs_FACE)
    while explorer.More():
        faces += 1
        explorer.Next()
    assert faces == len(result.body.faces)


def test_parts_lists_every_step_file_reconstruct_writes(written, result):
    """wireframe.step its 125 curves, body.step its faces, car.step both (named as in the two)."""
    proc = run_cli("parts", str(written[0] / "car.step"), "--json", check=True)
    assembly = json.loads(proc.stdout)
    from carbody.parts_cli import list_parts

    wire, body = list_parts(written[0] / "wireframe.step"), list_parts(written[0] / "body.step")
    assert len(wire["curves"]) == 125 and not wire["faces"]
    assert len(body["faces"]) == len(result.body.faces) and not body["curves"]
    assert [c["name"] for c in assembly["curves"]] == [c["name"] for c in wire["curves"]]
    assert sorted(f["name"] for f in assembly["faces"]) == sorted(f["name"] for f in body["faces"])
    assert assembly["product"] == result.name


def test_results_are_cadquery_and_build123d_shapes(result):
    import build123d as bd
    import cadquery as cq

    body, wire = result.body_cadquery(), result.wireframe_cadquery()
    assert isinstance(body, cq.Shell) and body.isValid() and body.Area() > 1e7
    assert isinstance(wire, cq.Compound) and len(wire.Edges()) == 125
    b3 = result.body_build123d()
    assert isinstance(b3, bd.Shell) and abs(b3.area - body.Area()) < 1e-6 * body.Area()
    assert isinstance(result.wireframe_build123d(), bd.Compound)


@pytest.mark.parametrize("script", ["cadquery_script.py", "build123d_script.py"])
def test_example_scripts_run(script, tmp_path):
    proc = subprocess.run([sys.executable, str(EXAMPLES / script), str(tmp_path)], capture_output=True,
                          text=True, cwd=REPO, env={**os.environ}, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "valid True" in proc.stdout
    written = {p.name for p in tmp_path.iterdir()}
    assert written >= ({"body_cut.step", "body_cut.stl"} if "cadquery" in script else {"panel.step"})


def test_cli_reconstruct_writes_the_folder_and_prints_the_summary(tmp_path):
    out = tmp_path / "car"
    proc = run_cli("reconstruct", str(PHOTO), "-k", str(KEYPOINTS), "--view", "30", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "residual" in proc.stdout and str(out.resolve()) in proc.stdout
    assert (out / "body.step").is_file() and (out / "car.step").is_file()


def _bad(tmp_path, *args):
    proc = run_cli("reconstruct", *args)
    lines = [line for line in proc.stderr.strip().splitlines() if "error" in line]
    return proc, lines


def test_a_camera_photo_with_the_car_off_centre_is_turned_to(tmp_path, library):
    """reconstruct reads the focal length from a camera JPEG's EXIF and turns the camera to a car
    15° off the photo's axis; the summary says so."""
    import carbody
    from carbody.camera import View
    from tests.conftest import camera_jpeg, off_centre_photo

    focal = camera_jpeg(tmp_path / "car.jpg", (2000, 1000), 17)
    marks = off_centre_photo(library.points(library.original("Volvo V60")), View(45, 10), noise=1.0, focal=focal)
    rec = carbody.reconstruct(tmp_path / "car.jpg", marks, view=45)
    report = rec.report()
    assert report["fit"]["camera_turn_deg"] == pytest.approx(15.0, abs=1.5)
    assert "deg from the photo's axis to the car" in rec.summary(report)


def test_bad_keypoint_file_is_one_line_and_writes_nothing(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"hello": 1}')
    out = tmp_path / "out"
    proc, lines = _bad(tmp_path, str(PHOTO), "-k", str(bad), "--view", "30", "-o", str(out))
    assert proc.returncode == 2 and len(lines) == 1 and "not a keypoint file" in lines[0]
    assert not out.exists()  # the folder made for the outputs is not left behind


def test_image_and_keypoints_of_different_sizes_are_refused(tmp_path):
    import cv2

    small = tmp_path / "small.png"
    cv2.imwrite(str(small), cv2.resize(cv2.imread(str(PHOTO)), (500, 320)))
    out = tmp_path / "out"
    proc, lines = _bad(tmp_path, str(small), "-k", str(KEYPOINTS), "--view", "30", "-o", str(out))
    assert proc.returncode == 2 and len(lines) == 1 and "1000 x 640" in lines[0] and "500 x 320" in lines[0]
    assert not out.exists()  # the folder made for the outputs is not left behind


def test_an_unwritable_output_folder_is_refused_before_any_work(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    proc, lines = _bad(tmp_path, str(PHOTO), "-k", str(KEYPOINTS), "--view", "30", "-o", str(blocker / "out"))
    assert proc.returncode == 2 and len(lines) == 1 and "cannot create the output folder" in lines[0] and "is a file" in lines[0]


def _other_side(marks: dict) -> dict:
    """The keypoints of the photo flipped left-right: the car's right side, named so."""
    from carbody.topology import load_topology

    off_plane = {k.name for k in load_topology().keypoints if not k.on_symmetry_plane}
    width = json.loads(KEYPOINTS.read_text())["image_size"][0]

    def swap(n):
        return n.removesuffix("_right") if n.endswith("_right") else n + "_right" if n in off_plane else n

    return {swap(n): [width - u, v] for n, (u, v) in marks.items()}


def test_the_keypoints_names_correct_the_classifier_s_side(tmp_path):
    """The classifier sees the example's left side (30°); keypoints of the right side (the photo's
    marks flipped and renamed) are fitted at its mirror, 330°, as well as the photo's own at
    30°: the classifier's view is a prior on the search, which the marks' names overrule. Told
    30° alike; and the example's own marks told the rear three-quarter or the side view land on
    30°."""
    import carbody
    from carbody.wireframe import read_wireframe

    marks = _other_side(json.loads(KEYPOINTS.read_text())["keypoints"])
    rec = carbody.reconstruct(PHOTO, marks)
    report = rec.report(truth=read_wireframe(TRUTH))
    assert report["view"]["source"] == "classifier" and report["view"]["classifier"]["class_deg"] == 30
    assert abs(report["view"]["azimuth_deg"] - 330) < 5
    assert report["fit"]["error_mm_at_truth_wheelbase_mean"] < 20
    assert abs(carbody.reconstruct(PHOTO, marks, view=30).fit.view.azimuth - 330) < 5
    for told in ("rear 30", "90"):
        (tmp_path / told).mkdir()
        run_cli("reconstruct", str(PHOTO), "-k", str(KEYPOINTS), "--view", told, "-o",
                       str(tmp_path / told / "out"), check=True)
        view = json.loads((tmp_path / told / "out" / "report.json").read_text())["view"]
        assert abs(view["azimuth_deg"] - 30) < 2 and view["source"] == "given", (told, view)


def _marks_seen_from(truth_mm: np.ndarray, azimuth: float, size=(1000, 640), noise: float = 1.0) -> dict:
    """The keypoints a camera 7 m from a car (mm) at 6° elevation marks on a picture of ``size``."""
    from carbody.camera import View, project
    from carbody.fit.solve import car_centre
    from carbody.fit.visibility import visible_slots

    view = View(azimuth, 6.0, 0.0, 7000.0, tuple(car_centre(truth_mm)))
    slots = visible_slots(view, truth_mm)
    pts = np.array([truth_mm[s.point_index] * s.sign for s in slots])
    both = np.concatenate([truth_mm, truth_mm * [-1, 1, 1]])
    p = project(both, view)
    scale = 0.8 * size[0] / np.ptp(p[:, 0])
    offset = np.array(size) / 2 - scale * (p.min(axis=0) + p.max(axis=0)) / 2
    uv = project(pts, view, scale, offset) + np.random.default_rng(0).normal(0.0, noise, (len(pts), 2))
    return {s.name: [float(u), float(v)] for s, (u, v) in zip(slots, uv)}


def test_a_right_rear_photo_the_classifier_took_for_the_left_front_lands_on_its_view():
    """The classifier says 30° (the example photo) and is sure of it; the keypoints are of the
    car's right rear three-quarter view (210°): the classifier's view is a prior, the search
    scores every view, and the fit lands on 210°."""
    import carbody
    from carbody.wireframe import read_wireframe

    truth = read_wireframe(TRUTH).control_points
    rec = carbody.reconstruct(PHOTO, _marks_seen_from(truth, 210.0))
    assert rec.view_prediction.class_deg == 30 and rec.view_prediction.confidence > 0.9
    assert rec.view_source == "classifier" and abs(rec.fit.view.azimuth - 210.0) < 5


def _paper_layout_only(monkeypatch):
    """Make ``build_body`` refuse, as it did before the layout by arc length, a wireframe with a
    region the paper's layout cannot surface, so the stiffer refits still have a case to take."""
    import carbody.surface
    from carbody.errors import SurfaceError

    build_body = carbody.surface.build_body

    def paper_only(wireframe, *args, **kwargs):
        body = build_body(wireframe, *args, **kwargs)
        notes = [r["layout_note"] for r in body.report["regions"].values() if r["layout"] != "skeleton"]
        if notes:
            raise SurfaceError(notes[0])
        return body

    monkeypatch.setattr(carbody.surface, "build_body", paper_only)


def test_a_stiffer_refit_takes_the_marks_the_fit_kept(first_library, monkeypatch):
    """The pickup left out, from behind, its right lower tail corner clicked 4 px from the left
    one's: the fit leaves that mark out, and when the body has to come from a stiffer fit, that
    fit takes the marks the fit kept (given every mark, the paper's plain mix bent onto it and
    passed 134 px from the marks on average, and the report said nothing). The surface stage now
    surfaces that fit itself; it is made to refuse it as the paper's layout alone did."""
    library = first_library
    import carbody

    name = "Ford F-150 SuperCrew 5.5 ft"
    t = library.template_names.index(name)
    truth = library.points(library.original(t)) * library.template_wheelbase_mm[t] / 1000.0
    marks = _marks_seen_from(truth, 165.0)
    u, v = marks["rear_bottom_corner"]
    marks["rear_bottom_corner_right"] = (u + 3.5, v + 1.0)
    picture = np.full((640, 1000, 3), 200, np.uint8)
    _paper_layout_only(monkeypatch)
    rec = carbody.reconstruct(picture, marks, view=165, elevation_deg=6.0, library=library.without(name))
    report = rec.report()
    assert report["fit_fallback"] is not None
    # the fit may also leave out a true mark the car it finds passes far from (the pickup's tail
    # top, 45 px): the stiffer fit takes neither
    rejected = set(report["fit"]["rejected_keypoints"])
    assert "rear_bottom_corner_right" in rejected and len(rejected) <= 2, rejected
    assert set(report["fit"]["residual_px"]) == set(marks) - rejected
    assert report["fit"]["residual_px_mean"] < 30, report["fit"]["residual_px_mean"]
    said = [line for line in rec.summary(report).splitlines() if "left out as misplaced:" in line]
    assert len(said) == 1 and "rear_bottom_corner_right" in said[0], said


def test_a_wireframe_whose_region_folds_is_surfaced_as_fitted(first_library):
    """The pickup left out of the library, seen from behind (165°): the default fit bends its cab
    until the window surround's outline crosses itself in its best-fit plane. That region is
    laid out by arc length, and the body comes from the fit itself: no stiffer refit."""
    library = first_library
    import carbody

    name = "Ford F-150 SuperCrew 5.5 ft"
    t = library.template_names.index(name)
    truth = library.points(library.original(t)) * library.template_wheelbase_mm[t] / 1000.0
    marks = _marks_seen_from(truth, 165.0)
    picture = np.full((640, 1000, 3), 200, np.uint8)
    rec = carbody.reconstruct(picture, marks, view=165, elevation_deg=6.0, library=library.without(name))
    report = rec.report()
    assert report["fit_fallback"] is None and report["surfaces"]["valid"]
    window = rec.body.report["regions"]["window_surround"]
    assert window["layout"] == "arc_length" and "crosses itself" in window["layout_note"]


def test_a_wireframe_that_cannot_be_surfaced_is_refitted_stiffer_and_said_so(first_library, monkeypatch):
    """The same pickup, with the surface stage made to refuse a region the paper's layout cannot
    surface (as it did before the layout by arc length): the body then comes from a stiffer fit
    (the library's span without the local field) blended back toward the fit as far as it
    surfaces, consistent with the wireframe written, and the report and summary say so; the
    example needs none."""
    library = first_library
    import carbody

    name = "Ford F-150 SuperCrew 5.5 ft"
    t = library.template_names.index(name)
    truth = library.points(library.original(t)) * library.template_wheelbase_mm[t] / 1000.0
    marks = _marks_seen_from(truth, 165.0)
    picture = np.full((640, 1000, 3), 200, np.uint8)
    _paper_layout_only(monkeypatch)
    rec = carbody.reconstruct(picture, marks, view=165, elevation_deg=6.0, library=library.without(name))
    report = rec.report()
    fallback = report["fit_fallback"]
    assert fallback["fit"].startswith("the library's span alone") and "crosses itself" in fallback["reason"]
    assert 0.0 <= fallback["share_of_fit"] < 1.0  # the fit blended back as far as it surfaces
    assert report["surfaces"]["valid"] and len(carbody.surface.build_body(rec.fit.wireframe).faces) == len(rec.body.faces)
    assert "blended with a stiffer fit" in rec.summary(report)
    assert carbody.reconstruct(PHOTO, KEYPOINTS, view=30).fallback is None


@pytest.mark.parametrize("command, refused", [
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/a.step", "--report", "/proc/r.json"),
     "cannot write in /proc"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/a.step", "--overlay", "{tmp}/o.txt"),
     "written here as .png / .jpg / .jpeg, not .txt"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}"), "is a folder"),
    (("surface", "{wire}", "-o", "{tmp}/b.step", "--png", "{tmp}/b.jpg"), "written here as .png, not .jpg"),
    (("surface", "{wire}", "-o", "{tmp}/b.step", "--report", "{tmp}/no/r.json"), "does not exist"),
    (("skeleton", "{wire}", "--region", "roof", "--png", "{tmp}/s"), "not a file without an ending"),
    (("templates", "show", "Volvo V60", "--png", "/proc/t.png"), "cannot write in /proc"),
    (("freecad", "{tmp}", "-o", "/proc/x.FCStd"), "cannot write in /proc"),
    (("train-view", "{tmp}", "-o", "/proc/w.pt"), "cannot write in /proc"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/a.txt"),
     "a STEP file is written here as .step / .stp, not .txt"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/a.step", "--overlay", "{tmp}/o.png",
      "--uncertainty", "{tmp}/o.png"), "given for both --overlay and --uncertainty"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/a.step", "--truth", "Volvo V60"),
     "--truth needs --report"),
    (("surface", "{wire}", "-o", "{tmp}/b.step", "--report", "{tmp}/r.yaml"), "a JSON report is written here"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/a.step", "--roll", "400"),
     "roll 400° is outside ±90°"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30"), "required: --output/-o (see carbody fit --help)"),
    (("reconstruct", "{photo}", "-k", "{keypoints}", "--exclude-template", "Model T", "-o", "{tmp}/r"), "Model T"),
])
def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path, command, refused):
    """Every command checks its output files (and its other options) first: one line, exit 2,
    nothing written."""
    wire = REPO / "templates_step" / "volvo_v60.step"
    args = [a.format(photo=PHOTO, keypoints=KEYPOINTS, tmp=tmp_path, wire=wire) for a in command]
    proc = run_cli(*args)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert refused in lines[0], lines[0]
    assert not any(tmp_path.iterdir())


def test_an_unreadable_photo_is_refused(tmp_path):
    junk = tmp_path / "car.png"
    junk.write_bytes(b"not an image at all")
    with pytest.raises(CarbodyError, match="not an image"):
        import carbody

        carbody.reconstruct(junk, KEYPOINTS, view=30)


def test_the_shipped_example_keypoints_name_their_photo_and_its_size():
    data = json.loads(KEYPOINTS.read_text())
    assert data["image"] == "car.png" and tuple(data["image_size"]) == (1000, 640)
    assert len(data["keypoints"]) >= 17
