"""Many photos: reconstruct every row of a manifest on a Dask cluster (``carbody batch``).

    from carbody.batch import run_batch
    summary = run_batch("photos.csv", "out/", workers=2)      # a local cluster of 2 processes
    summary.counts          # {"done": 23, "refused": 1, "failed": 0, "skipped": 0}

A manifest is a CSV file (a header row naming the columns of :data:`COLUMNS`), JSON lines (one
object a line, the same keys), or a folder of photos each with its marks in a same-named
``.json`` file beside it. Paths are relative to the manifest's folder. Each photo goes into
``OUT_DIR/NAME/``: what ``carbody reconstruct`` writes there, and ``batch_job.json`` (the row
it was made from). ``OUT_DIR/batch.json`` holds the summary: every photo, done, skipped or
refused with its one-line reason, and its time.

Each photo is one task, a call of the public API (:func:`carbody.reconstruct`, then
:meth:`~carbody.pipeline.Reconstruction.write`), so a batch and a single run cannot drift
apart. The task writes into a hidden folder beside ``OUT_DIR/NAME`` and renames it into place
once every file is written: a photo's folder is whole or absent, whatever stops the run. A
photo whose folder is whole, made from the same row and newer than its photo and marks is
skipped (:func:`up_to_date`), so a batch run again does only what is missing or changed, and a
batch killed half-way finishes the rest. A photo refused (a
:class:`~carbody.errors.CarbodyError`: unreadable, marks that do not fit, ...) or failing (a bug,
a worker that died) is one line in the summary; the other photos go on.
"""
from __future__ import annotations

import csv
import fcntl
import functools
import json
import logging
import math
import os
import re
import shutil
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from carbody.errors import BatchError, CarbodyError, OutputError

logger = logging.getLogger(__name__)

#: A manifest's columns (CSV header / JSON keys): what each gives. ``image`` and ``keypoints``
#: are required; the others pass to :func:`carbody.reconstruct` as ``carbody reconstruct``'s
#: options of the same names do (an empty cell: the option's default).
COLUMNS = {
    "image": "the photo (PNG, JPEG, ...)",
    "keypoints": "its marks: the project's JSON, COCO keypoints or labelme",
    "name": "the output folder OUT_DIR/NAME and the car's name in the STEP files (default: the photo's stem)",
    "view": "view azimuth in degrees or a name ('front 30'); default: the view classifier",
    "wheelbase": "the car's wheelbase, mm (default: fitted)",
    "elevation": "camera elevation told, degrees (default 0)",
    "distance": "camera distance, mm, 'auto' (default) or 'orthographic'",
    "exclude_template": "templates left out of the library, ';'-separated (a car it has never seen)",
}

#: Other names people give those columns.
ALIASES = {"photo": "image", "marks": "keypoints", "wheelbase_mm": "wheelbase", "elevation_deg": "elevation",
           "distance_mm": "distance", "exclude_templates": "exclude_template"}

#: Photos a folder manifest picks up (what OpenCV reads), each with ``<stem>.json`` beside it.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp", ".tif", ".tiff")

#: Each output folder's record of the row it was made from (:func:`up_to_date` compares it).
JOB_FILE = "batch_job.json"

#: The batch's summary, in OUT_DIR.
SUMMARY_FILE = "batch.json"

#: Held (``flock``) while a batch writes into OUT_DIR: one batch per folder at a time.
LOCK_FILE = ".carbody-batch.lock"

#: The summary file is rewritten at most this often while the batch runs, seconds (and at its
#: end; a summary that takes long to write, less often).
SUMMARY_EVERY_S = 5.0

#: Hidden folders a task works in beside OUT_DIR/NAME (a killed run leaves them; the next removes them).
_WORK_FOLDER = re.compile(r"^\..+\.(partial|old)-[A-Za-z0-9_]+$")

#: The screen table lists every photo up to this many, then only those refused or failed.
SCREEN_ROWS = 40


# ------------------------------------------------------------------------------------ manifest

