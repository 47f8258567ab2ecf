"""The built site in a real browser: headless Chromium (Debian's `chromium`), opened from
file:// with every host name unresolvable, so that what the pages show comes from the
site itself.

* the start page has its title and the picture;
* the equations of the notation and the physics pages are all rendered by the site's own
  KaTeX: as many rendered equations as the page's source has, none left as TeX, none in error;
* the search works from file:// (Material's offline plugin): a query finds the notation page.

Where Chromium is missing the tests are skipped, except when RSMCHECK_REQUIRE_BROWSER=1
(`.ci/run` sets it and installs Chromium): then they fail.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[2] / "docs"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--no-first-run",
         "--virtual-time-budget=10000", "--host-resolver-rules=MAP * ~NOTFOUND"]


def dom(chromium: str, page: Path, query: str = "") -> str:
    """The page's DOM after its scripts ran (`--dump-dom`)."""
    proc = subprocess.run([chromium, *FLAGS, "--dump-dom", page.as_uri() + query],
                          capture_output=True, text=True, timeout=120, check=False)
    assert "<body" in proc.stdout, f"Chromium returned no page: {proc.stderr[-500:]}"
    return proc.stdout


def article(page_dom: str) -> str:
    """The page's own content (not the navigation, nor the search panel)."""
    return re.search(r'<article class="md-content__inner[^>]*>(.*?)</article>', page_dom, re.S).group(1)


def equations_in_source(name: str) -> tuple[int, int]:
    """(display, inline) equations of docs/NAME.md: $$ … $$ spans (over one line or more),
    then $ … $ on one line."""
    text = (DOCS / f"{name}.md").read_text(encoding="utf-8")
    display = re.findall(r"\$\$.+?\$\$", text, re.S)
    prose = re.sub(r"\$\$.+?\$\$", "", text, flags=re.S)
    return len(display), len(re.findall(r"\$[^$\n]+\$", prose))


def test_the_start_page_has_its_title_and_the_picture(built, chromium):
    page = dom(chromium, built.folder / "index.html")
    assert re.search(r"<title>rsmcheck</title>", page)
    assert re.search(r'<h1 id="rsmcheck">rsmcheck', page)
    content = article(page)
    assert re.search(r'<img alt="The top of the report[^"]*" src="report-top.png"', content)
    assert (built.folder / "report-top.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for target in ("physics.html", "notation.html", "api/plugins.html", "api/cases.html"):
        assert f'href="{target}"' in content, target


@pytest.mark.parametrize("name", ["notation", "physics"])
def test_the_page_renders_every_equation_offline(built, name, chromium):
    display, inline = equations_in_source(name)
    assert display >= 10 and inline >= 20, (display, inline)
    content = article(dom(chromium, built.folder / f"{name}.html"))
    errors = re.findall(r'class="arithmatex math-error" title="([^"]*)"', content)
    assert not errors, errors  # what KaTeX could not read (docs/javascripts/render-math.js)
    assert content.count('<span class="katex-display">') == display
    assert content.count('<span class="katex">') == display + inline
    unrendered = re.findall(r'class="arithmatex">(?!<span class="katex)(.{0,60})', content)
    assert not unrendered, unrendered
    text = re.sub(r'<annotation encoding="application/x-tex">.*?</annotation>', "", content, flags=re.S)
    for raw in ("$$", "\\(", "\\["):
        assert raw not in text, f"raw TeX {raw!r} left on the page"


def test_the_search_works_from_file_urls(built, chromium):
    page = dom(chromium, built.folder / "index.html", "?q=Baumgarte")
    results = re.findall(r'<a href="([^"]+)" class="md-search-result__link"', page)
    assert any(r.endswith("/notation.html") for r in results), results
    assert "<mark>Baumgarte</mark>" in page
