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


def clear_of_others(page, state, name: str, px: float = 14.0) -> bool:
    """The ghost of ``name`` is further than ``px`` on the screen from every other ghost and mark,
    so a press on it takes it."""
    others = [g["uv"] for n, g in state["fit"]["ghosts"].items() if n != name] + list(state["marks"].values())
    here = np.array(page.client_xy(*state["fit"]["ghosts"][name]["uv"]))
    return all(np.hypot(*(np.array(page.client_xy(*uv)) - here)) > px for uv in others)


def test_clicking_the_examples_marks_ghosts_dragging_accepting_and_saving(page, tmp_path):
    """Click the example's marks for the keypoints the page asks: no ghost before the fifth,
    ghosts for the rest after it; drag a ghost onto its mark, then another ghost (not the one
    asked: its name shows under the pointer), accept the next with Enter, say
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

    # any ghost, not only the one asked: the one furthest off its mark, named under the pointer,
    # dragged onto the mark; the page goes on asking what it asked
    state = page.wait_refined()
    off = {n: float(np.hypot(*np.subtract(g["uv"], truth[n]))) for n, g in state["fit"]["ghosts"].items()
           if n in truth and n != state["ask"][0] and clear_of_others(page, state, n)}
    furthest = max(off, key=off.get)
    assert page.hover(*state["fit"]["ghosts"][furthest]["uv"]) == furthest
    state = page.drag(state["fit"]["ghosts"][furthest]["uv"], truth[furthest])
    assert np.hypot(*np.subtract(state["marks"][furthest], truth[furthest])) < CLICK_PX
    assert furthest not in state["ask"]
    clicked[furthest] = truth[furthest]

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


def test_loaded_marks_next_previous_picking_and_zooming(tmp_path):
    """Marks loaded with -k appear as placed and are saved as read; N and P step through the
    keypoints asked; one picked from the list is placed by the next click on the photo (a hidden
    one too); the wheel zooms about the pointer, and a click on the zoomed photo still lands on
    the pixel aimed at."""
    from selenium.webdriver.support.ui import Select

    from carbody.annotate.browser import Page, headless_chromium
    from carbody.annotate.server import AnnotationServer
    from carbody.annotate.session import AnnotationSession
    from carbody.fit import read_keypoints

    truth = read_keypoints(EXAMPLE_MARKS).points
    loaded = {n: [round(u), round(v)] for n, (u, v) in list(truth.items())[:3]}
    source = tmp_path / "start.json"
    source.write_text(json.dumps({"image": "car.png", "image_size": [1000, 640], "keypoints": loaded,
                                  "note": "kept"}))
    session = AnnotationSession(EXAMPLE, keypoints=source, view="front 30", full_fits=False)
    server = AnnotationServer(session)
    server.serve_in_thread()
    driver = headless_chromium(1400, 900)
    try:
        page = Page(driver).open(server.url)
        state = page.state
        assert state["marks"] == {n: [float(u), float(v)] for n, (u, v) in loaded.items()}
        assert page.js("return window.carbody.current") == state["ask"][0]

        page.press("n", changes=False)
        assert page.js("return window.carbody.current") == state["ask"][1]
        page.press("n", changes=False)
        page.press("p", changes=False)
        assert page.js("return window.carbody.current") == state["ask"][1]

        hidden = state["ask"][0]
        page.press("p", changes=False)
        state = page.press("h")
        assert hidden in state["hidden"] and hidden not in state["ask"]
        Select(driver.find_element("id", "pick")).select_by_value(hidden)  # picked again
        assert page.js("return window.carbody.current") == hidden

        scale = page.js("return window.carbody.view.scale")
        x, y = page.client_xy(*truth[hidden])
        page.js("""const c = document.getElementById('photo');  // three notches of the wheel, at the keypoint
                   for (let i = 0; i < 3; i++) c.dispatchEvent(new WheelEvent('wheel', {deltaY: -120,
                     clientX: arguments[0], clientY: arguments[1], bubbles: true, cancelable: true}));""", x, y)
        assert page.js("return window.carbody.view.scale") > 1.5 * scale
        assert np.hypot(*np.subtract(page.client_xy(*truth[hidden]), (x, y))) <= 2  # about the pointer
        state = page.click_at(*truth[hidden])
        assert hidden in state["marks"] and hidden not in state["hidden"]
        assert np.hypot(*np.subtract(state["marks"][hidden], truth[hidden])) < CLICK_PX / 2

        page.press("s", changes=False)
        page.wait(lambda: json.loads(source.read_text()).get("hidden") == [], 10, "the saved file")
        saved = json.loads(source.read_text())
        assert saved["note"] == "kept" and {n: saved["keypoints"][n] for n in loaded} == loaded
    finally:
        driver.quit()
        server.shutdown()
        server.server_close()
        session.close()
