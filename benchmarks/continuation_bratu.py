"""Bratu fold: accuracy against wall time, this library next to its peers.

Problem: u'' + lam e^u = 0, u(0) = u(1) = 0, continued in lam from the trivial
solution at lam = 0 past the fold lam* = 3.513830719125161. Reported for each
method: unknowns, |lam_fold - lam*|, median wall time over repeats (the whole
run: continuation from lam = 0 through the fold, including fold location),
and the time relative to this library's spectral run.

Methods
-------
- ``continuation`` (this library), Chebyshev collocation (spectral) and
  finite differences (order 2); fold by the minimally augmented system.
- AUTO-07p through ``bifpy`` (pip; builds Auto-07p from source, needs
  gfortran): Bratu as a 2-D first-order BVP, orthogonal collocation
  (NCOL = 4), fold located by AUTO's own test functions (EPSS = 1e-10).
  Each run is an Auto-07p subprocess, as bifpy always does it; both the
  default path (Python callbacks through ctypes) and ``transpile=True`` (a
  native executable compiled from the traced model, cached after warm-up).
- ``bice`` (pure Python): the same Chebyshev discretization and analytic
  Jacobian, its pseudo-arclength stepper (run until the fold is located),
  fold located by its eigenvalue bisection.
- scipy-only baseline: natural-parameter continuation with
  ``scipy.integrate.solve_bvp``, halving the lam step on failure; it cannot
  pass the fold, so its estimate is the last lam it converged at.

Peers are optional (the ``bench`` extra); a missing one is skipped with the
reason printed. Regenerate the table with::

    python3 benchmarks/continuation_bratu.py            # repeats = 5
    python3 benchmarks/continuation_bratu.py --repeats 3 --quick
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings

import numpy as np

from continuation import ContinuationSettings, continue_branch
from continuation.examples import BRATU_FOLD, Bratu

LAM_STAR = BRATU_FOLD
# Same step policy for every arclength method: first step 0.05, at most 0.5,
# 40 steps (the fold is passed after ~17).
DS0, DS_MAX, STEPS = 0.05, 0.5, 40


def timed(fn, repeats):
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, statistics.median(times)


# ------------------------------------------------------------------ this library
def ours(N, method):
    prob = Bratu(N, method)
    s = ContinuationSettings(ds0=DS0, ds_max=DS_MAX, max_steps=STEPS, p_min=0.0, p_max=4.0,
                             compute_stability=False)

    def run():
        br = continue_branch(prob, np.zeros(prob.n), 0.0, s)
        return br.folds[0].p

    return run, prob.n


# ------------------------------------------------------------------ AUTO-07p (bifpy)
def _auto_func(state, par):
    return [state[1], -par[0] * np.exp(state[0])]


def _auto_bcnd(ul, ur, par):
    return [ul[0], ur[0]]


def _auto_stpnt(state, par, t):
    state[0] = 0.0
    state[1] = 0.0
    par[0] = 0.0


def auto07p(ntst, ncol=4, nmx=STEPS, transpile=False):
    from bifpy import auto
    from bifpy.results import PointType

    settings = dict(ips=auto.IPS_GENERAL_BVP, ndim=2, nbc=2, nint=0, npar=1, nmx=nmx,
                    ntst=ntst, ncol=ncol, iad=0, ilp=1, isp=0, itmx=12, itnw=8, nwtn=3,
                    jac=0, ds=DS0, dsmin=1e-6, dsmax=DS_MAX, rl0=-0.1, rl1=4.0, a0=0.0,
                    a1=100.0, epsl=1e-12, epsu=1e-12, epss=1e-10)

    def run():
        res = auto.run(_auto_func, _auto_stpnt, settings, icu=[1], bcnd=_auto_bcnd,
                       transpile=transpile)
        folds = [p.parameters[0] for b in res.branches for p in b.points
                 if p.point_type == PointType.FOLD]
        return folds[0] if folds else float("nan")

    return run, (ntst * ncol + 1) * 2


def auto07p_startup(ntst=5):
    """AUTO-07p with NMX = 2: bifpy's subprocess start-up, for reference."""
    run, n = auto07p(ntst, nmx=2)

    def run2():
        run()
        return float("nan")

    return run2, n


