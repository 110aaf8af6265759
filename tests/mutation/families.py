"""The input families of the mutation campaign: one seed builder and one command line each.

A family is registered with one line in :data:`FAMILIES`; new readers (calibration images and
YAML, VIO inputs, report runs) join the campaign the same way::

    FAMILIES["calib_yaml"] = Family(build=_calib_yaml_seed, argv=lambda p, out: ["calib", str(p), ...])

``build(folder)`` writes a small valid seed into ``folder`` and returns the path given on the
command line; ``mutable(path)`` names the file whose bytes are mutated (a ROS 2 bag folder's
``.db3``); ``argv(path, out)`` is the command line (``out`` is an empty folder for outputs).
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from shared_data import TRAJECTORIES

SHARED = TRAJECTORIES  # ../shared/data/trajectories or $IBISCAPE_SHARED_DATA/trajectories
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "io"))


@dataclass(frozen=True)
class Family:
    build: Callable[[Path], Path]
    argv: Callable[[Path, Path], list[str]]
    mutable: Callable[[Path], Path] = field(default=lambda p: p)
    text: bool = True
    json: bool = True
    #: other names an error line may carry instead of the input's (e.g. the output folder when
    #: a run is refused for its size)
    also_names: tuple[str, ...] = ()


def _poses(n: int = 60, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = 1000.0 + np.arange(n) * 0.1
    pos = np.column_stack([np.cos(t / 3) * 5, np.sin(t / 2) * 4, 0.3 * np.sin(t)])
    pos = pos + rng.normal(0, 0.01, pos.shape)
    yaw = t / 5
    quat = np.column_stack([0.05 * np.sin(t), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return t, pos, quat


def _traj(seed: int = 0):  # type: ignore[no-untyped-def]
    from ibiscape_eval.core.trajectory import Trajectory

    t, pos, quat = _poses(seed=seed)
    return Trajectory((t * 1e9).round().astype(np.int64), pos, quat)


def _ref_tum(folder: Path) -> Path:
    """A clean TUM reference (the second input of ``ate``), shared by the pose families."""
    ref = folder / "ref.txt"
    if not ref.exists():
        t, pos, quat = _poses(seed=1)
        np.savetxt(ref, np.column_stack([t, pos, quat]), fmt="%.9f")
    return ref


def _tum_seed(folder: Path) -> Path:
    _ref_tum(folder)
    src = (SHARED / "freiburg1_xyz-groundtruth.txt").read_bytes().splitlines(keepends=True)
    t, pos, quat = _poses(seed=2)
    p = folder / "est.txt"
    head = b"".join(ln for ln in src[:3] if ln.startswith(b"#"))
    p.write_bytes(head + "".join(
        " ".join(f"{v:.9f}" for v in row) + "\n"
        for row in np.column_stack([t, pos, quat])).encode())
    return p


def _kitti_seed(folder: Path) -> Path:
    from ibiscape_eval.io import write_trajectory

    ref = folder / "ref_kitti.txt"
    write_trajectory(ref, _traj(1), fmt="kitti")
    p = folder / "est_kitti.txt"
    write_trajectory(p, _traj(2), fmt="kitti")
    return p


def _euroc_seed(folder: Path) -> Path:
    lines = (SHARED / "V102_groundtruth.csv").read_bytes().splitlines(keepends=True)
    p = folder / "data.csv"
    p.write_bytes(b"".join(lines[:1500]))
    est = folder / "V102.txt"
    shutil.copyfile(SHARED / "V102.txt", est)
    return p


def _ibiscape_seed(folder: Path) -> Path:
    from ibiscape_eval.io.ibiscape import write_ibiscape

    _ref_tum(folder)
    p = folder / "groundtruth_sync.csv"
    write_ibiscape(p, _traj(2))
    return p


def _ros1_seed(folder: Path) -> Path:
    from _bag_helpers import write_bag

    _ref_tum(folder)
    t, pos, quat = _poses(seed=2)
    p = folder / "est.bag"
    write_bag(p, 1, {"/pose": ("geometry_msgs/msg/PoseStamped",
                               (t * 1e9).round().astype(np.int64), pos, quat)})
    return p


def _ros2_seed(folder: Path) -> Path:
    p = folder / "tf_example_ros2"
    shutil.copytree(SHARED / "tf_example_ros2", p)
    for f in p.iterdir():
        f.chmod(0o644)
    p.chmod(0o755)
    return p


def _imu_arrays(n: int = 3000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    stamps = 10**12 + np.arange(n, dtype=np.int64) * 5_000_000
    gyro = rng.normal(0, 1e-3, (n, 3))
    accel = rng.normal(0, 1e-2, (n, 3)) + np.array([0.0, 0.0, 9.81])
    return stamps, gyro, accel


def _imu_csv_seed(folder: Path) -> Path:
    from ibiscape_eval.io.imu import write_imu_csv

    p = folder / "imu.csv"
    write_imu_csv(p, *_imu_arrays())
    return p


def _imu_named_csv_seed(folder: Path) -> Path:
    """Accelerometer first, columns found by header name, stamps in seconds."""
    s, g, a = _imu_arrays()
    p = folder / "imu_named.csv"
    rows = [f"{t // 10**9}.{t % 10**9:09d}," + ",".join(f"{v:.9g}" for v in (*ai, *gi))
            for t, ai, gi in zip(s.tolist(), a, g, strict=True)]
    p.write_text("\n".join(["time,acc_x,acc_y,acc_z,gyro_x,gyro_y,gyro_z", *rows]) + "\n")
    return p


def _imu_rostopic_seed(folder: Path) -> Path:
    """A ``rostopic echo -p`` CSV: text frame_id, covariances, ns stamps."""
    s, g, a = _imu_arrays()
    p = folder / "imu_rostopic.csv"
    head = ["%time", "field.header.seq", "field.header.stamp", "field.header.frame_id",
            *[f"field.orientation.{c}" for c in "xyzw"],
            *[f"field.angular_velocity.{c}" for c in "xyz"],
            *[f"field.linear_acceleration.{c}" for c in "xyz"],
            *[f"field.linear_acceleration_covariance{i}" for i in range(3)]]
    rows = [f"{t + 777},{i},{t},imu4,0,0,0,1," + ",".join(f"{v:.9g}" for v in (*gi, *ai))
            + ",0,0,0" for i, (t, gi, ai) in enumerate(zip(s.tolist(), g, a, strict=True))]
    p.write_text("\n".join([",".join(head), *rows]) + "\n")
    return p


def _imu_npy_seed(folder: Path) -> Path:
    s, g, a = _imu_arrays()
    p = folder / "imu.npy"
    np.save(p, np.column_stack([s.astype(np.float64), g, a]))
    return p


def _imu_npz_seed(folder: Path) -> Path:
    s, g, a = _imu_arrays()
    p = folder / "imu.npz"
    np.savez(p, stamps_ns=s, gyro_rad_s=g, accel_m_s2=a)
    return p


def _events() -> object:
    from ibiscape_eval.core.events import Events

    rng = np.random.default_rng(4)
    n = 4000
    t = np.sort(rng.integers(10**9, 2 * 10**9, n)).astype(np.int64)
    x = rng.integers(0, 64, n).astype(np.uint16)
    y = rng.integers(0, 48, n).astype(np.uint16)
    x[::7] = 5
    y[::7] = 9  # a hot pixel
    return Events(t, x, y, rng.random(n) < 0.5)


def _events_npz_seed(folder: Path) -> Path:
    from ibiscape_eval.io.events import write_events

    p = folder / "events.npz"
    write_events(p, _events())  # type: ignore[arg-type]
    return p


def _events_txt_seed(folder: Path) -> Path:
    from ibiscape_eval.io.events import write_events

    p = folder / "events.txt"
    write_events(p, _events())  # type: ignore[arg-type]
    txt = p.read_bytes()
    p.write_bytes(b"64 48\n" + txt if not txt[:6].strip().startswith(b"64") else txt)
    return p


def _dvs_folder_seed(folder: Path) -> Path:
    """An IBISCape DVS camera folder (``timestamps.csv`` + ``events/<ns>.npz`` windows, one of them
    empty as a still camera leaves it); the third window's ``.npz`` is the one mutated."""
    from ibiscape_eval.core.events import Events
    from ibiscape_eval.io.dvs_folder import DvsFolderWriter

    ev = _events()
    assert isinstance(ev, Events)
    root = folder / "davisL"
    w = DvsFolderWriter(root, frames=False)
    edges = np.linspace(10**9, 2 * 10**9, 6).astype(np.int64)
    for k in range(5):
        a, b = int(edges[k]), int(edges[k + 1])
        sel = (ev.t_ns >= a) & (ev.t_ns < b) if k != 1 else np.zeros(len(ev), bool)
        w.add(a, b, Events(ev.t_ns[sel], ev.x[sel], ev.y[sel], ev.p[sel]), None)
    w.close()
    return root


