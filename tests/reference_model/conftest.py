"""Fixtures of the reference-model tests: cases written as TOML files in tmp_path and
loaded through the real loader (its name must equal the file stem)."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Callable

import pytest

from rsmcheck.cases import Case, load_case


@pytest.fixture
def make_case(tmp_path: Path) -> Callable[[str, str], Case]:
    """make_case(name, body) → Case: writes `name = ...` + body to tmp_path/name.toml."""

    def make(name: str, body: str) -> Case:
        path = tmp_path / f"{name}.toml"
        path.write_text(f'name = "{name}"\n' + textwrap.dedent(body))
        return load_case(path)

    return make
