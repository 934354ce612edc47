"""The annotation page without a browser: its marks and files, the live fit it draws, the keypoint
it asks for, its server's rules, and the command's bad input."""
from __future__ import annotations

import json
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import REPO, run_cli

EXAMPLE = REPO / "examples" / "car.png"
EXAMPLE_MARKS = REPO / "examples" / "car_keypoints.json"


@pytest.fixture(scope="module")
def example_marks():
    from carbody.fit import read_keypoints

    return read_keypoints(EXAMPLE_MARKS).points


def quiet_session(tmp_path, **kwargs):
    """A session with no background work (no classifier, worker or warm-up): fast and
    deterministic."""
    from carbody.annotate.session import AnnotationSession

    kwargs.setdefault("output", tmp_path / "marks.json")
    return AnnotationSession(EXAMPLE, classify=False, full_fits=False, warm_up=False, view=30, **kwargs)


# ---------------------------------------------------------------- marks and files

def test_marks_loaded_are_saved_with_their_numbers_unless_moved(tmp_path):
    """A file's marks come back byte for byte (integers stay integers), its other fields are
    kept, a moved mark is written where it was moved to, a hidden one is listed."""
    from carbody.annotate.marks import MarkSheet

    source = tmp_path / "in.json"
    source.write_text(json.dumps({"image": "car.png", "image_size": [1000, 640], "car": "a crossover",
                                  "keypoints": {"nose_centre": [283, 310], "cowl_centre": [517.9, 228.6],
                                                "front_top_corner": [493.2, 326.9]}}))
    sheet = MarkSheet.load(source, "car.png", (1000, 640))
    sheet.place("cowl_centre", (520.25, 230.0))
    sheet.hide("sill_front")
    sheet.save(tmp_path / "out.json")
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["keypoints"]["nose_centre"] == [283, 310] and isinstance(out["keypoints"]["nose_centre"][0], int)
    assert out["keypoints"]["front_top_corner"] == [493.2, 326.9]
    assert out["keypoints"]["cowl_centre"] == [520.25, 230.0]
    assert out["car"] == "a crossover" and out["hidden"] == ["sill_front"] and out["image_size"] == [1000, 640]


def test_an_untouched_file_saves_back_to_the_same_marks(tmp_path):
    from carbody.annotate.marks import MarkSheet

    sheet = MarkSheet.load(EXAMPLE_MARKS, "car.png", (1000, 640))
    sheet.save(tmp_path / "out.json")
    assert json.loads((tmp_path / "out.json").read_text())["keypoints"] == json.loads(EXAMPLE_MARKS.read_text())["keypoints"]


def test_coco_output_reads_back_as_the_same_marks(tmp_path, example_marks):
    from carbody.annotate.marks import MarkSheet
    from carbody.fit import read_keypoints

    sheet = MarkSheet("car.png", (1000, 640))
    for name in ("nose_centre", "front_top_corner_right", "rear_arch_top"):
        sheet.place(name, example_marks.get(name, (100.0, 100.0)))
    sheet.hide("sill_front")
    project, coco = sheet.save(tmp_path / "m.json", tmp_path / "m.coco.json")
    back = read_keypoints(coco)
    assert back.points == read_keypoints(project).points == sheet.marks
    assert back.image_size == (1000, 640)


def test_the_sheet_refuses_what_the_fit_cannot_read(tmp_path):
    from carbody.annotate.marks import MarkSheet, check_output
    from carbody.errors import KeypointError, OutputError

    sheet = MarkSheet("car.png", (1000, 640))
    with pytest.raises(KeypointError, match="did you mean 'nose_centre'"):
        sheet.place("nose_center", (10, 10))
    with pytest.raises(KeypointError, match="outside the 1000 x 640 image"):
        sheet.place("nose_centre", (1200, 10))
    with pytest.raises(OutputError, match=r"\.json"):
        check_output(tmp_path / "marks.txt")
    with pytest.raises(OutputError, match="does not exist"):
        check_output(tmp_path / "nowhere" / "marks.json")
    bad = tmp_path / "other.json"
    bad.write_text(json.dumps({"image_size": [800, 600], "keypoints": {"nose_centre": [1, 1]}}))
    with pytest.raises(KeypointError, match="800 x 600"):
        MarkSheet.load(bad, "car.png", (1000, 640))


