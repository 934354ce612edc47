"""Progress a person can see: long commands show their stage and a bar on a terminal's stderr,
and nothing in a log, a pipe or with --quiet."""
from __future__ import annotations

import io
import sys

import pytest

from tests.conftest import REPO

EXAMPLES = REPO / "examples"


class Terminal(io.StringIO):
    """stderr as a terminal shows it (what tqdm asks before drawing)."""

    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("stream, quiet, shown", [(Terminal(), False, True), (io.StringIO(), False, False),
                                                  (Terminal(), True, False)])
def test_the_stage_bar_shows_on_a_terminal_only(monkeypatch, stream, quiet, shown):
    from carbody.progress import progress

    monkeypatch.setattr(sys, "stderr", stream)
    with progress(("read", "fit", "write"), quiet) as bar:
        for stage in ("read", "fit", "write"):
            bar.start(stage)
    text = stream.getvalue()
    assert ("carbody fit (stage 2 of 3)" in text and "carbody write (stage 3 of 3)" in text) == shown
    assert bool(text) == shown


@pytest.mark.parametrize("quiet", [False, True])
def test_fit_shows_its_stages(monkeypatch, capsys, tmp_path, quiet):
    from carbody.cli import main

    stderr = Terminal()
    monkeypatch.setattr(sys, "stderr", stderr)
    argv = ["fit", str(EXAMPLES / "car.png"), "-k", str(EXAMPLES / "car_keypoints.json"), "--view", "30",
            "--no-refine", "--distance", "orthographic", "-o", str(tmp_path / "w.step")]
    assert main(argv + (["--quiet"] if quiet else [])) == 0
    text = stderr.getvalue()
    assert ("carbody read" in text and "carbody fit" in text and "carbody write" in text) != quiet
    assert "fitted 35 keypoints" in capsys.readouterr().out


def test_every_command_takes_quiet():
    from carbody.cli import build_parser

    parser = build_parser()
    for argv in (["reconstruct", "a.png", "-k", "k.json", "-o", "out"], ["demo"], ["surface", "w.step", "-o", "b.step"],
                 ["templates", "build", "--out", "t"], ["render-dataset", "d"], ["view", "a.png"], ["parts", "a.step"]):
        assert parser.parse_args([*argv, "--quiet"]).quiet
