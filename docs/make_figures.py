"""Regenerate the README's pictures from the shipped example and a template.

Run:  .venv/bin/python docs/make_figures.py   (writes docs/*.png)
"""
from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent / "examples"


def main() -> None:
    import cv2

    import carbody
    from carbody.render import render_views
    from carbody.templates import load_template
    from carbody.templates.drawing import draw_four_views

    result = carbody.reconstruct(EXAMPLES / "car.png", EXAMPLES / "car_keypoints.json", view=30)
    out = result.write(HERE / "example_out")
    overlay = cv2.imread(str(out["overlay"]))
    cv2.imwrite(str(HERE / "overlay.png"), cv2.resize(overlay, (700, 448), interpolation=cv2.INTER_AREA))
    render_views(result.body, HERE / "body.png", size=(360, 250))
    wf = load_template("Toyota Camry XV70")
    draw_four_views(wf.control_points, HERE / "keypoints.png", f"keypoints on the {wf.name} template")
    for p in (HERE / "example_out").iterdir():
        p.unlink()
    (HERE / "example_out").rmdir()
    print(f"wrote overlay.png, body.png, keypoints.png to {HERE}")


if __name__ == "__main__":
    main()