def _dvs_window(root: Path) -> Path:
    return sorted((root / "events").glob("*.npz"))[2]


def _hot_list_seed(folder: Path) -> Path:
    _events_npz_seed(folder)
    p = folder / "hot.txt"
    p.write_text("5, 9\n17, 3\n")
    return p


def _kitti_times_seed(folder: Path) -> Path:
    _kitti_seed(folder)
    p = folder / "times.txt"
    p.write_text("".join(f"{1000.0 + 0.1 * i:.6f}\n" for i in range(60)))
    return p


def _sim_yaml_seed(folder: Path) -> Path:
    from ibiscape_eval.sim.config import dump_config, preset

    p = folder / "sim.yaml"
    p.write_text(dump_config(preset("svi", "slam", "clear", duration_s=1.0)))
    return p


#: the generated VIO sequence, built once per campaign and copied into each VIO family's seed
_VIO_TEMPLATE: dict[str, Path] = {}
VIO_FRAMES = 20  # the fewest frames the VIO initialises from (standstill) on the seed: ~0.2 s a run


def _vio_sequence(folder: Path) -> Path:
    """A 3 s generated SVI sequence with 20 rendered 160 px street frames per camera, its Kalibr
    camchain-imucam.yaml (cam0 = left) and imu.yaml, copied to ``folder / "SVI_1_town"``."""
    key = str(folder.parent)
    if key not in _VIO_TEMPLATE:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "vio"))
        from _walls import W, render_street

        from ibiscape_eval.core.kalibr import ImuNoise
        from ibiscape_eval.io.kalibr import write_imu_noise
        from ibiscape_eval.sim.config import preset
        from ibiscape_eval.sim.generator import generate
        from ibiscape_eval.vio.inputs import load_sequence
        from ibiscape_eval.vio.rig import StereoRig

        d = folder.parent / ".vio_template" / "SVI_1_town"
        generate(preset("svi", "slam", "clear", duration_s=3.0, seed=3), d)
        seq = load_sequence(d, require_images=False)
        r = seq.rig
        rig = StereoRig(r.left.scaled(W, W), r.right.scaled(W, W), r.T_body_left, r.T_body_right)
        gt = seq.groundtruth
        assert gt is not None
        render_street(d, gt, rig, gt.stamps_ns[: 10 * VIO_FRAMES : 10],
                      origin_xy=(gt.pos_m[0, 0], gt.pos_m[0, 1]), direction_xy=(1.0, 0.0))
        write_imu_noise(d / "imu.yaml", ImuNoise(
            accel_noise_density_m_s2_sqrt_hz=0.02, accel_random_walk_m_s3_sqrt_hz=4e-4,
            gyro_noise_density_rad_s_sqrt_hz=2e-3, gyro_random_walk_rad_s2_sqrt_hz=2e-5,
            update_rate_hz=200.0))
        _VIO_TEMPLATE[key] = d
    dst = folder / "SVI_1_town"
    shutil.copytree(_VIO_TEMPLATE[key], dst)
    return dst


