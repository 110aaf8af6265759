"""``ibiscape-eval sim``: generate a synthetic IBISCape-layout sequence with exact ground truth."""

from __future__ import annotations

from typing import Any

import click

from ibiscape_eval.sim.config import KINDS as _KINDS
from ibiscape_eval.sim.config import SCENARIOS as _SCENARIOS
from ibiscape_eval.sim.config import SETUPS as _SETUPS
from ibiscape_eval.sim.config import TARGETS as _TARGETS
from ibiscape_eval.sim.config import WEATHERS as _WEATHERS

from ._common import echo_json, fail, user_errors


def _summary_text(s: Any, rendered: list[str]) -> str:
    w = s.weather_averages
    lines = [
        f"sequence   {s.path}",
        f"setup      {s.setup} / {s.kind} / {s.weather}"
        + ("" if s.scenario == "default" else f" / {s.scenario}") + f"   seed {s.seed}",
        f"length     {s.length_m:.2f} m",
        f"duration   {s.duration_s:.2f} s",
        f"frames     {s.frames} (camera)   gt {s.gt_samples}   imu {s.imu_samples}   "
        f"gnss {s.gnss_fixes}",
        f"speed      {s.mean_speed_m_s:.2f} m/s (mean)",
        f"excitation roll std {s.roll_std_deg:.3f} deg   pitch std {s.pitch_std_deg:.3f} deg",
    ]
    if w:
        lines.append(f"weather    fog {w['fog_density']:.0f} %   rain {w['precipitation']:.0f} %   "
                     f"wind {w['wind_intensity']:.0f} %   clouds {w['cloudiness']:.0f} %   "
                     f"sun altitude {w['sun_altitude_angle']:.0f} deg")
    if s.frames and rendered:
        lines.append(f"images     rendered: {', '.join(rendered)}")
    elif s.frames:
        lines.append("images     not rendered (--no-render)")
    return "\n".join(lines)


@click.command(
    "sim",
    epilog="""\b
Examples:
  ibiscape-eval sim --setup svi --kind calibration --duration-s 30 --seed 1 --out SVI_1_calib
  ibiscape-eval sim --setup esvi --kind slam --weather dynamic --out ESVI_2_town --json
  ibiscape-eval sim --setup svi --scenario accident --out SVI_accident
  ibiscape-eval sim --setup imu --duration-s 604800 --out IMU_168h   (168 h, streamed)
  ibiscape-eval sim --setup full --print-config > sim.yaml ; ibiscape-eval sim --config sim.yaml --out X
  ibiscape-eval sim --setup svi --kind calibration --resolution 256 --duration-s 10 --out SVI_small
  ibiscape-eval sim --setup rgbd --resolution 640x480 --export tum-rgbd --out RGBD_1_town
  ibiscape-eval sim suite --out suite/ --scale 0.05   (the paper's 34 sequences; see sim suite --help)
""",
)
@click.option("--setup", type=click.Choice(_SETUPS), help="Sensor setup (default svi).")
@click.option("--kind", type=click.Choice(_KINDS), help="calibration or slam (default slam; imu is "
              "always a still calibration).")
@click.option("--weather", type=click.Choice(_WEATHERS), help="Weather preset (default clear).")
@click.option("--scenario", type=click.Choice(_SCENARIOS),
              help="accident: SVI SLAM run ending in a hard stop behind a car (6.13 s).")
@click.option("--duration-s", type=float, help="Sequence duration [s] (default: the preset's).")
@click.option("--seed", type=int, help="Seed of every random process (default 0).")
@click.option("--target", type=click.Choice(_TARGETS),
              help="Calibration target the vehicle drives toward.")
@click.option("--out", "out", type=click.Path(file_okay=False),
              help="Sequence folder (default ./<Setup>_1_<map>); must be absent or empty.")
@click.option("--config", "config_path", type=click.Path(),
              help="YAML config (see --print-config); command-line options win.")
@click.option("--ideal", is_flag=True, default=None, help="Turn every sensor noise off (IMU, GNSS).")
@click.option("--render/--no-render", "render", default=True, show_default=True,
              help="Render every camera (RGB, depth, segmentation, DVS events). --no-render "
              "writes ground truth, IMU, GNSS, controls and weather only (fast).")
