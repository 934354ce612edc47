"""Output files: checked before a command does its work, and written all or nothing.

A path that cannot be written, or that is one of the command's own inputs, is one line
(:class:`~carbody.errors.OutputError`) before anything is computed or written, not a traceback
after the first files are out. A command's files are then written into a staging folder
(``.carbody-*``) beside each target and moved into place together when every one is whole
(:func:`staged`): on a full disk, an interruption or any failure the files that were there stay
as they were, and the staging folder goes. A folder made for the outputs is removed again when
the run fails, if nothing else has been put in it since (:func:`output_folder`).
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from carbody.errors import CarbodyError, OutputError
from carbody.signals import held

#: Suffixes of the pictures the commands write (VTK, matplotlib and OpenCV all write PNG).
PICTURE = (".png",)

#: … and of the overlay, drawn with OpenCV, which writes JPEG too.
PHOTO = (".png", ".jpg", ".jpeg")

#: Suffixes of STEP files (the endings CAD programs open as STEP) …
STEP = (".step", ".stp")

#: … of the JSON reports …
JSON = (".json",)

#: … and of FreeCAD documents.
FREECAD = (".fcstd",)

#: Prefix of the staging folders (and of the probe files) the commands make beside their outputs.
STAGING_PREFIX = ".carbody-"

_KINDS = {PICTURE: "a picture", PHOTO: "a picture", STEP: "a STEP file", JSON: "a JSON report",
          FREECAD: "a FreeCAD document"}


def check_output_file(path: str | Path, suffixes: tuple[str, ...] | None = None) -> Path:
    """``path`` as a file this process can create or replace.

    Args:
        suffixes: the file name's allowed endings (lower case: ``PICTURE``, ``PHOTO``, ``STEP``,
            ``JSON``, ``FREECAD``), or None for any.
    Raises:
        OutputError: the path is a folder, a loop of symbolic links, a device or a pipe, a
            read-only file, its folder is missing or not writable (a file is created there and
            removed to find out), or its ending is not one of ``suffixes``.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise OutputError(f"{path}: a loop of symbolic links, not a file to write") from None
        if exc.errno == errno.ENOTDIR:
            raise OutputError(f"{path}: a file stands where its folder should be") from None
        raise OutputError(f"{path}: cannot write it ({exc.strerror or exc})") from None
    except ValueError as exc:  # a NUL byte in the name
        raise OutputError(f"{path!r}: not a file name ({exc})") from None
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{path}: is a folder, not a file")
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"{path}: not a regular file (a device or a pipe); carbody writes whole files")
        if not os.access(path, os.W_OK):
            raise OutputError(f"{path}: is read-only; not replacing it")
    folder = Path(os.path.abspath(path)).parent
    if not folder.is_dir():
        raise OutputError(f"{path}: its folder {folder} does not exist")
    if suffixes and path.suffix.lower() not in suffixes:
        raise OutputError(f"{path}: {_KINDS.get(suffixes, 'a file')} is written here as {' / '.join(suffixes)}, "
                          f"not {path.suffix or 'a file without an ending'}")
    try:
        with held(), tempfile.NamedTemporaryFile(dir=folder, prefix=STAGING_PREFIX, suffix=".probe"):
            pass  # (made and removed whole: a stop signal waits until it is gone)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {folder} ({exc.strerror or exc})") from None
    return path


def _same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two paths name one file (through symbolic links and hard links too)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_distinct(outputs: dict[str, str | Path | None]) -> None:
    """Refuse two outputs of one command given the same file ({option: path}; None: not asked
    for): the second would silently replace the first.

    Raises:
        OutputError: naming the file and both options.
    """
    given = [(option, path) for option, path in outputs.items() if path is not None]
    for i, (option, path) in enumerate(given):
        for other, earlier in given[:i]:
            if _same_file(path, earlier):
                raise OutputError(f"{path}: given for both {other} and {option}; each output needs its own file")


def check_not_inputs(outputs: dict[str, str | Path | None], inputs: dict[str, str | Path | None]) -> None:
    """Refuse an output that is one of the command's inputs ({what: path}; None: none): writing
    it would replace what the command reads (the photo under ``--overlay``).

    Raises:
        OutputError: naming the file, the output and the input.
    """
    for option, path in outputs.items():
        for what, source in inputs.items():
            if path is not None and source is not None and _same_file(path, source):
                raise OutputError(f"{path}: {option} would overwrite {what}, one of this command's inputs")


