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
