"""Code, tests and docs say what they hold, not where it came from: no tracked text file
names an issue number or an audit-row number (a reader of a clone has neither tracker). The
words are matched across a line break too, as a wrapped comment would have them."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# built from its parts so that this file does not match itself (nor do its examples)
ISSUE, AUDIT = "iss" + "ue", "aud" + "it"
TRACKER = re.compile(r"\bissues?\s+#?[0-9]|\baudit\s+" + "row", re.IGNORECASE)


def tracked_text_files() -> list[Path]:
    names = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, check=True,
                           capture_output=True).stdout.decode().split("\0")
    files = []
    for name in filter(None, names):
        path = REPO / name
        if path.is_file() and b"\0" not in path.read_bytes()[:8192]:
            files.append(path)
    return files


def tracker_numbers(text: str) -> list[tuple[int, str]]:
    """(line, matched text) of every issue or audit-row number in ``text``."""
    return [(text.count("\n", 0, m.start()) + 1, " ".join(m.group().split()))
            for m in TRACKER.finditer(text)]


def test_the_pattern_finds_what_it_is_for() -> None:
    text = (f"x ({ISSUE} 21, part 3)\n# {ISSUE.title()} #4\nsee the {ISSUE}\n20 here\n"
            f"{AUDIT.title()}\n row 7\n{ISSUE}s and {AUDIT}s")
    assert tracker_numbers(text) == [(1, f"{ISSUE} 2"), (2, f"{ISSUE.title()} #4"),
                                     (3, f"{ISSUE} 2"), (5, f"{AUDIT.title()} row")]


def test_no_tracked_file_names_an_issue_or_audit_row_number() -> None:
    files = tracked_text_files()
    assert len(files) > 100 and REPO / "README.md" in files
    hits = [f"{p.relative_to(REPO)}:{line}: {found}"
            for p in files
            for line, found in tracker_numbers(p.read_text(encoding="utf-8",
                                                           errors="replace"))]
    assert hits == []
