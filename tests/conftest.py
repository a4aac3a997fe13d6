"""Shared test configuration: hypothesis profiles (the CI profile is derandomized)."""

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "default", deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)
settings.register_profile("thorough", parent=settings.get_profile("default"), max_examples=2000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


#: The test files that take longest from cold caches (most of it compiling steppers; sums
#: of ``pytest --durations=0`` on 2 cores, 56-102 s each), longest first.  They are handed
#: to the workers first (``--no-loadscope-reorder`` in ``addopts`` keeps this order; by
#: default pytest-xdist hands out the files with the most tests first, which left the
#: longest file, with 3 tests, to one worker at the end while the other idled).
LONGEST_FIRST = (
    "tests/test_figures.py",
    "tests/dynamics/test_dyn_contact.py",
    "tests/dynamics/test_dyn_effects.py",
    "tests/dynamics/test_dyn_driver.py",
    "tests/strip/test_strip_trace.py",
    "tests/dynamics/test_dynamics_implicit_stiffness.py",
    "tests/sweep/test_sweep_real.py",
    "tests/dynamics/test_dynamics_implicit.py",
)


def pytest_collection_modifyitems(session, config, items):
    """The files of :data:`LONGEST_FIRST` first, in its order; the others after them, in
    collection order (the tests of each file keep their order)."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))


def pytest_configure(config):
    """Generated steppers go to a cache private to the test runs (under .pytest_cache),
    never to the user's cache, unless DYNAMICS_CACHE_DIR is set already."""
    if not os.environ.get("DYNAMICS_CACHE_DIR"):
        d = config.rootpath / ".pytest_cache" / "dynamics-cache"
        d.mkdir(mode=0o700, parents=True, exist_ok=True)
        os.chmod(d, 0o700)
        os.environ["DYNAMICS_CACHE_DIR"] = str(d)
