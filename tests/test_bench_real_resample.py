"""The re-marking benchmark re-marks as it says (marks kept, at least six, moved by the noise
asked) and, where ``../shared/realphotos`` is present, runs a photo and a re-marking of it."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from tests.conftest import REPO

DATA = REPO.parent / "shared" / "realphotos"


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_real_resample

    return bench_real_resample


MARKS = {f"mark{i}": [100.0 + 10 * i, 200.0 - 5 * i] for i in range(12)}


def test_a_remarking_keeps_some_marks_moved_by_the_noise(bench):
    rng = np.random.default_rng(3)
    draws = [bench.remarked(MARKS, rng, 0.8, 2.0) for _ in range(40)]
    assert all(set(d) <= set(MARKS) for d in draws)
    assert all(len(d) >= bench.MIN_MARKS for d in draws)
    assert 0.7 < np.mean([len(d) for d in draws]) / len(MARKS) < 0.9
    moves = np.concatenate([[np.subtract(d[n], MARKS[n]) for n in d] for d in draws])
    assert np.std(moves) == pytest.approx(2.0, rel=0.15)


def test_a_mark_moved_off_the_photo_is_clicked_at_its_edge(bench):
    """A re-marking is a person's clicks: none lies off the image (one did, and the benchmark
    counted the input error as the fit's)."""
    edge = {n: [u, 0.5] for n, (u, v) in MARKS.items()}
    draws = [bench.remarked(edge, np.random.default_rng(i), 1.0, 20.0, (160, 240)) for i in range(10)]
    points = np.array([p for d in draws for p in d.values()])
    assert points.min() >= 0 and points[:, 0].max() <= 159 and points[:, 1].max() <= 239
    assert (points[:, 1] == 0).sum() > len(points) / 3  # about half were moved above the top


def test_a_run_of_some_photos_draws_what_the_full_run_drew_for_them(bench):
    from pathlib import Path

    photos = [bench.Photo(f"p{i}", Path(f"p{i}.jpg"), Path(f"p{i}.json"),
                          {"keypoints": {n: [u + i, v] for n, (u, v) in MARKS.items()}, "image_size": [640, 480]}, {})
              for i in range(4)]
    order = [p.name for p in photos]
    full = {(p.name, d): marks for p, d, marks, _ in bench.tasks(photos, 3, 0.7, 1.0, 5)}
    some = bench.tasks(photos[2:3], 3, 0.7, 1.0, 5, order)
    assert [d for _, d, _, _ in some] == [0, 1, 2, 3]
    assert all(marks == full[(p.name, d)] for p, d, marks, _ in some)
    assert any(marks != full[("p2", d)] for _, d, marks, _ in bench.tasks(photos[2:3], 3, 0.7, 1.0, 5) if d)


def test_the_photos_car_leaves_the_size_table_for_its_runs_only(bench):
    """--table-without-car: the rows with the photo's published length and wheelbase leave the
    table the fit sizes by, and come back after the run."""
    from pathlib import Path

    import carbody.fit.size as size

    car = {"length": 4795, "width": 1855, "height": 1835, "wheelbase": 2745}  # a Fortuner AN160's
    photo = bench.Photo("p", Path("p.jpg"), Path("p.json"),
                        {"keypoints": dict(MARKS), "image_size": [640, 480], "published_mm": car}, {})
    rows = bench.same_car_rows(photo)
    assert rows == ("Toyota Fortuner AN160",)
    assert [t[3] for t in bench.tasks([photo], 2, 0.8, 0.5, 0, table_without_car=True)] == [rows] * 3
    assert [t[3] for t in bench.tasks([photo], 2, 0.8, 0.5, 0)] == [()] * 3
    shipped = size.published_cars()
    row = bench.run_one((photo, 0, {}, rows))  # no marks: refused before any fit, the table put back
    assert row["outcome"] in ("refused", "error") and row["table_left_out"] == list(rows)
    assert size.published_cars() is shipped and "Toyota Fortuner AN160" in shipped.names


def test_too_few_kept_are_topped_up_to_six(bench):
    rng = np.random.default_rng(0)
    assert len(bench.remarked(MARKS, rng, 0.01, 0.0)) == bench.MIN_MARKS
    few = {n: MARKS[n] for n in list(MARKS)[:4]}
    assert bench.remarked(few, rng, 0.01, 0.0) == {n: tuple(v) for n, v in few.items()}


@pytest.mark.skipif(not (DATA / "parts.json").exists(), reason=f"no real-photo data at {DATA}")
def test_a_photo_and_a_remarking_of_it_come_out(bench, tmp_path, capsys):
    out = tmp_path / "resample.json"
    assert bench.main(["--photos", "te24", "--draws", "1", "--workers", "1", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert [r["draw"] for r in rows] == [0, 1]
    assert all(r["outcome"] in ("body", "refused", "error", "traceback") for r in rows)
    assert rows[0]["outcome"] == "body" and rows[0]["marks"] == 19
    assert "| own marks | 1 |" in capsys.readouterr().out


@pytest.mark.skipif(not (DATA / "parts.json").exists(), reason=f"no real-photo data at {DATA}")
def test_a_stray_click_the_car_bends_to_follow_is_left_out(bench):
    """The benchmark's second re-marking of cps_te30 (a front view, ten marks, front_top_corner
    without its twin): the car bent its depth to follow that lone click, 63 nats per coordinate,
    and the fit was refused as contradictory. Each mark tried out in turn finds it."""
    from carbody.pipeline import reconstruct

    photos = bench.load_photos(DATA)
    i = [p.name for p in photos].index("cps_te30")
    photo = photos[i]
    size, _ = bench.car_image_size(photo)
    rng = np.random.default_rng([0, i])
    marks = [bench.remarked(photo.meta["keypoints"], rng, 0.8, 0.005 * size) for _ in range(2)][1]
    assert "front_top_corner_right" in marks and "front_top_corner" not in marks
    fit = reconstruct(str(photo.image), marks).fit
    assert "front_top_corner_right" in fit.diagnostics.rejected
    assert fit.diagnostics.evidence_per_coordinate < 10.0  # the policy's poor_fit_evidence
    assert abs((fit.view.azimuth + 180) % 360 - 180) < 15
