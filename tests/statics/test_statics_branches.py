"""supp-fig5's branches (the paper's supplementary Fig 6): every branch, fold, branch point
and equal-energy point, checked three ways: against a finer resolution, by completeness
(a denser search finds nothing new) and by the physics (stability, symmetry)."""

import json

import numpy as np
import pytest

from elastocap.cli import main
from elastocap.scene import SceneError, load_scene
from elastocap.statics.branches import trace_branches
from elastocap.testing import FoldMismatch, assert_folds, compare_folds

FOLD_REF = 3.46979475156857  # LGL N = 40..64, see test_statics_convergence.py


@pytest.fixture(scope="module")
def fig6():
    return trace_branches(load_scene("supp-fig5"))


def test_one_fold_where_the_encapsulated_branch_appears(fig6):
    (fold,) = fig6.folds
    # default resolution N = 24: error ~1e-13 (convergence table in the README)
    assert fold["value"] == pytest.approx(FOLD_REF, abs=1e-11)
    assert fold["error_estimate"] < 1e-11
    assert fold["stability_change"] in ("0->1", "1->0")
    assert 1.0 < fold["measure"] < 1.1  # a U-shape around the drop


def test_flat_branch_is_stable_everywhere_and_bistability_above_the_fold(fig6):
    primary = fig6.branches[fig6.labels.index("primary")]
    assert np.all(primary.stability == 0)
    assert primary.p.min() == pytest.approx(0.02 * 4.6) and primary.p.max() == pytest.approx(4.6)

    # at Delta = 2.5 (paper: stays open) one stable state; at 4 (encapsulates) two
    def stable_measures(delta):
        out = []
        for br in fig6.branches:
            for i in range(len(br) - 1):
                a, b = br.p[i], br.p[i + 1]
                if (a - delta) * (b - delta) < 0 and br.stability[i] == br.stability[i + 1] == 0:
                    if br.observables["admissible"][i] > 0.5:
                        out.append(br.observables["measure"][i])
        return out

    assert len(stable_measures(2.51)) == 1
    m4 = sorted(stable_measures(4.01))
    assert len(m4) == 2 and m4[0] < 0.7 < 1.2 < m4[1]


def test_symmetry_breaking_branch_points_and_their_branches(fig6):
    values = sorted(b["value"] for b in fig6.branch_points)
    # two pitchforks, on the inverted and on the unstable wrapped branch (measured at N = 40
    # to agree to 1e-10 with the values below; N = 24 differs by the discretization error,
    # 1e-11 and 4e-11)
    assert values == pytest.approx([4.442808892637, 4.461518513478], abs=1e-10)
    asym = [br for br in fig6.branches if np.max(np.abs(br.observables["asymmetry"])) > 1e-3]
    assert len(asym) == 2  # one asymmetric branch (both mirror halves) per pitchfork


def _pitchfork_by_symmetry(problem, u0, p0, width=3e-3):
    """The symmetry-breaking pitchfork near (u0, p0), independently of the continuation:
    the mirror image R theta_j = -theta_{N-j}, R omega = -omega commutes with the Jacobian
    at a mirror-symmetric state; Newton restricted to the symmetric subspace (regular at
    the pitchfork) gives the symmetric branch at each Delta, and Brent finds the Delta
    where the smallest eigenvalue of the Jacobian on the antisymmetric subspace vanishes."""
    from scipy.optimize import brentq

    N = problem.N
    R = np.zeros((N + 2, N + 2))
    R[np.arange(N + 1), N - np.arange(N + 1)] = -1.0
    R[-1, -1] = -1.0
    w, V = np.linalg.eigh(R)
    sym, anti = V[:, w > 0], V[:, w < 0]

    def symmetric_state(p):
        y = sym.T @ u0
        for _ in range(40):
            r = sym.T @ problem.residual(sym @ y, p)
            if np.max(np.abs(r)) < 1e-14:
                break
            y -= np.linalg.solve(sym.T @ problem.jacobian(sym @ y, p) @ sym, r)
        return sym @ y

    def breaking_eigenvalue(p):
        ev = np.linalg.eigvals(anti.T @ problem.jacobian(symmetric_state(p), p) @ anti)
        ev = ev[np.abs(ev.imag) < 1e-9].real
        return ev[np.argmin(np.abs(ev))]

    return brentq(breaking_eigenvalue, p0 - width, p0 + width, xtol=1e-15, rtol=1e-15)


