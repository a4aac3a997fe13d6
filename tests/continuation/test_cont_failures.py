"""Failure modes: each ends in a value (status + message) or a clear input error."""

import dataclasses

import numpy as np
import pytest

import continuation as C
from continuation.examples import Bratu, Pitchfork

S = C.ContinuationSettings(ds0=0.05, ds_max=0.5, max_steps=60, p_min=0.0, p_max=4.0)


def test_singular_start_is_a_status_not_an_exception():
    br = C.continue_branch(Pitchfork(), [0.0], 0.0, S)
    assert br.status == C.START_FAILED and not br.success and len(br) == 0
    assert "singular" in br.message and "switch_branch" in br.message


def test_a_non_finite_derivative_at_the_start_is_a_status_not_an_exception():
    # F converges at p0, but dF/dp is NaN there (a model at the edge of its domain): the
    # tangent is diagnosed, not an SVD that fails to converge
    prob = C.FunctionProblem(lambda u, p: u - p, jacobian=lambda u, p: np.eye(2),
                             dfdp=lambda u, p: np.full(2, np.nan), name="nan-dfdp")
    br = C.continue_branch(prob, [0.0, 0.0], 0.0, S.replace(check_jacobian=False))
    assert br.status == C.START_FAILED and not br.success
    assert "2 non-finite entries in [dF/du, dF/dp]" in br.message


def test_newton_failure_at_start_says_what_to_try():
    # Bratu has no solution for lam > 3.5138: Newton at lam = 5 cannot converge.
    br = C.continue_branch(Bratu(16), np.zeros(15), 5.0, S.replace(check_jacobian=False))
    assert br.status == C.START_FAILED
    assert "p0=5.0" in br.message and "newton_tol" in br.message and "Try" in br.message


def test_step_that_cannot_converge_keeps_the_partial_branch():
    # The residual is undefined (NaN) beyond p = 0.5, e.g. a model leaving its domain.
    def res(u, p):
        return u - p if p < 0.5 else np.full_like(u, np.nan)

    prob = C.FunctionProblem(res, jacobian=lambda u, p: np.eye(1),
                             dfdp=lambda u, p: -np.ones(1), name="wall")
    s = S.replace(ds0=0.05, ds_max=0.05, p_max=1.0, ds_min=1e-6)
    br = C.continue_branch(prob, [0.0], 0.0, s)
    assert br.status == C.NON_FINITE and not br.success
    # Every computed point is kept, right up to the wall (within the last step).
    assert len(br) > 10 and 0.5 - 0.05 < br.p[-1] < 0.5
    assert np.allclose(br.u[:, 0], br.p, atol=1e-12)
    assert "NaN/inf just beyond p=0.5" in br.message and "Try p_min/p_max" in br.message
    assert br.special_points[-1].kind == "endpoint"


def test_newton_cannot_converge_with_unchecked_wrong_jacobian():
    base = Bratu(16)
    prob = C.FunctionProblem(base.residual, jacobian=lambda u, p: -base.jacobian(u, p),
                             dfdp=base.dfdp, name="wrong-sign")
    br = C.continue_branch(prob, np.zeros(15), 0.0, S.replace(check_jacobian=False))
    assert br.status == C.STEP_TOO_SMALL and br.success
    assert len(br) == 1 and br.p[0] == 0.0  # the start (exact) is kept
    assert "corrector failed at ds_min" in br.message and "check_jacobian=True" in br.message
    # With the default check the same problem is refused before any step.
    with pytest.raises(C.JacobianError, match="disagrees with finite differences"):
        C.continue_branch(prob, np.zeros(15), 0.0, S)


