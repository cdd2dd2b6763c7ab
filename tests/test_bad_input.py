"""Bad files, bad arguments and failing outputs (issue 5): exit status 2, one line
``dofview: error: …`` naming the file and the problem, no traceback, and no output file left behind
(an existing one untouched).

Most cases run ``dofview.cli.main`` in-process. Permission cases need a process that file
permissions apply to: as root (CI containers) that is the ``dofview`` console script run under
``setpriv`` with CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH dropped; as another user plain chmod.
The full disk is a real 16 KiB tmpfs where mounting is allowed, and an injected ENOSPC everywhere.
"""

import errno
import os
import shutil
import subprocess
import sys
import tempfile
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import random_scene

import dofview.io.exr
from dofview.camera import look_at
from dofview.cli import main
from dofview.errors import DofviewError, DofviewWarning
from dofview.io.cameras import save_cameras_json
from dofview.io.exr import read_exr
from dofview.io.ply import read_ply, scene_rows, write_ply
from dofview.lens import Lens
from dofview.rendering.quad import QuadBackend

VIEW = ["--width", "24", "--height", "16", "--focus", "5"]
DOFVIEW = str(Path(sys.executable).with_name("dofview"))


def run_cli(capsys, *argv) -> tuple[int, str]:
    """(exit status, stderr) of ``dofview argv`` run in-process."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:  # argparse's own errors
        rc = e.code
    return rc, capsys.readouterr().err


def assert_one_line_error(rc, err, *needles) -> str:
    assert rc == 2, err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("dofview: error: ")
    for needle in needles:
        assert str(needle) in lines[0]
    return lines[0]


def assert_nothing_written(folder: Path, keep=()) -> None:
    """Only the inputs ``keep`` are in ``folder``: no output, no temporary file."""
    assert sorted(p.name for p in folder.iterdir()) == sorted(keep)


@pytest.fixture
def good_ply(tmp_path) -> Path:
    path = tmp_path / "in" / "good.ply"
    path.parent.mkdir()
    write_ply(random_scene(n=60, degree=1), path)
    return path


def ply_file(path: Path, props, n=4, fmt="binary_little_endian", body=None, elements="") -> Path:
    """A PLY with a vertex element of ``props`` [(name, PLY type)] and a random body (or ``body``)."""
    head = f"ply\nformat {fmt} 1.0\n{elements}element vertex {n}\n"
    head += "".join(f"property {t} {name}\n" for name, t in props) + "end_header\n"
    if body is None:
        body = np.random.default_rng(0).integers(0, 64, 4096, dtype=np.uint8).tobytes()
    path.write_bytes(head.encode() + body)
    return path


GAUSSIAN = [(name, "float") for name in scene_rows(random_scene(n=1)).dtype.names]


def _without(*names):
    return [(n, t) for n, t in GAUSSIAN if n not in names]


# ---- bad scene files ----------------------------------------------------------------------------------
def _truncated(d):
    path = d / "cut.ply"
    write_ply(random_scene(n=60), path)
    path.write_bytes(path.read_bytes()[:-7])
    return path, ["cut short", "60 Gaussians"]


def _count_lies(d):
    path = d / "lies.ply"
    write_ply(random_scene(n=3), path)
    path.write_bytes(path.read_bytes().replace(b"element vertex 3\n", b"element vertex 1000000000000\n"))
    return path, ["cut short", "1000000000000 Gaussians"]


def _missing(d):
    return ply_file(d / "missing.ply", _without("opacity", "scale_1", "rot_3")), [
        "missing Gaussian properties opacity, scale_1, rot_3"]


def _no_degree(d):
    props = GAUSSIAN + [(f"f_rest_{i}", "float") for i in range(8)]
    return ply_file(d / "rest.ply", props), ["8 f_rest_* properties is no SH degree"]


def _wrong_types(d):
    props = [(n, {"opacity": "uchar", "x": "int"}.get(n, t)) for n, t in GAUSSIAN]
    return ply_file(d / "types.ply", props), ["must be float or double", "x (i4)", "opacity (u1)"]


def _list_property(d):
    path = d / "list.ply"
    head = "ply\nformat ascii 1.0\nelement vertex 1\n" + "".join(
        f"property {'list uchar float' if n == 'rot_0' else t} {n}\n" for n, t in GAUSSIAN) + "end_header\n"
    path.write_text(head + " ".join("1" for _ in GAUSSIAN) + "\n")
    return path, ["must be float or double", "rot_0 (list)"]


def _point_cloud(d):
    props = [("x", "float"), ("y", "float"), ("z", "float"), ("red", "uchar"), ("green", "uchar"), ("blue", "uchar")]
    return ply_file(d / "cloud.ply", props), ["plain point cloud", "f_dc_0", "rot_3"]


def _empty(d):
    (d / "empty.ply").write_bytes(b"")
    return d / "empty.ply", ["file is empty"]


def _not_ply(d):
    (d / "photo.ply").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
    return d / "photo.ply", ["not a PLY file"]


def _directory(d):
    (d / "folder.ply").mkdir()
    return d / "folder.ply", ["is a directory"]


def _missing_file(d):
    return d / "nowhere.ply", ["no such file"]


BAD_FILES = [_truncated, _count_lies, _missing, _no_degree, _wrong_types, _list_property, _point_cloud, _empty,
             _not_ply, _directory, _missing_file]


@pytest.mark.parametrize("make", BAD_FILES, ids=lambda f: f.__name__[1:])
def test_bad_scene_file(tmp_path, capsys, make):
    inputs = tmp_path / "in"
    inputs.mkdir()
    path, needles = make(inputs)
    out = tmp_path / "out"
    out.mkdir()
    rc, err = run_cli(capsys, "render", path, "-o", out / "x.exr", "--png", out / "x.png", *VIEW)
    assert_one_line_error(rc, err, f"{path}:", *needles)
    assert_nothing_written(out)


def test_vertex_count_beyond_the_file_is_refused_before_allocating(tmp_path):
    """10^12 announced Gaussians (68 TB), binary and ASCII: refused with < 4 MiB allocated on the way
    (the loader reads up to 1 MiB of header)."""
    for fmt in ("binary_little_endian", "ascii"):
        body = b"0 " * len(GAUSSIAN) if fmt == "ascii" else b"\0" * 4 * len(GAUSSIAN)
        path = ply_file(tmp_path / f"{fmt}.ply", GAUSSIAN, n=10**12, fmt=fmt, body=body)
        tracemalloc.start()
        try:
            with pytest.raises(DofviewError, match="cut short: the header announces 1000000000000 Gaussians"):
                read_ply(path)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 4 << 20


def test_extra_unknown_properties_and_elements_load_fine(tmp_path, capsys):
    """Normals, a uchar and a list property, and a face element before the vertices are ignored."""
    rows = scene_rows(random_scene(n=40, seed=3))
    props = [(n, "float") for n in rows.dtype.names]
    extra = np.zeros(40, [("confidence", "u1"), ("seg", "<i4")])
    body = b"\x02" + b"\x00\x00\x00\x00" * 2 + b"\x00" + _merge(rows, extra).tobytes()
    path = ply_file(tmp_path / "extra.ply", props + [("confidence", "uchar"), ("seg", "int")], n=40, body=body,
                    elements="element face 2\nproperty list uchar int vertex_indices\n")
    scene = read_ply(path)
    np.testing.assert_array_equal(scene.means, random_scene(n=40, seed=3).means)
    rc, err = run_cli(capsys, "render", path, "-o", tmp_path / "x.exr", *VIEW)
    assert rc == 0 and "error" not in err and (tmp_path / "x.exr").is_file()


def _merge(a, b):
    out = np.zeros(len(a), a.dtype.descr + b.dtype.descr)
    for rows in (a, b):
        for n in rows.dtype.names:
            out[n] = rows[n]
    return out


def test_nan_and_inf_gaussians_are_dropped_with_one_warning_and_the_rest_render(tmp_path, capsys):
    scene = random_scene(n=80, degree=1, seed=4)
    rows = scene_rows(scene)
    bad = {0: ("x", np.nan), 5: ("f_dc_1", np.inf), 9: ("opacity", np.nan), 17: ("scale_2", -np.inf),
           30: ("rot_3", np.nan), 41: ("f_rest_7", np.inf), 42: ("nx", np.nan)}  # nx is not read: kept
    for i, (name, value) in bad.items():
        rows[name][i] = value
    path = tmp_path / "nan.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 80\n"
                     + b"".join(f"property float {n}\n".encode() for n in rows.dtype.names)
                     + b"end_header\n" + rows.tobytes())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = read_ply(path)
    assert [str(w.message) for w in caught] == [f"{path}: dropped 6 of 80 Gaussians with NaN or infinite values"]
    assert caught[0].category is DofviewWarning
    keep = np.setdiff1d(np.arange(80), [0, 5, 9, 17, 30, 41])
    np.testing.assert_array_equal(loaded.means, scene.means[keep])

    rc, err = run_cli(capsys, "render", path, "-o", tmp_path / "x.exr", *VIEW, "--eye", "0,0,0", "--target", "0,0,5")
    assert rc == 0
    assert [line for line in err.splitlines() if "dofview:" in line] == [
        f"dofview: warning: {path}: dropped 6 of 80 Gaussians with NaN or infinite values"]
    assert "Traceback" not in err and "warnings.warn" not in err
    channels, _ = read_exr(tmp_path / "x.exr")
    clean = QuadBackend(scene.subset(keep)).render(look_at([0, 0, 0], [0, 0, 5], 24, 16, 50), Lens(5.0, 0.0))
    for i, c in enumerate("RGBA"):
        np.testing.assert_array_equal(channels[c], clean.rgba[..., i])


def test_unreadable_scene_file(tmp_path, unprivileged):
    path = tmp_path / "secret.ply"
    write_ply(random_scene(n=10), path)
    path.chmod(0)
    p = unprivileged(DOFVIEW, "render", path, "-o", tmp_path / "x.exr", *VIEW)
    assert_one_line_error(p.returncode, p.stderr, f"{path}:", "Permission denied")
    assert not (tmp_path / "x.exr").exists()


# ---- bad arguments ------------------------------------------------------------------------------------
@pytest.fixture
def cameras(tmp_path) -> Path:
    path = tmp_path / "in" / "cameras.json"
    path.parent.mkdir(exist_ok=True)
    save_cameras_json([look_at([0, 0, 0], [0, 0, 5], 24, 16), look_at([0.5, 0, 0], [0, 0, 5], 24, 16)], path)
    return path


@pytest.mark.parametrize("argv,needles", [
    (["--aperture", "-1"], ["argument --aperture: aperture must be ≥ 0, got -1"]),
    (["--fnumber", "-2", "--focal-mm", "50"], ["argument --fnumber: f-number must be > 0, got -2"]),
    (["--fnumber", "0", "--focal-mm", "50"], ["argument --fnumber: f-number must be > 0, got 0"]),
    (["--tau", "1"], ["argument --tau: tau must be in [0, 1), got 1"]),
    (["--tau", "-0.01"], ["argument --tau: tau must be in [0, 1), got -0.01"]),
    (["--tau", "3/2"], ["argument --tau: tau must be in [0, 1), got 3/2"]),
    (["--exposure", "nan"], ["argument --exposure: exposure must be finite, got 'nan'"]),
    (["--width", "0"], ["argument --width: width must be ≥ 1, got 0"]),
    (["--height", "-3"], ["argument --height: height must be ≥ 1, got -3"]),
    (["--focus", "0"], ["argument --focus: focus distance must be > 0, got 0"]),
    (["--view", "nope"], ["cameras.json: no camera named 'nope'"]),
    (["--view", "7"], ["cameras.json: view index 7 out of range (0…1)"]),
    (["--fnumber", "2", "--focal-mm", "50", "--focus", "0.05"], ["focus distance 0.05 must be beyond the focal length"]),
    (["--width", "100000"], ["100000×16 exceeds this OpenGL's limit"]),
    (["--up", "-z"], ["argument --up: expected one argument (one that starts with '-' is written --up=-…)"]),
    # a reader's option for a file it does not read, or a deep setting without --deep: dropped without a word before
    (["--lod", "2"], ["good.ply: --lod is for streamed LOD sets (lod-meta.json); this scene is not one"]),
    (["--budget", "3M"], ["good.ply: --budget is for streamed LOD sets"]),
    (["--spz-axes", "rdf"], ["good.ply: --spz-axes is for .spz files"]),
    (["--deep-cap", "4"], ["--deep-cap shapes the deep image: it needs --deep OUT.exr"]),
    (["--deep-tolerance", "0.1"], ["--deep-tolerance shapes the deep image: it needs --deep OUT.exr"]),
    (["--cameras", "{cameras}", "--fov", "20"], ["cameras.json: its views have their own field of view"]),
])
def test_invalid_cli_values(tmp_path, capsys, good_ply, cameras, argv, needles):
    """argparse-style errors: one line, exit 2, nothing written."""
    argv = [str(cameras) if a == "{cameras}" else a for a in argv]
    view = [] if "--cameras" in argv else ["--cameras", cameras] if "--view" in argv else ["--eye", "0,0,0", "--target", "0,0,5"]
    out = tmp_path / "out"
    out.mkdir()
    base = {"--width": "24", "--height": "16", "--focus": "5"}
    for flag in argv[::2]:
        base.pop(flag, None)
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "x.exr", *view,
                      *[v for kv in base.items() for v in kv], *argv)
    assert_one_line_error(rc, err, *needles)
    assert_nothing_written(out)


@pytest.mark.parametrize("argv,needles", [
    (["--views", "1", "--focus", "3", "--ks", "0.25"], ["--focus, --ks: not read with --views"]),
    (["--views", "1", "--tau", "0.02", "--near", "0.5"], ["--tau, --near: not read with --views"]),
    (["--views", "1", "--eye", "0,0,0", "--target", "0,0,5"], ["--eye, --target: not read with --views"]),
    (["--views", "1", "--view", "2"], ["--view: not read with --views"]),
    (["--coc-px", "4"], ["--coc-px: read only by the study of --views N"]),
])
def test_bench_refuses_options_its_mode_does_not_read(tmp_path, capsys, good_ply, argv, needles):
    """The full bench and the study of --views read different options; one the mode would drop is
    refused before anything is measured."""
    out = tmp_path / "out"
    rc, err = run_cli(capsys, "bench", good_ply, "--quick", "--no-plots", "--out", out, *argv)
    assert_one_line_error(rc, err, *needles)
    assert not out.exists()


def test_a_view_index_without_cameras_is_refused(tmp_path, capsys, good_ply):
    """--view of a scene without cameras (no --cameras, no run folder) used to frame the overview
    anyway, the index dropped without a word."""
    rc, err = run_cli(capsys, "render", good_ply, "-o", tmp_path / "x.exr", "--width", "24", "--height", "16",
                      "--view", "3")
    assert_one_line_error(rc, err, "--view picks a view of --cameras", "good.ply has none")
    assert not (tmp_path / "x.exr").exists()


# ---- outputs ------------------------------------------------------------------------------------------
def test_missing_output_folders_are_made_once_everything_is_checked(tmp_path, capsys, good_ply):
    """As renderers do: `-o out/biker.exr --png out/biker.png` in an empty folder makes out/ (it
    used to fail with 'folder out does not exist'); a command that fails its checks makes none."""
    out, png = tmp_path / "nope" / "deeper" / "x.exr", tmp_path / "pngs" / "x.png"
    rc, err = run_cli(capsys, "render", good_ply, "-o", out, "--png", png, *VIEW)
    assert rc == 0, err
    assert out.is_file() and png.is_file()
    later = tmp_path / "later" / "x.exr"
    rc, err = run_cli(capsys, "render", tmp_path / "missing.ply", "-o", later, *VIEW)
    assert_one_line_error(rc, err, "missing.ply")
    assert not later.parent.exists()


def test_output_under_a_file_is_an_error_before_rendering(tmp_path, capsys, good_ply):
    (tmp_path / "plain").write_bytes(b"a file")
    out = tmp_path / "plain" / "sub" / "x.exr"
    rc, err = run_cli(capsys, "render", good_ply, "-o", out, *VIEW)
    assert_one_line_error(rc, err, f"{out}:", f"{tmp_path / 'plain'} is a file, not a folder")
    assert (tmp_path / "plain").read_bytes() == b"a file" and sorted(p.name for p in tmp_path.iterdir()) == ["in", "plain"]


def test_unwritable_png_place_leaves_no_exr_behind_even_as_root(tmp_path, capsys, good_ply):
    """`-o out/ok.exr --png /sys/out.png`: permission bits let root through (os.access says yes),
    the file system does not; the place is tried before rendering, and out/ok.exr is not written."""
    place = Path("/sys")
    try:
        tempfile.NamedTemporaryFile(dir=place).close()
        pytest.skip("/sys can be written in here")
    except OSError:
        pass
    out = tmp_path / "out" / "ok.exr"
    rc, err = run_cli(capsys, "render", good_ply, "-o", out, "--png", place / "out.png", *VIEW)
    assert_one_line_error(rc, err, f"{place / 'out.png'}:", f"cannot write in {place}")
    assert not out.exists() and not out.parent.exists()


def test_read_only_output_directory(tmp_path, good_ply, unprivileged):
    """A real permission refusal (see the module docstring); the existing file stays as it was."""
    ro = tmp_path / "ro"
    ro.mkdir()
    (ro / "x.exr").write_bytes(b"previous render")
    ro.chmod(0o555)
    try:
        p = unprivileged(DOFVIEW, "render", good_ply, "-o", ro / "x.exr", *VIEW)
        assert_one_line_error(p.returncode, p.stderr, f"{ro / 'x.exr'}:", "Permission denied")
        assert_nothing_written(ro, keep=["x.exr"])
        assert (ro / "x.exr").read_bytes() == b"previous render"
    finally:
        ro.chmod(0o755)


def test_unwritable_output_directory_in_process(tmp_path, capsys, good_ply, monkeypatch):
    """The same refusal injected where the temporary file is created (EACCES), for any user."""
    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    rc, err = run_cli(capsys, "render", good_ply, "-o", tmp_path / "x.exr", *VIEW)
    assert_one_line_error(rc, err, f"{tmp_path / 'x.exr'}:", "Permission denied")
    assert not (tmp_path / "x.exr").exists()


class _DiskFullExr:
    """Stands in for OpenEXR.File: writes part of a file, then fails as OpenEXR does on ENOSPC."""

    def __init__(self, header, channels):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def write(self, name):
        Path(name).write_bytes(b"v/1\x01" + b"\0" * 2000)  # an EXR's magic number, then nothing
        raise RuntimeError(f'Failed to write pixel data to image file "{name}". No space left on device.')


def test_full_disk_simulated(tmp_path, capsys, good_ply, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "x.exr").write_bytes(b"previous render")
    monkeypatch.setattr(dofview.io.exr.OpenEXR, "File", _DiskFullExr)
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "x.exr", *VIEW)
    assert_one_line_error(rc, err, f"{out / 'x.exr'}:", "No space left on device", "nothing was written")
    assert_nothing_written(out, keep=["x.exr"])
    assert (out / "x.exr").read_bytes() == b"previous render"


def test_full_disk_on_a_tiny_tmpfs(tmp_path, capsys, good_ply, tiny_tmpfs):
    """A real ENOSPC: the EXR (≈ 100 KiB of noise) does not fit; then the PNG does not either."""
    (tiny_tmpfs / "x.exr").write_bytes(b"previous render")
    big = ["--width", "200", "--height", "150", "--focus", "5", "--eye", "0,0,0", "--target", "0,0,5"]
    rc, err = run_cli(capsys, "render", good_ply, "-o", tiny_tmpfs / "x.exr", *big)
    assert_one_line_error(rc, err, f"{tiny_tmpfs / 'x.exr'}:", "No space left on device")
    assert_nothing_written(tiny_tmpfs, keep=["x.exr"])
    assert (tiny_tmpfs / "x.exr").read_bytes() == b"previous render"
    (tiny_tmpfs / "x.exr").unlink()
    rc, err = run_cli(capsys, "render", good_ply, "-o", tmp_path / "x.exr", "--png", tiny_tmpfs / "x.png",
                      "--width", "600", "--height", "400", "--focus", "5")
    assert_one_line_error(rc, err, f"{tiny_tmpfs / 'x.png'}:", "No space left on device")
    assert_nothing_written(tiny_tmpfs)


def test_existing_output_is_replaced_only_when_complete(tmp_path, capsys, good_ply, monkeypatch):
    """An interrupt mid-write keeps the old file (and no temporary); a finished write replaces it."""
    out = tmp_path / "x.exr"
    out.write_bytes(b"previous render")

    def interrupted(self, name):
        Path(name).write_bytes(b"v/1\x01")
        raise KeyboardInterrupt

    real = dofview.io.exr.OpenEXR.File
    with monkeypatch.context() as m:
        m.setattr(real, "write", interrupted)
        rc, err = run_cli(capsys, "render", good_ply, "-o", out, *VIEW)
    assert rc == 130 and err.splitlines() == ["dofview: interrupted"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "x.exr"] and out.read_bytes() == b"previous render"
    rc, err = run_cli(capsys, "render", good_ply, "-o", out, *VIEW)
    assert rc == 0
    assert read_exr(out)[0]["A"].shape == (16, 24)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "x.exr"]


# ---- fixtures for real permission and disk failures ---------------------------------------------------
@pytest.fixture
def unprivileged():
    """Run a command as a process that file permissions apply to; returns a runner."""
    if os.geteuid() == 0:
        if not shutil.which("setpriv"):
            pytest.skip("running as root without setpriv: permissions cannot be enforced")
        caps = "-dac_override,-dac_read_search"
        prefix = ["setpriv", f"--inh-caps={caps}", f"--bounding-set={caps}"]
    else:
        prefix = []

    def run(*argv):
        return subprocess.run(prefix + [str(a) for a in argv], capture_output=True, text=True, timeout=120)

    return run


@pytest.fixture
def tiny_tmpfs():
    """A 16 KiB tmpfs (needs mount rights: root in a container that allows it)."""
    folder = Path(tempfile.mkdtemp(prefix="dofview-full-"))
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(folder)], capture_output=True)
    if p.returncode != 0:
        folder.rmdir()
        pytest.skip("cannot mount a tmpfs here; test_full_disk_simulated covers ENOSPC")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)
        folder.rmdir()


# ---- scenes with nothing to draw, cameras that see nothing (issue 22) --------------------------------
def _ply_of(scene, path: Path) -> Path:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DofviewWarning)
        write_ply(scene, path)
    return path


@pytest.mark.parametrize("spoil,needle", [
    ("nan", "no drawable Gaussian: all 40 have NaN or infinite values"),
    ("transparent", "no drawable Gaussian: all 40 are transparent"),
])
def test_a_scene_with_no_drawable_gaussian_is_a_one_line_error_for_every_command(tmp_path, capsys, spoil, needle):
    """Was: the NaN file loaded as an empty scene, "give --focus" and, with --focus, a black image and exit 0."""
    scene = random_scene(n=40, seed=3)
    if spoil == "nan":
        scene.means[:] = np.nan
    else:
        scene.opacities[:] = 0.0
    (tmp_path / "in").mkdir()
    path = _ply_of(scene, tmp_path / "in" / "bad.ply")
    out = tmp_path / "out"
    out.mkdir()
    for argv in (["render", path, "-o", out / "x.exr", *VIEW],
                 ["render", path, "-o", out / "x.exr", "--width", "24", "--height", "16"]):
        rc, err = run_cli(capsys, *argv)
        assert_one_line_error(rc, err, f"{path}: ", needle)
    assert_nothing_written(out)
    from dofview.io import load_scene
    with pytest.raises(DofviewError, match=needle):  # the API, the viewer's loader and bench read through it
        load_scene(path, progress=False)


def test_a_camera_that_sees_none_of_the_scene_says_so(tmp_path, capsys, good_ply):
    """cameras.json view 0 looks away from the scene: the error names the view, the cameras file in
    full and that none of the scene's Gaussians is in view, not "give --focus"; with --focus the
    empty image is written and a warning says why it is empty."""
    cams = tmp_path / "in" / "cameras.json"
    save_cameras_json([look_at([0, 0, 0], [0, 0, -5], 24, 16)], cams)  # the scene is around z = +5
    out = tmp_path / "out"
    out.mkdir()
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "x.exr", "--cameras", cams)
    line = assert_one_line_error(rc, err, f"camera 'view_000' of {cams.absolute()} sees none of the 60 Gaussians "
                                          f"of {good_ply}")
    assert "give --focus to render the empty view" in line
    assert_nothing_written(out)
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "x.exr", "--eye", "0,0,0", "--target", "0,0,-5",
                      "--width", "24", "--height", "16")
    assert_one_line_error(rc, err, "the camera of --eye/--target sees none of the 60 Gaussians")
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "x.exr", "--cameras", cams, "--focus", "5")
    assert rc == 0
    assert (f"dofview: warning: camera 'view_000' of {cams.absolute()} sees none of the 60 Gaussians of "
            f"{good_ply}: the image is empty") in err.splitlines()
    channels, _ = read_exr(out / "x.exr")
    assert channels["A"].max() == 0.0  # the warning is right: nothing was drawn
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "y.exr", "--eye", "0,0,0", "--target", "0,0,5",
                      "--width", "24", "--height", "16")
    assert rc == 0 and "sees none" not in err  # a camera that sees the scene is not warned about


# ---- every output path is checked before anything is rendered (issue 22) --------------------------------
@pytest.mark.parametrize("png,needle", [
    ("x.jpg", "--png must name a .png file"),
    ("plain/x.png", "plain is a file, not a folder"),
    ("taken.png", "is a folder, not a file name"),
])
def test_bad_png_path_leaves_no_exr_behind(tmp_path, capsys, good_ply, png, needle):
    out = tmp_path / "out"
    out.mkdir()
    (out / "taken.png").mkdir()
    (out / "plain").write_bytes(b"a file")
    rc, err = run_cli(capsys, "render", good_ply, "-o", out / "x.exr", "--png", out / png, *VIEW)
    assert_one_line_error(rc, err, f"{out / png}:", needle)
    assert_nothing_written(out, keep=["taken.png", "plain"])


def test_bad_sequence_png_path_leaves_no_frame_behind(tmp_path, capsys, good_ply):
    out = tmp_path / "out"
    out.mkdir()
    (out / "plain").write_bytes(b"a file")
    png = out / "plain" / "f_%04d.png"
    rc, err = run_cli(capsys, "render", good_ply, "--frames", "3", "--focus", "2:8", "-o", out / "f_%04d.exr",
                      "--png", png, *VIEW[:4])
    assert_one_line_error(rc, err, f"{png}:", f"{out / 'plain'} is a file, not a folder")
    assert_nothing_written(out, keep=["plain"])


def test_read_only_png_folder_leaves_no_exr_behind(tmp_path, good_ply, unprivileged):
    out, ro = tmp_path / "out", tmp_path / "ro"
    out.mkdir()
    ro.mkdir()
    ro.chmod(0o555)
    try:
        p = unprivileged(DOFVIEW, "render", good_ply, "-o", out / "x.exr", "--png", ro / "x.png", *VIEW)
        assert_one_line_error(p.returncode, p.stderr, f"{ro / 'x.png'}:", "Permission denied")
        assert_nothing_written(out)
    finally:
        ro.chmod(0o755)
