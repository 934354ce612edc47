"""The end-to-end benchmark's small honest version (``benchmarks/bench_end_to_end.py``): one car
left out of the whole library, photographed at one view, reconstructed as a user would; and its
tables read back from the run's rows."""
from __future__ import annotations

import sys

from tests.conftest import REPO


def bench():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_end_to_end

    return bench_end_to_end


def test_a_car_left_out_comes_back_as_a_valid_body_and_the_tables_name_it(capsys):
    b = bench()
    from carbody.library import load_library

    names = load_library().template_names
    t = names.index("Volkswagen Golf Mk7")
    (row,) = b.run_template((t, (30,), False, None))
    assert row["error"] is None and row["shell_valid"] and row["fallback"] is None
    assert row["template"] == "Volkswagen Golf Mk7" and row["keypoints"] >= 20
    assert row["azimuth_off_deg"] <= 5.0
    assert row["mean_mm"] < 60.0  # the whole library's mean over every car and view is 34 mm

    b.print_tables([row, dict(row, template="Other car", mean_mm=2 * row["mean_mm"])], seen={"Other car"})
    out = capsys.readouterr().out
    cars = [line for line in out.splitlines() if line.startswith("| Volkswagen Golf Mk7 |") or line.startswith("| Other car |")]
    assert [c.split("|")[1].strip() for c in cars] == ["Other car", "Volkswagen Golf Mk7"]  # worst first
    assert "| all | 2 | 2 | 0 | 0 |" in out
