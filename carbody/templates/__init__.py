"""The template library: real cars as STEP wireframes in ``templates_step/`` with a manifest.

``build_templates`` writes them from the design table (:mod:`carbody.templates.design`);
everything downstream reads the STEP files, so a template edited in another CAD system and saved
back is used as it is.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

from carbody.errors import TemplateError
from carbody.wireframe import Wireframe, read_wireframe

MANIFEST = "manifest.json"


def templates_dir() -> Path:
    """Folder of the template STEP files: ``$CARBODY_TEMPLATES_DIR`` or the shipped one
    (:data:`carbody.shipped.TEMPLATES`, the repository's ``templates_step/``)."""
    from carbody.shipped import TEMPLATES

    env = os.environ.get("CARBODY_TEMPLATES_DIR")
    return Path(env) if env else TEMPLATES


def slug(name: str) -> str:
    """File stem for a car name: ``"Toyota Camry XV70"`` -> ``"toyota_camry_xv70"``."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")


def load_manifest(folder: str | Path | None = None) -> list[dict]:
    """The manifest rows: name, class, published dimensions (mm), file, source."""
    from carbody.inputs import read_json

    folder = Path(folder) if folder else templates_dir()
    path = folder / MANIFEST
    if not path.exists():
        raise TemplateError(f"{path}: no template manifest (run `carbody templates build`)")
    rows = read_json(path, "template manifest", TemplateError)
    fields = ("name", "class", "file")
    if not isinstance(rows, list) or not all(isinstance(r, dict) and all(isinstance(r.get(f), str) for f in fields)
                                             for r in rows):
        raise TemplateError(f"{path}: not a template manifest (a list of cars, each with its "
                            f"{', '.join(fields)} as text)")
    return rows


def find_template(name: str, folder: str | Path | None = None) -> dict:
    """The manifest row of a car, by its name or file stem (case-insensitive)."""
    rows = load_manifest(folder)
    key = slug(name)
    for row in rows:
        if slug(row["name"]) == key or Path(row["file"]).stem == key:
            return row
    raise TemplateError(f"unknown template {name!r} (known: {', '.join(r['name'] for r in rows)})")


def load_template(name: str, folder: str | Path | None = None) -> Wireframe:
    """One template's wireframe, read from its STEP file."""
    folder = Path(folder) if folder else templates_dir()
    return read_wireframe(folder / find_template(name, folder)["file"])


def load_templates(folder: str | Path | None = None) -> list[tuple[dict, Wireframe]]:
    """Every template (manifest row, wireframe); any bad file refuses the whole set."""
    folder = Path(folder) if folder else templates_dir()
    return [(row, read_wireframe(folder / row["file"])) for row in load_manifest(folder)]


def build_templates(out_dir: str | Path, design_table: str | Path | None = None,
                    quiet: bool = False) -> list[dict]:
    """Build every car of the design table and write ``NAME.step`` files and the manifest into
    ``out_dir`` (the repository's is ``templates_step/``; an installed package's own is never
    written), all or nothing (:func:`carbody.outputs.staged`).

    Args:
        quiet: no progress bar.
    Returns:
        the manifest rows written.
    """
    from tqdm import tqdm

    from carbody.outputs import output_folder, staged
    from carbody.progress import bar_disabled
    from carbody.templates.design import load_design_tables

    tables = load_design_tables(design_table)
    with output_folder(out_dir) as out, \
            staged([out / f"{slug(d.name)}.step" for d in tables] + [out / MANIFEST]) as at:
        rows = [_build_one(d, at(out / f"{slug(d.name)}.step"))
                for d in tqdm(tables, desc="carbody templates build", unit="car", disable=bar_disabled(quiet),
                              leave=False)]
        at(out / MANIFEST).write_text(json.dumps(rows, indent=1) + "\n")
    return rows


def _build_one(d, path: Path) -> dict:
    """Build one car of the design table, write its STEP file to ``path``; its manifest row."""
    from carbody.templates.design import build_wireframe
    from carbody.wireframe import write_wireframe

    write_wireframe(path, Wireframe(d.name, build_wireframe(d)))
    return {
        "name": d.name, "class": d.car_class, "file": path.name,
        "length_mm": d.length, "width_mm": d.width, "height_mm": d.height,
        "wheelbase_mm": d.wheelbase, "front_overhang_mm": d.front_overhang,
        "rear_overhang_mm": d.rear_overhang, "track_front_mm": d.track_front,
        "track_rear_mm": d.track_rear, "tyre_radius_mm": d.tyre_radius,
        "ground_clearance_mm": d.ground_clearance, "source": d.source,
    }


def measure_template(row: dict, wireframe: Wireframe) -> dict[str, float]:
    """Length, width, height (above the ground, from the manifest's tyre radius), wheelbase; mm."""
    m = wireframe.measure()
    return {"length_mm": m["length_mm"], "width_mm": m["width_mm"],
            "height_mm": m["top_z_mm"] + row["tyre_radius_mm"], "wheelbase_mm": m["wheelbase_mm"]}
