"""The view classifier looks at the car, not the photo: ``--box``, ``-k`` and reconstruct's marks box."""
from __future__ import annotations

import json

import numpy as np
import pytest

from carbody.errors import ViewError
from carbody.view.predict import SHIPPED_WEIGHTS, crop_to_box, keypoint_box
from tests.conftest import REPO, run_cli

EXAMPLES = REPO / "examples"


def test_crop_frames_the_box_as_the_renders_frame_their_cars():
    img = np.zeros((100, 300, 3), np.uint8)
    img[20:60, 50:150] = 255                                   # the "car": 100 x 40 px
    crop = crop_to_box(img, (50, 20, 150, 60), fill=0.8)
    assert crop.shape == (125, 125, 3)                         # larger side / fill, square
    cols = np.flatnonzero(crop[:, :, 0].max(0) == 255)
    rows = np.flatnonzero(crop[:, :, 0].max(1) == 255)
    assert (cols[0], cols[-1] + 1) == (12, 112)                # centred, 80 % of the side
    assert (rows[0], rows[-1] + 1) == (42, 82)                 # and centred up-down, padded
    edge = crop_to_box(img, (0, 0, 60, 100), fill=0.5)         # outside the picture: its border repeats
    assert edge.shape == (200, 200, 3) and edge[0, 0, 0] == img[0, 0, 0]


def test_bad_boxes_are_refused_in_one_line():
    img = np.zeros((100, 100, 3), np.uint8)
    for box in [(10, 10, 5, 50), (0, 0, np.nan, 5), (200, 200, 300, 300), (1, 2, 3)]:
        with pytest.raises(ViewError):
            crop_to_box(img, box)


def test_keypoint_box_grows_the_marks_box():
    b = keypoint_box({"a": (100, 50), "b": (300, 150), "c": (float("nan"), 3)}, margin=0.1)
    assert b == pytest.approx((80, 30, 320, 170))
    assert keypoint_box({"a": (1, 1)}) is None and keypoint_box({"a": (5, 5), "b": (5.5, 5)}) is None


