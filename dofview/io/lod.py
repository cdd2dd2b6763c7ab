"""PlayCanvas streamed LOD sets (what SuperSplat and splat-transform publish large scenes as): a
``lod-meta.json`` beside one unbundled SOG (``meta.json`` + WebP images, :mod:`dofview.io.sog`) per
chunk. Open the ``lod-meta.json`` or its folder.

``lod-meta.json`` (``"version": 1``; files without a version predate it), as splat-transform 3.7
writes and reads it:

- ``lodLevels`` L: level 0 is the finest, L − 1 the coarsest;
- ``counts``: Gaussians per level, and ``count`` their sum (both absent from older files);
- ``filenames``: the chunks, relative to the ``lod-meta.json``'s folder; a chunk holds Gaussians of
  one level;
- ``tree``: a binary tree of boxes, ``{"bound": {"min": [x, y, z], "max": [x, y, z]}, "children":
  [node, node]}``, whose leaves name their Gaussians per level instead of children:
  ``"lods": {"0": {"file": i, "offset": o, "count": n}, …}`` are Gaussians o … o + n − 1 of chunk
  i (per-level ``errors``, written only with splat-transform's ``--lod-errors``, are not used);
- ``environment`` (optional): one more SOG whose Gaussians belong to every level (a backdrop).

A chunk's Gaussians are exactly the ranges its leaves name: disjoint, in one level, covering its
count. :func:`open_lod` checks all of that from the JSON files alone (the chunks' images are
decoded only when their Gaussians are asked for); a set that lies is refused, naming the file.
A single image is made by :func:`read_lod`: one level (``lod``, else the finest within ``budget``
Gaussians), every chunk decoded as :func:`dofview.io.sog.read_sog` decodes it. The viewer instead
draws a level per leaf, finer near the camera and coarser far (:meth:`LodSet.select`).
"""

from __future__ import annotations

import json
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from dofview.errors import DofviewError, SceneFormatError
from dofview.io._common import input_size, report_dropped
from dofview.io._packed import scene_and_finite
from dofview.io.sog import decode_sog, sog_header
from dofview.scene import GaussianScene

LOD_META = "lod-meta.json"
DEFAULT_BUDGET = 3_000_000
"""Gaussians drawn at most by default (``--budget``): the finest level within it, or in the viewer
the finest mix of levels."""
MAX_LOD_META = 64 << 20  # bytes: the tree of a 100M-Gaussian set is a few MB
MAX_LEVELS = 64
MAX_NODES = 1 << 22
DECODE_THREADS = 4  # chunks decoded at once (the WebP decoder lets go of the GIL)


def is_lod_set(path: str | Path) -> bool:
    """``path`` names a streamed LOD set: a ``lod-meta.json`` or a folder holding one."""
    path = Path(path)
    return path.name.lower().endswith(LOD_META) or (path.is_dir() and (path / LOD_META).is_file())


@dataclass(frozen=True)
class Chunk:
    """One chunk: an unbundled SOG of ``count`` Gaussians of level ``level`` (-1: the environment),
    SH degree ``degree`` (from its meta.json)."""

    path: Path
    level: int
    count: int
    degree: int


@dataclass
class _Decoded:
    """A decoded chunk: its Gaussians (``scene``, the set's SH degree) and which are finite (``ok``)."""

    scene: GaussianScene
    ok: np.ndarray


