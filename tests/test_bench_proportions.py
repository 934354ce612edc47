"""The fit reads a car's proportions without bias from marks as sparse and noisy as a person's
(``benchmarks/bench_proportions.py``): a left-out car photographed from close by, 12 marks with
4 px of noise, no view and no wheelbase told."""
from __future__ import annotations

import sys

import numpy as np

from tests.conftest import REPO


def test_a_left_out_car_comes_out_neither_narrow_nor_wide_from_a_dozen_noisy_marks():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_proportions

    rows = bench_proportions.fit_rows(0, 4000.0, 12, 4.0)
    assert len(rows) == len(bench_proportions.VIEWS) and all(r["marks"] == 12 for r in rows)
    width = np.array([r["width_over_wheelbase_pct"] for r in rows])
    # one car's own proportions differ from its neighbours' in the library by a few % (the
    # benchmark's spread over 33 cars: 5.7 %); its bias is the median over all of them
    assert abs(np.median(width)) < 7.0 and np.all(np.abs(width) < 12.0)
    # the view found stays near the truth: no drift toward the front or the side
    assert all(abs(r["azimuth_toward_side_deg"]) < 8.0 for r in rows)
