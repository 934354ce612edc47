"""Many photos on Dask: a batch finishes whatever one photo does, never leaves a folder
half-written, does again only what is missing or changed; the data set renders the same bits on
any number of workers."""
from __future__ import annotations

import json
import logging
import os
import shutil
import time

import pytest

from carbody.errors import BatchError
from tests.conftest import REPO

EXAMPLES = REPO / "examples"


@pytest.fixture
def cluster(library):
    """A local Dask cluster of 2 worker processes, one thread each (``library`` first fills the
    session's library cache, which the workers inherit through the environment). One test uses
    it: pytest-xdist would start one per test process otherwise (its ``loadgroup`` does not
    group on pytest 9)."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster:
        yield cluster


def photo_folder(folder, names=("a", "b", "c")):
    """Copies of the example photo and its marks as NAME.png + NAME.json in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(EXAMPLES / "car.png", folder / f"{name}.png")
        shutil.copy(EXAMPLES / "car_keypoints.json", folder / f"{name}.json")
    return folder


def test_on_two_workers_a_broken_photo_never_stops_the_batch_and_the_data_set_renders_the_same_bits(
        cluster, tmp_path):
    """Both on one cluster of 2 worker processes: a batch of 4 photos, one broken, run, run again
    and resumed (:func:`check_batch_finishes_and_resumes`); the classifier's data set rendered
    in this process, on 1 worker and on 2 (:func:`check_dataset_renders_the_same_bits`)."""
    check_batch_finishes_and_resumes(cluster, tmp_path / "batch")
    check_dataset_renders_the_same_bits(cluster, tmp_path / "dataset")


def check_batch_finishes_and_resumes(cluster, tmp_path):
    from carbody.batch import SUMMARY_FILE, run_batch

    photos = photo_folder(tmp_path / "photos")
    (photos / "broken.png").write_bytes(b"not a picture")
    shutil.copy(EXAMPLES / "car_keypoints.json", photos / "broken.json")
    manifest = tmp_path / "photos.csv"
    manifest.write_text("image,keypoints,view,wheelbase\n"
                        "photos/a.png,photos/a.json,,\n"
                        "photos/b.png,photos/b.json,front 30,2650\n"
                        "photos/broken.png,photos/broken.json,,\n"
                        "photos/c.png,photos/c.json,30,\n")
    out = tmp_path / "out"

    summary = run_batch(manifest, out, scheduler=cluster.scheduler_address, progress=False)
    assert summary.counts == {"done": 3, "skipped": 0, "refused": 1, "failed": 0} and not summary.ok
    saved = json.loads((out / SUMMARY_FILE).read_text())
    rows = {r["name"]: r for r in saved["photos"]}
    assert [r["name"] for r in saved["photos"]] == ["a", "b", "broken", "c"]     # the manifest's order
    assert "broken.png: not an image" in rows["broken"]["reason"] and "\n" not in rows["broken"]["reason"]
    assert all(rows[n]["status"] == "done" and rows[n]["seconds"] > 0 for n in "abc")
    assert saved["workers"] == 2 and len(saved["warm_up_s"]) == 2
    # each folder whole, as `carbody reconstruct` writes it, plus the row it came from
    for name in "abc":
        report = json.loads((out / name / "report.json").read_text())
        assert all((out / name / f).stat().st_size > 0 for f in report["files"])
        assert report["car"] == name and (out / name / "batch_job.json").is_file()
    b_report = json.loads((out / "b" / "report.json").read_text())
    assert b_report["view"]["source"] == "given" and b_report["fit"]["wheelbase_from"] == "told"
    assert not (out / "broken").exists()
    umask = os.umask(0)
    os.umask(umask)
    assert (out / "a").stat().st_mode & 0o777 == 0o777 & ~umask      # as `carbody reconstruct` makes it
    assert sorted(p.name for p in out.iterdir()) == [".carbody-batch.lock", "a", "b", "batch.json", "c"]

    # Again: nothing to do, no cluster needed; the refused photo is tried again (and refused).
    kept = {n: (out / n / "body.step").stat().st_mtime_ns for n in "abc"}
    again = run_batch(manifest, out, scheduler=cluster.scheduler_address, progress=False)
    assert again.counts == {"done": 0, "skipped": 3, "refused": 1, "failed": 0}
    assert {n: (out / n / "body.step").stat().st_mtime_ns for n in "abc"} == kept

    # As a batch killed half-way leaves it: b's folder not yet in place, its work folder half
    # written; and a's marks edited since. Run again: a and b are made, c is left as it was.
    shutil.rmtree(out / "b")
    (out / ".b.partial-x1y2z3").mkdir()
    (out / ".b.partial-x1y2z3" / "wireframe.step").write_text("ISO-10303-21; half")
    time.sleep(0.01)
    os.utime(photos / "a.json")
    resumed = run_batch(manifest, out, scheduler=cluster.scheduler_address, progress=False)
    status = {r["name"]: r["status"] for r in resumed.photos}
    assert status == {"a": "done", "b": "done", "broken": "refused", "c": "skipped"}
    assert (out / "c" / "body.step").stat().st_mtime_ns == kept["c"]
    assert not (out / ".b.partial-x1y2z3").exists() and (out / "b" / "report.json").is_file()


