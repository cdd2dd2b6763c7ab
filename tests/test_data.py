"""The tests read only what the repository holds: no test refers to the scenes folder beside the
checkout (../shared), and tests/data/README.md names exactly the files tests/data holds, so each
has its origin and licence written down."""

from __future__ import annotations

import re
from pathlib import Path

from inria_folder import SCENES

TESTS = Path(__file__).resolve().parent
# a path that climbs out of the checkout, or names the scenes folder beside it
OUTSIDE = re.compile(r"parents\[2\]|\"shared\"\s*/|shared/scenes|/work/shared|DOFVIEW_(SHARED_)?SCENES")
LISTED = re.compile(r"^\| `([^`]+)` \|", re.MULTILINE)  # a table row of the README: | `file` | …


def test_no_test_reads_beside_the_checkout():
    hits = [f"{p.name}:{n}: {line.strip()}" for p in sorted(TESTS.rglob("*.py")) if p != Path(__file__).resolve()
            for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if OUTSIDE.search(line)]
    assert not hits, "tests must read tests/data, not ../shared:\n" + "\n".join(hits)


def test_the_data_readme_names_every_file_and_only_those():
    assert SCENES == TESTS / "data"
    listed = LISTED.findall((SCENES / "README.md").read_text(encoding="utf-8"))
    present = sorted(p.name for p in SCENES.iterdir() if p.is_file() and p.name != "README.md")
    assert len(listed) == len(set(listed))
    assert sorted(listed) == present