# ---------------------------------------------------------------- the live fit

def test_from_the_fifth_mark_the_page_gets_a_wireframe_and_a_ghost_for_every_keypoint_shown(tmp_path, example_marks):
    """Four marks: no fit yet, and the page says how many more; the fifth: the car fitted, its
    wireframe in the photo, a ghost for every keypoint the view shows that is not marked, near
    where the example's own marks put them, and the next keypoint asked is an unmarked one."""
    session = quiet_session(tmp_path)
    asked = []
    for _ in range(4):
        name = session.state()["ask"][0]
        asked.append(name)
        state = session.place(name, example_marks[name])
    assert not state["fit"]["ok"] and "1 more mark" in state["fit"]["error"]
    name = state["ask"][0]
    state = session.place(name, example_marks[name])
    fit = state["fit"]
    assert fit["ok"] and abs(fit["view"]["azimuth_deg"] - 30) < 10
    assert len(fit["wireframe"]) == 125 and all(len(line) == 12 for line in fit["wireframe"])
    ghosts = fit["ghosts"]
    assert set(ghosts).isdisjoint(state["marks"]) and len(ghosts) >= 25
    off = [np.hypot(*np.subtract(g["uv"], example_marks[n])) for n, g in ghosts.items() if n in example_marks]
    assert np.median(off) < 25  # px, on a car 730 px long, from five marks
    assert state["ask"][0] in ghosts and state["ask"][0] not in state["marks"]
    assert all(m["residual_px"] is not None for m in fit["marks"].values())


def test_the_quick_fit_draws_the_car_where_the_full_fit_does(example_marks):
    """The per-click fit ranks fewer views and reads the marks' noise coarsely (it must answer
    within 300 ms); the full fit that replaces it a second later moves the keypoints little.
    Marks added in the file's order, each quick fit told the last one's view, as the page does."""
    from PIL import Image

    from carbody.annotate import live_fit
    from carbody.fit import ViewPrior

    names, size, last, off = list(example_marks), Image.open(EXAMPLE).size, None, []
    for count in (6, 10, 16, len(names)):
        marks = {n: example_marks[n] for n in names[:count]}
        prior = ViewPrior.told(last) if last is not None else None
        quick = live_fit.fit_marks(marks, size, prior, last, quick=True).fit
        full = live_fit.fit_marks(marks, size, None, quick=False).fit
        last = quick.view
        at_quick, at_full = live_fit.keypoint_positions(quick), live_fit.keypoint_positions(full)
        uv_quick = quick.project_points(np.array([at_quick[n] for n in at_full]))
        uv_full = full.project_points(np.array([at_full[n] for n in at_full]))
        off.append(float(np.median(np.linalg.norm(uv_quick - uv_full, axis=1))))
    assert max(off) < 6.0, off  # px, on a car 730 px long


def test_a_full_fit_given_the_photo_can_fit_its_outline_too(example_marks):
    """What the benchmark's oracle asks with --with-outline: the car's outline in the photo joins
    the marks (as reconstruct --outline), and without the switch it does not."""
    from carbody.annotate import live_fit
    from carbody.camera import View
    from carbody.view.predict import read_image

    rgb = read_image(EXAMPLE)
    size = (rgb.shape[1], rgb.shape[0])
    with_outline = live_fit.fit_marks(example_marks, size, View(30.0, 10.0), quick=False, photo=rgb, outline=True)
    assert with_outline.fit.outline.used and with_outline.fit.outline.points > 20
    assert with_outline.fit.outline.median_px_after <= with_outline.fit.outline.median_px_before
    assert live_fit.fit_marks(example_marks, size, View(30.0, 10.0), quick=False, photo=rgb).fit.outline is None


