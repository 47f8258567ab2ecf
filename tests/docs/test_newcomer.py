"""README's "Adding a case", followed as a newcomer would, with the commands it names.

The new case lives in a temporary folder named by RSMCHECK_CASES_DIR and its goldens in one
named by RSMCHECK_GOLDENS_DIR (README: "A case kept outside the repository"), so the test
leaves the tree alone.  A copy of the whole of cases/ would not do: a case name found in two
folders is an error, and cases/ is always read.  Step 6 (the generated row in docs/cases.md)
concerns the shipped cases only and is tests/docs/test_doc_tables.py's.

The new case's short variant flies 1 s (free_drift's flies 5 s); most of the test is the bless
(three runs per engine and a code path); the report,
restricted to the new case, leaves out the robot-wide tables (docs/commands.md).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NAME = "free_drift_fast"

#: what step 2 adds: another initial base rate, and a [compare] table (without one `check`
#: compares nothing and exits 1)
COMPARE = """
[compare.base_pose_I]
tolerance = 1e-6
metric = "max_abs"
why = "Both engines fly the same free tumble; a few times the difference measured on the short run."
"""


def _rsmcheck(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rsmcheck.cli", *args], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=600)


@pytest.mark.crosscheck
def test_a_new_case_can_be_checked_blessed_and_reported(tmp_path):
    cases, goldens, out = tmp_path / "cases", tmp_path / "goldens", tmp_path / "out"
    cases.mkdir()
    env = {**os.environ, "RSMCHECK_CASES_DIR": str(cases), "RSMCHECK_GOLDENS_DIR": str(goldens)}

    # 1. copy a case file; 2. edit its name, one initial value, and give it a [compare] table
    text = (ROOT / "cases" / "free_drift.toml").read_text(encoding="utf-8")
    edited = text.replace('name = "free_drift"', f'name = "{NAME}"')
    edited = re.sub(r"base_rate = \[[^\]]*\]", "base_rate = [0.02, -0.01, 0.05]", edited)
    # and a short variant of 1 s (free_drift's flies 5 s): every step below runs it
    edited = re.sub(r"short_duration = [0-9.]+", "short_duration = 1.0", edited)
    assert edited.count(NAME) == 1 and "0.05]" in edited and "short_duration = 1.0" in edited, \
        "free_drift.toml no longer looks as README says"
    (cases / f"{NAME}.toml").write_text(edited + COMPARE, encoding="utf-8")

    # 3. rsmcheck check --short NAME: exit 0
    check = _rsmcheck(env, "check", "--short", NAME)
    assert check.returncode == 0, check.stdout + check.stderr
    assert "base_pose_I" in check.stdout and "pass" in check.stdout

    # 4. rsmcheck bless NAME --reason ...: a golden per engine and the changelog entry
    reason = "new case: free drift with a faster initial spin"
    # (on the one code path whose numba cache the suite has already filled: the other CPUs'
    # paths each compile every kernel anew, a minute apiece; tests/rsmcheck/orchestration/
    # test_code_paths.py runs them)
    bless = _rsmcheck(env, "bless", NAME, "--reason", reason, "--code-paths", "blas-1-thread")
    assert bless.returncode == 0, bless.stdout + bless.stderr
    written = sorted(p.name for p in goldens.glob(f"{NAME}.*.h5"))
    assert written == [f"{NAME}.exudyn.h5", f"{NAME}.reference.h5"], written
    assert reason in (goldens / "CHANGELOG.md").read_text(encoding="utf-8")
    assert not (ROOT / "goldens" / f"{NAME}.reference.h5").exists()

    # 5. the report, restricted to the new case: it has its section
    page = out / "report.html"
    report = _rsmcheck(env, "report", "--short", "--cases", NAME, "--out", str(page))
    assert report.returncode == 0, report.stdout + report.stderr
    html = page.read_text(encoding="utf-8")
    assert f'<h3 id="{NAME}">{NAME}</h3>' in html, "the new case has no section in the report"
