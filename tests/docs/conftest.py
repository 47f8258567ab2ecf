"""The documentation site (mkdocs.yml), built once per session into a temporary folder.

The build is the one `make docs` runs, `mkdocs build --strict`, with the network shut:
every proxy points at a closed port of this machine, so a plug-in that tried to fetch
something (an inventory, a font) would fail the build instead of quietly reaching out.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DEAD_PROXY = "http://127.0.0.1:9"  # the discard port: nothing listens there


@dataclass
class Site:
    folder: Path
    returncode: int
    output: str  # stdout and stderr of the build
    seconds: float


@pytest.fixture(scope="session")
def site(tmp_path_factory) -> Site:
    try:
        import mkdocs  # noqa: F401
    except ImportError:
        pytest.fail("mkdocs is not installed: pip install -e '.[docs]' (`make venv` installs it)")
    folder = tmp_path_factory.mktemp("site")
    env = {k: v for k, v in os.environ.items() if k.lower() != "no_proxy"}
    for name in ("http_proxy", "https_proxy", "all_proxy"):
        env[name] = env[name.upper()] = DEAD_PROXY
    env["NO_MKDOCS_2_WARNING"] = "1"  # the theme's banner about its successor
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict",
                           "--config-file", str(ROOT / "mkdocs.yml"), "--site-dir", str(folder)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300, check=False)
    return Site(folder, proc.returncode, proc.stdout + proc.stderr, time.perf_counter() - start)


@pytest.fixture(scope="session")
def built(site) -> Site:
    """The site, for tests that look at it: a failed build fails them with its output."""
    assert site.returncode == 0, f"mkdocs build --strict failed:\n{site.output}"
    return site
