"""Board textures: built once per board, even when the two stereo views ask for them at once on
their own threads (both built it at the first frame before: the AprilGrid's temporaries twice,
+50 MB of the calibration drive's peak memory)."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ibiscape_eval.sim.render import textures


class _SlowBoard:
    """A board whose texture takes long enough to build that two threads overlap."""

    def __init__(self) -> None:
        self.calls = 0
        self._count = threading.Lock()
        self.z_toward_observer = False
        self.board_min_m = np.zeros(3)
        self.board_max_m = np.ones(3)

    def texture(self, px_per_m: float) -> np.ndarray:
        with self._count:
            self.calls += 1
        time.sleep(0.3)
        return np.full((8, 8), 255, np.uint8)


def test_two_views_build_a_board_texture_once() -> None:
    board: Any = _SlowBoard()
    targets = (board,)
    with ThreadPoolExecutor(2) as pool:
        a, b = pool.map(lambda _: textures.board_tables(targets), range(2))
    assert board.calls == 1
    assert a[0][0] is b[0][0]  # the same cached texture
    np.testing.assert_allclose(a[0][0], 0.88, rtol=1e-6)  # white paper's reflectance
