"""Speed of the `dynamics` stepper (not a test).

Prints medians and ratios for:

1. the generated bending-only stepper vs a bare hand-written RATTLE loop (same kernels,
   no effect machinery, no diagnostics): the cost of specialisation (target < 10%);
   and the share of the bending kernel itself;
2. the added cost of each effect, alone with bending;
3. node-updates per second and the paper's scenes (supp-fig5, strip);
3b. the impact runs of issue 5 (``elastocap impact``); with ``--baseline REV`` the same
   runs of git revision REV side by side (fresh processes, alternated, CPU-time medians);
4. Python-per-step driving vs the compiled loop (the per-step overhead avoided);
5. Newton/tridiagonal SHAKE vs Gauss-Seidel SHAKE (iterations and time), and the cost of
   each pass of one Newton iteration and of the velocity projection;
6. compile time with a cold cache vs a warm cache (fresh processes);
7. with ``--dt-bound``: the explicit stability constant C by bisection.

Usage: ``python benchmarks/dynamics_speed.py [--fast] [--dt-bound] [--only 3b|5]
[--baseline REV]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numba
import numpy as np

import dynamics
from dynamics import (
    Clamp,
    Damping,
    DistributedLoad,
    Gravity,
    Ground,
    PointLoad,
    Rod,
    simulate,
)
from dynamics.bending import BENDING_WORK_ROWS, bending_force_add
from dynamics.constraints import (
    _edges,
    _eliminate,
    _eliminate_serial,
    _move,
    _row_max,
    _shake_rows,
    _split,
    _substitute,
    new_work,
    shake,
    velocity_projection,
)

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests", "dynamics"))
from dyn_ext_kernels import AnchorSpring  # noqa: E402


def wavy_rod(n, L=4.6, amp=0.8):
    h = L / n
    s = (np.arange(n) + 0.5) * h
    th = amp * np.sin(2 * np.pi * s / L)
    x = np.zeros((n + 1, 2))
    x[1:, 0] = np.cumsum(h * np.cos(th))
    x[1:, 1] = np.cumsum(h * np.sin(th))
    return Rod(x, np.zeros_like(x), np.full(n, h))


@numba.njit(cache=True)
def bare_rattle(x, v, dt, n_steps, edge_len, winv, B, F, xn, vh, cw, lam, bw):
    """The same RATTLE step as the generated stepper, bending only, written by hand."""
    n = x.shape[0]
    half = 0.5 * dt
    F[:, :] = 0.0
    bending_force_add(x, edge_len, B, F, bw)
    for _ in range(n_steps):
        for i in range(n):
            for k in range(2):
                vh[i, k] = v[i, k] + half * winv[i, k] * F[i, k]
                xn[i, k] = x[i, k] + dt * vh[i, k]
        shake(x, xn, winv, edge_len, cw, lam, True)
        for i in range(n):
            for k in range(2):
                vh[i, k] = (xn[i, k] - x[i, k]) / dt
                x[i, k] = xn[i, k]
                F[i, k] = 0.0
        bending_force_add(x, edge_len, B, F, bw)
        for i in range(n):
            for k in range(2):
                v[i, k] = vh[i, k] + half * winv[i, k] * F[i, k]
        velocity_projection(x, v, winv, cw)


@numba.njit(cache=True)
def bending_loop(x, edge_len, B, F, n_steps):
    E = 0.0
    for _ in range(n_steps):
        F[:, :] = 0.0
        E += bending_force_add(x, edge_len, B, F)
    return E


@numba.njit(cache=True)
def gauss_seidel_shake(x_old, x_new, winv, edge_len, tol, max_sweeps):
    """Classical SHAKE (Ryckaert et al. 1977): one constraint at a time, sweeps."""
    m = edge_len.shape[0]
    for sweep in range(max_sweeps):
        err = 0.0
        for i in range(m):
            rx = x_new[i + 1, 0] - x_new[i, 0]
            rz = x_new[i + 1, 1] - x_new[i, 1]
            li2 = edge_len[i] * edge_len[i]
            phi = rx * rx + rz * rz - li2
            e = abs(phi) / (2 * li2)
            if e > err:
                err = e
            dx = x_old[i + 1, 0] - x_old[i, 0]
            dz = x_old[i + 1, 1] - x_old[i, 1]
            w = winv[i, 0] + winv[i + 1, 0]
            g = phi / (2.0 * w * (rx * dx + rz * dz))
            x_new[i, 0] += winv[i, 0] * g * dx
            x_new[i, 1] += winv[i, 1] * g * dz
            x_new[i + 1, 0] -= winv[i + 1, 0] * g * dx
            x_new[i + 1, 1] -= winv[i + 1, 1] * g * dz
        if err < tol:
            return sweep
    return -1


def median_time(fn, repeat=5):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def section(title):
    print(f"\n== {title}")


def bench_overhead(n=200, steps=20000, repeat=5):
    section(f"1. generated bending-only stepper vs bare RATTLE loop ({n} edges, {steps} steps)")
    rod = wavy_rod(n)
    dt = dynamics.stable_dt(rod.edge_len, 1, 1)
    m = rod.mass
    winv = np.repeat((1 / m)[:, None], 2, axis=1).copy()

    def bare():
        x, v = rod.x.copy(), rod.v.copy()
        w = [np.zeros_like(x) for _ in range(3)]
        bare_rattle(x, v, dt, steps, rod.edge_len, winv, 1.0, *w, new_work(n),
                    np.zeros(n + 2), np.zeros((BENDING_WORK_ROWS, n + 1)))

    def gen():
        r = simulate(rod, (), dt=dt, t_end=steps * dt, frames=2)
        return r.stats["run_time"]

    def kern():
        bending_loop(rod.x, rod.edge_len, 1.0, np.zeros_like(rod.x), steps)

    bare(), gen(), kern()
    tb = median_time(bare, repeat)
    tg = float(np.median([gen() for _ in range(repeat)]))
    tk = median_time(kern, repeat)
    print(f"bare RATTLE loop      {tb / steps * 1e6:8.2f} us/step")
    print(f"generated stepper     {tg / steps * 1e6:8.2f} us/step   ratio {tg / tb:.3f}")
    print(f"bending kernel alone  {tk / steps * 1e6:8.2f} us/step   share {tk / tb:.2f}")
    return tg / steps


def bench_effects(n=200, steps=20000, repeat=5):
    section(f"2. added cost of each effect ({n} edges, {steps} steps, {repeat} rounds)")
    rod = wavy_rod(n)
    rod.x[:, 1] += 1.0  # above the ground
    dt = dynamics.stable_dt(rod.edge_len, 1, 1)
    cases = {
        "bending only": lambda: (),
        "gravity": lambda: (Gravity(1e-3),),
        "ground": lambda: (Ground(),),
        "damping": lambda: (Damping(0.1),),
        "point load": lambda: (PointLoad(-1, (0.0, 1e-3)),),
        "distributed load": lambda: (DistributedLoad((0.0, 1e-3)),),
        "clamp": lambda: (Clamp(0, tuple(rod.x[0]), angle=0.0),),
        "external spring": lambda: (AnchorSpring(0, 1.0, tuple(rod.x[0])),),
        "all of the above": lambda: (Gravity(1e-3), Ground(), Damping(0.1),
                                     PointLoad(-1, (0, 1e-3)), DistributedLoad((0, 1e-3)),
                                     Clamp(0, tuple(rod.x[0]), angle=0.0)),
    }
    # round-robin over the cases and report the minimum: the machine is shared, and
    # contention only ever adds time (medians of consecutive repeats were seen to swing
    # by +-40% between otherwise identical cases)
    for make in cases.values():
        simulate(rod, make(), dt=dt, t_end=10 * dt, frames=2)  # compile / load
    times = {name: [] for name in cases}
    for _ in range(repeat):
        for name, make in cases.items():
            times[name].append(simulate(rod, make(), dt=dt, t_end=steps * dt, frames=2)
                               .stats["run_time"] / steps)
    base = min(times["bending only"])
    for name, ts in times.items():
        t = min(ts)
        print(f"{name:18s} min {t * 1e6:7.2f} us/step (median {np.median(ts) * 1e6:7.2f})"
              f"  +{(t / base - 1) * 100:5.1f}%  {(n + 1) / t / 1e6:5.1f} M node-updates/s")


def bench_scenes():
    section("3. scenes (after compile)")
    for n, t_end in ((100, 10.0), (100, 50.0), (200, 10.0), (200, 50.0)):
        rod = wavy_rod(n)
        dt = dynamics.stable_dt(rod.edge_len, 1, 1)
        r = simulate(rod, (), dt=dt, t_end=t_end, frames=101)
        print(f"supp-fig5 free rod L=4.6 N={n:3d} t_end={t_end:4.0f} dt={dt:.2e}: "
              f"{r.steps:7d} steps {r.stats['run_time']:6.3f} s  "
              f"({(n + 1) * r.steps / r.stats['run_time'] / 1e6:.1f} M node-updates/s)")
    for n in (100, 150):
        rod = Rod.straight(n, 14.3, angle=0.3, origin=(0.0, 0.2))
        dt = dynamics.stable_dt(rod.edge_len, 1, 1)
        r = simulate(rod, (Gravity(1.0), Ground(), Damping(0.05)), dt=dt, t_end=20.0,
                     frames=101)
        print(f"strip L=14.3 gravity+ground+damping N={n} t_end=20 dt={dt:.2e}: "
              f"{r.steps:7d} steps {r.stats['run_time']:6.3f} s  status {r.status}")


IMPACT_CASES = (("supp-fig5", {}), ("supp-fig5", {"drop.wetted_length": 3.5}),
                ("supp-fig5", {"drop.wetted_length": 4.0}), ("fig3-strip", {}))

#: Run in a fresh process by :func:`bench_impacts` with ``--baseline``: each case once to
#: compile/load, then ``reps`` timed runs; prints one JSON line per case.
IMPACT_SNIPPET = """
import json, sys, time
from elastocap.impact import run_impact
from elastocap.scene import load_scene
import elastocap, dynamics
assert elastocap.__file__.startswith(sys.argv[1]), (elastocap.__file__, sys.argv[1])
for name, ov in json.loads(sys.argv[2]):
    scene = load_scene(name, ov)
    run_impact(scene)
    cpu, wall = [], []
    for _ in range(int(sys.argv[3])):
        c, w = time.thread_time(), time.perf_counter()
        r = run_impact(scene)
        cpu.append(time.thread_time() - c)
        wall.append(time.perf_counter() - w)
    s = r.simulation
    # a revision before the driver's ``stats`` has the same numbers as attributes
    st = getattr(s, "stats", None) or dict(iterations_mean=s.shake_iterations_mean,
                                           run_time=s.wall_time)
    print(json.dumps(dict(case=[name, ov], cpu=min(cpu), wall=min(wall), outcome=r.outcome,
                          final_measure=r.final_measure, t_end=r.t_end, steps=r.steps,
                          it=st["iterations_mean"], loop=st["run_time"])))
