"""Decisions a notebook user needs too live in the library (time or index pairing), the commands'
choices are the library's lists, and the start-up tweaks of the trajectory commands leave the
process as they found it."""

from __future__ import annotations

import gc
import os

from ibiscape_eval.io import has_timestamps
from ibiscape_eval.metrics import choose_match


def test_pairing_by_index_only_without_real_stamps() -> None:
    assert has_timestamps("tum") and has_timestamps("kitti", "times.txt")
    assert not has_timestamps("kitti") and not has_timestamps("KITTI")
    assert choose_match(True, True) == "time"
    assert choose_match(has_timestamps("kitti"), True) == "index"
    assert choose_match(True, False) == "index"


def test_option_choices_are_the_library_lists() -> None:
    from ibiscape_eval.cli import allan, ate, compare, convert, events, hotpix, sim
    from ibiscape_eval.io.detect import TRAJECTORY_FORMATS
    from ibiscape_eval.io.events import FORMATS as EVENT_FORMATS
    from ibiscape_eval.io.imu import FORMATS as IMU_FORMATS
    from ibiscape_eval.metrics.alignment import Alignment
    from ibiscape_eval.sim.config import SCENARIOS, TARGETS

    def choices(cmd, name):
        return tuple(next(p for p in cmd.params if p.name == name).type.choices)

    assert choices(ate.ate, "alignment") == tuple(a.value for a in Alignment)
    assert choices(ate.rpe, "fmt") == ("auto", *TRAJECTORY_FORMATS)
    assert choices(convert.convert, "src_fmt") == ("auto", *TRAJECTORY_FORMATS)
    assert choices(allan.allan, "fmt") == IMU_FORMATS
    assert choices(hotpix.hotpix, "fmt") == ("auto", *EVENT_FORMATS)
    assert choices(sim.sim, "scenario") == SCENARIOS and choices(sim.sim, "target") == TARGETS
    assert choices(compare.compare, "alignment") == tuple(a.value for a in Alignment)
    assert choices(events.frames, "fmt") == ("auto", *EVENT_FORMATS)


def test_startup_tweaks_restore_the_process_state() -> None:
    from ibiscape_eval.cli.startup import numba_startup

    had = os.environ.get("OPENBLAS_NUM_THREADS")
    enabled = gc.isenabled()
    with numba_startup():
        assert not gc.isenabled()
        assert os.environ.get("OPENBLAS_NUM_THREADS") == (had or "1")
    assert gc.isenabled() == enabled
    assert os.environ.get("OPENBLAS_NUM_THREADS") == had
    gc.unfreeze()
