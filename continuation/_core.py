"""Pseudo-arclength continuation driver, special-point location and branch switching.

References
----------
- H. B. Keller, "Numerical solution of bifurcation and nonlinear eigenvalue
  problems" (1977): pseudo-arclength continuation with bordered systems.
- W. Govaerts, *Numerical Methods for Bifurcations of Dynamical Equilibria*
  (SIAM, 2000): minimally augmented systems for folds, bordered test functions.
- E. Doedel, AUTO-07p manual: branch switching through the algebraic
  bifurcation equation; step control.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping

import numpy as np
import scipy.optimize as sopt

from . import _branch as B
from ._branch import Branch, SpecialPoint, package_version
from ._linalg import bordered, factorize, inertia_negative
from ._problem import Evaluator, check_jacobian
from ._settings import ContinuationSettings

#: Largest residual ratio between consecutive chord iterations (:meth:`_Core.chord`): a
#: slower iteration is abandoned for the full Newton corrector.
CHORD_RATE = 0.25

# Branch-point test function borders: fixed pseudo-random vectors, so results
# are reproducible; any vectors not orthogonal to the kernels work.
_BORDER_SEED = 20240611

# Relative finite-difference step for second derivatives (directional
# derivatives of the Jacobian): eps**(1/3) balances truncation and rounding.
_FD2 = np.finfo(float).eps ** (1.0 / 3.0)


class _Corrected:
    __slots__ = ("x", "iters", "fac", "ok", "reason", "normF")

    def __init__(self, x, iters, fac, ok, reason, normF):
        self.x, self.iters, self.fac, self.ok, self.reason, self.normF = (
            x, iters, fac, ok, reason, normF)


class _Core:
    """Configuration + numerical kernels shared by the driver and the locators."""

    def __init__(self, ev: Evaluator, settings: ContinuationSettings, n: int):
        self.ev, self.s, self.n = ev, settings, n
        self.wu = settings.theta / n
        self.wp = 1.0 - settings.theta
        rng = np.random.default_rng(_BORDER_SEED)
        self.bb = rng.standard_normal(n + 1)
        self.bc = rng.standard_normal(n + 1)

    # -------------------------------------------------------------- weighted norm
    def dot(self, a, b) -> float:
        n = self.n
        return self.wu * float(a[:n] @ b[:n]) + self.wp * float(a[n] * b[n])

    def normalize(self, t):
        return t / math.sqrt(self.dot(t, t))

    def wrow(self, t):
        r = np.empty_like(t)
        r[: self.n] = self.wu * t[: self.n]
        r[self.n] = self.wp * t[self.n]
        return r

    # -------------------------------------------------------------- bordered matrix
    def bmatrix(self, x, row):
        n = self.n
        u, p = x[:n], x[n]
        return bordered(self.ev.J(u, p), self.ev.Fp(u, p), row[:n], row[n])

    # -------------------------------------------------------------- Newton corrector
    def correct(self, x0, row, c, moore_penrose=False, tol=None, max_iter=None) -> _Corrected:
        """Newton on ``F(x) = 0, row . x = c`` (one bordered LU per iteration).

        With ``moore_penrose`` the row is replaced at each iteration by the
        current tangent and the constraint by orthogonality of the update.
        """
        s = self.s
        tol = s.newton_tol if tol is None else tol
        max_iter = s.max_newton if max_iter is None else max_iter
        n = self.n
        x = x0.copy()
        fac = None
        prev = math.inf
        best_x, best_norm = x, math.inf
        rhs = np.empty(n + 1)
        for it in range(max_iter + 1):
            u, p = x[:n], x[n]
            F = self.ev.F(u, p)
            normF = float(np.abs(F).max()) if F.size else 0.0
            if not math.isfinite(normF):
                return _Corrected(x, it, None, False, "non-finite residual", normF)
            arc_ok = moore_penrose or abs(float(row @ x - c)) <= 1e-8 * (1.0 + abs(c))
            if normF < best_norm and arc_ok:
                best_x, best_norm = x, normF
            arc = 0.0 if moore_penrose else float(row @ x - c)
            if normF <= tol and abs(arc) <= tol * (1.0 + abs(c)):
                return _Corrected(x, it, fac, True, "", normF)
            # On failure the best iterate (smallest residual on the arclength constraint) is
            # returned with its residual: near a branch point the bordered matrix is nearly
            # singular and rounding makes Newton wander after reaching ~10 newton_tol, which
            # is accurate enough to locate special points (see _point_at).
            if it == max_iter:
                return _Corrected(best_x, it, fac, False,
                                  f"Newton did not converge in {max_iter} iterations "
                                  f"(max|F|={normF:.2e} > newton_tol={tol:.1e})", best_norm)
            # Quadratic convergence from a tangent predictor never lets the
            # residual grow after the first iteration: growth means divergence.
            if it >= 2 and normF > prev:
                return _Corrected(best_x, it, fac, False,
                                  f"Newton diverging (max|F| grew {prev:.2e} -> {normF:.2e})",
                                  best_norm)
            prev = normF
            A = bordered(self.ev.J(u, p), self.ev.Fp(u, p), row[:n], row[n])
            fac = factorize(A)
            if fac is None:
                return _Corrected(x, it, None, False, "singular bordered Jacobian", normF)
            rhs[:n] = -F
            rhs[n] = -arc
            dx = fac.solve(rhs)
            if moore_penrose:
                e = np.zeros(n + 1)
                e[n] = 1.0
                tnew = self.normalize(fac.solve(e))
                row = self.wrow(tnew)
            x = x + dx
            # Step criterion: when rounding keeps max|F| above an absolute
            # newton_tol (large states, stiff operators), an update below
            # newton_tol relative to the state means Newton has converged as
            # far as floating point allows.
            if float(np.abs(dx).max()) <= tol * (1.0 + float(np.abs(x).max())):
                return _Corrected(x, it + 1, fac, True, "", normF)
        raise AssertionError("unreachable")

    def chord(self, x0, row, c, fac, tol=None, xtol=None, max_iter=None) -> _Corrected:
        """Newton on ``F(x) = 0, row . x = c`` reusing the factorization ``fac`` (a bordered
        matrix with this row, near the solution) for as long as it serves: the chord
        (simplified Newton) iteration, one residual and one back-substitution per step.

        Any fixed nonsingular matrix leaves the solutions unchanged (they are the fixed
        points of ``x - A^-1 R(x)``); only the rate depends on how close ``A`` is to the
        Jacobian there. Where a step reduces max|F| by less than ``CHORD_RATE``, the bordered
        matrix is factorized afresh at the iterate of least residual (a Newton step), and
        the iteration goes on with the new factorization; where even a fresh one does not
        reduce it, the residual is at its round-off floor. The iteration stops at an update
        below ``xtol`` relative to the state (default: ``locate_tol``, so that the point
        is as accurate as the location it serves), or at the floor, and succeeds if it
        meets the corrector's own criteria there (``max|F| <= tol`` on the constraint, or
        a last update below ``tol`` relative to the state). Otherwise (``ok`` False, e.g.
        no contraction from a poor start, ``max_iter`` residuals) the caller runs the full
        corrector. The returned ``fac`` is the last factorization used.
        """
        s = self.s
        tol = s.newton_tol if tol is None else tol
        xtol = s.locate_tol if xtol is None else xtol
        max_iter = 4 * s.max_newton if max_iter is None else max_iter
        n = self.n
        x = x0.copy()
        rhs = np.empty(n + 1)
        prev = math.inf
        best_x, best_norm, best_F, best_arc = None, math.inf, None, 0.0
        fresh = False  # whether the last step was taken with a factorization made for it
        step = normF = math.inf
        it = 0
        for it in range(1, max_iter + 1):
            F = self.ev.F(x[:n], x[n])
            normF = float(np.abs(F).max()) if F.size else 0.0
            if not math.isfinite(normF):
                break
            arc = float(row @ x - c)
            if normF < best_norm and abs(arc) <= 1e-8 * (1.0 + abs(c)):
                best_x, best_norm, best_F, best_arc = x, normF, F, arc
            if normF > CHORD_RATE * prev:
                if fresh or best_x is None:
                    break  # the round-off floor (or no progress from the start)
                fac = factorize(self.bmatrix(best_x, row))
                if fac is None:
                    break
                x, F, arc, normF, fresh = best_x, best_F, best_arc, best_norm, True
            else:
                fresh = False
            prev = normF
            rhs[:n] = -F
            rhs[n] = -arc
            dx = fac.solve(rhs)
            x = x + dx
            step = float(np.abs(dx).max()) / (1.0 + float(np.abs(x).max()))
            if step <= xtol:
                return _Corrected(x, it, fac, True, "", normF)
        if best_x is not None and (best_norm <= tol and abs(best_arc) <= tol * (1.0 + abs(c))
                                   or step <= tol):
            return _Corrected(best_x, it, fac, True, "", best_norm)
        return _Corrected(x0, it, fac, False, "chord iteration not contracting", normF)

    def tangent_from(self, fac, t_ref=None):
        """Unit tangent from a bordered factorization whose last row is ``W t_ref``."""
        e = np.zeros(self.n + 1)
        e[self.n] = 1.0
        t = self.normalize(fac.solve(e))
        return t

    # -------------------------------------------------------------- observations
    def observe(self, u, p):
        ev, s = self.ev, self.s
        obs = ev.observables(u, p) if ev.observables is not None else {}
        stab = -1
        if s.compute_stability and ev.hessian is not None:
            C = ev.constraint_jacobian(u, p) if ev.constraint_jacobian is not None else None
            stab = inertia_negative(ev.hessian(u, p), C)
        return obs, stab

    def bp_test(self, x, row, b, c):
        """Bordered test function for branch points and the kernel vectors.

        Solves ``[[A, b], [c^T, 0]] [phi; tau] = [0; 1]`` with
        ``A = [[J, F_p], [row]]``: ``tau`` is smooth, vanishes exactly where
        ``A`` is singular, and there ``phi`` spans the kernel of ``A``
        (Govaerts 2000, sec. 3.4); well defined at the branch point itself,
        unlike ``det A``. ``b, c`` must approximate the left and right kernel
        vectors (see :meth:`kernel_guess`): with arbitrary borders ``tau`` has
        poles near the zero.

        Returns ``(tau, phi, psi)`` with ``psi`` the left kernel vector
        (transpose system), or ``(nan, None, None)`` if the bordered matrix is
        singular.
        """
        A = self.bmatrix(x, row)
        M = bordered(A, b, c, 0.0)
        fac = factorize(M)
        if fac is None:
            return math.nan, None, None
        e = np.zeros(self.n + 2)
        e[-1] = 1.0
        y = fac.solve(e)
        z = fac.solve(e, trans=True)
        return float(y[-1]), y[:-1], z[:-1]

    def kernel_guess(self, x, row):
        """Right and left near-kernel vectors of ``A`` by two inverse iterations."""
        fac = factorize(self.bmatrix(x, row))
        if fac is None:
            return None
        r, l_ = self.bb.copy(), self.bc.copy()
        for _ in range(2):
            r = fac.solve(r)
            r /= np.linalg.norm(r)
            l_ = fac.solve(l_, trans=True)
            l_ /= np.linalg.norm(l_)
        return l_, r


# ================================================================== fold location
def fold_system(ev, u, p, b, c):
    """Solve ``[[J, b], [c^T, 0]] [v; g] = [0; 1]`` and its transpose.

    Returns ``g, v, w, J`` with ``g`` the minimally augmented fold test function
    (``g = 0`` iff ``J`` is singular, Govaerts 2000, sec. 4.2).
    """
    n = u.size
    J = ev.J(u, p)
    M = bordered(J, b, c, 0.0)
    fac = factorize(M)
    if fac is None:
        return None
    e = np.zeros(n + 1)
    e[n] = 1.0
    sv = fac.solve(e)
    sw = fac.solve(e, trans=True)
    return sv[n], sv[:n], sw[:n], J


def fold_gradient(ev, u, p, v, w, q_family=None):
    """``g_u = -w^T J_u v`` and ``g_p = -w^T J_p v`` by central differences.

    ``d/du (w^T J(u) v) = d/dh J(u + h v)^T w`` at h = 0, so two Jacobian
    evaluations give the whole gradient.
    """
    h = _FD2 * (1.0 + float(np.abs(u).max())) / max(float(np.abs(v).max()), 1e-300)
    Jp = ev.J(u + h * v, p)
    Jm = ev.J(u - h * v, p)
    gu = -np.asarray(Jp.T @ w - Jm.T @ w).ravel() / (2.0 * h)
    gp = -float(w @ (ev.Fp(u + h * v, p) - ev.Fp(u - h * v, p))) / (2.0 * h)
    return gu, gp


def _locate_fold(ev, u, p, v0, tol, max_iter=25, ftol=1e-10):
    """Newton on the minimally augmented system ``F = 0, g = 0``.

    Returns ``(u, p, v, converged, precision, iterations, message)``.
    """
    n = u.size
    u = u.copy()
    c = v0[:n] / np.linalg.norm(v0[:n])
    b = c.copy()
    # One transpose solve turns the right null guess into a left one, so the
    # bordered matrix stays well conditioned for non-symmetric J.
    r = fold_system(ev, u, p, b, c)
    if r is None:
        return u, p, c, False, math.inf, 0, "singular bordered matrix at the fold guess"
    _, v, w, _ = r
    if np.linalg.norm(w) > 0:
        b = w / np.linalg.norm(w)
    prec = math.inf
    for it in range(1, max_iter + 1):
        r = fold_system(ev, u, p, b, c)
        if r is None:
            return u, p, c, False, prec, it, "singular bordered matrix during fold Newton"
        g, v, w, J = r
        F = ev.F(u, p)
        Fp = ev.Fp(u, p)
        gu, gp = fold_gradient(ev, u, p, v, w)
        A = bordered(J, Fp, gu, gp)
        fac = factorize(A)
        if fac is None:
            return u, p, v, False, prec, it, "singular fold Jacobian (a cusp or a degenerate fold?)"
        dx = fac.solve(-np.concatenate([F, [g]]))
        if not np.all(np.isfinite(dx)):
            return u, p, v, False, prec, it, "non-finite Newton update in fold location"
        u = u + dx[:n]
        p = p + dx[n]
        prec = abs(dx[n])
        if np.abs(dx).max() <= tol * (1.0 + max(np.abs(u).max(), abs(p))):
            return u, p, v / np.linalg.norm(v), True, prec, it, ""
        # With finite-difference Jacobians the u-update stalls at rounding
        # noise while p has converged: accept once F is at the Newton
        # tolerance and p no longer moves.
        if (it >= 3 and float(np.abs(F).max()) <= ftol
                and prec <= tol * (1.0 + abs(p))):
            return u, p, v / np.linalg.norm(v), True, prec, it, ""
    return u, p, c, False, prec, max_iter, (
        f"fold Newton did not converge in {max_iter} iterations (last |dp|={prec:.1e})")


def locate_fold(problem, u, p, v=None, tol: float = 1e-12, max_iter: int = 25) -> SpecialPoint:
    """Locate a fold (limit point) of ``F(u, p) = 0`` near ``(u, p)``.

    Newton's method on the minimally augmented system ``F(u, p) = 0,
    g(u, p) = 0`` where ``g`` solves ``[[J, b], [c^T, 0]] [v; g] = [0; 1]``
    (Govaerts 2000, sec. 4.2; BifurcationKit's ``newton_fold``). Converges
    quadratically; the result solves the discrete problem to rounding error.

    Parameters
    ----------
    problem : Problem
    u : ndarray, shape (n,)
        Guess of the state at the fold (e.g. the branch point nearest the fold).
    p : float
        Guess of the parameter.
    v : ndarray, shape (n,) or (n + 1,), optional
        Guess of the null vector of dF/du (e.g. a branch tangent near the
        fold); default: the tangent of the branch through ``(u, p)``.
    tol : float
        Stop when the Newton update is below ``tol * (1 + max|x|)``.
    max_iter : int

    Returns
    -------
    SpecialPoint
        ``kind="fold"``; ``located`` says whether Newton converged; ``data``
        holds ``kernel`` (the null vector), ``iterations`` and ``message``.
    """
    ev = Evaluator(problem)
    ev.warn_if_fd()
    u = np.asarray(u, dtype=float)
    p = float(p)
    if v is None:
        v = _start_tangent(ev, u, p)[0]
        if v is None:
            v = np.ones(u.size)
    v = np.asarray(v, dtype=float)
    uf, pf, kern, ok, prec, its, msg = _locate_fold(ev, u, p, v, tol, max_iter)
    return SpecialPoint("fold", -1, float(pf), uf, prec, ok, "",
                        {"kernel": kern, "iterations": its, "message": msg})


def _start_tangent(ev, u, p):
    """Tangent at a solution, robust to a singular dF/du (start at a fold).

    Returns ``(t, message)``; ``t`` is None for a singular start (the null
    space of ``[dF/du, dF/dp]`` has dimension >= 2).
    """
    n = u.size
    J = ev.J(u, p)
    Fp = ev.Fp(u, p)
    e = np.zeros(n + 1)
    e[n] = 1.0
    fac = factorize(bordered(J, Fp, np.zeros(n), 1.0))
    if fac is not None:
        t = fac.solve(e)
        if np.all(np.isfinite(t)) and np.max(np.abs(t)) < 1e12:
            return t, ""
    # dF/du singular: the null vector of the n x (n+1) matrix [J, F_p] by SVD.
    Jd = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    Ext = np.hstack([Jd, Fp.reshape(n, 1)])
    bad = int(np.count_nonzero(~np.isfinite(Ext)))
    if bad:
        return None, (
            f"the start has {bad} non-finite entries in [dF/du, dF/dp] (NaN or inf): the "
            "problem is not differentiable there. Check u0 and p0 against the problem's "
            "domain.")
    try:
        _, sv, Vt = np.linalg.svd(Ext)
    except np.linalg.LinAlgError as err:
        return None, (f"the start's tangent could not be computed: the SVD of "
                      f"[dF/du, dF/dp] failed ({err}). Try a slightly different p0.")
    smax = sv[0] if sv.size else 0.0
    # A rank deficiency of [J, F_p] (second-smallest singular value of the
    # square completion below 1e-8 of the largest) means a branch point or a
    # degenerate start: the tangent is not unique.
    if smax == 0.0 or sv[-1] <= 1e-8 * smax:
        return None, (
            f"the start is singular: [dF/du, dF/dp] has rank < n (smallest singular value "
            f"{(sv[-1] if sv.size else 0.0):.2e}, largest {smax:.2e}), so the tangent is not "
            "unique (a branch point or a degenerate solution). Try starting at a slightly "
            "different p0, or use switch_branch from a computed branch.")
    return Vt[-1], ""


# ================================================================== the driver
class _Run:
    """Mutable state of one continuation run in one direction."""

    def __init__(self, core: _Core, events, stop_on, callback):
        self.core = core
        self.events = events
        self.stop_on = stop_on
        self.callback = callback
        self.p, self.u, self.t, self.ds, self.it, self.stab = [], [], [], [], [], []
        self.det, self.obs, self.ev_vals = [], [], []
        # slopes of the events' values (entries) along the tangent (event_dips, event_steps)
        self.ev_slopes = []
        self.sps: list[SpecialPoint] = []
        # factorization of the last step's bordered matrix (the row of the tangent at the
        # point before it), near the step's end: reused to locate events on the step
        self.fac = None
        self.status = B.MAX_STEPS
        self.message = ""

    def add(self, x, t, ds, its, det_sign):
        n = self.core.n
        obs, stab = self.core.observe(x[:n], x[n])
        self.p.append(float(x[n]))
        self.u.append(x[:n].copy())
        self.t.append(t.copy())
        self.ds.append(ds)
        self.it.append(its)
        self.stab.append(stab)
        self.det.append(det_sign)
        self.obs.append(obs)
        self.ev_vals.append({k: _event_value(g(x[:n], x[n])) for k, g in self.events.items()})
        st = self.core.s
        if (st.event_dips and st.locate or st.event_steps) and self.events:
            self.ev_slopes.append(_event_slopes(self.core, self.events, self.ev_vals[-1],
                                                x, t))


#: Forward-difference step of the events' slopes (:func:`_event_slopes`), relative to
#: 1 + |x| in the weighted norm: ~sqrt(eps), the usual balance of truncation and rounding.
_EVENT_FD = 1.5e-8


def _event_slopes(core, events, vals, x, t) -> dict:
    """{name: d(entries)/ds along the unit tangent ``t`` at ``x``} of each event (a 1-entry
    array for a scalar one), by a forward difference; ``vals`` its values at ``x``
    (:func:`_event_value`). Entries not finite at either point give non-finite slopes,
    which :func:`_event_dip` leaves out."""
    n = core.n
    h = _EVENT_FD * (1.0 + math.sqrt(core.dot(x, x)))
    xh = x + h * t
    out = {}
    for name, g in events.items():
        v0, e0 = vals[name]
        v1, e1 = _event_value(g(xh[:n], xh[n]))
        a0 = np.array([v0]) if e0 is None else e0
        a1 = np.array([v1]) if e1 is None else e1
        if a0.shape != a1.shape:
            out[name] = None
            continue
        with np.errstate(invalid="ignore", over="ignore"):
            out[name] = (a1 - a0) / h
    return out


def _p_reversed(pa, pb, dpa, dpb) -> bool:
    """Whether a step from p = pa to pb moved against dp/ds at both of its ends (dpa and
    dpb of one sign): p then turned twice inside the step, at two folds that the sign
    test of dp/ds cannot see. Round-off-level moves (1e-12 relative) do not count."""
    move = pb - pa
    return (dpa * dpb > 0.0 and move * dpa < 0.0
            and abs(move) > 1e-12 * (1.0 + abs(pa)))


def _fold_approach_step(ds, ds_used, dpa, dpb, ds_min) -> float:
    """The next step length after a step of ``ds_used`` along which dp/ds went from
    ``dpa`` to ``dpb`` (one sign, falling by more than half): at most twice the distance
    to the zero of the linear extrapolation of dp/ds (one distance past it), and at least
    ds_used / 20 (the step shrinks by at most 20 at a time)."""
    if not (dpa * dpb > 0.0 and abs(dpb) < 0.5 * abs(dpa)):
        return ds
    to_zero = ds_used * abs(dpb) / (abs(dpa) - abs(dpb))
    return max(min(ds, 2.0 * to_zero), ds_used / 20.0, ds_min)


def _event_reach(vals, slopes) -> float:
    """Arclength from a point where the events have values ``vals`` and slopes along the
    tangent ``slopes`` (:func:`_event_slopes`) to the nearest zero of their linear
    extrapolation (inf if none): positive (the least entry above 0), the first entry to
    reach 0; negative, the last negative entry to rise through 0, where each of them
    rises."""
    reach = math.inf
    for name, (g, e) in vals.items():
        sl = slopes.get(name)
        if sl is None or g == 0.0 or not math.isfinite(g):
            continue
        e = np.array([g]) if e is None else e
        with np.errstate(invalid="ignore", divide="ignore"):
            if g > 0.0:
                go = np.isfinite(e) & np.isfinite(sl) & (sl < 0.0)
                if go.any():
                    reach = min(reach, float(np.min(e[go] / -sl[go])))
            else:
                neg = e < 0.0
                if np.all(np.isfinite(sl[neg]) & (sl[neg] > 0.0)):
                    reach = min(reach, float(np.max(-e[neg] / sl[neg])))
    return reach


def _event_approach_step(ds, ds_used, reach, ds_min) -> float:
    """The next step length where an event's predicted zero is ``reach`` away
    (:func:`_event_reach`): at most twice that (one distance past it), and at least
    ds_used / 20, as for a fold (:func:`_fold_approach_step`)."""
    if not reach < 0.5 * ds:
        return ds
    return max(2.0 * reach, ds_used / 20.0, ds_min)


def _jumped(core, x, t, x_new, t_new, ds, fac) -> bool:
    """Whether a step of ``ds`` from ``x`` (tangent ``t``) to ``x_new`` (``t_new``) is not
    one arc of the branch: the point at its middle, corrected on the hyperplane normal to
    ``t`` from the cubic through the ends and their tangents (chord iterations on the
    step's factorization ``fac``), fails or lies farther than ds / 2 from that cubic."""
    guess = 0.5 * (x + x_new) + 0.125 * ds * (t - t_new)
    r = _point_at(core, x, t, 0.5 * ds, guess=guess, fac=fac)
    if not r.ok:
        return True
    d = r.x - guess
    return math.sqrt(core.dot(d, d)) > 0.5 * ds


def _run_direction(core: _Core, x0, t0, det0, events, stop_on, callback, skip_first=False):
    s = core.s
    n = core.n
    run = _Run(core, events, stop_on, callback)
    run.add(x0, t0, 0.0, 0, det0)
    x, t = x0.copy(), t0.copy()
    ds = s.ds0
    cos_turn = math.cos(s.max_turn)
    mp = s.corrector == "moore-penrose"
    hook = getattr(core.ev.problem, "_on_accept", None)

    def event_reach():
        # the arclength from the last point to the events' nearest predicted zero
        # (event_steps), once per point
        return (_event_reach(run.ev_vals[-1], run.ev_slopes[-1])
                if s.event_steps and run.ev_slopes else math.inf)

    reach = event_reach()
    for step in range(1, s.max_steps + 1):
        # ---- predictor-corrector with step rejection
        last_reason = ""
        while True:
            x_pred = x + ds * t
            row = core.wrow(t)
            res = core.correct(x_pred, row, float(row @ x_pred), moore_penrose=mp)
            if res.ok:
                fac = res.fac
                if fac is None:  # predictor exact: factorize once for the tangent
                    fac = factorize(core.bmatrix(res.x, row))
                if fac is None:
                    res.ok, res.reason = False, "singular bordered Jacobian at the new point"
                else:
                    t_new = core.tangent_from(fac)
                    if core.dot(t_new, t) < 0:  # only possible with Moore-Penrose rows
                        t_new = -t_new
                    if core.dot(t_new, t) < cos_turn:
                        res.ok = False
                        res.reason = (f"tangent turned by "
                                      f"{math.degrees(math.acos(min(1, core.dot(t_new, t)))):.1f}"
                                      f" deg > max_turn")
                    elif _p_reversed(x[n], res.x[n], t[n], t_new[n]):
                        # p moved against dp/ds at both ends: an even number of folds
                        # inside the step (an S near a cusp), invisible to the sign test
                        res.ok = False
                        res.reason = "p reversed within the step (two folds inside it)"
                    elif reach < ds and _jumped(core, x, t, res.x, t_new, ds, fac):
                        # an event predicted inside the step: a corrector that jumps to
                        # another part of the branch there sees it at neither end
                        res.ok = False
                        res.reason = "the step's middle is off its arc (a jump)"
            if res.ok:
                break
            last_reason = res.reason
            ds *= s.step_shrink
            if ds < s.ds_min:
                if last_reason == "non-finite residual":
                    run.status = B.NON_FINITE
                    run.message = (
                        f"step {step}: the residual is NaN/inf just beyond p={x[n]:.12g} even "
                        f"at ds_min={s.ds_min:.1e}: the problem leaves its domain there. Try "
                        "p_min/p_max to stop before it, or check the residual for overflow.")
                else:
                    run.status = B.STEP_TOO_SMALL
                    run.message = (
                        f"step {step}: corrector failed at ds_min={s.ds_min:.1e} near p="
                        f"{x[n]:.12g} ({last_reason}). Try a smaller ds_min, a larger "
                        "max_newton, a looser newton_tol, or check the Jacobian "
                        "(check_jacobian=True).")
                return run
        x_new = res.x
        det_new = fac.det_sign()
        # ---- parameter bounds: end exactly on the bound
        bound = None
        if x_new[n] > s.p_max:
            bound = s.p_max
        elif x_new[n] < s.p_min:
            bound = s.p_min
        if bound is not None:
            a = (bound - x[n]) / (x_new[n] - x[n])
            xg = x + a * (x_new - x)
            e = np.zeros(n + 1)
            e[n] = 1.0
            rb = core.correct(xg, e, bound)
            if not rb.ok or abs(bound - x[n]) <= 1e-14 * (1 + abs(bound)):
                run.status = B.PARAMETER_BOUND
                run.message = (f"reached the parameter bound {bound!r} (p={x[n]:.10g}; the point "
                               "on the bound itself was not computed: "
                               f"{rb.reason or 'start already on the bound'}).")
                return run
            x_new = rb.x
            fb = factorize(core.bmatrix(x_new, core.wrow(t)))
            t_new = core.tangent_from(fb) if fb is not None else t_new
            det_new = fb.det_sign() if fb is not None else det_new
            fac = fb
        run.fac = fac
        run.add(x_new, t_new, ds, res.iters, det_new)
        k = len(run.p) - 1
        if hook is not None:  # e.g. FoldProblem refreshes its borders
            hook(x_new[:n], x_new[n])
        _detect(core, run, k, skip_first=(skip_first and k == 1))
        stop = None
        for sp_ in run.sps:
            if sp_.kind == "event" and sp_.index == k and sp_.name in stop_on:
                stop = sp_
        # a terminal event on the step that was cut back onto a bound lies before the bound
        # along the step: it ends the run, so that a caller restarting at events sees it
        if stop is not None:
            run.status = B.STOPPED
            run.message = f"terminal event {stop.name!r} at p={stop.p:.12g}."
            return run
        if bound is not None:
            run.status = B.PARAMETER_BOUND
            run.message = f"reached the parameter bound p={bound!r}."
            return run
        if callback is not None:
            info = {"step": step, "p": x_new[n], "u": x_new[:n], "ds": ds,
                    "newton_iterations": res.iters, "stability": run.stab[-1]}
            if callback(info) is False:
                run.status = B.STOPPED
                run.message = f"stopped by the callback at step {step} (p={x_new[n]:.10g})."
                return run
        # ---- closed loop (isola): back at the start, heading the same way
        if step > 3 and math.sqrt(core.dot(x_new - x0, x_new - x0)) < 0.5 * ds \
                and core.dot(t_new, t0) > 0.9:
            run.status = B.LOOP_CLOSED
            run.message = f"the branch closed on itself after {step} steps (an isola)."
            return run
        # ---- adapt the step: grow after easy convergence
        ds_used = ds
        if res.iters <= s.newton_easy:
            ds = min(ds * s.step_grow, s.ds_max)
        # ... and approach a fold: where dp/ds falls towards zero, the next step ends at
        # most one predicted distance past the zero of its linear extrapolation, so that
        # a fold (or the two folds of an S next to a cusp, which a longer step could
        # cross at once) is bracketed step by step
        ds = _fold_approach_step(ds, ds_used, t[n], t_new[n], s.ds_min)
        # ... and likewise an event's zero, predicted from its value and slope at the new
        # point: a longer step could pass over a stretch where it has the other sign
        reach = event_reach()
        ds = _event_approach_step(ds, ds_used, reach, s.ds_min)
        x, t = x_new, t_new
    run.status = B.MAX_STEPS
    run.message = (f"reached max_steps={s.max_steps} at p={x[n]:.10g}. Try increasing "
                   "max_steps or ds_max, or set p_min/p_max to stop at a parameter value.")
    return run


# Near a branch point the bordered matrix is nearly singular and the residual's round-off
# floor rises above a tight newton_tol (measured: 3e-11 against 1e-11 on the elastica with a
# drop); a point whose residual stalls within this factor of the tolerance is as accurate as
# the arithmetic allows, and is accepted for locating special points.
_LOCATE_STALL_FACTOR = 30.0


def _point_at(core, x_a, t_a, s_arc, guess=None, fac=None):
    """Corrected point at arclength ``s_arc`` from ``x_a`` along ``t_a`` (Newton on the
    hyperplane through ``x_a + s_arc t_a`` normal to ``t_a``, started from ``guess`` when
    given, else from that predictor). With ``fac`` (a factorization of the bordered
    matrix of that hyperplane near the point) the chord iteration is tried first, and
    full Newton runs only where it does not contract."""
    row = core.wrow(t_a)
    xp = x_a + s_arc * t_a
    x0 = xp if guess is None else guess
    c = float(row @ xp)
    if fac is not None:
        r = core.chord(x0, row, c, fac, tol=core.s.newton_tol)
        if r.ok:
            return r
    r = core.correct(x0, row, c, tol=core.s.newton_tol, max_iter=2 * core.s.max_newton)
    if not r.ok and r.normF <= _LOCATE_STALL_FACTOR * core.s.newton_tol:
        r.ok = True
    return r


def _bisect_on_arc(core, run, k, func, fa, fb, chord=False, end=None, start=None):
    """Root of ``func(x)`` between points k-1 and k, by Brent's method in arclength.

    The points on the arc are corrected on the hyperplanes normal to the tangent at k-1,
    the rows of the step's own corrector; with ``chord`` its last factorization
    (``run.fac``) serves their chord iterations (:meth:`_Core.chord`). ``end``: a point
    of the step's arc (corrected on one of those hyperplanes, e.g. a located event) that
    bounds the bracket instead of point k; ``start`` (likewise, where ``func`` is ``fa``)
    instead of point k-1. Not for branch
    points: there the bordered matrix is singular, the chord iteration would refactorize
    at every point, and the corrected points are as ill-determined as the matrix is
    singular, so each corrector gives other ones (full Newton is kept there)."""
    xa = np.concatenate([run.u[k - 1], [run.p[k - 1]]])
    xb = np.concatenate([run.u[k], [run.p[k]]]) if end is None else np.asarray(end, float)
    ta = run.t[k - 1]
    sb = core.dot(xb - xa, ta)
    s0 = 0.0 if start is None else core.dot(np.asarray(start, float) - xa, ta)
    cache = {}
    # the factorization the points are corrected with: the step's own, then the last one
    # made while correcting them (nearer the root, where Brent's points close in)
    fac = [run.fac if chord else None]
    # corrected points by arclength: each new one starts from the nearest (Brent's points
    # close in on the root, so Newton starts ever closer to the solution it converges to)
    near = {0.0: xa, sb: xb}
    if start is not None:
        near[s0] = np.asarray(start, float)

    def f(sv):
        if sv == s0:
            return fa
        if sv == sb:
            return fb
        sn = min(near, key=lambda s: abs(s - sv))
        r = _point_at(core, xa, ta, sv, guess=near[sn] + (sv - sn) * ta, fac=fac[0])
        if not r.ok:
            raise _LocateError(r.reason)
        if chord and r.fac is not None:
            fac[0] = r.fac
        val = func(r.x)
        cache[sv] = (r.x, val)
        near[sv] = r.x
        return val

    xtol = core.s.locate_tol * max(1.0, abs(sb))
    try:
        sroot = sopt.brentq(f, s0, sb, xtol=xtol, rtol=4 * np.finfo(float).eps, maxiter=60)
    except (_LocateError, ValueError, RuntimeError):
        return None, abs(sb)
    if sroot in cache:
        return cache[sroot][0], xtol
    r = _point_at(core, xa, ta, sroot, fac=fac[0])
    return (r.x if r.ok else None), xtol


class _LocateError(Exception):
    pass


#: Offsets (in units of h) of the points through which :func:`_polish_on_arc` interpolates.
_POLISH_OFFSETS = np.array([-3.0, -2.0, -1.0, 1.0, 2.0, 3.0])
#: ... and h as a fraction of the bracketing step's arclength.
_POLISH_H = 5e-3


def _polish_on_arc(core, run, k, func, xr, prec):
    """Refine a root ``xr`` of a smooth test function (the branch-point test ``tau``) found
    by :func:`_bisect_on_arc`.

    At a branch point the corrector's bordered matrix is singular, so the points Brent
    evaluates next to the root are corrected only to the residual's round-off floor there
    (a few newton_tol; the point drifts along the kernel), and the root they give is off
    by ~1e-10 in p on the elastica. Here ``func`` and the point are instead interpolated
    (degree 5) through six points at arclength offsets of +-1, 2, 3 h from the root, with
    h = 5e-3 of the step: far enough that the corrector is well conditioned, near enough
    that the interpolation error (~h^6) is below round-off. Returns ``(x, precision)``,
    the precision being the difference in p from the root of the cubic through the four
    inner points (an estimate of the interpolation error); or the input when a point
    fails or the interpolated root is not unique.
    """
    xa = np.concatenate([run.u[k - 1], [run.p[k - 1]]])
    ta = run.t[k - 1]
    sb = core.dot(np.concatenate([run.u[k], [run.p[k]]]) - xa, ta)
    s0 = core.dot(xr - xa, ta)
    h = _POLISH_H * abs(sb)
    if not h > 0.0:
        return xr, prec
    ss = s0 + h * _POLISH_OFFSETS
    row = core.wrow(ta)
    xs, fs = [], []
    for sv in ss:
        # corrected to the round-off floor (1e-2 newton_tol, or as far as it goes below
        # newton_tol): the interpolation carries the points' errors into the root
        xp = xa + sv * ta
        r = core.correct(xp, row, float(row @ xp), tol=1e-2 * core.s.newton_tol,
                         max_iter=2 * core.s.max_newton)
        if not r.ok and r.normF <= core.s.newton_tol:
            r.ok = True
        if not r.ok:
            return xr, prec
        xs.append(r.x)
        fs.append(func(r.x))
    fs = np.array(fs)
    if not (np.all(np.isfinite(fs)) and fs[2] * fs[3] < 0):
        return xr, prec
    xs = np.array(xs)

    def interpolated_root(t, f, x):
        roots = np.roots(np.polyfit(t, f, len(t) - 1))
        roots = roots[(np.abs(roots.imag) < 1e-9) & (np.abs(roots.real) <= 1.0)].real
        if roots.size != 1:
            return None
        w = float(roots[0])
        # Lagrange weights of the point at offset w (the same interpolation)
        lw = np.array([np.prod([(w - t[m]) / (t[j] - t[m]) for m in range(len(t)) if m != j])
                       for j in range(len(t))])
        return lw @ x

    x = interpolated_root(_POLISH_OFFSETS, fs, xs)
    x3 = interpolated_root(_POLISH_OFFSETS[1:-1], fs[1:-1], xs[1:-1])
    if x is None or x3 is None:
        return xr, prec
    return x, max(abs(float(x[-1] - x3[-1])), 4 * np.finfo(float).eps * (1 + abs(x[-1])))


#: Slack of the bracket check of a located fold, relative to (1 + |p|): the fold's Newton
#: stops at locate_tol ~ 1e-12, so 1e-10 never rejects a correct fold.
FOLD_BRACKET_SLACK = 1e-10
#: ... and how far beyond the bracket a fold may lie, in bracket widths (p is quadratic
#: in s near a fold, so the extremum overshoots the bracketing values by a fraction of it).
FOLD_BRACKET_REACH = 10.0


def _fold_in_bracket(pf, slope, pa, pb, reach=0.0):
    """Whether ``pf`` can be the extremum of p on a continuation step from ``pa`` to ``pb``
    whose dp/ds at ``pa`` is ``slope``: a maximum (slope > 0) lies at or beyond both
    values, a minimum at or below both, and within FOLD_BRACKET_REACH step widths."""
    slack = FOLD_BRACKET_SLACK * (1.0 + abs(pf))
    span = max(abs(pb - pa), reach / FOLD_BRACKET_REACH) + 1e-12 * (1.0 + abs(pb))
    if slope > 0:
        return max(pa, pb) - slack <= pf <= max(pa, pb) + FOLD_BRACKET_REACH * span
    return min(pa, pb) - FOLD_BRACKET_REACH * span <= pf <= min(pa, pb) + slack


def _detect(core, run, k, skip_first=False):
    """Detect (and locate) special points between points k-1 and k.

    ``skip_first`` skips folds and branch points on this interval: used when
    point k-1 is itself a branch point (after switching), where both tests
    are ill-defined.
    """
    s = core.s
    n = core.n
    ta, tb = run.t[k - 1], run.t[k]
    # ---- folds: dp/ds changes sign
    # A sign change of dp/ds at rounding level (both |dp/ds| < 1e-13, e.g. on
    # an asymptote p -> 0) is noise, not a fold.
    if (s.detect_folds and not skip_first and ta[n] * tb[n] < 0
            and max(abs(ta[n]), abs(tb[n])) > 1e-13):
        j = k - 1 if abs(ta[n]) < abs(tb[n]) else k
        sp = SpecialPoint("fold", k, run.p[j], run.u[j].copy(),
                          abs(run.p[k] - run.p[k - 1]), False, "", {})
        if s.locate:
            # Newton from the end nearer the fold first, then from the other end: with two
            # folds within one step (near a cusp) the first can converge to the fold
            # outside the bracket.
            other = []
            for jj in (j, 2 * k - 1 - j):
                uf, pf, kern, ok, prec, its, msg = _locate_fold(
                    core.ev, run.u[jj], run.p[jj], run.t[jj], s.locate_tol,
                    ftol=s.newton_tol)
                sp.data["iterations"] = sp.data.get("iterations", 0) + its
                if msg:
                    sp.data["message"] = msg
                # the step's arclength bounds how far p can turn beyond the bracket values
                reach = run.ds[k] / math.sqrt(1.0 - s.theta)
                if ok and _fold_in_bracket(pf, ta[n], run.p[k - 1], run.p[k], reach):
                    sp.p, sp.u, sp.precision, sp.located = float(pf), uf, prec, True
                    sp.data["kernel"] = kern
                    obs, _ = core.observe(uf, pf)
                    sp.data["observables"] = obs
                    sp.data.pop("message", None)
                    break
                if ok:
                    other.append(float(pf))
            if not sp.located and other:
                lo, hi = sorted((run.p[k - 1], run.p[k]))
                sp.data["message"] = (
                    f"fold bracketed in [{lo:.12g}, {hi:.12g}] but its Newton converged to "
                    f"another fold at {other[0]:.12g} (two folds within one step, e.g. "
                    "near a cusp); reduce the continuation step")
        run.sps.append(sp)
    # ---- branch points: the bordered determinant changes sign
    if s.detect_branch_points and not skip_first and run.det[k - 1] * run.det[k] < 0:
        sp = SpecialPoint("branch_point", k, run.p[k], run.u[k].copy(),
                          abs(run.p[k] - run.p[k - 1]), False, "", {})
        if s.locate:
            row = core.wrow(ta)
            xa = np.concatenate([run.u[k - 1], [run.p[k - 1]]])
            xb = np.concatenate([run.u[k], [run.p[k]]])
            guess = core.kernel_guess(xb, row)
            xr = None
            if guess is not None:
                bl, cr = guess

                def tau(x):
                    return core.bp_test(x, row, bl, cr)[0]

                fa, fb = tau(xa), tau(xb)
                if fa * fb < 0:
                    xr, prec = _bisect_on_arc(core, run, k, tau, fa, fb)
                    if xr is not None:
                        xr, prec = _polish_on_arc(core, run, k, tau, xr, prec)
            if xr is None:
                # Fallback: bisection on the sign of det A (always brackets).
                def dets(x):
                    f = factorize(core.bmatrix(x, row))
                    return 0.0 if f is None else float(f.det_sign())

                xr, prec = _bisect_on_arc(core, run, k, dets, float(run.det[k - 1]),
                                          float(run.det[k]))
                guess = core.kernel_guess(xr, row) if xr is not None else None
            if xr is not None and guess is not None:
                tval, phi, psi = core.bp_test(xr, row, guess[0], guess[1])
                sp.p, sp.u, sp.precision, sp.located = float(xr[n]), xr[:n].copy(), prec, True
                if phi is not None:
                    sp.data["kernel"] = core.normalize(phi)
                    sp.data["left_kernel"] = psi[:n] / np.linalg.norm(psi[:n])
                sp.data["test_function"] = tval
                # The branch's own tangent at the point (bisected between the
                # bracketing tangents, which are close: the branch is smooth).
                sp.data["tangent"] = core.normalize(ta + tb)
        if "tangent" not in sp.data:
            sp.data["tangent"] = tb.copy()
        run.sps.append(sp)
    # ---- stability changes
    if run.stab[k - 1] >= 0 and run.stab[k] >= 0 and run.stab[k - 1] != run.stab[k]:
        sp = SpecialPoint(
            "stability", k, run.p[k], run.u[k].copy(), abs(run.p[k] - run.p[k - 1]), False,
            f"{run.stab[k - 1]} -> {run.stab[k]}",
            {"stability": [run.stab[k - 1], run.stab[k]]})
        # For a gradient problem the (projected) Hessian can only change
        # inertia where the Jacobian is singular: at a fold or branch point.
        # If one was located in the same interval, the change is there.
        for other in run.sps:
            if other.index == k and other.kind in ("fold", "branch_point") and other.located:
                sp.p, sp.u, sp.precision, sp.located = other.p, other.u, other.precision, True
                sp.data["at"] = other.kind
                break
        run.sps.append(sp)
    # ---- user events
    found = set()
    for name, g in run.events.items():
        (ga, va), (gb, vb) = run.ev_vals[k - 1][name], run.ev_vals[k][name]
        if ga * gb < 0 or (gb == 0 and ga != 0):
            found.add(name)
            run.sps.append(_event_point(core, run, k, name, g, ga, va, gb, vb))
    # An event of one sign at both ends that changes sign and back inside the step: a cubic
    # through its values and slopes at the ends says where it may, corrected points on the
    # step's arc confirm it (_event_dip). Measured on the strip (x = 4, n = 297, without
    # event_steps): a free node's gap negative over 0.013-0.015 in Delta, down to
    # -0.23 q h, inside one step of 0.017; compared at the ends only, the trace walked
    # through it.
    dips = []
    if s.locate and s.event_dips:
        for name, g in run.events.items():
            if name not in found:
                dip = _event_dip(core, run, k, name, g)
                if dip:
                    found.add(name)
                    dips.extend(dip)
        run.sps.extend(dips)
    # A terminal event inside the step ends the run at its root, where the step is cut:
    # an event whose function crosses 0 and back within the step has one sign at both of
    # the step's ends, yet changes sign between point k-1 and that root. Measured on the
    # strip (x = 4.5, n = 198): a reaction negative over 0.0068 in Delta inside a step of
    # 0.024, with a terminal corner in that interval; compared at the step's ends only,
    # the run stopped at the corner with the constraint violated and the lift-off unseen.
    stops = [sp for sp in run.sps if sp.kind == "event" and sp.index == k and sp.located
             and sp.name in run.stop_on]
    if not stops:
        return
    xa = np.concatenate([run.u[k - 1], [run.p[k - 1]]])
    cut = min((np.concatenate([sp.u, [sp.p]]) for sp in stops),
              key=lambda x: core.dot(x - xa, ta))
    # the roots of a dip past the terminal event's lie beyond the run's end
    s_cut = core.dot(cut - xa, ta)
    for sp in dips:
        if sp.located and core.dot(np.concatenate([sp.u, [sp.p]]) - xa, ta) > s_cut:
            run.sps.remove(sp)
    if not (s.locate and len(found) < len(run.events)):
        return
    for name, g in run.events.items():
        if name in found:
            continue
        (ga, va), (gc, vc) = run.ev_vals[k - 1][name], _event_value(g(cut[:n], cut[n]))
        if ga * gc < 0 or (gc == 0 and ga != 0):
            run.sps.append(_event_point(core, run, k, name, g, ga, va, gc, vc, end=cut))


def _event_point(core, run, k, name, g, ga, va, gb, vb, end=None, start=None):
    """The special point of the event ``name`` whose function ``g`` changes sign (values
    ``ga``, ``gb``, entries ``va``, ``vb`` of a vector event) between points k-1 and k (or
    ``start`` and ``end``, points of the step's arc), located there when the settings ask
    for it."""
    n = core.n
    xb = np.concatenate([run.u[k], [run.p[k]]]) if end is None else end
    pa = run.p[k - 1] if start is None else float(start[n])
    sp = SpecialPoint("event", k, float(xb[n]), xb[:n].copy(), abs(xb[n] - pa), False,
                      name, {})
    if core.s.locate:
        xr, prec = (None, None) if va is None else \
            _locate_vector_event(core, run, k, g, va, vb, end=end, start=start)
        if xr is None:
            xr, prec = _bisect_on_arc(
                core, run, k, lambda x, g=g: _event_value(g(x[:n], x[n]))[0],
                ga, gb, chord=True, end=end, start=start)
        if xr is not None:
            sp.p, sp.u, sp.precision, sp.located = float(xr[n]), xr[:n].copy(), prec, True
    return sp


#: Event dips (:func:`_event_dip`): the interpolant's extremum is sought on this grid of the
#: step (fractions of its arclength), ...
_DIP_GRID = np.linspace(0.0, 1.0, 257)
#: ... confirmed by at most this many corrected points, ...
_DIP_POINTS = 3
#: ... and not tried where the tangent turns by more than this cosine over the step (the
#: slope at its end, taken along the end's tangent, is divided by it).
_DIP_MIN_COS = 0.1


def _dip_fit(taus, vals, da, db):
    """Coefficients (highest power first, one column per entry) of the polynomial of least
    degree through ``vals`` (rows) at ``taus`` with slopes ``da`` at 0 and ``db`` at 1."""
    taus = np.asarray(taus, float)
    m = taus.size + 2
    powers = np.arange(m - 1, -1, -1)
    rows = [taus[i] ** powers for i in range(taus.size)]
    rows.append(np.where(powers == 1, 1.0, 0.0))  # slope at 0
    rows.append(powers.astype(float))  # slope at 1: the sum of p c_p
    rhs = np.vstack([np.asarray(vals, float), da[None, :], db[None, :]])
    return np.linalg.solve(np.array(rows), rhs)


def _event_dip(core, run, k, name, g) -> list:
    """The special points of the event ``name`` (function ``g``) where it changes sign
    and back between points k-1 and k, with one sign at both; [] if it does not.

    The arc's points are parametrized as the corrector's: s in [0, sb] along the tangent
    t_a at k-1 (the hyperplanes normal to it), tau = s / sb. Each entry of the event (its
    value, for a scalar one) is interpolated by the cubic with its values and slopes at
    both ends (the slope at k along t_b, divided by t_a . t_b = ds/dsigma there): falling
    (positive at both ends), an entry may dip below 0 only where
    min(value_a, value_b) < max(|slope_a - chord|, |slope_b - chord|) / 4 (the cubic's
    departure from the chord), so most steps stop at that bound. Otherwise the least
    entry of the interpolants is searched on a grid of the step for its extremum (rising,
    negative at both ends: the greatest); where it has the other sign, the point of the
    arc there is corrected (the step's factorization, chord iterations) and the event
    evaluated on it. A crossing confirmed there is located between k-1 and that point
    (the first root) and, unless the event is terminal (the run ends at the first),
    between it and k (the second). A point that does not confirm it joins the
    interpolation (values there, a polynomial one degree higher), at most _DIP_POINTS.
    A step whose tangent turns by more than arccos(_DIP_MIN_COS), or an entry not finite
    at an end (value or slope), is not tested.
    """
    n = core.n
    (ga, va), (gb, vb) = run.ev_vals[k - 1][name], run.ev_vals[k][name]
    sa, sbl = run.ev_slopes[k - 1].get(name), run.ev_slopes[k].get(name)
    if not ga * gb > 0.0 or sa is None or sbl is None:
        return []
    ta, tb = run.t[k - 1], run.t[k]
    cos = core.dot(tb, ta)
    xa = np.concatenate([run.u[k - 1], [run.p[k - 1]]])
    xb = np.concatenate([run.u[k], [run.p[k]]])
    sb = core.dot(xb - xa, ta)
    if not (cos > _DIP_MIN_COS and sb > 0.0):
        return []
    ea = np.array([ga]) if va is None else va
    eb = np.array([gb]) if vb is None else vb
    with np.errstate(invalid="ignore", over="ignore"):
        da, db = sa * sb, sbl * (sb / cos)
        use = np.isfinite(ea) & np.isfinite(eb) & np.isfinite(da) & np.isfinite(db)
        chord = eb - ea
        bound = 0.25 * np.maximum(np.abs(da - chord), np.abs(db - chord))
    fall = ga > 0.0
    if fall:
        # only the entries whose cubic can reach 0 matter for the minimum's sign
        use &= np.minimum(ea, eb) < bound
        if not use.any():
            return []
    elif not use.any() or np.any(use & (np.maximum(ea, eb) + bound < 0.0)):
        # rising: an entry whose cubic stays negative keeps the minimum negative
        return []
    taus, vals = [0.0, 1.0], [ea[use], eb[use]]
    da, db = da[use], db[use]
    for _ in range(_DIP_POINTS):
        coef = _dip_fit(taus, vals, da, db)
        least = np.min(np.polynomial.polynomial.polyvander(_DIP_GRID, coef.shape[0] - 1)
                       @ coef[::-1], axis=1)
        i = int(np.argmin(least) if fall else np.argmax(least))
        if (least[i] >= 0.0) if fall else (least[i] <= 0.0):
            return []
        tau = float(_DIP_GRID[i])
        if min(abs(tau - t) for t in taus) < 2.0 / (_DIP_GRID.size - 1):
            return []  # no new point to try
        r = _point_at(core, xa, ta, tau * sb, guess=xa + tau * (xb - xa), fac=run.fac)
        if not r.ok:
            return []
        gc, vc = _event_value(g(r.x[:n], r.x[n]))
        if gc * ga < 0.0:
            pts = [_event_point(core, run, k, name, g, ga, va, gc, vc, end=r.x)]
            if name not in run.stop_on:
                pts.append(_event_point(core, run, k, name, g, gc, vc, gb, vb, start=r.x))
            return pts
        ec = np.array([gc]) if vc is None else vc
        if ec.shape != ea.shape:
            return []
        ec = ec[use]
        keep = np.isfinite(ec)
        if not keep.any():
            return []
        taus.append(tau)
        vals = [v[keep] for v in vals] + [ec[keep]]
        da, db = da[keep], db[keep]
        use[np.flatnonzero(use)[~keep]] = False
    return []


def _event_value(val):
    """(value, entries) of an event function's output: a float is its own value (entries
    None); a 1-D array's value is its smallest entry."""
    if np.ndim(val) == 0:
        return float(val), None
    v = np.asarray(val, dtype=float)
    if v.ndim != 1 or v.size == 0:
        raise ValueError(f"an event function returned an array of shape {v.shape}; "
                         "expected a float or a non-empty 1-D array")
    return float(v.min()), v


def _locate_vector_event(core, run, k, g, va, vb, end=None, start=None):
    """Root of a vector event's smallest entry between points k-1 and k (or ``start`` and
    ``end``, points of the step's arc, where ``va`` and ``vb`` are taken:
    :func:`_bisect_on_arc`), located on the
    one entry whose sign change makes it (:func:`_bisect_on_arc` on a smooth function,
    where the smallest entry has kinks where the entries cross each other, and Brent's
    method takes bisection steps there).

    Falling (the smallest entry positive at k-1): the entry that turns negative first by
    linear interpolation; rising: the negative one that turns positive last. The root is
    accepted where every other entry has the sign the smallest entry needs there (the
    root of that entry is then the smallest entry's root); otherwise, or where the entry's
    values are not finite, ``(None, None)`` and the caller locates the smallest entry
    itself."""
    n = core.n
    fall = va.min() > 0.0
    # the entries that change sign the way the smallest does, finite at both ends
    cand = np.flatnonzero(((vb <= 0.0) if fall else (va < 0.0))
                          & np.isfinite(va) & np.isfinite(vb))
    if cand.size == 0:
        return None, None
    # their linear interpolants' zeros, as fractions of the step (va != vb: a sign change)
    cross = va[cand] / (va[cand] - vb[cand])
    j = int(cand[np.argmin(cross) if fall else np.argmax(cross)])
    xr, prec = _bisect_on_arc(core, run, k, lambda x: float(g(x[:n], x[n])[j]),
                              float(va[j]), float(vb[j]), chord=True, end=end,
                              start=start)
    if xr is None:
        return None, None
    v = np.asarray(g(xr[:n], xr[n]), dtype=float).copy()
    v[j] = np.inf
    # falling: no other entry negative before the root; rising: none still negative
    if v.min() < 0.0:
        return None, None
    return xr, prec


def _normalize_events(events):
    if events is None:
        return {}
    if isinstance(events, Mapping):
        out = dict(events)
    else:
        out = {}
        for g in events:
            out[getattr(g, "__name__", f"event{len(out)}")] = g
    for k, g in out.items():
        if not callable(g):
            raise TypeError(f"events[{k!r}]: expected a callable g(u, p) -> float; got "
                            f"{type(g).__name__}.")
    return out


def _assemble(core, runs, problem, settings, extra_meta, parameter="p") -> Branch:
    """Join one or two direction runs into a Branch (backward part reversed)."""
    n = core.n
    if len(runs) == 1:
        parts = [(runs[0], False)]
    else:
        parts = [(runs[0], True), (runs[1], False)]
    p, u, t, ds, it, st, obs = [], [], [], [], [], [], []
    sps = []
    offset = 0
    for j, (run, rev) in enumerate(parts):
        m = len(run.p)
        # The second part starts at the shared start point: skip its copy.
        idx = list(range(m - 1, -1, -1)) if rev else (range(1, m) if j else range(m))
        for i in idx:
            p.append(run.p[i])
            u.append(run.u[i])
            t.append(-run.t[i] if rev else run.t[i])
            ds.append(run.ds[i])
            it.append(run.it[i])
            st.append(run.stab[i])
            obs.append(run.obs[i])
        for sp in run.sps:
            if rev:
                sp.index = m - sp.index  # bracket (i-1, i) -> (m-1-i, m-i)
            else:
                sp.index = sp.index + offset
            sps.append(sp)
        offset += m - 1
    sps.sort(key=lambda sp: sp.index)
    m = len(p)
    names = sorted({k for o in obs for k in o})
    observables = {k: np.array([o.get(k, np.nan) for o in obs], dtype=float) for k in names}
    ends = [r.status for r in runs]
    if len(runs) == 2:
        message = f"backward: {runs[0].message} forward: {runs[1].message}"
        # The worse end decides: failures before bounds before max_steps.
        status = max(ends, key=lambda c: {B.START_FAILED: 5, B.NON_FINITE: 4,
                                          B.STEP_TOO_SMALL: 3}.get(c, 0))
    else:
        message, status = runs[0].message, runs[0].status
    if m:
        if len(runs) == 2:
            sps.insert(0, SpecialPoint("endpoint", 0, p[0], u[0].copy(), 0.0, True,
                                       "backward end"))
        sps.append(SpecialPoint("endpoint", m - 1, p[-1], u[-1].copy(), 0.0, True,
                                "forward end" if len(runs) == 2 else "end"))
    meta = {
        "problem": getattr(problem, "name", type(problem).__name__),
        "n_unknowns": n,
        "settings": settings.to_dict(),
        "package": "continuation",
        "version": package_version(),
        "end_status": [B.STATUS_NAMES.get(c, c) for c in ends],
        "nfev": core.ev.nfev,
        "njev": core.ev.njev,
    }
    params = getattr(problem, "parameters", None)
    if params is not None:
        try:  # recorded only if JSON-able (a dict of numbers/strings)
            json.dumps(params)
            meta["problem_parameters"] = params
        except (TypeError, ValueError):
            meta["problem_parameters"] = repr(params)
    meta.update(extra_meta)
    keep = settings.store_states
    return Branch(
        p=np.array(p, dtype=float),
        u=np.array(u) if keep and m else None,
        tangent=np.array(t) if keep and m else None,
        ds=np.array(ds, dtype=float),
        newton_iterations=np.array(it, dtype=int),
        stability=np.array(st, dtype=int),
        observables=observables,
        special_points=sps,
        status=status,
        message=message,
        parameter=parameter,
        metadata=meta,
    )


def _failed(problem, settings, n, message, p0, parameter="p") -> Branch:
    return Branch(
        p=np.empty(0), u=None, tangent=None, ds=np.empty(0),
        newton_iterations=np.empty(0, dtype=int), stability=np.empty(0, dtype=int),
        observables={}, special_points=[], status=B.START_FAILED, message=message,
        parameter=parameter,
        metadata={"problem": getattr(problem, "name", type(problem).__name__), "n_unknowns": n,
                  "settings": settings.to_dict(), "version": package_version(), "p0": p0},
    )


def continue_branch(
    problem,
    u0,
    p0: float,
    settings: ContinuationSettings | None = None,
    *,
    events: Mapping[str, Callable] | None = None,
    stop_on=(),
    callback: Callable | None = None,
    tangent=None,
    tangent_det_sign: int | None = None,
) -> Branch:
    """Continue a branch of solutions of ``F(u, p) = 0`` from ``(u0, p0)``.

    Newton-corrects ``u0`` at fixed ``p0``, then runs pseudo-arclength
    continuation (Keller 1977; Moore-Penrose with ``corrector=
    "moore-penrose"``) with one LU of the bordered matrix
    ``[[dF/du, dF/dp], [tangent^T]]`` per Newton iteration. The tangent at a
    new point comes from the last LU (one back-substitution); the sign of its
    determinant, also free, detects branch points. Folds are located by
    Newton on a minimally augmented system, branch points and events by
    Brent's method along the arclength.

    Parameters
    ----------
    problem : Problem
        See :class:`continuation.Problem`.
    u0 : array_like, shape (n,)
        Initial guess (corrected by Newton at fixed ``p0``).
    p0 : float
    settings : ContinuationSettings, optional
    events : dict[str, callable] or list of callables, optional
        User functions ``g(u, p) -> float``; a sign change between two points
        is located and recorded as a special point of kind ``"event"``. A function may
        return a 1-D array instead: its value is the smallest entry, and its sign change
        is located on the entry that makes it (smooth where the smallest entry has kinks;
        see :func:`_locate_vector_event`).
    stop_on : collection of str
        Names of events that end the run (status ``STOPPED``), also on the step cut back
        onto ``p_min`` or ``p_max`` (the event lies before the bound).
    callback : callable, optional
        Called after each accepted step with a dict (``step, p, u, ds,
        newton_iterations, stability``); returning ``False`` stops the run.
    tangent : array_like, shape (n + 1,), optional
        Initial tangent (du/ds, dp/ds); default: computed at the start and
        oriented by ``settings.direction``.
    tangent_det_sign : {-1, 1}, optional
        With ``tangent``: the sign of ``det [[dF/du, dF/dp], [tangent^T]]`` at the
        start, where the caller has it (for a tangent proportional to ``(w, 1)`` with
        ``dF/du w = -dF/dp``, the sign of ``det dF/du`` times that of ``dp/ds``: the
        LU that gave ``w`` gives it). The branch-point test's first sign; default:
        from the LU of that bordered matrix at the start.

    Returns
    -------
    Branch
        Never raises for a numerical failure: ``status``/``message`` say why
        the run ended, and every computed point is kept.

    Raises
    ------
    ValueError
        Invalid input (shapes, non-finite values), naming the argument.
    JacobianError
        If ``settings.check_jacobian`` and a supplied derivative disagrees
        with finite differences.
    """
    t_start = time.perf_counter()
    settings = ContinuationSettings() if settings is None else settings
    if not isinstance(settings, ContinuationSettings):
        raise TypeError(f"settings: expected ContinuationSettings; got {type(settings).__name__}")
    u0 = np.array(u0, dtype=float).ravel()
    if u0.size == 0 or not np.all(np.isfinite(u0)):
        raise ValueError(f"u0: expected a non-empty finite array; got {u0!r:.200}")
    if not math.isfinite(float(p0)):
        raise ValueError(f"p0: expected a finite float; got {p0!r}")
    p0 = float(p0)
    ev = Evaluator(problem)
    F0 = ev.F(u0, p0)
    if F0.shape != u0.shape:
        raise ValueError(f"problem.residual(u0, p0) returned shape {F0.shape}; expected "
                         f"{u0.shape} (the shape of u0): F must be square in u.")
    ev.warn_if_fd()
    n = u0.size
    if settings.check_jacobian and np.all(np.isfinite(F0)):
        check_jacobian(problem, u0, p0)
    core = _Core(ev, settings, n)
    events = _normalize_events(events)
    unknown = set(stop_on) - set(events)
    if unknown:
        raise ValueError(f"stop_on: {sorted(unknown)} are not event names; events: "
                         f"{sorted(events)}")
    # ---- Newton at fixed p0
    x0 = np.concatenate([u0, [p0]])
    e = np.zeros(n + 1)
    e[n] = 1.0
    with np.errstate(all="ignore"):
        r0 = core.correct(x0, e, p0, max_iter=max(2 * settings.max_newton, 20))
        if not r0.ok and r0.normF <= _LOCATE_STALL_FACTOR * settings.newton_tol:
            # a start at a located special point (dF/du singular): as accurate as the
            # arithmetic allows there
            r0.ok = True
        if not r0.ok:
            return _failed(problem, settings, n, (
                f"Newton at the start p0={p0!r} failed: {r0.reason} (max|F|={r0.normF:.2e}, "
                f"newton_tol={settings.newton_tol:.1e}). Try a better u0, a looser newton_tol, "
                "or a p0 away from a fold/branch point (a singular dF/du there stops Newton "
                "at fixed p)."), p0)
        x0 = r0.x
        if tangent is None:
            t0, msg = _start_tangent(ev, x0[:n], p0)
            if t0 is None:
                return _failed(problem, settings, n, msg, p0)
            t0 = core.normalize(t0)
            if t0[n] < 0 or (t0[n] == 0 and np.sum(t0[:n]) < 0):
                t0 = -t0
        else:
            t0 = core.normalize(np.asarray(tangent, dtype=float).ravel())
            if t0.size != n + 1:
                raise ValueError(f"tangent: expected shape ({n + 1},); got {t0.shape}")
        if tangent is not None and tangent_det_sign is not None:
            if tangent_det_sign not in (-1, 1):
                raise ValueError(f"tangent_det_sign: got {tangent_det_sign!r}; expected -1 or "
                                 "1")
            # the weighted row wrow(t0) has the sign of t0's: det[[J, F_p], [wrow]] =
            # det J a (w_p + w_u |w|^2) for t0 = a (w, 1)
            det0 = int(tangent_det_sign)
        else:
            fac0 = factorize(core.bmatrix(x0, core.wrow(t0)))
            det0 = fac0.det_sign() if fac0 is not None else 0
        runs = []
        dirs = [settings.direction] if settings.direction != 0 else [-1, 1]
        for d in dirs:
            tt = t0 if d == 1 else -t0
            # det[[J, F_p], [t^T]] is linear in t: reversing t flips its sign.
            runs.append(_run_direction(core, x0, tt, det0 * d, events, set(stop_on), callback,
                                       skip_first=(det0 == 0)))
    br = _assemble(core, runs, problem, settings, {"p0": p0})
    br.metadata["wall_time_s"] = time.perf_counter() - t_start
    return br


def switch_branch(
    problem,
    point: SpecialPoint,
    settings: ContinuationSettings | None = None,
    *,
    ds: float | None = None,
    both_sides: bool = True,
    events=None,
    stop_on=(),
    callback=None,
) -> Branch:
    """Continue the other branch through a located simple branch point.

    The direction of the bifurcating branch solves the algebraic bifurcation
    equation (Keller 1977; AUTO's branch switching): with ``t1`` the known
    tangent, ``phi`` the second null vector of ``[dF/du, dF/dp]`` and ``psi``
    its left null vector, ``c_ij = psi . D^2F[e_i, e_j]`` (``e_1 = t1``,
    ``e_2 = phi``, second derivatives by central differences of the
    Jacobian); the root other than ``t1`` is ``t2 = -c22/(2 c12) t1 + phi``.
    The run goes both ways from the branch point. The first point of each
    side is checked to lie on the new branch (its secant is closer to ``t2``
    than to ``t1``); if not, that side ends with status ``START_FAILED`` and a
    message, never silently on the old branch.

    Parameters
    ----------
    problem : Problem
    point : SpecialPoint
        A located branch point from :func:`continue_branch`.
    settings : ContinuationSettings, optional
        ``direction`` is not used; see ``both_sides``.
    ds : float, optional
        First step off the branch point; default ``settings.ds0``.
    both_sides : bool
        Continue both halves of the new branch (default) or only the one
        along ``+t2`` (oriented so that p increases when it can).
    events, stop_on, callback
        As in :func:`continue_branch`.

    Returns
    -------
    Branch
        Starts at one side, passes through the branch point, ends at the other.
    """
    settings = ContinuationSettings() if settings is None else settings
    if not isinstance(point, SpecialPoint) or point.kind != "branch_point":
        raise ValueError(f"point: expected a SpecialPoint of kind 'branch_point'; got {point!r}")
    if not point.located or "kernel" not in point.data:
        raise ValueError(
            f"point: the branch point at p={point.p:.10g} was only bracketed, not located "
            "(no kernel vector). Rerun continue_branch with locate=True and a smaller ds_max.")
    ev = Evaluator(problem)
    ev.warn_if_fd()
    u = np.asarray(point.u, dtype=float)
    n = u.size
    ds = settings.ds0 if ds is None else float(ds)
    settings = settings.replace(ds0=min(max(ds, settings.ds_min), settings.ds_max))
    core = _Core(ev, settings, n)
    x = np.concatenate([u, [point.p]])
    t1 = core.normalize(np.asarray(point.data["tangent"], dtype=float))
    phi = np.asarray(point.data["kernel"], dtype=float)
    phi = core.normalize(phi - core.dot(phi, t1) * t1)
    psi = np.asarray(point.data["left_kernel"], dtype=float)
    with np.errstate(all="ignore"):
        c11 = _d2(core, x, t1, t1, psi)
        c12 = _d2(core, x, t1, phi, psi)
        c22 = _d2(core, x, phi, phi, psi)
    # Two roots of c11 a^2 + 2 c12 a b + c22 b^2 = 0; one is ~t1 (a=1, b=0 when
    # c11 ~ 0). The other: b = 1, a = -c22 / (2 c12). A vanishing c12 means a
    # degenerate (non-simple) branch point: fall back to phi, and say so.
    note = ""
    if abs(c12) > 1e-8 * max(abs(c11), abs(c22), 1e-300):
        a = -c22 / (2.0 * c12)
    else:
        a = 0.0
        note = " (c12 ~ 0: degenerate branch point, used the kernel direction)"
    t2 = core.normalize(a * t1 + phi)
    events = _normalize_events(events)
    runs = []
    if t2[n] < 0:
        t2 = -t2
    dirs = [-1, 1] if both_sides else [1]
    with np.errstate(all="ignore"):
        for d in dirs:
            tt = t2 if d == 1 else -t2
            run = _run_direction(core, x, tt, 0, events, set(stop_on), callback,
                                 skip_first=True)
            if len(run.p) > 1:
                x1 = np.concatenate([run.u[1], [run.p[1]]])
                sec = core.normalize(x1 - x)
                if abs(core.dot(sec, t1)) >= abs(core.dot(sec, t2)):
                    run.status = B.START_FAILED
                    run.message = (
                        f"branch switching at p={point.p:.10g} landed on the original branch "
                        f"(secant/old tangent cosine {abs(core.dot(sec, t1)):.3f}); the computed "
                        "points were discarded. Try a smaller ds or check that the branch point "
                        "is simple." + note)
                    del run.p[1:], run.u[1:], run.t[1:], run.ds[1:], run.it[1:]
                    del run.stab[1:], run.det[1:], run.obs[1:], run.ev_vals[1:]
                    run.sps = []
                elif note:
                    run.message += note
            runs.append(run)
    br = _assemble(core, runs, problem, settings,
                   {"switched_at": float(point.p), "abe": [c11, c12, c22]})
    j = (len(runs[0].p) - 1) if len(runs) == 2 else 0
    bp = SpecialPoint("branch_point", j, float(point.p), u.copy(), point.precision, True,
                      "switched here", {"tangent": t2, "old_tangent": t1})
    br.special_points.insert(1 if len(runs) == 2 else 0, bp)
    br.special_points.sort(key=lambda sp: sp.index)
    return br


def _d2(core, x, a, b, psi):
    """``psi . D^2 F(x)[a, b]`` by central differences of ``[J, F_p] b`` along ``a``."""
    n = core.n
    ev = core.ev
    scale = 1.0 + float(np.max(np.abs(x)))
    h = _FD2 * scale / max(float(np.max(np.abs(a))), 1e-300)

    def jext(y):
        return np.asarray(ev.J(y[:n], y[n]) @ b[:n]).ravel() + ev.Fp(y[:n], y[n]) * b[n]

    return float(psi @ (jext(x + h * a) - jext(x - h * a))) / (2.0 * h)
