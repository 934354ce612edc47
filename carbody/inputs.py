"""Input files checked before a command reads them: a path that is missing, a folder, a symbolic
link loop, a device or larger than any such file is one line naming it (the caller's
:class:`~carbody.errors.CarbodyError` subclass), before anything is parsed.

JSON inputs (keypoint files, the template manifest) are read here too: UTF-8 with or without a
byte-order mark, a name given twice in one object refused (JSON would keep the last silently),
nesting too deep for the parser refused in one line.
"""
from __future__ import annotations

import errno
import json
import os
import stat
from pathlib import Path
from typing import Any

from carbody.errors import CarbodyError

#: The largest JSON input read, bytes. A keypoint file of one car is a few kB and a COCO file
#: of thousands of annotated photos a few MB; anything larger is not one (and parsing it would
#: take the time and memory of a file that size).
MAX_JSON_BYTES = 32 * 2**20

#: The largest STEP input read, bytes: a carbody body is about 1 MB; a file a hundred times that
#: is no car wireframe or body, and OCCT would take minutes and gigabytes to read it.
MAX_STEP_BYTES = 100 * 2**20

#: The largest view-classifier weights file read, bytes (the shipped MobileNetV2 is 4.5 MB).
MAX_WEIGHTS_BYTES = 512 * 2**20


def input_file(path: str | Path, what: str, error: type[CarbodyError],
               max_bytes: int | None = None) -> Path:
    """``path`` as a regular file that can be opened for reading.

    Args:
        what: what the file should be, for the message ("keypoint file", "image file").
        error: the exception class to raise.
        max_bytes: refuse a larger file (by its size on disk, before reading it).
    Raises:
        error: missing, a folder, a symbolic link loop, not a regular file (a device such as
            /dev/zero, a pipe), unreadable, or larger than ``max_bytes``.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise error(f"{path}: a loop of symbolic links, not {_a(what)}") from None
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            raise error(f"{path}: no such {what}") from None
        raise error(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    except ValueError as exc:  # a NUL byte in the name
        raise error(f"{path!r}: not a file name ({exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{path}: is a folder, not {_a(what)}")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: not a regular file (a device or a pipe), not {_a(what)}")
    if max_bytes is not None and st.st_size > max_bytes:
        raise error(f"{path}: {st.st_size / 2**20:.0f} MB is larger than any {what} "
                    f"({max_bytes / 2**20:.0f} MB at most)")
    if not os.access(path, os.R_OK):
        raise error(f"{path}: cannot read the {what} (permission denied)")
    return path


def _a(noun: str) -> str:
    return ("an " if noun[:1] in "aeiou" else "a ") + noun


def read_json(path: str | Path, what: str, error: type[CarbodyError], max_bytes: int = MAX_JSON_BYTES) -> Any:
    """The JSON data of an input file (:func:`input_file` first).

    Raises:
        error: as :func:`input_file`; not UTF-8, not JSON, nested too deeply, or a name given
            twice in one object.
    """
    path = input_file(path, what, error, max_bytes)

    def unique(pairs: list) -> dict:  # JSON keeps the last of a name given twice: say so instead
        data = dict(pairs)
        if len(data) < len(pairs):
            seen: set = set()
            twice = next(k for k, _ in pairs if k in seen or seen.add(k))
            raise error(f"{path}: {twice!r} is given twice in one object (which is meant?)")
        return data

    try:
        text = path.read_bytes().decode("utf-8-sig")  # a byte-order mark, as Windows editors write, is no content
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: the {what} is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        return json.loads(text, object_pairs_hook=unique)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: the {what} is not JSON ({exc.msg}, line {exc.lineno} column {exc.colno})") from None
    except RecursionError:
        raise error(f"{path}: the {what} is nested too deeply to be one") from None
