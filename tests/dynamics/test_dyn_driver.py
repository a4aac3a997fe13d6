"""The one driver of both methods: the same trajectories as the two steppers it replaced
(bit for bit), named diagnostics that save and load, the effect protocol, and no numba
internals in the generated code."""

import json
import logging
import platform
from pathlib import Path

import numba
import numpy as np
import pytest

from dynamics import (
    STATS_KEYS,
    Damping,
    Event,
    Gravity,
    Ground,
    RestCriterion,
    Rod,
    SimulationResult,
    simulate,
)
from elastocap.capillary import Capillary

REF = Path(__file__).parent / "data" / "reference_trajectories.npz"


def _rod(n, L):
    x = np.zeros((n + 1, 2))
    x[:, 0] = np.linspace(0.0, L, n + 1)
    return Rod(x, np.zeros_like(x), np.full(n, L / n), 1.0, 1.0)


def _free(method):
    # a free rod carrying a drop (supp-fig5's kind of run), 40 edges
    dt = 0.9 * 0.45 * (4.6 / 40) ** 2 if method == "rattle" else 0.01
    return simulate(_rod(40, 4.6), (Capillary(1.5, 0.3, 4.3, 1.0), Damping(0.2)),
                    method=method, dt=dt, t_end=3.0, frames=4)


def _strip(method):
    # a strip on the ground with gravity, a drop, damping and a drop event (fig3-strip's
    # kind of run), 60 edges
    b = 0.45 * (14.3 / 60) ** 2
    return simulate(_rod(60, 14.3), (Capillary(0.36, 8.7, 9.9, 40.0), Gravity(1.0), Ground(),
                                     Damping(0.1)),
                    method=method, dt=(0.7 if method == "rattle" else 8.0) * b, t_end=2.0,
                    frames=5, events=[Event(0.5, "capillary", "s2", 10.0)],
                    rest=RestCriterion(1e-9, 1.0))


@pytest.mark.parametrize("scene", ["free", "strip"])
@pytest.mark.parametrize("method", ["rattle", "midpoint"])
def test_trajectories_are_those_of_the_previous_steppers(scene, method):
    """The positions and velocities recorded by the two separate steppers the driver
    replaced (``simulate`` and ``simulate_implicit`` of the previous code, same machine,
    numba 0.68.1): bit for bit where the method did not change.  RATTLE's strip run is
    recorded with the ground releasing the nodes it would pull and projecting the drift
    again with them free (0.0125 from the run that kept the held projection; at t = 2 the
    run is 0.028 from the midpoint rule at 1/64 of its step and RATTLE at 1/16 of its step
    is 1.7e-3 from it, the midpoint rule's own change from 1/64 to 1/128 of its step being
    3.2e-3).  On another CPU or
    numba version round-off may differ: there the comparison is to 1e-9."""
    ref = np.load(REF)
    res = (_free if scene == "free" else _strip)(method)
    assert res.success, res.message
    same_build = (str(ref["numba_version"]) == numba.__version__
                  and str(ref["machine"]) == platform.machine())
    for got, key in ((res.positions, f"{scene}_{method}"), (res.velocities,
                                                           f"{scene}_{method}_v")):
        if same_build:
            assert np.array_equal(got, ref[key]), np.abs(got - ref[key]).max()
        else:
            np.testing.assert_allclose(got, ref[key], rtol=0, atol=1e-9)


def test_stats_are_named_and_round_trip(tmp_path):
    for method in ("rattle", "midpoint"):
        res = _strip(method)
        assert set(STATS_KEYS) <= set(res.stats)
        assert res.stats["steps"] == res.steps > 0
        assert res.stats["compile_time"] >= 0.0 and res.stats["run_time"] > 0.0
        assert res.stats["constraint_error"] < 1e-10
        assert res.stats["iterations_mean"] > 0.0
        assert res.method == method
        d = res.to_dict()
        assert json.loads(json.dumps(d))["stats"] == res.stats
        p = tmp_path / f"{method}.npz"
        res.save_npz(p)
        back = SimulationResult.load_npz(p)
        assert back.stats == res.stats and back.method == method
        assert np.array_equal(back.positions, res.positions)
        # a result compares by value (the generated == would raise on its arrays)
        assert back == res and not back != res
        moved = SimulationResult.load_npz(p)
        # the next float (an added 1e-15 would round away at a coordinate above 8)
        moved.positions[-1, -1, 0] = np.nextafter(moved.positions[-1, -1, 0], np.inf)
        assert moved != res
        moved = SimulationResult.load_npz(p)
        moved.energies["kinetic"] = moved.energies["kinetic"][:-1]
        assert moved != res
    # the midpoint method's own counters are in its stats
    assert {"jacobians", "contact_updates"} <= set(res.stats)


def test_save_npz_is_atomic_and_names_like_numpy(tmp_path, monkeypatch):
    res = _strip("rattle")
    res.save_npz(tmp_path / "run")  # numpy's rule: ".npz" added
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz"]
    before = (tmp_path / "run.npz").read_bytes()

    def half_written(f, **arrays):
        f.write(b"PK\x03\x04 cut")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", half_written)
    with pytest.raises(OSError, match="disk full"):
        res.save_npz(tmp_path / "run.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz"]
    assert (tmp_path / "run.npz").read_bytes() == before