def test_wrong_jacobian_detected_with_clear_message():
    base = Bratu(16)

    def bad_jac(u, p):
        J = base.jacobian(u, p)
        J[3, 4] += 0.1 * np.abs(J).max()  # a wrong entry
        return J

    prob = C.FunctionProblem(base.residual, jacobian=bad_jac, dfdp=base.dfdp, name="bad")
    with pytest.raises(C.JacobianError, match=r"jacobian\(u, p\) disagrees") as exc:
        C.continue_branch(prob, np.zeros(15) + 0.1, 1.0, S)
    msg = str(exc.value)
    assert "component 3" in msg and "rtol" in msg and "finite differences" in msg
    # Wrong dF/dp: sign error.
    prob2 = C.FunctionProblem(base.residual, jacobian=base.jacobian,
                              dfdp=lambda u, p: -np.exp(u), name="bad-dfdp")
    with pytest.raises(C.JacobianError, match=r"dfdp\(u, p\) disagrees"):
        C.check_jacobian(prob2, np.zeros(15), 1.0)
    # A correct problem passes with a tiny mismatch.
    assert C.check_jacobian(base, np.zeros(15) + 0.1, 1.0) < 1e-7


def test_settings_validation_quotes_field_and_value():
    with pytest.raises(ValueError, match=r"ContinuationSettings.ds0=1.0: expected ds_min <= ds0"):
        C.ContinuationSettings(ds0=1.0, ds_max=0.5)
    with pytest.raises(ValueError, match=r"ContinuationSettings.direction=2"):
        C.ContinuationSettings(direction=2)
    with pytest.raises(ValueError, match=r"ContinuationSettings.max_newton=0"):
        C.ContinuationSettings(max_newton=0)
    with pytest.raises(ValueError, match=r"ContinuationSettings.corrector='newton'"):
        C.ContinuationSettings(corrector="newton")
    with pytest.raises(dataclasses.FrozenInstanceError):
        S.ds0 = 0.1  # frozen
    d = S.to_dict()
    assert C.ContinuationSettings.from_dict(d) == S
    with pytest.raises(ValueError, match="unknown fields"):
        C.ContinuationSettings.from_dict({**d, "dsmax": 1})


def test_settings_round_trip_through_standard_json():
    """Unbounded ends and an undamped search are null in the JSON (no NaN/Infinity, no
    strings) and load back as -inf / inf."""
    import json
    import math

    def strict(text):
        def refuse(name):
            raise ValueError(name)
        return json.loads(text, parse_constant=refuse)

    for S in (C.ContinuationSettings(), C.ContinuationSettings(p_min=0.0),
              C.ContinuationSettings(p_max=2.0)):
        d = strict(json.dumps(S.to_dict(), allow_nan=False))
        assert all(not isinstance(v, str) or k == "corrector" for k, v in d.items()), d
        assert C.ContinuationSettings.from_dict(d) == S
    d = strict(json.dumps(C.ContinuationSettings().to_dict()))
    assert d["p_min"] is None and d["p_max"] is None
    for T in (C.SearchSettings(), C.SearchSettings(max_step=math.inf, sample_values=(0.5,))):
        d = strict(json.dumps(T.to_dict(), allow_nan=False))
        assert C.SearchSettings.from_dict(d) == T
    assert C.SearchSettings(max_step=math.inf).to_dict()["max_step"] is None


def test_invalid_inputs_name_the_argument():
    with pytest.raises(ValueError, match="u0: expected a non-empty finite array"):
        C.continue_branch(Bratu(8), np.full(7, np.nan), 0.0, S)
    short = C.FunctionProblem(lambda u, p: u[:-1] - p, name="non-square")
    with pytest.raises(ValueError, match=r"returned shape \(5,\); expected \(6,\)"):
        C.continue_branch(short, np.zeros(6), 0.0, S)
    with pytest.raises(TypeError, match="residual"):
        C.continue_branch(object(), np.zeros(3), 0.0, S)
    with pytest.raises(ValueError, match="stop_on"):
        C.continue_branch(Bratu(8), np.zeros(7), 0.0, S, stop_on=["nope"])
    fold_guess = C.SpecialPoint("fold", 3, 1.0, np.zeros(7), located=False)
    with pytest.raises(ValueError, match="only bracketed"):
        C.continue_fold(lambda q: Bratu(8), fold_guess, 0.0)
