"""The ``ibiscape-eval`` command: a click group whose subcommands are imported on first use,
so that ``ibiscape-eval --help`` and ``ibiscape-eval ate`` start without loading the heavy stack."""

from __future__ import annotations

import importlib
from typing import Any

import click

# name -> (module in ibiscape_eval.cli, attribute, one-line help shown by --help)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "ate": (
        "ate",
        "ate",
        "Absolute trajectory error after alignment (translation m, rotation deg).",
    ),
    "rpe": (
        "ate",
        "rpe",
        "Relative pose error over a delta in frames, seconds, metres or degrees.",
    ),
    "drift": ("ate", "drift", "KITTI-style drift over segment lengths, in % and deg/m."),
    "compare": (
        "compare",
        "compare",
        "ATE and RPE of several estimates against one reference (REF first), saved results.",
    ),
    "convert": (
        "convert",
        "convert",
        "Convert a trajectory between formats (TUM, KITTI, EuRoC, ...).",
    ),
    "allan": ("allan", "allan", "IMU noise densities and random walks from the Allan deviation."),
    "hotpix": (
        "hotpix",
        "hotpix",
        "Detect and remove DVS hot pixels (top-N and n-sigma criteria).",
    ),
    "events": ("events", "events", "Event-camera utilities: accumulation frames, time surfaces."),
    "sim": ("sim", "sim", "Generate a synthetic IBISCape-layout sequence with exact ground truth."),
    "report": ("report", "report", "Evaluate a folder of runs: paper-style table, figures, HTML."),
    "calib": ("calib", "calib", "Camera calibration (checkerboard/AprilGrid, mono/stereo, RGB/DVS)."),
    "vio": ("vio", "vio", "Stereo visual-inertial odometry baseline (OpenCV + GTSAM) on a sequence."),
    "benchmark": (
        "benchmark",
        "benchmark",
        "The whole paper on generated data: suite, calibrations, IMU noise, hot pixels, VIO, report.",
    ),
}

# "<command> <word>" pairs that run another command (``sim suite`` beside ``sim [options]``)
SUBCOMMANDS: dict[tuple[str, str], tuple[str, str, str]] = {
    ("sim", "suite"): (
        "sim",
        "sim_suite",
        "Generate the paper's 34-sequence table as batch jobs (--scale for quick runs).",
    ),
}


class LazyGroup(click.Group):
    """Import a subcommand's module only when that subcommand runs (or its help is asked for)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module, attr, _ = COMMANDS[cmd_name]
        mod = importlib.import_module(f"{__package__}.{module}")
        cmd: click.Command = getattr(mod, attr)
        return cmd

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        if len(args) >= 2 and (args[0], args[1]) in SUBCOMMANDS:
            module, attr, _ = SUBCOMMANDS[(args[0], args[1])]
            mod = importlib.import_module(f"{__package__}.{module}")
            return f"{args[0]} {args[1]}", getattr(mod, attr), args[2:]
        return super().resolve_command(ctx, args)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, COMMANDS[name][2]) for name in self.list_commands(ctx)]
        rows += [(" ".join(k), v[2]) for k, v in SUBCOMMANDS.items()]
        rows.sort()
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="ibiscape-eval")
def cli() -> None:
    """Evaluate and calibrate multi-modal SLAM systems.

    \b
    Examples:
      ibiscape-eval ate est.txt gt.txt --align se3
      ibiscape-eval rpe est.txt gt.txt --delta 1 --delta-unit metres
      ibiscape-eval drift est.txt gt.txt --lengths-pct 10,20,30,40,50
    """


def main(argv: list[str] | None = None) -> Any:
    """Console-script entry point."""
    return cli.main(args=argv, prog_name="ibiscape-eval")


if __name__ == "__main__":  # pragma: no cover
    main()
