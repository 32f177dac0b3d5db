"""A small W3C WebDriver client, standard library only: ``chromedriver`` (Debian's
chromium-driver) driving headless Chromium, for tests that click and hover in a page.

WebDriver is HTTP and JSON (https://www.w3.org/TR/webdriver2/), so a client is a few calls
through ``urllib``: start a session, go to a URL, find elements by CSS selector, read their
text, move the pointer onto one (a real hover: the page's mouse events fire), click, run a
script, take a screenshot. Selenium would do the same for a dependency the tests do not need.
Used by tests/report/test_explore_browser.py.
"""

from __future__ import annotations

import base64
import json
import shutil
import socket
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any, Callable

ELEMENT = "element-6066-11e4-a52e-4f735466cecf"  # the W3C key of an element reference


class WebDriverError(RuntimeError):
    pass


def chromedriver() -> str | None:
    """chromedriver on PATH (Debian: apt-get install chromium-driver), or None."""
    return shutil.which("chromedriver")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Browser:
    """Headless Chromium under chromedriver, one session; ``quit()`` ends both."""

    def __init__(self, chromium: str, profile: Path, *, width: int = 1400, height: int = 1000):
        port = free_port()
        self.base = f"http://127.0.0.1:{port}"
        self.proc = subprocess.Popen(
            [chromedriver() or "chromedriver", f"--port={port}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        self.session = None
        try:
            self._wait_ready()
            args = [
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                f"--window-size={width},{height}",
                f"--user-data-dir={profile}",
            ]
            caps = {
                "capabilities": {
                    "alwaysMatch": {
                        "browserName": "chrome",
                        "goog:chromeOptions": {"binary": chromium, "args": args},
                    }
                }
            }
            self.session = self._call("POST", "/session", caps)["sessionId"]
        except BaseException:
            self.quit()
            raise

    def _wait_ready(self, timeout: float = 20.0) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                if self._call("GET", "/status").get("ready"):
                    return
            except (OSError, WebDriverError):
                pass
            time.sleep(0.1)
        raise WebDriverError("chromedriver did not start")

    def _call(self, method: str, path: str, body: Any = None, timeout: float = 120.0) -> Any:
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(
            self.base + path, data=data, method=method, headers={"Content-Type": "application/json"}
        )
        try:
            with urllib.request.urlopen(request, timeout=timeout) as response:
                answer = json.loads(response.read() or b"{}")
        except urllib.error.HTTPError as exc:
            answer = json.loads(exc.read() or b"{}")
            value = answer.get("value", {})
            raise WebDriverError(
                f"{method} {path}: {value.get('error')}: {str(value.get('message', ''))[:300]}"
            ) from None
        return answer.get("value")

    def cmd(self, method: str, path: str, body: Any = None) -> Any:
        return self._call(method, f"/session/{self.session}{path}", body)

    # -- what a test does in the page
    def get(self, url: str) -> None:
        self.cmd("POST", "/url", {"url": url})

    def execute(self, script: str, *args: Any) -> Any:
        return self.cmd("POST", "/execute/sync", {"script": script, "args": list(args)})

    def find_all(self, css: str) -> list[dict]:
        return self.cmd("POST", "/elements", {"using": "css selector", "value": css})

    def find(self, css: str) -> dict:
        return self.cmd("POST", "/element", {"using": "css selector", "value": css})

    def text(self, element: dict) -> str:
        return self.cmd("GET", f"/element/{element[ELEMENT]}/text")

    def hover(self, element: dict) -> None:
        """Move the pointer to the element's centre (the page's mousemove fires there)."""
        move = {
            "type": "pointerMove",
            "duration": 0,
            "x": 0,
            "y": 0,
            "origin": {ELEMENT: element[ELEMENT]},
        }
        self.cmd(
            "POST",
            "/actions",
            {
                "actions": [
                    {
                        "type": "pointer",
                        "id": "mouse",
                        "parameters": {"pointerType": "mouse"},
                        "actions": [move],
                    }
                ]
            },
        )

    def click(self, element: dict) -> None:
        """A pointer click at the element's centre (as a person clicks; the page's own
        handlers run)."""
        self.hover(element)
        down_up = [{"type": "pointerDown", "button": 0}, {"type": "pointerUp", "button": 0}]
        self.cmd(
            "POST",
            "/actions",
            {
                "actions": [
                    {
                        "type": "pointer",
                        "id": "mouse",
                        "parameters": {"pointerType": "mouse"},
                        "actions": down_up,
                    }
                ]
            },
        )

    def wait(self, check: Callable[[], Any], timeout: float = 60.0, what: str = "") -> Any:
        """``check()``'s first truthy value, polled until ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while True:
            found = check()
            if found:
                return found
            if time.monotonic() > end:
                raise TimeoutError(f"waited {timeout:g} s for {what or check}")
            time.sleep(0.1)

    def screenshot(self, path: Path) -> None:
        Path(path).write_bytes(base64.b64decode(self.cmd("GET", "/screenshot")))

    def quit(self) -> None:
        try:
            if self.session is not None:
                self._call("DELETE", f"/session/{self.session}", timeout=30)
        except (OSError, WebDriverError):
            pass
        finally:
            self.session = None
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
