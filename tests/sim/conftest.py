"""Scenes built once per test session and shared by the renderer tests (read-only use)."""

from __future__ import annotations

import pytest

from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.world import build_world


@pytest.fixture(scope="session")
def town_dynamic() -> Renderer:
    """A 2-block town with moving cars and pedestrians, noise-free images (no targets there, so
    the supersampling option does not matter)."""
    world = build_world(kind="slam", seed=3, scene="dynamic", town_blocks=2)
    return Renderer(world, options=RenderOptions(noise=False))
