"""The library (paper II.E): normalised, expanded x6 -> x42 -> x252 per template (the paper's 14
templates: 84 -> 588 -> 3528), cached on disk. Counts come from the template manifest."""
from __future__ import annotations

import json

import numpy as np
import pytest

from carbody.library import Expansion, expand, load_library, normalise
from carbody.wireframe import wheel_centre
from carbody.occ.step_curves import write_curves_step
from tests.conftest import run_cli


def _base(templates, topology):
    return np.array([normalise(w.control_points, topology) for _, w in templates])


def test_normalised_wheel_centres_are_0_0_and_1000_0(templates, topology):
    for model in _base(templates, topology):
        assert wheel_centre(model, topology, "front") == pytest.approx([0, 0], abs=1e-9)
        assert wheel_centre(model, topology, "rear") == pytest.approx([1000, 0], abs=1e-9)


def test_normalising_undoes_a_pitch_and_offset(templates, topology):
    pts = templates[0][1].control_points
    a = np.radians(3.0)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    moved = pts.copy()
    moved[:, 1:] = pts[:, 1:] @ rot.T + [250.0, -40.0]
    assert normalise(moved, topology) == pytest.approx(normalise(pts, topology), abs=1e-9)


@pytest.mark.parametrize("expansion, per_template", [
    (Expansion(front_overhang=(), rear_overhang=(), width=()), 6),
    (Expansion(width=()), 42),
    (Expansion(), 252),
])
def test_each_expansion_step_counts_as_the_paper(templates, topology, expansion, per_template):
    points, index, factors = expand(_base(templates, topology), expansion, topology)
    assert expansion.models_per_template == per_template
    assert len(points) == len(index) == len(factors) == per_template * len(templates)


def test_curves_that_shared_an_end_still_share_it_after_every_scaling(templates, topology):
    points, _, factors = expand(_base(templates, topology), Expansion(), topology)
    for junction, idx in topology.junction_groups().items():
        spread = np.ptp(points[:, idx, :], axis=1).max()
        assert spread < 1e-9, junction
    # and every scaling did what it says: the wheel centres never move
    for side, target in (("front", [0, 0]), ("rear", [1000, 0])):
        a, b = (topology.junction_point_index(j) for j in topology.wheel_centres[side])
        centres = (points[:, a, 1:] + points[:, b, 1:]) / 2
        assert np.abs(centres - target).max() < 1e-9
    assert set(np.unique(factors[:, 0])) == {0.7, 0.8, 0.9, 1.0, 1.1, 1.2}


def test_overhang_scaling_stretches_only_the_overhang(templates, topology):
    base = _base(templates, topology)[:1]
    points, _, factors = expand(base, Expansion(height=(), rear_overhang=(), width=()), topology)
    longer = points[np.flatnonzero(factors[:, 1] == 1.1)[0]]
    nose = topology.junction_point_index("nose_centre")
    tail = topology.junction_point_index("tail_top_centre")
    boundary = longer[topology.junction_point_index("front_arch_front"), 1]
    assert longer[nose, 1] - boundary == pytest.approx(1.1 * (base[0, nose, 1] - boundary))
    assert longer[tail, 1] == pytest.approx(base[0, tail, 1])


def test_library_matrix_and_leave_one_out(library):
    from carbody.templates import load_manifest

    n = len(load_manifest())
    assert library.S.shape == (840, 252 * n)
    assert library.template_names == [row["name"] for row in load_manifest()]
    assert np.bincount(library.template_index).tolist() == [252] * n
    loo = library.without(library.template_names[4])
    assert loo.n_models == 252 * (n - 1) and library.template_names[4] not in loo.template_names
    assert np.bincount(loo.template_index).tolist() == [252] * (n - 1)


def test_the_cache_is_rebuilt_when_a_template_changes(template_copy, templates):
    first = load_library(template_copy)
    again = load_library(template_copy)
    assert np.array_equal(first.S, again.S)
    row, wf = templates[5]
    curves = wf.named_curves()
    i = [n for n, _ in curves].index("roof_centre_2")
    poles = curves[i][1].copy()
    poles[1, 2] += 60.0  # raise one inner control point of the roof
    curves[i] = (curves[i][0], poles)
    write_curves_step(template_copy / row["file"], curves, wf.name)
    edited = load_library(template_copy)
    changed = np.flatnonzero(np.abs(edited.S - first.S).max(axis=0) > 1e-6)
    assert set(edited.template_index[changed]) == {5}


def test_a_larger_library_needs_no_code_change(templates, topology):
    finer = Expansion(height=(0.75, 0.8, 0.85, 0.9, 0.95, 1.05, 1.1), width=(0.8, 0.9, 1.1, 1.2))
    base = _base(templates, topology)
    doubled = np.concatenate([base, base * [1.05, 1, 1]])
    points, index, _ = expand(doubled, finer, topology)
    assert len(points) == 2 * len(base) * 8 * 7 * 5 and index.max() == 2 * len(base) - 1


def test_cli_library_json():
    from carbody.templates import load_manifest

    n = len(load_manifest())
    data = json.loads(run_cli("library", "--json", check=True).stdout)
    assert data["templates"] == n and data["models"] == 252 * n and data["shape"] == [840, 252 * n]