def test_the_first_marks_asked_spread_over_the_car(tmp_path, example_marks):
    """Before a fit the page asks the keypoints the guessed view shows in farthest-point order:
    the first five span most of the car's length and height in the photo."""
    session = quiet_session(tmp_path)
    first = session.state()["ask"][:5]
    uv = np.array([example_marks[n] for n in first])
    everything = np.array(list(example_marks.values()))
    assert np.ptp(uv[:, 0]) > 0.7 * np.ptp(everything[:, 0])
    assert np.ptp(uv[:, 1]) > 0.6 * np.ptp(everything[:, 1])


def test_enter_places_a_ghost_where_it_is_and_hidden_names_are_not_asked_again(tmp_path, example_marks):
    from carbody.errors import KeypointError

    session = quiet_session(tmp_path)
    for _ in range(5):
        name = session.state()["ask"][0]
        session.place(name, example_marks[name])
    state = session.state()
    ghost_name = state["ask"][0]
    where = state["fit"]["ghosts"][ghost_name]["uv"]
    state = session.accept(ghost_name)
    assert state["marks"][ghost_name] == pytest.approx(where)
    hidden = state["ask"][0]
    state = session.hide(hidden)
    assert hidden in state["hidden"] and hidden not in state["ask"] and hidden not in state["marks"]
    state = session.remove(ghost_name)
    assert ghost_name not in state["marks"]
    with pytest.raises(KeypointError, match="no predicted position"):
        session.accept("no_such_keypoint")


def test_after_the_fit_the_page_asks_only_for_ghosts_on_the_photo_least_sure_first(tmp_path, example_marks):
    """The example cut at the nose: the ghosts the car puts off the photo are drawn but never
    asked (nobody can click them); the rest are asked, the one the fit is least sure of first."""
    import cv2

    from carbody.annotate.session import AnnotationSession

    cut = 250  # px off the photo's left: the nose and the front wheel's front go
    photo = tmp_path / "cut.png"
    cv2.imwrite(str(photo), cv2.imread(str(EXAMPLE))[:, cut:])
    marks = {n: (u - cut, v) for n, (u, v) in example_marks.items() if u > cut + 5}
    session = AnnotationSession(photo, output=tmp_path / "m.json", classify=False, full_fits=False,
                                warm_up=False, view=30)
    for name in list(marks)[:12]:
        state = session.place(name, marks[name])
    ghosts = state["fit"]["ghosts"]
    off = {n for n, g in ghosts.items() if not g["in_photo"]}
    assert off and all(ghosts[n]["uv"][0] < 0 for n in off)
    assert off.isdisjoint(state["ask"]) and set(state["ask"]) == set(ghosts) - off
    sure = [ghosts[n]["sd_px"] for n in state["ask"]]
    assert sure == sorted(sure, reverse=True) and sure[0] > sure[-1]


def test_marking_a_keypoint_hidden_answers_without_a_refit(tmp_path, example_marks):
    """H changes nothing the fit reads: the page's answer is the fit it had (no quick fit run),
    still refined if it was, and the keypoint is asked no more; hiding a placed mark refits."""
    session = quiet_session(tmp_path)
    for _ in range(6):
        name = session.state()["ask"][0]
        session.place(name, example_marks[name])
    state = session.refine_now()
    assert state["refined"]
    asked = state["ask"][0]
    fit_before = session.payload
    after = session.hide(asked)
    assert session.payload is fit_before and after["refined"] and after["revision"] == state["revision"] + 1
    assert after["fit_revision"] == after["revision"] and asked not in after["ask"]
    placed = next(iter(after["marks"]))
    again = session.hide(placed)
    assert session.payload is not fit_before and placed not in again["marks"] and not again["refined"]