def check_dataset_renders_the_same_bits(cluster, tmp_path):
    from distributed import Client

    from carbody.cluster import connect
    from carbody.view.dataset import read_manifest, render_dataset

    kw = dict(count=24, seed=4, bodies_per_template=2, templates=["Volvo V60"], progress=False)
    render_dataset(tmp_path / "here", **kw)
    with connect(workers=1, warm=("kernel",)) as one:
        render_dataset(tmp_path / "one", **kw, client=one)
    with Client(cluster) as two:
        assert len(two.nthreads()) == 2
        render_dataset(tmp_path / "two", **kw, client=two)
    rows = read_manifest(tmp_path / "here")
    assert len(rows) == 24 and len({r["body"] for r in rows}) == 2
    for name in ("one", "two"):
        assert (tmp_path / name / "manifest.csv").read_bytes() == (tmp_path / "here" / "manifest.csv").read_bytes()
        assert (tmp_path / name / "dataset.json").read_bytes() == (tmp_path / "here" / "dataset.json").read_bytes()
        for r in rows:
            assert (tmp_path / name / r["file"]).read_bytes() == (tmp_path / "here" / r["file"]).read_bytes()


# ------------------------------------------------------------------ without a cluster: fast

def test_manifests_as_csv_json_lines_or_a_folder_read_alike(tmp_path):
    from carbody.batch import read_batch_manifest

    photos = photo_folder(tmp_path / "p", names=("a", "b"))
    (photos / "lonely.jpg").write_bytes(b"x")          # a photo without marks
    csv_rows = read_batch_manifest(_write(tmp_path / "m.csv", "photo,marks,name,view,wheelbase_mm,exclude_template\n"
                                          "p/a.png,p/a.json,first,rear 30,2700,Volvo V60; Mazda MX-5 ND\n"
                                          "p/b.png,p/b.json,,,,\n"))
    jsonl_rows = read_batch_manifest(_write(tmp_path / "m.jsonl", json.dumps(
        {"image": "p/a.png", "keypoints": "p/a.json", "name": "first", "view": 150, "wheelbase": 2700,
         "exclude_template": ["Volvo V60", "Mazda MX-5 ND"]}) + "\n\n" + json.dumps(
        {"image": "p/b.png", "keypoints": "p/b.json"}) + "\n"))
    for rows in (csv_rows, jsonl_rows):
        first, second = rows
        assert first.name == "first" and first.view == 150.0 and first.wheelbase_mm == 2700.0
        assert first.exclude_templates == ("Volvo V60", "Mazda MX-5 ND") and first.problem is None
        assert first.image == photos / "a.png" and first.image.is_absolute()
        assert second.name == "b" and second.view is None and second.camera_distance_mm == "auto"
    folder_rows = read_batch_manifest(photos)
    assert [p.name for p in folder_rows] == ["a", "b", "lonely"]
    assert folder_rows[0].keypoints == photos / "a.json" and folder_rows[2].problem.startswith("no marks file lonely.json")


