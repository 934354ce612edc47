"""Shared fixtures. The library cache goes to a per-session temporary folder."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    os.environ["CARBODY_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))
    yield


@pytest.fixture(scope="session")
def topology():
    from carbody.topology import load_topology

    return load_topology()


@pytest.fixture(scope="session")
def templates():
    from carbody.templates import load_templates

    return load_templates()


@pytest.fixture(scope="session")
def library():
    from carbody.library import load_library

    return load_library()


@pytest.fixture
def template_copy(tmp_path):
    """A writable copy of the shipped template folder."""
    from carbody.templates import templates_dir

    dst = tmp_path / "templates_step"
    shutil.copytree(templates_dir(), dst)
    return dst


def run_cli(*args: str, check: bool = False) -> subprocess.CompletedProcess:
    """Run ``carbody ARGS`` in a subprocess (the real console entry point's module)."""
    proc = subprocess.run([sys.executable, "-m", "carbody", *args], capture_output=True, text=True,
                          cwd=REPO, env={**os.environ})
    if check and proc.returncode != 0:
        raise AssertionError(f"carbody {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr}")
    return proc
