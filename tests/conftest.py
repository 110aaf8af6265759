"""Suite-wide test settings."""

from hypothesis import HealthCheck, settings

# Property tests must not fail on a slow or busy CI machine: no per-example deadline and no
# "too slow" health check (generating file fixtures is legitimately slow).
settings.register_profile("ibiscape", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ibiscape")
