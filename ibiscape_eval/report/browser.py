"""Open an HTML page in a real headless Chromium: console messages, the parsed DOM, a screenshot.

Used to check the report page (the test suite) and to picture it (``make demo``).  Chromium is
Debian's ``chromium`` package (``make test`` / ``make demo`` install it when it is missing).  Each
call starts a throw-away browser profile in a temporary folder; nothing else is touched.
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ibiscape_eval.batch.files import atomic_output_path
from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["BrowserCheck", "Overflow", "check_page", "find_chromium", "page_overflow"]

_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
# "[pid:tid:date:INFO:CONSOLE:12] "message", source: file:///... (12)" (older builds: CONSOLE(12))
_CONSOLE = re.compile(r":CONSOLE[:(]\d*\)?\]\s*(.*)$")


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome executable on PATH, or None."""
    for name in _NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


@dataclass(frozen=True)
class BrowserCheck:
    """What the browser saw.

    Attributes
    ----------
    console : tuple of str
        Console messages of the page (errors, warnings, uncaught exceptions, logs), in order.
    dom : str
        The DOM after parsing (``--dump-dom``).
    screenshot : str or None
        The PNG written, if one was asked for.
    """

    console: tuple[str, ...]
    dom: str
    screenshot: str | None

    def __repr__(self) -> str:
        return f"BrowserCheck({len(self.console)} console messages, {len(self.dom)} chars of DOM)"


def _chromium_or_refuse(chromium: str | None) -> str:
    """``chromium`` or the one on PATH; refused (IbiscapeError) when there is none."""
    exe = chromium or find_chromium()
    if exe is None:
        raise IbiscapeError("no chromium executable on PATH; install Debian's chromium package "
                            "(make test / make demo do it)")
    return exe


def _run(exe: str, args: list[str], timeout_s: float) -> subprocess.CompletedProcess[str]:
    with tempfile.TemporaryDirectory(prefix="ibiscape-chromium-") as profile:
        argv = [exe, "--headless", "--disable-gpu", "--no-first-run", "--hide-scrollbars",
                f"--user-data-dir={profile}", *args]
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            argv.insert(1, "--no-sandbox")  # Chromium refuses to run its sandbox as root
        try:
            return subprocess.run(argv, capture_output=True, text=True, timeout=timeout_s,
                                  check=False)
        except subprocess.TimeoutExpired:
            raise IbiscapeError(f"{exe} did not finish within {timeout_s:g} s") from None


def check_page(
    page: str | os.PathLike[str],
    *,
    screenshot: str | os.PathLike[str] | None = None,
    window: tuple[int, int] = (1400, 2400),
    timeout_s: float = 90.0,
    chromium: str | None = None,
) -> BrowserCheck:
    """Load ``page`` in headless Chromium; collect its console messages and DOM, and optionally
    write a ``window``-sized screenshot (PNG, atomically).

    Raises
    ------
    IbiscapeError
        No Chromium found, or it failed to load the page.
    """
    exe = _chromium_or_refuse(chromium)
    url = Path(page).resolve().as_uri()
    size = f"--window-size={window[0]},{window[1]}"
    shot: str | None = None
    logging_args = ["--enable-logging=stderr", "--v=0", size]
    if screenshot is not None:
        with atomic_output_path(screenshot) as tmp:
            res = _run(exe, [*logging_args, f"--screenshot={tmp}", url], timeout_s)
            if res.returncode != 0 or not tmp.is_file() or tmp.stat().st_size == 0:
                raise IbiscapeError(f"{exe} could not take a screenshot of {page} (exit "
                                    f"{res.returncode}): {res.stderr.strip()[-300:]}")
        shot = str(screenshot)
    else:
        res = _run(exe, [*logging_args, "--dump-dom", url], timeout_s)
    console = tuple(m.group(1).strip() for line in res.stderr.splitlines()
                    if (m := _CONSOLE.search(line)))
    dom = _run(exe, [size, "--dump-dom", url], timeout_s)
    if dom.returncode != 0 or "<html" not in dom.stdout:
        raise IbiscapeError(f"{exe} could not load {page} (exit {dom.returncode}): "
                            f"{dom.stderr.strip()[-300:]}")
    return BrowserCheck(console, dom.stdout, shot)


@dataclass(frozen=True)
class Overflow:
    """How a page fits a window ``viewport_px`` wide.

    Attributes
    ----------
    viewport_px : int
        The window's inner width, CSS pixels.
    page_width_px : int
        The document's scroll width: wider than ``viewport_px`` when something sticks out and the
        reader must scroll the whole page sideways.
    offenders : tuple of str
        Elements reaching past the window's edge (tag, class, right edge) that are not inside a
        box that scrolls or clips on its own; empty when the page fits.
    """

    viewport_px: int
    page_width_px: int
    offenders: tuple[str, ...]

    @property
    def fits(self) -> bool:
        return self.page_width_px <= self.viewport_px and not self.offenders


# Measures after layout; an element inside a box with its own horizontal overflow handling (a
# table in a scrolling div) does not count: the reader scrolls that box, not the page.
_MEASURE = """<script>
(function () {
  const W = document.documentElement.clientWidth;
  const page = document.documentElement.scrollWidth;
  const bad = [];
  for (const el of document.body.querySelectorAll("*")) {
    let p = el.parentElement, boxed = false;
    while (p && p !== document.body) {
      const ox = getComputedStyle(p).overflowX;
      if (ox === "auto" || ox === "scroll" || ox === "hidden") { boxed = true; break; }
      p = p.parentElement;
    }
    if (boxed) continue;
    const r = el.getBoundingClientRect();
    if (r.width > 0 && (r.right > W + 0.5 || r.left < -0.5)) {
      bad.push(el.tagName.toLowerCase() + (el.className ? "." + el.className : "")
               + " right=" + Math.round(r.right));
    }
  }
  const out = document.createElement("pre");
  out.id = "ibiscape-overflow";
  out.textContent = JSON.stringify({viewport: window.innerWidth, page: page,
                                    offenders: bad.slice(0, 20)});
  document.body.appendChild(out);
})();
</script>"""
_RESULT = re.compile(r'<pre id="ibiscape-overflow">(.*?)</pre>', re.S)


def page_overflow(
    page: str | os.PathLike[str],
    *,
    width: int,
    height: int = 1200,
    timeout_s: float = 90.0,
    chromium: str | None = None,
) -> Overflow:
    """Load a copy of ``page`` in headless Chromium in a window ``width`` CSS pixels wide and
    measure what sticks out of it (the page itself is not changed: the measuring script goes into
    a temporary copy).

    Raises
    ------
    IbiscapeError
        No Chromium found, or it failed to load the page.
    """
    exe = _chromium_or_refuse(chromium)
    text = Path(page).read_text(encoding="utf-8")
    cut = text.rfind("</body>")
    text = (text[:cut] + _MEASURE + text[cut:]) if cut >= 0 else text + _MEASURE
    with tempfile.TemporaryDirectory(prefix="ibiscape-overflow-") as tmp:
        copy = Path(tmp) / "page.html"
        copy.write_text(text, encoding="utf-8")
        res = _run(exe, [f"--window-size={width},{height}", "--dump-dom", copy.as_uri()],
                   timeout_s)
    m = _RESULT.search(res.stdout)
    if res.returncode != 0 or m is None:
        raise IbiscapeError(f"{exe} could not measure {page} (exit {res.returncode}): "
                            f"{res.stderr.strip()[-300:]}")
    doc = json.loads(html.unescape(m.group(1)))
    return Overflow(int(doc["viewport"]), int(doc["page"]), tuple(doc["offenders"]))
