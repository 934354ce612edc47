"""The templates: real cars of different classes, sized to their published figures, as STEP.

Counts come from the manifest: adding a car to the design table needs no test change.
"""
from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest

from carbody.errors import TemplateError
from carbody.occ.step_curves import read_curves_step, write_curves_step
from carbody.templates import load_manifest, load_templates, measure_template
from carbody.wireframe import Wireframe, read_wireframe, write_wireframe
from tests.conftest import run_cli


#: Issue 24: a prior that knows real cars needs at least this many templates.
MIN_TEMPLATES = 30


def test_thirty_cars_or_more_of_the_required_classes(templates):
    assert len(templates) == len(load_manifest()) >= MIN_TEMPLATES
    classes = Counter(row["class"] for row, _ in templates)
    assert classes["sedan"] >= 3 and classes["hatchback"] >= 2 and classes["suv"] >= 4
    assert classes["wagon"] >= 1 and classes["pickup"] >= 4 and classes["mpv"] >= 1
    assert classes["coupe"] + classes["sports"] + classes["roadster"] >= 1
    assert classes["city"] >= 2 and classes["compact_mpv"] >= 2 and classes["crossover"] >= 2
    assert classes["van"] >= 2
    assert len({row["name"] for row, _ in templates}) == len(templates)


def test_step_files_carry_the_car_and_one_named_cubic_per_curve(templates, topology):
    from carbody.templates import templates_dir

    row, wf = templates[0]
    product, curves = read_curves_step(templates_dir() / row["file"])
    assert product == row["name"] == wf.name
    assert [c.name for c in curves] == [c.name for c in topology.curves]
    assert all(c.degree == 3 and c.spans == 1 and len(c.poles) == 4 and not c.rational for c in curves)
    text = (templates_dir() / row["file"]).read_text()
    assert "SI_UNIT(.MILLI.,.METRE.)" in text and "AUTOMOTIVE_DESIGN" in text


def test_round_trip_step_points_step_agrees_to_1e9_mm(templates, tmp_path):
    for row, wf in templates:
        path = write_wireframe(tmp_path / row["file"], wf)
        back = read_wireframe(path)
        assert back.name == wf.name
        assert np.abs(back.control_points - wf.control_points).max() <= 1e-9, row["name"]


@pytest.mark.parametrize("i", range(len(load_manifest())))
def test_measured_dimensions_match_the_manifest_within_1_percent(templates, i):
    row, wf = templates[i]
    measured = measure_template(row, wf)
    for key in ("length_mm", "width_mm", "height_mm", "wheelbase_mm"):
        assert measured[key] == pytest.approx(row[key], rel=0.01), (row["name"], key)


def test_bodies_have_the_shape_of_their_class(templates):
    """A pickup's roof ends over its wheelbase, ahead of its bed, a hatchback's far behind the
    rear axle; a cab-over van's windshield starts ahead of its front wheels; an SUV and a van
    stand taller than any sedan, a city car is the shortest; every body is symmetric and above
    the ground."""
    def rows(cls):
        return [(row, wf.keypoints()) for row, wf in templates if row["class"] == cls]

    for row, kp in rows("pickup"):
        assert kp["roof_rear_centre"][1] < kp["deck_centre"][1] < row["wheelbase_mm"], row["name"]
    for row, kp in rows("hatchback"):
        assert kp["roof_rear_centre"][1] > row["wheelbase_mm"] * 1.1, row["name"]
    for row, kp in rows("van"):
        assert kp["cowl_centre"][1] < 0, row["name"]
    tallest_sedan = max(row["height_mm"] for row, _ in rows("sedan"))
    for cls in ("suv", "van"):
        assert min(row["height_mm"] for row, _ in rows(cls)) > tallest_sedan + 150, cls
    assert max(row["length_mm"] for row, _ in rows("city")) < min(
        row["length_mm"] for row, _ in templates if row["class"] not in ("city", "roadster", "van"))
    for row, wf in templates:
        pts = wf.control_points
        assert pts[:, 0].min() >= 0  # the left half
        assert pts[:, 2].min() > -row["tyre_radius_mm"]  # above the ground


def test_show_json_and_png(tmp_path):
    proc = run_cli("templates", "show", "Volkswagen Golf Mk7", "--json", "--png", str(tmp_path / "golf.png"),
                   check=True)
    data = json.loads(proc.stdout)
    assert data["name"] == "Volkswagen Golf Mk7"
    assert np.array(data["control_points"]).shape == (280, 3)
    assert len(data["keypoints"]) == 35 and len(data["keypoints"]["front_arch_top"]) == 3
    import matplotlib.image as mpimg

    img = mpimg.imread(tmp_path / "golf.png")
    assert img.shape[0] > 500 and img.shape[1] > 1000
    ink = (img[..., :3].mean(axis=2) < 0.6).mean()
    assert 0.01 < ink < 0.5  # something is drawn, and not a black square


