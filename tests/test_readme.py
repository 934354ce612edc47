"""The docs a user reads stay true to the code: every keypoint is listed, and every command the
README and docs/ name exists."""
from __future__ import annotations

import re

from tests.conftest import REPO


def test_the_keypoint_page_lists_every_keypoint_with_its_description(topology):
    text = (REPO / "docs" / "keypoints.md").read_text()
    for k in topology.keypoints:
        assert f"| {k.id} | `{k.name}` | {k.description} |" in text


def test_every_command_the_docs_show_exists():
    from carbody.cli import build_parser

    commands = set(build_parser()._subparsers._group_actions[0].choices)
    for page in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        shown = set(re.findall(r"`carbody ([a-z][a-z-]*)", page.read_text()))
        assert shown <= commands, (page.name, shown - commands)
