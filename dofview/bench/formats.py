"""What the distribution formats lose: each format's image error and per-attribute errors against
the ``.ply`` it was made from (``python -m dofview.bench.formats``; the tables in docs/FORMATS.md).

Files are made by the formats' own tool, PlayCanvas splat-transform (``scripts/setup.sh`` installs
it into ``.tools``), and by dofview's ``.spz`` writer; each is read back by dofview and rendered at
training view 0 of the sample beside the source, pinhole, with the source's colour space.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from dofview.api import load, load_cameras, render
from dofview.bench.metrics import psnr
from dofview.errors import DofviewError
from dofview.io import save_scene
from dofview.lens import Lens
from dofview.scene import GaussianScene

ROOT = Path(__file__).resolve().parents[2]
FORMATS = ("spz", "compressed.ply", "sog")
ATTRIBUTES = ("position", "log_scale", "opacity", "colour", "rotation", "sh_rest")


def splat_transform() -> str | None:
    """The splat-transform CLI: ``.tools`` of the source tree first, then PATH; None when absent."""
    local = ROOT / ".tools" / "node_modules" / ".bin" / "splat-transform"
    return str(local) if local.exists() else shutil.which("splat-transform")


def convert(src: Path, dst: Path) -> Path:
    """``splat-transform src dst`` on the CPU, overwriting; returns ``dst``.

    Raises:
        DofviewError: the tool is missing or fails.
    """
    tool = splat_transform()
    if tool is None:
        raise DofviewError("splat-transform is not installed (scripts/setup.sh installs it into .tools)")
    done = subprocess.run([tool, "-q", "-w", "-g", "cpu", str(src), str(dst)], capture_output=True, text=True,
                          check=False, timeout=600)
    if done.returncode:
        raise DofviewError(f"splat-transform {src.name} → {dst.name} failed: {done.stderr.strip()[-500:]}")
    return dst


def match(a: GaussianScene, b: GaussianScene, reach: float = 0.02) -> np.ndarray:
    """(N_a,) int: for each Gaussian of ``a`` the index of the nearest Gaussian of ``b`` in position
    (colour and log-scale break ties), for formats that reorder Gaussians (Morton order). Only
    Gaussians of ``b`` within ``reach`` scene units in x are candidates (the formats move positions
    far less), which keeps this near linear."""
    def features(s: GaussianScene) -> np.ndarray:
        return np.hstack([s.means, 1e-3 * np.clip(s.base_colour(), 0, 2), 1e-3 * np.log(s.scales)]).astype(np.float64)

    fa, fb = features(a), features(b)
    order = np.argsort(fb[:, 0], kind="stable")
    fb, xb = fb[order], fb[order, 0]
    lo = np.searchsorted(xb, fa[:, 0] - reach)
    hi = np.maximum(np.searchsorted(xb, fa[:, 0] + reach), lo + 1)
    out = np.empty(a.count, np.int64)
    rows = max(1, (1 << 22) // int((hi - lo).max()))  # bound the (rows, window) temporaries
    for s in range(0, a.count, rows):
        window = np.arange(int((hi[s:s + rows] - lo[s:s + rows]).max()))
        cand = np.minimum(lo[s:s + rows, None] + window, len(xb) - 1)
        d = ((fa[s:s + rows, None, :] - fb[cand]) ** 2).sum(-1)
        d[lo[s:s + rows, None] + window >= hi[s:s + rows, None]] = np.inf
        out[s:s + rows] = order[cand[np.arange(len(cand)), d.argmin(1)]]
    return out


def attribute_errors(got: GaussianScene, ref: GaussianScene) -> dict[str, float]:
    """Max absolute errors of ``got`` against ``ref`` (same count and order): position (scene
    units), log_scale, opacity, colour (base colour SH_C0·dc + 0.5), rotation (angle, radians) and
    sh_rest (coefficients; only when ``ref`` has them)."""
    q, q0 = got.unit_quats(), ref.unit_quats()
    angle = 2.0 * np.arccos(np.clip(np.abs(np.sum(q * q0, axis=1)), 0.0, 1.0))
    errors = {
        "position": np.abs(got.means - ref.means).max(),
        "log_scale": np.abs(np.log(got.scales) - np.log(ref.scales)).max(),
        "opacity": np.abs(got.opacities - ref.opacities).max(),
        "colour": np.abs(got.base_colour() - ref.base_colour()).max(),
        "rotation": angle.max(),
    }
    if ref.sh_rest is not None and got.sh_rest is not None:
        errors["sh_rest"] = np.abs(got.sh_rest - ref.sh_rest).max()
    return {k: float(v) for k, v in errors.items()}


def view_psnr(scene: GaussianScene, ref: GaussianScene, cameras: Path, size=(160, 120)) -> float:
    """PSNR (dB, linear RGBA, peak max(1, brightest reference value)) of ``scene`` against ``ref``
    at view 0 of ``cameras``, resized to ``size``, pinhole."""
    camera = load_cameras(cameras)[0].resized(*size)
    a = render(scene, camera, Lens(focus=1.0, aperture=0.0)).rgba
    b = render(ref, camera, Lens(focus=1.0, aperture=0.0)).rgba
    return psnr(a, b, max(1.0, float(b.max())))


def measure(source: Path, cameras: Path, folder: Path) -> list[tuple[str, float, dict[str, float]]]:
    """(label, PSNR, attribute errors) per format for one source ``.ply``."""
    ref = load(source)
    made = [(f"splat-transform .{ext}", convert(source, folder / f"{source.stem}.{ext}")) for ext in FORMATS]
    ours = folder / f"{source.stem}.dofview.spz"
    save_scene(ref, ours)
    made.append(("dofview .spz", ours))
    rows = []
    for label, path in made:
        # splat-transform writes .spz in PLY axes as they are; dofview writes the spec's RUB
        scene = load(path, colour_space=ref.colour_space,
                     spz_axes="rdf" if label == "splat-transform .spz" else None)
        same_order = label.endswith(".spz")
        errors = attribute_errors(scene, ref if same_order else ref.subset(match(scene, ref)))
        rows.append((label, view_psnr(scene, ref, cameras), errors))
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m dofview.bench.formats", description=__doc__.split("\n\n")[0])
    p.add_argument("samples", nargs="*", default=["cards", "lamp"], help="bundled samples (default cards lamp)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.samples:
            source = ROOT / "samples" / f"{name}.ply"
            print(f"\n{name}.ply ({load(source).count} Gaussians), view 0 at 160×120\n")
            print("| file | PSNR (dB) | " + " | ".join(ATTRIBUTES) + " |")
            print("|---|---:|" + "---:|" * len(ATTRIBUTES))
            for label, db, errors in measure(source, ROOT / "samples" / f"{name}_cameras.json", Path(tmp)):
                cells = [f"{errors[a]:.3g}" if a in errors else "–" for a in ATTRIBUTES]
                print(f"| {label} | {db:.1f} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
