"""The annotation page in a real browser: headless Chromium (Debian's ``chromium`` and
``chromium-driver``) driven by Selenium with the browser's own mouse and keys."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import REPO

EXAMPLE = REPO / "examples" / "car.png"
EXAMPLE_MARKS = REPO / "examples" / "car_keypoints.json"

#: A click lands within this of the pixel aimed at (the page's scale is about 1 screen px per
#: photo px, and the mouse moves in whole screen pixels).
CLICK_PX = 1.5


def _chromium():
    from carbody.annotate.browser import chromium_available

    return chromium_available()


pytestmark = pytest.mark.skipif(not _chromium(), reason="needs chromium, chromium-driver and selenium (make system-deps)")


@pytest.fixture
def page(tmp_path):
    from carbody.annotate.browser import Page, headless_chromium
    from carbody.annotate.server import AnnotationServer
    from carbody.annotate.session import AnnotationSession

    session = AnnotationSession(EXAMPLE, output=tmp_path / "marks.json", view="front 30")
    server = AnnotationServer(session)
    server.serve_in_thread()
    driver = headless_chromium(1400, 900)
    try:
        yield Page(driver).open(server.url)
    finally:
        driver.quit()
        server.shutdown()
        server.server_close()
        session.close()


def test_clicking_the_examples_marks_ghosts_dragging_accepting_and_saving(page, tmp_path):
    """Click the example's marks for the keypoints the page asks: no ghost before the fifth,
    ghosts for the rest after it; drag a ghost onto its mark, accept the next with Enter, say
    the next is hidden with H, take a mark away with Backspace, save with S: the file holds
    exactly the marks as placed."""
    from selenium.webdriver.common.keys import Keys

    from carbody.fit import read_keypoints

    truth = read_keypoints(EXAMPLE_MARKS).points
    clicked = {}
    for i in range(5):
        state = page.state
        assert not state["fit"]["ok"] if i < 4 else True
        name = state["ask"][0]
        state = page.click_at(*truth[name])
        clicked[name] = truth[name]
        assert np.hypot(*np.subtract(state["marks"][name], truth[name])) < CLICK_PX
    assert state["fit"]["ok"] and len(state["fit"]["ghosts"]) >= 25
    assert page.js("return document.getElementById('fit-summary').textContent").startswith("mean residual")
    page.driver.save_screenshot(str(tmp_path / "after_fifth.png"))

    # the full fit lands (the ghosts stop moving), then one ghost dragged onto its mark
    state = page.wait_refined()
    dragged = state["ask"][0]
    ghost = state["fit"]["ghosts"][dragged]["uv"]
    state = page.drag(ghost, truth[dragged])
    assert np.hypot(*np.subtract(state["marks"][dragged], truth[dragged])) < CLICK_PX
    clicked[dragged] = truth[dragged]

    accepted = state["ask"][0]
    assert page.js("return window.carbody.current") == accepted
    where = state["fit"]["ghosts"][accepted]["uv"]
    state = page.press(Keys.ENTER)
    assert state["marks"][accepted] == pytest.approx(where)

    hidden = state["ask"][0]
    state = page.press("h")
    assert hidden in state["hidden"] and hidden not in state["marks"]

    # select a mark by clicking on it, take it away
    removed = next(iter(clicked))
    page.click_at(*state["marks"][removed], edits=False)
    assert page.js("return window.carbody.current") == removed
    state = page.press(Keys.BACKSPACE)
    assert removed not in state["marks"]
    del clicked[removed]

    page.press("s", changes=False)
    page.wait(lambda: (tmp_path / "marks.json").exists(), 10, "the saved file")
    saved = json.loads((tmp_path / "marks.json").read_text())
    assert saved["image_size"] == [1000, 640] and saved["hidden"] == [hidden]
    assert set(saved["keypoints"]) == set(clicked) | {accepted}
    for name, uv in clicked.items():
        assert np.hypot(*np.subtract(saved["keypoints"][name], uv)) < CLICK_PX, name
    assert saved["keypoints"][accepted] == pytest.approx(where, abs=0.01)
    assert read_keypoints(tmp_path / "marks.json").points.keys() == saved["keypoints"].keys()
    latencies = page.js("return window.carbody.latencies")
    assert any(x["kind"] == "refined" for x in latencies)
