"""The project stands alone: no tracked source, doc, case file or test points the reader at a
document that is not in the repository (a design contract or engine notes kept elsewhere,
a sibling folder, an issue tracker).  What the reader needs is in README.md and docs/*.md,
and references cite those (e.g. "docs/physics.md §11").

Every tracked .py, .md and .toml file is read from the working tree; nothing is excluded.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: (pattern, what it points at).  The patterns are written so that this file does not
#: match itself.
FORBIDDEN: list[tuple[re.Pattern[str], str]] = [
    (re.compile(r"\bSPEC\b"), "the external design contract (cite README.md or docs/*.md)"),
    (re.compile(r"ENGINE[-_]NOTES", re.IGNORECASE), "the external engine notes (cite docs/exudyn.md)"),
    (re.compile(r"(?:\.\./|/work/)shared\b"), "a folder outside the repository"),
    (re.compile(r"\b(?:issues?|tickets?|bugs?|PRs?|pull requests?|merge requests?)\s*#?\d+\b", re.IGNORECASE),
     "an issue tracker"),
    (re.compile(r"\bGH-\d+\b", re.IGNORECASE), "an issue tracker"),
    # "#12" as a tracker number: after a space or an opening bracket, not a CSS colour
    # ("color: #070"), an anchor ("page#12") or an HTML entity ("&#12;")
    (re.compile(r"(?:^|(?<=[\s(\[,]))(?<!: )#\d{1,6}\b(?![\w;])"), "an issue tracker"),
]

SUFFIXES = (".py", ".md", ".toml")


def tracked_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    names = [n for n in out.decode().split("\0") if n.endswith(SUFFIXES)]
    return [ROOT / n for n in names if (ROOT / n).is_file()]  # a tracked file being deleted is not read


def hits(text: str) -> list[tuple[int, str, str]]:
    """(line number, line, what it points at) for every forbidden reference in `text`."""
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for pattern, what in FORBIDDEN:
            if pattern.search(line):
                found.append((number, line.strip(), what))
                break
    return found


def test_no_reference_to_documents_outside_the_repository():
    files = tracked_files()
    assert len(files) > 50, "git ls-files found too few files: not run inside the repository?"
    problems = []
    for path in files:
        for number, line, what in hits(path.read_text(encoding="utf-8", errors="replace")):
            problems.append(f"{path.relative_to(ROOT)}:{number}: {what}: {line}")
    assert not problems, f"{len(problems)} reference(s) to documents outside the repository:\n" + "\n".join(problems)


# the patterns themselves: what they must catch and what they must leave alone
# (each example is cut in two so that this file, which is tracked too, does not match itself)
CAUGHT = [
    "One row of SP" + "EC §4.",
    "see SP" + "EC.md",
    "as the ENGINE-" + "NOTES say",
    "engine-" + "notes.md",
    "copied from ../sha" + "red/seed",
    "fixed in iss" + "ue 12",
    "(Iss" + "ue #" + "7)",
    "see P" + "R 31",
    "follows up #" + "12 and more",
    "(#" + "12)",
    "closes g" + "h-40",
]
LEFT_ALONE = [
    "SPECTRAL_RADIUS_DEFAULT = 0.6",
    "class InitialSpec:",
    "body{color:#222}.pass{color:#070}",
    "td { color: #555; }",
    "see docs/physics.md §11 and README#command-line",
    "&#12; is an entity",
    "# 12 samples per period",
    "a shared controller, on 2 shared cores",
    "17 plausible bugs (10 reference, 3 Exudyn)",
    "this issue is decided in docs/physics.md §3.3",
]


@pytest.mark.parametrize("text", CAUGHT)
def test_pattern_catches(text):
    assert hits(text), text


@pytest.mark.parametrize("text", LEFT_ALONE)
def test_pattern_leaves_legitimate_text_alone(text):
    assert not hits(text), text
