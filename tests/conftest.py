"""Suite-wide test settings, and how the suite is spread over pytest-xdist workers.

``make test`` runs ``pytest -n auto --dist loadfile --no-loadscope-reorder`` (see the Makefile).
Work that is built once is built on one worker:

- the tests of a file run on one worker (``--dist loadfile``): module-scoped fixtures (``bench``,
  ``scheduler``...) and the files' ``lru_cache`` helpers are computed once, as in a serial run;
- the files that use a session-scoped fixture of a folder's conftest (``tests/vio``: the
  generated SVI drive and its rendered street; ``tests/sim``: the town renderer) run on one
  worker, one after the other (``pytest_xdist_make_scheduler`` below): the fixture is built once;
- the tests of the ``SPLIT`` files share nothing that costs more than a second to rebuild (each
  its own data or subprocess; the camera-IMU coverage tests share 0.2 s scenes), and each is
  slow: they spread over the workers one by one.

The groups start longest first (the seconds measured in the last run, kept in pytest's cache, or
``SLOW_FIRST`` on a fresh clone) so that no long group starts last and holds the run up. Without
xdist (``pytest tests/x.py``) nothing here changes the order.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings
from shared_data import require_shared  # (tests/ is on sys.path: rootdir conftest)

# Property tests must not fail on a slow or busy CI machine: no per-example deadline and no
# "too slow" health check (generating file fixtures is legitimately slow).
settings.register_profile("ibiscape", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ibiscape")

TESTS = Path(__file__).resolve().parent
#: Files whose tests share nothing built once (each test its own data or subprocess).
SPLIT = ("tests/examples/test_examples.py", "tests/test_readme.py",
         "tests/mutation/test_mutation_campaign.py", "tests/calib/test_calib_rendered.py",
         "tests/calib/test_imu_camera_coverage.py")
#: The longest groups of a full run (seconds on the quiet machine), for a clone without a cache.
SLOW_FIRST = {
    "tests/benchmark/test_benchmark.py": 110.0,
    "tests/calib/test_calib_dvs_cli.py": 75.0,
    "tests/calib/test_imu_camera_coverage.py::test_bias_random_walk_between_knots_is_covered": 25.0,
    "tests/calib/test_imu_camera_coverage.py::test_misweighted_noise_is_measured": 23.0,
    "tests/calib/test_imu_camera_coverage.py::test_intrinsics_error_is_propagated": 21.0,
    "tests/calib/test_calib_command.py": 50.0,
    "tests/calib/test_imu_camera_dvs.py": 50.0,
    "tests/calib/test_imu_camera_sequence.py": 45.0,
    "tests/test_readme.py::test_readme_commands_run[calib]": 45.0,
    "tests/test_readme.py::test_readme_commands_run[setups]": 40.0,
    "tests/calib/test_calib_rendered.py::test_calib_on_simulator_renders_meets_the_issue_targets[aprilgrid]": 25.0,
    "tests/examples/test_examples.py::test_example_runs[calibrate_imu_camera.py]": 32.0,
    "tests/calib/test_imu_camera.py": 25.0,
    "tests/calib/test_calib_rendered.py::test_calib_on_simulator_renders_meets_the_issue_targets[checkerboard]": 20.0,
    "tests/test_readme.py::test_readme_commands_run[sim]": 20.0,
    "tests/test_readme.py::test_readme_commands_run[vio]": 15.0,
    "tests/test_readme.py::test_readme_commands_run[allan]": 15.0,
    "tests/examples/test_examples.py::test_example_runs[calibrate_cameras.py]": 14.0,
}
CACHE_KEY = "ibiscape/xdist_group_seconds"
_SESSION_FIXTURE = re.compile(r'@pytest\.fixture\(scope="session"[^)]*\)\s*\ndef (\w+)')


@functools.cache
def shared_fixture_groups() -> dict[str, str]:
    """``{test file: conftest folder}`` for the files that use a session-scoped fixture of a
    conftest below ``tests/`` (read from the sources: the controller collects no tests)."""
    root = TESTS.parent
    groups = {}
    for conftest in TESTS.glob("*/**/conftest.py"):
        names = _SESSION_FIXTURE.findall(conftest.read_text())
        if not names:
            continue
        uses = re.compile(r"\b(" + "|".join(names) + r")\b")
        folder = conftest.parent.relative_to(root).as_posix()
        for f in conftest.parent.rglob("test_*.py"):
            if uses.search(f.read_text()):
                groups[f.relative_to(root).as_posix()] = folder
    return groups


def group_of(nodeid: str) -> str:
    """The work unit of a test: its file, its conftest folder (shared session fixture), or
    itself (``SPLIT``)."""
    path = nodeid.split("::", 1)[0]
    if path in SPLIT:
        return nodeid
    return shared_fixture_groups().get(path, path)


@pytest.hookimpl(optionalhook=True, tryfirst=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``--dist loadfile`` with the groups of ``group_of`` as its work units."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class GroupScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return group_of(nodeid)

        def _reschedule(self, node) -> None:
            """The next group once the worker is on its last test (xdist's own waits for two:
            a worker busy with a long one-test group would queue two more groups behind it
            while the other worker runs dry)."""
            if node.shutting_down:
                return
            if not self.workqueue:
                node.shutdown()
                return
            if self._pending_of(self.assigned_work[node]) <= 1:
                self._assign_work_unit(node)

    return GroupScheduling(config, log)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On an xdist worker: the groups longest first (every worker sorts the same collection by
    the same cache, as xdist requires), then in collection order."""
    if not hasattr(config, "workerinput"):
        return
    cache = getattr(config, "cache", None)
    seconds = {**SLOW_FIRST, **(cache.get(CACHE_KEY, {}) if cache else {})}
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        first.setdefault(group_of(item.nodeid), i)
    items.sort(key=lambda it: (-seconds.get(group_of(it.nodeid), 0.0), first[group_of(it.nodeid)]))


_seconds: dict[str, float] = {}


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _seconds[report.nodeid] = _seconds.get(report.nodeid, 0.0) + report.duration


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Keep each group's measured seconds (controller or serial run) for the next run's order."""
    config = session.config
    cache = getattr(config, "cache", None)
    if hasattr(config, "workerinput") or cache is None or not _seconds:
        return
    per_group: dict[str, float] = {}
    for nodeid, s in _seconds.items():
        per_group[group_of(nodeid)] = per_group.get(group_of(nodeid), 0.0) + s
    kept = cache.get(CACHE_KEY, {})
    kept.update({g: round(s, 2) for g, s in per_group.items() if s >= 1.0})
    cache.set(CACHE_KEY, kept)


@pytest.fixture
def shared_trajectories():
    """``../shared/data/trajectories``: skips when missing, fails under CI=true."""
    return require_shared("trajectories")


@pytest.fixture(scope="module")
def scheduler():
    """The address of a real Dask LocalCluster on loopback (2 worker processes)."""
    import distributed  # a dependency: missing it is a failure, not a skip

    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()