"""


def export_revision(rev, dest):
    """Files of git revision ``rev`` of this repository into ``dest`` (no checkout, no
    change to the repository)."""
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    archive = subprocess.run(["git", "-C", root, "archive", rev], capture_output=True,
                             check=True).stdout
    subprocess.run(["tar", "-x", "-C", dest], input=archive, check=True)


def bench_impacts(repeat=3, baseline=None):
    """The impact runs of issue 5's targets, at default resolution, after compilation.

    Without ``baseline``: the automatic dt (0.9 of the bound without a ground, 0.5 with
    one) side by side with the former fixed 0.5, in the same run.  With ``baseline`` (a git
    revision): the same runs by that revision and by the working tree, in fresh processes
    alternated ``repeat`` times (the machine is shared: medians of per-process minima of
    CPU time, wall time beside).
    """
    section("3b. impact runs (elastocap impact, default resolution, after compile)")
    if baseline is not None:
        return _bench_impacts_against(repeat, baseline)
    from elastocap.impact import impact_settings, run_impact
    from elastocap.scene import load_scene

    for name, ov in IMPACT_CASES:
        scene = load_scene(name, ov)
        st = impact_settings(scene)
        half = scene.with_overrides({"numerics.dt": 0.5 * st["dt_max"]})
        run_impact(scene)
        walls = {"auto": [], "0.5": []}
        for _ in range(repeat):
            for key, sc in (("auto", scene), ("0.5", half)):
                r = run_impact(sc)
                walls[key].append(r.wall_time_s)
                if key == "auto":
                    ra = r
        med = {k: float(np.median(v)) for k, v in walls.items()}
        label = name + "".join(f" {k}={v}" for k, v in ov.items())
        frac = ra.settings["dt"] / st["dt_max"]
        print(f"{label:36s} edges {st['n_edges']:3d}  dt/bound {frac:.2f}"
              f"  steps {ra.steps:6d}  {ra.outcome:12s} median {med['auto']:.3f} s"
              f"  (dt 0.5 of bound: {med['0.5']:.3f} s, ratio {med['0.5'] / med['auto']:.2f})"
              f"  {ra.wall_time_s / ra.steps * 1e6:.2f} us/step")


def alternate_processes(trees, baseline, snippet, cases, inner, repeat):
    """Run ``snippet`` (``python -c``; arguments: the tree, ``cases``, ``inner``) in a
    fresh process per tree (``{label: folder}``), ``repeat`` rounds in alternated order;
    returns ``{label: [one list per process of its output lines read as JSON]}``.  The
    ``baseline`` tree keeps its generated steppers in its own folder, out of the user's
    cache."""
    import json

    res = {k: [] for k in trees}
    for r in range(repeat):
        for label in (trees if r % 2 == 0 else list(trees)[::-1]):
            env = dict(os.environ, PYTHONPATH=trees[label])
            if label == baseline:
                env["DYNAMICS_CACHE_DIR"] = os.path.join(trees[label], "_stepper_cache")
            out = subprocess.run([sys.executable, "-c", snippet, trees[label], cases,
                                  str(inner)], env=env, cwd=trees[label],
                                 capture_output=True, text=True)
            if out.returncode:
                raise SystemExit(f"{label}: {out.stderr[-2000:]}")
            res[label].append([json.loads(line) for line in out.stdout.splitlines()])
    return res


def _bench_impacts_against(repeat, baseline, inner=2):
    import json

    here = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    cases = json.dumps([list(c) for c in IMPACT_CASES])
    with tempfile.TemporaryDirectory() as tmp:
        export_revision(baseline, tmp)
        trees = {baseline: tmp, "working tree": here}
        res = alternate_processes(trees, baseline, IMPACT_SNIPPET, cases, inner, repeat)
    for k, (name, ov) in enumerate(IMPACT_CASES):
        label = name + "".join(f" {a}={b}" for a, b in ov.items())
        rows = {t: [run[k] for run in res[t]] for t in trees}
        med = {t: {q: float(np.median([x[q] for x in rows[t]])) for q in ("cpu", "wall")}
               for t in trees}
        old, new = (rows[t][-1] for t in trees)
        print(f"{label:30s} {baseline}: {med[baseline]['cpu']:.3f} s cpu "
              f"({med[baseline]['wall']:.3f} wall)  working tree: "
              f"{med['working tree']['cpu']:.3f} s cpu ({med['working tree']['wall']:.3f} "
              f"wall)  ratio {med[baseline]['cpu'] / med['working tree']['cpu']:.2f}")
        print(f"{'':30s} outcome {old['outcome']}/{new['outcome']}  final measure "
              f"{old['final_measure']:.12f}/{new['final_measure']:.12f}  t_end "
              f"{old['t_end']:.6f}/{new['t_end']:.6f}  SHAKE updates/step {old['it']:.3f}/"
              f"{new['it']:.3f}")


def bench_python_loop(n=100, steps=2000):
    section(f"4. Python call per step vs compiled loop ({n} edges)")
    rod = wavy_rod(n)
    dt = dynamics.stable_dt(rod.edge_len, 1, 1)
    mod = dynamics.rattle.compile_stepper(())
    x, v = rod.x.copy(), rod.v.copy()
    m = rod.mass
    winv0 = np.repeat((1 / m)[:, None], 2, axis=1).copy()
    A, cw, lam = np.zeros((7, n + 1, 2)), new_work(n), np.zeros(n + 2)
    bw = np.zeros((BENDING_WORK_ROWS, n + 1))
    energy, diag, rest = np.zeros(1), np.zeros(10), np.zeros(3)
    ck = dynamics.contact.new_contact_work(np.ones(1))  # a token: no self-contact
    args = (rod.edge_len, m, winv0, 1.0, A, cw, lam, bw, energy, diag, rest, ck, ())
    mod.run(x, v, 0.0, dt, 1, *args)

    def per_step():
        for k in range(steps):
            mod.run(x, v, k * dt, dt, 1, *args)

    def chunk():
        mod.run(x, v, 0.0, dt, steps, *args)

    tp, tc = median_time(per_step), median_time(chunk)
    print(f"one Python call per step {tp / steps * 1e6:7.2f} us/step")
    print(f"compiled loop            {tc / steps * 1e6:7.2f} us/step   "
          f"overhead avoided {(tp - tc) / steps * 1e6:.2f} us/step ({tp / tc:.2f}x)")


def bench_shake(repeat=5):
    section("5. SHAKE: Newton + tridiagonal vs Gauss-Seidel sweeps (to 1e-13)")
    rng = np.random.default_rng(1)
    for n in (50, 100, 200):
        rod = wavy_rod(n)
        dt = dynamics.stable_dt(rod.edge_len, 1, 1)
        # a typical predictor: random velocities of order 1, one step
        vel = rng.standard_normal((n + 1, 2))
        xs = rod.x + dt * vel
        winv = np.repeat((1 / rod.mass)[:, None], 2, axis=1).copy()
        cw, lam = new_work(n), np.zeros(n + 2)
        xn = xs.copy()
        _, it, _, _ = shake(rod.x, xn, winv, rod.edge_len, cw, lam)
        xg = xs.copy()
        sw = gauss_seidel_shake(rod.x, xg, winv, rod.edge_len, 1e-13, 100000)

        def newton(rod=rod, xs=xs, winv=winv, cw=cw, lam=lam):
            shake(rod.x, xs.copy(), winv, rod.edge_len, cw, lam)

        def gs(rod=rod, xs=xs, winv=winv):
            gauss_seidel_shake(rod.x, xs.copy(), winv, rod.edge_len, 1e-13, 100000)

        tn = median_time(newton, repeat)
        tg = median_time(gs, repeat)
        print(f"N={n:3d}: Newton {it} iterations {tn * 1e6:7.1f} us | Gauss-Seidel {sw:5d} "
              f"sweeps {tg * 1e6:8.1f} us | ratio {tg / tn:6.1f}x")
    bench_passes(repeat)


@numba.njit(cache=True)
def _passes_loop(which, xo, xf, wf, edge_len, work, w0, k):
    s = 0.0
    for _ in range(k):
        if which == 0:
            _split(xf, work, 8)
            _shake_rows(edge_len, work)
        elif which == 1:
            for r in range(2, 7):
                for i in range(work.shape[1]):
                    work[r, i] = w0[r, i]
            s += _eliminate(work)
        elif which == 2:
            for r in range(2, 7):
                for i in range(work.shape[1]):
                    work[r, i] = w0[r, i]
        elif which == 3:
            _substitute(work)
        elif which == 4:
            _move(xf, wf, work, work[5])
        elif which == 5:
            _edges(xo, work)
        elif which == 6:
            s += _row_max(work, 6)
        elif which == 7:
            for r in range(2, 7):
                for i in range(work.shape[1]):
                    work[r, i] = w0[r, i]
            _eliminate_serial(work)
        else:
            velocity_projection(xo.reshape(xo.size // 2, 2), xf.reshape(xf.size // 2, 2),
                                wf.reshape(wf.size // 2, 2), work)
    return s


def bench_passes(repeat=5, k=20000):
    """Cost of each pass of a SHAKE Newton iteration (rows, residual maximum, two-ended
    elimination by leading minors and its serial fallback, back substitution, node update)
    and of a velocity projection, on a rod of 198 edges (fig3-strip's resolution)."""
    n = 198
    rod = wavy_rod(n)
    winv = np.repeat((1 / rod.mass)[:, None], 2, axis=1).copy()
    xs = rod.x + 1e-5 * rod.edge_len[0] * np.random.default_rng(2).standard_normal(rod.x.shape)
    work = new_work(n)
    xo, xf, wf = rod.x.reshape(-1), xs.reshape(-1), winv.reshape(-1)
    _edges(xo, work)
    _split(wf, work, 10)
    _split(xf, work, 8)
    _shake_rows(rod.edge_len, work)
    w0 = work.copy()
    names = ("rows (split + build)", "elimination", "", "back substitution", "node update",
             "edges", "residual maximum", "serial elimination", "velocity projection")
    t = {}
    for which in range(9):
        _passes_loop(which, xo, xf.copy(), wf, rod.edge_len, work, w0, 10)
        work[:] = w0
        t[which] = min(median_time(lambda: _passes_loop(which, xo, xf.copy(), wf,  # noqa: B023
                                                        rod.edge_len, work, w0, k), 1)
                       for _ in range(repeat)) / k
        work[:] = w0
    t[1] -= t[2]  # the restore of the rows
    t[7] -= t[2]
    print(f"one SHAKE Newton iteration, {n} edges: " + ", ".join(
        f"{names[w]} {t[w] * 1e9:.0f} ns" for w in (0, 6, 1, 7, 3, 4)) +
        f"; edges {t[5] * 1e9:.0f} ns; a velocity projection {t[8] * 1e9:.0f} ns")


COMPILE_SNIPPET = """
import time, numpy as np
t = time.perf_counter()
import dynamics
ti = time.perf_counter() - t
rod = dynamics.Rod.straight(50, 4.6)
r = dynamics.simulate(rod, ({effects}), dt=1e-3, t_end=0.01, frames=2)
print(ti, r.stats["compile_time"], time.perf_counter() - t)
"""


def bench_compile():
    section("6. compile time, fresh processes (import, stepper compile/load, total)")
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, DYNAMICS_CACHE_DIR=tmp, NUMBA_CACHE_DIR=tmp)
        for label, eff in (("bending only", ""),
                           ("gravity+ground+damping", "dynamics.Gravity(), dynamics.Ground(),"
                                                      " dynamics.Damping(0.1),")):
            for temp in ("cold", "warm"):
                out = subprocess.run([sys.executable, "-c",
                                      COMPILE_SNIPPET.format(effects=eff)], env=env,
                                     capture_output=True, text=True, check=True).stdout
                ti, tcomp, tt = map(float, out.split())
                print(f"{label:24s} {temp} cache: import {ti:5.2f} s  stepper {tcomp:5.2f} s"
                      f"  total {tt:5.2f} s")


