"""World building and terrain: bumps, gradients, layout, agents, determinism, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.sim.terrain import Bump, Terrain
from ibiscape_eval.sim.world import SHUTTLE_SCALE, build_world


def _bumps():
    return Terrain(
        (
            Bump("bubble", (1.0, 2.0), 0.2, radius_m=1.2),
            Bump("wave", (5.0, 0.0), 0.15, width_m=2.0, length_m=5.0, heading_rad=0.4),
        )
    )


def test_terrain_heights_and_exact_gradient():
    terr = _bumps()
    assert terr.height_m(np.array([[1.0, 2.0]]))[0] == pytest.approx(0.2)
    assert terr.height_m(np.array([[5.0, 0.0]]))[0] == pytest.approx(0.15)
    assert terr.height_m(np.array([[30.0, 30.0], [2.2, 2.0]])).tolist() == [0.0, 0.0]
    rng = np.random.default_rng(0)
    xy = rng.uniform([-1, -2], [8, 4], size=(4000, 2))
    h = 1e-6
    g = terr.gradient(xy)
    ex, ey = np.array([h, 0.0]), np.array([0.0, h])
    gx = (terr.height_m(xy + ex) - terr.height_m(xy - ex)) / (2 * h)
    gy = (terr.height_m(xy + ey) - terr.height_m(xy - ey)) / (2 * h)
    assert np.abs(g - np.stack((gx, gy), -1)).max() < 1e-5


def test_terrain_is_c1_at_the_rims():
    b = Bump("bubble", (0.0, 0.0), 0.25, radius_m=1.0)
    terr = Terrain((b,))
    r = np.linspace(0.0, 1.2, 24001)
    xy = np.stack((r, np.zeros_like(r)), -1)
    gr = terr.gradient(xy)[:, 0]
    assert np.abs(np.diff(gr)).max() < 2e-3  # no slope jump at the cap/fillet or fillet/ground joins
    assert terr.height_m(xy).min() >= 0.0 and abs(gr[-1]) == 0.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"kind": "hill", "centre_m": (0, 0), "height_m": 0.1}, "kind"),
        ({"kind": "bubble", "centre_m": (0, 0), "height_m": -0.1, "radius_m": 1.0}, "height"),
        ({"kind": "bubble", "centre_m": (0, 0), "height_m": 0.6, "radius_m": 1.0}, "radius"),
        ({"kind": "wave", "centre_m": (0, 0), "height_m": 0.1}, "width_m"),
    ],
)
def test_bad_bumps(kwargs, match):
    with pytest.raises(IbiscapeError, match=match):
        Bump(**kwargs)


def test_slam_world_layout():
    w = build_world(kind="slam", seed=4, town_blocks=3, scene="moderate")
    assert len(w.lanes) == 4 * 4  # two directions, (n + 1) roads per axis
    assert len(w.buildings) > 20 and len(w.parked_cars) > 5 and len(w.poles) > 10
    assert w.targets == () and len(w.agents) == 12
    assert 0 < len(w.terrain.bumps) < len(build_world(kind="calibration", seed=4).terrain.bumps)
    # buildings stay off the roads (road half width 6 m around every grid line)
    c = w.buildings.centre_m[:, :2]
    off = np.abs(c - np.round(c / w.block_m) * w.block_m)
    assert np.all(np.maximum(off[:, 0], off[:, 1]) > 6.0 + 3.0)
    d = w.to_dict()
    assert d["counts"]["buildings"] == len(w.buildings) and d["counts"]["cars"] == 4


def test_calibration_world_targets_and_bumps():
    w = build_world(kind="calibration", seed=1, target="aprilgrid", calibration_drive="loop")
    kinds = [t.target_type for t in w.targets]
    assert kinds == ["checkerboard", "aprilgrid"] and w.target == "aprilgrid"
    kb = [b.kind for b in w.terrain.bumps]
    assert kb.count("bubble") >= 6 and kb.count("wave") >= 6
    # every board faces the start of its approach loop
    for t in w.targets:
        start = w.routes[t.target_type][0]
        to_start = np.r_[start, 0.0] - t.centre_world_m
        assert np.dot(to_start, t.observer_normal_world) > 0.9 * np.linalg.norm(to_start)
    d = w.to_dict()
    assert d["targets"][1]["tagRows"] == 6 and len(d["terrain"]["bumps"]) == len(w.terrain.bumps)


def test_still_world_is_empty_and_flat():
    w = build_world(kind="still", seed=0, scene="dynamic")
    assert len(w.agents) == 0 and w.terrain.bumps == () and w.lanes == ()


def test_agents_move_along_their_loops():
    w = build_world(kind="slam", seed=2, town_blocks=2, scene="dynamic")
    st = w.agents.epoch_ns + np.arange(0, 20_000_000_000, 100_000_000, dtype=np.int64)
    pos, yaw = w.agents.poses_at(st)
    assert pos.shape == (len(w.agents), len(st), 3) and yaw.shape == (len(w.agents), len(st))
    step = np.linalg.norm(np.diff(pos, axis=1), axis=-1) / 0.1
    # constant speed except where a step cuts a loop corner
    frac = np.mean(np.abs(step - w.agents.speed_m_s[:, None]) < 1e-6)
    assert frac > 0.95
    assert np.all(pos[..., 0] >= w.agents.loop_min_m[:, None, 0] - 1e-9)
    assert np.all(pos[..., 0] <= w.agents.loop_max_m[:, None, 0] + 1e-9)


def test_world_determinism():
    a = build_world(kind="slam", seed=7, town_blocks=2, scene="dynamic")
    b = build_world(kind="slam", seed=7, town_blocks=2, scene="dynamic")
    c = build_world(kind="slam", seed=8, town_blocks=2, scene="dynamic")
    assert np.array_equal(a.buildings.size_m, b.buildings.size_m)
    assert a.terrain == b.terrain
    assert not np.array_equal(a.buildings.size_m[:5], c.buildings.size_m[:5])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"kind": "race"}, "kind"),
        ({"kind": "slam", "scene": "stormy"}, "scene"),
        ({"kind": "calibration", "target": "circles"}, "target"),
        ({"kind": "slam", "town_blocks": 0}, "town_blocks"),
        ({"kind": "slam", "seed": -2}, "seed"),
    ],
)
def test_bad_world_requests(kwargs, match):
    kw = {"seed": 0, **kwargs}
    with pytest.raises(IbiscapeError, match=match):
        build_world(**kw)


@pytest.mark.parametrize("target", ["checkerboard", "aprilgrid"])
def test_shuttle_legs_face_the_board_and_close(target):
    w = build_world(kind="calibration", seed=2, target=target)
    assert w.calibration_drive == "shuttle" and w.to_dict()["calibration_drive"] == "shuttle"
    legs = w.shuttles[target]
    c = w.target_named(target).centre_world_m[:2]
    assert len(legs) % 2 == 0 and np.allclose(legs[-1][-1], legs[0][0])  # drivable again
    for i, leg in enumerate(legs):
        nxt = legs[(i + 1) % len(legs)]
        assert np.allclose(leg[-1], nxt[0])
        d_end = (leg[-1] - leg[-2]) / np.linalg.norm(leg[-1] - leg[-2])
        d_next = (nxt[1] - nxt[0]) / np.linalg.norm(nxt[1] - nxt[0])
        assert d_end @ d_next == pytest.approx(-1.0)  # a cusp: the next leg starts straight back
        r = np.linalg.norm(leg[[0, -1]] - c, axis=1) / SHUTTLE_SCALE[target]
        assert r.min() > 4.4 and r.max() < 15.2
    kb = [b.kind for b in w.terrain.bumps]
    assert kb.count("bubble") >= 3 and kb.count("wave") >= 1
    flat = build_world(kind="calibration", seed=2, target=target, bumps=False)
    assert flat.terrain.bumps == () and len(flat.shuttles[target]) == len(legs)
    with pytest.raises(IbiscapeError, match="calibration_drive"):
        build_world(kind="calibration", seed=2, calibration_drive="figure8")
