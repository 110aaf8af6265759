"""Re-pack a stereo+IMU sequence into the layouts people have: EuRoC/ASL with OpenCV's
``%YAML:1.0`` sensor files, TUM-VI (``dso/camchain.yaml``), ROS 1 and ROS 2 bags.

Used by tests/io/test_open_sequence*.py and the mutation families (tests/mutation/families.py).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import yaml

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
EUROC_REAL = REAL / "euroc_v1_01_kimera"
BAG_REAL = REAL / "euroc_v1_01_bag" / "v1_01_excerpt.bag"

_IMU_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
               "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n")


def opencv_yaml(doc: dict) -> str:
    """``doc`` as OpenCV's FileStorage writes it: the ``%YAML:1.0`` directive, then YAML."""
    return "%YAML:1.0\n" + yaml.safe_dump(doc, sort_keys=False)


def euroc_from(seq_dir: Path, out: Path, calib: Path, *, empty_gt: bool = True) -> Path:
    """Re-pack an IBISCape-layout stereo sequence (with its camchain-imucam.yaml) as an EuRoC ASL
    folder whose sensor.yaml files carry ``%YAML:1.0`` and whose ground-truth csv is empty."""
    from ibiscape_eval.io.kalibr import read_camchain
    from ibiscape_eval.vio.inputs import load_sequence

    src = load_sequence(seq_dir, calib=calib)
    m = out / "mav0"
    chain = {c.name: c for c in read_camchain(calib).cameras}
    for cam, stamps, files in (("cam0", src.frame_stamps_ns, src.left_files),
                               ("cam1", src.frame_stamps_ns, src.right_files)):
        (m / cam / "data").mkdir(parents=True)
        rows = []
        for t, f in zip(stamps, files, strict=True):
            shutil.copy(f, m / cam / "data" / f"{t}.png")
            rows.append(f"{t},{t}.png")
        (m / cam / "data.csv").write_text("#timestamp [ns],filename\n" + "\n".join(rows) + "\n")
        c = chain[cam]
        assert c.T_cam_imu is not None
        T_BS = np.linalg.inv(c.T_cam_imu)
        k = c.camera.to_kalibr()
        (m / cam / "sensor.yaml").write_text(opencv_yaml({
            "sensor_type": "camera", "rate_hz": 20,
            "T_BS": {"cols": 4, "rows": 4, "data": T_BS.ravel().tolist()},
            "resolution": k["resolution"], "camera_model": "pinhole",
            "intrinsics": k["intrinsics"], "distortion_model": "radial-tangential",
            "distortion_coefficients": k["distortion_coeffs"]}))
    (m / "imu0").mkdir()
    rows = [f"{t},{','.join(repr(float(x)) for x in (*g, *a))}"
            for t, g, a in zip(src.imu_stamps_ns, src.gyro_rad_s, src.accel_m_s2, strict=True)]
    (m / "imu0" / "data.csv").write_text(_IMU_HEADER + "\n".join(rows) + "\n")
    n = src.noise
    (m / "imu0" / "sensor.yaml").write_text(opencv_yaml({
        "T_BS": {"cols": 4, "rows": 4, "data": np.eye(4).ravel().tolist()}, "rate_hz": 200,
        "gyroscope_noise_density": n.gyro_noise_density_rad_s_sqrt_hz,
        "gyroscope_random_walk": n.gyro_random_walk_rad_s2_sqrt_hz,
        "accelerometer_noise_density": n.accel_noise_density_m_s2_sqrt_hz,
        "accelerometer_random_walk": n.accel_random_walk_m_s3_sqrt_hz}))
    (m / "state_groundtruth_estimate0").mkdir()
    gt = m / "state_groundtruth_estimate0" / "data.csv"
    if empty_gt:
        gt.write_bytes(b"")
    else:
        from ibiscape_eval.io import write_trajectory

        assert src.groundtruth is not None
        write_trajectory(gt, src.groundtruth, "euroc")
    return out


def tumvi_from_euroc(euroc: Path, out: Path) -> Path:
    """The EuRoC folder plus a TUM-VI ``dso/camchain.yaml`` (Kalibr camchain-imucam, equidistant
    cameras with small coefficients) and ``dso/imu_config.yaml``; the sensor.yaml files removed."""
    shutil.copytree(euroc, out)
    m = out / "mav0"
    doc = {}
    for k, cam in enumerate(("cam0", "cam1")):
        s = yaml.safe_load((m / cam / "sensor.yaml").read_text().split("\n", 1)[1])
        T_cam_imu = np.linalg.inv(np.asarray(s["T_BS"]["data"], float).reshape(4, 4))
        doc[cam] = {"T_cam_imu": T_cam_imu.tolist(), "camera_model": "pinhole",
                    "distortion_coeffs": [0.01, -0.002, 0.0005, -0.0001], "distortion_model": "equidistant",
                    "intrinsics": s["intrinsics"], "resolution": s["resolution"],
                    "rostopic": f"/{cam}/image_raw", "timeshift_cam_imu": 0.0}
        if k:
            doc[cam]["T_cn_cnm1"] = (np.asarray(doc[cam]["T_cam_imu"])
                                     @ np.linalg.inv(np.asarray(doc["cam0"]["T_cam_imu"]))).tolist()
        (m / cam / "sensor.yaml").unlink()
    imu = yaml.safe_load((m / "imu0" / "sensor.yaml").read_text().split("\n", 1)[1])
    (m / "imu0" / "sensor.yaml").unlink()
    (out / "dso").mkdir()
    (out / "dso" / "camchain.yaml").write_text(yaml.safe_dump(doc))
    (out / "dso" / "imu_config.yaml").write_text(yaml.safe_dump({
        k: imu[k] for k in ("gyroscope_noise_density", "gyroscope_random_walk",
                            "accelerometer_noise_density", "accelerometer_random_walk")}
        | {"update_rate": 200.0, "rostopic": "/imu0"}))
    return out


