"""The off-screen renderer draws real OCCT shapes under the SPEC camera contract."""
from __future__ import annotations

import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from carbody.errors import RenderError  # noqa: E402
from carbody.camera import AngleError, View, parse_view, project, view_rotation  # noqa: E402
from carbody.render import (Look, Scene,  # noqa: E402
                            render_shape, render_views, save_png, tessellate)


def silhouette_box(img: np.ndarray, background=(255, 255, 255)) -> tuple[int, int]:
    """(width, height) in pixels of everything that differs from the background."""
    mask = np.any(np.abs(img.astype(int) - np.array(background)) > 30, axis=2)
    ys, xs = np.nonzero(mask)
    return xs.max() - xs.min() + 1, ys.max() - ys.min() + 1


def marker_scene():
    """A 300 x 400 x 200 box (x, y, z) with a green ball at its left-rear-top corner."""
    body = cq.Workplane().box(300, 400, 200).val()
    ball = cq.Workplane().sphere(12).translate((150, 100, 100)).val()
    meshes = tessellate([("body", body), ("marker", ball)])
    look = Look(paint=(0.5, 0.5, 0.5), colours={"marker": (0, 1, 0)}, ambient=1.0, diffuse=0.0, specular=0.0)
    return Scene(meshes, size=(240, 160)), look


def marker_pixels(img):
    m = (img[..., 1] > 150) & (img[..., 0] < 80)
    ys, xs = np.nonzero(m)
    return xs, ys


def test_camera_basis_follows_spec():
    d, r, w = view_rotation(View(90, 0))
    assert np.allclose(d, [1, 0, 0]) and np.allclose(r, [0, 1, 0]) and np.allclose(w, [0, 0, 1])
    d, r, w = view_rotation(View(0, 30))
    assert np.allclose(d, [0, -np.cos(np.radians(30)), 0.5])
    for t, p, q in [(37, 12, 0), (250, 28, 9)]:
        d, r, w = view_rotation(View(t, p, q))
        assert np.allclose(np.linalg.det(np.stack([r, w, d])), 1.0)   # right-handed: r x w = d
    # at the side view the nose (negative y) is on the left of the picture
    uv = project(np.array([[0, -1000, 0], [0, 0, 0]]), View(90))
    assert uv[0, 0] < uv[1, 0]


@pytest.mark.parametrize("text,theta", [("front 30°", 30), ("side", 90), ("rear 30°", 150),
                                        ("rear", 180), ("right side", 270), (" 45 ", 45), (400, 40)])
def test_parse_view(text, theta):
    assert parse_view(text) == pytest.approx(theta)


def test_parse_view_refuses_nonsense():
    with pytest.raises(AngleError, match="cannot read view"):
        parse_view("upside down")


def test_box_silhouette_aspect_matches_view():
    box = cq.Workplane().box(100, 200, 50)      # x width, y length, z height
    side = render_shape(box, 90, size=(200, 200))
    front = render_shape(box, 0, size=(200, 200))
    w, h = silhouette_box(side)
    assert w / h == pytest.approx(4.0, rel=0.06)
    w, h = silhouette_box(front)
    assert w / h == pytest.approx(2.0, rel=0.06)
    assert side.dtype == np.uint8 and side.shape == (200, 200, 3)


def test_left_side_seen_at_90_not_270():
    body = cq.Workplane().box(300, 400, 200).val()
    left = cq.Workplane().sphere(20).translate((150, 0, 0)).val()     # on the x > 0 face
    scene = Scene(tessellate([("body", body), ("marker", left)]), size=(120, 80))
    look = Look(paint=(0.5, 0.5, 0.5), colours={"marker": (0, 1, 0)}, ambient=1.0, diffuse=0.0, specular=0.0)
    assert len(marker_pixels(scene.render(90, 10, look=look))[0]) > 20
    assert len(marker_pixels(scene.render(270, 10, look=look))[0]) == 0


@pytest.mark.parametrize("kw", [dict(view_deg=60, elevation_deg=20),
                                dict(view_deg=60, elevation_deg=20, roll_deg=15, offset=(0.1, -0.05)),
                                dict(view_deg=120, elevation_deg=10, distance=1500, offset=(0.05, 0.1))])