@click.option("--resolution", metavar="N|WxH",
              help="Resize every camera to N x N or W x H pixels, keeping its field of view.")
@click.option("--export", "export_fmt", type=click.Choice(("euroc", "tum-rgbd", "rosbag")),
              help="Also export the sequence for other tools (into --export-out).")
@click.option("--export-out", type=click.Path(),
              help="Export folder (euroc, tum-rgbd) or .bag file (rosbag); default <out>_<format>.")
@click.option("--overwrite", is_flag=True, help="Replace a non-empty --out folder.")
@click.option("--print-config", is_flag=True,
              help="Print the full configuration (commented YAML) and exit.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as one JSON document.")
@user_errors
def sim(setup: str | None, kind: str | None, weather: str | None, scenario: str | None,
        duration_s: float | None, seed: int | None, target: str | None, out: str | None,
        config_path: str | None, ideal: bool | None, render: bool, resolution: str | None,
        export_fmt: str | None, export_out: str | None, overwrite: bool,
        print_config: bool, as_json: bool) -> None:
    """Generate a synthetic sequence in the IBISCape layout (CPU only, seeded, exact truth).

    Writes vehicle_gt/groundtruth_sync.csv (CARLA frame, like IBISCape), other_sensors/imu*.csv
    and gnss.csv, the vehicle controls, weather.csv per camera frame and sequence.yaml (cameras,
    IMUs, target, GNSS reference, conventions).  The folder appears only when complete.  A summary
    (length, duration, frames, speed, roll/pitch excitation, weather) is printed at the end.
    """
    from ibiscape_eval.sim.config import (
        dump_config,
        load_config,
        parse_resolution,
        preset,
        with_resolution,
    )
    from ibiscape_eval.sim.generator import generate, sequence_name

    overrides: dict[str, Any] = {"duration_s": duration_s, "seed": seed, "target": target,
                                 "ideal": ideal}
    overrides = {k: v for k, v in overrides.items() if v is not None}
    if config_path is not None:
        cfg = load_config(config_path, setup=setup, kind=kind, weather=weather, scenario=scenario,
                          **overrides)
    else:
        if scenario == "accident" and setup is None:
            setup = "svi"
        cfg = preset(setup or "svi", kind or "slam", weather or "clear",
                     scenario=scenario or "default", **overrides)
    if resolution is not None:
        cfg = with_resolution(cfg, *parse_resolution(resolution))
    if print_config:
        click.echo(dump_config(cfg), nl=False)
        return
    if export_fmt is not None and not (render and cfg.cameras):
        fail(f"--export {export_fmt} needs rendered images; drop --no-render (setup {cfg.setup} "
             f"has {len(cfg.cameras)} cameras)")
    if export_fmt is not None:
        from ibiscape_eval.sim.render.sequence import export_problem

        problem = export_problem(cfg, export_fmt)
        if problem is not None:
            fail(problem)
    out_dir = out if out is not None else sequence_name(cfg)

    from .progress import fraction_callback, progress_bar

    do_render = render and bool(cfg.cameras)
    with progress_bar(1000, "sim", unit="‰", unit_scale=False, delay_s=0.0) as bar:
        summary = generate(cfg, out_dir, overwrite=overwrite,
                           progress=fraction_callback(bar, "sim"), render=do_render)
    rendered = [c.name for c in cfg.cameras] if do_render else []
    exported = None
    if export_fmt is not None:
        from pathlib import Path

        from ibiscape_eval.sim.export import export_sequence

        dst = export_out or str(Path(out_dir).with_name(
            Path(out_dir).name + "_" + export_fmt + (".bag" if export_fmt == "rosbag" else "")))
        with progress_bar(1000, "export", unit="‰", unit_scale=False, delay_s=0.0) as ebar:
            exported = export_sequence(out_dir, export_fmt, dst, overwrite=overwrite,
                                       progress=fraction_callback(ebar, "export"))
    if as_json:
        doc = summary.to_dict()
        doc["rendered_cameras"] = rendered
        if exported is not None:
            doc["export"] = exported.to_dict()
        echo_json(doc)
    else:
        click.echo(_summary_text(summary, rendered))
        if exported is not None:
            click.echo(f"export     {export_fmt}: {exported.path}")


