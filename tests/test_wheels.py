"""The wheels in the photo (carbody.fit.wheels): hubs found where the photo shows them, fitted as
soft rows of the same solve as the marks.

A lifted crossover (arch clearance 160 mm; every template has 55 mm) is drawn with its wheels
on a plain floor and wall and marked as people mark photos: the glass, the nose, the arch tops,
not the sills nor the arch points level with the hubs. The marks then leave the hubs where the library's clearance puts them,
too high; the wheels found must bring them down to the drawn ones. A photo with no wheels
gives no rows and leaves the fit as the marks alone make it.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from carbody.camera import View, project
from carbody.fit import FitOptions, fit_wireframe
from carbody.fit.visibility import visible_slots
from carbody.fit.wheels import WHEELS, HubTargets, find_wheels, hub_points, ride_height_direction
from carbody.policy import FIT_POLICY
from carbody.topology import load_topology
from carbody.wireframe import MIRROR, sample_curves

#: The marks people place most (the 27 real photos' count, benchmarks/bench_real_photos.py): the
#: glass, the bonnet and nose, the arch tops; seldom the sills, the doors' bottoms, and the arch
#: points level with the hubs.
MARKED = ("a_pillar_base", "roof_front_corner", "front_top_corner", "nose_centre", "cowl_centre", "front_arch_top",
          "roof_front_centre", "rear_arch_top", "b_pillar_belt", "window_rear_bottom", "front_arch_front_end",
          "front_bumper_bottom_centre", "front_bottom_corner", "b_pillar_top", "window_rear_top",
          "window_front_top")

VIEW = View(55.0, 8.0)
SCALE, SIZE = 0.5, (1200, 760)  # px per normalised unit; the photo


@pytest.fixture(scope="module")
def lifted():
    """(truth (280, 3) normalised, its tyre radius, normalised): a crossover on the template
    builder whose arches clear the tyres by 160 mm."""
    from carbody.templates.design import DesignTable, build_wireframe

    design = DesignTable(name="lifted crossover", car_class="suv", length=4420.0, width=1830.0, height=1700.0,
                         wheelbase=2650.0, front_overhang=890.0, track_front=1585.0, track_rear=1590.0,
                         tyre_radius=330.0, ground_clearance=230.0,
                         details={"arch_clearance": 160.0, "roof_rear_y": 1.22, "deck_y": 1.29, "cowl_y": 0.29,
                                  "nose_h": 0.54})
    unit = 1000.0 / design.wheelbase
    return build_wireframe(design) * unit, design.tyre_radius * unit


def offset_for(points: np.ndarray, view: View = VIEW) -> np.ndarray:
    """(u0, v0) that puts the car's projection from ``view`` in the middle of the photo."""
    uv = project(np.concatenate([points, points * MIRROR]), view, SCALE)
    return np.array(SIZE) / 2 - (uv.min(axis=0) + uv.max(axis=0)) / 2


