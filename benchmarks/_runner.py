"""Shared benchmark plumbing: run a command in a fresh process, measure wall time and peak RSS."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

# GNU time forks the measured command from its own small process.  Reading the child's peak RSS
# with wait4 from Python instead is wrong: subprocess spawns with vfork + exec, and Linux records
# the parent's (shared) memory high-water mark as the child's ru_maxrss at exec.
GNU_TIME = "/usr/bin/time" if os.path.exists("/usr/bin/time") else shutil.which("time")


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
    """Run ``cmd``; wall time, the command's own peak RSS (MB, via GNU time) and its stdout.

    A command still running after ``timeout_s`` is killed and reported with an infinite time.
    """
    with tempfile.NamedTemporaryFile(prefix="rss_", suffix=".txt") as rss:
        argv = [GNU_TIME, "-q", "-f", "%M", "-o", rss.name, *cmd] if GNU_TIME else cmd
        t0 = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        timer = threading.Timer(timeout_s, proc.kill) if timeout_s else None
        if timer:
            timer.start()
        out, _ = proc.communicate()
        wall = time.perf_counter() - t0
        if timer:
            timer.cancel()
        if proc.returncode == -9:
            return Run(float("inf"), float("nan"), out, -9)
        text = Path(rss.name).read_text().split() if GNU_TIME else []
        peak_mb = int(text[-1]) / 1024.0 if text and text[-1].isdigit() else float("nan")
        return Run(wall, peak_mb, out, proc.returncode)
