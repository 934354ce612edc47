"""What a view leaves unknown is the library's, not the fit's: the reference estimator of
``benchmarks/bench_fit_reference.py``, told the image's exact scale and offset, is still far off
on a level pure front view (no length in the picture) and close on a front three-quarter one."""
from __future__ import annotations

import sys

import pytest

from tests.conftest import REPO


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_fit_reference

    return bench_fit_reference


@pytest.mark.parametrize("template", [0, 5, 9])  # a sedan, an SUV, a coupe
def test_a_level_front_view_leaves_the_length_unknown_even_told_the_image_scale(bench, template):
    front, three_quarter = bench.run_template((template, (0, 30), 0.0, 1.0, True))
    best = {r["azimuth"]: min(r["reference_mm"].values()) for r in (front, three_quarter)}
    assert best[0] > 50.0 and best[0] > 4.0 * best[30]
    # raised 10°, the front view shows some length: the same estimator comes closer
    raised, = bench.run_template((template, (0,), 10.0, 1.0, True))
    assert min(raised["reference_mm"].values()) < best[0]


def test_the_reference_told_the_offset_does_better_than_without_it(bench):
    """A level near-side view: the image offset trades against the car's width, so the reference
    not told it does worse there (docs/fit_accuracy.md: 16 against 38 mm over the 14 cars at 75°)."""
    told, = bench.run_template((9, (75,), 0.0, 1.0, True))
    untold, = bench.run_template((9, (75,), 0.0, 1.0, False))
    assert min(told["reference_mm"].values()) < min(untold["reference_mm"].values())
