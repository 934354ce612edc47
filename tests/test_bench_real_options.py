"""The options benchmark runs ``carbody reconstruct`` under each option it names and counts the
outcomes; where ``../shared/realphotos`` is present, a photo taken from 3 m told a distant
camera is refused naming the camera, not the marks."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.conftest import REPO

DATA = REPO.parent / "shared" / "realphotos"


def test_each_photo_gets_the_options_its_data_allows():
    sys.path.insert(0, str(REPO / "benchmarks"))
    from bench_real_options import variants
    from bench_real_photos import Photo

    bare = Photo("p", REPO / "p.jpg", REPO / "p.json", {}, {})
    told = Photo("p", REPO / "p.jpg", REPO / "p.json",
                 {"view_estimate_deg": 350, "published_mm": {"wheelbase": 2700}}, {})
    assert "view" not in variants(bare) and "wheelbase" not in variants(bare) and variants(bare)["none"] == []
    assert variants(told)["other end"] == ["--view", "170"] and variants(told)["wheelbase"] == ["--wheelbase", "2700"]


@pytest.mark.skipif(not (DATA / "parts.json").exists(), reason=f"no real-photo data at {DATA}")
def test_a_close_photo_told_a_distant_camera_is_refused_naming_the_camera(tmp_path):
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / "bench_real_options.py"), "--photos", "te31",
                           "--variants", "orthographic", "--out", str(tmp_path / "out"), "--json",
                           str(tmp_path / "r.json")], capture_output=True, text=True, timeout=600, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    result = json.loads((tmp_path / "r.json").read_text())
    outcome = {r["variant"]: r for r in result["rows"]}
    assert outcome["none"]["outcome"] == "body"
    assert outcome["orthographic"]["outcome"] == "refused" and "no distant camera" in outcome["orthographic"]["line"]
    assert {s["variant"]: s["blaming_marks"] for s in result["summary"]} == {"none": 0, "orthographic": 0}
    assert "| orthographic | 1 | 0 / 1 / 0 | 0 |" in proc.stdout
