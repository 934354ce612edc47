"""Nothing lost, nothing overwritten: a run writes all its files or none, never over its own
inputs, removes only what it made, and stops in one line when told to."""
from __future__ import annotations

import errno
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from carbody.errors import OutputError
from tests.conftest import REPO, run_cli

EXAMPLES = REPO / "examples"
PHOTO, KEYPOINTS = EXAMPLES / "car.png", EXAMPLES / "car_keypoints.json"
OUTPUTS = {"wireframe.step", "body.step", "car.step", "overlay.png", "body.png", "report.json", "summary.txt"}


def digests(folder: Path) -> dict[str, str]:
    """{name: sha256} of the files in ``folder`` (hidden ones too: a staging folder would show)."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder"
            for p in sorted(folder.iterdir())}


def leftovers(folder: Path) -> list[str]:
    """Staging folders, probes and temporary files a run may have left in ``folder``."""
    return [p.name for p in folder.rglob("*") if p.name.startswith(".") or ".tmp" in p.name]


@pytest.fixture(scope="module")
def result(example_reconstruction):
    return example_reconstruction


@pytest.fixture(scope="module")
def earlier(result, tmp_path_factory):
    """A finished reconstruction folder, as an earlier run left it."""
    out = tmp_path_factory.mktemp("earlier") / "out"
    result.write(out)
    return out


def test_a_failing_reconstruct_removes_only_the_folders_it_made(tmp_path, monkeypatch):
    """Run A makes the folder and fails after run B has written into it: B's file stays. A run
    that fails alone leaves nothing behind, its missing parents included."""
    import carbody.pipeline
    from carbody.cli import main
    from carbody.errors import FitError

    out = tmp_path / "shared" / "out"

    def other_run_writes_then_this_one_fails(*args, **kwargs):
        (out / "report.json").write_text("{}")  # another run's finished output
        raise FitError("the marks fit no car")

    monkeypatch.setattr(carbody.pipeline, "reconstruct", other_run_writes_then_this_one_fails)
    argv = ["reconstruct", str(PHOTO), "-k", str(KEYPOINTS), "--view", "30", "-o", str(out), "--quiet"]
    assert main(argv) == 2
    assert (out / "report.json").read_text() == "{}" and not leftovers(tmp_path)

    def this_run_fails(*args, **kwargs):
        raise FitError("the marks fit no car")

    monkeypatch.setattr(carbody.pipeline, "reconstruct", this_run_fails)
    alone = tmp_path / "new" / "deeper" / "out"
    assert main(["reconstruct", str(PHOTO), "-k", str(KEYPOINTS), "--view", "30", "-o", str(alone), "--quiet"]) == 2
    assert not (tmp_path / "new").exists()


def test_output_folder_keeps_what_another_run_put_there(tmp_path):
    from carbody.outputs import output_folder

    out = tmp_path / "a" / "b"
    with pytest.raises(RuntimeError):
        with output_folder(out):
            (tmp_path / "a" / "theirs.txt").write_text("x")  # beside ours, in a folder this run made
            raise RuntimeError
    assert not out.exists() and (tmp_path / "a" / "theirs.txt").is_file()


@pytest.mark.parametrize("command, what", [
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/w.step", "--overlay", "{photo}"),
     "--overlay would overwrite the photo"),
    (("fit", "{photo}", "-k", "{keypoints}", "--view", "30", "-o", "{tmp}/w.step", "--report", "{keypoints}"),
     "--report would overwrite the keypoint file"),
    (("surface", "{wire}", "-o", "{wire}"), "--output would overwrite the wireframe"),
    (("reconstruct", "{tmp}/d/overlay.png", "-k", "{keypoints}", "-o", "{tmp}/d"),
     "the output overlay.png would overwrite the photo"),
    (("freecad", "{tmp}/d", "-o", "{tmp}/d/report.json"), "--output would overwrite the folder's report.json"),
])
def test_no_output_may_be_an_input(tmp_path, command, what):
    """Refused in one line before any work; the input is as it was."""
    (tmp_path / "d").mkdir()
    photo, keypoints, wire = tmp_path / "car.png", tmp_path / "k.json", tmp_path / "w.step"
    for src, dst in ((PHOTO, photo), (KEYPOINTS, keypoints), (REPO / "templates_step" / "volvo_v60.step", wire),
                     (PHOTO, tmp_path / "d" / "overlay.png")):
        shutil.copy(src, dst)
    (tmp_path / "d" / "report.json").write_text("{}")
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    proc = run_cli(*[a.format(photo=photo, keypoints=keypoints, wire=wire, tmp=tmp_path) for a in command])
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and what in lines[0], proc.stderr
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def _can_mount_tmpfs() -> bool:
    if not shutil.which("unshare"):
        return False
    probe = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
                           capture_output=True)
    return probe.returncode == 0


def test_a_full_disk_leaves_the_earlier_outputs_as_they_were(earlier, result, tmp_path, monkeypatch):
    """On a disk too small for a second run (a tmpfs in a private mount namespace when this
    machine allows one; else the write made to fail with ENOSPC), the run says "no space left"
    naming the file, the earlier outputs are unchanged and no staging folder or temporary file
    is left."""
    if _can_mount_tmpfs():
        used = sum(p.stat().st_size for p in earlier.iterdir())
        disk = tmp_path / "disk"
        disk.mkdir()
        script = (f"mount -t tmpfs -o size={used + 600_000} tmpfs {disk} && cp -r {earlier} {disk}/out && "
                  f"{sys.executable} -m carbody reconstruct {PHOTO} -k {KEYPOINTS} --view 30 --wheelbase 2700 "
                  f"-o {disk}/out; echo rc=$?; sha256sum {disk}/out/* ; ls -a {disk}/out")
        proc = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True, cwd=REPO,
                              env={**os.environ})
        lines = proc.stderr.strip().splitlines()
        assert "rc=2" in proc.stdout and len(lines) == 1, proc.stdout + proc.stderr
        assert "no space left on device" in lines[0] and f"{disk}/out/" in lines[0]
        sums = {line.split()[1].rsplit("/", 1)[1]: line.split()[0] for line in proc.stdout.splitlines()
                if line.count(" ") == 2 and "/out/" in line}
        assert sums == digests(earlier)
        listed = proc.stdout.split("rc=2", 1)[1].split()
        assert not [n for n in listed if n.startswith(".") and n not in (".", "..") or ".tmp" in n]
        return
    out = tmp_path / "out"
    shutil.copytree(earlier, out)
    before = digests(out)
    real = Path.write_bytes

    def full(self, data):
        if ".carbody-" in str(self) and self.suffix == ".png":  # the STEP files fit, the pictures do not
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", full)
    with pytest.raises(OutputError, match="no space left on device") as err:
        result.write(out)
    assert str(out / "overlay.png") in str(err.value)
    assert digests(out) == before and not leftovers(out)


def test_a_folder_where_an_output_goes_is_named_before_the_work(earlier, tmp_path):
    """An unwritable file inside the output folder (here a folder where body.png goes; a
    read-only file for a user other than root): one line naming it, before any work, and the
    earlier outputs as they were."""
    out = tmp_path / "out"
    shutil.copytree(earlier, out)
    (out / "body.png").unlink()
    (out / "body.png").mkdir()
    before = digests(out)
    proc = run_cli("reconstruct", str(PHOTO), "-k", str(KEYPOINTS), "--view", "30", "-o", str(out), "--progress")
    lines = proc.stderr.strip().splitlines()
    # one line, and no "carbody: stage ..." line: refused before the classifier, the fit and the surfaces
    assert proc.returncode == 2 and len(lines) == 1 and f"{out / 'body.png'}: is a folder" in lines[0], proc.stderr
    assert digests(out) == before and not leftovers(out)
    if os.geteuid() != 0:  # root may write a read-only file, so carbody would too
        (out / "body.png").rmdir()
        shutil.copy(earlier / "body.png", out / "body.png")
        (out / "body.png").chmod(0o444)
        proc = run_cli("reconstruct", str(PHOTO), "-k", str(KEYPOINTS), "--view", "30", "-o", str(out))
        assert proc.returncode == 2 and "body.png: is read-only" in proc.stderr


def test_a_move_that_fails_puts_every_earlier_file_back(earlier, result, tmp_path, monkeypatch):
    """The files go into place together: when the fourth move fails, the three already moved are
    put back with the files they replaced."""
    import carbody.outputs

    out = tmp_path / "out"
    shutil.copytree(earlier, out)
    before = digests(out)
    real, moves = os.replace, []

    def replace(src, dst):
        if ".carbody-" in str(src) and ".carbody-" not in str(dst) and not Path(src).name.startswith(".previous"):
            moves.append(dst)
            if len(moves) == 4:
                raise OSError(errno.EIO, os.strerror(errno.EIO), str(dst))
        return real(src, dst)

    monkeypatch.setattr(carbody.outputs.os, "replace", replace)
    with pytest.raises(OutputError, match="input/output error"):
        result.write(out)
    assert len(moves) == 4 and digests(out) == before and not leftovers(out)


@pytest.mark.parametrize("name", ["body", "wireframe"])
def test_a_car_named_like_a_part_is_written(result, tmp_path, name):
    from dataclasses import replace

    from carbody.parts_cli import list_parts

    paths = replace(result, name=name).write(tmp_path / name)
    listing = list_parts(paths["assembly"])
    assert listing["product"] == name and len(listing["curves"]) == 125 and len(listing["faces"]) == len(result.body.faces)


def _caught(pid: int, signum: int) -> bool:
    """Whether process ``pid`` has a handler for ``signum`` yet (Linux /proc)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    mask = int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)
    return bool(mask >> (signum - 1) & 1)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
