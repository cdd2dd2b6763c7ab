"""The layout holds: imports run one way (import-linter contracts in pyproject.toml), no module
imports another that imports it back, the CLI is a thin layer over the Python API, and the README's
Python example runs as written."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def test_import_contracts_hold():
    lint = Path(sys.executable).with_name("lint-imports")
    p = subprocess.run([str(lint)], cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-2000:]
    assert "0 broken" in p.stdout


def type_checking_imports(module: str) -> set[str]:
    """dofview modules that ``module`` imports inside ``if TYPE_CHECKING:`` blocks (grimp may skip
    them; a circle through a type-only import still ties the two modules together)."""
    import ast
    import importlib.util

    tree = ast.parse(Path(importlib.util.find_spec(module).origin).read_text())
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for inner in ast.walk(node):
                if isinstance(inner, ast.ImportFrom) and inner.module and inner.module.startswith("dofview"):
                    found.add(inner.module)
                elif isinstance(inner, ast.Import):
                    found |= {a.name for a in inner.names if a.name.startswith("dofview")}
    return found


def import_graph() -> dict[str, set[str]]:
    """Module → the dofview modules it imports, at run time or for type checking only."""
    import grimp

    graph = grimp.build_graph("dofview", exclude_type_checking_imports=True)
    return {m: set(graph.find_modules_directly_imported_by(m)) | (type_checking_imports(m) & graph.modules)
            for m in graph.modules}


def test_type_checking_imports_are_seen():
    """The parse finds the type-only imports (panel.py types its argument with the viewer model)."""
    assert "dofview.viewer.model" in type_checking_imports("dofview.viewer.panel")


def test_no_import_cycles():
    """Strongly connected components of the import graph, type-only imports included."""
    graph = import_graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(m: str) -> None:  # Tarjan's algorithm
        index[m] = low[m] = len(index)
        stack.append(m)
        for n in graph[m]:
            if n not in index:
                visit(n)
                low[m] = min(low[m], low[n])
            elif n in stack:
                low[m] = min(low[m], index[n])
        if low[m] == index[m]:
            comp = []
            while True:
                n = stack.pop()
                comp.append(n)
                if n == m:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for m in sorted(graph):
        if m not in index:
            visit(m)
    assert cycles == []


def test_readme_python_example_runs_verbatim(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python API"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert len(code.strip().splitlines()) <= 12
    (tmp_path / "samples").symlink_to(ROOT / "samples")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    from dofview.io.exr import read_exr
    from dofview.io.png import read_png

    channels, header = read_exr(tmp_path / "cards.exr")
    assert set(channels) == {"R", "G", "B", "A", "Z"} and channels["R"].shape == (240, 320)
    assert "dofview:lens" in header and read_png(tmp_path / "cards.png").shape == (240, 320, 3)


def test_cli_render_is_the_api_render(tmp_path):
    """`dofview render` writes exactly what dofview.render() returns: same float32 pixels, same depth."""
    import dofview
    from dofview.cli import main
    from dofview.io.exr import read_exr

    cards, cams = ROOT / "samples" / "cards.ply", ROOT / "samples" / "cards_cameras.json"
    out = tmp_path / "cli.exr"
    assert main(["render", str(cards), "--cameras", str(cams), "--view", "2", "--width", "96", "--height", "72",
                 "--focus", "4", "--aperture", "60", "--raster", "quad", "-o", str(out)]) == 0
    channels, header = read_exr(out)
    frame = dofview.render(dofview.load(cards), dofview.load_cameras(cams)[2].resized(96, 72),
                           dofview.Lens(4.0, 60.0 * 96 / 800), raster="quad")  # --aperture holds at the view's 800 px
    rgba = np.stack([channels[c] for c in "RGBA"], axis=-1)
    assert np.array_equal(rgba, frame.rgba) and np.array_equal(channels["Z"], frame.depth)
    api_header = frame.meta
    for key in ("dofview:camera", "dofview:render", "dofview:version"):
        assert header[key] == api_header[key]
    cli_lens, api_lens = json.loads(header["dofview:lens"]), json.loads(api_header["dofview:lens"])
    assert {k: cli_lens[k] for k in api_lens} == api_lens  # the CLI adds the physical-lens fields
