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
