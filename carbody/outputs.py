"""Output files checked before a command does its work: a path that cannot be written is one
line (:class:`~carbody.errors.OutputError`) before anything is computed or written, not a
traceback after the first files are out."""
from __future__ import annotations

import tempfile
from pathlib import Path

from carbody.errors import OutputError

#: Suffixes of the pictures the commands write (VTK, matplotlib and OpenCV all write PNG).
PICTURE = (".png",)

#: … and of the overlay, drawn with OpenCV, which writes JPEG too.
PHOTO = (".png", ".jpg", ".jpeg")

#: Suffixes of STEP files (the endings CAD programs open as STEP) …
STEP = (".step", ".stp")

#: … and of the JSON reports.
JSON = (".json",)

_KINDS = {PICTURE: "a picture", PHOTO: "a picture", STEP: "a STEP file", JSON: "a JSON report"}


def check_output_file(path: str | Path, suffixes: tuple[str, ...] | None = None) -> Path:
    """``path`` as a file this process can create or replace.

    Args:
        suffixes: the file name's allowed endings (lower case: ``PICTURE``, ``PHOTO``, ``STEP``,
            ``JSON``), or None for any.
    Raises:
        OutputError: the path is a folder, its folder is missing or not writable (a file is
            created there and removed to find out), or its ending is not one of ``suffixes``.
    """
    path = Path(path)
    folder = path.resolve().parent
    if path.is_dir():
        raise OutputError(f"{path}: is a folder, not a file")
    if not folder.is_dir():
        raise OutputError(f"{path}: its folder {folder} does not exist")
    if suffixes and path.suffix.lower() not in suffixes:
        raise OutputError(f"{path}: {_KINDS.get(suffixes, 'a file')} is written here as {' / '.join(suffixes)}, "
                          f"not {path.suffix or 'a file without an ending'}")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=f".{path.name}.", suffix=".probe"):
            pass
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {folder} ({exc.strerror or exc})") from None
    return path


def check_distinct(outputs: dict[str, str | Path | None]) -> None:
    """Refuse two outputs of one command given the same file ({option: path}; None: not asked
    for): the second would silently replace the first.

    Raises:
        OutputError: naming the file and both options.
    """
    seen: dict[Path, str] = {}
    for option, path in outputs.items():
        if path is None:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise OutputError(f"{path}: given for both {seen[key]} and {option}; each output needs its own file")
        seen[key] = option
