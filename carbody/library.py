"""The model library (paper II.E): normalised templates expanded by axis scalings into S.

Each template is normalised so its front wheel centre is (y, z) = (0, 0) and its rear wheel
centre (1000, 0); x scales by the same factor. Expansion, as the paper does it (models per
template; the paper's 14 templates give 84 -> 588 -> 3528, however many the manifest lists):

1. heights: z of points above the wheel-centre line x {0.7, 0.8, 0.9, 1.1, 1.2}   (1 -> 6)
2. overhangs: the front overhang x {0.8, 0.9, 1.1} and, separately, the rear    (6 -> 42)
   overhang x {0.8, 0.9, 1.1}, each about its own boundary point (the front of the front
   wheel arch, the rear of the rear one), so curves stay joined
3. widths: all x x {0.7, 0.8, 0.9, 1.1, 1.2}                                    (42 -> 252)

Every scaling is a continuous map of space, so curve ends that coincide before still coincide
after. The shape matrix S is (3 x 280, N) = (840, N): column j is model j's shape vector
(x1, y1, z1, ..., x280, y280, z280). S is cached on disk, keyed by the template files' bytes and
the expansion factors, and rebuilt when either changes.
"""
from __future__ import annotations

import functools

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from carbody.errors import LibraryError
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import Topology, load_topology
from carbody.wireframe import wheel_centre

#: Cache format version: bump when the normalisation or expansion code changes meaning.
CACHE_VERSION = 1


@dataclass(frozen=True)
class Expansion:
    """Scale factors of the three expansion steps (the original, factor 1, is always kept)."""

    height: tuple[float, ...] = (0.7, 0.8, 0.9, 1.1, 1.2)
    front_overhang: tuple[float, ...] = (0.8, 0.9, 1.1)
    rear_overhang: tuple[float, ...] = (0.8, 0.9, 1.1)
    width: tuple[float, ...] = (0.7, 0.8, 0.9, 1.1, 1.2)

    @property
    def models_per_template(self) -> int:
        return ((1 + len(self.height)) * (1 + len(self.front_overhang) + len(self.rear_overhang))
                * (1 + len(self.width)))


@dataclass
class Library:
    """N library models in normalised units.

    Attributes:
        S: (840, N) float, normalised shape vectors as columns.
        template_names: the templates, in order.
        template_index: (N,) int, each model's template.
        factors: (N, 4) float, each model's (height, front overhang, rear overhang, width) factor.
        template_wheelbase_mm: (T,) float, each template's real wheelbase.
    """

    S: np.ndarray
    template_names: list[str]
    template_index: np.ndarray
    factors: np.ndarray
    template_wheelbase_mm: np.ndarray
    template_classes: list[str] = field(default_factory=list)

    @property
    def digest(self) -> str | None:
        """What identifies the contents: :func:`load_library`'s cache key for a library it
        loaded, None for any other (built, ``without`` some templates, a ``dataclasses.replace``
        copy). The fit stores the preparations of a library with a digest on disk
        (:mod:`carbody.fit.prepared_store`)."""
        return self.__dict__.get("_digest")

    @property
    def n_models(self) -> int:
        return self.S.shape[1]

    @property
    def model_wheelbase_mm(self) -> np.ndarray:
        """(N,) float: the real wheelbase of each model (its template's)."""
        return self.template_wheelbase_mm[self.template_index]

    def points(self, j: int) -> np.ndarray:
        """(280, 3) normalised control points of model ``j``."""
        return self.S[:, j].reshape(-1, 3)

    def original(self, template: str | int) -> int:
        """The column of a template's own model (every expansion factor 1), by name or index."""
        t = self.template_names.index(template) if isinstance(template, str) else int(template)
        return int(np.flatnonzero((self.template_index == t) & np.all(self.factors == 1.0, axis=1))[0])

    def without(self, *templates: str) -> "Library":
        """This library less the templates named and all their expansions (leave-one-out)."""
        for template in templates:
            if template not in self.template_names:
                raise LibraryError(f"unknown template {template!r} (known: {', '.join(self.template_names)})")
        drop = [i for i, n in enumerate(self.template_names) if n in templates]
        keep = ~np.isin(self.template_index, drop)
        remap = np.cumsum([i not in drop for i in range(len(self.template_names))]) - 1
        return Library(
            S=self.S[:, keep],
            template_names=[n for i, n in enumerate(self.template_names) if i not in drop],
            template_index=remap[self.template_index[keep]],
            factors=self.factors[keep],
            template_wheelbase_mm=np.delete(self.template_wheelbase_mm, drop),
            template_classes=[c for i, c in enumerate(self.template_classes) if i not in drop],
        )


