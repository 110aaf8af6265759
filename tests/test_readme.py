"""Every ``ibiscape-eval`` command in the README's bash blocks runs, exits 0 and produces output.

Commands run in a scratch folder that holds ``examples/`` (linked), a small ``demo-output/`` made
with the same generators as ``make demo``, and the illustrative inputs (``still.npy``, ``log.csv``,
``events.txt``).  Each command must print numbers (or valid JSON with numbers) and write every file
or folder its options name.  Only the commands listed in ``ILLUSTRATIVE`` (inputs that cannot be
made here) are not run, and the test fails if any other command is skipped.  The commands run in
independent groups (``GROUPS``, in README order within a group), each in its own folder with only
the inputs it reads, so that the groups spread over the pytest-xdist workers.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli

ROOT = Path(__file__).resolve().parents[1]
# subcommand -> how many leading positional arguments are inputs that must exist
INPUTS = {"ate": 2, "rpe": 2, "drift": 2, "compare": 3, "convert": 1, "allan": 1, "hotpix": 1, "frames": 1,
          "sim": 0, "report": 1, "calib": 1, "vio": 1, "benchmark": 0}
# inputs of README commands that are illustrations only (a ROS bag is not generated here)
ILLUSTRATIVE = {"recording.bag"}
# options whose value is a file or folder the command must create
OUTPUT_OPTIONS = ("--plot", "--yaml", "--csv", "--save-csv", "--save-aligned", "--save-results",
                  "--hot-out", "--filtered-out", "--out")
NUMBER = re.compile(r"\d+\.\d+|\b\d+\b")


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


# The README's commands in independent groups (each its own inputs; a command that reads what an
# earlier one wrote is in that command's group): pytest-xdist spreads them over the workers
# (tests/conftest.py SPLIT), and each group builds only the inputs it reads.
GROUPS = ("metrics", "sim", "allan", "events", "report", "calib", "vio", "setups")


def group_of(args: list[str]) -> str:
    """The group of a README command (see ``GROUPS``)."""
    if any(("ESVI_1_town" in a or "RGBD_1_town" in a) for a in args):
        return "setups"  # the ESVI and RGB-D drives and their VIO
    sub = args[0]
    if sub in ("ate", "rpe", "drift", "compare", "convert"):
        return "vio" if "est.txt" in args else "metrics"
    if sub in ("sim", "benchmark"):  # the benchmark reads the suite `sim suite` wrote
        return "sim"
    if sub in ("hotpix", "events"):
        return "events"
    return sub  # allan, report, calib, vio


def _imu_inputs(root: Path) -> None:
    """``demo-output/IMU_still`` and the allan section's illustrative inputs."""
    from ibiscape_eval.io.imu import write_imu_csv
    from ibiscape_eval.sim import generate, preset
    from ibiscape_eval.sim.noise import imu_noise

    out = root / "demo-output"
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
    m = 40_000
    np.save(root / "still.npy", s[:m])  # (N, 6) gyro + accel, read with --rate-hz 200
    deg, g = np.pi / 180.0, 9.80665
    cols = np.column_stack((np.arange(m) / 200.0, s[:m, :3] / deg, s[:m, 3:] / g))
    np.savetxt(root / "log.csv", cols, delimiter=",", header="time,gx,gy,gz,ax,ay,az", comments="",
               fmt="%.12g")
    # the allan section's foreign layouts: accelerometer first by name and without a
    # header, a rostopic echo -p csv, and a generated drive (not still)
    acc_first = np.column_stack((10**12 + np.arange(m) * 5_000_000, s[:m, 3:], s[:m, :3]))
    for name, head in (("phone.csv", "timestamp,ax,ay,az,gx,gy,gz"), ("noheader.csv", "")):
        np.savetxt(root / name, acc_first, delimiter=",", header=head, comments="",
                   fmt=["%d"] + ["%.9g"] * 6)
    ros = ["%time,field.header.seq,field.header.stamp,field.header.frame_id,"
           + ",".join(f"field.angular_velocity.{c}" for c in "xyz") + ","
           + ",".join(f"field.linear_acceleration.{c}" for c in "xyz")]
    ros += [f"{10**12 + 5_000_000 * i + 99},{i},{10**12 + 5_000_000 * i},imu,"
            + ",".join(f"{v:.9g}" for v in row) for i, row in enumerate(s[:m])]
    (root / "imu_echo.csv").write_text("\n".join(ros) + "\n")
    generate(preset("svi", "slam", "clear", duration_s=30.0, seed=4), root / "drive")


