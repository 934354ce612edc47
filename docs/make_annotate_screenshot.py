"""The picture of the annotation page in docs/annotate.md: the example after its fifth mark.

Run:  .venv/bin/python docs/make_annotate_screenshot.py   (writes docs/annotate.png; needs
Chromium and its driver, ``make system-deps``, and selenium, the ``dev`` extras)
"""
from __future__ import annotations

import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent / "examples"


def main() -> None:
    import cv2

    from carbody.annotate.browser import Page, headless_chromium
    from carbody.annotate.server import AnnotationServer
    from carbody.annotate.session import AnnotationSession
    from carbody.fit import read_keypoints

    marks = read_keypoints(EXAMPLES / "car_keypoints.json").points
    with tempfile.TemporaryDirectory() as tmp:
        session = AnnotationSession(EXAMPLES / "car.png", output=Path(tmp) / "marks.json", view="front 30")
        server = AnnotationServer(session)
        server.serve_in_thread()
        driver = headless_chromium(1400, 860)
        try:
            page = Page(driver).open(server.url)
            for _ in range(5):  # the five keypoints the page asks first, clicked where they are
                page.click_at(*marks[page.state["ask"][0]])
            page.wait_refined()
            shot = Path(tmp) / "page.png"
            driver.save_screenshot(str(shot))
        finally:
            driver.quit()
            server.shutdown()
            session.close()
        image = cv2.imread(str(shot))
        cv2.imwrite(str(HERE / "annotate.png"), image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {HERE / 'annotate.png'}")


if __name__ == "__main__":
    main()