def test_before_the_fit_the_names_marked_turn_a_guess_made_from_the_wrong_end(tmp_path, example_marks):
    """The classifier reads the whole photo as the car's other end (210° for a car seen at 30°):
    the page's guess starts there, and three marks whose names that end cannot see bring it to
    the car's own side; the fits' prior stays the classifier's."""
    from carbody.annotate.session import AnnotationSession
    from carbody.camera import View
    from carbody.view.labels import CLASS_ANGLES_DEG, angular_difference

    session = AnnotationSession(EXAMPLE, classify=False, full_fits=False, warm_up=False, output=tmp_path / "m.json")
    p = np.full(24, 0.5 / 23)                # as sure as the calibrated classifier is when wrong
    p[list(CLASS_ANGLES_DEG).index(210.0)] = 0.5
    session.use_classifier(p)
    assert angular_difference(session.guess.azimuth, 210.0) < 8
    prior = session.prior
    for name in ("nose_centre", "front_top_corner", "front_arch_front"):
        session.place(name, example_marks[name])
    assert angular_difference(session.guess.azimuth, 30.0) <= 30 and session.prior is prior
    session.pick_view(90.0)                   # a view picked is kept as it is
    session.place("sill_front", example_marks["sill_front"])
    assert session.guess == View(90.0, session.guess.elevation) and session.view_source == "picked"


def test_before_the_fit_the_page_asks_what_the_guessed_view_shows_squarely(tmp_path):
    """The first keypoints asked face the camera squarely from the guessed view and from views
    20° either side of it (a guess may be that far off): none is seen edge on."""
    from carbody.annotate import guide
    from carbody.camera import View

    session = quiet_session(tmp_path)
    first = session.state()["ask"][:5]
    for delta in (-20.0, 0.0, 20.0):
        cos = guide.facing_cosines(View(30.0 + delta, 5.0))
        assert all(guide.markable(cos[n]) == 1.0 for n in first), (delta, first)


def test_a_mark_the_fit_leaves_out_is_said_next_to_it(tmp_path, example_marks):
    """All the example's marks with one clicked 80 px off: the page's payload says that mark is
    left out (and why), the others keep residuals of a pixel or two."""
    marks = dict(example_marks)
    marks["b_pillar_belt"] = (marks["b_pillar_belt"][0] + 80.0, marks["b_pillar_belt"][1] - 10.0)
    source = tmp_path / "in.json"
    source.write_text(json.dumps({"image": "car.png", "image_size": [1000, 640],
                                  "keypoints": {n: list(uv) for n, uv in marks.items()}}))
    session = quiet_session(tmp_path, keypoints=source)
    state = session.refine_now()
    info = state["fit"]["marks"]
    assert info["b_pillar_belt"]["status"] == "rejected" and "left out" in info["b_pillar_belt"]["note"]
    kept = [m["residual_px"] for n, m in info.items() if n != "b_pillar_belt"]
    assert np.median(kept) < 3


def test_a_file_with_five_marks_or_more_is_fitted_when_the_page_opens(tmp_path):
    session = quiet_session(tmp_path, keypoints=EXAMPLE_MARKS, output=None)
    state = session.state()
    assert state["fit"]["ok"] and len(state["marks"]) == 35 and state["ask"] == []
    assert state["loaded_unmoved"] == sorted(state["marks"])
    assert session.output == EXAMPLE_MARKS  # Save writes back to the file it read


# ---------------------------------------------------------------- the server

@pytest.fixture
def server(tmp_path):
    from carbody.annotate.server import AnnotationServer

    session = quiet_session(tmp_path)
    srv = AnnotationServer(session)
    srv.serve_in_thread()
    yield srv
    srv.shutdown()
    srv.server_close()


def request(url: str, body: dict | None = None, headers: dict | None = None):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json", **(headers or {})})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def test_the_server_listens_on_loopback_and_serves_only_its_own_files(server):
    assert server.server_address[0] == "127.0.0.1"
    status, page = request(server.url)
    assert status == 200 and server.token.encode() in page
    for name in ("annotate.js", "annotate.css"):
        assert request(server.url + "static/" + name)[0] == 200
    assert request(server.url + "static/../server.py")[0] == 404
    assert request(server.url + "result/overlay.png")[0] == 404
    status, photo = request(server.url + "photo")
    assert status == 200 and photo[:4] == b"\x89PNG"


