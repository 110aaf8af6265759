"""``ibiscape-eval allan``: IMU noise densities and random walks from the Allan deviation."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import click

from ibiscape_eval.imu.gaps import MAX_MISSING_FRACTION
from ibiscape_eval.io.imu import FORMATS as IMU_FORMATS

from ._common import echo_json, fail, info, user_errors
from .progress import progress_bar

_GYRO_U = ("rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)", "rad/s")
_ACCEL_U = ("m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)", "m/s^2")


def _range(text: str | None, option: str) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        fail(f"{option}: expected two taus in seconds, e.g. 0.02,1 ; got {text!r}")
        raise  # pragma: no cover
    if not (0 < lo < hi and math.isfinite(hi)):
        fail(f"{option}: expected 0 < lo < hi, got {text!r}")
    return lo, hi


def _pair(text: str | None, option: str) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        g, a = (float(v) for v in text.split(","))
    except ValueError:
        fail(f"{option}: expected two numbers GYRO,ACCEL, e.g. 2e-5,3e-3 ; got {text!r}")
        raise  # pragma: no cover
    if not (g > 0 and a > 0 and math.isfinite(g) and math.isfinite(a)):
        fail(f"{option}: expected two positive numbers, got {text!r}")
    return g, a


def _fmt(v: float, u: float) -> str:
    if not math.isfinite(v):
        return "n/a"
    return f"{v:.4g} ± {u:.2g}"


@click.command(
    "allan",
    epilog="""\b
Examples:
  ibiscape-eval allan imu.csv
  ibiscape-eval allan imu.csv --yaml imu.yaml --plot adev.png --csv curves.csv
  ibiscape-eval allan still.npy --rate-hz 200 --json
  ibiscape-eval allan log.csv --columns t_s=time,w_x=gx,w_y=gy,w_z=gz,a_x=ax,a_y=ay,a_z=az \\
      --units gyro=deg/s,accel=g
  ibiscape-eval allan recording.bag --rostopic /imu0 --yaml imu.yaml
  ibiscape-eval allan accel_first.csv --columns t,ax,ay,az,gx,gy,gz
  ibiscape-eval allan drive_imu.csv --force     (a record that is not still, analysed anyway)
