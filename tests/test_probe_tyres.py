"""The tyre probe's training data: each render's wheel mask is the wheels that render shows."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from tests.conftest import REPO


@pytest.fixture(scope="module")
def probe():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import probe_tyres

    return probe_tyres


def test_each_renders_wheel_mask_covers_its_dark_tyres_inside_the_cars_box(probe, tmp_path):
    import cv2

    assert probe.render(tmp_path, images_per_body=3, max_bodies=1) == 3
    for picture in sorted(tmp_path.glob("*.jpg")):
        image = cv2.imread(str(picture), cv2.IMREAD_GRAYSCALE).astype(float)
        mask = cv2.imread(str(picture).replace(".jpg", "_mask.png"), cv2.IMREAD_GRAYSCALE) > 127
        x0, y0, x1, y1 = (int(round(float(v))) for v in picture.with_suffix(".box").read_text().split())
        car = np.zeros_like(mask)
        car[y0:y1, x0:x1] = True
        assert mask.any() and not (mask & ~car).any()          # wheels, all on the car
        assert 0.005 < mask.sum() / car.sum() < 0.25           # a share of the car, not all of it
        # the mask sits on the wheels, mirrored shots too: tyres are darker than the car round them
        assert image[mask].mean() < image[car & ~mask].mean()


def test_the_crop_maps_the_cars_box_into_the_networks_square(probe):
    image = np.zeros((300, 500, 3), np.uint8)
    crop, M = probe.square_crop(image, (100, 50, 400, 200), margin=0.25)
    assert crop.shape == (probe.INPUT_PX, probe.INPUT_PX, 3)
    corners = np.array([[100, 50, 1], [400, 200, 1]], float) @ M.T
    assert corners[:, 0] == pytest.approx([16.0, 144.0])  # the longer side spans 1 / 1.25 of it
    assert corners.mean(axis=0) == pytest.approx([80.0, 80.0])