class LodSet:
    """A streamed LOD set, opened and checked (:func:`open_lod`); chunks are decoded on demand
    and kept until :meth:`keep_only` lets them go.

    Attributes:
        path: the ``lod-meta.json``.
        levels: L, the number of levels (0 finest).
        counts: (L,) int64 Gaussians per level, the environment not included.
        chunks: the chunks by their index in ``filenames`` (None for one no leaf names).
        environment: the environment chunk, or None.
        bounds: (K, 2, 3) float64 each leaf's box (min, max corners), scene units.
        refs: (K, L, 3) int64 each leaf's Gaussians of each level as (chunk, offset, count);
            (-1, 0, 0) where the leaf has none of that level.
        sh_degree: the highest SH degree of the chunks (lower ones are padded with zeros).
    """

    def __init__(self, path: Path, levels: int, chunks: list[Chunk | None], environment: Chunk | None,
                 bounds: np.ndarray, refs: np.ndarray) -> None:
        self.path, self.levels, self.chunks, self.environment = path, levels, chunks, environment
        self.bounds, self.refs = bounds, refs
        self.counts = refs[:, :, 2].sum(axis=0)
        used = [c for c in (*chunks, environment) if c is not None]
        self.sh_degree = max((c.degree for c in used), default=0)
        self.name = path.parent.name or path.stem
        self._decoded: dict[int, _Decoded] = {}
        self._lock = threading.Lock()

    @property
    def leaves(self) -> int:
        return int(self.bounds.shape[0])

    @property
    def environment_count(self) -> int:
        return self.environment.count if self.environment is not None else 0

    def describe(self) -> str:
        """The levels in words, e.g. ``2 levels: 1,495,636 / 746,973 Gaussians``."""
        env = f" + {self.environment_count:,} of environment" if self.environment is not None else ""
        return f"{self.levels} levels: {' / '.join(f'{int(c):,}' for c in self.counts)} Gaussians{env}"

    # ---- choosing -------------------------------------------------------------------------------
    def choose_level(self, lod: int | None = None, budget: int | None = None) -> tuple[int, str]:
        """The level one image draws, and why in words: ``lod`` when given, else the finest whose
        Gaussians (with the environment's) are within ``budget`` (default :data:`DEFAULT_BUDGET`),
        else the coarsest.

        Raises:
            DofviewError: ``lod`` is not a level of this set.
        """
        if lod is not None:
            if not 0 <= lod < self.levels:
                raise DofviewError(f"{self.path}: --lod {lod}: the set has levels 0 (finest) to {self.levels - 1}")
            return lod, "--lod"
        budget = DEFAULT_BUDGET if budget is None else budget
        for level in range(self.levels):
            if self.counts[level] > 0 and self.counts[level] + self.environment_count <= budget:
                return level, f"the finest within the budget of {budget:,}"
        return self.levels - 1, f"the coarsest; every level exceeds the budget of {budget:,}"

    def select(self, eye: np.ndarray, budget: int) -> np.ndarray:
        """(K,) int the level of each leaf for a camera at ``eye`` ((3,) scene units): leaves in
        order of their boxes' distance from the eye take the finest level that keeps every leaf
        not yet chosen at its coarsest within ``budget`` Gaussians, and no leaf is finer than a
        nearer one: finer near, coarser far. When even every leaf at its coarsest exceeds the
        budget, the farthest leaves are left out (level -1) until the rest fit."""
        eye = np.asarray(eye, np.float64)
        gap = np.maximum(np.maximum(self.bounds[:, 0] - eye, eye - self.bounds[:, 1]), 0.0)
        order = np.argsort(np.linalg.norm(gap, axis=1), kind="stable")
        n = self.refs[:, :, 2]
        coarsest = self.levels - 1
        choice = np.full(self.leaves, coarsest, np.int64)
        total = int(n[:, coarsest].sum()) + self.environment_count
        if total > budget:  # the farthest leaves go until the nearer ones fit at their coarsest
            kept = np.cumsum(n[order, coarsest]) + self.environment_count <= budget
            choice[order[~kept]] = -1
            return choice
        cap = 0  # no leaf farther than one at level l is finer than l
        for leaf in order:
            extra = n[leaf, :coarsest] - n[leaf, coarsest]
            fits = np.flatnonzero(total + extra[cap:] <= budget)
            if not fits.size:
                break
            choice[leaf] = cap = cap + int(fits[0])
            total += int(extra[cap])
        return choice

    def _refs(self, choice: np.ndarray) -> np.ndarray:
        """(M, 3) (chunk, offset, count) of the Gaussians that levels ``choice`` draw (count > 0)."""
        refs = self.refs[np.arange(self.leaves), np.maximum(choice, 0)]
        return refs[(choice >= 0) & (refs[:, 2] > 0)]

    def selection_count(self, choice: np.ndarray) -> int:
        """Gaussians drawn with levels ``choice`` ((K,) int, -1 none), the environment included."""
        return int(self._refs(choice)[:, 2].sum()) + self.environment_count

    # ---- decoding -------------------------------------------------------------------------------
    def level_scene(self, level: int, progress: Callable[[int, int], None] | None = None) -> GaussianScene:
        """Every Gaussian of ``level`` (and the environment's), chunks in file order."""
        return self.gather(np.full(self.leaves, level, np.int64), progress)

    def gather(self, choice: np.ndarray, progress: Callable[[int, int], None] | None = None) -> GaussianScene:
        """The Gaussians of each leaf at its level in ``choice`` ((K,) int, -1 none), and the environment's,
        as one sRGB scene: chunks in file order, each chunk's ranges in its order; chunks decoded
        as needed (Gaussians with a non-finite value dropped with one warning per chunk).

        Raises:
            SceneFormatError: a chunk that cannot be decoded (a missing or truncated image).
        """
        refs = self._refs(choice)
        files = sorted(set(refs[:, 0].tolist()))
        keys = files + ([-1] if self.environment is not None else [])
        self._decode(keys, progress)
        parts = []
        for f in files:
            own = refs[refs[:, 0] == f]
            own = own[np.argsort(own[:, 1])]
            idx = np.concatenate([np.arange(o, o + c) for _, o, c in own])
            d = self._decoded[f]
            parts.append(d.scene.subset(idx[d.ok[idx]]))
        if self.environment is not None:
            d = self._decoded[-1]
            parts.append(d.scene.subset(d.ok))
        return _concatenate(parts, self.sh_degree, self.name)

    def keep_only(self, choice: np.ndarray) -> None:
        """Let go of the decoded chunks that levels ``choice`` do not draw."""
        keep = set(self._refs(choice)[:, 0].tolist()) | {-1}
        with self._lock:
            for f in [f for f in self._decoded if f not in keep]:
                del self._decoded[f]

    def _decode(self, keys: list[int], progress: Callable[[int, int], None] | None) -> None:
        with self._lock:
            missing = [k for k in keys if k not in self._decoded]
        chunk = [self.environment if k == -1 else self.chunks[k] for k in keys]
        total = sum(c.count for c in chunk)
        done = sum(c.count for k, c in zip(keys, chunk) if k not in missing)
        if progress:
            progress(done, total)
        if not missing:
            return
        with ThreadPoolExecutor(min(DECODE_THREADS, len(missing), os.cpu_count() or 1)) as pool:
            for k, d in zip(missing, pool.map(lambda k: self._decode_one(k), missing)):
                with self._lock:
                    self._decoded[k] = d
                done += d.scene.count
                if progress:
                    progress(done, total)

    def _decode_one(self, key: int) -> _Decoded:
        c = self.environment if key == -1 else self.chunks[key]
        try:
            a = decode_sog(c.path)
        except SceneFormatError as e:
            raise SceneFormatError(f"{self.path}: {e}") from None
        if a.count != c.count:  # checked at open; a file changed since
            raise SceneFormatError(f"{self.path}: {c.path} holds {a.count:,} Gaussians; its meta.json said {c.count:,}")
        rest = a.sh_rest
        k = (self.sh_degree + 1) ** 2 - 1
        if k and (rest is None or rest.shape[1] < k):  # a lower degree than the set's: zero terms
            pad = np.zeros((a.count, k, 3), np.float32)
            if rest is not None:
                pad[:, :rest.shape[1]] = rest
            rest = pad
        scene, ok = scene_and_finite(a.means, a.quats, a.log_scales, a.opacities, a.sh_dc, rest, self.name)
        report_dropped(c.path, ok)
        return _Decoded(scene, ok)