# ------------------------------------------------------------------ bice
def bice_run(N):
    import bice

    base = Bratu(N, "chebyshev")

    class Eq(bice.Equation):
        def __init__(self):
            super().__init__(shape=(base.n,))
            self.lam = 0.0

        def rhs(self, u):
            return base.residual(u, self.lam)

        def jacobian(self, u):
            return base.jacobian(u, self.lam)

    class Prob(bice.Problem):
        def __init__(self):
            super().__init__()
            self.bratu = Eq()  # not `self.eq`: bice.Problem owns that name
            self.add_equation(self.bratu)
            self.continuation_parameter = (self.bratu, "lam")

    def run():
        pr = Prob()
        pr.settings.neigs = 4
        pr.settings.always_locate_bifurcations = True
        pr.settings.verbose = False
        pr.continuation_stepper.ds = DS0
        pr.continuation_stepper.ds_max = DS_MAX
        lam_max = 0.0
        # bice grows its step by only 1.1 per step and measures it in the
        # full state norm, so it needs more steps: run until the fold is
        # located (or lam turns back), at most 10x our step budget.
        for _ in range(10 * STEPS):
            pr.continuation_step()
            lam_max = max(lam_max, pr.bratu.lam)
            folds = [s.p for s in pr.bifurcation_diagram.active_branch.bifurcations()]
            if folds or pr.bratu.lam < lam_max - 1e-3:
                break
        return folds[0] if folds else lam_max

    return run, base.n


# ------------------------------------------------------------------ scipy baseline
def scipy_natural(nodes, tol=1e-8):
    from scipy.integrate import solve_bvp

    x = np.linspace(0.0, 1.0, nodes)

    def run():
        y = np.zeros((2, x.size))
        lam, dlam = 0.0, 0.25
        mesh = x
        # Halve the step on failure; stop when it drops below 1e-7 (the
        # natural parameter cannot pass the fold, only approach it).
        while dlam > 1e-7:
            trial = lam + dlam

            def f(t, yy, trial=trial):
                return np.vstack([yy[1], -trial * np.exp(yy[0])])

            def bc(ya, yb):
                return np.array([ya[0], yb[0]])

            sol = solve_bvp(f, bc, mesh, y, tol=tol, max_nodes=5000)
            if sol.success and np.max(np.abs(sol.y[0])) < 50:
                lam, mesh, y = trial, sol.x, sol.y
            else:
                dlam /= 2
        return lam

    return run, 2 * nodes


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="fewer resolutions")
    args = ap.parse_args(argv)
    rows, skipped = [], []

    def add(name, factory, *a):
        try:
            run, n = factory(*a)
            run()  # warm-up (imports, caches); not timed
            val, t = timed(run, args.repeats)
            rows.append((name, n, abs(val - LAM_STAR), t))
        except Exception as exc:  # a peer that cannot run is reported, not fatal
            skipped.append(f"{name}: {type(exc).__name__}: {exc}")

    for N in ([16, 24] if args.quick else [12, 16, 20, 24, 32]):
        add(f"continuation, Chebyshev N={N}", ours, N, "chebyshev")
    for N in ([40] if args.quick else [20, 40, 80]):
        add(f"continuation, FD N={N}", ours, N, "fd")
    try:
        import bifpy  # noqa: F401

        for ntst in ([5, 10] if args.quick else [5, 10, 20]):
            add(f"AUTO-07p (bifpy) NTST={ntst} NCOL=4", auto07p, ntst)
        for ntst in ([10] if args.quick else [5, 10, 20]):
            # Native executable compiled from the traced model (cached after
            # the untimed warm-up run): AUTO's fastest bifpy path.
            add(f"AUTO-07p (bifpy, transpile=True) NTST={ntst} NCOL=4", auto07p, ntst,
                4, STEPS, True)
        add("AUTO-07p (bifpy) start-up only (NMX=2, no fold)", auto07p_startup)
    except ImportError as exc:
        skipped.append(f"AUTO-07p (bifpy): not installed ({exc}); pip install bifpy "
                       "(needs gfortran: apt-get install gfortran)")
    try:
        import bice  # noqa: F401

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for N in ([24] if args.quick else [16, 24]):
                add(f"bice, Chebyshev N={N}", bice_run, N)
    except ImportError as exc:
        skipped.append(f"bice: not installed ({exc}); pip install bice")
    for nodes in ([21] if args.quick else [11, 41]):
        add(f"scipy solve_bvp natural, {nodes} initial nodes", scipy_natural, nodes)

    ref = next((r[3] for r in rows if r[0] == "continuation, Chebyshev N=24"), None)
    print(f"Bratu fold lam* = {LAM_STAR!r}; median of {args.repeats} runs; "
          f"python {sys.version.split()[0]}")
    print()
    print("| method | unknowns | fold error | wall time [s] | time / ours (Cheb N=24) |")
    print("|---|---:|---:|---:|---:|")
    for name, n, err, t in rows:
        ratio = f"{t / ref:.1f}" if ref else "-"
        e = "-" if np.isnan(err) else f"{err:.1e}"
        print(f"| {name} | {n} | {e} | {t:.4f} | {ratio} |")
    for s in skipped:
        print(f"\nskipped: {s}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