@pytest.mark.parametrize("signum, command, when", [
    (signal.SIGTERM, "reconstruct", "staging"), (signal.SIGHUP, "surface", "staging"),
    (signal.SIGINT, "reconstruct", "started")])
def test_a_signal_stops_the_run_in_one_line_and_leaves_nothing(tmp_path, signum, command, when):
    """SIGTERM and SIGHUP while the files are being staged: the staging folder goes, and with it
    the folder the run made; SIGINT (Ctrl-C) is one line, not a traceback."""
    out = tmp_path / "out"
    if command == "reconstruct":
        argv = ["reconstruct", PHOTO, "-k", KEYPOINTS, "--view", "30", "-o", out]
    else:
        out.mkdir()
        argv = ["surface", REPO / "templates_step" / "volvo_v60.step", "-o", out / "b.step", "--png", out / "b.png"]
    proc = subprocess.Popen([sys.executable, "-m", "carbody", *map(str, argv)], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # a worker may ignore it
    deadline = time.time() + 240
    while time.time() < deadline and proc.poll() is None:
        if when == "started" and _caught(proc.pid, signal.SIGTERM) and out.is_dir():
            break
        if when == "staging" and out.is_dir() and any(p.is_dir() for p in out.glob(".carbody-*")):
            break
        time.sleep(0.01)
    assert proc.poll() is None, "the run ended before the signal"
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=240)
    lines = err.strip().splitlines()
    assert proc.returncode == 128 + signum and lines == [f"carbody {command}: stopped by {signal.Signals(signum).name}"]
    assert not out.exists() if command == "reconstruct" else not any(out.iterdir())