def _concatenate(parts: list[GaussianScene], degree: int, name: str) -> GaussianScene:
    def cat(attr: str, shape: tuple[int, ...]) -> np.ndarray:
        return np.concatenate([getattr(p, attr) for p in parts]) if parts else np.zeros((0, *shape), np.float32)

    k = (degree + 1) ** 2 - 1
    return GaussianScene(means=cat("means", (3,)), quats=cat("quats", (4,)), scales=cat("scales", (3,)),
                         opacities=cat("opacities", ()), sh_dc=cat("sh_dc", (3,)),
                         sh_rest=cat("sh_rest", (k, 3)) if k else None, colour_space="srgb", name=name)


# ---- lod-meta.json -------------------------------------------------------------------------------
def _int(v: object, lo: int = 0) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and lo <= v < 1 << 40


def _corner(v: object) -> bool:
    return (isinstance(v, list) and len(v) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in v))


def _chunk_path(path: Path, name: object, what: str) -> Path:
    if not isinstance(name, str) or not name or Path(name).is_absolute() or ".." in Path(name).parts:
        raise SceneFormatError(f"{path}: bad {what} {name!r} in {LOD_META}")
    return path.parent / name


def _read_meta(path: Path) -> dict:
    if input_size(path) > MAX_LOD_META:
        raise SceneFormatError(f"{path}: {path.stat().st_size:,} bytes, too large for a {LOD_META}")
    try:
        meta = json.loads(path.read_bytes())
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise SceneFormatError(f"{path}: not valid JSON ({e})") from None
    if not isinstance(meta, dict):
        raise SceneFormatError(f"{path}: not a JSON object")
    if meta.get("version", 1) != 1:
        raise SceneFormatError(f"{path}: unsupported {LOD_META} version {meta.get('version')!r} (dofview reads 1)")
    levels = meta.get("lodLevels")
    if not _int(levels, 1) or levels > MAX_LEVELS:
        raise SceneFormatError(f"{path}: lodLevels must be a whole number from 1 to {MAX_LEVELS}, not {levels!r}")
    names = meta.get("filenames")
    if not isinstance(names, list) or len(names) > MAX_NODES:
        raise SceneFormatError(f"{path}: filenames must be a list of chunk files")
    if not isinstance(meta.get("tree"), dict):
        raise SceneFormatError(f"{path}: has no tree")
    return meta


