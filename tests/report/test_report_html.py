"""The report's HTML page in a real headless Chromium (Debian's package, installed by make)."""

from __future__ import annotations

import base64
import io
import os
import re

import numpy as np
import pytest
from _report_runs import build_runs

from ibiscape_eval.batch import LocalExecutor
from ibiscape_eval.report.batch_report import write_report
from ibiscape_eval.report.browser import check_page, find_chromium
from ibiscape_eval.report.evaluate import EvaluationOptions, evaluate_runs
from ibiscape_eval.report.runs import discover_runs


@pytest.fixture(scope="module")
def chromium() -> str:
    exe = find_chromium()
    if exe is None:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail("chromium not found on CI: `make test` installs Debian's chromium "
                        "package (sysdeps target); the HTML check must run here")
        pytest.skip("chromium not installed (run `make sysdeps` to install Debian's package)")
    return exe


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("html")
    runs, seqs = build_runs(root)
    ev = evaluate_runs(discover_runs(runs, sequences_dir=seqs), EvaluationOptions(align="none"),
                       executor=LocalExecutor(1))
    write_report(root / "out", ev)
    return root / "out"


def _png(data: bytes) -> np.ndarray:
    from matplotlib.image import imread

    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return np.asarray(imread(io.BytesIO(data), format="png"))


def test_page_is_self_contained_and_its_images_decode(report_dir) -> None:
    page = (report_dir / "report.html").read_text()
    refs = re.findall(r'(?:src|href)="([^"]*)"', page)
    assert refs and all(r.startswith("data:image/png;base64,") for r in refs)
    assert "<script" not in page
    for r in refs:
        img = _png(base64.b64decode(r.split(",", 1)[1]))
        assert img.shape[0] > 100 and img.shape[1] > 100 and img.std() > 0.01


def test_chromium_loads_the_page_without_console_errors(chromium, report_dir) -> None:
    shot = report_dir.parent / "report.png"
    res = check_page(report_dir / "report.html", screenshot=shot, chromium=chromium)
    assert res.console == ()
    # the browser parsed the table and the figures
    assert res.dom.count("<img") == 3
    assert re.search(r"<th[^>]*>seq1</th>", res.dom) and "<strong>0.0000</strong>" in res.dom
    assert "3/4" in res.dom and "seq1/beta/t4" in res.dom
    img = _png(shot.read_bytes())
    assert img.shape[:2] == (2400, 1400)
    assert img[..., :3].std() > 0.05  # rendered content, not a blank page


def test_the_check_reports_console_errors(chromium, tmp_path) -> None:
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"><title>t</title></head>'
                   '<body><script>console.error("deliberate failure"); undefinedCall();'
                   "</script></body></html>")
    res = check_page(bad, chromium=chromium)
    assert any("deliberate failure" in m for m in res.console)
    assert any("undefinedCall" in m for m in res.console)


@pytest.mark.parametrize("width", [500, 1600])  # 500: headless Chromium's narrowest
def test_nothing_overflows_the_page_at_narrow_and_wide_viewports(chromium, report_dir,
                                                                 width) -> None:
    from ibiscape_eval.report.browser import page_overflow

    res = page_overflow(report_dir / "report.html", width=width, chromium=chromium)
    assert res.viewport_px == width
    # the page is never wider than the window; a wide table scrolls inside its own box
    assert res.page_width_px <= width, res
    assert res.offenders == (), res


def test_the_overflow_check_catches_a_wide_page(chromium, tmp_path) -> None:
    from ibiscape_eval.report.browser import page_overflow

    wide = tmp_path / "wide.html"
    wide.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"><title>t</title></head>'
                    '<body><table><tr>' + "<td>0.123456789&nbsp;±&nbsp;0.1</td>" * 30
                    + "</tr></table></body></html>")
    res = page_overflow(wide, width=500, chromium=chromium)
    assert res.page_width_px > 500 and res.offenders
