"""The tests read only what the repository holds: no test refers to a path outside the checkout,
and tests/data/README.md names exactly the files tests/data holds, so each
has its origin and licence written down."""

from __future__ import annotations

import re
from pathlib import Path

from inria_folder import SCENES

TESTS = Path(__file__).resolve().parent
# a path that climbs out of the checkout (the tests folder's grandparent or above, a parent-folder
# folder path, an absolute path of this machine; a bare "../name" is a fuzz input, not a path read) or an environment variable that points the tests elsewhere
OUTSIDE = re.compile(r"parents\[[2-9]\]|\.\./\w+/|/work/|DOFVIEW_\w*SCENES")
LISTED = re.compile(r"^\| `([^`]+)` \|", re.MULTILINE)  # a table row of the README: | `file` | …


def test_no_test_reads_beside_the_checkout():
    hits = [f"{p.name}:{n}: {line.strip()}" for p in sorted(TESTS.rglob("*.py")) if p != Path(__file__).resolve()
            for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if OUTSIDE.search(line)]
    assert not hits, "tests must read what the repository holds (tests/data, samples), nothing beside it:\n" + "\n".join(hits)


def test_the_data_readme_names_every_file_and_only_those():
    assert SCENES == TESTS / "data"
    listed = LISTED.findall((SCENES / "README.md").read_text(encoding="utf-8"))
    present = sorted(p.name for p in SCENES.iterdir() if p.is_file() and p.name != "README.md")
    assert len(listed) == len(set(listed))
    assert sorted(listed) == present
