"""The README a user reads stays true to the code: every keypoint and every command it names exists."""
from __future__ import annotations

import re

from tests.conftest import REPO


def test_readme_lists_every_keypoint_with_its_description(topology):
    text = (REPO / "README.md").read_text()
    for k in topology.keypoints:
        assert f"| {k.id} | `{k.name}` | {k.description} |" in text


def test_every_command_the_readme_shows_exists():
    from carbody.cli import build_parser

    commands = set(build_parser()._subparsers._group_actions[0].choices)
    shown = set(re.findall(r"`carbody ([a-z-]+)", (REPO / "README.md").read_text()))
    assert shown and shown <= commands, shown - commands