def test_branch_points_agree_with_the_symmetry_computation(fig6):
    """Each located pitchfork agrees with the independent symmetric-subspace computation
    at the same resolution (measured: 6e-13 and 2e-14); the gap to the N = 40 values of
    the test above is the discretization error (1e-11 and 4e-11)."""
    points = [(sp, br) for br in fig6.branches
              if np.max(np.abs(br.observables["asymmetry"])) < 1e-6
              for sp in br.branch_points if sp.located]
    reported = sorted(b["value"] for b in fig6.branch_points)
    assert len(reported) == 2
    for v in reported:
        sp = min((sp for sp, _ in points), key=lambda sp: abs(sp.p - v))
        assert sp.p == v
        ref = _pitchfork_by_symmetry(fig6.problem, sp.u, sp.p)
        assert abs(v - ref) < 1e-11, (v, ref)


def test_global_minimum_exchange(fig6):
    (mx,) = fig6.maxwell_points
    assert 3.47 < mx["value"] < 4.0
    assert mx["value"] == pytest.approx(3.606684698578, abs=1e-9)


def test_contact_lines_meet_ends_the_inverted_branch(fig6):
    ends = [e for e in fig6.endpoints if e["kind"] == "contact_lines_meet"]
    assert ends and all(e["measure"] < -1.0 for e in ends)


def test_search_is_complete_denser_grid_finds_nothing_new(fig6):
    dense = trace_branches(load_scene("supp-fig5"), samples=8, error_estimates=False)
    assert len(dense.branches) == len(fig6.branches)
    assert len(dense.folds) == len(fig6.folds)
    assert len(dense.branch_points) == len(fig6.branch_points)


def test_continuation_in_other_parameters():
    sc = load_scene("supp-fig5", {"drop.wetted_length": 4.0})
    bs = trace_branches(sc, "drop.area", (0.5, 3.0), error_estimates=False)
    assert bs.folds, "the wrapped branch folds in A too"
    # the rod length only moves the straight dry arms: no fold, same wet equilibrium
    bl = trace_branches(sc, "rod.length", (4.0, 6.0), error_estimates=False)
    assert not bl.folds
    assert bl.metadata["equilibrium_independent_of_parameter"]


def test_gravity_scene_refused_with_clear_error():
    with pytest.raises(SceneError, match="effects: got .*statics handles the free rod"):
        trace_branches(load_scene("fig3-strip"))


