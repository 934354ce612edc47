"""Edit the wireframe, the body follows: an edited wireframe surfaces again with the moved curves
on the body; a region folded by the edit is one line naming it and its curves, never a valid-
looking shell that folds in silence."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import carbody
from carbody.errors import FoldError
from carbody.tolerances import FOLD_AREA_SHARE, SHELL_TOL_MM  # the templates: tests/test_surface.py
from carbody.wireframe import write_wireframe_json
from tests.conftest import REPO, run_cli


@pytest.fixture(scope="module")
def car(templates):
    return templates[0][1]


def curve_points(wf, names, n=9):
    """(2 k n, 3) points along the named curves of both halves, mm."""
    from carbody.topology import load_topology
    from carbody.wireframe import MIRROR, sample_curves

    topo = load_topology()
    pts = np.concatenate([sample_curves(wf.curve_points(topo.curve(c).index), n)[0] for c in names])
    return np.r_[pts, pts * MIRROR]


def test_moving_a_junction_keeps_its_curves_joined_and_the_car_symmetric(car, topology):
    moved = car.with_junction_moved("roof_front_corner", [0, 0, 50])
    groups = topology.junction_groups()
    p = moved.control_points
    assert np.allclose(p[groups["roof_front_corner"]], car.control_points[groups["roof_front_corner"]][0] + [0, 0, 50])
    assert np.count_nonzero(np.abs(p - car.control_points).max(axis=1)) == 2 * len(groups["roof_front_corner"])
    poles_only = car.with_junction_moved("roof_front_corner", [0, 0, 50], handles=False).control_points
    assert np.count_nonzero(np.abs(poles_only - car.control_points).max(axis=1)) == len(groups["roof_front_corner"])
    # a junction on the symmetry plane moves in its plane only; the right twin mirrors
    centre = car.with_junction_moved("roof_front_centre", [30, 0, 20]).control_points[groups["roof_front_centre"]]
    assert np.all(centre[:, 0] == 0)
    right = car.with_junction_moved("roof_front_corner_right", [-10, 0, 0]).control_points[groups["roof_front_corner"]]
    assert np.allclose(right[:, 0], car.control_points[groups["roof_front_corner"]][:, 0] + 10)


def test_the_roof_raised_the_body_follows_through_the_moved_curves(car, topology):
    """The roof-front junction up 50 mm: one valid sewn shell again, open only at the bottom,
    passing through every curve that moved (both halves) within 0.01 mm; nothing folds."""
    from carbody.occ.checks import points_to_faces_distance

    moved = car.with_junction_moved("roof_front_corner", [0, 0, 50])
    body = carbody.surface_wireframe(moved)
    shell = body.report["shell"]
    assert shell["valid"] and shell["free_closed_loops"] == 1 and body.report["folds"] == []
    touched = [c.name for c in topology.curves if "roof_front_corner" in (c.start, c.end)]
    assert len(touched) == 3
    dist = points_to_faces_distance([f for _, f in body.faces], curve_points(moved, touched))
    assert dist.max() <= SHELL_TOL_MM


def test_a_junction_dragged_far_folds_a_region_said_in_one_line(car):
    """The roof's front corner pulled 800 mm back over the roof: BRepCheck finds the shell valid,
    but the roof turns back over itself; surface_wireframe refuses it naming the roof and its
    curves, and gives it with allow_folds."""
    folded = car.with_junction_moved("roof_front_corner", [0, 800, 0])
    with pytest.raises(FoldError) as err:
        carbody.surface_wireframe(folded)
    message = str(err.value)
    assert "\n" not in message and message.startswith("region roof folds: ") and "roof_side_1" in message
    body = carbody.surface_wireframe(folded, allow_folds=True)
    assert body.report["shell"]["valid"]  # the kernel sees nothing wrong
    assert body.report["regions"]["roof"]["folded_area_share"] > FOLD_AREA_SHARE
    assert body.report["regions"]["roof"]["fold"] == body.report["folds"][0]


def test_a_folded_face_is_measured_as_folded():
    from carbody.surface.folds import face_folded_area

    u, v = np.meshgrid(np.linspace(0, 1, 4), np.linspace(0, 1, 4), indexing="ij")
    flat = np.stack([u * 300, v * 300, 0 * u], axis=-1)
    assert face_folded_area(flat)[0][0] == 0
    # the same sheet run out along y and creased back part of the way: the part coming back
    # (by area) faces the other way
    creased = flat.copy()
    creased[:, :, 1] = np.array([0.0, 450.0, 450.0, 100.0])[None, :]
    folded, whole = face_folded_area(creased)
    y = np.polynomial.polynomial.polyval(np.linspace(0, 1, 2001), [0, 1350, -1350, 100])  # y(v) of those poles
    back = -np.diff(y)[np.diff(y) < 0].sum() / np.abs(np.diff(y)).sum()
    assert folded[0] / whole[0] == pytest.approx(back, abs=0.02) and back > 0.2


def test_an_outline_crossing_itself_in_3d_folds(car, topology):
    """The door's belt curve bent down through the middle of its sill curve: the outline crosses
    itself in 3D, which no sheet bounded by it can do."""
    from carbody.errors import SurfaceError
    from carbody.surface.folds import outline_crossing
    from carbody.surface.regions import region_outlines

    belt, sill = topology.curve("belt_2").index, topology.curve("sill_top_2").index
    p0, p3 = car.curve_points(belt)[[0, 3]]
    middle = car.curve_points(sill).T @ np.array([1, 3, 3, 1]) / 8  # sill_top_2 at t = 1/2
    poles = np.array([p0, (8 * middle - p0 - p3) / 6, (8 * middle - p0 - p3) / 6, p3])
    crossed = car.with_curve_poles("belt_2", poles)
    door = next(o for o in region_outlines(crossed.control_points) if o.name == "door")
    (a, b), gap = outline_crossing(crossed.control_points, door)
    assert {a, b} == {"belt_2", "sill_top_2"} and gap < 1e-6
    assert outline_crossing(car.control_points, door) is None
    with pytest.raises(SurfaceError) as err:
        carbody.surface_wireframe(crossed)
    assert "region door" in str(err.value) and "\n" not in str(err.value)


def test_the_cli_says_which_regions_fold_and_refuses_on_request(car, tmp_path):
    path = write_wireframe_json(tmp_path / "folded.json", car.with_junction_moved("roof_front_corner", [0, 800, 0]))
    proc = run_cli("surface", str(path), "-o", str(tmp_path / "body.step"))
    assert proc.returncode == 0 and "warning: region roof folds" in proc.stderr
    proc = run_cli("surface", str(path), "-o", str(tmp_path / "refused.step"), "--refuse-folds")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "region roof folds" in lines[0]
    assert not (tmp_path / "refused.step").exists()


def test_edit_roofline_example_runs(tmp_path, templates):
    from carbody.templates import templates_dir
    from carbody.wireframe import read_wireframe

    row, wf = templates[0]
    proc = subprocess.run([sys.executable, str(REPO / "examples" / "edit_roofline.py"), str(tmp_path),
                           "--wireframe", str(templates_dir() / row["file"])], capture_output=True, text=True,
                          cwd=REPO, env={**os.environ}, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "valid True" in proc.stdout and "folds 0" in proc.stdout
    raised = read_wireframe(tmp_path / "wireframe_raised.step")
    dz = raised.control_points[:, 2] - wf.control_points[:, 2]
    assert dz.max() == pytest.approx(40.0) and dz.min() == pytest.approx(0.0)
    assert (tmp_path / "body_raised.step").is_file()
