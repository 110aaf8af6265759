r"""One door for a recording: :func:`open_sequence` returns a typed, lazy
:class:`~ibiscape_eval.core.sequence.Sequence` from every layout people have.

Layouts, tried in this order (the first that fits is taken; when none fits the error lists what
each lacked):

- **rosbag**: a ROS 1 ``.bag`` file, or a ROS 2 bag (folder with ``metadata.yaml``, or its
  ``.db3`` / ``.mcap`` file), read through ``rosbags`` (no ROS install).  ``sensor_msgs/Image`` and
  ``CompressedImage`` topics are cameras (frames decoded on demand), ``sensor_msgs/Imu`` the IMU,
  ``dvs_msgs/EventArray`` topics event cameras (read by :func:`ibiscape_eval.io.events.open_events`).
  Topics are chosen with ``image_topics`` / ``imu_topic``; the bag's topics are listed when the
  choice is ambiguous or a named topic is missing.
- **ibiscape**: our generator's folders and the paper's: camera folders (``rgbL``, ``rgbR``,
  ``rgb``, ``davisL``, ``davisR``) with ``timestamps.csv`` and ``frames/`` (DVS: ``events/``),
  ``other_sensors/imu*.csv``, ``vehicle_gt/groundtruth_sync.csv``, and (ours) ``sequence.yaml``
  with the cameras, IMU noise, target and truth.
- **tumvi**: the ASL layout below plus ``dso/camchain.yaml`` (Kalibr camchain-imucam, equidistant
  cameras) and ``dso/imu_config.yaml``; ground truth ``mav0/mocap0/data.csv``.
- **euroc**: ``mav0/camN/data.csv`` + ``data/``, ``mav0/imu0/data.csv``, ``sensor.yaml`` per
  sensor (OpenCV's ``%YAML:1.0`` header accepted), ground truth
  ``mav0/state_groundtruth_estimate0/data.csv`` optional (an EMPTY csv counts as none).
- **images**: ``NAME=GLOB`` specifications (``images=``), paired by a number in the file names.

Opening reads only the frame lists and the small YAML files; images, event windows, IMU samples
and ground truth are read on first use, so a one-hour EuRoC folder opens in well under a second
(``benchmarks/bench_open_sequence.py``).

A Kalibr camchain given with ``calib=`` replaces the layout's intrinsics; a camchain that
disagrees with the recording on camera names or resolution is refused naming both.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from collections.abc import Sequence as Seq
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError, Remedy
from ibiscape_eval.core.sequence import CameraStream, ImuStream, Lazy, Sequence

from .yaml_file import read_yaml_mapping

__all__ = ["NoLayoutError", "apply_camchain", "open_sequence"]

#: IBISCape camera folder names, in chain order
CAMERA_FOLDERS = ("rgbL", "rgbR", "rgb", "davisL", "davisR")
IMU_NOISE_KEYS = ("gyroscope_noise_density", "gyroscope_random_walk",
                  "accelerometer_noise_density", "accelerometer_random_walk")


class NoLayoutError(FormatError):
    """A path in none of the layouts (the message says what each lacked)."""


# ------------------------------------------------------------------------------------ frame lists
def _frame_list(csv: Path, folders: Seq[Path]) -> tuple[npt.NDArray[np.int64], Lazy[tuple[Path, ...]], int]:
    """Stamps and (lazy) files of a ``#timestamp [ns],filename`` list; names are resolved in the
    first of ``folders`` holding the first frame (one check, not one per frame)."""
    from .stereo import read_frame_list

    stamps, names = read_frame_list(csv)
    bad = next((i for i, n in enumerate(names) if "\x00" in n), None)
    if bad is not None:  # a path cannot hold a NUL byte: name the line instead of failing later
        with open(csv, "rb") as fh:
            line = next(no for no, raw in enumerate(fh, start=1) if b"\x00" in raw)
        raise FormatError(csv, "a file name holds a NUL byte; the frame list is damaged", line=line)
    base = next((f for f in folders if (f / names[0]).is_file()), folders[0])
    return stamps, Lazy(lambda: tuple(base / n for n in names)), len(names)


def _image_loader(files: Lazy[tuple[Path, ...]]) -> Any:
    from .image_sets import read_image

    return lambda i: read_image(files.get()[i])


def _size(v: Any) -> tuple[int, int] | None:
    try:
        w, h = (int(x) for x in v)
    except (TypeError, ValueError):
        return None
    return (w, h) if w > 0 and h > 0 else None


def _model_or_none(entry: Mapping[str, Any]) -> CameraModel | None:
    try:
        return CameraModel.from_kalibr(dict(entry))
    except (IbiscapeError, OverflowError, TypeError, ValueError):
        return None


def _gt_lazy(path: Path, fmt: str) -> tuple[Lazy[Any] | None, str | None]:
    """Ground truth read on first use; None (and a note) for a missing or empty csv."""
    if not path.is_file():
        return None, None
    with open(path, "rb") as fh:
        head = fh.read(4096)
    rows = any(ln.strip() and not ln.lstrip().startswith(b"#") for ln in head.splitlines())
    if not rows and len(head) < 4096:
        return None, f"{path}: ground-truth csv is empty; the sequence has no ground truth"

    def read() -> Any:
        from .trajectory import read_trajectory

        return read_trajectory(path, fmt, name="groundtruth")

    return Lazy(read), None


def _imu_lazy(path: Path, fmt: str) -> Lazy[Any]:
    def read() -> Any:
        from .stereo import read_imu_samples

        return read_imu_samples(path, fmt=fmt)

    return Lazy(read)


def _noise(doc: Mapping[str, Any] | None, source: str) -> tuple[Any, str | None]:
    """``(ImuNoise, None)`` when ``doc`` states the densities, ``(None, problem)`` when it states
    them badly, ``(None, None)`` when it states none."""
    from ibiscape_eval.core.kalibr import ImuNoise

    if not isinstance(doc, Mapping) or not any(k in doc for k in IMU_NOISE_KEYS):
        return None, None
    try:
        return ImuNoise.from_kalibr(doc, source=source), None
    except IbiscapeError as e:
        return None, str(e).removeprefix(f"{source}: ")


def _rate(v: Any) -> float | None:
    try:
        r = float(v)
    except (TypeError, ValueError):
        return None
    return r if np.isfinite(r) and r > 0 else None


# ---------------------------------------------------------------------------------------- IBISCape
def _ibiscape(root: Path) -> Sequence | str:
    """IBISCape (ours or the paper's), or what the folder lacks."""
    from .sequence import read_sequence_yaml

    has_doc = (root / "sequence.yaml").is_file()
    cam_dirs = [n for n in CAMERA_FOLDERS if (root / n / "timestamps.csv").is_file()]
    single = root.name in CAMERA_FOLDERS and (root / "timestamps.csv").is_file()
    if not (has_doc or cam_dirs or single or (root / "other_sensors").is_dir()):
        return ("no sequence.yaml, no camera folder (rgbL, rgbR, rgb, davisL, davisR) with "
                "timestamps.csv, no other_sensors/")
    doc: dict[str, Any] = read_sequence_yaml(root / "sequence.yaml") if has_doc else {}
    if single and not has_doc and (root.parent / "sequence.yaml").is_file():
        doc = read_sequence_yaml(root.parent / "sequence.yaml")  # a camera folder of a sequence
    seq_cams = doc.get("cameras") if isinstance(doc.get("cameras"), dict) else {}
    assert isinstance(seq_cams, dict)
    cameras: list[CameraStream] = []
    folders = [(root.name, root)] if single else [(n, root / n) for n in cam_dirs]
    for name, folder in folders:
        entry = seq_cams.get(name) if isinstance(seq_cams.get(name), dict) else {}
        assert isinstance(entry, dict)
        T_bc = None
        if "T_body_cam" in entry:
            try:
                T_bc = np.asarray(entry["T_body_cam"], dtype=np.float64).reshape(4, 4)
            except (TypeError, ValueError):
                T_bc = None
        common: dict[str, Any] = dict(
            root=folder, sensor_size=_size(entry.get("resolution")), rate_hz=_rate(entry.get("rate_hz")),
            camera=_model_or_none(entry) if "intrinsics" in entry else None, T_body_cam=T_bc,
            rostopic=entry.get("rostopic"), entry=entry,
            calibration_source=str((root.parent if single else root) / "sequence.yaml") if entry else "")
        if (folder / "events").is_dir():
            from .events import open_events

            src = open_events(folder)
            win = np.array([[a, b] for a, b, _ in src.windows], np.int64).reshape(-1, 2)
            paths = tuple(p for _, _, p in src.windows)
            cameras.append(CameraStream(name, "events", win[:, 1].copy(), windows_ns=win,
                                        files=Lazy.of(paths), n=len(paths), events=Lazy.of(src),
                                        **common))
            continue
        stamps, files, n = _frame_list(folder / "timestamps.csv", [folder / "frames", folder])
        cameras.append(CameraStream(name, "frames", stamps, files=files, loader=_image_loader(files),
                                    n=n, **common))
    imu = _ibiscape_imu(root, doc)
    gt, note = _gt_lazy(root / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    target = doc.get("target") if isinstance(doc.get("target"), dict) else None
    return Sequence(root, "ibiscape", tuple(cameras), imu, target,
                    f"{root}/sequence.yaml: target" if target else "", gt, doc,
                    tuple(n for n in (note,) if n))


def _ibiscape_imu(root: Path, doc: Mapping[str, Any]) -> ImuStream | None:
    imus = doc.get("imus") if isinstance(doc.get("imus"), dict) else {}
    assert isinstance(imus, dict)
    name = "imu0" if "imu0" in imus else next(iter(imus), "imu0")
    entry = imus.get(name) if isinstance(imus.get(name), dict) else {}
    assert isinstance(entry, dict)
    f = root / str(entry["file"]) if entry.get("file") else None
    if f is None or not f.is_file():
        cands = sorted((root / "other_sensors").glob("imu*.csv"))
        f = cands[0] if cands else None
    src = f"{root / 'sequence.yaml'}: imus"
    noise, problem = _noise(entry, src)
    if f is None and noise is None and problem is None:
        return None
    T = None
    if "T_body_imu" in entry:
        try:
            T = np.asarray(entry["T_body_imu"], dtype=np.float64).reshape(4, 4)
        except (TypeError, ValueError):
            T = None
    fmt = "ibiscape" if (root / "vehicle_gt").is_dir() else "euroc"
    if f is None:  # sequence.yaml states the IMU, but its samples are not here
        def missing() -> Any:
            raise FormatError(root / "other_sensors", "no IMU file (other_sensors/imu0.csv), although "
                              "sequence.yaml states the IMU; give the IMU samples of this run (calib "
                              "--imu: --imu-data PATH)")

        samples: Lazy[Any] = Lazy(missing)
        f = root / "other_sensors" / "imu0.csv"
    else:
        samples = _imu_lazy(f, fmt)
    return ImuStream(name, f, samples, noise, str(root / "sequence.yaml") if noise or problem else "",
                     _rate(entry.get("update_rate")), T, entry.get("rostopic"), fmt, problem)


# ---------------------------------------------------------------------------------- EuRoC / TUM-VI
def _asl_root(root: Path) -> Path | None:
    for m in (root / "mav0", root):
        if any(m.glob("cam[0-9]*/data.csv")):
            return m
    return None


def _asl(root: Path, tumvi: bool) -> Sequence | str:
    from .asl import read_asl_sensor_yaml  # with the trajectory readers (scipy): not for --images

    m = _asl_root(root)
    if m is None:
        return "no mav0/camN/data.csv"
    camchain = root / "dso" / "camchain.yaml"
    if tumvi and not camchain.is_file():
        return "no dso/camchain.yaml"
    chain: dict[str, Any] = {}
    if tumvi:
        from .kalibr import read_camchain

        chain = {c.name: c for c in read_camchain(camchain).cameras}
    cams = sorted((c for c in m.glob("cam[0-9]*") if c.name[3:].isdigit() and (c / "data.csv").is_file()),
                  key=lambda c: int(c.name[3:]))
    cameras = []
    for c in cams:
        stamps, files, n = _frame_list(c / "data.csv", [c / "data", c])
        entry: dict[str, Any] = {}
        T_bc: npt.NDArray[np.float64] | None = None
        src = ""
        rate = None
        model = None
        if c.name in chain:
            cc = chain[c.name]
            model = cc.camera
            entry = {**model.to_kalibr(), **({"rostopic": cc.rostopic} if cc.rostopic else {})}
            src = str(camchain)
            if cc.T_cam_imu is not None:
                from ibiscape_eval.core.transforms import invert_transforms

                T_bc = invert_transforms(cc.T_cam_imu)
        elif (c / "sensor.yaml").is_file():
            from .asl import read_asl_camera

            model, T_bc = read_asl_camera(c / "sensor.yaml")  # the one EuRoC camera mapping
            entry = model.to_kalibr()
            src = str(c / "sensor.yaml")
            rate = _rate(read_asl_sensor_yaml(c / "sensor.yaml").get("rate_hz"))
        cameras.append(CameraStream(
            c.name, "frames", stamps, c, _size(entry.get("resolution")), rate,
            model or (_model_or_none(entry) if "intrinsics" in entry else None), T_bc,
            entry.get("rostopic"), entry, files=files, loader=_image_loader(files), n=n,
            calibration_source=src))
    imu = None
    if (m / "imu0" / "data.csv").is_file():
        f = m / "imu0" / "data.csv"
        noise, problem, nsrc, rate, T = None, None, "", None, None
        if (m / "imu0" / "sensor.yaml").is_file():
            nsrc = str(m / "imu0" / "sensor.yaml")
            d = read_asl_sensor_yaml(nsrc)
            (noise, problem), rate, T = _noise(d, nsrc), _rate(d.get("rate_hz")), d["T_BS"]
        cfg = root / "dso" / "imu_config.yaml"
        if tumvi and cfg.is_file():
            d = read_yaml_mapping(cfg, what="imu_config.yaml")
            if any(k in d for k in IMU_NOISE_KEYS):
                (noise, problem), nsrc = _noise(d, str(cfg)), str(cfg)
                rate = _rate(d.get("update_rate")) or rate
        imu = ImuStream("imu0", f, _imu_lazy(f, "euroc"), noise, nsrc if noise or problem else "", rate,
                        np.eye(4) if T is None and tumvi else T, None, "euroc", problem)
    notes = []
    gt = None
    for sub in ("state_groundtruth_estimate0", "mocap0", "gt0"):
        gt, note = _gt_lazy(m / sub / "data.csv", "euroc")
        if note:
            notes.append(note)
        if gt is not None:
            break
    return Sequence(m.parent if m.name == "mav0" else m, "tumvi" if tumvi else "euroc",
                    tuple(cameras), imu, None, "", gt, {}, tuple(notes))


# -------------------------------------------------------------------------------------------- bags
def _is_bag(p: Path) -> bool:
    from .bag import BAG_SUFFIXES

    return (p.is_file() and p.suffix in BAG_SUFFIXES) or (p.is_dir() and (p / "metadata.yaml").is_file())


def _bag(p: Path, image_topics: Seq[str] | None, imu_topic: str | None,
         event_topics: Seq[str] | None) -> Sequence:
    from .bag import EVENT_MSGTYPE, IMAGE_MSGTYPES, IMU_MSGTYPE, BagImageTopic, bag_topics

    topics = bag_topics(p)
    listing = ", ".join(f"{t} ({ty.replace('/msg/', '/')}, {n})" for t, ty, n in topics) or "none"
    kinds = {t: ty for t, ty, _ in topics}
    imgs = [t for t, ty, _ in topics if ty in IMAGE_MSGTYPES]
    evs = [t for t, ty, _ in topics if ty == EVENT_MSGTYPE]
    imus = [t for t, ty, _ in topics if ty == IMU_MSGTYPE]

    def need(topic: str, types: tuple[str, ...], what: str) -> None:
        if topic not in kinds:
            raise FormatError(p, f"no topic {topic!r} in the bag; its topics: {listing}")
        if kinds[topic] not in types:
            raise FormatError(p, f"topic {topic!r} carries {kinds[topic]}, not {what}; its topics: {listing}")

    if image_topics:
        for t in image_topics:
            need(t, IMAGE_MSGTYPES, "sensor_msgs/Image or CompressedImage")
        chosen = list(image_topics)
    elif len(imgs) <= 2:
        chosen = imgs
    else:
        raise FormatError(p, f"{len(imgs)} image topics ({', '.join(imgs)}); choose the cameras with "
                          "--topic (repeat, in chain order)")
    if event_topics:
        for t in event_topics:
            need(t, (EVENT_MSGTYPE,), "dvs_msgs/EventArray")
        chosen_ev = list(event_topics)
    else:
        chosen_ev = evs if not image_topics else []
    if imu_topic:
        need(imu_topic, (IMU_MSGTYPE,), "sensor_msgs/Imu")
    elif len(imus) > 1:
        raise FormatError(p, f"{len(imus)} sensor_msgs/Imu topics ({', '.join(imus)}); choose one "
                          "with {0}", hint=(Remedy("imu_topic"),))
    else:
        imu_topic = imus[0] if imus else None
    if not chosen and not chosen_ev:
        raise FormatError(p, f"no camera topics (sensor_msgs/Image, CompressedImage, dvs_msgs/EventArray); "
                          f"its topics: {listing}")
    names = _topic_names(chosen + chosen_ev)
    cameras = []
    for t in chosen:
        src = BagImageTopic.index(p, t)
        cameras.append(CameraStream(names[t], "frames", src.stamps_ns, p, src.sensor_size, None,
                                    rostopic=t, loader=src.load, n=len(src.stamps_ns),
                                    exact_stamps=False))
    for t in chosen_ev:
        cameras.append(CameraStream(names[t], "events", None, p, rostopic=t,
                                    events=Lazy(partial(_bag_events, p, t)), n=0))
    imu = None
    if imu_topic is not None:
        def read_imu(topic: str = imu_topic) -> Any:
            from .bag import read_imu_bag

            st, data, _ = read_imu_bag(p, topic)
            return (st, np.ascontiguousarray(data[:, :3]), np.ascontiguousarray(data[:, 3:]))

        imu = ImuStream(_topic_names([imu_topic])[imu_topic], p, Lazy(read_imu), None, "", None, None,
                        imu_topic, "rosbag")
    return Sequence(p, "rosbag", tuple(cameras), imu)


def _bag_events(p: Path, topic: str) -> Any:
    """An event topic through the events reader (one reader for dvs_msgs/EventArray)."""
    from .events import open_events

    return open_events(p, topic=topic)


def _topic_names(topics: Seq[str]) -> dict[str, str]:
    """A camera name per topic: its first path element (``/cam0/image_raw`` -> ``cam0``) when they
    differ, else the whole topic."""
    first = {t: (t.strip("/").split("/") or [t])[0] or t for t in topics}
    if len(set(first.values())) == len(topics):
        return first
    return {t: t.strip("/").replace("/", "_") or t for t in topics}


# ------------------------------------------------------------------------------------------ globs
def _globs(specs: Seq[str]) -> Sequence:
    from .image_sets import image_sets_from_globs

    cams = []
    for s in image_sets_from_globs(specs):
        files = Lazy.of(s.paths)
        cams.append(CameraStream(s.name, "frames", s.stamps_ns, s.root, files=files,
                                 loader=_image_loader(files), n=len(s.paths),
                                 exact_stamps=s.exact_stamps))
    return Sequence(Path(str(cams[0].root)) if cams else Path("."), "images", tuple(cams))


# ------------------------------------------------------------------------------------------- door
def open_sequence(path: str | os.PathLike[str] | None = None, *,
                  images: Seq[str] | None = None, cameras: Seq[str] | None = None,
                  image_topics: Seq[str] | None = None, imu_topic: str | None = None,
                  event_topics: Seq[str] | None = None, layout: str | None = None,
                  calib: str | os.PathLike[str] | None = None,
                  sensor_size: tuple[int, int] | None = None) -> Sequence:
    """Open a recording in any supported layout (module docstring) without reading its data.

    Parameters
    ----------
    path : folder, bag file or bag folder
        None with ``images``.
    images : list of ``NAME=GLOB``
        Plain image files per camera, in chain order.
    cameras : list of str, optional
        Keep only these cameras, in this order (folder names, ``camN``, a bag topic's camera).
    image_topics, imu_topic, event_topics : ROS topics, optional
        Bags: the camera topics (in chain order), the IMU topic, the event topics.
    layout : str, optional
        Force a layout (``ibiscape``, ``euroc``, ``tumvi``, ``rosbag``) instead of detecting it.
    calib : Kalibr camchain(-imucam).yaml, optional
        Intrinsics (and ``T_cam_imu``) replacing the layout's; checked against the recording
        (:func:`apply_camchain`).
    sensor_size : (width, height), optional
        For cameras whose size the layout does not state (event cameras of the paper's layout).

    Raises
    ------
    NoLayoutError
        The path is in none of the layouts: the message lists each layout and what it lacked.
    FormatError
        A file of the recording is malformed, a bag topic is missing or ambiguous (the bag's
        topics are listed), a camchain disagrees with the recording.
    """
    if images:
        if path is not None:
            raise IbiscapeError("give either a sequence path or image globs, not both")
        seq = _globs(images)
    else:
        if path is None:
            raise IbiscapeError("give a sequence folder, a ROS bag, or image globs (NAME=GLOB)")
        p = Path(path)
        if not p.exists():
            raise FormatError(p, "no such file or folder; give a sequence folder (IBISCape, EuRoC, "
                              "TUM-VI), a ROS bag, or image globs (--images NAME=GLOB)")
        seq = _detect(p, layout, image_topics, imu_topic, event_topics)
    if sensor_size is not None:
        seq = seq.with_cameras([c if c.sensor_size is not None else c.with_sensor_size(sensor_size)
                                for c in seq.cameras])
    seq = seq.select(list(cameras) if cameras else None)
    if calib is not None:
        seq = apply_camchain(seq, calib)
    return seq


def _detect(p: Path, layout: str | None, image_topics: Seq[str] | None, imu_topic: str | None,
            event_topics: Seq[str] | None) -> Sequence:
    tried: list[tuple[str, str]] = []
    order = [layout] if layout else ["rosbag", "ibiscape", "tumvi", "euroc"]
    for name in order:
        if name == "rosbag":
            if _is_bag(p):
                return _bag(p if p.suffix not in (".db3", ".mcap") else p.parent, image_topics,
                            imu_topic, event_topics)
            if p.is_file() and p.suffix in (".db3", ".mcap"):
                return _bag(p.parent, image_topics, imu_topic, event_topics)
            tried.append((name, "not a .bag file or a folder with metadata.yaml"))
            continue
        if not p.is_dir():
            tried.append((name, "not a folder"))
            continue
        if name == "ibiscape":
            r: Sequence | str = _ibiscape(p)
        elif name in ("euroc", "tumvi"):
            r = _asl(p, tumvi=name == "tumvi")
        else:
            raise IbiscapeError(f"layout {name!r}: choose one of rosbag, ibiscape, tumvi, euroc")
        if isinstance(r, Sequence):
            return r
        tried.append((name, r))
    raise NoLayoutError(p, "in none of the sequence layouts: " + "; ".join(
        f"{_LAYOUT_NAMES[n]}: {why}" for n, why in tried)
        + "; for plain image files use --images NAME=GLOB")


_LAYOUT_NAMES = {"rosbag": "ROS bag", "ibiscape": "IBISCape", "tumvi": "TUM-VI", "euroc": "EuRoC/ASL"}


# --------------------------------------------------------------------------------------- camchain
def apply_camchain(seq: Sequence, calib: str | os.PathLike[str]) -> Sequence:
    """The sequence with the intrinsics (and ``T_body_cam = inv(T_cam_imu)`` when given) of a
    Kalibr camchain, matched to the cameras by the rostopic ``/<name>/...``, the ``camN`` key, or
    chain order (:func:`ibiscape_eval.core.kalibr.check_camchain_matches`).

    Raises
    ------
    FormatError
        The camchain has no entry for a camera of the sequence, or a resolution differs from the
        size the recording states (naming both).
    """
    from ibiscape_eval.core.kalibr import check_camchain_matches
    from ibiscape_eval.core.transforms import invert_transforms

    from .kalibr import read_camchain

    chain = read_camchain(calib)
    found = check_camchain_matches(chain, {c.name: c.sensor_size for c in seq.cameras},
                                   source=str(calib))
    cams = []
    for c in seq.cameras:
        cc = chain.cameras[found[c.name]]
        T_bc = c.T_body_cam if cc.T_cam_imu is None else invert_transforms(cc.T_cam_imu)
        entry = {**cc.camera.to_kalibr(), **({"rostopic": cc.rostopic} if cc.rostopic else {})}
        cams.append(replace(c, camera=cc.camera, sensor_size=cc.resolution, T_body_cam=T_bc, entry=entry,
                            calibration_source=str(calib), rostopic=cc.rostopic or c.rostopic))
    return seq.with_cameras(cams)
