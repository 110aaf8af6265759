"""Suite-wide test settings."""

from hypothesis import HealthCheck, settings

# Property tests must not fail on a slow or busy CI machine: no per-example deadline and no
# "too slow" health check (generating file fixtures is legitimately slow).
settings.register_profile("ibiscape", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ibiscape")


import pytest  # noqa: E402
from shared_data import require_shared  # noqa: E402  (tests/ is on sys.path: rootdir conftest)


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
