"""The guided-page benchmark's rule for "the same fit" (benchmarks/bench_annotate.py)."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_annotate as ba  # noqa: E402


def reference(spread):
    """A Reference built from re-marking distances alone (no fits)."""
    ref = object.__new__(ba.Reference)
    ref.set_spread(spread)
    return ref


def test_a_fit_is_the_same_when_it_scores_as_the_median_remarking_does():
    ref = reference([(40, 4.0), (60, 3.0), (50, 5.0), (30, 4.5), (70, 3.5)])
    assert (ref.tau3, ref.tau2) == (50.0, 4.0)
    assert ref.bar == pytest.approx(1.95)         # scores 1.8, 1.95, 2.25, 1.725, 2.275
    assert ref.same(45, 3.8) and ref.same_earlier_rule(45, 3.8)
    assert ref.same(60, 3.0) and not ref.same_earlier_rule(60, 3.0)   # trades 3D for the photo
    assert not ref.same(55, 4.4)                  # both a tenth over the means
    assert not ref.same(float("nan"), float("nan"))   # no fit


def test_the_earlier_rule_fails_most_remarkings_whose_errors_trade_off():
    # re-markings whose 3D and photo distances trade off (one high when the other is low)
    d3 = np.array([30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80, 85], dtype=float)
    d2 = 8.0 - d3 / 20.0 + np.tile([0.0, 0.2], 6)
    ref = reference(np.column_stack([d3, d2]))
    by_score, by_rule, draws = ref.remarkings_passing()
    assert draws == 12
    assert 5 <= by_score <= 7                      # about half, by construction
    assert by_rule < by_score


@pytest.mark.parametrize("flags, at", [((0, 1, 1, 1), 2), ((1, 1, 0, 1), 4), ((1, 1, 1, 0), None), ((1, 1, 1, 1), 1)])
def test_same_from_is_the_first_action_that_stays_the_same_to_the_end(flags, at):
    rows = [{"action": i + 1, "same": bool(f)} for i, f in enumerate(flags)]
    assert ba.same_from(rows, "same") == at
