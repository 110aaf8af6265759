"""The mutation campaign's VIO families under the two numeric mutators only, with more mutants
than the campaign's share: among them the seeded mutants that broke the contract before the VIO
checked its numbers (sequence.yaml nan_inf #21: GTSAM's indeterminate linear system; camchain
huge_number #0, #6, #11, #30, #34: a rectification error without the file name; imu.yaml
huge_number #37: a KeyError after the smoother lost its keyframe)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "mutation"))

from campaign import run_one

INDICES = sorted(set(range(12)) | {21, 30, 34, 37})


@pytest.mark.parametrize("family", ["vio_sequence_yaml", "vio_camchain", "vio_imu_yaml"])
@pytest.mark.parametrize("mutator", ["nan_inf", "huge_number"])
def test_numeric_mutants_keep_the_contract(tmp_path_factory, family, mutator):
    root = tmp_path_factory.getbasetemp() / "vio_numeric_mutants"
    work = root / "work"
    work.mkdir(parents=True, exist_ok=True)
    broke = [o for i in INDICES
             if (o := run_one(root / "seeds", work, family, mutator, i)).problem]
    assert not broke, "\n".join(map(str, broke))
