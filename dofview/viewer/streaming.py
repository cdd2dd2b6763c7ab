"""Streaming a LOD set's chunks as the viewer's camera moves, off the UI thread.

The viewer asks (:meth:`LodStream.request`, every frame, cheap) for the camera it draws; a worker
thread chooses each leaf's level for the latest camera asked (:meth:`dofview.io.lod.LodSet.select`:
finer near, coarser far, within the Gaussian budget) and, when the choice differs from the one
drawn, decodes the chunks it needs, gathers their Gaussians, packs them for the GPU and sorts them
for that camera. The UI thread takes a finished swap (:meth:`LodStream.take`) and hands it to
:meth:`Renderer.swap_scene <dofview.rendering.base.Renderer.swap_scene>`, which only uploads: no
frame waits for a decode, a pack or a sort.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io.lod import LodSet
from dofview.rendering.depth_order import front_to_back
from dofview.rendering.packing import gpu_arrays
from dofview.scene import GaussianScene


@dataclass
class Swap:
    """A subset made for ``camera``: its ``scene``, storage ``arrays``, front-to-back ``order`` for
    the camera, the leaves' levels ``choice`` ((K,) int; -1 left out) and the seconds it took."""

    scene: GaussianScene
    arrays: dict[int, np.ndarray]
    order: np.ndarray
    camera: Camera
    choice: np.ndarray
    seconds: float


class LodStream:
    """One worker thread streaming ``lod_set`` for a renderer that stores its scene ``packed`` with
    colour scale ``colour_scale``; ``choice`` is the leaves' levels of the scene drawn at the start.

    ``error`` holds the last failure in one line (a chunk that cannot be decoded): the scene drawn
    stays, and the stream waits for the next view.
    """

    def __init__(self, lod_set: LodSet, budget: int, packed: bool, colour_scale: float, choice: np.ndarray) -> None:
        self.lod_set, self.budget = lod_set, budget
        self._pack: Callable[[GaussianScene], dict[int, np.ndarray]] = lambda s: gpu_arrays(s, packed, colour_scale)
        self.choice = np.asarray(choice)  # the leaves' levels drawn (or on their way)
        self.error: str | None = None
        self.swaps = 0
        self.made_s = 0.0  # the worker's time for the last swap taken (decode, gather, pack, sort)
        self._cond = threading.Condition()
        self._camera: Camera | None = None
        self._eye: np.ndarray | None = None
        self._result: Swap | None = None
        self._busy = False
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="dofview-lod", daemon=True)
        self._thread.start()

    def request(self, camera: Camera) -> None:
        """Stream for ``camera`` (the latest request replaces one not yet started)."""
        eye = camera.centre
        with self._cond:
            if self._eye is not None and np.array_equal(eye, self._eye):
                return  # levels follow the eye alone: turning the camera needs no new choice
            self._eye, self._camera = eye, camera
            self._cond.notify()

    def take(self) -> Swap | None:
        """The newest finished swap not taken yet, or None."""
        with self._cond:
            res, self._result = self._result, None
        if res is not None:
            self.swaps += 1
            self.made_s = res.seconds
        return res

    @property
    def pending(self) -> bool:
        """A choice is being made or gathered, or a swap waits to be taken."""
        with self._cond:
            return self._busy or self._camera is not None or self._result is not None

    def close(self) -> None:
        """Stop the worker (a gather in progress ends on its own; its result is dropped)."""
        with self._cond:
            self._stop = True
            self._cond.notify()

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._camera is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                camera, self._camera = self._camera, None
                self._busy = True
            try:
                swap = self.make(camera)
            except DofviewError as e:
                swap, self.error = None, str(e)
            with self._cond:
                if swap is not None and not self._stop:
                    self._result = swap
                self._busy = False

    def make(self, camera: Camera) -> Swap | None:
        """The swap for ``camera`` made on this thread, or None when its choice is the one drawn (the
        worker's step; the viewer calls it itself only while it opens a set, before the first frame).

        Raises:
            SceneFormatError: a chunk that cannot be decoded.
        """
        choice = self.lod_set.select(camera.centre, self.budget)
        if np.array_equal(choice, self.choice):
            return None
        t0 = time.perf_counter()
        scene = self.lod_set.gather(choice)
        self.lod_set.keep_only(choice)
        swap = Swap(scene, self._pack(scene), front_to_back(scene.means, camera), camera, choice,
                    time.perf_counter() - t0)
        self.choice, self.error = choice, None
        return swap
