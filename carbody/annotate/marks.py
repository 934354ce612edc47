"""The marks of one photo as the page edits them, and the files they are saved to.

A :class:`MarkSheet` holds the marks placed (``{name: (u, v)}`` photo pixels), the names the
user said the photo does not show (``hidden``), and the marks a file brought in: a mark loaded
and never moved is written back with the very numbers it was read with (an integer stays an
integer), and the file's other fields (``source``, ``car``, notes …) are kept. It writes the
project's JSON (``{"image", "image_size", "keypoints", "hidden"}``) and, on request, COCO
keypoints; both atomically (never a half-written file).
"""
from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from carbody.errors import KeypointError, OutputError

#: Fields of the project's JSON the sheet writes itself; any other field of a loaded file is kept.
OWN_FIELDS = ("image", "image_size", "keypoints", "hidden")


@dataclass
class MarkSheet:
    """The marks of one photo (module docstring).

    Attributes:
        image: the photo's file name as the saved file names it.
        image_size: (width, height) px.
        marks: {name: (u, v)} photo pixels, in the order placed (loaded ones first).
        hidden: names marked as not shown by the photo.
        loaded: {name: the [u, v] exactly as the loaded file had it}, for marks not moved since.
        extra: the loaded file's other fields, written back unchanged.
        from_project_json: the marks came from a file in the project's JSON (not COCO, labelme).
    """

    image: str
    image_size: tuple[int, int]
    marks: dict[str, tuple[float, float]] = field(default_factory=dict)
    hidden: set[str] = field(default_factory=set)
    loaded: dict[str, list] = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    from_project_json: bool = False

    @classmethod
    def load(cls, path: str | Path, image: str, image_size: tuple[int, int]) -> "MarkSheet":
        """The marks of a keypoint file (the project's JSON, COCO or labelme), checked against
        the photo (its size, names the fit knows, marks on the image).

        Raises:
            KeypointError: unreadable file, another image size, an unknown name, a mark off the
                photo.
        """
        from carbody.fit.keypoints_io import check_image_size, read_keypoints

        path = Path(path)
        ann = read_keypoints(path)
        check_image_size(ann, image_size)
        raw = json.loads(path.read_text())
        sheet = cls(image, tuple(image_size))
        own = raw.get("keypoints") if isinstance(raw, dict) and isinstance(raw.get("keypoints"), dict) else {}
        for name, uv in ann.points.items():
            sheet.place(name, uv)
            # the numbers as written, when the file is the project's JSON (else as read)
            original = own.get(name)
            sheet.loaded[name] = list(original[:2]) if isinstance(original, list) else [uv[0], uv[1]]
        if isinstance(raw, dict) and isinstance(raw.get("keypoints"), dict):
            sheet.from_project_json = True
            sheet.extra = {k: v for k, v in raw.items() if k not in OWN_FIELDS}
            hidden = raw.get("hidden") or []
            sheet.hidden = {n for n in hidden if isinstance(n, str) and n not in sheet.marks}
            _check_names(sheet.hidden, path)
        return sheet

    def place(self, name: str, uv: tuple[float, float]) -> None:
        """Put ``name``'s mark at ``uv`` (moving it if placed; a hidden name is shown again).

        Raises:
            KeypointError: an unknown name or a mark off the photo.
        """
        _check_names([name])
        u, v = (float(c) for c in uv)
        w, h = self.image_size
        if not (0 <= u <= w and 0 <= v <= h):
            raise KeypointError(f"keypoint {name!r} at ({u:g}, {v:g}) lies outside the {w} x {h} image")
        if self.marks.get(name) != (u, v):
            self.loaded.pop(name, None)
        self.marks[name] = (u, v)
        self.hidden.discard(name)

    def remove(self, name: str) -> None:
        """Take ``name``'s mark (or its hidden flag) away."""
        self.marks.pop(name, None)
        self.loaded.pop(name, None)
        self.hidden.discard(name)

    def hide(self, name: str) -> None:
        """Mark ``name`` as not shown by the photo (its mark, if any, removed)."""
        _check_names([name])
        self.remove(name)
        self.hidden.add(name)

    def keypoints_json(self) -> dict[str, list]:
        """{name: [u, v]} as saved: loaded marks not moved with their numbers as read."""
        return {n: self.loaded.get(n, [round(u, 2), round(v, 2)]) for n, (u, v) in self.marks.items()}

    def project_json(self) -> dict:
        """The project's keypoint JSON (what ``carbody reconstruct -k`` reads)."""
        return {**self.extra, "image": self.image, "image_size": list(self.image_size),
                "keypoints": self.keypoints_json(), "hidden": sorted(self.hidden)}

    def coco_json(self) -> dict:
        """COCO keypoints: one category listing every markable name, one annotation (flag 2 for
        a mark; 0, not labelled, for the rest and the hidden ones)."""
        from carbody.fit import keypoint_slots

        names = list(keypoint_slots())
        marks = self.keypoints_json()
        flat: list = []
        for n in names:
            flat += [*marks[n], 2] if n in marks else [0, 0, 0]
        us = [p[0] for p in marks.values()] or [0]
        vs = [p[1] for p in marks.values()] or [0]
        w, h = self.image_size
        return {"images": [{"id": 1, "file_name": self.image, "width": w, "height": h}],
                "categories": [{"id": 1, "name": "car", "keypoints": names}],
                "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "keypoints": flat,
                                 "num_keypoints": len(marks),
                                 "bbox": [min(us), min(vs), max(us) - min(us), max(vs) - min(vs)]}]}

    def save(self, path: str | Path, coco_path: str | Path | None = None) -> list[Path]:
        """Write the project's JSON to ``path`` (and COCO to ``coco_path``); returns the files.

        Raises:
            OutputError: a file that cannot be written.
        """
        written = [write_json(path, self.project_json())]
        if coco_path is not None:
            written.append(write_json(coco_path, self.coco_json()))
        return written


def coco_path_for(path: str | Path) -> Path:
    """Where the COCO file goes beside the project's JSON ``path``: ``NAME.coco.json``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.coco.json")


def _check_names(names, where: str | Path | None = None) -> None:
    from difflib import get_close_matches

    from carbody.fit import keypoint_slots

    known = keypoint_slots()
    for name in names:
        if name not in known:
            close = get_close_matches(str(name), list(known), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise KeypointError(f"{where + ': ' if where else ''}unknown keypoint name {name!r}{hint}")


def check_output(path: str | Path) -> Path:
    """Refuse an output the sheet cannot be saved to, before any work: not ``.json``, a folder, or
    in a folder that does not exist or cannot be written.

    Raises:
        OutputError: naming the file and why.
    """
    path = Path(path)
    if path.suffix.lower() != ".json":
        raise OutputError(f"{path}: the marks are saved as JSON: name the file .json")
    if path.is_dir():
        raise OutputError(f"{path}: is a folder, not a file")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError(f"{path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise OutputError(f"{path}: cannot be written (no permission)")
    return path


def write_json(path: str | Path, data: dict) -> Path:
    """Write ``data`` as JSON to ``path`` atomically."""
    path = check_output(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(suffix=".json", dir=path.parent, prefix=f".{path.stem}.")
        with os.fdopen(fd, "w") as f:
            json.dump(data, f, indent=1)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual mode
        os.replace(tmp, path)
    except OSError as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path
