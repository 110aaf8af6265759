"""How the commands are built: options shared through ``cli/_common.py`` (no command module imports
another), typed option groups instead of ``**kwargs`` bags, and library errors whose
machine-readable remedy the command line prints as flags."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import click
import pytest

from ibiscape_eval.cli.main import COMMANDS, SUBCOMMANDS, cli
from ibiscape_eval.core.errors import DegenerateInputError, FormatError, IbiscapeError, Remedy

CLI_DIR = Path(__file__).resolve().parents[2] / "cli"
COMMAND_MODULES = {m for m, _, _ in (*COMMANDS.values(), *SUBCOMMANDS.values())}


def _imported_cli_modules(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1 and node.module:
                out.add(node.module.split(".")[0])
            elif node.level == 1:
                out.update(a.name for a in node.names)
            elif (node.module or "").startswith("ibiscape_eval.cli."):
                out.add(node.module.split(".")[2])
    return out


@pytest.mark.parametrize("module", sorted(COMMAND_MODULES | {"_common", "calib_imu"}))
def test_no_command_imports_another_command(module: str) -> None:
    others = _imported_cli_modules(CLI_DIR / f"{module}.py") & (COMMAND_MODULES - {module})
    assert not others, f"cli/{module}.py imports the command module(s) {others}"


def _commands() -> list[tuple[str, click.Command]]:
    ctx = click.Context(cli)
    out = []
    for name in COMMANDS:
        cmd = cli.get_command(ctx, name)
        assert cmd is not None
        subs = cmd.commands.values() if isinstance(cmd, click.Group) else [cmd]
        out += [(f"{name} {c.name}", c) for c in subs]
    return out


def test_no_command_takes_an_option_bag() -> None:
    bags = [name for name, cmd in _commands()
            if any(p.kind is p.VAR_KEYWORD
                   for p in inspect.signature(inspect.unwrap(cmd.callback)).parameters.values())]
    assert bags == []


def test_library_errors_speak_keywords_and_the_cli_flags() -> None:
    from ibiscape_eval.cli._common import cli_flag

    e = DegenerateInputError("collinear; use {0} or {1}",
                             hint=(Remedy("align", "yaw"), Remedy("align", "origin")))
    assert str(e) == 'collinear; use align="yaw" or align="origin"'
    assert e.render(cli_flag) == "collinear; use --align yaw or --align origin"
    f = FormatError("imu.csv", "{0} gaps; pass {1}", line=7,
                    hint=(Remedy("max_diff_s"), Remedy("allow_gaps", flag=True)))
    assert str(f) == "imu.csv:7: {0} gaps; pass allow_gaps=True".replace("{0}", "max_diff_s")
    assert f.render(cli_flag) == "imu.csv:7: --max-diff-s gaps; pass --allow-gaps"
    assert f.detail == "max_diff_s gaps; pass allow_gaps=True" and f.path == "imu.csv"
    # named differently on the command line, or with a placeholder
    assert cli_flag(Remedy("imu_yaml")) == "--imu imu.yaml"
    assert cli_flag(Remedy("sensor_size")) == "--sensor-size WxH"
    # braces that are not remedies are left alone; no hint: the message as given
    assert str(IbiscapeError("{x} and {0}", hint=(Remedy("a"),))) == "{x} and a"
    assert str(IbiscapeError("{0} as is")) == "{0} as is"


def test_a_hinted_library_error_reaches_stderr_as_flags(run_cli, tmp_path: Path) -> None:
    import numpy as np
    from _cli_data import assert_one_error_line, write_tum

    t = np.arange(50) * 0.1
    line = np.column_stack([t, 0 * t, 0 * t])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (50, 1))
    a = write_tum(tmp_path / "a.txt", t, line, quat)
    res = run_cli("ate", a, a, "--align", "se3")
    assert_one_error_line(res, "collinear", "use --align yaw or --align origin")
    assert 'align="' not in res.stderr
