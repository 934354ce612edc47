"""``bench_fit_accuracy.py --real-marks``: library cars marked where real photos were marked,
seen from close by at those photos' estimated views, are fitted at their own view (no lean
toward the car's end or side). Skipped where ``../shared/realphotos`` is absent."""
from __future__ import annotations

import sys

import pytest

from tests.conftest import REPO

DATA = REPO.parent / "shared" / "realphotos"


@pytest.mark.skipif(not (DATA / "keypoints").is_dir(), reason=f"no real-photo data at {DATA}")
def test_library_cars_marked_as_real_photos_are_fitted_without_a_lean():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_fit_accuracy as bench

    sets = {name: s for s in bench.real_mark_sets(DATA) for name in [s[0]]}
    assert "cps_te79" in sets and "cps_te30" not in sets  # a three-quarter view; a front view is not one
    rows = bench.run_real_marks((0, [sets["cps_te79"], sets["cps_te86"]]))
    assert [r["failed"] for r in rows] == [None, None]
    assert all(abs(r["lean"]) < 5.0 for r in rows), rows
    assert "median lean" in bench.real_marks_table(rows)


def test_the_far_half_is_the_one_turned_away_from_the_camera():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_fit_accuracy as bench

    assert bench.far_side("a_pillar_base_right", 50.0) and not bench.far_side("a_pillar_base", 50.0)
    assert bench.far_side("a_pillar_base", 305.0) and not bench.far_side("a_pillar_base_right", 305.0)
    assert not bench.far_side("nose_centre", 50.0) and not bench.far_side("nose_centre", 305.0)


@pytest.mark.skipif(not (DATA / "keypoints").is_dir(), reason=f"no real-photo data at {DATA}")
def test_a_real_photos_own_marks_are_fitted_three_ways_each_giving_a_lean():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_fit_accuracy as bench

    [row] = bench.run_real_marks_own((DATA, "cps_te79"))
    assert row["near_marks"] == row["marks"] - 2  # its two far-side windshield corners left out
    assert all(isinstance(row[k], float) and abs(row[k]) < 90 for k in ("lean", "lean_loose_prior", "lean_near_half"))
    assert "prior ×0.1" in bench.real_marks_own_table([row])
