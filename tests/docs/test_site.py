"""The documentation site builds strictly and offline, and the built site stands alone.

* `mkdocs build --strict` passes with no warning at all (a broken link or anchor, a page
  left out of the nav, a docstring the API pages cannot read) — with the network shut
  (conftest.py);
* the API pages show the objects of rsmcheck.core.plugins and rsmcheck.core.cases with
  their docstrings and `#:` comments;
* no page or stylesheet loads anything from another host, and the vendored KaTeX
  stylesheet names only files the site has.
"""

from __future__ import annotations

import re

CDN_HOSTS = re.compile(r"unpkg\.com|jsdelivr|googleapis|gstatic|cdnjs|mathjax\.org|polyfill\.io|cloudflare")
#: the theme's bundle names two CDN files it loads only when a page needs them: Mermaid for
#: a ```mermaid diagram (this site has no Mermaid fence) and a ResizeObserver polyfill
#: for a browser without one (every browser since 2020 has it)
THEME_FALLBACKS = {"unpkg.com/mermaid@11/dist/mermaid.min.js", "unpkg.com/resize-observer-polyfill"}
#: an attribute or CSS rule that makes the browser fetch something
LOADS = [
    re.compile(r"<(?:script|img|iframe|source|audio|video|embed)\b[^>]*\bsrc=[\"']?(https?:)?//", re.I),
    re.compile(r"<link\b[^>]*\bhref=[\"']?(https?:)?//", re.I),
]
CSS_LOADS = re.compile(r"url\(\s*[\"']?(https?:)?//|@import\s", re.I)
#: the text files a browser reads (the rest are fonts, pictures, and the theme's source
#: maps, which only a browser's developer tools open)
TEXT = (".html", ".css", ".js", ".json", ".xml", ".txt")


def test_the_site_builds_strictly_without_a_warning(site):
    assert site.returncode == 0, f"mkdocs build --strict failed:\n{site.output}"
    warnings = [line for line in site.output.splitlines() if "WARNING" in line]
    assert not warnings, "the build warned:\n" + "\n".join(warnings)
    assert site.seconds < 60, f"the build took {site.seconds:.1f} s"


def test_the_api_pages_show_the_documented_objects(built):
    plugins = (built.folder / "api" / "plugins.html").read_text(encoding="utf-8")
    for name in ("EnginePlugin", "Fault", "LineStyle", "WorkCounter", "plugins", "plugin", "require"):
        assert f'id="rsmcheck.core.plugins.{name}"' in plugins, name
    assert "the engine's name in case files" in plugins  # a `#:` comment (griffe-sphinx)
    cases = (built.folder / "api" / "cases.html").read_text(encoding="utf-8")
    for name in ("Case", "load_case", "CompareSpec", "Case.variant"):
        assert f'id="rsmcheck.core.cases.{name}"' in cases, name
    assert "Load and validate one case file" in cases  # load_case's docstring


def test_no_page_loads_anything_from_another_host(built):
    problems = []
    for path in sorted(built.folder.rglob("*")):
        if not path.is_file() or path.suffix not in TEXT:
            continue
        name = path.relative_to(built.folder).as_posix()
        text = path.read_text(encoding="utf-8", errors="replace")
        rules = LOADS if path.suffix == ".html" else [CSS_LOADS] if path.suffix == ".css" else []
        problems += [f"{name}: loads {m.group(0)!r}" for rule in rules for m in rule.finditer(text)]
        for m in CDN_HOSTS.finditer(text):
            url = re.match(r"[\w.@/-]+", text[m.start():]).group(0)
            if not (name.startswith("assets/javascripts/bundle.") and url in THEME_FALLBACKS):
                problems.append(f"{name}: names a CDN: {url}")
    assert not problems, "\n".join(problems)


def test_the_vendored_stylesheet_names_only_files_the_site_has(built):
    katex = built.folder / "javascripts" / "katex"
    urls = re.findall(r"url\(([^)]+)\)", (katex / "katex.min.css").read_text(encoding="utf-8"))
    assert len(urls) == 20, urls  # one woff2 per KaTeX font
    missing = [u for u in urls if not (katex / u.strip("\"'")).is_file()]
    assert not missing, missing