def test_a_bad_cell_refuses_its_photo_and_a_bad_manifest_the_batch(tmp_path):
    from carbody.batch import read_batch_manifest

    rows = read_batch_manifest(_write(tmp_path / "m.csv", "image,keypoints,view,wheelbase\n"
                                      "a.png,a.json,upside down,\n" "b.png,b.json,,-3\n" ",c.json,,\n"))
    assert [p.problem is not None for p in rows] == [True, True, True]
    assert "-3" in rows[1].problem and rows[2].problem == "no image given"
    bad = {
        "unknown column 'wheelbse'": ("m.csv", "image,keypoints,wheelbse\na.png,a.json,2700\n"),
        "no 'keypoints' column": ("m.csv", "image\na.png\n"),
        "both write a/": ("m.csv", "image,keypoints\nx/a.png,a.json\ny/a.png,b.json\n"),
        "m.jsonl line 2: not JSON": ("m.jsonl", '{"image": "a.png", "keypoints": "a.json"}\n{image: b.png}\n'),
        "lists no photos": ("m.csv", "image,keypoints\n"),
        "not .txt": ("m.txt", "image,keypoints\n"),
    }
    for message, (name, text) in bad.items():
        with pytest.raises(BatchError, match=message.replace("(", r"\(")):
            read_batch_manifest(_write(tmp_path / name, text))


def test_a_folder_is_up_to_date_only_whole_from_the_same_row_and_newer_than_its_inputs(tmp_path):
    from dataclasses import replace

    from carbody.batch import JOB_FILE, read_batch_manifest, up_to_date

    photo = read_batch_manifest(photo_folder(tmp_path / "p", names=("a",)))[0]
    folder = tmp_path / "out" / "a"
    folder.mkdir(parents=True)
    (folder / "body.step").write_text("ISO-10303-21;")
    (folder / "report.json").write_text(json.dumps({"files": ["body.step", "report.json"]}))
    (folder / JOB_FILE).write_text(json.dumps({"row": photo.job()}))
    assert up_to_date(photo, folder)
    assert not up_to_date(replace(photo, view=30.0), folder)            # another row
    assert not up_to_date(photo, tmp_path / "out" / "b")                 # no folder
    later = time.time() + 5
    os.utime(photo.image, (later, later))                                # the photo changed since
    assert not up_to_date(photo, folder)
    os.utime(photo.image, (later - 10, later - 10))
    assert up_to_date(photo, folder)
    (folder / "body.step").write_text("")                                # a file emptied
    assert not up_to_date(photo, folder)


def test_a_folder_is_replaced_whole(tmp_path):
    from carbody.batch import publish

    final, work = tmp_path / "car", tmp_path / ".car.partial-abc"
    final.mkdir()
    (final / "old.txt").write_text("old")
    work.mkdir()
    (work / "new.txt").write_text("new")
    publish(work, final)
    assert [p.name for p in final.iterdir()] == ["new.txt"] and sorted(p.name for p in tmp_path.iterdir()) == ["car"]


def test_the_command_refuses_a_bad_manifest_in_one_line_before_any_cluster(tmp_path, capsys):
    from carbody.cli import main

    manifest = _write(tmp_path / "m.csv", "image,keypoints,colour\na.png,a.json,red\n")
    assert main(["batch", str(manifest), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown column 'colour'" in err
    assert main(["batch", str(tmp_path / "none.csv"), "-o", str(tmp_path / "out")]) == 2
    photo_folder(tmp_path / "p", names=("a",))
    assert main(["batch", str(tmp_path / "p"), "-o", str(tmp_path / "out"), "--workers", "0"]) == 2
    assert "--workers must be at least 1" in capsys.readouterr().err


def test_one_batch_at_a_time_per_output_folder(tmp_path):
    from carbody.batch import _exclusive

    out = tmp_path / "out"
    out.mkdir()
    with _exclusive(out):
        with pytest.raises(BatchError, match="another carbody batch"):
            with _exclusive(out):
                pass
    with _exclusive(out):
        pass


def _write(path, text):
    path.write_text(text)
    return path
