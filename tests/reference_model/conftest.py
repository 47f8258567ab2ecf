"""Fixtures of the reference-model tests: cases written as TOML files in tmp_path and
loaded through the real loader (its name must equal the file stem)."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Callable

import pytest

from rsmcheck.core.cases import Case, load_case


@pytest.fixture
def make_case(tmp_path: Path) -> Callable[[str, str], Case]:
    """make_case(name, body) → Case: writes `name = ...` + body to tmp_path/name.toml."""

    def make(name: str, body: str) -> Case:
        path = tmp_path / f"{name}.toml"
        path.write_text(f'name = "{name}"\n' + textwrap.dedent(body))
        return load_case(path)

    return make


RINGING_CHAIN = """
description = "open chain with rates: links and rotors ring"
duration = 1.0
[initial]
base_rate = [0.0, 0.0, 0.05]
joint_rates = [0.05, -0.05, 0.05, -0.05, 0.05, -0.05]
grasp = [1, 0]
[solver]
control_period = 1e-3
output_period = 1e-2
rtol = 1e-9
"""


@pytest.fixture
def ringing_chain(make_case) -> Case:
    """An open chain (arm 1 holds the target) started with base and joint rates, so that its
    links and rotors ring: the integrators' dynamic test case (rtol 1e-9; a test that
    studies rtol passes its own)."""
    return make_case("dynamic", RINGING_CHAIN)
