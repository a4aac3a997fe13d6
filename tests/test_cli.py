"""The elastocap command, called in-process through main(argv)."""

import json

import pytest

from elastocap.cli import main


def test_scenes_and_show_json(capsys):
    assert main(["scenes", "--json"]) == 0
    names = [s["name"] for s in json.loads(capsys.readouterr().out)["scenes"]]
    assert "supp-fig5" in names
    assert main(["show", "supp-fig5", "--set", "drop.area=1.0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["drop"]["area"] == 1.0
    assert out["derived"]["flat_cap"]["chord"] == 2.5
    assert out["derived"]["l_ec"] == 1.0


def test_show_experiment_reports_weber(capsys):
    assert main(["show", "fig3-experiment", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["derived"]["experiment"]["weber"] == pytest.approx(1000 * 0.25 * 1.55e-3 / 0.072)
    assert out["derived"]["l_eg"] == 1.0


@pytest.mark.parametrize(
    "argv",
    [
        ["show", "supp-fig5", "--set", "drop.area=-1"],
        ["show", "supp-fig5", "--set", "drop.aera=1"],
        ["show", "nope"],
        ["show"],
        ["frobnicate"],
    ],
)
def test_bad_input_exit_2_one_line(argv, capsys):
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err.startswith("elastocap: error: ")
    assert cap.err.count("\n") == 1
