"""Every paper figure runs in fast mode and reproduces its key number (they cannot rot)."""

import json

import pytest

from elastocap.cli import main
from elastocap.paper_figures import FIGURES, run_figures


@pytest.fixture(scope="module")
def figs(tmp_path_factory):
    out = tmp_path_factory.mktemp("figs")
    return out, run_figures(out, fast=True)


def test_every_figure_writes_its_files(figs):
    out, written = figs
    assert set(written) == set(FIGURES)
    for paths in written.values():
        for p in paths:
            assert p.stat().st_size > 200


def test_supp_fig6_fold(figs):
    out, _ = figs
    folds = json.loads((out / "supp-fig6.json").read_text())["folds"]
    # draft resolution (16 LGL intervals): fold error 1.4e-9 (README convergence table)
    assert len(folds) == 1 and folds[0]["value"] == pytest.approx(3.46979475157, abs=5e-9)


def test_bistability_curve_passes_through_the_fold(figs):
    out, _ = figs
    (curve,) = json.loads((out / "bistability.json").read_text())["curves"]
    import numpy as np

    a, d = np.array(curve["area"]), np.array(curve["delta"])
    # on the lower half (before the first extremum of A) Delta(A = 1.5) is the fold of supp-fig5
    k = int(np.argmax(a))
    assert np.interp(1.5, a[: k + 1], d[: k + 1]) == pytest.approx(3.4698, abs=2e-3)
    assert max(a) == pytest.approx(1.7449, abs=2e-3)  # the cusp


def test_supp_fig5_outcomes(figs):
    out, _ = figs
    s = json.loads((out / "supp-fig5.json").read_text())
    assert s["a"]["outcome"] == "open" and s["b"]["outcome"] == "encapsulated"


def test_overlay_branch_reached(figs):
    out, _ = figs
    runs = json.loads((out / "overlay.json").read_text())["runs"]
    assert [r["branch_reached"] for r in runs][0] == "primary"
    # the last run ends on the wrapped branch; at Delta = 4.5 ~ L (draft) its outcome is
    # undecided: the energy audit fails where the contact lines nearly meet inside the wrap
    # (measured 0.0245 gamma Delta after two halvings of dt)
    assert runs[-1]["branch_reached"] != "primary"
    assert runs[-1]["outcome"] in ("encapsulated", "undecided")


def test_figures_cli_rejects_unknown_name(capsys):
    assert main(["figures", "--only", "fig99"]) == 2
    assert "expected one of" in capsys.readouterr().err


def test_fig3d_fast_line(figs):
    out, _ = figs
    runs = json.loads((out / "fig3d.json").read_text())["runs"]
    # x = 3 l_eg (draft, damping 0.1): We^1/2 = 1 stays open, 2.5 encapsulates (README Fig 3d)
    got = {r["we_sqrt"]: r["outcome"] for r in runs}
    assert got == {1.0: "open", 2.5: "encapsulated"}


def test_fig4_floppy_encapsulation(figs):
    out, _ = figs
    s = json.loads((out / "fig4_fig5.json").read_text())
    assert s["fig4B"]["outcome"] == "encapsulated" == s["fig4B"]["companion_outcome"]


def test_energy_barrier_band(figs):
    out, _ = figs
    d = json.loads((out / "energy_barrier.json").read_text())
    assert d["not_handled"]  # the limits are written into the output, not hidden
    # x = 2 l_eg: the lifted wrapped state exists for 0.924 < Delta < 1.278 (strip statics)
    lo, hi = d["x2"]["window"]
    assert lo == pytest.approx(0.92394, abs=1e-3) and hi == pytest.approx(1.27773, abs=1e-3)


def test_every_json_record_says_what_made_it(figs):
    out, written = figs
    for paths in written.values():
        for p in paths:
            if p.suffix == ".json":
                made = json.loads(p.read_text())["made_by"]
                assert made["elastocap"] and made["scene"]["name"]
                assert "accuracy" in made["numerics"]
