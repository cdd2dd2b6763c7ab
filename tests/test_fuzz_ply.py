"""Property-based fuzzing of the .ply loader: random and mutated headers and bodies either load a
valid scene or raise DofviewError — never another exception, a hang or a huge allocation.

Bounded: a few hundred examples per property (deadline off, llvmpipe machines are slow and shared).
"""

import io
import warnings

import plyfile
import pytest
from conftest import assert_valid_scene, mutate_bytes, random_scene
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dofview.errors import DofviewError, DofviewWarning
from dofview.io.ply import REQUIRED, read_ply, scene_rows
from dofview.io.ply_header import PLY_TYPES

FUZZ = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _ply_bytes(degree: int, fmt: str, n: int = 3) -> bytes:
    rows = scene_rows(random_scene(n=n, degree=degree, seed=degree))
    buf = io.BytesIO()
    el = plyfile.PlyElement.describe(rows, "vertex")
    plyfile.PlyData([el], text=fmt == "ascii", byte_order=">" if fmt == "binary_big_endian" else "<",
                    comments=["dofview colour_space linear"]).write(buf)
    return buf.getvalue()


BASES = [_ply_bytes(d, f) for d in (0, 1, 3) for f in ("ascii", "binary_little_endian", "binary_big_endian")]
HEADER_WORDS = ["ply", "format", "ascii", "binary_little_endian", "binary_big_endian", "1.0", "element", "vertex",
                "face", "property", "list", "uchar", "int", "float", "double", "comment", "end_header",
                "0", "1", "2", "3", "9", "99999999999999999999", "-1", "nan", *REQUIRED, "f_rest_0", "f_rest_8",
                "red", "nx", *PLY_TYPES]


def check_loads_or_refuses(tmp_dir, data: bytes) -> None:
    path = tmp_dir / "fuzz.ply"
    path.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DofviewWarning)
        try:
            scene = read_ply(path)
        except DofviewError as e:
            assert str(path) in str(e)
            return
    assert_valid_scene(scene)


@pytest.fixture(scope="module")
def tmp_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@FUZZ
@given(base=st.sampled_from(BASES), data=st.data())
def test_mutated_files(tmp_dir, base, data):
    """Byte flips, cuts, insertions and deletions anywhere in a valid file (header or body)."""
    check_loads_or_refuses(tmp_dir, mutate_bytes(data, base, kinds=("flip", "cut", "insert", "delete", "digit")))


@FUZZ
@given(lines=st.lists(st.lists(st.sampled_from(HEADER_WORDS), min_size=1, max_size=6), max_size=30),
       body=st.binary(max_size=512), fmt=st.sampled_from(["ascii", "binary_little_endian", "binary_big_endian"]))
def test_random_headers_and_bodies(tmp_dir, lines, body, fmt):
    """Headers assembled from PLY keywords and property names, with random bodies."""
    header = ["ply", f"format {fmt} 1.0"] + [" ".join(words) for words in lines] + ["end_header"]
    check_loads_or_refuses(tmp_dir, ("\n".join(header) + "\n").encode() + body)


@FUZZ
@given(base=st.sampled_from(BASES), count=st.one_of(st.integers(0, 10), st.integers(0, 2**64)),
       extra=st.binary(max_size=64))
def test_vertex_counts_that_lie(tmp_dir, base, count, extra):
    """The header's vertex count replaced by anything up to 2^64 (never allocated before checking)."""
    head, sep, body = base.partition(b"end_header\n")
    lines = [(f"element vertex {count}".encode() if ln.startswith(b"element vertex") else ln)
             for ln in head.split(b"\n")]
    check_loads_or_refuses(tmp_dir, b"\n".join(lines) + sep + body + extra)


@FUZZ
@given(body=st.binary(max_size=2048))
def test_random_bytes(tmp_dir, body):
    check_loads_or_refuses(tmp_dir, body)
    check_loads_or_refuses(tmp_dir, b"ply\n" + body)
