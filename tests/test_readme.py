"""Every ``ibiscape-eval`` command in the README's bash blocks runs and exits 0.

Commands run in a scratch folder that holds ``examples/`` (linked) and a small ``demo-output/``
made with the same generators as ``make demo``.  A command whose input files do not exist there
(illustrations such as ``recording.bag``) is skipped; the test checks that most commands ran.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli

ROOT = Path(__file__).resolve().parents[1]
# subcommand -> how many leading positional arguments are inputs that must exist
INPUTS = {"ate": 2, "rpe": 2, "drift": 2, "convert": 1, "allan": 1, "hotpix": 1, "frames": 1, "sim": 0, "calib": 1}


def readme_commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    cmds = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("  #")[0].strip()
            if line.startswith("ibiscape-eval "):
                cmds.append(shlex.split(line)[1:])
    return cmds


def inputs_of(args: list[str]) -> list[str]:
    words = [a for a in args if not a.startswith("-")]
    sub = words[1] if words and words[0] == "events" else words[0]
    start = 2 if words[0] == "events" else 1
    return words[start : start + INPUTS[sub]]


def make_demo_output(root: Path) -> None:
    from ibiscape_eval.events import synthetic_events
    from ibiscape_eval.io.events import write_events
    from ibiscape_eval.io.imu import write_imu_csv
    from ibiscape_eval.sim.noise import imu_noise

    out = root / "demo-output"
    out.mkdir()
    rate_hz, n = 20.0, (3 * 3600 * 20)  # 3 h at 20 Hz: short to write, long enough for K
    s = imu_noise(
        n,
        rate_hz,
        noise_density=[2.8e-4] * 3 + [5e-3] * 3,
        random_walk=[7e-5] * 3 + [1.3e-3] * 3,
        bias0=[0, 0, 0, 0, 0, 9.81],
        seed=1,
    )
    imu_csv = out / "IMU_still" / "other_sensors" / "imu.csv"
    imu_csv.parent.mkdir(parents=True)
    write_imu_csv(imu_csv, np.arange(n, dtype=np.int64) * 50_000_000, s[:, :3], s[:, 3:])
    ev = synthetic_events(sensor_size=(128, 96), duration_s=0.5, n_hot=40, seed=2)
    write_events(out / "davisL", ev.events, fmt="ibiscape")


def test_readme_commands_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    make_demo_output(tmp_path)
    monkeypatch.chdir(tmp_path)
    ran, skipped = 0, []
    for args in readme_commands():
        if not all(Path(p).exists() for p in inputs_of(args)):
            skipped.append(shlex.join(args))
            continue
        redirect = args[args.index(">") + 1] if ">" in args else None
        argv = args[: args.index(">")] if redirect else args
        res = CliRunner().invoke(cli, argv, catch_exceptions=False)
        assert res.exit_code == 0, f"ibiscape-eval {shlex.join(args)}\n{res.output}"
        if redirect:
            Path(redirect).write_text(res.stdout)
        ran += 1
    assert ran >= 20, f"only {ran} README commands ran; skipped: {skipped}"
    assert len(skipped) <= 6, skipped
