"""The fit's per-library preparations on disk: read back unchanged, rebuilt when damaged or when
the library or the code changes, skipped where nothing can be written."""
import dataclasses

import numpy as np
import pytest

from carbody.fit import prepared_store
from carbody.fit.prepared_store import code_digest, stored_path
from carbody.fit.shape_prior import prepared, prepared_field
from carbody.library import load_library


def _fresh(library):
    """The library loaded again, as a new process would (the memory cache is keyed by the S
    array; the disk store by the digest)."""
    return load_library()


def _same(a, b) -> bool:
    return all(np.array_equal(getattr(a, f.name), getattr(b, f.name)) if getattr(a, f.name) is not None
               else getattr(b, f.name) is None for f in dataclasses.fields(a))


def test_the_shape_model_is_stored_once_and_rebuilt_when_damaged(library, tmp_path, monkeypatch):
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(tmp_path))
    built = prepared(_fresh(library), "mixture", field=False)
    files = list(tmp_path.glob("prepared-*.npz"))
    assert len(files) == 1 and library.digest in files[0].name
    read = prepared(_fresh(library), "mixture", field=False)
    assert read is not built and _same(read, built)
    files[0].write_bytes(files[0].read_bytes()[:1000])  # a truncated file
    rebuilt = prepared(_fresh(library), "mixture", field=False)
    assert _same(rebuilt, built)
    assert _same(prepared(_fresh(library), "mixture", field=False), built)  # written whole again


def test_the_deformation_fields_come_back_unchanged(library, tmp_path, monkeypatch):
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(tmp_path))
    built = prepared(_fresh(library), "mixture"), prepared_field(_fresh(library))
    read = prepared(_fresh(library), "mixture"), prepared_field(_fresh(library))
    assert all(_same(a, b) for a, b in zip(read, built))
    assert len(list(tmp_path.glob("prepared-*.npz"))) == 3  # shape model, joint field, deformation field


def test_the_store_is_keyed_on_the_library_and_the_code(library, monkeypatch):
    path = stored_path(library.digest, "gauss")
    assert path is not None and path != stored_path(library.digest, "sized")
    assert stored_path("another library", "gauss") != path
    assert library.without(library.template_names[0]).digest is None  # kept in memory only
    assert dataclasses.replace(library, S=library.S * 1.1).digest is None
    assert stored_path(None, "gauss") is None
    monkeypatch.setattr(prepared_store, "SOURCES", prepared_store.SOURCES[1:])  # other code
    code_digest.cache_clear()
    try:
        assert stored_path(library.digest, "gauss") != path
    finally:
        monkeypatch.undo()
        code_digest.cache_clear()
    assert stored_path(library.digest, "gauss") == path


def test_a_cache_folder_that_cannot_be_written_is_skipped(library, tmp_path, monkeypatch):
    blocked = tmp_path / "a file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(blocked / "cache"))
    model = prepared(_fresh(library), "mixture", field=False)
    assert model.basis.shape[0] == library.S.shape[0]
    assert blocked.read_text() == "not a folder"


@pytest.mark.parametrize("damage", [b"", b"PK\x03\x04 not a zip", None])
def test_a_damaged_or_foreign_file_reads_as_none(tmp_path, damage):
    from carbody.fit.solve import ShapeModel

    path = tmp_path / "prepared.npz"
    if damage is None:  # whole, but of another preparation
        np.savez(path, _kind=np.array("ndarray"), _what=np.array("'other'"), value=np.zeros(3))
    else:
        path.write_bytes(damage)
    assert prepared_store.read_stored(path, "gauss", {"ShapeModel": ShapeModel}) is None


def test_a_new_store_removes_what_older_code_stored_for_the_same_library_and_key(library, tmp_path, monkeypatch):
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(tmp_path))
    path = stored_path(library.digest, "gauss")
    lib, code, tag = path.name.removeprefix("prepared-").rsplit("-", 2)
    older = tmp_path / f"prepared-{lib}-{'0' * len(code)}-{tag}"
    other_key = tmp_path / f"prepared-{lib}-{'0' * len(code)}-{'1' * 12}.npz"
    other_library = tmp_path / f"prepared-another-{'0' * len(code)}-{tag}"
    for p in (older, other_key, other_library):
        p.write_bytes(b"stored by older code")
    prepared_store.write_stored(path, "gauss", np.arange(3.0))
    assert path.is_file() and not older.exists()
    assert other_key.exists() and other_library.exists()
