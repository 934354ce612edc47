"""The length-move benchmark leaves a car out of the library and the size table, marks its views
as it says, and fits each with the move on and off; the table is put back after."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from tests.conftest import REPO


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_length_move

    return bench_length_move


def test_the_far_end_is_left_out_on_the_side_that_recedes(bench, library, topology):
    from carbody.fit.keypoints_io import keypoint_slots

    truth = library.points(library.original(0))
    slots = keypoint_slots()
    front, rear = (truth[topology.junction_point_index(f"{end}_arch_top"), 1] for end in ("front", "rear"))
    for azimuth, kept in ((30, lambda y: y <= rear + 0.25 * (rear - front)),
                          (150, lambda y: y >= front - 0.25 * (rear - front))):
        kps, _, _ = bench.synthetic_view(truth, azimuth, np.random.default_rng(0), 10.0)
        marks = bench.chosen_marks(kps, truth, azimuth, "far_end_out", np.random.default_rng(0))
        assert 0 < len(marks) < len(kps)
        assert set(marks) == {n for n in kps if kept(truth[slots[n].point_index, 1])}
    assert bench.chosen_marks(kps, truth, 150, "all", np.random.default_rng(0)) == kps


def test_a_template_left_out_is_fitted_both_ways_and_the_table_comes_back(bench):
    import carbody.fit.size as size

    shipped = size.published_cars()
    rows = bench.run_template(0)  # the Camry XV70, a row of the table
    assert len(rows) == len(bench.VIEWS) * len(bench.MODES) * 2
    assert all(r["table_left_out"] and not r["refused"] for r in rows)
    assert all(r["length_move_pct"] == 0.0 for r in rows if not r["move"])
    assert all(abs(r["ratio_err_pct"]) < 10 and r["mean_mm"] < 100 for r in rows)
    assert size.published_cars() is shipped and "Toyota Camry XV70" in shipped.names
    assert "| far_end_out | on |" in bench.summary_table(rows)
