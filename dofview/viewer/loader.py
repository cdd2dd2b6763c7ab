"""Loading a scene file in the background, with a progress fraction and the error kept for the UI."""

from __future__ import annotations

import sys
import threading
import time
import traceback
from pathlib import Path

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.io.lod import LodSet, is_lod_set, open_lod
from dofview.io.runfolder import find_run
from dofview.scene import GaussianScene


class SceneLoad:
    """One scene file (or run folder) being read on a worker thread.

    Poll :attr:`done`; then either :attr:`scene` is set, or :attr:`error` holds a one-line message.
    :attr:`fraction` (0…1) and :attr:`elapsed` (s) drive the progress bar meanwhile. A run folder,
    or a file with a ``cameras.json`` near it (dofview.io.runfolder), also fills :attr:`cameras`,
    and :attr:`found` says what was found. A streamed LOD set is read at its finest level within
    ``budget`` Gaussians, and :attr:`lod_set` keeps it (the viewer streams its other chunks).
    """

    def __init__(self, path: str | Path, colour_space: str | None = None, budget: int | None = None) -> None:
        self.path = Path(path)
        self.colour_space = colour_space
        self.budget = budget
        self.lod_set: LodSet | None = None
        self.fraction = 0.0
        self.scene: GaussianScene | None = None
        self.cameras: list[Camera] = []
        self.found = ""
        self.error: str | None = None
        self._t0 = time.perf_counter()
        self._finished = threading.Event()
        threading.Thread(target=self._run, name="dofview-load", daemon=True).start()

    @property
    def done(self) -> bool:
        return self._finished.is_set()

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self._t0

    def wait(self, timeout: float | None = None) -> bool:
        return self._finished.wait(timeout)

    def _progress(self, done: int, total: int) -> None:
        self.fraction = done / max(total, 1)

    def _run(self) -> None:
        try:
            run = find_run(self.path)
            if run.cameras is not None:
                self.cameras = load_cameras_json(run.cameras)
            if run.cameras is not None or run.root is not None:
                self.found = run.describe(len(self.cameras) if self.cameras else None)
            self.path = run.scene
            self.lod_set = open_lod(self.path) if is_lod_set(self.path) else None
            scene = load_scene(self.path, progress=self._progress, budget=self.budget, lod_set=self.lod_set)
            if self.colour_space:
                scene.colour_space = self.colour_space
            self.scene = scene
        except DofviewError as e:
            self.error = str(e)
        except Exception as e:  # a bug or an unexpected library failure: keep the viewer alive, show it
            traceback.print_exc(file=sys.stderr)
            self.error = f"{self.path}: could not load ({type(e).__name__}: {e})"
        finally:
            self.fraction = 1.0
            self._finished.set()
