"""Property-based fuzzing of the distribution-format readers (.spz v2–v4, .compressed.ply, .sog):
mutated files either load a valid scene or raise DofviewError naming the file — never another
exception, a hang or a huge allocation. Modelled on test_fuzz_ply.py; 50 examples per property.

Valid bases: .spz written by dofview (v4) and rebuilt from its streams as gzip v3 and v2; a
.compressed.ply and a .sog (with an SH palette) made by splat-transform from a small random scene.
"""

import gzip
import io
import json
import struct
import warnings
import zipfile

import numpy as np
import pytest
from conftest import assert_valid_scene, mutate_bytes, random_scene
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dofview.bench.formats import convert, splat_transform
from dofview.errors import DofviewError, DofviewWarning
from dofview.io import load_scene
from dofview.io.ply import write_ply
from dofview.io.spz import _parse_v4, pack_spz

FUZZ = settings(max_examples=50, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


def _spz_bases() -> dict[str, bytes]:
    scene = random_scene(n=40, degree=1, seed=2)
    v4 = pack_spz(scene)
    _, n, degree, frac, flags, blocks, _ = _parse_v4(None, v4)
    legacy = struct.pack("<IIIBBBx", 0x5053474E, 3, n, degree, frac, flags)
    v3 = gzip.compress(legacy + b"".join(blocks))
    xyz = scene.unit_quats()[:, 1:] * np.where(scene.unit_quats()[:, :1] < 0, -1.0, 1.0)
    rot2 = np.clip(np.round(xyz * 127.5 + 127.5), 0, 255).astype(np.uint8).tobytes()
    v2 = gzip.compress(struct.pack("<IIIBBBx", 0x5053474E, 2, n, degree, frac, flags)
                       + b"".join(blocks[:4]) + rot2 + blocks[5])
    return {"v4": v4, "v3": v3, "v2": v2}


SPZ = _spz_bases()


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A small .compressed.ply and .sog from splat-transform: {ext: bytes}."""
    splat_transform() or pytest.fail("splat-transform is not installed: run scripts/setup.sh")
    folder = tmp_path_factory.mktemp("fuzzbase")
    ply = folder / "small.ply"
    write_ply(random_scene(n=300, degree=1, seed=4), ply)
    return {ext: convert(ply, folder / f"small.{ext}").read_bytes() for ext in ("compressed.ply", "sog")}


@pytest.fixture(scope="module")
def tmp_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


def check_loads_or_refuses(path, data: bytes) -> None:
    path.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DofviewWarning)
        try:
            scene = load_scene(path, progress=False)
        except DofviewError as e:
            assert str(path) in str(e) and "\n" not in str(e)
            return
    assert_valid_scene(scene)


@FUZZ
@given(version=st.sampled_from(sorted(SPZ)), data=st.data())
def test_mutated_spz(tmp_dir, version, data):
    check_loads_or_refuses(tmp_dir / "fuzz.spz", mutate_bytes(data, SPZ[version]))


@FUZZ
@given(version=st.sampled_from(["v3", "v2"]), data=st.data())
def test_mutated_spz_inside_the_gzip(tmp_dir, version, data):
    """The legacy stream mutated before compression, so the gzip layer stays valid."""
    raw = gzip.decompress(SPZ[version])
    check_loads_or_refuses(tmp_dir / "fuzz.spz", gzip.compress(mutate_bytes(data, raw)))


@FUZZ
@given(data=st.data())
def test_mutated_compressed_ply(made, tmp_dir, data):
    check_loads_or_refuses(tmp_dir / "fuzz.compressed.ply", mutate_bytes(data, made["compressed.ply"]))


@FUZZ
@given(data=st.data())
def test_mutated_sog_bundle(made, tmp_dir, data):
    check_loads_or_refuses(tmp_dir / "fuzz.sog", mutate_bytes(data, made["sog"]))


def _json_values(data, v):
    """``v`` with some of its numbers, strings and lists replaced by other JSON values."""
    if isinstance(v, dict):
        return {k: _json_values(data, x) for k, x in v.items() if data.draw(st.integers(0, 9)) > 0}
    if isinstance(v, list) and v and data.draw(st.integers(0, 5)) == 0:
        return data.draw(st.sampled_from([[], v[:1], v * 2, "x", None]))
    if isinstance(v, list):
        return [_json_values(data, x) for x in v]
    if data.draw(st.integers(0, 7)) == 0:
        return data.draw(st.sampled_from([0, -1, 2**40, 1.5, "", "../meta.json", None, True, [], {}]))
    return v


@FUZZ
@given(data=st.data())
def test_sog_with_mutated_meta_json(made, tmp_dir, data):
    """meta.json's values replaced or dropped (counts, codebooks, file names, versions)."""
    src = zipfile.ZipFile(io.BytesIO(made["sog"]))
    meta = _json_values(data, json.loads(src.read("meta.json")))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for info in src.infolist():
            z.writestr(info.filename, json.dumps(meta) if info.filename == "meta.json" else src.read(info))
    check_loads_or_refuses(tmp_dir / "fuzz.sog", out.getvalue())