@dataclass(frozen=True)
class Photo:
    """One row of a manifest, its paths absolute.

    Attributes:
        name: the output folder's name (OUT_DIR/NAME) and the car's in the STEP files.
        image, keypoints: the photo and its marks (None: not given).
        view: azimuth in degrees, or None (the classifier).
        wheelbase_mm, elevation_deg, camera_distance_mm: as :func:`carbody.reconstruct`'s.
        exclude_templates: templates left out of the library.
        where: the row, for messages ("photos.csv line 4").
        problem: why the row is refused before any work (a bad cell), or None.
    """

    name: str
    image: Path | None
    keypoints: Path | None
    view: float | None = None
    wheelbase_mm: float | None = None
    elevation_deg: float = 0.0
    camera_distance_mm: float | str | None = "auto"
    exclude_templates: tuple[str, ...] = ()
    where: str = ""
    problem: str | None = None

    def job(self) -> dict:
        """What the outputs are made from, JSON-ready (kept in each folder's ``batch_job.json``)."""
        return {"image": str(self.image), "keypoints": str(self.keypoints), "view": self.view,
                "wheelbase_mm": self.wheelbase_mm, "elevation_deg": self.elevation_deg,
                "camera_distance_mm": self.camera_distance_mm,
                "exclude_templates": list(self.exclude_templates)}


def read_batch_manifest(manifest: str | Path) -> list[Photo]:
    """The photos of a manifest: a ``.csv`` file, JSON lines (``.jsonl``, ``.ndjson``,
    ``.json``) or a folder of photos with same-named ``.json`` marks.

    A row with a bad cell (no photo, a view that is no view, a wheelbase that is no number) is
    read with its ``problem`` set: the batch refuses that photo and runs the rest.

    Raises:
        BatchError: no such manifest, not CSV or JSON lines, an unknown or missing column, a
            line that is not JSON, no rows, or two rows writing one folder.
    """
    path = Path(manifest)
    if path.is_dir():
        photos = _read_folder(path)
    elif not path.is_file():
        raise BatchError(f"{path}: no such manifest (a CSV or JSON-lines file, or a folder of photos)")
    elif path.suffix.lower() == ".csv":
        photos = _read_csv(path)
    elif path.suffix.lower() in (".jsonl", ".ndjson", ".json"):
        photos = _read_json_lines(path)
    else:
        raise BatchError(f"{path}: a manifest is a .csv or JSON-lines (.jsonl) file or a folder of photos, "
                         f"not {path.suffix or 'a file without an ending'}")
    if not photos:
        raise BatchError(f"{path}: lists no photos")
    seen: dict[str, Photo] = {}
    for photo in photos:
        if photo.name in seen:
            raise BatchError(f"{seen[photo.name].where} and {photo.where} both write {photo.name}/ "
                             f"(give them a name column)")
        seen[photo.name] = photo
    return photos


def _column(key: str, where: str) -> str:
    key = key.strip().lower().replace(" ", "_").replace("-", "_")
    key = ALIASES.get(key, key)
    if key not in COLUMNS:
        raise BatchError(f"{where}: unknown column {key!r} (known: {', '.join(COLUMNS)})")
    return key


def _read_csv(path: Path) -> list[Photo]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise BatchError(f"{path}: is empty (need a header row: image,keypoints,...)")
            keys = [_column(k, str(path)) for k in header]
            for required in ("image", "keypoints"):
                if required not in keys:
                    raise BatchError(f"{path}: no {required!r} column (the header names {', '.join(keys)})")
            photos = []
            for cells in reader:
                if not any(c.strip() for c in cells):
                    continue
                where = f"{path.name} line {reader.line_num}"
                row = dict(zip(keys, cells))
                if len(cells) > len(keys):
                    photos.append(_photo(row, path.parent, where, f"{len(cells)} cells, the header names {len(keys)}"))
                else:
                    photos.append(_photo(row, path.parent, where))
            return photos
    except (UnicodeDecodeError, csv.Error) as exc:
        raise BatchError(f"{path}: not a CSV text file ({exc})") from None


def _read_json_lines(path: Path) -> list[Photo]:
    photos = []
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise BatchError(f"{path}: not a text file") from None
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        where = f"{path.name} line {n}"
        try:
            row = json.loads(line)
        except json.JSONDecodeError as exc:
            raise BatchError(f"{where}: not JSON ({exc.msg}; a JSON-lines manifest holds one object a line)") from None
        if not isinstance(row, dict):
            raise BatchError(f"{where}: a JSON-lines manifest holds one object a line, not a {type(row).__name__}")
        photos.append(_photo({_column(k, where): v for k, v in row.items()}, path.parent, where))
    return photos