@pytest.mark.skipif(not SHIPPED_WEIGHTS.is_file(), reason="no shipped weights")
def _view_json(capsys, *args: str) -> dict:
    """``carbody view ... --json`` in this process (the subprocess start-up is tested elsewhere)."""
    from carbody.cli import main

    capsys.readouterr()
    assert main(["view", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_view_box_and_keypoints_crop_before_classifying(tmp_path, capsys):
    from carbody.fit.keypoints_io import read_keypoints
    from carbody.render import save_png
    from carbody.view.predict import predict_probabilities, read_image

    photo = read_image(EXAMPLES / "car.png")
    box = keypoint_box(read_keypoints(EXAMPLES / "car_keypoints.json").points)
    # The car small in a wide, busy frame: the box must bring back what the crop alone gives.
    h, w = photo.shape[:2]
    rng = np.random.default_rng(0)
    wide = rng.integers(0, 255, (3 * h, 3 * w, 3), dtype=np.uint8)
    wide[h:2 * h, w:2 * w] = photo
    save_png(wide, tmp_path / "wide.png")
    shifted = (box[0] + w, box[1] + h, box[2] + w, box[3] + h)
    want = predict_probabilities([crop_to_box(photo, box)])[0]
    from carbody.view.marks import combine_with_marks

    marks = read_keypoints(EXAMPLES / "car_keypoints.json").points
    out = _view_json(capsys, str(tmp_path / "wide.png"), "--box", *(f"{v:.3f}" for v in shifted))
    got = np.array(list(out["probabilities"].values()))
    assert out["box"] == pytest.approx(shifted, abs=0.1)
    assert np.abs(got - want).max() < 2e-3
    out = _view_json(capsys, str(EXAMPLES / "car.png"), "-k", str(EXAMPLES / "car_keypoints.json"))
    assert out["box"] == pytest.approx(box, abs=0.1)
    assert np.abs(np.array(list(out["probabilities"].values())) - combine_with_marks(want, marks)).max() < 2e-3
    bad = run_cli("view", str(EXAMPLES / "car.png"), "--box", "10", "10", "5", "5")
    assert bad.returncode == 2 and "box" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_reconstruct_gives_the_classifier_the_marks_box(monkeypatch):
    import carbody
    import carbody.view.predict as predict
    from carbody.fit.keypoints_io import read_keypoints

    seen = []
    real = predict.predict_view

    def spy(image, weights=None, mirror_average=True, box=None, marks=None):
        seen.append(box)
        assert marks is None        # the fit's own search over every view reads the marks' names
        return real(image, weights, mirror_average, box=box, marks=marks) if SHIPPED_WEIGHTS.is_file() else _flat()

    def _flat():
        return predict.ViewPrediction(2, 30.0, 30.0, 1 / 24, np.full(24, 1 / 24))

    monkeypatch.setattr(predict, "predict_view", spy)
    carbody.reconstruct(EXAMPLES / "car.png", EXAMPLES / "car_keypoints.json")
    assert seen == [pytest.approx(keypoint_box(read_keypoints(EXAMPLES / "car_keypoints.json").points))]


def test_temperature_fit_undoes_an_over_confident_network():
    from carbody.view.calibrate import expected_calibration_error, fit_temperature, mirrored_probabilities

    rng = np.random.default_rng(1)
    labels = rng.integers(0, 24, 4000)
    true_logits = rng.normal(0, 1.0, (4000, 24))
    true_logits[np.arange(4000), labels] += 2.0
    # sample the "true" class from the calibrated softmax, then make the network 3x over-confident
    p_true = mirrored_probabilities(true_logits, None, 1.0)
    drawn = np.array([rng.choice(24, p=p) for p in p_true])
    t = fit_temperature(3.0 * true_logits, drawn)
    assert t == pytest.approx(3.0, rel=0.1)
    over = mirrored_probabilities(3.0 * true_logits, None, 1.0)
    fixed = mirrored_probabilities(3.0 * true_logits, None, t)
    assert expected_calibration_error(fixed, drawn) < 0.03 < expected_calibration_error(over, drawn)


@pytest.mark.skipif(not SHIPPED_WEIGHTS.is_file(), reason="no shipped weights")
def test_weights_in_the_package_stay_within_10_mb_and_carry_a_fitted_temperature():
    from carbody.view.predict import load_classifier

    files = sorted(SHIPPED_WEIGHTS.parent.glob("*.pt"))
    assert sum(f.stat().st_size for f in files) <= 10_000_000
    for f in files:
        _, meta = load_classifier(str(f))
        assert 0.3 < meta["temperature"] < 3.0 and meta["calibration"]["ece_after"] <= meta["calibration"]["ece_before"]


def test_the_marks_names_tell_the_end_and_the_side():
    from carbody.view.labels import class_of
    from carbody.view.marks import combine_with_marks, mark_likelihood

    front_left = ["nose_centre", "cowl_centre", "a_pillar_base", "a_pillar_base_right", "front_arch_top",
                  "b_pillar_belt", "rear_arch_top"]
    like = mark_likelihood(front_left)
    assert like[class_of(30)] > 20 * like[class_of(150)]          # the nose is marked: not from behind
    assert like[class_of(30)] > 20 * like[class_of(330)]          # left arches marked: the left side
    rear_right = ["tail_top_centre", "rear_bumper_bottom_centre", "rear_arch_top_right", "deck_corner_right"]
    assert mark_likelihood(rear_right).argmax() in {class_of(a) for a in (180, 195, 210, 225, 240)}
    # a classifier torn between front-left and rear-right is settled by the names
    p = np.zeros(24)
    p[class_of(30)], p[class_of(210)] = 0.45, 0.55
    assert combine_with_marks(p, front_left).argmax() == class_of(30)
    assert np.array_equal(mark_likelihood(["no_such_mark"]), np.ones(24))


def test_the_shipped_visibility_table_is_what_the_geometry_gives():
    from carbody.view.marks import TABLE_FILE, compute_visibility_table, visibility_table

    assert TABLE_FILE.is_file()
    names, table = visibility_table()
    fresh_names, fresh = compute_visibility_table(classes=[2, 12])     # front 30°, rear
    assert names == fresh_names and np.abs(table[[2, 12]] - fresh).max() < 1e-3
