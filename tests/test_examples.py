"""Every script in examples/ runs in fast mode and gets its key number right.

Each key number is checked against a value from another method: the supp-fig5 fold against
AUTO-07p's (an independent Kirchhoff BVP, agreeing to 1e-12; docs/guide/accuracy.md), an
impact's final measure against the static equilibrium it settles on, and the sweep's
threshold bracket against the static fold (an impact cannot encapsulate where the
encapsulated branch does not exist) and the 11-run bisection of the threshold study.
"""

import csv
import importlib.util
import io
import json
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: The supp-fig5 fold: elastocap at N = 24 and AUTO-07p (NTST >= 20, NCOL = 4) agree to 1e-12.
FOLD = 3.469794751569
#: Delta* of supp-fig5 at 50 edges (draft), 11-run bisection, +-1.3e-4 (docs/guide/accuracy.md).
THRESHOLD_DRAFT = 3.52979


def _load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_example_is_tested():
    scripts = {p.stem for p in EXAMPLES.glob("*.py")}
    assert scripts == {"trace_and_check_folds", "impact_overlay", "sweep_and_export"}
    for s in scripts:
        assert callable(_load(s).main)


def test_trace_and_check_folds(tmp_path):
    res = _load("trace_and_check_folds").main(tmp_path, fast=True)
    (fold,) = res["folds"]
    err = abs(fold["value"] - FOLD)
    # draft (16 LGL intervals): the error estimate is the error, and it is ~1e-9
    assert err <= fold["error_estimate"] + 1e-12
    assert 1e-11 < fold["error_estimate"] < 1e-8
    # one stable and one unstable side (the order follows the direction of tracing)
    assert sorted(fold["stability_change"].split("->")) == ["0", "1"]
    for f in res["files"]:
        assert Path(f).stat().st_size > 30
    saved = json.loads((tmp_path / "branches" / "branches.json").read_text())
    assert saved["folds"][0]["value"] == pytest.approx(fold["value"], rel=1e-15)


def test_impact_overlay(tmp_path):
    res = _load("impact_overlay").main(tmp_path, fast=True)
    low, high = res["runs"]
    assert (low["outcome"], low["branch_reached"]) == ("open", "primary")
    assert high["outcome"] == "encapsulated" and high["branch_reached"] != "primary"
    for r in (low, high):
        assert r["t_end"] < 200  # came to rest
        # the damped run settles on the static equilibrium; the rest criterion stops it
        # while it still creeps, ~2e-3 away (docs/guide/accuracy.md)
        assert r["final_measure"] == pytest.approx(r["branch_measure"], abs=5e-3)
    assert Path(res["files"][0]).stat().st_size > 1000


def test_sweep_and_export(tmp_path):
    res = _load("sweep_and_export").main(tmp_path, fast=True)
    low, high = res["boundary"]
    assert high - low <= 0.05
    assert FOLD < low  # above the static fold
    assert low <= THRESHOLD_DRAFT <= high
    rows = list(csv.DictReader(io.StringIO((tmp_path / "sweep.csv").read_text())))
    assert len(rows) == res["runs"] >= 3
    assert {r["outcome"] for r in rows} == {"open", "encapsulated"}
    again = _load("sweep_and_export").main(tmp_path, fast=True)  # resumes from the store
    assert again["boundary"] == res["boundary"]
    rows = list(csv.DictReader(io.StringIO((tmp_path / "sweep.csv").read_text())))
    assert all(r["cached"] == "True" for r in rows)