def _event_inputs(root: Path) -> None:
    """``demo-output/davisL`` (planted hot pixels) and the illustrative ``events.txt``."""
    from ibiscape_eval.events import synthetic_events
    from ibiscape_eval.io.events import write_events

    ev = synthetic_events(sensor_size=(128, 96), duration_s=0.5, n_hot=40, seed=2)
    write_events(root / "demo-output" / "davisL", ev.events, fmt="ibiscape")
    write_events(root / "events.txt", ev.events, fmt="text")


def _report_inputs(root: Path) -> None:
    """The runs folder of `make demo` step 5 (real data and synthetic trials; no simulation)."""
    _example("report_runs").make_runs_folder(root / "demo-output" / "runs")


def _calib_inputs(root: Path) -> None:
    out = root / "demo-output"
    # the stereo calibration sequence of the demo's calib step (the simulator's renderer), fewer
    # views at half size
    _example("calibrate_cameras").render_sequence(out / "stereo_checkerboard", "checkerboard",
                                                  n_views=10, seed=0, size=0.5)
    # the camera-IMU calibration drive of `calib --imu` (board frames, with imu.yaml and camchain.yaml),
    # 5 frames a second: the three commands calibrate it in 6.5 s of CPU each (8 s at 10 frames/s)
    _example("calibrate_imu_camera").make_sequence(out / "SVI_calib_imu", duration_s=10.0, size=320,
                                                   rate_hz=5.0)


def _vio_inputs(root: Path) -> None:
    """A small rendered SVI drive and its EuRoC export, as `make demo`'s vio step writes them."""
    res = CliRunner().invoke(cli, ["sim", "--setup", "svi", "--kind", "slam", "--duration-s", "4",
                                    "--seed", "4", "--resolution", "160", "--out",
                                    str(root / "demo-output" / "SVI_vio"), "--export", "euroc"])
    assert res.exit_code == 0, res.output


#: what each group reads besides ``examples/`` (the other groups read nothing made here)
INPUTS_OF_GROUP = {"allan": _imu_inputs, "events": _event_inputs, "report": _report_inputs,
                   "calib": _calib_inputs, "vio": _vio_inputs}


