"""``ibiscape-eval allan``: outputs, and every bad input -> exit 2, one line naming file/line, no output."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _cli_data import assert_one_error_line

from ibiscape_eval.io.imu import write_imu_csv
from ibiscape_eval.io.kalibr import read_imu_noise
from ibiscape_eval.sim.noise import imu_noise

N_TRUE = [1e-3, 1e-3, 1e-3, 2e-2, 2e-2, 2e-2]
K_TRUE = [2e-4, 2e-4, 2e-4, 4e-3, 4e-3, 4e-3]


def _imu(path: Path, hours: float, rate: float = 20.0, seed: int = 1, rw: bool = True) -> Path:
    n = int(hours * 3600 * rate)
    y = imu_noise(n, rate, noise_density=N_TRUE, random_walk=K_TRUE if rw else 0.0, seed=seed)
    t = 1_600_000_000_000_000_000 + np.arange(n, dtype=np.int64) * int(1e9 / rate)
    write_imu_csv(path, t, y[:, :3], y[:, 3:])
    return path


@pytest.fixture(scope="module")
def long_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _imu(tmp_path_factory.mktemp("allan") / "imu.csv", hours=6)




def test_all_outputs(run_cli, long_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = run_cli("allan", long_csv, "--yaml", out / "imu.yaml", "--csv", out / "c.csv",
                  "--plot", out / "adev.png", "--rostopic", "/imu0")
    assert res.exit_code == 0, res.output
    assert "w_x" in res.stdout and "a_z" in res.stdout and "±" in res.stdout
    doc = read_imu_noise(out / "imu.yaml").to_kalibr()
    assert doc["gyroscope_noise_density"] == pytest.approx(1e-3, rel=0.03)
    assert doc["accelerometer_random_walk"] == pytest.approx(4e-3, rel=0.3)
    assert doc["update_rate"] == pytest.approx(20.0) and doc["rostopic"] == "/imu0"
    assert "per-sample" in (out / "imu.yaml").read_text()
    assert (out / "adev.png").stat().st_size > 10_000
    head = (out / "c.csv").read_text().splitlines()[0]
    assert head.startswith("tau_s,m,n_terms,edf,adev_w_x,adev_lo_w_x,adev_hi_w_x")


def test_json(run_cli, long_csv: Path) -> None:
    res = run_cli("allan", long_csv, "--json")
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    assert set(doc["axes"]) == {"w_x", "w_y", "w_z", "a_x", "a_y", "a_z"}
    for name, n_true in zip(doc["axes"], N_TRUE, strict=True):
        a = doc["axes"][name]
        assert a["noise_density"] == pytest.approx(n_true, rel=0.03)
        assert a["discrete_sigma"] == pytest.approx(a["noise_density"] * np.sqrt(20.0))
    gyro_max = max(doc["axes"][n]["random_walk"] for n in ("w_x", "w_y", "w_z"))
    assert doc["kalibr"]["gyroscope_random_walk"] == gyro_max


def test_short_record_writes_curve_but_refuses_yaml(run_cli, tmp_path: Path) -> None:
    p = _imu(tmp_path / "short.csv", hours=0.1, rw=False)
    res = run_cli("allan", p, "--csv", tmp_path / "c.csv", "--yaml", tmp_path / "imu.yaml")
    assert_one_error_line(res, "imu.yaml not written", "random_walk", stdout_empty=False)
    assert "too short to see the rate random walk" in res.stderr
    assert (tmp_path / "c.csv").exists()
    assert not (tmp_path / "imu.yaml").exists()
    assert "w_x" in res.stdout  # the table with N is still printed


def _broken(tmp_path: Path, line: int, text: str) -> Path:
    p = _imu(tmp_path / "imu.csv", hours=0.05)
    lines = p.read_text().splitlines()
    lines[line - 1] = text
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize(
    ("line", "text", "needle"),
    [
        (12, "1600000000550000000,0.1,oops,0.3,0.4,0.5,0.6", "column 3 is not a number"),
        (13, "1600000000600000000,0.1,0.2,0.3,0.4,0.5,0.6,0.7", "expected 7 comma-separated"),
        (14, "1600000000000000000,0.1,0.2,0.3,0.4,0.5,0.6", "not strictly increasing"),
    ],
)
def test_bad_rows(run_cli, tmp_path: Path, line: int, text: str, needle: str) -> None:
    p = _broken(tmp_path, line, text)
    res = run_cli("allan", p, "--yaml", tmp_path / "imu.yaml", "--csv", tmp_path / "c.csv",
                  "--plot", tmp_path / "a.png")
    assert_one_error_line(res, f"imu.csv:{line}:", needle)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["imu.csv"]


def test_large_gap_refused_unless_allowed(run_cli, tmp_path: Path) -> None:
    n, rate = 20_000, 20.0
    y = imu_noise(n, rate, noise_density=N_TRUE, random_walk=K_TRUE, seed=3)
    t = np.arange(n, dtype=np.int64) * 50_000_000
    t[5000:] += 600 * 10**9  # ten minutes missing
    write_imu_csv(tmp_path / "imu.csv", t, y[:, :3], y[:, 3:])
    res = run_cli("allan", tmp_path / "imu.csv", "--csv", tmp_path / "c.csv")
    assert_one_error_line(res, "imu.csv:5002:", "gap", "--allow-gaps")
    assert not (tmp_path / "c.csv").exists()
    res = run_cli("allan", tmp_path / "imu.csv", "--allow-gaps", "--csv", tmp_path / "c.csv")
    assert res.exit_code == 0 and (tmp_path / "c.csv").exists()


def test_constant_axis(run_cli, tmp_path: Path) -> None:
    n = 5000
    y = imu_noise(n, 20.0, noise_density=N_TRUE, random_walk=0.0, seed=4)
    y[:, 4] = 0.0
    write_imu_csv(tmp_path / "imu.csv", np.arange(n, dtype=np.int64) * 50_000_000, y[:, :3], y[:, 3:])
    res = run_cli("allan", tmp_path / "imu.csv", "--plot", tmp_path / "a.png")
    assert_one_error_line(res, "'a_y' is constant")
    assert not (tmp_path / "a.png").exists()


def test_unknown_units_missing_file_and_bad_range(run_cli, tmp_path: Path) -> None:
    p = _imu(tmp_path / "imu.csv", hours=0.05)
    assert_one_error_line(run_cli("allan", p, "--units", "gyro=rpm"), "unknown gyro unit 'rpm'")
    assert_one_error_line(run_cli("allan", tmp_path / "nope.csv"), "nope.csv", "no such file")
    assert_one_error_line(run_cli("allan", p, "--walk-range", "5"), "--walk-range")


def test_npy_without_stamps_needs_rate(run_cli, tmp_path: Path) -> None:
    np.save(tmp_path / "y.npy", imu_noise(5000, 20.0, noise_density=N_TRUE, random_walk=0.0, seed=5))
    assert_one_error_line(run_cli("allan", tmp_path / "y.npy"), "y.npy", "--rate-hz")
    res = run_cli("allan", tmp_path / "y.npy", "--rate-hz", "20", "--json")
    assert res.exit_code == 0
    assert json.loads(res.stdout)["rate_hz"] == 20.0


def test_help_has_an_example(run_cli) -> None:
    res = run_cli("allan", "--help")
    assert res.exit_code == 0 and "ibiscape-eval allan imu.csv" in res.output


def test_format_ibiscape_gives_the_same_noise(run_cli, tmp_path: Path) -> None:
    """CARLA's left-handed frame (sign flips) changes no Allan number; --help names the format."""
    n, rate = 20_000, 20.0
    y = imu_noise(n, rate, noise_density=N_TRUE, random_walk=K_TRUE, seed=6)
    t = np.arange(n, dtype=np.int64) * 50_000_000
    write_imu_csv(tmp_path / "carla.csv", t, y[:, :3], y[:, 3:], frame="ibiscape")
    write_imu_csv(tmp_path / "ours.csv", t, y[:, :3], y[:, 3:])
    a = run_cli("allan", tmp_path / "carla.csv", "--format", "ibiscape", "--json")
    b = run_cli("allan", tmp_path / "ours.csv", "--json")
    assert a.exit_code == 0 and b.exit_code == 0, a.output + b.output
    da, db = json.loads(a.stdout)["axes"], json.loads(b.stdout)["axes"]
    assert da.keys() == db.keys()
    for name in da:
        assert da[name].keys() == db[name].keys()
        for key, va in da[name].items():
            vb = db[name][key]
            assert va == (pytest.approx(vb, rel=1e-12) if isinstance(vb, float) else vb), (name, key)
    assert da["w_z"]["noise_density"] == pytest.approx(N_TRUE[2], rel=0.05)
    assert "ibiscape" in run_cli("allan", "--help").stdout