def measure_dt_bound():
    section("7. explicit stability constant C (dt_max = C h^2 sqrt(mu/B)) by bisection")
    for n in (25, 100, 200, 400):
        L = 4.6
        h = L / n
        rng = np.random.default_rng(0)
        th = np.cumsum(1e-3 * rng.standard_normal(n))
        x = np.zeros((n + 1, 2))
        x[1:, 0] = np.cumsum(h * np.cos(th))
        x[1:, 1] = np.cumsum(h * np.sin(th))
        rod = Rod(x, np.zeros_like(x), np.full(n, h))
        lo, hi = 0.2, 0.8
        for _ in range(14):
            mid = 0.5 * (lo + hi)
            dt = mid * h * h
            r = simulate(rod, (), dt=dt, t_end=30000 * dt, frames=2, check_dt=False)
            E = r.energies["total"]
            bad = (not r.success) or not np.isfinite(E[-1]) or E[-1] > 2 * E[0]
            lo, hi = (lo, mid) if bad else (mid, hi)
        print(f"N={n:3d}: C in [{lo:.4f}, {hi:.4f}]  (DT_BOUND_C = {dynamics.DT_BOUND_C})")


def main(fast=False, dt_bound=False, only=None, baseline=None):
    steps = 4000 if fast else 20000
    repeat = 3 if fast else 5
    print(f"numba {numba.__version__}, numpy {np.__version__}, threads "
          f"{numba.config.NUMBA_NUM_THREADS}")
    if only == "3b":
        bench_impacts(repeat=1 if fast else 5, baseline=baseline)
        return
    if only == "5":
        bench_shake(repeat=repeat)
        return
    bench_overhead(steps=steps, repeat=repeat)
    bench_effects(steps=steps, repeat=repeat)
    if not fast:
        bench_scenes()
    bench_impacts(repeat=1 if fast else 3, baseline=baseline)
    bench_python_loop()
    bench_shake(repeat=repeat)
    if not fast:
        bench_compile()
    if dt_bound:
        measure_dt_bound()


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fast", action="store_true")
    ap.add_argument("--dt-bound", action="store_true")
    ap.add_argument("--only", choices=["3b", "5"], help="run one section")
    ap.add_argument("--baseline", metavar="REV",
                    help="git revision to time beside the working tree in section 3b")
    a = ap.parse_args()
    main(fast=a.fast, dt_bound=a.dt_bound, only=a.only, baseline=a.baseline)
