"""The calib tests import their helpers (_calib_render, _calib_scenes, _calib_seqs) from this folder."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