def _read_folder(folder: Path) -> list[Photo]:
    photos = []
    for image in sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES):
        marks = image.with_suffix(".json")
        where = f"{folder.name}/{image.name}"
        photos.append(_photo({"image": image.name, "keypoints": marks.name}, folder, where,
                             None if marks.is_file() else f"no marks file {marks.name} beside the photo"))
    return photos


def _photo(row: dict[str, Any], base: Path, where: str, problem: str | None = None) -> Photo:
    """A :class:`Photo` from one row's cells (strings from CSV, JSON values), paths against ``base``."""
    from carbody.camera import read_view
    from carbody.fit.cli import parse_distance

    cells = {k: (v.strip() if isinstance(v, str) else v) for k, v in row.items()}
    cells = {k: v for k, v in cells.items() if v not in ("", None, [])}

    def path_of(key: str) -> Path | None:
        value = cells.get(key)
        return None if value is None else Path(os.path.abspath(base / Path(str(value)).expanduser()))

    image, keypoints = path_of("image"), path_of("keypoints")
    name = str(cells.get("name") or (image.stem if image else where.replace(" ", "_")))
    values: dict[str, Any] = {}
    try:
        if image is None:
            raise BatchError("no image given")
        if keypoints is None:
            raise BatchError("no keypoints given")
        if name in (".", "..") or name.startswith(".") or "/" in name or "\\" in name or name == SUMMARY_FILE:
            raise BatchError(f"{name!r} cannot be an output folder's name")
        if "view" in cells:
            values["view"] = read_view(cells["view"])
        if "wheelbase" in cells:
            values["wheelbase_mm"] = _positive(cells["wheelbase"], "wheelbase")
        if "elevation" in cells:
            values["elevation_deg"] = _number(cells["elevation"], "elevation")
        if "distance" in cells:
            values["camera_distance_mm"] = parse_distance(str(cells["distance"]))
        if "exclude_template" in cells:
            names = cells["exclude_template"]
            names = names.split(";") if isinstance(names, str) else [str(n) for n in names]
            values["exclude_templates"] = tuple(n.strip() for n in names if n.strip())
    except CarbodyError as exc:
        problem = problem or str(exc)
    return Photo(name, image, keypoints, where=where, problem=problem, **values)


