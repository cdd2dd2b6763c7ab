"""Property-based fuzzing of the streamed LOD set reader (dofview/io/lod.py), modelled on
test_fuzz_formats.py: a set made by splat-transform (tests/lod_sets.py, with an environment) whose
lod-meta.json, or one chunk's meta.json, has values replaced or bytes mutated either loads a valid
scene at every level or raises DofviewError in one line naming the lod-meta.json — never another
exception, a hang or a huge allocation. 50 examples per property."""

import json
import shutil
import warnings

import pytest
from conftest import assert_valid_scene, mutate_bytes
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lod_sets import sh_set
from test_fuzz_formats import _json_values

from dofview.errors import DofviewError, DofviewWarning
from dofview.io import load_scene
from dofview.io.lod import open_lod

FUZZ = settings(max_examples=50, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A copy of the set (lod-meta.json, chunk folders, env) to mutate, and its original texts."""
    folder = tmp_path_factory.mktemp("fuzzlod") / "set"
    shutil.copytree(sh_set().parent, folder)
    chunk = folder / json.loads((folder / "lod-meta.json").read_text())["filenames"][0]
    return folder, (folder / "lod-meta.json").read_bytes(), chunk, chunk.read_bytes()


def check_every_level_loads_or_refuses(folder) -> None:
    path = folder / "lod-meta.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DofviewWarning)
        try:
            levels = open_lod(path).levels
            for level in range(min(levels, 3)):
                assert_valid_scene(load_scene(path, progress=False, lod=level))
            assert_valid_scene(load_scene(folder, progress=False))
        except DofviewError as e:
            assert str(path) in str(e) and "\n" not in str(e)


@FUZZ
@given(data=st.data())
def test_lod_meta_with_mutated_values(base, data):
    """lod-meta.json's values replaced or dropped (levels, counts, file names, tree nodes, ranges)."""
    folder, meta, chunk, chunk_meta = base
    chunk.write_bytes(chunk_meta)
    (folder / "lod-meta.json").write_text(json.dumps(_json_values(data, json.loads(meta))))
    check_every_level_loads_or_refuses(folder)


@FUZZ
@given(data=st.data())
def test_lod_meta_with_mutated_bytes(base, data):
    folder, meta, chunk, chunk_meta = base
    chunk.write_bytes(chunk_meta)
    (folder / "lod-meta.json").write_bytes(mutate_bytes(data, meta, kinds=("flip", "cut", "insert", "delete", "digit")))
    check_every_level_loads_or_refuses(folder)


@FUZZ
@given(data=st.data())
def test_chunk_meta_with_mutated_values(base, data):
    """A chunk's meta.json (count, codebooks, file names) changed under a valid lod-meta.json."""
    folder, meta, chunk, chunk_meta = base
    (folder / "lod-meta.json").write_bytes(meta)
    chunk.write_text(json.dumps(_json_values(data, json.loads(chunk_meta))))
    check_every_level_loads_or_refuses(folder)