def drawn(points: np.ndarray, offset: np.ndarray, tyre: float | None, view: View = VIEW,
          steer_deg: float = 0.0, decoys: tuple = ()) -> np.ndarray:
    """(h, w, 3) uint8 RGB: the car's regions (both halves) in a dark blue paint on a light
    wall and a grey floor, seen from ``view``, and, given the tyre radius, its wheels on top: a
    black tyre, a silver rim (0.62 of the tyre) with five dark spokes' gaps and a dark hub cap,
    each a circle about its hub (:func:`~carbody.fit.wheels.hub_points`) in its side plane, the
    front wheels' turned ``steer_deg`` about the vertical (+: their fronts toward x > 0), and a
    wheel just like them about each of ``decoys`` ((3,) points, normalised units)."""
    import cv2

    w, h = SIZE
    image = np.full((h, w, 3), 215, np.uint8)
    image[h // 2 + 120:] = 150
    curves = sample_curves(points, 16)
    for side in (np.ones(3), MIRROR):
        for region in load_topology().regions:
            loop = np.concatenate([(curves[c][::-1] if rev else curves[c])[:-1] for c, rev in region.loop]) * side
            cv2.fillPoly(image, [np.round(project(loop, view, SCALE, offset) * 16).astype(np.int32)],
                         (40, 55, 110), cv2.LINE_AA, shift=4)
    if tyre is not None:
        angle = np.linspace(0, 2 * np.pi, 90, endpoint=False)
        up = np.array([0.0, 0.0, 1.0])

        def fill(points3d, colour):
            cv2.fillPoly(image, [np.round(project(points3d, view, SCALE, offset) * 16).astype(np.int32)], colour,
                         cv2.LINE_AA, shift=4)

        for name, hub in [*zip(WHEELS, hub_points(points)), *(("decoy", d) for d in decoys)]:
            if hub[0] <= 0:
                continue  # the far side's hide behind the body
            turn = np.radians(steer_deg if name.startswith("front") else 0.0)
            forward = np.array([np.sin(turn), np.cos(turn), 0.0])

            def arc(radius, t):
                return hub + radius * (np.cos(t)[:, None] * forward + np.sin(t)[:, None] * up)

            fill(arc(tyre, angle), (20, 20, 20))
            fill(arc(0.62 * tyre, angle), (190, 190, 195))
            for k in range(5):  # the gaps between the spokes: annular sectors
                a = (np.linspace(0.15, 0.85, 12) + k) * 2 * np.pi / 5
                fill(np.concatenate([arc(0.2 * tyre, a), arc(0.52 * tyre, a[::-1])]), (60, 60, 65))
            fill(arc(0.12 * tyre, angle), (70, 70, 75))
    rng = np.random.default_rng(3)
    return np.clip(image + rng.normal(0, 3, image.shape), 0, 255).astype(np.uint8)


def marks_of(points: np.ndarray, offset: np.ndarray) -> dict[str, tuple[float, float]]:
    """The visible keypoints people mark most (``MARKED``), projected, with a pixel of noise."""
    rng = np.random.default_rng(5)
    marks = {}
    for s in visible_slots(VIEW, points):
        if s.name.removesuffix("_right") in MARKED:
            u, v = project(points[s.point_index] * s.sign, VIEW, SCALE, offset) + rng.normal(0.0, 1.0, 2)
            marks[s.name] = (float(u), float(v))
    return marks


def true_hubs_px(points: np.ndarray, offset: np.ndarray) -> dict[str, np.ndarray]:
    return {w: project(p, VIEW, SCALE, offset) for w, p in zip(WHEELS, hub_points(points)) if p[0] > 0}


def test_a_drawn_car_s_hubs_are_found_within_two_pixels_from_where_a_fit_puts_them_off(lifted):
    points, tyre = lifted
    offset = offset_for(points)
    photo = drawn(points, offset, tyre)
    # the fit's camera a third of an arch radius off: where the library's clearance puts the hubs
    shifted = offset + np.array([0.1, -0.35]) * SCALE * (tyre + 60.0)
    found = find_wheels(photo, points.ravel(), VIEW, SCALE, shifted, FIT_POLICY)
    truth = true_hubs_px(points, offset)
    assert sorted(f.wheel for f in found) == sorted(truth)
    for f in found:
        assert np.linalg.norm(f.uv - truth[f.wheel]) < 2.0, (f.wheel, f.uv, truth[f.wheel])


def front_left_found_off_px(lifted, view: View, steer_deg: float = 0.0) -> float | None:
    """How far from its true hub the front left wheel's is found (px), the car drawn from ``view``
    with its front wheels turned ``steer_deg`` and the fit's camera a third of an arch radius
    off; None when it is not found."""
    points, tyre = lifted
    offset = offset_for(points, view)
    photo = drawn(points, offset, tyre, view, steer_deg)
    shifted = offset + np.array([0.1, -0.35]) * SCALE * (tyre + 60.0)
    found = {f.wheel: f for f in find_wheels(photo, points.ravel(), view, SCALE, shifted, FIT_POLICY)}
    if "front_left" not in found:
        return None
    return float(np.linalg.norm(found["front_left"].uv - project(hub_points(points)[0], view, SCALE, offset)))


@pytest.mark.parametrize("steer_deg", [25.0, 30.0])
def test_a_turned_front_wheel_seen_near_the_front_is_found_within_two_pixels(lifted, steer_deg):
    """Parked cars' front wheels are often turned; near a front view that stretches the wheel in
    the warped patch by half or more, beyond what the view's own error does."""
    off = front_left_found_off_px(lifted, View(20.0, 8.0), steer_deg)
    assert off is not None and off < 2.0, off


def test_a_front_wheel_seen_from_a_camera_close_by_is_still_looked_for(lifted):
    """A camera 1.6 wheelbases from the car's middle, 25° off its front (a phone held near the
    bonnet): the patch stretched most along the car reaches the camera. The stretches that do
    not are tried; before, the wheel was not looked for at all."""
    off = front_left_found_off_px(lifted, View(25.0, 8.0, 0.0, 1600.0, (0.0, 500.0, 250.0)))
    assert off is not None and off < 2.0, off


def test_a_wheel_alike_beside_a_hub_is_carried_as_its_rival_and_the_marks_pick_the_hub(lifted, library):
    """A second wheel drawn just like the front one over it, a tyre radius ahead and a third of one
    higher, hides part of it and scores higher: the search cannot tell which is the hub (it used
    to give none), so it carries both, and the fit weighs each by how well the car the marks
    make fits it: the true hub wins and the car sits on it."""
    points, tyre = lifted
    offset = offset_for(points)
    hub = hub_points(points)[0]
    ahead = hub + [0.0, -tyre, 0.3 * tyre]
    photo = drawn(points, offset, tyre, decoys=(ahead,))
    truth, decoy = project(hub, VIEW, SCALE, offset), project(ahead, VIEW, SCALE, offset)
    shifted = offset + np.array([0.1, -0.35]) * SCALE * (tyre + 60.0)
    front = {f.wheel: f for f in find_wheels(photo, points.ravel(), VIEW, SCALE, shifted, FIT_POLICY)}["front_left"]
    centres = [uv for uv, _ in front.candidates()]
    assert len(centres) == 2
    assert np.linalg.norm(centres[0] - decoy) < 2.0 and np.linalg.norm(centres[1] - truth) < 3.0
    fit = fit_wireframe(marks_of(points, offset), VIEW, library, image_size=SIZE, photo=photo,
                        options=FitOptions(refine=False, camera_distance_mm=None, wheels=True))
    row = {r["wheel"]: r for r in fit.wheels.wheels}["front_left"]
    assert np.linalg.norm(np.subtract(row["found_px"], truth)) < 3.0 and len(row["rivals"]) == 1
    fitted = fit.project_points(hub_points(fit.wireframe.control_points))[0]
    assert np.linalg.norm(fitted - truth) < 4.0 < np.linalg.norm(fitted - decoy)


def test_a_photo_without_wheels_adds_no_rows_and_leaves_the_fit_unchanged(lifted, library):
    points, _ = lifted
    offset = offset_for(points)
    marks = marks_of(points, offset)
    options = FitOptions(refine=False, camera_distance_mm=None, wheels=True)
    alone = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options)
    wheelless = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options,
                              photo=drawn(points, offset, None))
    assert alone.wheels is None
    assert not wheelless.wheels.used and wheelless.wheels.wheels == []
    assert np.array_equal(wheelless.wireframe.control_points, alone.wireframe.control_points)


