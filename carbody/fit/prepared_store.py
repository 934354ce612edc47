"""The fit's per-library preparations kept on disk beside the library's own cache.

The shape models (a covariance of the library and its partial eigendecomposition) and the
displacement fields (eigendecompositions of 840 × 840 kernels) cost about 0.6 s to build, in
every process that fits. They depend only on the library's contents and on the code that
builds them, so they are stored once per library in :func:`carbody.library.cache_dir`, keyed
by the library's digest (:attr:`carbody.library.Library.digest`), the bytes of the modules that
build them and the numpy and scipy versions. A file that cannot be read back whole (truncated,
damaged, of another layout) is rebuilt; one that cannot be written (a read-only or full disk)
is skipped, and the preparation stays in memory for the process.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
from pathlib import Path

import numpy as np

#: Layout version of the stored files: bump when what is stored changes meaning.
STORE_VERSION = 1

#: The modules whose code decides what is stored (relative to the package): any edit to one
#: of them makes new files.
SOURCES = ("fit/solve.py", "fit/shape_prior.py", "fit/deform.py", "topology.py", "data/topology.json")


@functools.cache
def code_digest() -> str | None:
    """A digest of :data:`SOURCES`' bytes, the layout version and the numpy and scipy versions
    (None when the sources cannot be read: nothing is then stored)."""
    from importlib.metadata import version

    import carbody

    root = Path(carbody.__file__).parent
    digest = hashlib.sha256(f"v{STORE_VERSION}|numpy {np.__version__}|scipy {version('scipy')}".encode())
    try:
        for name in SOURCES:
            digest.update((root / name).read_bytes())
    except OSError:
        return None
    return digest.hexdigest()[:20]


def stored_path(library_digest: str | None, what) -> Path | None:
    """Where the preparation ``what`` (a key such as ``"gauss"``) of a library is stored, or
    None when it is not (a library without a digest, no cache folder, unreadable sources)."""
    from carbody.library import cache_dir

    folder, code = cache_dir(), code_digest()
    if library_digest is None or folder is None or code is None:
        return None
    tag = hashlib.sha256(repr(what).encode()).hexdigest()[:12]
    return folder / f"prepared-{library_digest}-{code}-{tag}.npz"


def read_stored(path: Path, what, kinds: dict[str, type]):
    """The preparation stored at ``path``, or None when there is none or it is not whole (it is
    then rebuilt): a numpy array or one of the dataclasses of ``kinds`` (by name) whose fields
    are arrays, floats or None."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["_what"]) != repr(what):
                return None
            kind = str(z["_kind"])
            if kind == "ndarray":
                return z["value"]
            cls = kinds[kind]
            values = {}
            for f in dataclasses.fields(cls):
                if f.name in z.files:
                    value = z[f.name]
                    values[f.name] = float(value) if value.ndim == 0 else value
                else:
                    values[f.name] = None
            return cls(**values)
    except Exception:  # none yet, or a damaged file (numpy's and zipfile's own errors)
        return None


def write_stored(path: Path, what, value) -> None:
    """Store ``value`` at ``path`` (:func:`carbody.library.write_cache_file`: whole or not at
    all), and remove what an earlier version of the code stored for the same library and key
    (:func:`stored_path`: the same name but for the code's digest), which nothing reads again."""
    from carbody.library import write_cache_file

    if isinstance(value, np.ndarray):
        arrays = {"_kind": np.array("ndarray"), "value": value}
    else:
        arrays = {"_kind": np.array(type(value).__name__)}
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            if v is not None:
                arrays[f.name] = np.asarray(v)
    arrays["_what"] = np.array(repr(what))
    write_cache_file(path, **arrays)
    prefix, _, tag = path.name.rsplit("-", 2)
    for old in path.parent.glob(f"{prefix}-*-{tag}"):
        if old != path:
            old.unlink(missing_ok=True)
