"""The sweep command (``python -m elastocap.sweep``, the same handler as ``elastocap
sweep``): bad input exits 2 with one line naming option, value and what is allowed, and
writes nothing; a real run prints one JSON object with runs and boundary."""

import json

import pytest

from elastocap.scene import SceneError
from elastocap.sweep.__main__ import main

BASE = ["--progress", "none", "--workers", "2", "--set", "numerics.accuracy=draft",
        "--set", "numerics.t_max=5.0"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["fig3-strip", "--x", "1:3", "--we", "1:2:2"], "--x: got '1:3'; expected LO:HI:N"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:0"], "--we: got '1:2:0'; N = 0 < 1"),
        (["fig3-strip", "--x", "3:1:4", "--we", "1:2:2"], "--x: got '3:1:4'; LO = 3 > HI = 1"),
        (["fig3-strip", "--x", "1:3:2", "--delta", "x:1:2"], "--delta: got 'x:1:2'"),
        (["nope", "--x", "1:3:2", "--we", "1:2:2"], "scene: got 'nope'; not a built-in scene"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--set", "drop.wetted_length=1"],
         "drop.wetted_length: got 1; set by the sweep"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--set", "drop.aera=1"],
         "drop.aera: got 1; unknown key"),
        (["supp-fig5", "--x", "1:3:2", "--we", "1:2:2"],
         "--we: got '1:2:2'; scene 'supp-fig5' has no [spreading] law"),
        (["fig3-experiment", "--x", "1:3:2", "--we", "1:2:2"], "an [experiment] scene"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--workers", "0"],
         "--workers: got 0; expected an integer from 1 to "),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--refine", "-1"],
         "--refine: got -1.0; expected a finite number > 0"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--scheduler", "localhost"],
         "--scheduler: got 'localhost'; expected a dask scheduler address"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--experiments", "missing.csv"],
         "--experiments: got 'missing.csv'; no such file"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--converge", "0"],
         "--converge: got 0; expected an integer from 1 to 4"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--verify", "--converge", "2"],
         "not allowed with argument"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--verify", "--every-level"],
         "--every-level: needs --converge K"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--export", "r.txt"],
         "--export: got 'r.txt'; expected a file name ending in .csv or .parquet"),
        (["fig3-strip", "--x", "1:3:2"], "one of the arguments --we --delta is required"),
        (["fig3-strip", "--x", "1:3:2", "--we", "1:2:2", "--delta", "1:2:2"],
         "not allowed with argument"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_writes_nothing(argv, message, tmp_path,
                                                            monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.startswith("elastocap: error: ") and message in err, err
    assert err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []  # no store, no out/ directory


def test_run_raises_for_the_cli_to_map(tmp_path):
    import argparse

    from elastocap.sweep import cli

    p = argparse.ArgumentParser()
    cli.add_arguments(p)
    args = p.parse_args(["nope", "--x", "1:2:2", "--we", "1:2:2", "--out", str(tmp_path / "o")])
    with pytest.raises(SceneError, match="scene: got 'nope'"):
        cli.run(args)
    args = p.parse_args(["fig3-strip", "--x", "1:2:0", "--we", "1:2:2"])
    with pytest.raises(ValueError, match="--x: got '1:2:0'"):
        cli.run(args)
    assert not (tmp_path / "o").exists()


def test_json_run_has_runs_and_boundary(tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["fig3-strip", "--x", "2:3:2", "--we", "0.5:3:2", "--refine", "1.0",
                 "--out", str(out), "--json", *BASE])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    rep = json.loads(stdout)
    assert len(rep["runs"]) == rep["counts"]["runs"] >= 4
    for r in rep["runs"]:
        assert {"x", "we_sqrt", "wetted_length", "outcome", "companion_outcome"} <= set(r)
        # t_max = 5 may stop a run before rest: then it is undecided, with its reason
        assert r["outcome"] in ("open", "encapsulated", "undecided")
        assert (r["outcome"] == "undecided") == bool(r.get("reason"))
    assert [b["x"] for b in rep["boundary"]] == [2.0, 3.0]
    for b in rep["boundary"]:
        assert {"x", "we_sqrt_low", "we_sqrt_high", "status"} <= set(b)
        if b["status"] == "bracketed":
            assert b["we_sqrt_high"] - b["we_sqrt_low"] <= 1.0
    assert rep["x_unit"] == "l_eg" and rep["variable"] == "we_sqrt"
    # every --set override is recorded (and drawn in the plot's title from it)
    assert rep["overrides"] == ["numerics.accuracy=draft", "numerics.t_max=5.0"]
    assert rep["resolution"]["n_edges"] == 80  # draft at the largest Delta (We^1/2 = 3)
    for f in ("sweep.sqlite", "sweep.json", "phase-diagram.png"):
        assert (out / f).stat().st_size > 0
    assert json.loads((out / "sweep.json").read_text())["runs"] == rep["runs"]
    # again, text output: everything from the store
    code = main(["fig3-strip", "--x", "2:3:2", "--we", "0.5:3:2", "--refine", "1.0",
                 "--out", str(out), *BASE])
    text = capsys.readouterr().out
    assert code == 0
    n = rep["counts"]["runs"]
    assert f"{n} runs (0 computed, {n} from the store)" in text.splitlines()[0]


def test_a_file_that_is_not_a_store_exits_2_and_is_left_alone(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("not a database " * 100)
    code = main(["fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--store", "notes.txt"])
    err = capsys.readouterr().err
    assert code == 2 and "--store: store 'notes.txt': not a usable sweep store" in err
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]
    assert (tmp_path / "notes.txt").read_text() == "not a database " * 100


def test_missing_dask_names_the_extra(tmp_path, monkeypatch, capsys):
    import sys

    from elastocap.sweep.executors import MissingExtraError, check_scheduler

    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    with pytest.raises(MissingExtraError, match=r"pip install 'elastocap\[distributed\]'"):
        check_scheduler("tcp://127.0.0.1:8786")
    monkeypatch.chdir(tmp_path)
    code = main(["fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--scheduler",
                 "tcp://127.0.0.1:8786"])
    err = capsys.readouterr().err
    assert code == 2 and "needs dask.distributed" in err and "elastocap[distributed]" in err
    assert list(tmp_path.iterdir()) == []


def test_text_report_marks_every_line_verified_or_not(tmp_path, capsys):
    from concurrent.futures import ThreadPoolExecutor

    import sweep_fakes as fk

    from elastocap.jsonutil import jsonable
    from elastocap.scene import load_scene
    from elastocap.sweep import cli, run_sweep

    scene = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
    with ThreadPoolExecutor(2) as ex:
        res = run_sweep(scene, [0.5, 1.0, 3.0], we_sqrts=[0.5, 1.5, 2.5, 3.5],
                        store=tmp_path / "s.sqlite", refine_tol=0.02, executor=ex,
                        run_fn=fk.coarse_shift_run, verify_levels=1)
    cli._print_text(jsonable(res.to_dict()), [])
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("  x = ")]
    # x = 0.5: only We^1/2 = 0.5 fits on the strip (open); x = 1: threshold 1.53, holds;
    # x = 3: moves by -0.3
    assert len(lines) == 3
    assert "all-open" in lines[0]
    assert "NOT verified: line is all-open, no change from open" in lines[0]
    assert "verified: holds at 1.5x the edges" in lines[1]
    assert "NOT verified: moved, the bracket midpoint moves by -0.3" in lines[2]
    assert "[level 1: 117 edges]" in lines[2]  # 1.5 x 78 (4 edges across Delta(0.5))
