"""The compiled loop of the RATTLE stepper: frames recorded inside it, the multiplier
predictor of SHAKE, the kinetic energy."""

import numpy as np
from dyn_helpers import clamped

from dynamics import Clamp, Damping, Gravity, Ground, simulate
from dynamics.rod import kinetic_energy


def test_kinetic_energy_matches_numpy_to_round_off():
    rng = np.random.default_rng(0)
    for n in (1, 2, 3, 4, 5, 7, 101):
        m = rng.random(n) + 0.5
        v = rng.standard_normal((n, 2))
        ref = 0.5 * np.sum(m[:, None] * v * v)
        assert abs(kinetic_energy(m, v) - ref) <= 4e-16 * ref


def test_frames_are_the_states_of_shorter_runs(wavy_rod):
    """A frame recorded by the compiled loop is, bit for bit, the end state of a run
    stopped at that time (the loop runs step by step through the frame stops)."""
    # a rod pinned at one end swinging under gravity, damped (the effects of the clamped-rod
    # tests, whose stepper the suite compiles once for all)
    effects = lambda: clamped(Clamp(0, tuple(wavy_rod.x[0])), g=0.3, damping=0.05)  # noqa: E731
    long = simulate(wavy_rod, effects(), dt=2e-3, t_end=1.0, frames=11)
    short = simulate(wavy_rod, effects(), dt=2e-3, t_end=0.5, frames=2)
    np.testing.assert_array_equal(long.times, (np.arange(11) * 50) * 2e-3)
    assert np.array_equal(long.positions[5], short.positions[-1])
    assert np.array_equal(long.positions[0], wavy_rod.x)
    # the energies of a frame are those of its state
    assert long.energies["kinetic"][5] == short.energies["kinetic"][-1]
    ke = 0.5 * np.sum(wavy_rod.mass[:, None] * long.velocities**2)
    assert abs(long.energies["kinetic"][-1] - ke) <= 1e-15 * ke


def test_rest_appends_the_final_state_once(wavy_rod):
    """A run stopped at rest between frames ends with one frame at the stopping time."""
    from dynamics import RestCriterion

    # no gravity and the ground far below: the ground tests' compiled stepper
    r = simulate(wavy_rod, (Gravity(0.0), Ground(-100.0), Damping(2.0)), dt=2e-3, t_end=50.0,
                 frames=6, rest=RestCriterion(1e-10, 0.5))
    assert r.status == "at_rest"
    assert r.times[-1] == r.t_final and np.all(np.diff(r.times) > 0)
    assert r.energies["kinetic"][-1] < 1e-10
    assert np.array_equal(r.positions[-1].shape, wavy_rod.x.shape)


def test_multiplier_predictor_saves_newton_updates(wavy_rod):
    """SHAKE starts from the previous step's multipliers.  A rod pinned at one end and
    pulled at the other by a force of 200 (tension 200, against bending forces ~1): the
    constraint force dominates the step, and the Verlet prediction, which lacks it, needs
    4 Newton updates per step (measured with the former cold start); from the previous
    multipliers 2.  A free rod: at most 2 (unchanged)."""
    rod = wavy_rod
    # no gravity, no damping: the cantilever's stepper (test_dyn_effects.py)
    pulled = simulate(rod, clamped(Clamp(0, tuple(rod.x[0])), load=(200.0, 0.0)),
                      dt=2e-3, t_end=3.0, frames=2)
    assert pulled.success and pulled.stats["constraint_error"] < 5e-14
    # measured 2.001 (the first step starts cold)
    assert pulled.stats["iterations_mean"] < 2.01
    free = simulate(rod, (), dt=2e-3, t_end=5.0, frames=2)
    assert free.success and free.stats["constraint_error"] < 5e-14
    assert free.stats["iterations_max"] <= 2


def test_dependency_digest_covers_what_a_kernel_uses_in_its_package(tmp_path, monkeypatch):
    # a kernel whose helper lives in another module of its package: editing the helper
    # must change the generated stepper's key (numba's cache of the stepper would not see
    # it); touching it without a change must not (content, not mtime)
    import os
    import sys

    from dynamics.cache import dependency_digest, module_closure

    pkg = tmp_path / "fpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text("def twice(a):\n    return 2.0 * a\n")
    (pkg / "kern.py").write_text("import numpy as np\nfrom fpkg.helper import twice\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    __import__("fpkg.kern")
    try:
        files = module_closure(["fpkg.kern"])
        assert files == {str(pkg / "kern.py"), str(pkg / "helper.py")}  # numpy left out
        before = dependency_digest(["fpkg.kern"])
        st = os.stat(pkg / "helper.py")
        os.utime(pkg / "helper.py", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        assert dependency_digest(["fpkg.kern"]) == before
        (pkg / "helper.py").write_text("def twice(a):\n    return a + a\n")
        assert dependency_digest(["fpkg.kern"]) != before
    finally:
        for m in ("fpkg.kern", "fpkg.helper", "fpkg"):
            sys.modules.pop(m, None)
