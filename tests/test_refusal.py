"""A fit that explains the marks badly is not given out: exit 2 with one line naming the marks,
the overlay and report written so a person can see why, unless ``--force``."""
import json
import random

import pytest

from tests.conftest import REPO, run_cli

EXAMPLE = REPO / "examples"


@pytest.fixture(scope="module")
def shuffled(tmp_path_factory):
    """The example's marks with their places dealt out to the wrong names."""
    data = json.loads((EXAMPLE / "car_keypoints.json").read_text())
    names = list(data["keypoints"])
    places = [data["keypoints"][n] for n in names]
    random.Random(3).shuffle(places)
    data["keypoints"] = dict(zip(names, places))
    path = tmp_path_factory.mktemp("shuffled") / "marks.json"
    path.write_text(json.dumps(data))
    return path


def test_a_reconstruct_whose_fit_misses_the_marks_exits_2_and_writes_why(tmp_path, shuffled):
    out = tmp_path / "out"
    out.mkdir()
    (out / "body.step").write_text("an earlier run's body")
    proc = run_cli("reconstruct", str(EXAMPLE / "car.png"), "-k", str(shuffled), "--view", "30",
                   "-o", str(out), "--quiet")
    assert proc.returncode == 2, proc.stderr
    line, = proc.stderr.strip().splitlines()
    assert "contradict each other" in line or "misses the marks" in line
    assert "furthest:" in line and "--force" in line and "overlay.png" in line
    assert sorted(p.name for p in out.iterdir()) == ["overlay.png", "report.json", "summary.txt"]
    report = json.loads((out / "report.json").read_text())
    assert report["outcome"] == "failed" and report["error"] in line and report["surfaces"] is None
    assert report["fit"]["residual_px_mean"] > 50
    assert "no body:" in (out / "summary.txt").read_text()


def test_a_fit_that_misses_the_marks_gives_its_report_only_unless_forced(tmp_path, shuffled):
    args = ("fit", str(EXAMPLE / "car.png"), "-k", str(shuffled), "--view", "30", "--distance", "orthographic",
            "-o", str(tmp_path / "car.step"), "--report", str(tmp_path / "r.json"))
    proc = run_cli(*args)
    assert proc.returncode == 2 and "furthest:" in proc.stderr and not (tmp_path / "car.step").exists()
    assert json.loads((tmp_path / "r.json").read_text())["refused"] in proc.stderr
    forced = run_cli(*args, "--force")
    assert forced.returncode == 0, forced.stderr
    assert (tmp_path / "car.step").stat().st_size > 1000
    assert json.loads((tmp_path / "r.json").read_text())["refused"] is None


def test_the_examples_own_marks_are_not_refused():
    """The refusal's thresholds leave a photo's honest marks alone (the API: no FitRefused)."""
    from carbody.fit import fit_wireframe
    from carbody.fit.keypoints_io import read_keypoints
    from carbody.fit.report import refusal_line

    ann = read_keypoints(EXAMPLE / "car_keypoints.json")
    fit = fit_wireframe(ann.points, 30, image_size=(1000, 640))
    assert refusal_line(fit) is None
