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


def _summary_text(s: Any) -> str:
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
    lines.append("images     not rendered (--no-render: rendering comes with a later release)")
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
@click.option("--no-render/--render", "no_render", default=True, show_default=True,
              help="Write ground truth, IMU, GNSS, controls and weather only. Rendering images "
              "and events is not available yet: --no-render is the only mode.")
@click.option("--overwrite", is_flag=True, help="Replace a non-empty --out folder.")
@click.option("--print-config", is_flag=True,
              help="Print the full configuration (commented YAML) and exit.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as one JSON document.")
@user_errors
def sim(setup: str | None, kind: str | None, weather: str | None, scenario: str | None,
        duration_s: float | None, seed: int | None, target: str | None, out: str | None,
        config_path: str | None, ideal: bool | None, no_render: bool, overwrite: bool,
        print_config: bool, as_json: bool) -> None:
    """Generate a synthetic sequence in the IBISCape layout (CPU only, seeded, exact truth).

    Writes vehicle_gt/groundtruth_sync.csv (CARLA frame, like IBISCape), other_sensors/imu*.csv
    and gnss.csv, the vehicle controls, weather.csv per camera frame and sequence.yaml (cameras,
    IMUs, target, GNSS reference, conventions).  The folder appears only when complete.  A summary
    (length, duration, frames, speed, roll/pitch excitation, weather) is printed at the end.
    """
    from ibiscape_eval.sim.config import dump_config, load_config, preset
    from ibiscape_eval.sim.generate import generate, sequence_name

    if not no_render:
        fail("--render: rendering images and events is not available yet; use --no-render")
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
    if print_config:
        click.echo(dump_config(cfg), nl=False)
        return
    out_dir = out if out is not None else sequence_name(cfg)

    from .progress import fraction_callback, progress_bar

    with progress_bar(1000, "sim", unit="‰", unit_scale=False, delay_s=0.0) as bar:
        summary = generate(cfg, out_dir, overwrite=overwrite,
                           progress=fraction_callback(bar, "sim"))
    if as_json:
        echo_json(summary.to_dict())
    else:
        click.echo(_summary_text(summary))
