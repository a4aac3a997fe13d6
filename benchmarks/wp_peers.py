"""Peers side by side: PyElastica on the clamped-free cantilever's first-mode frequency, at
matched accuracy, against our ``dynamics``. AUTO-07p (bifpy) on the statics is in
wp_auto_elastica.py (see AUTO_NOTE). Peers are never runtime dependencies (the ``bench``
extra; PyElastica: ``pip install pyelastica``).

The cantilever: L = 1, B = EI = 1, mu = rho A = 1, first mode omega = 1.8751^2
(``dynamics.reference.euler_bernoulli_omega``).

* PyElastica's rod is a 3D Cosserat rod (extensible, shearable, with rotary inertia) of
  radius r = 0.005 L, shear modulus E/3 (Poisson ratio 0.5): its continuum first mode
  differs from Euler-Bernoulli by O((r/L)^2) ~ 1e-5, below every error compared here. It
  starts straight with the mode shape as velocity (amplitude 1e-4), clamped by
  ``OneEndFixedBC`` (root at the first element's centre, as for our Clamp), Position
  Verlet at dt = 0.05 dx / c, c = sqrt(E/rho) = 2/r the axial wave speed (measured: 0.2
  dx / c blows up within a tenth of a period, 0.1 at 10 elements; a row at 0.025 checks
  that the time step does not limit the error).
* Ours: the set-up of tests/dynamics (mode shape as initial displacement), dt = 1/2 of
  the bending bound.

Both over 2 periods; frequency from the downward zero crossings of the mode projection.
Time: one run each after a warm-up run (numba compiled).

Run: ``python3 benchmarks/wp_peers.py``.
"""

from __future__ import annotations

import math
import time

import numpy as np
from wp_common import IMG, save_record, table, wp_plot

from dynamics import euler_bernoulli_omega

AUTO_NOTE = (
    "AUTO-07p (bifpy 0.3) is compared on the statics, in benchmarks/wp_auto_elastica.py: it "
    "poses the wet part of supp-fig5 as a 7-component Kirchhoff BVP (the enclosed area carried "
    "by the ODE, the cap's curvature and half angle as free parameters, 10 boundary conditions) "
    "and continues it in Delta from the open branch through both folds. Its fold error falls as "
    "h^(2 NCOL) and agrees with ours to 1e-12 (its output resolution) from NTST = 20, NCOL = 4. "
    "This file compares the dynamics (the cantilever) with PyElastica."
)

PERIODS = 2
AMPLITUDE = 1e-4
RADIUS = 0.005


def _mode_shape(s):
    from test_dyn_validation import _mode

    return _mode("clamped-free", s, 1.0)


def _frequency_from(t, q, omega):
    q = q - q.mean()
    i = np.nonzero((q[:-1] > 0) & (q[1:] <= 0))[0]
    tc = t[i] - q[i] * (t[i + 1] - t[i]) / (q[i + 1] - q[i])
    period = (tc[-1] - tc[0]) / (len(tc) - 1)
    return abs(2 * math.pi / period / omega - 1.0)