def _leaves(path: Path, meta: dict) -> tuple[np.ndarray, np.ndarray]:
    """(K, 2, 3) boxes and (K, L, 3) (chunk, offset, count) of the tree's nodes that name Gaussians."""
    levels, files = meta["lodLevels"], len(meta["filenames"])
    bounds, refs = [], []
    stack, seen = [meta["tree"]], 0
    while stack:
        node = stack.pop()
        seen += 1
        if seen > MAX_NODES or not isinstance(node, dict):
            raise SceneFormatError(f"{path}: the tree has a node that is not an object (or over {MAX_NODES:,} nodes)")
        bound, children, lods = node.get("bound"), node.get("children", []), node.get("lods")
        if not isinstance(bound, dict) or not _corner(bound.get("min")) or not _corner(bound.get("max")):
            raise SceneFormatError(f"{path}: a tree node has no bound of min and max corners")
        if not isinstance(children, list) or (lods is None and not children):
            raise SceneFormatError(f"{path}: a tree node has neither children nor lods")
        stack.extend(reversed(children))
        if lods is None:
            continue
        if not isinstance(lods, dict):
            raise SceneFormatError(f"{path}: a tree leaf's lods is not an object")
        row = np.zeros((levels, 3), np.int64)
        row[:, 0] = -1
        for key, ref in lods.items():
            level = int(key) if isinstance(key, str) and key.isdigit() else -1
            if not 0 <= level < levels:
                raise SceneFormatError(f"{path}: a tree leaf names level {key!r}; the set has {levels} (lodLevels)")
            if (not isinstance(ref, dict) or not _int(ref.get("file")) or not _int(ref.get("offset"))
                    or not _int(ref.get("count"))):
                raise SceneFormatError(f"{path}: a tree leaf's level {key} is not a file, offset and count")
            if ref["file"] >= files:
                raise SceneFormatError(f"{path}: a tree leaf points at chunk {ref['file']}; filenames lists {files}")
            row[level] = ref["file"], ref["offset"], ref["count"]
        bounds.append([bound["min"], bound["max"]])
        refs.append(row)
    if not refs:
        raise SceneFormatError(f"{path}: the tree names no Gaussians")
    return np.asarray(bounds, np.float64).reshape(-1, 2, 3), np.stack(refs)