@click.command(
    "sim suite",
    epilog="""\b
Examples:
  ibiscape-eval sim suite --out suite/ --scale 0.05           (quick: 3 s runs, 224 px, 8.4 h IMU)
  ibiscape-eval sim suite --out suite/ --scale 1              (the paper's sizes; hours of CPU)
  ibiscape-eval sim suite --out suite/ --only SVI_slam_dyn_1 --only SVI_calib_1 --scale 0.25
  ibiscape-eval sim suite --out suite/ --scheduler tcp://10.0.0.5:8786
""",
)
@click.option("--out", "out", type=click.Path(file_okay=False), default=None,
              help="(required) Suite folder: one sequence folder per entry and suite.json (the manifest).")
@click.option("--scale", type=float, default=1.0, show_default=True,
              help="In (0, 1]: durations x F (at least 3 s, calibration drives 12 s, still IMU 30 "
              "min), image sides 1024 x sqrt(F) (at least 128 px, calibration drives 320 px, "
              "AprilGrid drives 512 px).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Base seed (sequence i gets seed + i).")
@click.option("--render/--no-render", "render", default=True, show_default=True,
              help="Render the cameras; --no-render writes ground truth, IMU and GNSS only.")
@click.option("--only", multiple=True, metavar="NAME",
              help="Generate only this sequence (repeat); the manifest lists every entry.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the jobs on this Dask scheduler (tcp://host:port) instead of locally.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Local worker processes (default: the usable CPUs).")
@click.option("--list", "list_only", is_flag=True,
              help="Print the suite's entries (name, preset, duration, image side) and exit.")
@click.option("--json", "as_json", is_flag=True, help="Print the manifest as one JSON document.")
@user_errors
def sim_suite(out: str | None, scale: float, seed: int, render: bool, only: tuple[str, ...],
              scheduler: str | None, workers: int | None, list_only: bool, as_json: bool) -> None:
    """Generate the paper's sequence table (34 sequences: calibration and SLAM runs across setups
    and weathers) as batch jobs, named like the paper's (SVI_calib_1, ESVI_slam_dyn_2).

    Every sequence is one job: locally on a pool of processes, or on an existing Dask cluster
    with --scheduler.  Sequences already complete in OUT (same entry) are kept, so a re-run
    resumes; a sequence that fails is reported with its error and the others carry on.
    """
    from ibiscape_eval.batch import make_executor
    from ibiscape_eval.sim.suite import run_suite, suite_entries

    from ._common import info

    entries = suite_entries(scale, seed=seed)
    if list_only:
        if as_json:
            echo_json({"scale": scale, "sequences": [e.to_dict() for e in entries]})
            return
        for e in entries:
            click.echo(f"{e.name:<18} {e.setup:<5} {e.kind:<12} {e.weather:<9} "
                       f"{e.duration_s:>9g} s  {e.side_px or '-'!s:>5} px  "
                       f"{e.target or '':<12} seed {e.seed}")
        return
    if out is None:
        raise click.UsageError("Missing option '--out' (the suite folder).")
    executor = make_executor(scheduler=scheduler, workers=workers)
    n = len(only) if only else len(entries)
    info(f"{n} sequences at scale {scale:g}" + (f" on the Dask scheduler {scheduler}" if scheduler else ""))
    from .progress import BatchBar

    bar = BatchBar("sim suite", unit="seq", delay_s=0.0)
    try:
        res = run_suite(out, scale=scale, seed=seed, render=render, executor=executor, progress=bar,
                        only=list(only) or None)
    finally:
        bar.close()
        executor.close()
    for s in res.failed:
        info(f"warning: {s['name']} failed: {s['error']}")
    if as_json:
        echo_json(res.to_dict())
        return
    for s in res.sequences:
        summ = s.get("summary") or {}
        how = "kept" if s.get("reused") else f"{s.get('seconds', 0.0):.1f} s"
        what = (f"{summ.get('length_m', 0.0):8.1f} m  {summ.get('frames', 0):5d} frames"
                if s["status"] == "ok" else f"FAILED: {s['error']}")
        click.echo(f"{s['name']:<18} {s['status']:<6} {what}  ({how})")
    ok = res.summary["n_ok"]
    click.echo(f"{ok}/{len(res.sequences)} sequences in {out} (manifest {out}/suite.json)")
    if ok == 0:
        fail("every sequence failed; nothing usable was written")