def test_marker_lands_where_the_camera_contract_says(kw):
    scene, look = marker_scene()
    img = scene.render(look=look, **kw)
    xs, ys = marker_pixels(img)
    assert len(xs) > 20
    u, v = scene.project(np.array([150.0, 100.0, 100.0]))[0]
    assert abs(xs.mean() + 0.5 - u) < 1.5 and abs(ys.mean() + 0.5 - v) < 1.5


def test_orthographic_projection_is_the_spec_formula():
    """Scene.project (what was drawn) equals u0 + s(p.r), v0 - s(p.w) for some s, u0, v0."""
    scene, look = marker_scene()
    scene.render(33, 17, look=look)
    pts = np.random.default_rng(0).uniform(-200, 200, (20, 3))
    uv = scene.project(pts)
    ref = project(pts, View(33, 17))
    A = np.c_[ref[:, 0], np.ones(20)]
    s, u0 = np.linalg.lstsq(A, uv[:, 0], rcond=None)[0]
    assert np.allclose(A @ [s, u0], uv[:, 0], atol=1e-6)
    assert np.allclose(s * ref[:, 1] + (uv[:, 1] - s * ref[:, 1]).mean(), uv[:, 1], atol=1e-6)


def test_glass_faces_get_the_glass_colour():
    body = cq.Workplane().box(100, 100, 100).val()
    pane = cq.Workplane().box(1, 60, 60).translate((51, 0, 0)).val()
    img = render_shape([("door", body), ("side_window", pane)], 90, size=(100, 100),
                       paint=(1.0, 0.0, 0.0), glass=(0.0, 0.0, 1.0), specular=0.0)
    centre, corner = img[50, 50].astype(int), img[15, 15].astype(int)
    assert centre[2] > centre[0] and corner[0] > corner[2]


def test_textured_background_and_views_strip(tmp_path):
    rng = np.random.default_rng(1)
    texture = rng.integers(0, 255, (50, 70, 3), dtype=np.uint8)
    img = render_shape(cq.Workplane().box(10, 40, 10), 90, size=(64, 48), background=texture)
    assert img[0:3, 0:3].std() > 5          # corners show the texture, not a flat colour
    strip = render_views(cq.Workplane().box(10, 40, 10), tmp_path / "v.png", size=(80, 60))
    assert strip.shape == (60, 240, 3) and (tmp_path / "v.png").stat().st_size > 200


def test_bad_inputs_raise_render_error(tmp_path):
    box = cq.Workplane().box(10, 10, 10)
    with pytest.raises(RenderError):
        render_shape([], 90)
    with pytest.raises(RenderError, match="size"):
        render_shape(box, 90, size=(0, 10))
    with pytest.raises(RenderError, match="colour"):
        render_shape(box, 90, paint="purple")
    with pytest.raises(RenderError, match="inside"):
        render_shape(box, 90, distance=1.0)
    with pytest.raises(RenderError):
        save_png(np.zeros((4, 4)), tmp_path / "x.png")
    assert not list(tmp_path.iterdir())


def test_surfaced_body_renders_both_halves_with_glass(templates):
    """A real body from our surfacing: both halves are meshed, glass regions come out dark."""
    surface = pytest.importorskip("carbody.surface")
    _, wf = templates[0]
    body = surface.build_body(wf, check=False)
    meshes = tessellate(body)
    xs = np.concatenate([m.vertices[:, 0] for m in meshes])
    assert xs.min() < -0.9 * wf.control_points[:, 0].max() and xs.max() > 0.9 * wf.control_points[:, 0].max()
    assert {"side_window", "windshield", "door", "hood"} <= {m.name for m in meshes}
    img = render_shape(body, "side", size=(240, 160), paint=(0.9, 0.9, 0.9), glass=(0.0, 0.0, 0.0),
                       background=(0.0, 0.6, 0.0), specular=0.0)
    dark = (img.max(axis=2) < 60).sum()          # glass (background is green)
    bright = (img.min(axis=2) > 150).sum()
    assert dark > 100 and bright > 1000