""",
)
@click.argument("imu", type=click.Path(dir_okay=True, path_type=str))
@click.option("--format", "fmt", type=click.Choice(IMU_FORMATS),
              help="Input format (default: from the file name). 'ibiscape' is the EuRoC csv in "
              "CARLA's left-handed frame, converted to right-handed (w_x, w_z, a_y negated); "
              "chosen by itself for <seq>/other_sensors/imu*.csv next to <seq>/vehicle_gt/.")
@click.option("--columns", help="Column mapping when the header names do not say (they are "
              "recognised by themselves: ax/acc_x/a_RS_S_x..., gx/gyro_x/w_RS_S_x/"
              "field.angular_velocity.x...): t=0 (stamp unit from the header or the sample "
              "interval; t_s, t_ms, t_us, t_ns state it), w_x..a_z = 0-based index or header name; "
              "or the file's columns in order, e.g. t,ax,ay,az,gx,gy,gz (_ skips one).")
@click.option("--units", help="Units of the file, e.g. gyro=deg/s,accel=g (default rad/s, m/s^2).")
@click.option("--rostopic", help="sensor_msgs/Imu topic in a bag (also written to --yaml).")
@click.option("--rate-hz", type=float, help="Sample rate for files without timestamps (.npy (N, 6)).")
@click.option("--allow-gaps", is_flag=True, help="Analyse records with gaps above the threshold.")
@click.option("--max-missing", type=float, default=MAX_MISSING_FRACTION, show_default=True,
              help="Largest fraction of missing samples (gaps) accepted without --allow-gaps.")
@click.option("--points-per-decade", type=int, default=10, show_default=True,
              help="Density of the log-spaced taus.")
@click.option("--white-range", help="Tau range (s) of the slope -1/2 fit, e.g. 0.02,1 (default: auto).")
@click.option("--walk-range", help="Tau range (s) of the slope +1/2 fit, e.g. 1000,6000 (default: auto).")
@click.option("--yaml", "yaml_path", type=click.Path(dir_okay=False), help="Write a Kalibr imu.yaml.")
@click.option("--random-walk-fallback", "rw_fallback",
              help="GYRO,ACCEL random walks (rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)) written to --yaml "
              "when the record is too short to determine them (recorded in a comment).")
@click.option("--inflate", type=float, default=1.0, show_default=True,
              help="Multiply every --yaml value by this factor (recorded in a comment).")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), help="Write the curves (one row per tau).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Write a log-log figure (png/pdf/svg).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the table.")
@click.option("--force", is_flag=True, help="Analyse a record that the stillness test refuses "
              "(moving IMU); every output then says so.")
@user_errors
def allan(imu: str, fmt: str | None, columns: str | None, units: str | None, rostopic: str | None,
          rate_hz: float | None, allow_gaps: bool, max_missing: float, points_per_decade: int,
          white_range: str | None, walk_range: str | None, yaml_path: str | None,
          rw_fallback: str | None, inflate: float, csv_path: str | None, plot_path: str | None, as_json: bool,
          force: bool) -> None:
    """IMU noise from the overlapping Allan deviation of a still recording.

    Prints the white-noise density N (slope -1/2 read at 1 s), the rate random walk K (slope +1/2
    read at 3 s) and the bias instability B (minimum / 0.664) of the three gyro and three
    accelerometer axes, with one-sigma uncertainties, as continuous-time densities (Kalibr's
    convention) and as per-sample sigmas at the file's rate.

    The record must be of an IMU at rest: the window means of every axis may move only as much
    as noise explains, the gyro mean stays below 0.2 rad/s, the accelerometer reads g (exit 2
    otherwise, or --force and a warning in every output).
    """
    from ibiscape_eval.imu import allan_deviation, fit_noise_model

    fallback = _pair(rw_fallback, "--random-walk-fallback")
    if not (math.isfinite(inflate) and inflate > 0):
        fail(f"--inflate must be a positive number, got {inflate!r}")
    wr = _range(white_range, "--white-range")
    kr = _range(walk_range, "--walk-range")
    if points_per_decade < 1:
        fail("--points-per-decade must be at least 1")
    rec, tm, still = _read_still(imu, fmt, columns, units, rostopic, rate_hz, max_missing,
                                 allow_gaps, force)
    warning = still.warning
    with progress_bar(rec.n_samples * rec.n_columns, "allan", unit="sample") as bar:
        res = allan_deviation(rec, rec.rate_hz, points_per_decade=points_per_decade,
                              names=rec.names, progress=bar.update)
    model = fit_noise_model(res, white_range_s=wr, walk_range_s=kr)

    _write_curves(res, model, csv_path, plot_path, warning)  # always meaningful: first
    kalibr: dict[str, Any] = {
        **model.kalibr(gyro=rec.names[:3], accel=rec.names[3:]),
        "rostopic": rostopic or rec.rostopic or "/imu0",
        "update_rate": rec.rate_hz,
    }
    for a in model.axes:
        for note in a.notes:
            info(f"note: {a.name}: {note}")

    if as_json:
        echo_json(_json_doc(imu, rec, tm, res, model, still, kalibr))
    else:
        if warning:
            click.echo(warning)
        _table(model, rec.rate_hz)

    if yaml_path:
        _write_yaml(yaml_path, imu, rec, model, fallback, inflate, warning, str(kalibr["rostopic"]))


def _read_still(imu: str, fmt: str | None, columns: str | None, units: str | None,
                rostopic: str | None, rate_hz: float | None, max_missing: float,
                allow_gaps: bool, force: bool) -> tuple[Any, Any, Any]:
    """Read the record, say its timing and notes, refuse gaps and motion (unless allowed)."""
    from ibiscape_eval.imu import check_gaps, check_still
    from ibiscape_eval.io.imu import read_imu

    rec = read_imu(imu, fmt=fmt, columns=columns, units=units, rostopic=rostopic, rate_hz=rate_hz)
    tm = rec.timing
    if tm.has_stamps:
        info(f"{imu}: {rec.n_samples} samples at {rec.rate_hz:.6g} Hz (median interval), "
             f"{rec.n_samples / rec.rate_hz / 3600:.3g} h; {tm.n_gaps} gap(s), "
             f"{100 * tm.missing_fraction:.3g} % missing, largest interval {tm.largest_gap_s:.4g} s, "
             f"jitter {tm.jitter_s * 1e6:.3g} us")
    for note in rec.notes:
        info(f"note: {note}")
    check_gaps(tm, imu, max_missing=max_missing, allow_gaps=allow_gaps)
    still = check_still(rec, rec.rate_hz, path=imu, force=force)
    for note in still.notes:
        info(f"note: {note}")
    if still.warning:
        info(still.warning)
    return rec, tm, still


def _write_curves(res: Any, model: Any, csv_path: str | None, plot_path: str | None,
                  warning: str | None) -> None:
    if csv_path:
        from ibiscape_eval.io.atomic import atomic_write

        frame = res.to_frame()
        if warning:
            frame["forced_not_still"] = True
        with atomic_write(csv_path) as fh:
            frame.to_csv(fh, index=False, float_format="%.17g", lineterminator="\n")
    if plot_path:
        from ibiscape_eval.report.plots import plot_allan

        plot_allan(plot_path, res, model, title="overlapping Allan deviation" + (
            "\nNOT STILL: analysed with --force, the curves include the motion" if warning else ""))


def _json_doc(imu: str, rec: Any, tm: Any, res: Any, model: Any, still: Any,
              kalibr: dict[str, Any]) -> dict[str, Any]:
    warning = still.warning
    return {
        "file": imu,
        "rate_hz": rec.rate_hz,
        "n_samples": rec.n_samples,
        "duration_s": res.duration_s,
        "timing": dataclasses.asdict(tm),
        "forced_not_still": bool(warning),
        "warning": warning,
        "stillness": still.to_dict(),
        "layout": rec.layout.to_dict() if rec.layout is not None else None,
        "notes": list(rec.notes),
        "n_taus": int(res.taus_s.size),
        "confidence": res.ci,
        "edf_model": "white FM (NIST SP 1065 Table 5), chi-squared bounds",
        "axes": {a.name: {**{k: getattr(a, k) for k in a.__dataclass_fields__ if k != "name"},
                          "notes": list(a.notes)} for a in model.axes},
        "kalibr": kalibr,
    }


def _write_yaml(yaml_path: str, imu: str, rec: Any, model: Any, fallback: Any, inflate: float,
                warning: str | None, rostopic: str) -> None:
    """The Kalibr imu.yaml: the largest value over the three axes, with the per-sample sigmas."""
    from ibiscape_eval.core.errors import IbiscapeError
    from ibiscape_eval.core.kalibr import ImuNoise
    from ibiscape_eval.io.kalibr import write_imu_noise

    try:
        vals, notes = model.kalibr_values(random_walk_fallback=fallback, inflate=inflate,
                                          gyro=rec.names[:3], accel=rec.names[3:])
    except IbiscapeError as e:
        raise IbiscapeError(f"{yaml_path} not written: {e.template}", hint=e.hint) from None
    rate = rec.rate_hz
    root = math.sqrt(rate)
    bad = [k for k, v in vals.items() if not (math.isfinite(v) and v > 0)]
    if bad:
        raise IbiscapeError(f"cannot write {yaml_path}: {', '.join(bad)} not determined (NaN); "
                            "record longer or give the fit ranges")
    noise = ImuNoise(accel_noise_density_m_s2_sqrt_hz=vals["accelerometer_noise_density"],
                     accel_random_walk_m_s3_sqrt_hz=vals["accelerometer_random_walk"],
                     gyro_noise_density_rad_s_sqrt_hz=vals["gyroscope_noise_density"],
                     gyro_random_walk_rad_s2_sqrt_hz=vals["gyroscope_random_walk"],
                     update_rate_hz=rate, rostopic=rostopic)
    write_imu_noise(
        yaml_path, noise,
        comments=[
            f"ibiscape-eval allan {imu}: largest value over the three axes, continuous time",
            *([warning] if warning else []),
            *notes,
            f"per-sample (discrete) sigmas at {rate:.6g} Hz:",
            f"  gyroscope_noise_sigma: {vals['gyroscope_noise_density'] * root:.6g} rad/s",
            f"  gyroscope_bias_step_sigma: {vals['gyroscope_random_walk'] / root:.6g} rad/s",
            f"  accelerometer_noise_sigma: {vals['accelerometer_noise_density'] * root:.6g} "
            "m/s^2",
            f"  accelerometer_bias_step_sigma: {vals['accelerometer_random_walk'] / root:.6g} "
            "m/s^2",
        ],
    )


def _table(model: Any, rate_hz: float) -> None:
    head = (f"{'axis':<5} {'N (white noise density)':>26} {'K (random walk)':>24} "
            f"{'B (bias instability)':>24} {'sigma/sample':>13} {'units N, K, B'}")
    click.echo(head)
    for i, a in enumerate(model.axes):
        u = _GYRO_U if i < 3 else _ACCEL_U
        click.echo(f"{a.name:<5} {_fmt(a.noise_density, a.noise_density_unc):>26} "
                   f"{_fmt(a.random_walk, a.random_walk_unc):>24} "
                   f"{_fmt(a.bias_instability, a.bias_instability_unc):>24} "
                   f"{a.discrete_sigma:>13.4g} {u[0]}, {u[1]}, {u[2]}")
    click.echo(f"(uncertainties one sigma; sigma/sample = N*sqrt({rate_hz:.6g} Hz))")


