"""The (Delta, A) fold curves of the free rod, computed once, as the reference for the
one-parameter searches of any scene of the family.

The free-rod equilibria depend on Delta/l_ec and A/l_ec^2 only (the rod length and the
drop's position place the straight dry arms), so the fold curves in the (Delta, A) plane,
continued by two-parameter continuation from the folds of reference scenes (L = 8, drop
centred, A = 0.6, 1.0, 1.5, 1.9), give the folds of every scene with B = gamma = 1 whose
folds lie on a curve that reaches one of those areas: at area A, the folds in Delta are the
curves' crossings of A. The one-parameter search knows nothing of these curves
(``fold_curve_seeds=False``).
"""

import functools

from continuation import ContinuationSettings, continue_fold
from elastocap.scene import load_scene
from elastocap.statics.branches import trace_branches

A_RANGE = (0.3, 2.4)


#: The reference scenes: the longest rod of the property family, drop centred, Delta over
#: the whole rod, a denser search (8 interior samples) than the default, at areas spread
#: over the family: a fold curve need not reach every area (the one through Delta = 6.12 at
#: A = 1 spans A = 0.3 ... 1.10 only), so curves seeded at one area miss folds of others.
REF = {"rod.length": 8.0, "drop.wetted_length": 2.5}
REF_AREAS = (0.6, 1.0, 1.5, 1.9)


@functools.lru_cache(maxsize=1)
def fold_curves():
    """Every fold curve (in A) through the folds of the reference scenes."""
    s = ContinuationSettings(ds0=0.01, ds_max=0.02, max_steps=3000, p_min=A_RANGE[0],
                             p_max=A_RANGE[1], direction=0, newton_tol=1e-11,
                             check_jacobian=False)
    curves = []
    for area in REF_AREAS:
        bs = trace_branches(load_scene("supp-fig5", {**REF, "drop.area": area}), samples=8,
                            error_estimates=False, fold_curve_seeds=False)
        base = bs.problem

        def family(q, base=base):  # the equilibria depend on Delta and A only
            return base.with_(**{"drop.area": q})

        folds = []
        for br in bs.branches:
            # a turn in the step of a branch point (a pitchfork seen from its bifurcating
            # branch) is no fold of the scene, whether or not its fold Newton happened to
            # converge there: its "fold curve" would be a curve of pitchforks
            bp_steps = {q.index for q in br.branch_points}
            for sp in br.folds:
                if (sp.located and sp.index not in bp_steps
                        and not any(abs(sp.p - f.p) < 1e-8 for f in folds)
                        and not _on(curves, area, sp.p)):
                    folds.append(sp)
        curves += [continue_fold(family, f, area, s, parameter="drop.area") for f in folds]
    return curves, family


def _on(curves, area, delta) -> bool:
    """Whether a fold at (area, delta) lies on one of ``curves`` already traced."""
    for fc in curves:
        q = fc.p
        for i in range(len(q) - 1):
            if (q[i] - area) * (q[i + 1] - area) <= 0 and q[i] != q[i + 1]:
                w = (area - q[i]) / (q[i + 1] - q[i])
                d = (1 - w) * fc.u[i][-1] + w * fc.u[i + 1][-1]
                if abs(d - delta) < 1e-3:
                    return True
    return False


def curve_folds(A, lo, hi):
    """The fold curves' crossings of area A with lo <= Delta <= hi, Newton-located."""
    from continuation import locate_fold

    curves, family = fold_curves()
    out = []
    for fc in curves:
        q = fc.p
        for i in range(len(q) - 1):
            if (q[i] - A) * (q[i + 1] - A) > 0 or q[i] == q[i + 1]:
                continue
            w = (A - q[i]) / (q[i + 1] - q[i])
            U = (1 - w) * fc.u[i] + w * fc.u[i + 1]
            sp = locate_fold(family(A), U[:-1], U[-1])
            if sp.located and lo <= sp.p <= hi:
                out.append(float(sp.p))
    # the curves through the reference folds may be one curve traced twice: a crossing
    # found on both (to 1e-9) is one fold
    out.sort()
    return [float(v) for i, v in enumerate(out) if i == 0 or v - out[i - 1] > 1e-9]
