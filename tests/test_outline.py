"""The car's outline in the photo (carbody.fit.outline): a term of the same fit as the marks.

A car drawn on a plain background, marked everywhere but on its roof: the marks leave the
roof's height to the library prior, and the outline must bring it toward the truth. A mask that
is garbage is refused by the quality check, and the fit then is the marks' alone.
"""
from __future__ import annotations

import numpy as np
import pytest

from carbody.camera import View, project
from carbody.fit import FitOptions, fit_wireframe
from carbody.fit.outline import CarOutline, check_segmentation, segment_car
from carbody.fit.visibility import visible_slots
from carbody.policy import FIT_POLICY
from carbody.topology import load_topology
from carbody.wireframe import MIRROR, sample_curves
from tests.conftest import REPO

#: The marks a person leaves out here: every one on the roof and the glass's upper edge.
ROOF = ("roof_front_centre", "roof_rear_centre", "roof_front_corner", "roof_rear_corner", "window_front_top",
        "window_rear_top", "b_pillar_top")

TRUTH = "Toyota Land Cruiser Prado J150"
VIEW = View(60.0, 10.0)
SCALE, SIZE = 0.45, (1400, 800)


def centred_offset(points: np.ndarray) -> np.ndarray:
    """(u0, v0) that puts the car's projection in the middle of the photo."""
    both = np.concatenate([points, points * MIRROR])
    uv = project(both, VIEW, SCALE)
    return np.array(SIZE) / 2 - (uv.min(axis=0) + uv.max(axis=0)) / 2


def drawn_car(points: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """(h, w, 3) uint8: the car's projected regions (both halves) filled dark red on a light
    grey floor and wall, with a little pixel noise."""
    import cv2

    w, h = SIZE
    rng = np.random.default_rng(1)
    image = np.full((h, w, 3), 200, np.uint8)
    image[h // 2 + 150:] = 150
    curves = sample_curves(points, 16)
    for side in (np.ones(3), MIRROR):
        for region in load_topology().regions:
            loop = np.concatenate([(curves[c][::-1] if rev else curves[c])[:-1] for c, rev in region.loop]) * side
            uv = project(loop, VIEW, SCALE, offset)
            cv2.fillPoly(image, [np.round(uv).astype(np.int32)], (120, 20, 25))
    return np.clip(image + rng.normal(0, 4, image.shape), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def roofless(library):
    """(truth (280, 3) normalised, its photo, the marks off its roof, the library without it)."""
    truth = library.points(library.original(TRUTH)).reshape(-1, 3)
    offset = centred_offset(truth)
    marks = {}
    for s in visible_slots(VIEW, truth):
        if s.name.removesuffix("_right") not in ROOF:
            u, v = project(truth[s.point_index] * s.sign, VIEW, SCALE, offset)
            marks[s.name] = (float(u), float(v))
    return truth, drawn_car(truth, offset), marks, library.without(TRUTH)


def roof_height_error(fit, truth: np.ndarray) -> float:
    """Mean height (z) error of the roof keypoints, normalised units (the outline of a view
    from the side pins their height; where they lie along the roof's edge it cannot tell)."""
    topo = load_topology()
    idx = [topo.keypoint_point_indices[i] for i, k in enumerate(topo.keypoints) if k.name in ROOF]
    fitted = fit.solution.shape.reshape(-1, 3)
    return float(np.mean(np.abs(fitted[idx, 2] - truth[idx, 2])))


def test_outline_brings_the_roof_height_the_marks_leave_out_toward_the_truth(roofless):
    truth, photo, marks, library = roofless
    options = FitOptions(refine=False, camera_distance_mm=None, deform=False, outline=True)
    alone = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options)
    outlined = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options, photo=photo)
    assert alone.outline is None
    assert outlined.outline.used and outlined.outline.points >= FIT_POLICY.outline_min_points
    assert outlined.outline.median_px_after < outlined.outline.median_px_before
    assert roof_height_error(outlined, truth) < 0.6 * roof_height_error(alone, truth)


def test_the_car_is_cut_out_of_a_plain_background_quickly(roofless):
    truth, photo, marks, _ = roofless
    outline = segment_car(photo, np.array(list(marks.values())), FIT_POLICY)
    assert outline.usable, outline.reason
    assert outline.seconds < 3.0  # ≈ 0.2 s on an idle core; a shared machine's wall time
    import cv2

    drawn = np.abs(photo.astype(int) - (120, 20, 25)).max(axis=2) < 20  # the car's own pixels
    drawn = cv2.resize(drawn.astype(np.uint8), outline.mask.shape[::-1], interpolation=cv2.INTER_AREA) > 0
    iou = (drawn & outline.mask).sum() / (drawn | outline.mask).sum()
    assert iou > 0.7  # (0.74: the roof past the marks' hull is partly lost, the floor between the wheels taken)


@pytest.mark.parametrize("garbage", ["everything", "nothing", "a speck"])
def test_a_garbage_mask_is_refused(garbage):
    mask = np.zeros((300, 400), bool)
    if garbage == "everything":
        mask[:] = True
    elif garbage == "a speck":
        mask[140:150, 190:200] = True
    usable, reason, _ = check_segmentation(mask, hull_area=200.0 * 120.0, policy=FIT_POLICY)
    assert not usable and reason


def test_a_refused_outline_leaves_the_fit_to_the_marks(roofless):
    truth, photo, marks, library = roofless
    options = FitOptions(refine=False, camera_distance_mm=None, deform=False, outline=True)
    mask = np.ones((400, 700), bool)  # the whole photo: background taken for the car
    usable, reason, ratio = check_segmentation(mask, 1e5, FIT_POLICY)
    assert not usable
    garbage = CarOutline(mask, mask.astype(float), 0.5, SIZE, usable, reason, ratio)
    alone = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options)
    refused = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options, photo=garbage)
    assert not refused.outline.used and refused.outline.reason == reason
    assert np.array_equal(refused.wireframe.control_points, alone.wireframe.control_points)


def test_a_car_at_or_behind_a_close_camera_is_told_apart_from_one_before_it(library):
    from carbody.fit.solve import reaches_camera

    car = library.points(library.original(TRUTH)).reshape(-1, 3)
    far, close = View(30.0, 5.0, distance=5000.0), View(30.0, 5.0, distance=300.0)
    assert not reaches_camera(car, far) and reaches_camera(car, close)
    assert not reaches_camera(car, View(30.0, 5.0))  # orthographic: no camera in the scene


REAL = REPO.parent / "shared" / "realphotos"


@pytest.mark.skipif(not (REAL / "images" / "cps_te85.jpg").exists(), reason=f"no real photos at {REAL}")
def test_an_outline_that_would_pull_the_car_through_a_close_camera_is_not_followed():
    """The cab-over truck seen from 3 m, marked on its front only: its outline's solve bent the
    car through the camera, and ``reconstruct --outline`` refused the photo ("camera inside the
    car"). The fit now keeps the marks' car and says why."""
    from carbody.pipeline import reconstruct

    done = reconstruct(REAL / "images" / "cps_te85.jpg", REAL / "keypoints" / "cps_te85.json", outline=True)
    assert done.fit.view.distance is not None
    assert not done.fit.outline.used and "through the camera" in done.fit.outline.reason
    assert done.body_cadquery().isValid()
