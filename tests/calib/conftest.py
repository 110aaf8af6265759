"""The calib tests import their helpers (_render, _scenes, _seqs) from this folder."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
