"""Progress on stderr when it is not a terminal (a log, CI): plain lines, no redrawn bar."""

from __future__ import annotations

import pytest

from ibiscape_eval.cli import progress as prog


class _Log:
    def __init__(self, capsys) -> None:
        self.capsys = capsys

    def getvalue(self) -> str:
        return str(self.capsys.readouterr().err)


@pytest.fixture
def log(capsys) -> _Log:
    assert not prog.sys.stderr.isatty()  # captured: not a terminal
    return _Log(capsys)


def test_a_batch_writes_one_line_per_finished_job(log) -> None:
    bar = prog.BatchBar("suite", delay_s=0.0)
    bar.step("suite", 0, 0, 3)
    for done in (1, 2, 3):
        bar.step("suite", done, int(done >= 2), 3 - done)
    bar.step("vio", 0, 0, 1)
    bar.step("vio", 1, 0, 0)
    bar.close()
    text = log.getvalue()
    lines = text.splitlines()
    assert [ln.split("  ")[0] for ln in lines] == [
        "suite: 1/3 job (failed 0, remaining 2)", "suite: 2/3 job (failed 1, remaining 1)",
        "suite: 3/3 job (failed 1, remaining 0)", "vio: 1/1 job (failed 0, remaining 0)"]
    assert "\r" not in text


def test_nothing_before_the_delay(log) -> None:
    bar = prog.BatchBar("report", unit="run", delay_s=60.0)
    for done in range(5):
        bar(done, 0, 5 - done)
    bar.close()
    assert log.getvalue() == ""


def test_a_bar_writes_a_line_every_interval(log, monkeypatch) -> None:
    now = [100.0]
    monkeypatch.setattr(prog.time, "monotonic", lambda: now[0])
    with prog.progress_bar(1000, "sim", unit="‰", unit_scale=False, delay_s=0.0) as bar:
        update = prog.fraction_callback(bar, "sim")
        for t in range(20):  # 20 s of work, an update every second
            now[0] = 100.0 + t + 1
            update((t + 1) / 20, f"stage {t // 10}")
    lines = log.getvalue().splitlines()
    assert len(lines) == 20 // int(prog.LOG_INTERVAL_S)
    assert lines[0] == f"sim: stage 0: 250/1000 ‰  {prog.LOG_INTERVAL_S:.0f} s"
    assert lines[-1].startswith("sim: stage 1: 1000/1000")


def test_the_log_lines_take_every_bar_call_the_commands_make(log) -> None:
    # calib resets its bar once it knows the number of images
    with prog.progress_bar(0, "calib", unit="img", unit_scale=False, delay_s=0.0) as bar:
        bar.reset(total=4)
        bar.set_postfix_str("views 2")
        bar.update(4)
        assert (bar.n, bar.total) == (4, 4)
    assert log.getvalue() == ""  # done within the interval: no line
