"""Shared benchmark plumbing: run a command in a fresh process, measure wall time and peak RSS."""

from __future__ import annotations

import os
import subprocess
import threading
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class Run:
    wall_s: float
    peak_mb: float
    stdout: str
    returncode: int

    @property
    def ok(self) -> bool:
        return self.returncode == 0


def run(cmd: list[str], *, timeout_s: float | None = None) -> Run:
    """Run ``cmd`` and reap it with ``os.wait4``, which reports that child's own peak RSS.

    A command still running after ``timeout_s`` is killed and reported with an infinite time.
    """
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    timer = threading.Timer(timeout_s, proc.kill) if timeout_s else None
    if timer:
        timer.start()
    assert proc.stdout is not None
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if timer:
        timer.cancel()
    proc.returncode = os.waitstatus_to_exitcode(status)  # already reaped: tell Popen
    proc.stdout.close()
    if proc.returncode == -9:
        return Run(float("inf"), float("nan"), out, -9)
    return Run(wall, usage.ru_maxrss / 1024.0, out, proc.returncode)