def test_nothing_the_page_loads_comes_from_elsewhere():
    """No CDN: the page's files name no other host (every URL is the server's own path)."""
    import re

    from carbody.annotate.server import static_file, static_names

    assert set(static_names()) >= {"index.html", "annotate.js", "annotate.css"}
    for name in static_names():
        text = static_file(name).decode()
        assert not re.search(r"(https?:)?//[a-z0-9.-]+\.[a-z]{2,}", text, re.I), name
        assert "@import" not in text


def test_edits_need_the_pages_token_and_its_host(server, example_marks):
    url = server.url + "api/edit"
    body = {"op": "place", "name": "nose_centre", "uv": list(example_marks["nose_centre"])}
    assert request(url, body)[0] == 403
    assert request(url, body, {"X-Carbody-Token": "guess"})[0] == 403
    status, data = request(url, body, {"X-Carbody-Token": server.token})
    assert status == 200 and json.loads(data)["marks"]["nose_centre"] == list(example_marks["nose_centre"])
    status, data = request(url, {"op": "place", "name": "nose_center", "uv": [1, 1]}, {"X-Carbody-Token": server.token})
    assert status == 422 and "did you mean" in json.loads(data)["error"]
    rebound = urllib.request.Request(server.url + "api/state", headers={"Host": "evil.example:80"})
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(rebound, timeout=10)
    assert err.value.code == 403


def test_save_writes_the_projects_json_and_coco_on_request(server, tmp_path):
    from carbody.fit import read_keypoints

    token = {"X-Carbody-Token": server.token}
    request(server.url + "api/edit", {"op": "place", "name": "nose_centre", "uv": [283.5, 310.1]}, token)
    status, data = request(server.url + "api/save", {"coco": True}, token)
    saved = json.loads(data)["saved"]
    assert status == 200 and [Path(p).name for p in saved] == ["marks.json", "marks.coco.json"]
    assert read_keypoints(saved[0]).points == read_keypoints(saved[1]).points == {"nose_centre": (283.5, 310.1)}


# ---------------------------------------------------------------- the command

def test_the_command_refuses_bad_input_in_one_line(tmp_path):
    for args, message in ((["annotate", str(tmp_path / "none.png"), "--no-browser"], "no such image"),
                          (["annotate", str(EXAMPLE), "-o", str(tmp_path / "m.txt"), "--no-browser"], ".json"),
                          (["annotate", str(EXAMPLE), "-k", str(tmp_path / "none.json"), "--no-browser"], "no such keypoint file"),
                          (["annotate", str(EXAMPLE), "--port", "70000", "--no-browser"], "port")):
        proc = run_cli(*args)
        assert proc.returncode == 2, (args, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], proc.stderr


def test_reconstruct_runs_the_whole_job_into_a_folder_and_serves_its_pictures(tmp_path):
    """The page's Reconstruct: the example's marks loaded, the job run in the background into
    the folder asked, then its overlay and shaded body served to the page."""
    import time

    from carbody.annotate.server import AnnotationServer

    session = quiet_session(tmp_path, keypoints=EXAMPLE_MARKS, output=tmp_path / "marks.json")
    srv = AnnotationServer(session)
    srv.serve_in_thread()
    try:
        token = {"X-Carbody-Token": srv.token}
        status, data = request(srv.url + "api/reconstruct", {"folder": str(tmp_path / "out")}, token)
        assert status == 200 and json.loads(data)["reconstruction"]["state"] == "running"
        deadline = time.monotonic() + 240
        while session.reconstruction.state == "running" and time.monotonic() < deadline:
            time.sleep(0.5)
        rec = json.loads(request(srv.url + "api/state")[1])["reconstruction"]
        assert rec["state"] == "done", rec
        assert {"body.step", "wireframe.step", "overlay.png", "body.png", "report.json"} <= set(rec["files"])
        for name in ("overlay.png", "body.png"):
            status, png = request(srv.url + "result/" + name)
            assert status == 200 and png[:4] == b"\x89PNG"
    finally:
        srv.shutdown()
        srv.server_close()