def pyelastica_error(n, dt_fraction=0.05):
    """(relative frequency error, wall time [s], steps) of PyElastica's cantilever."""
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints):
        pass

    L, B, mu, r = 1.0, 1.0, 1.0, RADIUS
    area, inertia = math.pi * r * r, math.pi * r**4 / 4
    E, rho = B / inertia, mu / area
    # OneEndFixedBC holds node 0 and the director of element 0: the beam root is the first
    # element's centre (as for our Clamp), so the rod is L + dx/2 long with dx = L/(n - 1/2)
    # (a rod of length L clamped this way is dx/2 short: a first-order frequency error)
    dx = L / (n - 0.5)
    sim = Sim()
    rod = ea.CosseratRod.straight_rod(
        n,
        np.array([-0.5 * dx, 0.0, 0.0]),
        np.array([1.0, 0, 0]),
        np.array([0, 0, 1.0]),
        n * dx,
        r,
        rho,
        youngs_modulus=E,
        shear_modulus=E / 3.0,
    )
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    sim.finalize()
    s_nodes = (np.arange(n + 1) - 0.5) * dx
    phi = _mode_shape(np.clip(s_nodes, 0.0, None))
    omega = euler_bernoulli_omega("clamped-free", L, B, mu)
    rod.velocity_collection[1, :] = AMPLITUDE * omega * phi
    # the matching rotation rate of the elements: d(v_y)/ds about the global z (= d1)
    rod.omega_collection[0, :] = AMPLITUDE * omega * np.diff(phi) / dx
    dt = dt_fraction * dx / math.sqrt(E / rho)
    steps = int(math.ceil(PERIODS * 2 * math.pi / omega / dt))
    every = max(1, steps // (PERIODS * 400))
    stepper = ea.PositionVerlet()
    mass = rod.mass
    ts, qs = [], []
    t = 0.0
    t0 = time.perf_counter()
    for k in range(steps):
        if k % every == 0:
            ts.append(t)
            qs.append(float(np.sum(mass * rod.position_collection[1] * phi)))
        t = float(stepper.step(sim, t, dt))
    wall = time.perf_counter() - t0
    return _frequency_from(np.array(ts), np.array(qs), omega), wall, steps


def ours_error(n, dt_fraction=0.5):
    """(relative frequency error, wall time [s], steps) of ``dynamics`` (tests' set-up)."""
    from wp_dynamics import frequency_error

    from dynamics import stable_dt

    err, wall = frequency_error(n, dt_fraction, periods=PERIODS)
    h = 1.0 / (n - 0.5)
    steps = int(
        math.ceil(
            PERIODS
            * 2
            * math.pi
            / euler_bernoulli_omega("clamped-free", 1.0, 1.0, 1.0)
            / (dt_fraction * stable_dt(np.full(n, h), 1.0, 1.0))
        )
    )
    return err, wall, steps


def main(fast=False):
    rows = []
    try:
        import elastica  # noqa: F401

        have = True
    except ImportError:
        have = False
        print("PyElastica not installed (pip install pyelastica): peer column skipped")
    ns = (10, 20) if fast else (10, 20, 40, 80)
    for n in ns:
        e, w, st = ours_error(n)
        rows.append(
            {
                "code": "elastocap dynamics",
                "n": n,
                "dt": "0.5 bound",
                "error": e,
                "time": w,
                "steps": st,
            }
        )
    if have:
        pyelastica_error(6)  # warm-up: numba compilation
        for n in ns[:3] if not fast else ns[:1]:
            e, w, st = pyelastica_error(n)
            rows.append(
                {
                    "code": "PyElastica 1.0",
                    "n": n,
                    "dt": "0.05 dx/c",
                    "error": e,
                    "time": w,
                    "steps": st,
                }
            )
        if not fast:
            e, w, st = pyelastica_error(10, 0.025)
            rows.append(
                {
                    "code": "PyElastica 1.0",
                    "n": 10,
                    "dt": "0.025 dx/c",
                    "error": e,
                    "time": w,
                    "steps": st,
                }
            )
    print(f"\n## peers: clamped-free first-mode frequency ({PERIODS} periods)")
    print(
        table(
            rows,
            [
                ("code", "code", "s"),
                ("n", "elements", "d"),
                ("dt", "dt", "s"),
                ("error", "rel. error", ".1e"),
                ("time", "wall [s]", ".3f"),
                ("steps", "steps", "d"),
            ],
        )
    )
    series = []
    for code in dict.fromkeys(r["code"] for r in rows):
        rs = [r for r in rows if r["code"] == code]
        rs = [r for r in rs if r["dt"] != "0.025 dx/c"]
        series.append(
            {
                "label": code,
                "time": [r["time"] for r in rs],
                "error": [r["error"] for r in rs],
                "notes": [r["n"] for r in rs],
            }
        )
    if not fast:
        wp_plot(
            IMG / "wp-peers-cantilever.png",
            series,
            "clamped-free first-mode frequency (labels: elements)",
        )
        save_record("peers", {"rows": rows, "auto": AUTO_NOTE})
    print("\nAUTO-07p: " + AUTO_NOTE)
    return rows


if __name__ == "__main__":
    import sys

    main("--fast" in sys.argv)