def _number(value: Any, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise BatchError(f"{what} {value!r} is not a number") from None
    if not math.isfinite(number):
        raise BatchError(f"{what} {value!r} is not a finite number")
    return number


def _positive(value: Any, what: str) -> float:
    number = _number(value, what)
    if number <= 0:
        raise BatchError(f"{what} {value!r} is not a positive number of mm")
    return number


# --------------------------------------------------------------------------- one photo, a task

def up_to_date(photo: Photo, folder: str | Path) -> bool:
    """Whether ``folder`` holds ``photo``'s outputs, whole, from the same row and newer than
    its photo and marks: every file its ``report.json`` lists is there and not empty, its
    ``batch_job.json`` records this row, and the oldest of them is no older than the newer of
    the two inputs."""
    folder = Path(folder)
    try:
        job = json.loads((folder / JOB_FILE).read_text())
        report = json.loads((folder / "report.json").read_text())
        if job.get("row") != photo.job():
            return False
        outputs = [(folder / f).stat() for f in report["files"]] + [(folder / JOB_FILE).stat()]
        inputs = [photo.image.stat(), photo.keypoints.stat()]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False
    return all(s.st_size > 0 for s in outputs) and \
        min(s.st_mtime_ns for s in outputs) >= max(s.st_mtime_ns for s in inputs)


def reconstruct_photo(photo: Photo, out_dir: str | Path) -> dict:
    """One photo of a batch, run where it is called (a Dask worker, or any process): the
    photo's row of the summary.

    ``carbody.reconstruct`` on the row, ``Reconstruction.write`` into a hidden folder in
    ``out_dir``, its ``batch_job.json`` beside, and the folder renamed to ``out_dir/NAME``
    (:func:`publish`). Never raises for the photo's sake: a refusal or a failure is the row's
    ``status`` and one-line ``reason``.

    Returns:
        {"name", "image", "status": "done" | "refused" | "failed", "reason": str | None,
         "seconds": the task's wall time, "timings_s": the stages' (done only), "worker"}.
    """
    start = time.perf_counter()
    row: dict[str, Any] = {"name": photo.name, "image": str(photo.image), "status": None, "reason": None,
                           "worker": _worker_name()}
    out = Path(out_dir)
    work = None
    try:
        if photo.problem:
            raise BatchError(photo.problem)
        if not out.is_dir():  # a worker on another machine that does not mount it
            raise OutputError(f"{out}: no such output folder on this worker's file system")
        from carbody import reconstruct

        result = reconstruct(photo.image, photo.keypoints, photo.view, photo.wheelbase_mm, name=photo.name,
                             elevation_deg=photo.elevation_deg, camera_distance_mm=photo.camera_distance_mm,
                             library=library_for(photo.exclude_templates))
        # os.mkdir, not mkdtemp: the folder gets the umask's mode, as `carbody reconstruct`'s does
        work = out / f".{photo.name}.partial-{uuid.uuid4().hex[:12]}"
        os.mkdir(work)
        result.write(work)
        (work / JOB_FILE).write_text(json.dumps(
            {"row": photo.job(), "where": photo.where, "worker": row["worker"],
             "timings_s": result.timings_s}, indent=1))
        publish(work, out / photo.name)
        work = None
        row.update(status="done", timings_s=dict(result.timings_s))
    except CarbodyError as exc:
        row.update(status="refused", reason=_one_line(str(exc)))
    except Exception as exc:  # noqa: BLE001  a bug met by one photo must not stop the batch
        logger.exception("carbody batch: %s failed", photo.name)
        row.update(status="failed", reason=_one_line(f"{type(exc).__name__}: {exc}"))
    finally:
        if work is not None:
            shutil.rmtree(work, ignore_errors=True)
    row["seconds"] = time.perf_counter() - start
    return row


def publish(work: Path, final: Path) -> None:
    """Put the whole folder ``work`` at ``final`` by renames: an older ``final`` is first moved
    aside (then removed), so at every moment ``final`` is either the old folder, absent, or the
    new one, never a mix."""
    old = None
    if final.exists() or final.is_symlink():
        old = final.with_name(f".{final.name}.old-{uuid.uuid4().hex[:12]}")
        os.rename(final, old)
    os.rename(work, final)
    if old is not None:
        _remove(old)


def library_for(excluded: Iterable[str]):
    """The library a row asks for: None (the shipped one, :func:`carbody.library.default_library`)
    or the shipped one without ``excluded``, built once per process for a few such sets."""
    excluded = tuple(sorted(excluded))
    return _library_without(excluded) if excluded else None


@functools.lru_cache(maxsize=4)
def _library_without(excluded: tuple[str, ...]):
    from carbody.fit.cli import library_without

    return library_without(list(excluded))


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().name)
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


# ----------------------------------------------------------------------------------- the batch

