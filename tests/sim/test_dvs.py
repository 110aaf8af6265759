"""DVS model: known answers on log-linear ramps, ordering, refractory period, determinism,
adaptive vs fixed-rate agreement, rain/fog noisy pixels and hot-pixel detection end to end."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as hs
from hypothesis.extra import numpy as hnp

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events
from ibiscape_eval.events import detect_hot_pixels
from ibiscape_eval.io.events import open_events, read_events, read_hot_pixels
from ibiscape_eval.sim.config import CameraSpec, preset
from ibiscape_eval.sim.dvs import DvsConfig, DvsSimulator, weather_level, write_dvs_camera
from ibiscape_eval.sim.dvs.scenes import brightness_ramp, log_ramp, translating_texture
from ibiscape_eval.sim.weather import simulate_weather

T0 = 1_000_000_000
PERIOD = 50_000_000


def _cam(w: int, h: int) -> CameraSpec:
    return CameraSpec(name="davisL", kind="dvs", width_px=w, height_px=h, rate_hz=20.0,
                      position_m=(0.0, 0.1, 2.8), mount="davisL")


def _stamps(n_windows: int) -> np.ndarray:
    return T0 + PERIOD * np.arange(n_windows + 1, dtype=np.int64)


def _slopes(h: int, w: int) -> np.ndarray:
    """Per-pixel log-intensity slopes in 1/s, both signs, several magnitudes."""
    rng = np.random.default_rng(7)
    return rng.uniform(0.5, 6.0, (h, w)) * np.where(rng.random((h, w)) < 0.5, -1.0, 1.0)


@pytest.mark.parametrize("adaptive", [True, False])
def test_log_ramp_count_per_pixel_is_delta_l_over_c(tmp_path: Path, adaptive: bool) -> None:
    h, w = 12, 16
    slope = _slopes(h, w)
    stamps = _stamps(10)
    cfg = DvsConfig(adaptive=adaptive, max_internal_rate_hz=400.0, frames=False)
    res = write_dvs_camera(log_ramp((h, w), T0, slope), _cam(w, h), stamps, tmp_path / "d",
                           dvs_config=cfg)
    ev = read_events(tmp_path / "d")
    counts = np.bincount(ev.y.astype(np.int64) * w + ev.x, minlength=h * w).reshape(h, w)
    delta_l = np.abs(slope) * (stamps[-1] - stamps[0]) * 1e-9
    # the k-th level sits at k*C exactly; allow one level of slack only where |dL|/C is an integer
    # up to rounding of the float arithmetic
    expect = np.floor(delta_l / 0.3 + 1e-9)
    assert np.array_equal(counts, expect)
    assert res.n_events == res.n_scene_events == len(ev) and res.n_noise_events == 0
    # polarity follows the sign of the slope at every pixel
    sign = np.where(slope > 0, True, False)
    assert np.array_equal(ev.p, sign[ev.y, ev.x])


def test_log_ramp_event_times_are_the_crossing_times(tmp_path: Path) -> None:
    h, w = 4, 5
    slope = _slopes(h, w)
    write_dvs_camera(log_ramp((h, w), T0, slope), _cam(w, h), _stamps(6), tmp_path / "d",
                     dvs_config=DvsConfig(frames=False))
    ev = read_events(tmp_path / "d")
    assert np.all(np.diff(ev.t_ns) >= 0)
    for yy in range(h):
        for xx in range(w):
            t = ev.t_ns[(ev.x == xx) & (ev.y == yy)]
            assert t.size == math.floor(abs(slope[yy, xx]) * 0.3 / 0.3 + 1e-9)
            k = np.arange(1, t.size + 1)
            expect = T0 + k * 0.3 / abs(slope[yy, xx]) * 1e9
            # interpolation is exact for L linear in t; the float32 image limits L to ~1e-7,
            # i.e. the times to ~1e-7 / |slope| s (<= 0.2 us here), against 50+ ms between events
            assert t.size == 0 or np.max(np.abs(t - expect)) <= 1000.0


def test_brightness_ramp_matches_log_difference(tmp_path: Path) -> None:
    h, w = 6, 8
    stamps = _stamps(20)
    res = write_dvs_camera(brightness_ramp((h, w), T0, start=10.0, rate_per_s=200.0), _cam(w, h),
                           stamps, tmp_path / "d")
    dl = math.log(0.001 + 210.0 / 255.0) - math.log(0.001 + 10.0 / 255.0)
    assert res.n_events == h * w * math.floor(dl / 0.3)
    assert res.n_positive == res.n_events


def test_refractory_period_is_respected(tmp_path: Path) -> None:
    h, w = 3, 4
    slope = np.full((h, w), 30.0)  # a crossing every 10 ms
    refr = 25_000_000
    cfg = DvsConfig(refractory_period_ns=refr, frames=False)
    res = write_dvs_camera(log_ramp((h, w), T0, slope), _cam(w, h), _stamps(4), tmp_path / "d",
                           dvs_config=cfg)
    ev = read_events(tmp_path / "d")
    crossings = math.floor(30.0 * 0.2 / 0.3 + 1e-9)
    for pix in range(h * w):
        t = ev.t_ns[ev.y.astype(np.int64) * w + ev.x == pix]
        assert np.all(np.diff(t) >= refr)
        # crossings at 10, 20, ... 200 ms; kept: 10, 40, 70, ... (every third)
        assert t.size == len(range(0, crossings, 3))
    assert res.n_refractory_dropped == h * w * crossings - len(ev)


def test_threshold_sigma_changes_counts_but_stays_seeded(tmp_path: Path) -> None:
    h, w = 10, 10
    slope = np.full((h, w), 4.0)
    cfg = DvsConfig(sigma_positive_threshold=0.05, sigma_negative_threshold=0.05, frames=False)
    a = write_dvs_camera(log_ramp((h, w), T0, slope), _cam(w, h), _stamps(8), tmp_path / "a",
                         dvs_config=cfg, rng=np.random.default_rng(1))
    b = write_dvs_camera(log_ramp((h, w), T0, slope), _cam(w, h), _stamps(8), tmp_path / "b",
                         dvs_config=cfg, rng=np.random.default_rng(1))
    ev = read_events(tmp_path / "a")
    counts = np.bincount(ev.y.astype(np.int64) * w + ev.x, minlength=h * w)
    assert counts.min() != counts.max()  # thresholds vary per pixel
    assert a.n_events == b.n_events


def _digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _dynamic_weather(stamps: np.ndarray, seed: int = 1):  # type: ignore[no-untyped-def]
    return simulate_weather(preset("esvi", "slam", "dynamic").weather_model, stamps, seed=seed)


def test_same_seed_gives_byte_identical_folders(tmp_path: Path) -> None:
    stamps = _stamps(6)
    outs = []
    for k in range(2):
        scene = translating_texture((40, 48), T0, speed_px_s=80.0, seed=2)
        write_dvs_camera(scene, _cam(48, 40), stamps, tmp_path / f"r{k}",
                         weather=_dynamic_weather(stamps), rng=np.random.default_rng(11))
        outs.append(_digest(tmp_path / f"r{k}"))
    assert outs[0] == outs[1]
    assert any(k.startswith("events/") for k in outs[0]) and any(k.startswith("frames/") for k in outs[0])
    scene = translating_texture((40, 48), T0, speed_px_s=80.0, seed=2)
    write_dvs_camera(scene, _cam(48, 40), stamps, tmp_path / "other",
                     weather=_dynamic_weather(stamps), rng=np.random.default_rng(12))
    assert _digest(tmp_path / "other") != outs[0]


def test_folder_layout_and_windows(tmp_path: Path) -> None:
    stamps = _stamps(5)
    res = write_dvs_camera(translating_texture((32, 40), T0), _cam(40, 32), stamps, tmp_path / "d")
    src = open_events(tmp_path / "d")
    assert [(a, b, p.name) for a, b, p in src.windows] == [
        (int(stamps[i - 1]), int(stamps[i]), f"{int(stamps[i])}.npz") for i in range(1, 6)]
    assert res.n_windows == 5
    pngs = sorted(p.name for p in (tmp_path / "d" / "frames").glob("*.png"))
    assert pngs == sorted(f"{int(s)}.png" for s in stamps[1:])
    ev = read_events(tmp_path / "d")
    for a, b, p in src.windows:
        part = np.load(p)["t"]
        assert part.size == 0 or (part.min() >= a and part.max() <= b)
    assert len(ev) == res.n_events


def test_adaptive_agrees_with_fixed_rate_reference(tmp_path: Path) -> None:
    stamps = _stamps(8)
    counts = {}
    renders = {}
    for adaptive in (True, False):
        scene = translating_texture((64, 64), T0, speed_px_s=60.0, seed=4)
        r = write_dvs_camera(scene, _cam(64, 64), stamps, tmp_path / str(adaptive),
                             dvs_config=DvsConfig(adaptive=adaptive, max_internal_rate_hz=1000.0,
                                                  frames=False))
        counts[adaptive] = r.n_events
        renders[adaptive] = r.n_renders
    assert abs(counts[True] - counts[False]) <= 0.03 * counts[False]
    assert renders[True] < renders[False] / 4


def test_clear_weather_adds_no_noise_and_dynamic_records_noisy_pixels(tmp_path: Path) -> None:
    h, w = 100, 120
    stamps = _stamps(20)
    clear = simulate_weather(preset("esvi", "slam", "clear").weather_model, stamps, seed=1)
    r0 = write_dvs_camera(translating_texture((h, w), T0, seed=5), _cam(w, h), stamps,
                          tmp_path / "clear", weather=clear, rng=np.random.default_rng(2))
    assert r0.n_noise_events == 0 and r0.noisy_pixels == ()
    r1 = write_dvs_camera(translating_texture((h, w), T0, seed=5), _cam(w, h), stamps,
                          tmp_path / "dyn", weather=_dynamic_weather(stamps),
                          rng=np.random.default_rng(2))
    assert len(r1.noisy_pixels) == round(0.001 * h * w)
    assert r1.n_scene_events == r0.n_scene_events  # noise never changes the scene's events
    ev = read_events(tmp_path / "dyn")
    counts = np.bincount(ev.y.astype(np.int64) * w + ev.x, minlength=h * w).reshape(h, w)
    clean = np.bincount(read_events(tmp_path / "clear").y.astype(np.int64) * w
                        + read_events(tmp_path / "clear").x, minlength=h * w).reshape(h, w)
    extra = counts - clean
    noisy = np.array(r1.noisy_pixels)
    on_noisy = int(extra[noisy[:, 1], noisy[:, 0]].sum())
    # plus the few background events that happen to land on a noisy pixel
    assert 0 <= on_noisy - r1.n_noisy_pixel_events <= 0.01 * r1.n_noise_events
    assert extra.sum() == r1.n_noise_events
    # the noisy pixels carry ~90 % of the noise; the rest is a thin uniform background
    assert on_noisy >= 0.8 * r1.n_noise_events
    level = float(weather_level(_dynamic_weather(stamps), stamps).mean())
    assert 0.35 < level < 0.8  # rain ~45, fog ~70 in the dynamic preset
    assert 0.15 < r1.noise_fraction < 0.35


def test_dynamic_weather_hot_pixels_found_by_the_library_and_the_cli(tmp_path: Path) -> None:
    h, w = 160, 200
    stamps = _stamps(20)
    res = write_dvs_camera(translating_texture((h, w), T0, speed_px_s=90.0, seed=8), _cam(w, h),
                           stamps, tmp_path / "davisL", weather=_dynamic_weather(stamps, seed=3),
                           rng=np.random.default_rng(5))
    truth = {tuple(p) for p in res.noisy_pixels}
    assert len(truth) == 32
    ev = read_events(tmp_path / "davisL")
    found = {tuple(map(int, p)) for p in detect_hot_pixels(ev.x, ev.y, sensor_size=(w, h)).pixels}
    tp = len(found & truth)
    assert tp / len(found) >= 0.95 and tp / len(truth) >= 0.95
    hot_txt = tmp_path / "hot_pixels.txt"
    out = CliRunner().invoke(cli, ["hotpix", str(tmp_path / "davisL"), "--sensor-size",
                                   f"{w}x{h}", "--hot-out", str(hot_txt)], catch_exceptions=False)
    assert out.exit_code == 0, out.output
    found_cli = {tuple(map(int, p)) for p in read_hot_pixels(hot_txt)}
    tp = len(found_cli & truth)
    assert tp / len(found_cli) >= 0.95 and tp / len(truth) >= 0.95


def test_bad_inputs(tmp_path: Path) -> None:
    cam = _cam(8, 6)
    with pytest.raises(IbiscapeError, match="shape"):
        write_dvs_camera(lambda t: np.zeros((5, 8), np.float32), cam, _stamps(2), tmp_path / "a")
    with pytest.raises(IbiscapeError, match="increasing"):
        write_dvs_camera(brightness_ramp((6, 8), T0), cam, np.array([T0, T0]), tmp_path / "b")
    with pytest.raises(IbiscapeError, match="positive_threshold"):
        DvsConfig(positive_threshold=0.0)
    with pytest.raises(IbiscapeError, match="refractory"):
        DvsConfig(refractory_period_ns=-1)
    sim = DvsSimulator((2, 2), DvsConfig(), np.random.default_rng(0))
    with pytest.raises(IbiscapeError, match="reset"):
        sim.step(T0, np.zeros((2, 2)))
    (tmp_path / "full" / "events").mkdir(parents=True)
    (tmp_path / "full" / "events" / "x.npz").write_bytes(b"")
    with pytest.raises(IbiscapeError, match="already holds files"):
        write_dvs_camera(brightness_ramp((6, 8), T0), cam, _stamps(2), tmp_path / "full")


def test_result_to_dict_is_strict_json(tmp_path: Path) -> None:
    stamps = _stamps(4)
    r = write_dvs_camera(translating_texture((30, 30), T0), _cam(30, 30), stamps, tmp_path / "d",
                         weather=_dynamic_weather(stamps))
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["noisy_pixels"] == [list(p) for p in r.noisy_pixels]
    assert "DvsResult(davisL" in repr(r)
    assert DvsConfig().to_dict()["positive_threshold"] == 0.3


@settings(max_examples=40)
@given(data=hs.data())
def test_reference_tracks_log_intensity_within_one_threshold(data: hs.DataObject) -> None:
    """Whatever the images, with sigma 0 and no refractory period each pixel's reference stays
    within C of its log intensity: L_end - L_start - C (n_pos - n_neg) lies in (-C, C); events are
    time-ordered and inside the rendered span."""
    h, w = data.draw(hs.integers(1, 5)), data.draw(hs.integers(1, 5))
    n = data.draw(hs.integers(2, 6))
    imgs = data.draw(hnp.arrays(np.float32, (n, h, w), elements=hs.floats(0, 255, width=32)))
    steps = data.draw(hnp.arrays(np.int64, n - 1, elements=hs.integers(1, 10**8)))
    times = T0 + np.concatenate([[0], np.cumsum(steps)])
    c_pos, c_neg = data.draw(hs.floats(0.05, 1.0)), data.draw(hs.floats(0.05, 1.0))
    cfg = DvsConfig(positive_threshold=c_pos, negative_threshold=c_neg)
    sim = DvsSimulator((h, w), cfg, np.random.default_rng(0))
    sim.reset(int(times[0]), imgs[0])
    parts = [sim.step(int(t), img)[0] for t, img in zip(times[1:], imgs[1:], strict=True)]
    ev = Events.concatenate(parts)
    assert np.all(np.diff(ev.t_ns) >= 0)
    assert len(ev) == 0 or (ev.t_ns[0] >= times[0] and ev.t_ns[-1] <= times[-1])
    pix = ev.y.astype(np.int64) * w + ev.x
    n_pos = np.bincount(pix[ev.p], minlength=h * w)
    n_neg = np.bincount(pix[~ev.p], minlength=h * w)
    log = np.log(0.001 + imgs.astype(np.float64) / 255.0).reshape(n, -1)
    drift = log[-1] - log[0] - (c_pos * n_pos - c_neg * n_neg)
    assert np.all(drift < max(c_pos, c_neg) + 1e-6) and np.all(drift > -max(c_pos, c_neg) - 1e-6)
    np.testing.assert_allclose(sim.ref, log[0] + c_pos * n_pos - c_neg * n_neg, atol=1e-9)


def test_sequence_yaml_records_the_dvs_settings_and_calib_uses_them(tmp_path: Path) -> None:
    """``sequence.yaml: cameras.<name>.dvs`` carries the thresholds the events were made with (with
    or without rendering), and the calibration's reconstruction takes its contrast from there."""
    from ibiscape_eval.calib.events import contrast_from_sequence, event_set_frames
    from ibiscape_eval.core.kalibr import target_from_kalibr
    from ibiscape_eval.io.sequence import read_sequence_yaml

    seq = tmp_path / "ESVI_gt"
    r = CliRunner().invoke(cli, ["sim", "--setup", "esvi", "--kind", "calibration", "--no-render",
                                 "--duration-s", "2", "--out", str(seq)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    doc = read_sequence_yaml(seq / "sequence.yaml")
    for cam in ("davisL", "davisR"):
        dvs = doc["cameras"][cam]["dvs"]
        assert (dvs["positive_threshold"], dvs["negative_threshold"]) == (0.3, 0.3)
        assert dvs["refractory_period_ns"] == 0 and dvs["sigma_positive_threshold"] == 0.0
        assert "frames" not in dvs and "n_events" not in dvs  # nothing rendered: settings only
        assert contrast_from_sequence(doc["cameras"][cam]) == (0.3, 0.3)
    # a rendered camera with its own (unequal) thresholds: counts and settings side by side
    cfg = DvsConfig(positive_threshold=0.25, negative_threshold=0.4, refractory_period_ns=1000,
                    sigma_negative_threshold=0.02)
    res = write_dvs_camera(translating_texture((32, 40), T0), _cam(40, 32), _stamps(6), tmp_path / "d",
                           dvs_config=cfg)
    entry = {"dvs": json.loads(json.dumps(res.to_dict()))}
    assert entry["dvs"]["refractory_period_ns"] == 1000 and entry["dvs"]["n_events"] == res.n_events
    assert entry["dvs"]["sigma_negative_threshold"] == 0.02
    windows = open_events(tmp_path / "d").windows
    target = target_from_kalibr(doc["target"])
    _, used = event_set_frames([p for _, _, p in windows], [(a, b) for a, b, _ in windows], (40, 32),
                               target, reconstruction="log-intensity", camera_doc=entry)
    assert (used["contrast_pos"], used["contrast_neg"], used["contrast_from"]) == (0.25, 0.4, "sequence.yaml")
    _, guessed = event_set_frames([p for _, _, p in windows], [(a, b) for a, b, _ in windows], (40, 32),
                                  target, reconstruction="log-intensity", camera_doc={})
    assert guessed["contrast_from"] == "polarity balance"


@settings(max_examples=200, deadline=None)
@given(data=hs.data())
def test_adaptive_quantile_kernel_is_np_partition_exactly(data: hs.DataObject) -> None:
    """The adaptive step's quantile of |dL| (an exponent-bucket selection) equals np.partition's
    value bit for bit, so the render times, hence the events, are unchanged (zeros, ties, tiny and
    huge differences included)."""
    from ibiscape_eval.sim.dvs._kernels import abs_diff_kth

    n = data.draw(hs.integers(1, 400))
    floats = hs.one_of(hs.just(0.0), hs.floats(-1e6, 1e6, allow_nan=False, width=64),
                       hs.floats(-1e-300, 1e-300, allow_nan=False))
    l0 = data.draw(hnp.arrays(np.float64, n, elements=floats))
    step = data.draw(hnp.arrays(np.float64, n, elements=floats))
    l1 = l0 + step * (np.arange(n) % data.draw(hs.integers(1, 4)) == 0)
    k = data.draw(hs.integers(0, n - 1))
    assert abs_diff_kth(l0, l1, k) == np.partition(np.abs(l1 - l0), k)[k]