def check_library(library) -> None:
    """Refuse anything but a :class:`Library` (or None: the shipped one) where one is asked for.

    Raises:
        LibraryError: naming what was given.
    """
    if library is not None and not isinstance(library, Library):
        raise LibraryError(f"library must be a carbody.library.Library, got a {type(library).__name__}")


def normalise(points_mm: np.ndarray, topology: Topology | None = None) -> np.ndarray:
    """Move, level and scale a wireframe so its wheel centres are (0, 0) and (1000, 0).

    Args:
        points_mm: (280, 3) float, mm, car frame.
    Returns:
        (280, 3) float, normalised units (x scaled by the same factor as y and z).
    """
    topo = topology or load_topology()
    front = wheel_centre(points_mm, topo, "front")
    rear = wheel_centre(points_mm, topo, "rear")
    axis = rear - front
    wheelbase = float(np.hypot(*axis))
    if wheelbase <= 0:
        raise LibraryError("wheel centres coincide: cannot normalise")
    c, s = axis / wheelbase
    rot = np.array([[c, s], [-s, c]])  # rotates the wheel axis onto +y in the yz plane
    out = np.empty_like(points_mm, dtype=float)
    scale = NORMALISED_WHEELBASE / wheelbase
    out[:, 0] = points_mm[:, 0] * scale
    out[:, 1:] = (points_mm[:, 1:] - front) @ rot.T * scale
    return out


def expand(models: np.ndarray, expansion: Expansion = Expansion(), topology: Topology | None = None):
    """Expand normalised models by the paper's three scalings.

    Args:
        models: (T, 280, 3) float, normalised.
    Returns:
        (points (T * M, 280, 3), template index (T * M,), factors (T * M, 4)); M per template.
    """
    topo = topology or load_topology()
    front_b = topo.junction_point_index(topo.overhang_boundaries["front"])
    rear_b = topo.junction_point_index(topo.overhang_boundaries["rear"])
    out, index, factors = [], [], []
    for t, base in enumerate(models):
        for fz in (1.0, *expansion.height):
            tall = base.copy()
            tall[:, 2] = np.where(tall[:, 2] > 0, tall[:, 2] * fz, tall[:, 2])
            y_front, y_rear = tall[front_b, 1], tall[rear_b, 1]
            overhangs = [(1.0, 1.0)] + [(f, 1.0) for f in expansion.front_overhang] + \
                        [(1.0, f) for f in expansion.rear_overhang]
            for ff, fr in overhangs:
                long = tall.copy()
                y = long[:, 1]
                long[:, 1] = np.where(y < y_front, y_front + ff * (y - y_front),
                                      np.where(y > y_rear, y_rear + fr * (y - y_rear), y))
                for fx in (1.0, *expansion.width):
                    wide = long.copy()
                    wide[:, 0] *= fx
                    out.append(wide)
                    index.append(t)
                    factors.append((fz, ff, fr, fx))
    return np.array(out), np.array(index), np.array(factors)


def cache_dir() -> Path | None:
    """Where S is cached, and the fit's preparations of it (:mod:`carbody.fit.prepared_store`):
    ``$CARBODY_CACHE_DIR`` or ``~/.cache/carbody``; None when there is no home folder to put it
    in (both are then built in memory each run)."""
    env = os.environ.get("CARBODY_CACHE_DIR")
    if env:
        return Path(env)
    try:
        return Path.home() / ".cache" / "carbody"
    except RuntimeError:  # no $HOME and no user entry to find one
        return None


