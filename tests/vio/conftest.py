"""Fixtures of the VIO tests: one short generated SVI sequence (no images) shared by the module
tests, and synthetic stereo measurements of it."""

from __future__ import annotations

from pathlib import Path

import pytest
from _walls import render_street_sequence

from ibiscape_eval.sim import generate, preset
from ibiscape_eval.vio.inputs import StereoSequence, load_sequence
from ibiscape_eval.vio.rig import StereoRig


@pytest.fixture(scope="session")
def svi_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 14 s SVI slam sequence (clear weather, IMU noise on): starts still, then drives."""
    out = tmp_path_factory.mktemp("vio") / "SVI_1_town"
    generate(preset("svi", "slam", "clear", duration_s=14.0, seed=3), out)
    return out


@pytest.fixture(scope="session")
def svi_seq(svi_folder: Path) -> StereoSequence:
    return load_sequence(svi_folder, require_images=False)


@pytest.fixture(scope="session")
def small_rig(svi_seq: StereoSequence) -> StereoRig:
    """The sequence's stereo rig on 256 x 256 px images."""
    r = svi_seq.rig
    return StereoRig(r.left.scaled(256, 256), r.right.scaled(256, 256), r.T_body_left, r.T_body_right)



@pytest.fixture(scope="session")
def street(svi_folder: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(sequence folder with 160 px street images, its camchain-imucam.yaml)."""
    dst = tmp_path_factory.mktemp("street") / "SVI_street"
    return dst, render_street_sequence(svi_folder, dst)
