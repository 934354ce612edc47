"""The photo ablation's table (``benchmarks/bench_view.py --photo-ablation --table``) from the
rows' stored results: each cell the mean over the training seeds run, the seed-to-seed spread,
and a row whose renders were drawn otherwise than the row says is flagged. Also the speed run's
options and ``--real --recolour``'s recolouring."""
from __future__ import annotations

import json
import sys

import pytest

from tests.conftest import REPO


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_view

    return bench_view


def result(bench, value: float) -> dict:
    keys = [k for _, ks, _ in bench.PHOTO_COLUMNS for k in ks]
    return {k: value for k in keys} | {"train_s": 600.0, "val_acc": value}


#: The first pass's switches, in every data set's dataset.json.
FIRST_PASS = dict(camera=True, ground=True, environment=True, backdrop=True, artefacts=True, plates=True)


def write(path, data) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data))


def test_the_table_averages_seeds_and_flags_renders_drawn_otherwise(bench, tmp_path, capsys):
    write(tmp_path / "D" / "result_e30_64px_w0.5.json", result(bench, 0.5))
    write(tmp_path / "D" / "result_e30_64px_w0.5_s1.json", result(bench, 0.7))
    write(tmp_path / "D" / "result_e30_64px.json", result(bench, 0.1))          # another width: not D's row
    write(tmp_path / "D" / "dataset.json",        # drawn before tone existed: no such key, so off
          {"variation": {"photo": FIRST_PASS | dict(framing=True, details=True, sharp=True)}})
    write(tmp_path / "B" / "result_e30_64px_w0.5.json", result(bench, 0.4))
    write(tmp_path / "B" / "dataset.json", {"variation": {"photo": FIRST_PASS | dict(framing=True, tone=True)}})
    write(tmp_path / "measured" / "shipped.json", {"label": "shipped"} | result(bench, 0.3))

    bench.print_photo_ablation(tmp_path, 30, 0.5)
    out = capsys.readouterr().out
    rows = {line.split(":")[0].strip("| "): line for line in out.splitlines() if line.startswith("| ")}
    assert "| 2 | 0.60 / 0.60 / 0.60 / 0.60 |" in rows["D"]       # mean of the two seeds
    assert "renders drawn" not in rows["D"]
    assert "renders drawn with + tone" in rows["B"] and "| 1 | 0.40 /" in rows["B"]
    assert "| D | 0.20 / 0.20 /" in out                           # seed to seed: 0.7 - 0.5
    assert "| shipped | 0.30 / 0.30 /" in out
    assert not any(k in rows for k in ("A", "C", "E", "F"))          # no results, no row


def test_the_speed_run_times_every_call_on_the_threads_asked_and_refuses_none(bench, tmp_path):
    """``--speed`` on a synthetic picture (no photo folder): a timed row per call (the network's
    two looks only where the picture is read three-quarter on), the thread count in its header;
    ``--threads 0`` is refused in one line with exit 2."""
    import subprocess

    script = str(REPO / "benchmarks" / "bench_view.py")
    run = subprocess.run([sys.executable, script, "--speed", "--repeats", "3", "--threads", "2",
                          "--photos", str(tmp_path)], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "2 thread(s); picture synthetic" in run.stdout
    rows = [line for line in run.stdout.splitlines() if line.startswith("| whole call") or line.startswith("| network")]
    two = "two looks" in rows[0]           # a three-quarter view read in the picture: the second look's row too
    assert len(rows) == 3 + two and all(float(r.split("|")[2]) > 0 for r in rows)
    assert rows[1].startswith("| whole call, mirror averaged, one look") and "network alone" in rows[2]
    bad = subprocess.run([sys.executable, script, "--speed", "--threads", "0"], capture_output=True, text=True,
                         cwd=REPO, timeout=300)
    assert bad.returncode == 2 and bad.stderr.strip().splitlines() == ["bench_view: --threads must be at least 1, not 0"]


def test_recolouring_turns_the_reds_grey_and_leaves_the_rest(bench):
    """``--recolour``: a red lamp loses its colour, a blue panel keeps it; all grey is grey."""
    import numpy as np

    picture = np.zeros((2, 2, 3), dtype=np.uint8)
    picture[0, 0] = (200, 20, 30)       # a tail lamp's red
    picture[0, 1] = (30, 40, 200)       # blue paint
    picture[1, :] = (120, 120, 120)     # grey road
    red = bench.recoloured(picture, "red")
    assert len(set(red[0, 0])) == 1 and red[0, 0, 0] < 200
    assert (red[0, 1] == picture[0, 1]).all() and (red[1] == picture[1]).all()
    grey = bench.recoloured(picture, "grey")
    assert all(len(set(px)) == 1 for px in grey.reshape(-1, 3))


def test_the_looks_rules_vote_as_named(bench):
    """``--looks``' rules: one look keeps the whole car's call; the shipped product lets a sure
    near end turn a car the whole car read unsure of its end; the axis rule takes the end from the
    near end alone. Pictures without a second look are left as read."""
    import numpy as np

    from carbody.view.ends import combine_looks
    from carbody.view.labels import CLASS_ANGLES_DEG, continuous_estimate

    k30, k210 = (int(np.argmin(abs(CLASS_ANGLES_DEG - a))) for a in (30.0, 210.0))
    p = np.full(24, 1e-4)
    p[k30], p[k210] = 0.9, 0.1
    p /= p.sum()
    q = np.full(24, 1e-4)
    q[k210] = 1.0
    q /= q.sum()
    rules = bench._look_rules()
    one, shipped, axis = rules.values()
    assert np.allclose(one(p, q), p)
    assert np.allclose(shipped(p, q), combine_looks(p, q))
    for rule in (shipped, axis):
        assert abs(continuous_estimate(bench.voted(p[None], {0: q}, rule)[0]) - 210.0) < 10.0
    assert np.allclose(bench.voted(np.stack([p, p]), {1: q}, shipped)[0], p)       # no second look: as read
    assert bench.facing_read(q, 210.0) > 0.99 and bench.facing_read(q, 30.0) < 0.01


def test_the_looks_run_measures_every_rule_on_renders(bench, tmp_path):
    """``--looks`` with no photo folder: a few photo-like renders of the held-out cars are drawn
    into ``--workdir`` and every rule gets a row of shares, the second look's own table too."""
    import subprocess

    script = str(REPO / "benchmarks" / "bench_view.py")
    run = subprocess.run([sys.executable, script, "--looks", "--count", "24", "--workdir", str(tmp_path),
                          "--photos", str(tmp_path / "none")], capture_output=True, text=True, cwd=REPO, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "real photos: none at" in run.stdout and (tmp_path / "test_photo" / "manifest.csv").is_file()
    rows = [line.split("|")[1:-1] for line in run.stdout.splitlines()
            if line.startswith("| one look") or line.startswith("| the whole car") or line.startswith("| shipped")]
    assert len(rows) == 4
    assert all(0.0 <= float(cell) <= 1.0 for row in rows for cell in row[1:])
    ends = [line for line in run.stdout.splitlines() if line.startswith("| front |") or line.startswith("| rear |")]
    assert len(ends) == 2
