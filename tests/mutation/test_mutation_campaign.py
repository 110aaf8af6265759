"""The mutation campaign as a test: N_MUTANTS seeded mutants over every input family, each run
in-process through the command line and held to the bad-input contract (see campaign.py)."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from campaign import N_MUTANTS, plan, prepare, run_one
from families import FAMILIES
from mutators import BYTE_MUTATORS, PATH_MUTATORS
from shared_data import require_shared


def test_plan_covers_every_family_and_mutator() -> None:
    p = plan()
    assert len(p) >= N_MUTANTS - len(FAMILIES)
    assert {f for f, _, _ in p} == set(FAMILIES)
    used = {m for _, m, _ in p}
    assert set(PATH_MUTATORS) <= used
    assert set(BYTE_MUTATORS) <= used


@pytest.fixture(scope="session")
def campaign_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The campaign's folder: each family's seed is built once there (``campaign.prepare``) and
    copied by every mutant and by the unmutated run below (session-scoped: the families' tests
    run between other files' tests on a worker, and a module fixture would be built again)."""
    return tmp_path_factory.mktemp("mutation")


@pytest.mark.parametrize("family", list(FAMILIES))
def test_every_mutant_keeps_the_contract(campaign_root: Path, family: str) -> None:
    """The campaign's mutants of one family (the families spread over the xdist workers:
    tests/conftest.py SPLIT; together they are ``campaign``'s N_MUTANTS)."""
    require_shared("trajectories")  # the EuRoC / ROS 2 bag seeds: fails under CI when missing
    seeds, work = campaign_root / "seeds", campaign_root / "work"
    work.mkdir(parents=True, exist_ok=True)
    mine = [(m, i) for f, m, i in plan() if f == family]
    assert mine, family
    broke = [o for o in (run_one(seeds, work, family, m, i) for m, i in mine) if o.problem]
    assert not broke, f"{len(broke)} of {len(mine)} mutants of {family} broke the contract:\n" + "\n".join(
        map(str, broke[:20]))


def test_every_seed_passes_unmutated(campaign_root: Path, tmp_path: Path) -> None:
    """The campaign is only meaningful if each family's seed is accepted as it is."""
    require_shared("trajectories")  # fails under CI when missing
    from click.testing import CliRunner

    from ibiscape_eval.cli.main import cli

    for name, fam in FAMILIES.items():
        seed = prepare(campaign_root / "seeds", name)  # the campaign's seed, as each mutant copies it
        folder = tmp_path / name
        shutil.copytree(seed.parent, folder, symlinks=True)
        inp = folder / seed.name
        out = folder / "out"
        out.mkdir()
        res = CliRunner().invoke(cli, fam.argv(inp, out))
        assert res.exit_code == 0, f"{name}: {res.stderr}"
