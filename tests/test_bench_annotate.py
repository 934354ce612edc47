"""The guided-page benchmark's rule for "the same fit" (benchmarks/bench_annotate.py)."""
import json
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


def test_the_ghost_user_drags_the_ghost_furthest_off_and_stops_when_none_is_off():
    hand = {"a": (0.0, 0.0), "b": (100.0, 0.0), "c": (0.0, 100.0)}
    ghost = lambda u, v: {"uv": [u, v], "sd_px": 3.0}  # noqa: E731
    state = {"ask": ["a", "d", "b"], "marks": {"c": [0.0, 100.0]},
             "fit": {"ok": True, "ghosts": {"a": ghost(2.0, 0.0), "b": ghost(100.0, 9.0), "d": ghost(50.0, 50.0)}}}
    assert ba.next_action(state, hand, 5.0, "ghosts") == ("drag", "b", {"op": "place", "name": "b", "uv": [100.0, 0.0]})
    # the page's own order: the asked keypoint's ghost is within a click, so it is accepted
    assert ba.next_action(state, hand, 5.0, "asked")[:2] == ("accept", "a")
    # every ghost within a click: the ghosts user stops; the asked user accepts, and hides a
    # keypoint the hand marks lack
    state["fit"]["ghosts"]["b"] = ghost(100.0, 4.0)
    assert ba.next_action(state, hand, 5.0, "ghosts") == ("stop", None, None)
    assert ba.next_action(state, hand, 5.0, "asked")[:2] == ("accept", "a")
    state["ask"] = ["d", "b"]
    assert ba.next_action(state, hand, 5.0, "asked")[:2] == ("hide", "d")
    # before the first fit there are no ghosts: the asked keypoint is clicked
    state["fit"] = {"ok": False, "ghosts": {}}
    state["ask"] = ["b"]
    assert ba.next_action(state, hand, 5.0, "ghosts") == ("click", "b", {"op": "place", "name": "b", "uv": [100.0, 0.0]})


def test_the_ghosts_any_user_drags_one_of_the_ghosts_off_by_more_than_a_click():
    hand = {"a": (0.0, 0.0), "b": (100.0, 0.0), "c": (0.0, 100.0)}
    state = {"ask": ["a"], "marks": {},
             "fit": {"ok": True, "ghosts": {"a": {"uv": [2.0, 0.0]}, "b": {"uv": [100.0, 9.0]}, "c": {"uv": [0.0, 130.0]}}}}
    rng = np.random.default_rng(0)
    picks = {ba.next_action(state, hand, 5.0, "ghosts-any", rng)[1] for _ in range(40)}
    assert picks == {"b", "c"}                    # never "a": its ghost is within a click
    # noticing only the badly off: "c" (30 px) is, "b" (9 px) is not half as far off
    picks = {ba.next_action(state, hand, 5.0, "ghosts-any", rng, notice=0.5)[1] for _ in range(20)}
    assert picks == {"c"}


def test_a_detectors_marks_are_moved_as_far_as_asked_at_the_median():
    hand = {f"k{i}": (100.0 + i, 200.0) for i in range(4000)}
    moved = ba.moved_marks(hand, 10.0, np.random.default_rng(0))
    assert np.median([np.hypot(*np.subtract(moved[n], hand[n])) for n in hand]) == pytest.approx(10.0, rel=0.05)


def test_the_detector_keys_user_puts_right_the_mark_furthest_off_until_none_is_off():
    hand = {"a": (0.0, 0.0), "b": (100.0, 0.0), "c": (0.0, 100.0)}
    seen = []

    class Fits:  # the "fit" is the marks; every fit's keypoints (ghosts) where the hand marks are
        def fit_marks(self, marks):
            seen.append(dict(marks))
            return marks

        def projected(self, fit):
            return {**hand, "d": (50.0, 50.0)}

        def distances(self, marks):
            d = float(np.mean([np.hypot(*np.subtract(marks.get(n, uv), uv)) for n, uv in hand.items()]))
            return d, d

        def same(self, d3, d2):
            return d3 <= 2.0

    # the key places "a" within a click, "b" 12 px off and "d", which the annotator left out, 40 px
    # off the hand fit's; it leaves out "c", whose ghost sits on its point
    found = {"a": (1.0, 0.0), "b": (100.0, 12.0), "d": (90.0, 50.0)}
    steps = ba.drags_to_the_hand_fit(found, hand, Fits(), accept_px=5.0)
    assert seen[1] == {"a": (1.0, 0.0), "b": (100.0, 12.0)}   # "d" removed first
    assert seen[2] == {"a": (1.0, 0.0), "b": (100.0, 0.0)}    # then "b" dragged onto its point
    assert [s["same"] for s in steps] == [False, False, True] and ba.same_from(steps, "same") == 3


def test_quick_against_full_compares_both_quick_policies_on_the_same_full_fits(tmp_path):
    """--quick-vs-full on the example's first twelve marks: a row per quick policy, each fit at
    the same counts; the page's quick fit lands near the full fit, from the same view."""
    from carbody.fit import read_keypoints

    marks = dict(list(read_keypoints(ba.REPO / "examples" / "car_keypoints.json").points.items())[:12])
    path = tmp_path / "twelve.json"
    path.write_text(json.dumps({"image": "car.png", "keypoints": {n: list(uv) for n, uv in marks.items()}}))
    rows = ba.quick_against_full([("example", ba.REPO / "examples" / "car.png", path)], every=6)
    assert [r["policy"] for r in rows] == list(ba.QUICK_POLICIES)
    assert all(r["fits"] == 2 and len(r["cpu_ms"]) == 2 and r["views_off"] == 0 for r in rows)
    assert max(rows[0]["off_pct"]) < 2.0  # % of the car's length