def bag_from_euroc(euroc: Path, out: Path, *, ros2: bool = False, compressed_right: bool = True,
                   extra_image_topics: tuple[str, ...] = (), extra_imu_topics: tuple[str, ...] = ()
                   ) -> Path:
    """A ROS 1 bag (or ROS 2 sqlite3 bag folder) with the EuRoC folder's frames and IMU samples:
    ``/cam0/image_raw`` (``Image`` mono8), ``/cam1/image_raw[/compressed]``, ``/imu0`` (``Imu``),
    plus extra copies of the left images / IMU on the given topics (to make choices ambiguous)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if not ros2 else Stores.ROS2_HUMBLE)
    Image = ts.types["sensor_msgs/msg/Image"]
    CImage = ts.types["sensor_msgs/msg/CompressedImage"]
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    Vec = ts.types["geometry_msgs/msg/Vector3"]
    Quat = ts.types["geometry_msgs/msg/Quaternion"]

    def hdr(t: int, fid: str) -> object:
        stamp = Time(sec=t // 10**9, nanosec=t % 10**9)
        return Header(seq=0, stamp=stamp, frame_id=fid) if not ros2 else Header(stamp=stamp, frame_id=fid)

    def ser(msg: object, ty: str) -> bytes:
        return ts.serialize_ros1(msg, ty) if not ros2 else ts.serialize_cdr(msg, ty)

    m = euroc / "mav0"
    msgs: list[tuple[int, str, str, bytes]] = []
    right_topic = "/cam1/image_raw/compressed" if compressed_right else "/cam1/image_raw"
    for cam, topics in (("cam0", ("/cam0/image_raw", *extra_image_topics)), ("cam1", (right_topic,))):
        for line in (m / cam / "data.csv").read_text().splitlines()[1:]:
            t, name = int(line.split(",")[0]), line.split(",")[1].strip()
            f = m / cam / "data" / name
            for topic in topics:
                if topic.endswith("compressed"):
                    msg = CImage(header=hdr(t, cam), format="mono8; png compressed",
                                 data=np.frombuffer(f.read_bytes(), np.uint8))
                    msgs.append((t, topic, CImage.__msgtype__, ser(msg, CImage.__msgtype__)))
                else:
                    img = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
                    msg = Image(header=hdr(t, cam), height=img.shape[0], width=img.shape[1],
                                encoding="mono8", is_bigendian=0, step=img.shape[1], data=img.reshape(-1))
                    msgs.append((t, topic, Image.__msgtype__, ser(msg, Image.__msgtype__)))
    for line in (m / "imu0" / "data.csv").read_text().splitlines()[1:]:
        v = line.split(",")
        t, f6 = int(v[0]), [float(x) for x in v[1:7]]
        msg = Imu(header=hdr(t, "imu0"), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                  orientation_covariance=np.full(9, -1.0),
                  angular_velocity=Vec(x=f6[0], y=f6[1], z=f6[2]), angular_velocity_covariance=np.zeros(9),
                  linear_acceleration=Vec(x=f6[3], y=f6[4], z=f6[5]),
                  linear_acceleration_covariance=np.zeros(9))
        raw = ser(msg, Imu.__msgtype__)
        for topic in ("/imu0", *extra_imu_topics):
            msgs.append((t, topic, Imu.__msgtype__, raw))
    if ros2:
        from rosbags.rosbag2 import Writer as Writer2

        w2 = Writer2(out, version=8)
        w2.open()
        conns = {}
        for _, topic, ty, _ in msgs:
            if topic not in conns:
                conns[topic] = w2.add_connection(topic, ty, typestore=ts)
        for t, topic, _, raw in sorted(msgs, key=lambda x: x[0]):
            w2.write(conns[topic], t, raw)
        w2.close()
        return out
    from rosbags.rosbag1 import Writer

    with Writer(out) as w:
        conns = {}
        for _, topic, ty, _ in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, ty, typestore=ts)
        for t, topic, _, raw in sorted(msgs, key=lambda x: x[0]):
            w.write(conns[topic], t, raw)
    return out
