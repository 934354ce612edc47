"""It installs like a Python package: the wheel built from the repository, installed into a fresh
virtual environment, reconstructs the example from a folder outside the checkout, with the
templates, the view classifier's weights and the demo's files (``carbody demo`` runs the same
on them) as package data, writes nothing
into its own install folder, and needs no home folder it can write to."""
from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
from pathlib import Path

from tests.conftest import REPO

#: What the copy of the repository the wheel is built from leaves out (a checkout's own state).
NOT_SOURCE = (".git", ".venv", "out", "build", "*.egg-info", "__pycache__", ".pytest_cache", ".cache",
              ".hypothesis")


def run(*argv, **kwargs) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=600, **kwargs)
    assert proc.returncode == 0, f"{' '.join(map(str, argv))}:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc


def files_under(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def test_the_wheel_installs_and_reconstructs_the_example_outside_the_checkout(tmp_path):
    source = tmp_path / "source"
    shutil.copytree(REPO, source, symlinks=True, ignore=shutil.ignore_patterns(*NOT_SOURCE))
    wheels = tmp_path / "wheels"
    run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--quiet", "-w", wheels, source)
    (wheel,) = wheels.glob("carbody-*.whl")

    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", "--without-pip", venv)
    python = venv / "bin" / "python"
    run(sys.executable, "-m", "pip", "--python", python, "install", "--no-deps", "--no-index", "--quiet", wheel)
    installed = Path(run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    # The heavy dependencies (OCP, torch, VTK) come from this environment rather than the
    # network: its site-packages are put after the new one's, so carbody itself is the wheel's.
    (installed / "carbody_test_dependencies.pth").write_text("\n".join(site.getsitepackages()) + "\n")

    work, home = tmp_path / "elsewhere", tmp_path / "home"
    work.mkdir()
    home.write_text("")  # a home nothing can be written under (for root too): no caches, and no word of it
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "CARBODY_TEMPLATES_DIR", "CARBODY_CACHE_DIR", "XDG_CACHE_HOME")}
    env.update(HOME=str(home), OMP_NUM_THREADS="1")
    where = run(python, "-c", "import carbody, carbody.shipped as s; print(carbody.__file__); "
                              "print(all(p.is_dir() for p in (s.TEMPLATES, s.EXAMPLES, s.WORKBENCH)))",
                cwd=work, env=env).stdout.split()
    assert Path(where[0]).is_relative_to(installed) and where[1] == "True"
    before = files_under(installed)

    example = installed / "carbody" / "shipped" / "examples"  # the demo's files, as the wheel ships them
    for name in ("car.png", "car_keypoints.json"):
        shutil.copy(example / name, work / name)
    carbody = venv / "bin" / "carbody"
    proc = run(carbody, "reconstruct", "car.png", "-k", "car_keypoints.json", "--truth", example / "car_truth.step",
               "-o", "out", cwd=work, env=env)
    assert "classifier said" in proc.stdout and proc.stderr == "", proc.stderr  # the shipped weights
    assert "3D keypoint error vs truth" in proc.stdout
    assert {p.name for p in (work / "out").iterdir()} == {"wireframe.step", "body.step", "car.step", "overlay.png",
                                                          "body.png", "report.json", "summary.txt"}
    assert files_under(installed) == before  # nothing written into site-packages
