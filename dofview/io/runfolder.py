"""Run folders: what a 3DGS trainer leaves behind, opened as it was left.

The Inria trainer (and the many that copy its layout) writes a model folder::

    output/bicycle/
        cameras.json            the training views (dofview.io.cameras)
        cfg_args                the training arguments (a Python Namespace repr)
        point_cloud/iteration_7000/point_cloud.ply
        point_cloud/iteration_30000/point_cloud.ply

:func:`find_run` turns what the user gave (that folder, or a scene file inside such a folder) into
the scene file to read and the ``cameras.json`` that belongs to it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from dofview.errors import DofviewError

CAMERAS_NAME = "cameras.json"
_ITERATION = re.compile(r"^iteration_(\d+)$")


@dataclass(frozen=True)
class RunFolder:
    """What was found for one scene argument.

    Attributes:
        scene: the scene file to read.
        cameras: the run folder's ``cameras.json`` (an absolute path: it is said in full), or None.
        root: the run folder when the argument was one (or the scene sits in one), else None.
        iteration: the training iteration of ``scene`` when it came from ``point_cloud/iteration_N``.
        iterations: every iteration the run folder holds, ascending (empty for a plain file).
        cfg_args: the run's ``cfg_args`` file, or None.
    """

    scene: Path
    cameras: Path | None = None
    root: Path | None = None
    iteration: int | None = None
    iterations: tuple[int, ...] = ()
    cfg_args: Path | None = None

    def describe(self, views: int | None = None) -> str:
        """One line saying what was found, e.g. ``run folder out/bicycle: iteration 30000 (of 7000, 30000);
        cameras.json: 301 views``."""
        parts = []
        if self.iteration is not None:
            others = f" (of {', '.join(map(str, self.iterations))})" if len(self.iterations) > 1 else ""
            parts.append(f"iteration {self.iteration}{others}")
        if self.cameras is not None:
            parts.append(f"{self.cameras}: {views} views" if views is not None else str(self.cameras))
        else:
            parts.append("no cameras.json")
        where = f"run folder {self.root}" if self.root is not None else str(self.scene)
        return f"{where}: " + "; ".join(parts)


def _iterations(point_cloud: Path) -> dict[int, Path]:
    """iteration number → its point_cloud.ply, for every ``iteration_N`` folder that has one."""
    found = {}
    if point_cloud.is_dir():
        for d in point_cloud.iterdir():
            m = _ITERATION.match(d.name)
            if m and (d / "point_cloud.ply").is_file():
                found[int(m.group(1))] = d / "point_cloud.ply"
    return found


def _in_run(scene: Path, root: Path, iteration: int, iterations: tuple[int, ...]) -> RunFolder:
    """``scene`` of run folder ``root``, with the folder's cameras.json and cfg_args where it has them."""
    cameras, cfg = root / CAMERAS_NAME, root / "cfg_args"
    return RunFolder(scene, cameras.absolute() if cameras.is_file() else None, root, iteration, iterations,
                     cfg if cfg.is_file() else None)


def find_run(path: str | Path, iteration: int | None = None) -> RunFolder:
    """The scene file and cameras for ``path``: a run folder or a scene file.

    A folder must hold ``point_cloud/iteration_N/point_cloud.ply``; the highest N is taken unless
    ``iteration`` names one; a folder holding ``lod-meta.json`` (a streamed LOD set) or ``meta.json`` (an
    unbundled SOG) is a scene, read as such.
    A file is taken as it is; it has the run folder's ``cameras.json`` only when it sits where the
    trainer writes it, ``ROOT/point_cloud/iteration_N/point_cloud. py`` with ROOT holding
    ``cameras.json``. A ``cameras.json`` that merely lies in a folder above some scene file belongs to
    something else (issue 22: one above ``scenes/`` made ``scenes/biker.spz`` open looking at nothing).

    Raises:
        DofviewError: a folder without iterations, an iteration it does not have, or ``iteration``
            given with a file.
    """
    path = Path(path)
    if path.is_dir():
        found = _iterations(path / "point_cloud")
        for inside in ("lod-meta.json", "meta.json"):  # a streamed LOD set, an unbundled SOG: folder scenes
            if not found and iteration is None and (path / inside).is_file():
                return find_run(path / inside)
        if not found:
            raise DofviewError(f"{path}: is a directory, neither a scene file nor a 3DGS run folder "
                               f"(no point_cloud/iteration_N/point_cloud.ply in it)")
        its = tuple(sorted(found))
        if iteration is None:
            iteration = its[-1]
        elif iteration not in found:
            raise DofviewError(f"{path}: no iteration {iteration} (it has {', '.join(map(str, its))})")
        return _in_run(found[iteration], path, iteration, its)
    if iteration is not None:
        raise DofviewError(f"{path}: --iteration picks an iteration of a run folder; give the folder, not a file")
    m = _ITERATION.match(path.parent.name)
    if m and path.name == "point_cloud.ply" and path.parent.parent.name == "point_cloud":
        its = tuple(sorted(_iterations(path.parent.parent)))
        return _in_run(path, path.parent.parent.parent, int(m.group(1)), its)
    return RunFolder(path)
