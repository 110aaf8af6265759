"""Write rendered calibration scenes as IBISCape-layout sequence folders (for the CLI tests)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml


def write_camera_folder(folder: Path, images: list[np.ndarray], stamps_ns: list[int]) -> None:
    (folder / "frames").mkdir(parents=True, exist_ok=True)
    rows = ["#timestamp [ns],filename"]
    for img, t in zip(images, stamps_ns, strict=True):
        if img is not None:
            cv2.imwrite(str(folder / "frames" / f"{t}.png"), img)
        rows.append(f"{t},{t}.png ")
    (folder / "timestamps.csv").write_text("\n".join(rows) + "\n")


def sequence_yaml(cams: dict, T_body_cam: dict, target: dict | None) -> dict:
    entries = {}
    for name, cam in cams.items():
        e = cam.to_kalibr()
        e["rostopic"] = f"/{name}/image_raw"
        e["T_body_cam"] = np.asarray(T_body_cam[name]).tolist()
        entries[name] = e
    return {"generator": {"name": "tests"}, "conventions": {}, "imus": {}, "gnss": {},
            "cameras": entries, "target": target}


def write_sequence(root: Path, scene, names=("rgbL", "rgbR"), *, with_target: bool = True,
                   t0_ns: int = 1_000_000_000, dt_ns: int = 50_000_000) -> Path:
    """``scene`` from :func:`_scenes.stereo_scene`; returns the sequence folder."""
    target, cams, T10, _poses, (imgs_l, imgs_r), _obs = scene
    root.mkdir(parents=True, exist_ok=True)
    stamps = [t0_ns + i * dt_ns for i in range(len(imgs_l))]
    write_camera_folder(root / names[0], imgs_l, stamps)
    write_camera_folder(root / names[1], imgs_r, stamps)
    doc = sequence_yaml({names[0]: cams[0], names[1]: cams[1]},
                        {names[0]: np.eye(4), names[1]: np.linalg.inv(T10)},
                        target.to_kalibr() if with_target else None)
    (root / "sequence.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return root


def write_dvs_folder(folder: Path, windows: list, events: list) -> None:
    """An IBISCape DVS folder: ``timestamps.csv`` (start, end, file) and ``events/<ns>.npz``."""
    (folder / "events").mkdir(parents=True, exist_ok=True)
    rows = ["#timestamp_start [ns],timestamp_end [ns],filename"]
    for (a, b), ev in zip(windows, events, strict=True):
        np.savez(folder / "events" / f"{b}.npz", t=np.asarray(ev.t_ns), x=np.asarray(ev.x),
                 y=np.asarray(ev.y), p=np.asarray(ev.p))
        rows.append(f"{a},{b},{b}.npz ")
    (folder / "timestamps.csv").write_text("\n".join(rows) + "\n")