@dataclass
class BatchSummary:
    """What a batch did: one row per photo of the manifest, in its order.

    Attributes:
        manifest, out_dir: where from and to.
        photos: per photo {"name", "image", "status": "done" | "skipped" | "refused" |
            "failed" | "not run", "reason", "seconds", "worker", ...}.
        cluster: the cluster it ran on ("local, 2 workers", a scheduler's address, or "none":
            every photo up to date).
        workers: how many workers the cluster had.
        wall_s: the batch's wall time, seconds.
        start_s: of which starting the cluster (or connecting to it) and warming its workers.
        warm_up_s: per worker, the seconds each part of :func:`carbody.cluster.warm_up` took.
    """

    manifest: str
    out_dir: Path
    photos: list[dict]
    cluster: str = "none"
    workers: int = 0
    wall_s: float = 0.0
    start_s: float = 0.0
    warm_up_s: dict[str, dict[str, float]] = field(default_factory=dict)
    started: str = field(default_factory=lambda: time.strftime("%Y-%m-%dT%H:%M:%S%z"))

    @property
    def counts(self) -> dict[str, int]:
        counts = {s: 0 for s in ("done", "skipped", "refused", "failed")}
        for row in self.photos:
            if row is None:  # still running
                continue
            counts[row["status"]] = counts.get(row["status"], 0) + 1
        return counts

    @property
    def photos_per_minute(self) -> float | None:
        """Photos done per minute once the workers were warm (``wall_s − start_s``)."""
        done, seconds = self.counts["done"], self.wall_s - self.start_s
        return 60.0 * done / seconds if done and seconds > 0 else None

    @property
    def ok(self) -> bool:
        """Every photo done or up to date."""
        return all(row["status"] in ("done", "skipped") for row in self.photos)

    def as_dict(self) -> dict:
        return {"manifest": self.manifest, "out_dir": str(self.out_dir), "started": self.started,
                "cluster": self.cluster, "workers": self.workers, "warm_up_s": self.warm_up_s,
                "wall_s": round(self.wall_s, 3), "start_s": round(self.start_s, 3),
                "photos_per_minute": None if self.photos_per_minute is None else round(self.photos_per_minute, 2),
                "counts": self.counts, "photos": self.photos}

    def write(self) -> Path:
        """``OUT_DIR/batch.json``, replaced in one rename."""
        path = self.out_dir / SUMMARY_FILE
        tmp = path.with_name(f".{SUMMARY_FILE}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(self.as_dict(), indent=1))
        os.replace(tmp, path)
        return path

    def table(self, rows: int = SCREEN_ROWS) -> str:
        """The summary for a screen: a line per photo (past ``rows`` photos, only those refused
        or failed), then the counts."""
        shown = self.photos if len(self.photos) <= rows else \
            [r for r in self.photos if r["status"] not in ("done", "skipped")]
        width = max([len(r["name"]) for r in shown] + [4])
        lines = [f"{'name':<{width}}  {'status':<8}  {'time':>7}  reason"] if shown else []
        for r in shown:
            seconds = f"{r['seconds']:.1f} s" if r.get("seconds") is not None else "—"
            lines.append(f"{r['name']:<{width}}  {r['status']:<8}  {seconds:>7}  {r.get('reason') or ''}".rstrip())
        if len(shown) < len(self.photos):
            lines.append(f"(and {len(self.photos) - len(shown)} done or up to date: {SUMMARY_FILE} lists every photo)")
        c = self.counts
        rate = f", {self.photos_per_minute:.1f} photos/min" if self.photos_per_minute else ""
        where = f" on {self.cluster}" if self.cluster != "none" else ""
        lines.append(f"{len(self.photos)} photos: {c['done']} done, {c['skipped']} up to date, {c['refused']} refused, "
                     f"{c['failed']} failed; {self.wall_s:.1f} s{where}"
                     + (f" ({self.start_s:.1f} s of it starting them)" if self.start_s else "") + rate)
        return "\n".join(lines)


def run_batch(manifest: str | Path, out_dir: str | Path, scheduler: str | None = None,
              workers: int | None = None, *, force: bool = False, progress: bool = True,
              client=None, on_photo: Callable[[dict], None] | None = None) -> BatchSummary:
    """Reconstruct every photo of ``manifest`` into ``out_dir/NAME/`` on a Dask cluster and
    write ``out_dir/batch.json``.

    Args:
        manifest: CSV, JSON lines or a folder of photos (:func:`read_batch_manifest`).
        out_dir: the output folder (created if needed).
        scheduler: a running cluster's scheduler address (``tcp://host:8786``); None starts a
            local cluster for the run.
        workers: the local cluster's worker processes (default one per core).
        force: redo photos that are up to date too.
        progress: a progress bar over photos on stderr (at a terminal only).
        client: a ``distributed.Client`` to run on instead (its workers get
            :class:`carbody.cluster.CarbodyWorker`).
        on_photo: called with each photo's summary row as it finishes.

    Raises:
        BatchError: a bad manifest (before any work), another batch writing ``out_dir``, or a
            cluster that cannot be used. A photo's own trouble never raises: it is its row.
    """
    from carbody.pipeline import prepare_output_dir

    start = time.perf_counter()
    photos = read_batch_manifest(manifest)
    out = prepare_output_dir(out_dir).resolve()
    with _exclusive(out):
        _remove_work_folders(out)
        summary = BatchSummary(str(manifest), out, [None] * len(photos))  # type: ignore[list-item]
        todo = []
        for i, photo in enumerate(photos):
            base = {"name": photo.name, "image": photo.image and str(photo.image), "reason": None, "seconds": None}
            if photo.problem:
                summary.photos[i] = {**base, "status": "refused", "reason": photo.problem}
            elif not force and up_to_date(photo, out / photo.name):
                summary.photos[i] = {**base, "status": "skipped", "reason": "up to date"}
            else:
                todo.append(i)
        try:
            if todo:
                _run_on_cluster(summary, photos, todo, out, scheduler, workers, client, progress, on_photo, start)
        finally:
            for i in todo:
                if summary.photos[i] is None:  # stopped (Ctrl-C) before its result came back
                    whole = up_to_date(photos[i], out / photos[i].name)
                    summary.photos[i] = {"name": photos[i].name, "image": str(photos[i].image),
                                         "status": "done" if whole else "not run",
                                         "reason": "finished as the batch stopped" if whole else "the batch stopped first",
                                         "seconds": None}
            summary.wall_s = time.perf_counter() - start
            summary.write()
    return summary


def _run_on_cluster(summary: BatchSummary, photos: list[Photo], todo: list[int], out: Path, scheduler, workers,
                    client, progress: bool, on_photo, start: float) -> None:
    import contextlib

    from distributed import as_completed
    from tqdm import tqdm

    from carbody.cluster import WARM_PARTS, CarbodyWorker, check_shared_folder, connect, warm_up_seconds

    with contextlib.ExitStack() as stack:
        if client is None:
            client = stack.enter_context(connect(scheduler, workers))
            summary.cluster = scheduler or f"local, {len(client.nthreads())} workers"
        else:
            client.register_plugin(CarbodyWorker(WARM_PARTS))
            summary.cluster = str(client.scheduler.address)
        summary.workers = len(client.nthreads())
        summary.start_s = time.perf_counter() - start
        summary.warm_up_s = warm_up_seconds(client)
        check_shared_folder(client, out)
        futures = {client.submit(reconstruct_photo, photos[i], str(out), key=f"photo-{i}-{uuid.uuid4().hex[:8]}",
                                 pure=False, retries=0): i for i in todo}
        bar = stack.enter_context(tqdm(total=len(photos), initial=len(photos) - len(todo), desc="batch",
                                       unit="photo", file=sys.stderr, disable=None if progress else True))
        next_write = time.perf_counter() + SUMMARY_EVERY_S
        try:
            for future in as_completed(futures):
                i = futures[future]
                try:
                    row = future.result()
                except Exception as exc:  # noqa: BLE001  the worker died (KilledWorker) or the task was lost
                    row = {"name": photos[i].name, "image": str(photos[i].image), "status": "failed",
                           "reason": _one_line(f"{type(exc).__name__}: {exc}"), "seconds": None}
                summary.photos[i] = row
                bar.update(1)
                c = summary.counts
                bar.set_postfix_str(f"{c['refused'] + c['failed']} refused" if c["refused"] + c["failed"] else "")
                if on_photo:
                    on_photo(row)
                if time.perf_counter() > next_write:
                    # a huge batch's summary takes a while to write: at most 5 % of the time on it
                    began = summary.wall_s = time.perf_counter() - start
                    summary.write()
                    took = time.perf_counter() - start - began
                    next_write = time.perf_counter() + max(SUMMARY_EVERY_S, 20.0 * took)
        except BaseException:
            client.cancel(list(futures))
            raise


class _exclusive:
    """Holds ``OUT_DIR/.carbody-batch.lock`` (released when the process ends, however it ends)."""

    def __init__(self, out: Path):
        self.path = out / LOCK_FILE

    def __enter__(self):
        self.fh = open(self.path, "a+")
        try:
            fcntl.flock(self.fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self.fh.close()
            raise BatchError(f"{self.path.parent}: another carbody batch is writing there") from None
        return self

    def __exit__(self, *exc):
        fcntl.flock(self.fh, fcntl.LOCK_UN)
        self.fh.close()


def _remove_work_folders(out: Path) -> None:
    """A killed run's half-written work folders (never a photo's own folder)."""
    for entry in out.iterdir():
        if _WORK_FOLDER.match(entry.name):
            _remove(entry)
