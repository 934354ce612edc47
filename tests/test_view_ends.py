"""The near end's look settles which way a three-quarter view's car faces (carbody.view.ends)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import torch

from carbody.errors import ViewError
from carbody.view.ends import (END_GREY, END_LOOK_KEY, combine_looks, end_look, is_three_quarter,
                               near_end_on_left, second_look_view, write_end_looks)
from carbody.view.labels import CLASS_ANGLES_DEG, class_of, continuous_estimate
from carbody.view.predict import SHIPPED_WEIGHTS, crop_to_box, predict_probabilities
from carbody.view.train import to_square_input
from tests.conftest import REPO, run_cli


def test_three_quarter_views_and_their_near_end():
    assert [is_three_quarter(v) for v in (0, 15, 25, 45, 75, 90, 135, 170, 200, 300, 350)] == \
        [False, False, True, True, False, False, True, False, True, True, False]
    # front-left (30°) and rear-right (210°) show the near end on the picture's left
    assert near_end_on_left(30) and near_end_on_left(210)
    assert not near_end_on_left(150) and not near_end_on_left(330)


def test_a_second_look_needs_a_box_and_a_three_quarter_first_look():
    def peaked(deg):
        p = np.full(len(CLASS_ANGLES_DEG), 1e-4)
        p[class_of(deg)] = 1.0
        return p / p.sum()

    box = (0, 0, 10, 10)
    assert abs(second_look_view(box, peaked(45)) - 45) < 1
    assert second_look_view(None, peaked(45)) is None
    assert second_look_view(box, peaked(0)) is None and second_look_view(box, peaked(90)) is None


def test_the_end_look_keeps_the_near_end_and_paints_the_rest_grey():
    img = np.full((100, 200, 3), 7, np.uint8)
    box = (40, 20, 160, 80)
    left = end_look(img, box, 30.0, keep=0.5)       # near end on the left: columns from 100 on are grey
    assert (left[:, :100] == 7).all() and (left[:, 100:] == END_GREY).all()
    right = end_look(img, box, 330.0, keep=0.25)    # on the right: all left of 160 − 30 is grey
    assert (right[:, :130] == END_GREY).all() and (right[:, 130:] == 7).all()
    assert (img == 7).all()                         # a copy


def test_combining_the_looks_lets_the_surer_say_which_way_the_car_faces():
    whole = np.full(24, 0.002)
    whole[class_of(210)], whole[class_of(225)], whole[class_of(30)] = 0.6, 0.05, 0.3   # a half turn in doubt
    whole /= whole.sum()
    end = np.full(24, 0.002)
    end[class_of(45)] = 0.95                          # the near end is sure: the car faces the camera
    end /= end.sum()
    p = combine_looks(whole, end)
    assert p.sum() == pytest.approx(1.0, abs=1e-6)
    assert CLASS_ANGLES_DEG[p.argmax()] == 30         # the end is surer: the car faces the camera
    assert p[class_of(30)] / p[class_of(45)] == pytest.approx(whole[class_of(30)] / whole[class_of(45)], rel=0.05)
    same = combine_looks(whole, np.roll(end, 12))     # both looks agree: the call stands, surer
    assert CLASS_ANGLES_DEG[same.argmax()] == 210 and same[class_of(210)] > whole[class_of(210)]
    unsure = np.full(24, 1 / 24)                      # an end that cannot tell changes nothing
    assert np.allclose(combine_looks(whole, unsure), whole, atol=1e-6)


def _render_set(folder, rows):
    import cv2

    (folder / "images").mkdir(parents=True)
    for i, r in enumerate(rows):
        r["file"] = f"images/{i}.png"
        cv2.imwrite(str(folder / r["file"]), np.full((128, 128, 3), 200, np.uint8))
    with open(folder / "manifest.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["file", "class_index", "theta_deg", "split", "box"])
        w.writeheader()
        w.writerows(rows)
    (folder / "dataset.json").write_text(json.dumps({"seed": 0}))


def test_end_looks_of_a_render_set_keep_its_framed_three_quarter_views(tmp_path):
    _render_set(tmp_path / "src", [
        {"class_index": 2, "theta_deg": 31.0, "split": "train", "box": "20 40 100 80"},   # kept
        {"class_index": 6, "theta_deg": 88.0, "split": "train", "box": "20 40 100 80"},   # side-on
        {"class_index": 3, "theta_deg": 44.0, "split": "val", "box": ""},                 # not framed
        {"class_index": 14, "theta_deg": 212.0, "split": "val", "box": "20 40 100 80"}])  # kept
    assert write_end_looks(tmp_path / "src", tmp_path / "ends") == 2
    rows = list(csv.DictReader(open(tmp_path / "ends" / "manifest.csv")))
    assert [r["theta_deg"] for r in rows] == ["31.0", "212.0"] and rows[1]["split"] == "val"
    import cv2

    look = cv2.imread(str(tmp_path / "ends" / rows[0]["file"]))
    assert (look[:, :52] == 200).all() and (look[:, 68:] == END_GREY).all()   # 40–60 % of the box kept
    assert json.loads((tmp_path / "ends" / "dataset.json").read_text())[END_LOOK_KEY]["images"] == 2
    with pytest.raises(ViewError, match="exists"):
        write_end_looks(tmp_path / "src", tmp_path / "ends")
    with pytest.raises(ViewError, match="not a render-dataset"):
        write_end_looks(tmp_path, tmp_path / "other")
    assert not (tmp_path / "other").exists()
    r = run_cli("end-looks", str(tmp_path / "src"), str(tmp_path / "ends2"))
    assert r.returncode == 0 and "2 end looks" in r.stdout


@pytest.mark.skipif(not SHIPPED_WEIGHTS.is_file(), reason="no shipped weights")
def test_a_three_quarter_view_with_a_box_gets_the_second_look(tmp_path):
    car = (REPO / "examples" / "car.png")
    import cv2

    image = cv2.cvtColor(cv2.imread(str(car)), cv2.COLOR_BGR2RGB)
    box = (40.0, 60.0, image.shape[1] - 40.0, image.shape[0] - 60.0)
    payload = torch.load(SHIPPED_WEIGHTS, map_location="cpu", weights_only=True)
    flagged, plain = tmp_path / "flagged.pt", tmp_path / "plain.pt"
    torch.save({k: v for k, v in payload.items() if k != END_LOOK_KEY}, plain)
    torch.save(payload | {END_LOOK_KEY: {"folders": ["test"]}}, flagged)
    one = predict_probabilities([image], plain, boxes=[box])[0]
    assert np.array_equal(one, predict_probabilities([image], flagged, boxes=[box], end_looks=False)[0])
    view = continuous_estimate(one)
    assert is_three_quarter(view)           # the example is a 30° view
    size = int(payload["input_size"])
    end = predict_probabilities([to_square_input(crop_to_box(end_look(image, box, view), box), size)], plain)[0]
    two = predict_probabilities([image], flagged, boxes=[box])[0]
    assert np.allclose(two, combine_looks(one, end), atol=1e-6)
    assert np.array_equal(predict_probabilities([image], flagged)[0], predict_probabilities([image], plain)[0])
