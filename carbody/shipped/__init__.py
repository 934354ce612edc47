"""The files carbody ships beside its code: the template library (``templates_step/``), the
example photo with its keypoints and true wireframe (``examples/``) and the FreeCAD workbench
(``workbench/``).

They live at the repository's top level, where SPEC puts them. The links in this folder put
them inside the package too, so the code finds them in one place whether it runs from a
checkout or from an installed wheel, which carries them as package data (setuptools copies the
files the links point to). Nothing is ever written here at run time.
"""
from __future__ import annotations

from pathlib import Path

_HERE = Path(__file__).resolve().parent

#: The template cars: one wireframe STEP file each, and ``manifest.json``.
TEMPLATES = _HERE / "templates_step"

#: The demo's photo (``car.png``), its keypoints (``car_keypoints.json``) and the car's true
#: wireframe (``car_truth.step``).
EXAMPLES = _HERE / "examples"

#: The FreeCAD workbench (``carbody freecad`` runs its headless core).
WORKBENCH = _HERE / "workbench"
