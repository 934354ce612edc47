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