def test_list_json_contract():
    rows = json.loads(run_cli("templates", "list", "--json", check=True).stdout)
    assert [r["name"] for r in rows] == [r["name"] for r in load_manifest()]
    assert set(rows[0]) == {"name", "class", "length_mm", "width_mm", "height_mm", "wheelbase_mm", "file"}


def test_manifest_gives_sources_and_overhangs():
    for row in load_manifest():
        assert row["source"]
        assert row["front_overhang_mm"] + row["wheelbase_mm"] + row["rear_overhang_mm"] == pytest.approx(row["length_mm"])


def test_a_reversed_or_degree_raised_curve_is_read_as_the_same_cubic(templates, tmp_path):
    row, wf = templates[3]
    curves = wf.named_curves()
    name, poles = curves[10]
    # Degree elevation of a cubic to a quartic describes the same curve with 5 poles.
    q = np.vstack([poles[0], [(i * poles[i - 1] + (4 - i) * poles[i]) / 4 for i in range(1, 4)], poles[3]])
    curves[10] = (name, q)
    curves[11] = (curves[11][0], curves[11][1][::-1])
    path = write_curves_step(tmp_path / "edited.step", curves, wf.name)
    back = read_wireframe(path)
    assert np.abs(back.control_points - wf.control_points).max() < 1e-6


def _broken(wf, tmp_path, change):
    curves = wf.named_curves()
    change(curves)
    return write_curves_step(tmp_path / "broken.step", curves, wf.name)


@pytest.mark.parametrize("change, words", [
    (lambda c: c.pop(5), ["windshield_centre_2", "missing"]),
    (lambda c: c.append(("spoiler", c[0][1] + 5.0)), ["spoiler", "unknown"]),
    (lambda c: c.__setitem__(7, ("hood_edge_front", c[7][1])), ["hood_edge_front", "unknown"]),
    (lambda c: c.__setitem__(8, (c[8][0], np.vstack([c[8][1][:2], [[0, 1500, 900]] * 2, c[8][1][2:]]))),
     ["roof_centre_3", "not a cubic"]),
    (lambda c: c.append((c[3][0], c[3][1])), ["hood_centre_3", "twice"]),
    (lambda c: c.__setitem__(0, (c[0][0], c[0][1] + [0, 0, 40.0])), ["front_centre", "do not meet"]),
])
def test_a_mis_structured_template_is_refused_naming_file_and_curve(templates, tmp_path, change, words):
    _, wf = templates[0]
    path = _broken(wf, tmp_path, change)
    with pytest.raises(TemplateError) as err:
        read_wireframe(path)
    message = str(err.value)
    assert str(path) in message and "\n" not in message
    for word in words:
        assert word in message


def test_a_corrupt_file_is_refused(tmp_path):
    bad = tmp_path / "corrupt.step"
    bad.write_text("ISO-10303-21;\nHEADER;\nthis is not step\n")
    with pytest.raises(TemplateError, match="corrupt.step: not a readable STEP file"):
        read_wireframe(bad)
    bad.write_bytes(b"\x00\xff" * 500)
    with pytest.raises(TemplateError, match="not a readable STEP file"):
        read_wireframe(bad)


def test_one_bad_template_refuses_the_whole_set_and_the_cli_says_it_in_one_line(template_copy, templates):
    row, wf = templates[2]
    curves = wf.named_curves()[:-1]
    write_curves_step(template_copy / row["file"], curves, wf.name)
    with pytest.raises(TemplateError, match="rear_fender_bottom"):
        load_templates(template_copy)
    proc = run_cli("library", "--dir", str(template_copy))
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and row["file"] in lines[0] and "rear_fender_bottom" in lines[0]


def test_a_wireframe_needs_280_points():
    with pytest.raises(TemplateError, match="280 x 3"):
        Wireframe("x", np.zeros((10, 3)))


def test_the_four_view_drawing_labels_every_axis_in_the_car_frame(templates):
    """Seen from above and from behind, the car's left (x > 0) is drawn at the bottom and on the
    left: those axes run backwards, their labels still the car frame's mm (not negated)."""
    import matplotlib.pyplot as plt

    from carbody.templates.drawing import four_views_figure

    cp = templates[0][1].control_points
    fig = four_views_figure(cp)
    try:
        side, front, top, rear = fig.axes[:4]
        assert [a.get_title() for a in (side, front, top, rear)] == ["side (left)", "front", "top", "rear"]
        assert top.yaxis_inverted() and rear.xaxis_inverted() and not front.xaxis_inverted()
        # the left flank's widest point is plotted at its own x, on the top view's vertical axis
        widest = cp[:, 0].max()
        assert top.get_ylim()[0] >= widest and min(top.get_ylim()) <= -widest
        assert any(np.isclose(np.max(line.get_ydata()), widest) for line in top.lines)
    finally:
        plt.close(fig)
