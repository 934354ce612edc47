"""Drive the page in a real browser: headless Chromium through Selenium (the tests, the docs'
screenshot, the benchmark's browser latencies).

Needs Debian's ``chromium`` and ``chromium-driver`` (``make system-deps``) and ``selenium``
(the ``dev`` extras). The mouse is the browser's own (W3C actions at viewport pixels), so a
click on a photo pixel goes through the page's own event handling, zoom and pan.
"""
from __future__ import annotations

import shutil
import time
from dataclasses import dataclass

#: Where Debian puts them.
CHROMIUM_BINARIES = ("chromium", "chromium-browser", "google-chrome")
CHROMEDRIVER = "chromedriver"


def chromium_available() -> bool:
    """Whether a Chromium and its driver are installed, and Selenium is importable."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return False
    return shutil.which(CHROMEDRIVER) is not None and any(shutil.which(b) for b in CHROMIUM_BINARIES)


def headless_chromium(width: int = 1400, height: int = 900):
    """A headless Chromium WebDriver with a ``width`` × ``height`` window."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = next(shutil.which(b) for b in CHROMIUM_BINARIES if shutil.which(b))
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                f"--window-size={width},{height}", "--force-device-scale-factor=1", "--no-first-run"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(shutil.which(CHROMEDRIVER)), options=options)


@dataclass
class Page:
    """The page open in a driver, with the mouse and keys a person would use."""

    driver: object

    def open(self, url: str, timeout: float = 30.0) -> "Page":
        self.driver.get(url)
        self.wait(lambda: self.js("return !!(window.carbody && window.carbody.ready && window.carbody.state)"),
                  timeout, "the page did not start")
        return self

    def js(self, script: str, *args):
        return self.driver.execute_script(script, *args)

    @property
    def state(self) -> dict:
        return self.js("return window.carbody.state")

    def wait(self, condition, timeout: float = 20.0, what: str = "condition") -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if condition():
                return
            time.sleep(0.05)
        raise TimeoutError(f"timed out waiting: {what}")

    def settled(self, revision: int, timeout: float = 20.0) -> dict:
        """Wait until the page shows revision ``revision`` or later with no edit in flight."""
        self.wait(lambda: self.js("const a = window.carbody; return a.pending === 0 && a.state.revision >= arguments[0]",
                                  revision), timeout, f"revision {revision}")
        return self.state

    def client_xy(self, u: float, v: float) -> tuple[int, int]:
        x, y = self.js("return window.carbody.imageToClient(arguments[0], arguments[1])", u, v)
        return int(round(x)), int(round(y))

    def click_at(self, u: float, v: float, edits: bool = True) -> dict:
        """Click photo pixel (u, v); the state once the page has its answer (``edits`` False: a
        click that only selects a mark or a ghost)."""
        from selenium.webdriver.common.actions.action_builder import ActionBuilder

        revision = self.state["revision"]
        x, y = self.client_xy(u, v)
        actions = ActionBuilder(self.driver)
        actions.pointer_action.move_to_location(x, y)
        actions.pointer_action.click()
        actions.perform()
        return self.settled(revision + 1) if edits else self.state

    def hover(self, u: float, v: float) -> str | None:
        """Move the pointer over photo pixel (u, v), no button down; the name the page shows there
        (the mark or ghost under the pointer), or None."""
        from selenium.webdriver.common.actions.action_builder import ActionBuilder

        x, y = self.client_xy(u, v)
        actions = ActionBuilder(self.driver)
        actions.pointer_action.move_to_location(x, y)
        actions.perform()
        return self.js("return window.carbody.hover")

    def drag(self, from_uv: tuple[float, float], to_uv: tuple[float, float], steps: int = 8) -> dict:
        """Press at photo pixel ``from_uv``, move to ``to_uv`` and let go."""
        from selenium.webdriver.common.actions.action_builder import ActionBuilder

        revision = self.state["revision"]
        (x0, y0), (x1, y1) = self.client_xy(*from_uv), self.client_xy(*to_uv)
        actions = ActionBuilder(self.driver)
        actions.pointer_action.move_to_location(x0, y0)
        actions.pointer_action.pointer_down()
        for i in range(1, steps + 1):
            actions.pointer_action.move_to_location(int(round(x0 + (x1 - x0) * i / steps)),
                                                    int(round(y0 + (y1 - y0) * i / steps)))
        actions.pointer_action.pointer_up()
        actions.perform()
        return self.settled(revision + 1)

    def press(self, key: str, changes: bool = True) -> dict:
        """Press a key (``"s"``, ``"h"``, Selenium's ``Keys.ENTER`` …) on the page."""
        from selenium.webdriver.common.action_chains import ActionChains

        revision = self.state["revision"]
        ActionChains(self.driver).send_keys(key).perform()
        return self.settled(revision + 1) if changes else self.state

    def wait_refined(self, timeout: float = 30.0) -> dict:
        """Wait until the page shows the full fit of its latest edit."""
        self.wait(lambda: self.js("return window.carbody.state.refined"), timeout, "the full fit")
        return self.state
