"""The (Delta, A) fold curve of the free rod, computed once, as the reference for the
one-parameter searches of any scene of the family.

The free-rod equilibria depend on Delta/l_ec and A/l_ec^2 only (the rod length and the
drop's position place the straight dry arms), so one fold curve in the (Delta, A) plane,
continued by two-parameter continuation from supp-fig5's fold, gives the folds of every
scene with B = gamma = 1: at area A, the folds in Delta are the curve's crossings of A. The
one-parameter search knows nothing of this curve (``fold_curve_seeds=False``).
"""

import functools

import numpy as np

from continuation import ContinuationSettings, continue_fold
from elastocap.scene import load_scene
from elastocap.statics.branches import trace_branches

A_RANGE = (0.3, 2.4)


@functools.lru_cache(maxsize=1)
def fold_curve():
    """(q = A values, p = Delta values, states) of the fold curve through supp-fig5's fold."""
    bs = trace_branches(load_scene("supp-fig5"), error_estimates=False, fold_curve_seeds=False)
    br = next(b for b in bs.branches for sp in b.folds if sp.located)
    fold = next(sp for sp in br.folds if sp.located)
    base = bs.problem

    def family(q):
        return base.with_(**{"drop.area": q})

    s = ContinuationSettings(ds0=0.01, ds_max=0.02, max_steps=3000, p_min=A_RANGE[0],
                             p_max=A_RANGE[1], direction=0, newton_tol=1e-11,
                             check_jacobian=False)
    fc = continue_fold(family, fold, 1.5, s, parameter="drop.area")
    return fc, family


def curve_folds(A, lo, hi):
    """The fold curve's crossings of area A with lo <= Delta <= hi, Newton-located."""
    from continuation import locate_fold

    fc, family = fold_curve()
    q, d = fc.p, fc.observables["p"]
    out = []
    for i in range(len(q) - 1):
        if (q[i] - A) * (q[i + 1] - A) > 0 or q[i] == q[i + 1]:
            continue
        w = (A - q[i]) / (q[i + 1] - q[i])
        U = (1 - w) * fc.u[i] + w * fc.u[i + 1]
        sp = locate_fold(family(A), U[:-1], U[-1])
        if sp.located and lo <= sp.p <= hi:
            out.append(float(sp.p))
    return sorted(set(np.round(out, 11)))