def test_the_wheels_bring_the_hubs_of_a_lifted_car_down_to_the_photo_s(lifted, library):
    points, tyre = lifted
    offset = offset_for(points)
    marks, photo = marks_of(points, offset), drawn(points, offset, tyre)
    truth = true_hubs_px(points, offset)
    options = FitOptions(refine=False, camera_distance_mm=None)

    def hub_error(fit) -> float:
        hubs = fit.project_points(hub_points(fit.wireframe.control_points))
        return float(np.mean([np.linalg.norm(hubs[WHEELS.index(w)] - uv) for w, uv in truth.items()]))

    alone = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=options)
    wheeled = fit_wireframe(marks, VIEW, library, image_size=SIZE, options=replace(options, wheels=True), photo=photo)
    assert wheeled.wheels.used and len(wheeled.wheels.wheels) == 2
    assert hub_error(alone) > 8.0  # the library's clearance: the hubs sit too high (13 px)
    assert hub_error(wheeled) < 0.3 * hub_error(alone)  # (1.3 px)
    # the marks still fit as well as before: the body rose on its wheels rather than bending
    assert wheeled.solution.residual_px.mean() < 1.5 * alone.solution.residual_px.mean() + 0.5


def test_a_wheels_option_that_is_no_yes_or_no_is_refused_in_one_line():
    from carbody.errors import FitError

    with pytest.raises(FitError, match="wheels must be True or False"):
        FitOptions(wheels="yes")


def test_the_ride_height_moves_the_body_and_keeps_the_hubs():
    shape = np.random.default_rng(0).normal(size=840)
    lifted = shape + 7.0 * ride_height_direction()
    assert np.allclose(hub_points(lifted), hub_points(shape))
    topo = load_topology()
    top = topo.junction_point_index("front_arch_top")
    assert lifted.reshape(-1, 3)[top, 2] == pytest.approx(shape.reshape(-1, 3)[top, 2] + 7.0)