def open_lod(path: str | Path) -> LodSet:
    """Open a streamed LOD set (its ``lod-meta.json`` or folder) and check it against its chunks'
    meta.json files, decoding no image.

    Raises:
        SceneFormatError: bad JSON; a missing, malformed or unsupported field; a tree that points
            outside ``filenames`` or at levels the set lacks; a chunk file that is missing or whose
            Gaussians the leaves do not name exactly once, in one level; counts that are not the
            tree's.
    """
    path = Path(path)
    if path.is_dir():
        path = path / LOD_META
    meta = _read_meta(path)
    levels = meta["lodLevels"]
    bounds, refs = _leaves(path, meta)
    if np.any(bounds[:, 0] > bounds[:, 1]):
        raise SceneFormatError(f"{path}: a tree leaf's bound has min beyond max")
    chunks: list[Chunk | None] = [None] * len(meta["filenames"])
    used = refs[:, :, 2] > 0
    level_of = np.broadcast_to(np.arange(levels), used.shape)[used]
    for f, level in zip(refs[:, :, 0][used].tolist(), level_of.tolist()):
        if chunks[f] is not None and chunks[f].level != level:
            raise SceneFormatError(f"{path}: chunk {meta['filenames'][f]!r} is named by levels {chunks[f].level} and {level}")
        if chunks[f] is None:
            chunks[f] = Chunk(_chunk_path(path, meta["filenames"][f], "chunk file"), level, 0, 0)
    chunks = [None if c is None else _checked_chunk(path, c) for c in chunks]
    _check_ranges(path, refs[used], chunks)
    env = meta.get("environment")
    environment = None if env is None else _checked_chunk(path, Chunk(_chunk_path(path, env, "environment"), -1, 0, 0))
    lod = LodSet(path, levels, chunks, environment, bounds, refs)
    counts = meta.get("counts")
    if counts is not None and (not isinstance(counts, list) or counts != lod.counts.tolist()):
        raise SceneFormatError(f"{path}: counts {counts!r} are not the tree's ({lod.counts.tolist()})")
    if "count" in meta and meta["count"] != int(lod.counts.sum()):
        raise SceneFormatError(f"{path}: count {meta['count']!r} is not the tree's ({int(lod.counts.sum()):,})")
    return lod


def _checked_chunk(path: Path, chunk: Chunk) -> Chunk:
    """``chunk`` with its count and degree from its meta.json, whose files must exist."""
    try:
        count, degree = sog_header(chunk.path)
    except SceneFormatError as e:
        raise SceneFormatError(f"{path}: {e}") from None
    return Chunk(chunk.path, chunk.level, count, degree)


def _check_ranges(path: Path, refs: np.ndarray, chunks: list[Chunk | None]) -> None:
    """Each chunk's Gaussians named by ``refs`` ((M, 3) chunk, offset, count; count > 0) exactly once."""
    order = np.lexsort((refs[:, 1], refs[:, 0]))
    f, o, c = refs[order].T
    first = np.r_[True, f[1:] != f[:-1]]
    expected = np.where(first, 0, np.r_[0, o[:-1] + c[:-1]])  # each range starts where the last ended
    bad = np.flatnonzero(o != expected)
    if bad.size:
        i = int(bad[0])
        raise SceneFormatError(f"{path}: the tree's ranges of chunk {chunks[f[i]].path} overlap or leave a gap "
                               f"at Gaussian {int(min(o[i], expected[i])):,}")
    last = np.r_[f[1:] != f[:-1], True]
    for fi, end in zip(f[last].tolist(), (o + c)[last].tolist()):
        if end != chunks[fi].count:
            raise SceneFormatError(f"{path}: the tree names {end:,} Gaussians of {chunks[fi].path}, "
                                   f"which holds {chunks[fi].count:,}")


def read_lod(path: str | Path, progress: Callable[[int, int], None] | None = None, lod: int | None = None,
             budget: int | None = None, report: Callable[[str], None] | None = None,
             lod_set: LodSet | None = None) -> GaussianScene:
    """One level of a streamed LOD set as an sRGB scene: level ``lod``, else the finest whose
    Gaussians are within ``budget`` (default :data:`DEFAULT_BUDGET`). ``report`` gets one line
    saying the levels and the one read; ``lod_set``: the set already opened from ``path`` (its
    decoded chunks are kept, for the viewer's streaming).

    Raises:
        SceneFormatError: a bad set (:func:`open_lod`) or chunk.
        DofviewError: ``lod`` is not one of the set's levels.
    """
    lod_set = lod_set or open_lod(path)
    level, why = lod_set.choose_level(lod, budget)
    if report:
        report(f"{lod_set.path}: streamed LOD set, {lod_set.describe()}; level {level} ({why})")
    return lod_set.level_scene(level, progress)
