"""Malformed inputs the mutation campaign found (trajectories, IMU tables, events, bags, YAML):
each gives one error line naming the file, one test per class of defect."""

from __future__ import annotations

import json
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from shared_data import require_shared

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import FormatError, IbiscapeError, IbiscapeWarning
from ibiscape_eval.io import read_trajectory
from ibiscape_eval.io.events import read_events
from ibiscape_eval.io.imu import read_imu, write_imu_csv
from ibiscape_eval.io.paths import check_input

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "mutation"))


def run(*args: object):
    return CliRunner().invoke(cli, [str(a) for a in args])


def one_error(res, *needles: str) -> str:
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "Usage" not in res.stderr, res.stderr
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]


def tum(path: Path, n: int = 50, big: float | None = None) -> Path:
    t = 100 + np.arange(n) * 0.1
    pos = np.column_stack([np.cos(t), np.sin(t), 0.1 * t])
    if big is not None:
        pos[7, 0] = big
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    np.savetxt(path, np.column_stack([t, pos, q]), fmt="%.17g")
    return path


def imu_arrays(n: int = 3000):
    rng = np.random.default_rng(0)
    return (10**12 + np.arange(n, dtype=np.int64) * 5_000_000, rng.normal(0, 1e-3, (n, 3)),
            rng.normal(0, 1e-2, (n, 3)) + np.array([0.0, 0.0, 9.81]))


# --- paths: FIFOs, symlink loops, folders ----------------------------------------------------


@pytest.fixture
def fifo(tmp_path: Path) -> Path:
    p = tmp_path / "pipe.txt"
    os.mkfifo(p)
    return p


@pytest.fixture
def loop(tmp_path: Path) -> Path:
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    os.symlink(b, a)
    os.symlink(a, b)
    return a


def test_check_input_refuses_fifo_loop_folder(tmp_path: Path, fifo: Path, loop: Path) -> None:
    with pytest.raises(FormatError, match=r"pipe.txt: is a named pipe \(FIFO\), not a regular file"):
        check_input(fifo)
    with pytest.raises(FormatError, match=r"a.txt: symbolic link loop"):
        check_input(loop)
    with pytest.raises(FormatError, match=r"is a folder, expected a file"):
        check_input(tmp_path)
    with pytest.raises(FormatError, match=r"is a file, expected a folder"):
        check_input(tum(tmp_path / "x.txt"), "folder")
    assert check_input(tmp_path, "any") == tmp_path
    with pytest.raises(FileNotFoundError):
        check_input(tmp_path / "missing")


@pytest.mark.parametrize("reader", [
    read_trajectory,
    lambda p: read_trajectory(p, fmt="kitti"),
    read_imu,
    lambda p: read_imu(p, fmt="npy"),
    read_events,
])
def test_every_reader_refuses_a_fifo_without_opening_it(fifo: Path, reader) -> None:
    with pytest.raises(FormatError, match="named pipe"):
        reader(fifo)


def test_cli_fifo_loop_and_config_folder(tmp_path: Path, fifo: Path, loop: Path) -> None:
    ref = tum(tmp_path / "ref.txt")
    one_error(run("ate", fifo, ref), "pipe.txt", "named pipe")
    one_error(run("ate", loop, ref), "a.txt", "symbolic link loop")
    one_error(run("sim", "--config", loop, "--out", tmp_path / "o"), "a.txt", "loop")
    one_error(run("sim", "--config", tmp_path, "--out", tmp_path / "o"), str(tmp_path),
              "is a folder")
    assert not (tmp_path / "o").exists()


# --- numbers ---------------------------------------------------------------------------------


def test_tum_position_1e308_is_refused_with_its_line(tmp_path: Path) -> None:
    bad = tum(tmp_path / "est.txt", big=1e308)
    with pytest.raises(FormatError, match=r"est.txt:8: position .* beyond 1e\+09 m"):
        read_trajectory(bad)
    one_error(run("ate", bad, tum(tmp_path / "ref.txt"), "--json"), "est.txt:8")


def test_imu_csv_40_digit_stamp_and_8_mib_line(tmp_path: Path) -> None:
    p = tmp_path / "imu.csv"
    write_imu_csv(p, *imu_arrays())
    lines = p.read_text().splitlines()
    lines[5] = "9" * 40 + lines[5][lines[5].index(","):]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"imu.csv:6: column 1 is too large"):
        read_imu(p)
    lines = p.read_text().splitlines()
    lines[5] = lines[6] + "1" * (8 << 20)
    p.write_text("\n".join(lines) + "\n")
    one_error(run("allan", p, "--json"), "imu.csv:6")