def test_hub_rows_are_a_keypoint_s_rows_for_a_hub():
    """The hub's rows in the solve read its projection like a keypoint's: a shape's hubs at
    their own projected pixels leave no residual."""
    from carbody.fit.solve import _outline_rows, camera_rows
    from carbody.fit.keypoints_io import keypoint_slots

    shape = np.random.default_rng(1).normal(scale=50.0, size=840)
    slots = [keypoint_slots()[n] for n in ("nose_centre", "roof_rear_corner", "sill_front", "rear_arch_top")]
    view = View(60.0, 10.0, 0.0, 4000.0, (0.0, 500.0, 300.0))
    idx = load_topology().keypoint_point_indices
    M, const = camera_rows(slots, view, shape.reshape(-1, 3)[idx])
    uv = project(np.array([shape.reshape(-1, 3)[s.point_index] * s.sign for s in slots]), view)
    from carbody.fit.wheels import WheelFound

    found = [WheelFound("front_left", np.zeros(2), 1.0, 0.0)]
    hubs = HubTargets.of(found, project(hub_points(shape)[[0]], view), np.ones(1))
    L, c, target = _outline_rows(hubs, M, const, uv, view, shape, idx)
    assert np.allclose(L @ shape + c, target, atol=1e-6)


def test_a_circle_is_supported_all_round_and_a_straight_edge_adds_nothing():
    """The score counts circles by the sectors they run through: a ring's edge all of them; a
    straight edge (a spoke, a sill) a few, where the circles cross or touch it, under the
    floor below which a circle adds nothing."""
    import cv2

    from carbody.fit.wheels import circle_support, patch_edges

    patch = np.full((120, 120), 200, np.float32)
    cv2.circle(patch, (60, 60), 30, 40.0, -1, cv2.LINE_AA)
    cv2.rectangle(patch, (0, 100), (119, 119), 90.0, -1)  # a straight edge below
    edges = patch_edges(patch, np.ones_like(patch, bool))
    radii = np.arange(10.0, 50.0)
    support = circle_support(edges, np.array([60.0, 60.0]), radii, 24, 0.9)[0]
    assert support[np.argmin(np.abs(radii - 30))] > 0.9
    assert support[np.abs(radii - 30) > 2].max() < FIT_POLICY.wheel_circle_floor  # (4 sectors of 24)


@pytest.mark.parametrize("angle_deg, stretch", [(0.0, 1.25), (90.0, 0.8), (30.0, None)])
def test_a_rims_ellipse_is_found_from_a_circle_guess_and_says_how_it_is_stretched(angle_deg, stretch):
    """A rim drawn 25 % wider along the car than up (or turned) is found from a circle of the
    mean radius, its centre and stretch (extent along x over up) read back."""
    import cv2

    from carbody.fit.wheels import patch_edges, rim_ellipse

    patch = np.full((140, 140), 200, np.float32)
    cv2.ellipse(patch, (72, 66), (35, 28), angle_deg, 0, 360, 40.0, -1, cv2.LINE_AA)
    ellipse = rim_ellipse(patch_edges(patch, np.ones_like(patch, bool)), np.array([70.0, 70.0]), 31.0, 24, rounds=6)
    assert ellipse is not None and ellipse.sectors_seen == 24
    assert ellipse.centre == pytest.approx([72.0, 66.0], abs=1.5)  # (Canny's edge pixels: a pixel or so)
    a, c, s = np.radians(angle_deg), 35.0, 28.0
    want = np.hypot(c * np.cos(a), s * np.sin(a)) / np.hypot(c * np.sin(a), s * np.cos(a))
    assert ellipse.stretch() == pytest.approx(want if stretch is None else stretch, rel=0.03)


def test_the_hubs_are_the_wireframe_s_wheel_centres_under_its_arch_tops(library):
    """The hubs the photo is searched round and the drawings above put their wheels at are the
    wheel centres the wireframe itself defines (:func:`carbody.wireframe.wheel_centre`, along the
    car and up), across the car under each arch top, on both sides."""
    from carbody.wireframe import wheel_centre

    topo = load_topology()
    for t in (0, 5, 9):
        points = library.points(library.original(t)) + [0.0, 37.0, 11.0]  # moved off the origin
        hubs = dict(zip(WHEELS, hub_points(points)))
        for side in ("front", "rear"):
            top = points[topo.junction_point_index(f"{side}_arch_top")]
            for name, sign in ((f"{side}_left", 1.0), (f"{side}_right", -1.0)):
                assert np.allclose(hubs[name][1:], wheel_centre(points, topo, side))
                assert np.isclose(hubs[name][0], sign * top[0])