def test_folds_cli_json_and_check(tmp_path, capsys):
    assert main(["folds", "supp-fig5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    (f,) = out["folds"]
    assert set(f) >= {"value", "measure", "stability_change", "error_estimate"}
    assert "branch_points" in out and "maxwell_points" in out
    ref = tmp_path / "ref.json"
    ref.write_text(json.dumps(out))
    assert main(["folds", "supp-fig5", "--check", str(ref)]) == 0
    assert "all folds match" in capsys.readouterr().out
    out["folds"][0]["value"] *= 1 + 1e-6
    ref.write_text(json.dumps(out))
    assert main(["folds", "supp-fig5", "--check", str(ref)]) == 1
    text = capsys.readouterr().out
    assert "MISMATCH" in text and "folds differ" in text
    bad = tmp_path / "bad.json"
    bad.write_text('{"nofolds": 1}')
    assert main(["folds", "supp-fig5", "--check", str(bad)]) == 2
    assert "expected a JSON object with a key 'folds'" in capsys.readouterr().err


def test_branches_cli_writes_files(tmp_path, capsys):
    import strict_json

    from elastocap.jsonutil import jsonable
    from elastocap.statics.branches import BranchSet

    assert main(["branches", "supp-fig5", "--out", str(tmp_path), "--json"]) == 0
    # every JSON written (stdout, branches.json, branch_K.json and the metadata inside
    # each branch_K.npz) is standard JSON with numbers as numbers or null
    out = strict_json.check(capsys.readouterr().out)
    files = [p for p in out["files"]]
    assert any(p.endswith("branches.png") for p in files)
    written = sorted(tmp_path.glob("*.json")) + sorted(tmp_path.glob(".*.json"))
    names = {p.name for p in written}
    npz = sorted(tmp_path.glob("branch_*.npz"))
    assert npz and {p.with_suffix(".json").name for p in npz} | {"branches.json"} <= names
    for path in written:
        strict_json.check(path.read_text())
    for path in npz:
        with np.load(path) as z:
            strict_json.check(str(z["metadata_json"]))
    from continuation import Branch

    br = Branch.load(tmp_path / "branch_0.npz")
    assert br.metadata["scene"]["name"] == "supp-fig5"
    assert br.metadata["statics"]["N"] == 24
    assert "version" in br.metadata["statics"]
    # loading round-trips: the special points as saved (a precision not estimated, null in
    # the JSON, is NaN again)
    saved = strict_json.loads((tmp_path / "branches.json").read_text())
    back = BranchSet.load(tmp_path)
    again = jsonable(back.summary())
    for key in ("folds", "branch_points", "maxwell_points", "endpoints", "unlocated"):
        assert again[key] == saved[key], key
    for k, b in enumerate(back.branches):
        a = Branch.load(tmp_path / f"branch_{k}.npz")
        assert [(s.kind, s.p, s.located) for s in a.special_points] == \
            [(s.kind, s.p, s.located) for s in b.special_points]
        assert all(isinstance(s.precision, float) for s in b.special_points)
    # a damaged branches.json (a fold's value NaN) is refused by name, not drawn
    saved["folds"][0]["value"] = float("nan")
    (tmp_path / "branches.json").write_text(json.dumps(saved))
    with pytest.raises(ValueError, match=r"folds\[0\].value = nan; BranchSet.save writes"):
        BranchSet.load(tmp_path)


def test_bad_range_exit_2(capsys):
    assert main(["folds", "supp-fig5", "--range", "3", "9"]) == 2
    assert (
        "--range: got [3.0, 9.0]; expected 0 < LO < HI <= rod.length = 4.6"
        in capsys.readouterr().err
    )
    assert main(["folds", "supp-fig5", "--param", "drop.colour"]) == 2


def test_assert_folds_helper(fig6):
    assert_folds(fig6, [{"value": FOLD_REF}])
    with pytest.raises(FoldMismatch, match="MISMATCH"):
        assert_folds(fig6, [{"value": FOLD_REF * 1.001}])
    ok, table = compare_folds(fig6.folds, [], 1e-8)
    assert not ok and "expected 0, found 1" in table


def test_branches_of_a_rod_with_a_thickness_say_the_model_has_no_contact(tmp_path, capsys):
    # the spectral free rod has no contact: a thickness in the scene is named, in the
    # warning, the report and the saved metadata, not silently dropped
    assert main(["branches", "supp-fig5", "--set", "rod.thickness=0.05", "--out",
                 str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert "warning: rod.thickness = 0.05 is not in this model" in cap.err
    assert "note: rod.thickness = 0.05 is not in this model" in cap.out
    assert "elastocap.strip.freerod" in cap.err
    from elastocap.statics.branches import BranchSet

    assert "rod.thickness = 0.05" in BranchSet.load(tmp_path).metadata["contact_note"]
    assert main(["branches", "supp-fig5", "--out", str(tmp_path / "none")]) == 0
    cap = capsys.readouterr()
    assert "thickness" not in cap.err + cap.out
