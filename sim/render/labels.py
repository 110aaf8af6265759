"""CARLA's semantic tags and the CityScapes palette its semantic camera saves (as IBISCape did).

The tables live with the image formats (:mod:`ibiscape_eval.io.images`); the renderer uses the
names through :data:`TAG`.  Raw label PNGs store the tag itself; palette PNGs store the colour,
exactly like ``image.save_to_disk(path, carla.ColorConverter.CityScapesPalette)``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.io.images import CARLA_TAGS, CITYSCAPES_PALETTE

__all__ = ["CARLA_TAGS", "CITYSCAPES_PALETTE", "TAG", "colorize_labels"]

#: name -> tag id
TAG: dict[str, int] = {v: k for k, v in CARLA_TAGS.items()}


def colorize_labels(labels: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """CityScapes colours ``(H, W, 3)`` uint8 RGB of a tag image ``(H, W)``; unknown tags are black."""
    lab = np.asarray(labels)
    idx = np.where(lab < len(CITYSCAPES_PALETTE), lab, 0).astype(np.intp)
    return CITYSCAPES_PALETTE[idx]