def test_unknown_method_and_options_are_refused_by_name():
    rod = Rod.straight(10, 1.0)
    with pytest.raises(ValueError, match=r"method: got 'euler'; expected one of \('rattle', "
                       r"'midpoint'\)"):
        simulate(rod, (), method="euler", dt=1e-3, t_end=0.1)
    with pytest.raises(TypeError, match="jacobian_age"):
        simulate(rod, (), method="rattle", dt=1e-4, t_end=0.1, jacobian_age=2)
    with pytest.raises(ValueError, match="would take 1e\\+12 steps"):
        simulate(rod, (), dt=1e-13, t_end=0.1)


def test_a_ground_is_known_by_the_protocol_not_by_its_name():
    # a renamed ground (in the effects of the strip above: the same stepper), and a
    # ground-like constraint that does not declare itself one
    b = 0.45 * (14.3 / 60) ** 2
    res = simulate(_rod(60, 14.3), (Capillary(0.36, 8.7, 9.9, 40.0), Gravity(1.0),
                                    Ground(name="floor"), Damping(0.1)),
                   method="midpoint", dt=8.0 * b, t_end=1.0, frames=2)
    assert res.success and res.positions[-1][:, 1].min() >= -1e-12
    assert res.stats["steps"] > 0
    rod = Rod.straight(10, 1.0)

    class Undeclared(Ground):
        ground_height_param = None

    with pytest.raises(ValueError, match="constraint effects other than a ground"):
        simulate(rod, (Undeclared(),), method="midpoint", dt=0.01, t_end=0.1)


def test_no_numba_internals_in_the_generated_steppers():
    from dynamics import midpoint, rattle

    effects = (Capillary(1.5, 0.3, 4.3, 1.0), Gravity(1.0), Ground(), Damping(0.2))
    for mod in (rattle.compile_stepper(effects), midpoint.compile_stepper(effects)):
        text = Path(mod.__file__).read_text()
        assert "numba.core" not in text and "intrinsic" not in text, mod.__file__
        assert "numba.njit(cache=True" in text


def test_first_compile_is_announced(tmp_path, monkeypatch, caplog):
    """The first compile of an effect combination is announced on the "dynamics" logger
    (the CLI shows it on stderr); a loaded one is not."""
    from dynamics import cache

    monkeypatch.setattr(cache, "_LOADED", {})
    from dynamics import rattle

    monkeypatch.setattr(rattle, "_MODULES", {})
    from dynamics import codegen

    monkeypatch.setattr(cache, "is_compiled", lambda mod, fns: False)
    monkeypatch.setattr(rattle, "is_compiled", lambda mod, fns: False)
    monkeypatch.setattr(codegen, "is_compiled", lambda mod, fns: False)
    with caplog.at_level(logging.INFO, logger="dynamics"):
        simulate(Rod.straight(10, 1.0), (), dt=1e-4, t_end=1e-3, frames=2)
    # bending only, nothing in numba's cache (a fresh install): the base estimate and the
    # package's kernels
    est = f"about {rattle.COMPILE_BASE_S + codegen.KERNELS_COLD_S:.0f} s"
    assert f"compiling the rattle stepper for bending: once, {est}" in caplog.text
    caplog.clear()
    monkeypatch.setattr(rattle, "is_compiled", lambda mod, fns: True)
    with caplog.at_level(logging.INFO, logger="dynamics"):
        simulate(Rod.straight(10, 1.0), (), dt=1e-4, t_end=1e-3, frames=2)
    assert "compiling" not in caplog.text


@pytest.mark.skipif(platform.system() == "Windows", reason="POSIX file locks")
def test_simulate_compiles_a_new_stepper_under_its_compile_lock(monkeypatch, caplog):
    """A stepper not compiled yet is compiled while holding its module's compile lock
    (:func:`dynamics.cache.compile_lock`): with another process holding it, ``simulate``
    waits, says so, and then runs as before."""
    import time

    from lock_holder import lock_held_by_another_process

    from dynamics import rattle

    before = _free("rattle")  # compiled in this process: "not compiled" is simulated below
    run = rattle.Run(_rod(40, 4.6), (Capillary(1.5, 0.3, 4.3, 1.0), Damping(0.2)),
                     0.9 * 0.45 * (4.6 / 40) ** 2, 0.0, None)
    monkeypatch.setattr(rattle.Run, "compiled", lambda self: False)
    with caplog.at_level(logging.INFO, logger="dynamics"), \
            lock_held_by_another_process(run.mod, 1.5):
        t0 = time.monotonic()
        res = _free("rattle")
        waited = time.monotonic() - t0
    assert "waiting for another process compiling the rattle stepper" in caplog.text
    assert "compiling the rattle stepper" in caplog.text
    assert waited > 1.0
    assert np.array_equal(res.positions, before.positions)