def _example(name: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def outputs_of(args: list[str]) -> list[Path]:
    """Files and folders the command must create (option values, convert's DST, a redirect)."""
    outs = [Path(args[i + 1]) for i, a in enumerate(args[:-1]) if a in OUTPUT_OPTIONS or a == ">"]
    if args[0] == "convert":
        outs.append(Path([a for a in args if not a.startswith("-")][2]))
    return outs


def check_output(args: list[str], stdout: str) -> None:
    """The command printed its result (numbers, or JSON holding numbers) and wrote its files."""
    cmd = f"ibiscape-eval {shlex.join(args)}"
    if "--json" in args:
        doc = json.loads(stdout)
        assert isinstance(doc, dict) and NUMBER.search(json.dumps(doc)), cmd
    elif ">" not in args and args[0] != "convert":
        assert NUMBER.search(stdout), f"{cmd}: no number on stdout:\n{stdout}"
    for p in outputs_of(args):
        assert p.exists(), f"{cmd}: {p} was not written"
        assert (any(p.iterdir()) if p.is_dir() else p.stat().st_size > 0), f"{cmd}: {p} is empty"


def test_every_readme_command_is_in_a_group() -> None:
    cmds = readme_commands()
    assert len(cmds) >= 20
    assert {group_of(args) for args in cmds} == set(GROUPS)


@pytest.mark.parametrize("group", GROUPS)
def test_readme_commands_run(group: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    (tmp_path / "demo-output").mkdir()
    if group in INPUTS_OF_GROUP:
        INPUTS_OF_GROUP[group](tmp_path)
    monkeypatch.chdir(tmp_path)
    ran, skipped = 0, []
    for args in (a for a in readme_commands() if group_of(a) == group):
        missing = [p for p in inputs_of(args) if not Path(p).exists()]
        if missing:
            skipped.append((shlex.join(args), missing))
            continue
        redirect = args[args.index(">") + 1] if ">" in args else None
        argv = args[: args.index(">")] if redirect else args
        res = CliRunner().invoke(cli, argv, catch_exceptions=False)
        assert res.exit_code == 0, f"ibiscape-eval {shlex.join(args)}\n{res.output}"
        if redirect:
            Path(redirect).write_text(res.stdout)
        check_output(args, res.stdout)
        ran += 1
    not_illustrative = [(c, m) for c, m in skipped if not set(m) <= ILLUSTRATIVE]
    assert not not_illustrative, f"README commands skipped for missing inputs: {not_illustrative}"
    assert ran >= 1, f"no README command of the group {group} ran"


# -- the README's measured numbers are produced, not typed -------------------------------------------

RECORDED = ROOT / "benchmarks" / "measured" / "demo.json"


def _numbers_script():
    import importlib.util

    path = ROOT / "benchmarks" / "update_readme_numbers.py"
    spec = importlib.util.spec_from_file_location("update_readme_numbers", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_readme_numbers_are_the_recorded_ones() -> None:
    """Every marked number of the README equals the demo's recorded numbers at its printed
    precision (rewrite them with benchmarks/update_readme_numbers.py --from demo-output/numbers.json)."""
    mod = _numbers_script()
    readme = (ROOT / "README.md").read_text()
    recorded = json.loads(RECORDED.read_text())
    keys = mod.marked_keys(readme)
    # the quick start's demo time and the benchmark's accuracies are marked, not typed
    assert "wall_min" in keys
    for part in ("camera_calibration", "imu_camera", "imu_noise", "hot_pixels", "evaluation"):
        assert any(k.startswith(f"benchmark.{part}.") for k in keys), part
    assert mod.check(readme, recorded) == []
    # no demo time typed outside the marks
    unmarked = mod.MARK.sub("", readme)
    assert not re.search(r"demo[^.]*\b\d+ s measured", unmarked)


def test_the_number_check_catches_a_typed_number() -> None:
    mod = _numbers_script()
    recorded = {"wall_min": 17.4, "b": {"focal": [0.32, 0.41], "k": -0.4}}
    readme = ("took <!-- measured:wall_min .0f -->17<!-- /measured --> minutes; focal "
              "<!-- measured:b.focal .2f -->0.32-0.41<!-- /measured --> px, K "
              "<!-- measured:b.k +.1f -->-0.4<!-- /measured --> %")
    assert mod.check(readme, recorded) == []
    for wrong in (readme.replace("-->17<", "-->4<"), readme.replace("0.32-0.41", "0.32-1.1"),
                  readme.replace("-->-0.4<", "-->+0.4<"), readme.replace("wall_min", "wall_h")):
        assert mod.check(wrong, recorded), wrong
        if "wall_h" not in wrong:
            assert mod.check(mod.rewrite(wrong, recorded), recorded) == []
    # the printed precision is the noise: 0.318 printed as 0.32 agrees, 0.33 does not
    assert mod.check(readme, {**recorded, "b": {"focal": [0.318, 0.41], "k": -0.4}}) == []
    assert mod.check(readme, {**recorded, "b": {"focal": [0.33, 0.41], "k": -0.4}})