def test_imu_1e300_sample_refused_not_infinity_in_json(tmp_path: Path) -> None:
    s, g, a = imu_arrays()
    g[100, 1] = 1e300
    p = tmp_path / "imu.csv"
    write_imu_csv(p, s, g, a)
    one_error(run("allan", p, "--json", "--csv", tmp_path / "c.csv"), "imu.csv:102", "w_y")
    assert not (tmp_path / "c.csv").exists()
    np.save(tmp_path / "imu.npy", np.column_stack([s.astype(np.float64), g, a]))
    with pytest.raises(FormatError, match=r"imu.npy:101: sample of axis w_y is beyond"):
        read_imu(tmp_path / "imu.npy")


def test_float32_stamps_refused(tmp_path: Path) -> None:
    s, g, a = imu_arrays()
    p = tmp_path / "imu.npz"
    np.savez(p, stamps_ns=s.astype(np.float32), gyro_rad_s=g, accel_m_s2=a)
    with pytest.raises(FormatError, match=r"imu.npz: timestamps stored as float32 are quantised"):
        read_imu(p)
    np.savez(p, stamps_ns=s.astype(np.float64), gyro_rad_s=g, accel_m_s2=a)
    assert read_imu(p).rate_hz == pytest.approx(200.0)


def test_rate_hz_ignored_warns_and_zero_is_explained(tmp_path: Path) -> None:
    s, g, a = imu_arrays()
    p = tmp_path / "imu.npz"
    np.savez(p, stamps_ns=s, gyro_rad_s=g, accel_m_s2=a)
    with pytest.warns(IbiscapeWarning, match=r"--rate-hz 100 ignored: the file has timestamps"):
        read_imu(p, rate_hz=100.0)
    q = tmp_path / "six.npy"
    np.save(q, np.column_stack([g, a]))
    with pytest.raises(FormatError, match=r"rate_hz=0 is not a positive number of Hz"):
        read_imu(q, rate_hz=0.0)
    one_error(run("allan", q, "--rate-hz", "0"), "six.npy", "positive number")


def test_events_uint64_stamps_beyond_int64_refused(tmp_path: Path) -> None:
    p = tmp_path / "ev.npz"
    t = np.array([2**63 - 10, 2**63 + 5], dtype=np.uint64)
    np.savez(p, t=t, x=np.array([1, 2], np.uint16), y=np.array([1, 2], np.uint16),
             p=np.array([True, False]))
    with pytest.raises(FormatError, match=r"ev.npz: t holds 9223372036854775813 ns, beyond int64"):
        read_events(p)
    one_error(run("events", "frames", p, "--out", tmp_path / "fr"), "ev.npz")
    assert not (tmp_path / "fr").exists()


# --- damaged binary files --------------------------------------------------------------------


