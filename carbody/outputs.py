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


def check_output_file(path: str | Path, suffixes: tuple[str, ...] | None = None) -> Path:
    """``path`` as a file this process can create or replace.

    Args:
        suffixes: the file name's allowed endings (lower case), or None for any.
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
        raise OutputError(f"{path}: a picture is written here as {' / '.join(suffixes)}, "
                          f"not {path.suffix or 'a file without an ending'}")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=f".{path.name}.", suffix=".probe"):
            pass
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {folder} ({exc.strerror or exc})") from None
    return path
