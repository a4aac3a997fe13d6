"""Shared test configuration: hypothesis profiles (the CI profile is derandomized)."""

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "default", deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)
settings.register_profile("thorough", parent=settings.get_profile("default"), max_examples=2000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def pytest_configure(config):
    """Generated steppers go to a cache private to the test runs (under .pytest_cache),
    never to the user's cache, unless DYNAMICS_CACHE_DIR is set already."""
    if not os.environ.get("DYNAMICS_CACHE_DIR"):
        d = config.rootpath / ".pytest_cache" / "dynamics-cache"
        d.mkdir(mode=0o700, parents=True, exist_ok=True)
        os.chmod(d, 0o700)
        os.environ["DYNAMICS_CACHE_DIR"] = str(d)
