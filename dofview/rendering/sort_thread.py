"""Depth sorting off the UI thread.

The quad backend's :meth:`~dofview.rendering.quad.QuadBackend.request_order` asks for the order of
a view with :meth:`SortThread.request` whenever the camera moves and keeps drawing with the last
order it has; :meth:`SortThread.result` hands over the newest finished order, which the backend
uploads on the calling (UI) thread, where GL calls stay. One thread per backend, so per scene.
Requests that arrive while a sort runs replace each other: only the latest view is sorted next.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from dofview.camera import Camera
from dofview.rendering.depth_order import front_to_back, order_key


@dataclass
class SortResult:
    """A finished sort: ``order`` (N,) uint32 back to front, for the view of ``view_key``
    (Camera.view_key) and every view of the same ``order_key`` (depth_order.order_key), taking ``ms``."""

    order: np.ndarray
    view_key: bytes
    order_key: bytes
    ms: float


class SortThread:
    """One daemon worker that sorts the latest requested view."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._request: tuple[np.ndarray, Camera] | None = None
        self._result: SortResult | None = None
        self._busy = False
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="dofview-sort", daemon=True)
        self._thread.start()

    def request(self, means: np.ndarray, camera: Camera) -> None:
        """Sort ``means`` ((N, 3) float32) for ``camera``."""
        with self._cond:
            self._request = (means, camera)
            self._cond.notify()

    def result(self) -> SortResult | None:
        """The newest finished sort not handed out yet, or None."""
        with self._cond:
            res, self._result = self._result, None
            return res

    @property
    def pending(self) -> bool:
        """A sort is queued or running."""
        with self._cond:
            return self._busy or self._request is not None

    def close(self, wait: bool = True) -> None:
        """Stop the worker; ``wait``: until a sort it is running ends (else it ends on its own)."""
        with self._cond:
            self._stop = True
            self._cond.notify()
        if wait:
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._request is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                (means, camera), self._request = self._request, None
                self._busy = True
            t0 = time.perf_counter()
            order = front_to_back(means, camera)[::-1].copy()
            res = SortResult(order, camera.view_key(), order_key(camera), (time.perf_counter() - t0) * 1e3)
            with self._cond:
                self._result = res
                self._busy = False
