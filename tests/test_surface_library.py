"""Library models (not only templates) surface into valid shells: the squashed low-roof variants
once left a junction rib slid off its junction by the keep-inside step."""
from __future__ import annotations

import pytest


@pytest.mark.parametrize("model", [42, 77, 2058, 2079, 1000, 3000])
def test_library_models_surface_into_one_valid_shell(library, model):
    from carbody.surface import build_body
    from carbody.wireframe import Wireframe

    scale = library.model_wheelbase_mm[model] / 1000.0
    body = build_body(Wireframe(f"model {model}", library.points(model) * scale))
    shell = body.report["shell"]
    assert shell["valid"] and shell["free_closed_loops"] == 1 and shell["free_open_wires"] == 0


@pytest.mark.parametrize("template, factors", [
    ("Toyota HiAce H200", (0.7, 1.0, 1.0, 0.7)),  # a van squashed to a low, narrow box
    ("Daihatsu Hijet Cargo S321V", (1.2, 1.0, 1.1, 1.2)),  # the kei van stretched every way
    ("Toyota Hilux AN120 Single Cab", (0.7, 1.0, 0.8, 1.2)),  # a low cab on a long bed
])
def test_the_extremes_of_boxy_and_long_bodies_surface_too(library, template, factors):
    import numpy as np

    from carbody.surface import build_body
    from carbody.wireframe import Wireframe

    t = library.template_names.index(template)
    model = int(np.flatnonzero((library.template_index == t) & np.all(library.factors == factors, axis=1))[0])
    scale = library.model_wheelbase_mm[model] / 1000.0
    body = build_body(Wireframe(f"{template} {factors}", library.points(model) * scale))
    shell = body.report["shell"]
    assert shell["valid"] and shell["free_closed_loops"] == 1 and shell["free_open_wires"] == 0