@contextlib.contextmanager
def output_folder(path: str | Path) -> Iterator[Path]:
    """Create the folder ``path`` (and its missing parents) for a run's outputs; when the run
    fails, remove again the folders it created that are still empty. A folder another run has
    written into since is never removed, nor anything in it.

    Raises:
        OutputError: the folder cannot be created.
    """
    path = Path(path)
    missing = []
    for folder in (path, *path.parents):
        if os.path.isdir(folder):
            break
        missing.append(folder)
    made: list[Path] = []
    ready = False
    try:
        for folder in reversed(missing):  # outermost first
            with held():  # made and noted whole
                try:
                    os.mkdir(folder)
                except FileExistsError:
                    if not os.path.isdir(folder):
                        raise OutputError(f"{path}: cannot create the output folder ({folder} is a file)") from None
                    continue  # made meanwhile by another run: theirs
                made.append(folder)
        ready = True
        yield path
    except BaseException as exc:
        for folder in reversed(made):  # innermost first; stops at the first another run has used
            try:
                os.rmdir(folder)
            except OSError:
                break
        if isinstance(exc, OSError) and not ready:
            raise OutputError(f"{path}: cannot create the output folder ({exc.strerror or exc})") from None
        raise


@contextlib.contextmanager
def staged(targets: Iterable[str | Path], remove: Iterable[str | Path] = ()) -> Iterator[Callable[[str | Path], Path]]:
    """Write a run's files all or nothing.

    Yields ``at(target)``: where to write each target file, in a staging folder
    (``.carbody-*``) made beside it. When the block ends normally every target must have been
    written; they are then moved into place together, and the files ``remove`` names (an
    earlier run's outputs this run does not make: stale beside its own) are taken away with
    them; if one move fails the ones already moved are put back, with the files that were there
    before. When the block fails (a full disk, an interruption), no target is touched. The
    staging folders are removed either way.

    Raises:
        OutputError: a staging folder cannot be made, or a target was not written.
    """
    targets = [Path(t) for t in targets]
    removals = [Path(r) for r in remove if os.path.lexists(r) and Path(r) not in targets]
    stages: dict[str, Path] = {}
    try:
        for target in targets + removals:
            folder = os.path.dirname(os.path.abspath(target))
            if folder not in stages:
                try:
                    with held():  # made and noted whole, so that it is removed
                        stages[folder] = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=folder))
                except OSError as exc:
                    raise OutputError(f"{target}: cannot write in {folder} ({exc.strerror or exc})") from None
        where = {target: stages[os.path.dirname(os.path.abspath(target))] / target.name for target in targets}

        def at(target: str | Path) -> Path:
            return where[Path(target)]

        try:
            yield at
            for target, new in where.items():
                if not new.is_file():
                    raise OutputError(f"{target}: was not written")
            gone = [(r, stages[os.path.dirname(os.path.abspath(r))] / f".removed-{k}") for k, r in enumerate(removals)]
            _move_into_place(list(where.items()), gone)
        except OSError as exc:  # named for the user's file, not the staging folder's
            named = _unstaged(f"{exc.filename}: " if exc.filename else "", stages, targets)
            raise OutputError(f"{named}{(exc.strerror or str(exc)).lower()}") from None
        except CarbodyError as exc:
            text = _unstaged(str(exc), stages, targets)
            if text == str(exc):
                raise
            raise type(exc)(text) from None
    finally:
        for folder in stages.values():
            shutil.rmtree(folder, ignore_errors=True)


def _unstaged(text: str, stages: dict[str, Path], targets: list[Path]) -> str:
    """``text`` with each staging folder's path read as the folder it stages for."""
    for folder, stage in stages.items():
        shown = next((str(t.parent) for t in targets if os.path.dirname(os.path.abspath(t)) == folder), folder)
        text = text.replace(str(stage), shown)
    return text


def _move_into_place(moves: list[tuple[Path, Path]], gone: list[tuple[Path, Path]] = ()) -> None:
    """Rename each staged file onto its target (same folder, so no copy and no new space), the
    previous file kept aside in the staging folder until all are in, and each file of ``gone``
    (file, where it is kept aside) into the staging folder; undone on any failure. A stop signal
    waits until they are all in."""
    with held():
        _move_all(moves, gone)


def _move_all(moves: list[tuple[Path, Path]], gone: list[tuple[Path, Path]] = ()) -> None:
    done: list[tuple[Path, Path | None]] = []
    try:
        for target, aside in gone:
            os.replace(target, aside)
            done.append((target, aside))
        for i, (target, new) in enumerate(moves):
            previous = None
            if os.path.lexists(target):
                previous = new.parent / f".previous-{i}"
                os.replace(target, previous)
            try:
                os.replace(new, target)
            except BaseException:
                if previous is not None:
                    os.replace(previous, target)
                raise
            done.append((target, previous))
    except BaseException:
        for target, previous in reversed(done):
            with contextlib.suppress(OSError):
                if previous is not None:
                    os.replace(previous, target)
                else:
                    os.unlink(target)
        raise
