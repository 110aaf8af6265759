"""``ibiscape-eval calib`` on event-camera folders: the reconstruction is reported and chosen by
``--reconstruction``; bad DVS inputs get one line naming the file and exit status 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from _calib_scenes import dvs_scene
from _calib_seqs import sequence_yaml, write_dvs_folder
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.events import Events


def run(*args):
    return CliRunner().invoke(cli, ["calib", *[str(a) for a in args]], catch_exceptions=False)


def _fails(res, *words):
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ")
    for w in words:
        assert w in lines[-1], lines[-1]


def _dvs_seq(tmp_path, windows, events, *, dvs_doc=None):
    target, cam, *_ = dvs_scene()
    seq = tmp_path / "DVS_calib"
    write_dvs_folder(seq / "davisL", windows, events)
    doc = sequence_yaml({"davisL": cam}, {"davisL": np.eye(4)}, target.to_kalibr())
    if dvs_doc is not None:
        doc["cameras"]["davisL"]["dvs"] = dvs_doc
    (seq / "sequence.yaml").write_text(yaml.safe_dump(doc))
    return seq


def _empty():
    return Events(np.zeros(0, np.int64), np.zeros(0, np.uint16), np.zeros(0, np.uint16), np.zeros(0, bool))


def _blink_on_off():
    """The blinking board of ``dvs_scene`` switched on (its window) and off again 25 ms later (the
    same pixels, opposite polarity), so that integration across windows returns to zero."""
    _, _, _, windows, events = dvs_scene()
    w, e = [], []
    for (a, b), ev in zip(windows, events, strict=True):
        w += [(a, b), (a + 25_000_000, b + 25_000_000)]
        e += [ev, Events(ev.t_ns + 25_000_000, ev.x, ev.y, ~ev.p)]
    return w, e


@pytest.mark.parametrize("method", ["log-intensity", "accumulate-signed"])
def test_reconstruction_is_selectable_and_reported(tmp_path, method):
    windows, events = _blink_on_off()
    # the thresholds the events were made with (dvs_events: 0.2 both ways); unequal ones would leave
    # every on/off blink a residue that the integration over the other views accumulates
    seq = _dvs_seq(tmp_path, windows, events, dvs_doc={"positive_threshold": 0.2, "negative_threshold": 0.2})
    # accumulate-signed finds the board in the "on" and in the "off" windows, 25 ms apart at one
    # pose, then 25 ms later at the next: the corners stand still, then jump.  Their events are not
    # those of moving edges, so no view is refined (the default event corners), and no corner is
    # fitted to the 1M+ events of its window: 3 s CPU instead of 114 s, and a focal error of
    # 0.03 px instead of the 0.74 px of corners refined with the jump as a velocity (measured).
    res = run(seq, "--json", "--reconstruction", method)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    rec = doc["reconstruction"]["davisL"]
    assert rec["method"] == method
    refinement = doc["detection"]["event_corner_refinement"]["davisL"]
    if method == "log-intensity":
        assert rec["contrast_from"] == "sequence.yaml"
        assert (rec["contrast_pos"], rec["contrast_neg"], rec["bidirectional"]) == (0.2, 0.2, True)
    # a blinking board does not move: no view is refined, the frames' corners are kept
    assert (rec["refine_corners"], refinement["method"], refinement["views_refinable"]) == ("events", "frames", 0)
    assert refinement["corners_refined"] == refinement["corners_detected"]
    # one quantised blink per view, 10 views of a 330 px camera: a sanity bound, not the accuracy
    assert doc["ground_truth"]["max_focal_error_px"] < 2.5
    if method == "accumulate-signed":
        # every view has two others within 100 ms (log-intensity finds the board in fewer windows)
        assert refinement["views_not_moving"] == refinement["views_detected"] == 14
        # the frames' corners: 0.028 px (refined from the events: 0.74 px)
        assert doc["ground_truth"]["max_focal_error_px"] < 0.1


def test_empty_windows_are_windows_without_events(tmp_path):
    """Empty windows (a still camera) are read as such, not skipped as corrupt."""
    _, _, _, windows, events = dvs_scene()
    w2 = [(a - 25_000_000, a) for a, _ in windows[:3]]
    allw = sorted([*windows, *w2])
    ev = {w: e for w, e in zip(windows, events, strict=True)}
    seq = _dvs_seq(tmp_path, allw, [ev.get(w, _empty()) for w in allw])
    res = run(seq, "--json", "--reconstruction", "accumulate-signed")
    assert res.exit_code == 0, res.output
    assert "skipped" not in res.stderr
    assert json.loads(res.stdout)["detection"]["cameras"][0]["unreadable"] == 0


def test_no_events_at_all(tmp_path):
    _, _, _, windows, _ = dvs_scene()
    seq = _dvs_seq(tmp_path, windows, [_empty() for _ in windows])
    _fails(run(seq, "--yaml", tmp_path / "o.yaml"), "no events in any", "davisL")
    assert not (tmp_path / "o.yaml").exists()


def test_corrupt_windows(tmp_path):
    _, _, _, windows, events = dvs_scene()
    seq = _dvs_seq(tmp_path, windows, events)
    files = sorted((seq / "davisL" / "events").iterdir())
    for f in files:
        f.write_bytes(b"not an npz")
    _fails(run(seq), "could be read", files[0].name)


def test_no_board_in_the_events(tmp_path):
    _, _, _, windows, _ = dvs_scene()
    rng = np.random.default_rng(0)
    noise = []
    windows = windows[:3]  # the exhaustive board search on noise is slow
    for a, b in windows:
        n = 3000
        noise.append(Events(np.sort(rng.integers(a, b, n)), rng.integers(0, 480, n).astype(np.uint16),
                            rng.integers(0, 360, n).astype(np.uint16), rng.random(n) < 0.5))
    seq = _dvs_seq(tmp_path, windows, noise)
    _fails(run(seq, "--reconstruction", "log-intensity"), "no target found", "reconstructed from events by log-intensity")


def test_events_outside_the_sensor(tmp_path):
    _, _, _, windows, events = dvs_scene()
    seq = _dvs_seq(tmp_path, windows, events)
    _fails(run(seq, "--sensor-size", "100x100", "--reconstruction", "log-intensity"), "outside the 100x100")