def _cache_key(folder: Path, rows: list[dict], expansion: Expansion) -> str:
    digest = hashlib.sha256(f"v{CACHE_VERSION}|{expansion}".encode())
    digest.update((folder / "manifest.json").read_bytes())
    for row in rows:
        digest.update((folder / row["file"]).read_bytes())
    return digest.hexdigest()[:20]


def build_library(folder: str | Path | None = None, expansion: Expansion = Expansion()) -> Library:
    """Read the templates' STEP files, normalise and expand them (no cache)."""
    from carbody.templates import load_templates, templates_dir

    topo = load_topology()
    templates = load_templates(folder or templates_dir())
    if not templates:
        raise LibraryError("the template manifest lists no templates")
    base = np.array([normalise(w.control_points, topo) for _, w in templates])
    points, index, factors = expand(base, expansion, topo)
    wheelbases = np.array([w.measure()["wheelbase_mm"] for _, w in templates])
    return Library(
        S=np.ascontiguousarray(points.reshape(len(points), -1).T),
        template_names=[row["name"] for row, _ in templates],
        template_index=index,
        factors=factors,
        template_wheelbase_mm=wheelbases,
        template_classes=[row["class"] for row, _ in templates],
    )


@functools.cache
def default_library() -> "Library":
    """The shipped library, loaded once per process (the fit keeps its shape models per library
    object, so one object for the whole process spares rebuilding them)."""
    return load_library()


def load_library(folder: str | Path | None = None, expansion: Expansion = Expansion(),
                 use_cache: bool = True) -> Library:
    """The library, from the disk cache when the templates and factors are unchanged.

    Args:
        folder: template folder (default :func:`carbody.templates.templates_dir`).
        expansion: scale factors of the expansion.
        use_cache: read and write the cache in :func:`cache_dir`.
    """
    from carbody.templates import load_manifest, templates_dir

    folder = Path(folder) if folder else templates_dir()
    if not use_cache:
        return build_library(folder, expansion)
    key = _cache_key(folder, load_manifest(folder), expansion)
    cache = cache_dir()
    path = None if cache is None else cache / f"library-{key}.npz"
    cached = _read_cache(path) if path is not None else None
    lib = cached if cached is not None else build_library(folder, expansion)
    if cached is None and path is not None:
        _write_cache(path, lib)
    lib._digest = key
    return lib


def _read_cache(path: Path) -> Library | None:
    """The library cached at ``path``, or None when there is none or it is damaged (truncated,
    not an archive, arrays missing or of the wrong shape): it is then rebuilt."""
    try:
        with np.load(path, allow_pickle=False) as z:
            lib = Library(S=z["S"], template_names=[str(n) for n in z["template_names"]],
                          template_index=z["template_index"], factors=z["factors"],
                          template_wheelbase_mm=z["template_wheelbase_mm"],
                          template_classes=[str(c) for c in z["template_classes"]])
    except Exception:  # none yet, or a damaged file (which fails in numpy's or zipfile's own ways)
        return None
    n, t = lib.S.shape[1], len(lib.template_names)
    sound = (lib.S.shape[0] == 3 * load_topology().n_points and lib.template_index.shape == (n,)
             and lib.factors.shape == (n, 4) and lib.template_wheelbase_mm.shape == (t,)
             and len(lib.template_classes) == t and n > 0 and np.isfinite(lib.S).all()
             and lib.template_index.min() >= 0 and lib.template_index.max() < t)
    return lib if sound else None


def _write_cache(path: Path, lib: Library) -> None:
    """Cache ``lib`` at ``path`` (:func:`write_cache_file`): the next run that cannot read it
    builds the library again."""
    write_cache_file(path, S=lib.S, template_names=np.array(lib.template_names), template_index=lib.template_index,
                     factors=lib.factors, template_wheelbase_mm=lib.template_wheelbase_mm,
                     template_classes=np.array(lib.template_classes))


def write_cache_file(path: Path, **arrays: np.ndarray) -> None:
    """Write a cache's arrays to ``path`` (.npz) whole, then rename it into place, so a reader
    never sees half of it; a cache that cannot be written (a read-only or full disk, no home
    folder) is skipped."""
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    except OSError:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