def test_npy_header_flips_and_npz_damage(tmp_path: Path) -> None:
    s, g, a = imu_arrays()
    p = tmp_path / "imu.npy"
    np.save(p, np.column_stack([s.astype(np.float64), g, a]))
    raw = bytearray(p.read_bytes())
    raw[raw.index(b"'descr'")] = ord('"')  # unterminated string: tokenize.TokenError in numpy
    p.write_bytes(bytes(raw))
    with pytest.raises(FormatError, match=r"imu.npy: damaged .npy header"):
        read_imu(p)
    z = tmp_path / "imu.npz"
    np.savez(z, stamps_ns=s, gyro_rad_s=g, accel_m_s2=a)
    good = z.read_bytes()
    z.write_bytes(good[: len(good) // 2])
    with pytest.raises(FormatError, match=r"imu.npz: "):
        read_imu(z)
    crc = bytearray(good)
    crc[200] ^= 0xFF  # inside the first member's data: Bad CRC-32
    z.write_bytes(bytes(crc))
    with pytest.raises(FormatError, match=r"imu.npz: damaged .npz member"):
        read_imu(z)
    z.write_text("hello\n")
    with pytest.raises(FormatError, match=r"first bytes are those of a text file"):
        read_imu(z)
    z.write_bytes(b"")
    one_error(run("allan", z), "imu.npz", "empty file")


def test_events_npz_crc_damage(tmp_path: Path) -> None:
    from ibiscape_eval.core.events import Events
    from ibiscape_eval.io.events import write_events

    p = tmp_path / "ev.npz"
    n = 500
    write_events(p, Events(np.arange(n, dtype=np.int64) * 1000, np.zeros(n, np.uint16),
                           np.zeros(n, np.uint16), np.ones(n, bool)))
    raw = bytearray(p.read_bytes())
    raw[150] ^= 0xFF
    p.write_bytes(bytes(raw))
    with pytest.raises(FormatError, match=r"ev.npz: "):
        read_events(p)


def test_replayed_bag_mutants_give_one_line(tmp_path: Path) -> None:
    """The bag mutants that raised AssertionError / ReaderError / AnyReaderError before."""
    from campaign import run_one

    require_shared("trajectories")  # the bag seeds: fails under CI when missing
    for fam, mut, idx in (("ros1_bag", "bit_flip", 3), ("ros1_bag", "bit_flip", 17),
                          ("ros2_bag", "bit_flip", 24), ("events_npz", "delete_bytes", 7),
                          ("imu_npz", "empty", 9)):
        o = run_one(tmp_path / "seeds", tmp_path / "work", fam, mut, idx)
        assert o.problem is None, str(o)


# --- text encodings --------------------------------------------------------------------------


def test_utf8_bom_accepted_by_trajectory_and_event_text_readers(tmp_path: Path) -> None:
    p = tum(tmp_path / "t.txt")
    plain = read_trajectory(p)
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    back = read_trajectory(p)
    np.testing.assert_array_equal(back.stamps_ns, plain.stamps_ns)
    np.testing.assert_array_equal(back.pos_m, plain.pos_m)
    e = tmp_path / "e.txt"
    e.write_bytes(b"\xef\xbb\xbf64 48\n1.0 3 4 1\n1.5 5 6 0\n")
    ev = read_events(e)
    assert ev.x.tolist() == [3, 5] and ev.t_ns.tolist() == [10**9, 15 * 10**8]


def test_event_text_outside_header_size_and_bad_header(tmp_path: Path) -> None:
    e = tmp_path / "e.txt"
    e.write_text("64 48\n1.0 3 4 1\n1.5 70 6 0\n")
    one_error(run("events", "frames", e, "--out", tmp_path / "fr"), "e.txt:3", "64x48")
    assert not (tmp_path / "fr").exists()
    e.write_text("0 48\n1.0 3 4 1\n")
    with pytest.raises(FormatError, match=r"e.txt:1: header gives a 0x48 sensor"):
        read_events(e)


# --- the simulator's YAML --------------------------------------------------------------------


@pytest.mark.parametrize(("body", "needle"), [
    (b"duration_s: 2\nseed: \xff\xfe\n", "sim.yaml:2: not UTF-8"),
    (b"x: " + b"[" * 10_000 + b"\n", "nested too deeply"),
    (b"duration_s: 2\nseed: 1\nduration_s: 3\n", "sim.yaml:3: key 'duration_s' given twice"),
    (b"gt_rate_hz: 1.0e+9\n", "gt_rate_hz = 1000000000.0 is beyond"),
    (b"duration_s: 1.0e+12\n", "duration_s = 1000000000000.0 is beyond"),
    (b"duration_s: .inf\n", "duration_s"),
    (b"motion: {town_blocks: 100000}\n", "sim.yaml: config: motion.town_blocks = 100000"),
])
def test_sim_config_refusals(tmp_path: Path, body: bytes, needle: str) -> None:
    p = tmp_path / "sim.yaml"
    p.write_bytes(body)
    line = one_error(run("sim", "--config", p, "--out", tmp_path / "seq"), "sim.yaml")
    assert needle in line
    assert sorted(os.listdir(tmp_path)) == ["sim.yaml"]


def test_sim_resource_estimate_refuses_with_numbers(tmp_path: Path) -> None:
    from ibiscape_eval.sim.config import check_resources, estimate_run, preset

    small = estimate_run(preset("svi", "slam", "clear", duration_s=10.0))
    big = estimate_run(preset("svi", "slam", "clear", duration_s=1.0e6))
    assert big.output_bytes > 1e4 * small.output_bytes > 0
    assert big.memory_bytes > small.memory_bytes
    with pytest.raises(IbiscapeError, match=r"seq: not generated: this run would need about .* GB "
                       r"of memory"):
        check_resources(preset("svi", "slam", "clear", duration_s=9.0e6), tmp_path / "seq")
    still = preset("imu", "calibration", "clear", duration_s=9.0e6)
    assert estimate_run(still).memory_bytes < 1e9  # streamed
    with pytest.raises(IbiscapeError, match=r"would write about .* GB but .* GB are free"):
        check_resources(still, tmp_path / "seq")
    assert not (tmp_path / "seq").exists()


# --- JSON ------------------------------------------------------------------------------------


def test_echo_json_is_strict_and_names_non_finite_values() -> None:
    from ibiscape_eval.cli._common import strict_json

    doc = strict_json({"a": float("inf"), "b": [1.0, np.float64("nan")], "c": np.arange(2),
                       "d": {"e": -np.inf}})
    text = json.dumps(doc, allow_nan=False)
    back = json.loads(text)
    assert back["a"] is None and back["b"] == [1.0, None] and back["c"] == [0, 1]
    assert back["non_finite"] == {"/a": "inf", "/b/1": "nan", "/d/e": "-inf"}


# --- interrupted runs ------------------------------------------------------------------------


def test_interrupted_write_leaves_no_temporary(tmp_path: Path, monkeypatch) -> None:
    """An exception in the middle of writing an output leaves neither the output nor a hidden
    temporary file or folder."""
    from ibiscape_eval.io import euroc

    ref = tum(tmp_path / "ref.txt")
    est = tum(tmp_path / "est.txt")
    out = tmp_path / "out"
    out.mkdir()
    real = euroc.write_table

    def boom(*args, **kwargs):
        real(*args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(euroc, "write_table", boom)
    with warnings.catch_warnings():
        res = run("convert", est, out / "x.txt", "--to", "euroc")
    assert res.exit_code != 0
    assert os.listdir(out) == []
    import importlib

    gen = importlib.import_module("ibiscape_eval.sim.generator")
    generate = gen.generate

    def fail_late(*a, **k):
        raise RuntimeError("injected")

    monkeypatch.setattr(gen, "_generate_moving", fail_late)
    from ibiscape_eval.sim.config import preset

    with pytest.raises(RuntimeError):
        generate(preset("svi", "slam", "clear", duration_s=1.0), out / "seq")
    assert os.listdir(out) == []
    assert ref.exists()


def test_euroc_rows_with_16_or_18_columns_get_a_note(tmp_path: Path) -> None:
    from families import SHARED

    require_shared("trajectories")  # fails under CI when missing
    lines = (SHARED / "V102_groundtruth.csv").read_text().splitlines()[:200]
    p = tmp_path / "data.csv"
    p.write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plain = read_trajectory(p)
    lines[10] = lines[10].rsplit(",", 1)[0]  # 16 columns
    lines[20] = lines[20] + ",0.5"  # 18 columns
    p.write_text("\n".join(lines) + "\n")
    with pytest.warns(IbiscapeWarning, match=r"data.csv: 2 rows with another column count than "
                      r"the usual 17 \(e.g. 16 at line 11; lines 11, 21\)"):
        back = read_trajectory(p)
    np.testing.assert_array_equal(back.pos_m, plain.pos_m)


def test_constant_imu_axis_names_the_file(tmp_path: Path) -> None:
    s, g, a = imu_arrays()
    g[:, 2] = 0.01
    p = tmp_path / "still.npz"
    np.savez(p, stamps_ns=s, gyro_rad_s=g, accel_m_s2=a)
    one_error(run("allan", p), "still.npz", "constant")


def test_small_text_inputs_refuse_non_utf8_and_fifos(tmp_path: Path, fifo: Path) -> None:
    from ibiscape_eval.io.events import read_hot_pixels
    from ibiscape_eval.io.kalibr import read_imu_noise

    h = tmp_path / "hot.txt"
    h.write_bytes(b"1, 2\n3, \xff\n")
    with pytest.raises(FormatError, match=r"hot.txt:2: not UTF-8"):
        read_hot_pixels(h)
    h.write_text("1, 2\n99999999999999999999, 3\n")
    with pytest.raises(FormatError, match=r"hot.txt:2: pixel coordinates must be in 0..65535"):
        read_hot_pixels(h)
    with pytest.raises(FormatError, match="named pipe"):
        read_hot_pixels(fifo)
    k = tmp_path / "imu.yaml"
    k.write_bytes(b"a: " + b"[" * 10_000)
    with pytest.raises(FormatError, match=r"imu.yaml"):
        read_imu_noise(k)


def test_hdf5_stamps_beyond_int64_ns_refused(tmp_path: Path) -> None:
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "ev.h5"
    with h5py.File(p, "w") as f:
        f["events/t"] = np.array([1, 2**62], dtype=np.uint64)  # microseconds
        f["events/x"] = np.array([1, 2], dtype=np.uint16)
        f["events/y"] = np.array([1, 2], dtype=np.uint16)
        f["events/p"] = np.array([0, 1], dtype=np.uint8)
    with pytest.raises(FormatError, match=r"ev.h5: events/t holds 4611686018427387904 us"):
        read_events(p)