def _vio_seq_seed(folder: Path) -> Path:
    return _vio_sequence(folder)


def _vio_calib_seed(folder: Path) -> Path:
    return _vio_sequence(folder) / "camchain-imucam.yaml"


def _vio_imu_yaml_seed(folder: Path) -> Path:
    return _vio_sequence(folder) / "imu.yaml"


def _vio_argv(seq: Path, out: Path, calib: Path | None = None, *extra: str) -> list[str]:
    calib = seq / "camchain-imucam.yaml" if calib is None else calib
    return ["vio", str(seq), "-o", str(out / "est.txt"), "--calib", str(calib), "--max-frames",
            str(VIO_FRAMES), "--json", *extra]


def _report_seed(folder: Path) -> Path:
    """runs/seq1/groundtruth.txt and runs/seq1/{alpha,beta}/t1/est.txt (TUM); the mutated file is
    alpha's trajectory."""
    from ibiscape_eval.io import write_trajectory

    runs = folder / "runs"
    (runs / "seq1" / "alpha" / "t1").mkdir(parents=True)
    (runs / "seq1" / "beta" / "t1").mkdir(parents=True)
    write_trajectory(runs / "seq1" / "groundtruth.txt", _traj(1), fmt="tum")
    write_trajectory(runs / "seq1" / "alpha" / "t1" / "est.txt", _traj(2), fmt="tum")
    write_trajectory(runs / "seq1" / "beta" / "t1" / "est.txt", _traj(3), fmt="tum")
    return runs


