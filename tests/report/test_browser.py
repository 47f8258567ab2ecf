"""The rendered page in a real browser: headless Chromium (Debian's `chromium`).

The page draws every figure with `#render-all` and then sets data-ready on <body>;
data-drawn counts the figures drawn, and a JavaScript error is written into
<pre id="js-errors">.  Where Chromium is missing the test is skipped, except when
RSMCHECK_REQUIRE_BROWSER=1 (`.ci/run` sets it and installs Chromium): then it fails.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path


SCREENSHOT = Path(__file__).resolve().parents[2] / "out" / "browser-test" / "report-top.png"


def _run(args: list[str], timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False)


FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--no-first-run",
         "--virtual-time-budget=60000"]


def test_the_page_draws_every_figure_without_a_javascript_error(rendered, chromium):
    proc = _run([chromium, *FLAGS, "--dump-dom", rendered.page.as_uri() + "#render-all"])
    dom = proc.stdout
    body = re.search(r"<body([^>]*)>", dom)
    assert body, f"Chromium returned no page: {proc.stderr[-500:]}"
    attrs = dict(re.findall(r'data-([a-z-]+)="([^"]*)"', body.group(1)))
    errors = re.search(r'<pre id="js-errors">(.*?)</pre>', dom, re.S).group(1).strip()
    assert errors == "", errors
    assert attrs.get("ready") == "1"
    assert int(attrs["figures"]) > 0 and attrs.get("drawn") == attrs["figures"]
    for sid in ("verdict", "mission", "paper", "cases", "pinocchio", "modes", "studies", "speed", "faults"):
        assert f'<section id="{sid}">' in dom
    assert dom.count('class="main-svg"') >= int(attrs["figures"])  # plotly drew an SVG for each


def test_a_screenshot_of_the_top_of_the_page(rendered, chromium):
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    SCREENSHOT.unlink(missing_ok=True)
    proc = _run([chromium, *FLAGS, "--window-size=1300,1100", f"--screenshot={SCREENSHOT}", rendered.page.as_uri()])
    assert SCREENSHOT.is_file() and SCREENSHOT.stat().st_size > 20_000, proc.stderr[-500:]