def _calib_sequence(folder: Path) -> Path:
    """A small rendered stereo checkerboard sequence (6 views, 320x240) and its camchain.yaml, built once
    per campaign through the calib command itself."""
    from click.testing import CliRunner

    from ibiscape_eval.cli.main import cli
    from ibiscape_eval.core.camera import CameraModel
    from ibiscape_eval.sim.calib_views import render_calibration_views

    seq = folder / "calib_seq"
    cam = CameraModel(320, 240, 210.0, 210.0, 159.5, 119.5, "radtan", (-0.1, 0.02, 0.0, 0.0))
    T = np.eye(4)
    T[0, 3] = 0.4
    render_calibration_views(seq, {"rgbL": cam, "rgbR": cam}, {"rgbR": T}, target="checkerboard",
                             n_views=6, seed=0, distance_m=(3.0, 7.0))
    res = CliRunner().invoke(cli, ["calib", str(seq), "--yaml", str(seq / "camchain.yaml")])
    assert res.exit_code == 0, res.output
    return seq


def _vio_camchain_opencv_seed(folder: Path) -> Path:
    """The VIO seed's camchain-imucam as OpenVINS ships it: ``%YAML:1.0`` header, ``T_imu_cam``
    (the inverse of Kalibr's ``T_cam_imu``), no ``T_cn_cnm1``."""
    import yaml

    seq = _vio_sequence(folder)
    doc = yaml.safe_load((seq / "camchain-imucam.yaml").read_text())
    for entry in doc.values():
        entry["T_imu_cam"] = np.linalg.inv(np.array(entry.pop("T_cam_imu"))).tolist()
        entry.pop("T_cn_cnm1", None)
    p = seq / "kalibr_imucam_chain.yaml"
    p.write_text("%YAML:1.0\n\n" + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return p


def _vio_imu_chain_opencv_seed(folder: Path) -> Path:
    """The VIO seed's imu.yaml as OpenVINS ships it: ``%YAML:1.0``, the keys under ``imu0:``."""
    import yaml

    seq = _vio_sequence(folder)
    doc = yaml.safe_load((seq / "imu.yaml").read_text())
    p = seq / "kalibr_imu_chain.yaml"
    p.write_text("%YAML:1.0\n\n" + yaml.safe_dump({"imu0": {"T_i_b": np.eye(4).tolist(), **doc}},
                                                      sort_keys=False, default_flow_style=None))
    return p


def _calib_target_seed(folder: Path) -> Path:
    """The calibration seed's target as a Kalibr target yaml (given to --target)."""
    from ibiscape_eval.core.kalibr import target_from_kalibr
    from ibiscape_eval.io.kalibr import read_target, write_target
    from ibiscape_eval.io.sequence import read_sequence_yaml

    seq = _calib_sequence(folder)
    p = seq / "target.yaml"
    write_target(p, target_from_kalibr(read_sequence_yaml(seq / "sequence.yaml")["target"]))
    read_target(p)
    return p


def _euroc_vio_seed(folder: Path) -> Path:
    """The VIO seed re-packed as an EuRoC/ASL folder the way real ones come: sensor.yaml files with
    OpenCV's ``%YAML:1.0`` header and an EMPTY ground-truth csv (open_sequence's EuRoC reader)."""
    from _sequence_helpers import euroc_from

    seq = _vio_sequence(folder)
    return euroc_from(seq, folder / "MH_street", seq / "camchain-imucam.yaml")


def _image_bag_seed(folder: Path) -> Path:
    """The EuRoC re-pack as a ROS 1 bag: Image + CompressedImage + Imu topics (the bag's image
    reader of open_sequence); the calibration and noise come from the VIO seed's Kalibr files."""
    from _sequence_helpers import bag_from_euroc

    return bag_from_euroc(_euroc_vio_seed(folder), folder / "street.bag")


def _euroc_vio_argv(p: Path, out: Path) -> list[str]:
    return ["vio", str(p), "-o", str(out / "est.txt"), "--max-frames", str(VIO_FRAMES), "--json"]


FAMILIES: dict[str, Family] = {
    "tum": Family(_tum_seed, lambda p, o: ["ate", str(p), str(p.parent / "ref.txt"), "--json",
                                           "--save-aligned", str(o / "aligned.txt")]),
    "kitti": Family(_kitti_seed, lambda p, o: ["ate", str(p), str(p.parent / "ref_kitti.txt"),
                                               "--format-est", "kitti", "--format-ref", "kitti",
                                               "--json"]),
    "euroc": Family(_euroc_seed, lambda p, o: ["ate", str(p.parent / "V102.txt"), str(p), "--json",
                                               "--save-csv", str(o / "errors.csv")]),
    "ibiscape_gt": Family(_ibiscape_seed, lambda p, o: ["ate", str(p.parent / "ref.txt"), str(p),
                                                        "--json"]),
    "ros1_bag": Family(_ros1_seed, lambda p, o: ["ate", str(p), str(p.parent / "ref.txt"),
                                                 "--json"], text=False),
    "ros2_bag": Family(_ros2_seed, lambda p, o: ["convert", str(p), str(o / "tf.txt"), "--to",
                                                 "tum", "--topic", "/tf:odom.base_footprint"],
                       mutable=lambda p: p / "tf_example.db3", text=False, json=False),
    "imu_csv": Family(_imu_csv_seed, lambda p, o: ["allan", str(p), "--json", "--csv",
                                                   str(o / "curves.csv")]),
    "imu_npy": Family(_imu_npy_seed, lambda p, o: ["allan", str(p), "--json"], text=False),
    "imu_npz": Family(_imu_npz_seed, lambda p, o: ["allan", str(p), "--json"], text=False),
    "events_npz": Family(_events_npz_seed, lambda p, o: ["hotpix", str(p), "--json", "--hot-out",
                                                         str(o / "hot.txt")], text=False),
    "events_txt": Family(_events_txt_seed, lambda p, o: ["events", "frames", str(p), "--out",
                                                         str(o / "frames"), "--rate-hz", "10",
                                                         "--json"]),
    "hot_list": Family(_hot_list_seed, lambda p, o: ["hotpix", str(p.parent / "events.npz"),
                                                     "--apply", str(p), "--filtered-out",
                                                     str(o / "clean.npz"), "--json"]),
    "kitti_times": Family(_kitti_times_seed, lambda p, o: [
        "ate", str(p.parent / "est_kitti.txt"), str(p.parent / "ref_kitti.txt"), "--format-est",
        "kitti", "--format-ref", "kitti", "--times-est", str(p), "--times-ref", str(p), "--json"]),
    # --no-render: the family tests the YAML reader and the config checks, not the renderer's speed
    "sim_yaml": Family(_sim_yaml_seed, lambda p, o: ["sim", "--config", str(p), "--out",
                                                     str(o / "seq"), "--no-render", "--json"],
                       also_names=("seq",)),
    # the VIO's inputs: the sequence's sequence.yaml, the Kalibr camchain and imu.yaml (a vio run
    # on the 20-frame seed costs ~0.2 s, so every family gets its full share of mutants)
    "vio_sequence_yaml": Family(_vio_seq_seed, lambda p, o: _vio_argv(p, o),
                                mutable=lambda p: p / "sequence.yaml"),
    "vio_camchain": Family(_vio_calib_seed, lambda p, o: _vio_argv(p.parent, o, p)),
    "vio_imu_yaml": Family(_vio_imu_yaml_seed,
                           lambda p, o: _vio_argv(p.parent, o, None, "--imu", str(p))),
    # the report command's runs folder: one mutated trajectory among the runs
    "report_runs": Family(_report_seed, lambda p, o: ["report", str(p), "--json", "--no-figures",
                                                      "--no-cache", "--workers", "1", "--out",
                                                      str(o / "report")],
                          mutable=lambda p: p / "seq1" / "alpha" / "t1" / "est.txt"),
    # the calibration's inputs: a Kalibr camchain given to --check, and the sequence.yaml that holds
    # the target and the true cameras
    "calib_camchain": Family(_calib_sequence, lambda p, o: ["calib", str(p), "--check",
                                                            str(p / "camchain.yaml"), "--json"],
                             mutable=lambda p: p / "camchain.yaml"),
    "calib_sequence_yaml": Family(_calib_sequence, lambda p, o: ["calib", str(p), "--json", "--yaml",
                                                                 str(o / "camchain.yaml")],
                                  mutable=lambda p: p / "sequence.yaml"),
    # (last: a new family keeps the seeds of the others' mutants, which hang on their index)
    # an IBISCape DVS folder: a corrupt events/<ns>.npz window is named in the one error line
    "events_dvs_folder": Family(_dvs_folder_seed, lambda p, o: ["hotpix", str(p), "--sensor-size", "64x48",
                                                                "--json", "--hot-out", str(o / "hot.txt")],
                                mutable=_dvs_window, text=False),
    # Kalibr's files as other projects ship them (one reader each, io.kalibr / io.yaml_file): an
    # OpenCV %YAML:1.0 camchain with T_imu_cam and an imu chain for the VIO, a target yaml for calib
    "vio_camchain_opencv": Family(_vio_camchain_opencv_seed,
                                  lambda p, o: _vio_argv(p.parent, o, p)),
    "vio_imu_chain_opencv": Family(_vio_imu_chain_opencv_seed,
                                   lambda p, o: _vio_argv(p.parent, o, None, "--imu", str(p))),
    "calib_target_yaml": Family(_calib_target_seed, lambda p, o: ["calib", str(p.parent), "--target",
                                                                  str(p), "--json"]),
    # the foreign IMU tables (after the others, so that their mutants keep their seeds)
    "imu_named_csv": Family(_imu_named_csv_seed, lambda p, o: ["allan", str(p), "--json", "--csv",
                                                               str(o / "curves.csv")]),
    "imu_rostopic_csv": Family(_imu_rostopic_seed, lambda p, o: ["allan", str(p), "--json"]),
    # one door for a sequence (io/open_sequence.py): an EuRoC folder's OpenCV-YAML sensor file and
    # frame list, and a ROS 1 bag's image and IMU messages
    "euroc_sensor_yaml": Family(_euroc_vio_seed, _euroc_vio_argv,
                                mutable=lambda p: p / "mav0" / "cam1" / "sensor.yaml"),
    "euroc_frame_list": Family(_euroc_vio_seed, _euroc_vio_argv,
                               mutable=lambda p: p / "mav0" / "cam0" / "data.csv"),
    "ros1_image_bag": Family(_image_bag_seed, lambda p, o: [
        "vio", str(p), "-o", str(o / "est.txt"), "--calib", str(p.parent / "SVI_1_town" / "camchain-imucam.yaml"),
        "--imu", str(p.parent / "SVI_1_town" / "imu.yaml"), "--max-frames", str(VIO_FRAMES), "--json"],
        text=False),
}


# ---- event files as people have them (AEDAT4, HDF5, ROS bags with dvs_msgs/EventArray) ----


def _events_us() -> object:
    from ibiscape_eval.core.events import Events

    ev = _events()
    assert isinstance(ev, Events)
    return Events(ev.t_ns // 1000 * 1000, ev.x, ev.y, ev.p)  # AEDAT4/HDF5 hold microseconds


def _event_file_seed(name: str, fmt: str):  # type: ignore[no-untyped-def]
    def build(folder: Path) -> Path:
        from ibiscape_eval.io.events import write_events

        p = folder / name
        write_events(p, _events_us(), fmt=fmt, sensor_size=(64, 48))  # type: ignore[arg-type]
        return p

    return build


def _hotpix_argv(p: Path, o: Path) -> list[str]:
    return ["hotpix", str(p), "--json", "--hot-out", str(o / "hot.txt"), "--filtered-out",
            str(o / f"clean{p.suffix}")]


FAMILIES["events_aedat4"] = Family(_event_file_seed("events.aedat4", "aedat4"), _hotpix_argv,
                                   text=False)
FAMILIES["events_hdf5"] = Family(_event_file_seed("events.h5", "hdf5"),
                                 lambda p, o: ["events", "frames", str(p), "--out", str(o / "frames"),
                                               "--json"], text=False)
FAMILIES["events_bag_ros1"] = Family(_event_file_seed("events.bag", "bag"), _hotpix_argv, text=False)
FAMILIES["events_bag_ros2"] = Family(_event_file_seed("events_ros2", "bag"), _hotpix_argv,
                                     mutable=lambda p: p / f"{p.name}.db3", text=False)


# ---- the RGB-D depth reader (vio --setup rgbd): one depth image of a generated sequence ----

#: the generated RGB-D sequence (64x48, 2 s), built once per campaign and copied into each seed
_RGBD_TEMPLATE: dict[str, Path] = {}


def _rgbd_seed(unit: str):  # type: ignore[no-untyped-def]
    """Seed: a copy of the RGB-D template; ``carla-log`` drops ``depth/mm/`` so that the reader
    takes CARLA's 8-bit log files in ``depth/frames/``."""
    def build(folder: Path) -> Path:
        key = str(folder.parent)
        if key not in _RGBD_TEMPLATE:
            from ibiscape_eval.sim.config import preset, with_resolution
            from ibiscape_eval.sim.generator import generate

            d = folder.parent / ".rgbd_template" / "RGBD_1_town"
            generate(with_resolution(preset("rgbd", "slam", "clear", duration_s=2.0, seed=3), 64, 48), d,
                     render=True)
            _RGBD_TEMPLATE[key] = d
        dst = folder / "RGBD_1_town"
        shutil.copytree(_RGBD_TEMPLATE[key], dst)
        if unit == "carla-log":
            shutil.rmtree(dst / "depth" / "mm")
        return dst

    return build


def _depth_image(sub: str):  # type: ignore[no-untyped-def]
    return lambda p: sorted((p / "depth" / sub).glob("*.png"))[3]


def _rgbd_argv(p: Path, o: Path) -> list[str]:
    return ["vio", str(p), "-o", str(o / "est.txt"), "--setup", "rgbd", "--max-frames",
            str(VIO_FRAMES), "--json"]


FAMILIES["rgbd_depth_mm"] = Family(_rgbd_seed("mm"), _rgbd_argv, mutable=_depth_image("mm"),
                                   text=False)
FAMILIES["rgbd_depth_carla_log"] = Family(_rgbd_seed("carla-log"), _rgbd_argv,
                                          mutable=_depth_image("frames"), text=False)


# ---- the PNG decoder (io.images.decode_png_grey) behind every VIO image: one RGB frame ----
FAMILIES["vio_rgb_png"] = Family(_rgbd_seed("mm"), _rgbd_argv,
                                 mutable=lambda p: sorted((p / "rgb" / "frames").glob("*.png"))[3], text=False)
