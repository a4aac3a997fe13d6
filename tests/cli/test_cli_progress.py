"""Progress on stderr: one protocol (none / text / tqdm) for every long command."""

import io
import time

import pytest

from elastocap.cli import main
from elastocap.progress import NoProgress, TextProgress, heartbeat, make_progress


def test_text_progress_lines_and_unknown_total():
    s = io.StringIO()
    p = TextProgress(stream=s, every=0.0, label="branches", unit="steps")
    p(0, 0, "tracing")
    p(1, 2, "writing")
    p.close()  # the last state was written: no repeat
    assert s.getvalue().splitlines() == ["branches: 0 steps tracing", "branches: 1/2 steps writing"]


def test_sweep_progress_unchanged():
    s = io.StringIO()
    p = TextProgress(stream=s)
    p(3, 10, "x = 2")
    p(4, 10, "x = 3")  # within 2 s: held back, written by close
    p.close()
    assert s.getvalue().splitlines() == ["sweep: 3/10 runs x = 2", "sweep: 4/10 runs x = 3"]


def test_heartbeat_reports_elapsed_time_of_a_long_phase():
    s = io.StringIO()
    p = TextProgress(stream=s, every=0.0, label="demo", unit="steps")
    with heartbeat(p, 0, 4, "tracing", every=0.05):
        time.sleep(0.3)
    lines = s.getvalue().splitlines()
    assert lines[0] == "demo: 0/4 steps tracing"
    assert len(lines) >= 3 and all(ln.startswith("demo: 0/4 steps tracing (") for ln in lines[1:])
    with heartbeat(NoProgress(), 0, 1, "quiet", every=0.01):  # no thread for silence
        pass


def test_make_progress_choices():
    assert isinstance(make_progress("none"), NoProgress)
    assert isinstance(make_progress("text", label="x"), TextProgress)
    with pytest.raises(ValueError, match="--progress: got 'bar'"):
        make_progress("bar")


def test_folds_reports_its_phases(capsys):
    assert main(["folds", "supp-fig5", "--accuracy", "draft", "--range", "3.0", "4.0",
                 "--progress", "text", "--json"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("folds: 0/1 steps tracing the branches of supp-fig5")
    assert err[-1].startswith("folds: 1/1 steps folds located: ")


def _stopping(what):
    """A stand-in for a command's long work: it announces a compilation on the "dynamics"
    logger, as the driver does, and stops the command (exit 2)."""
    import logging

    from elastocap.scene import SceneError

    def fake(*a, **k):
        logging.getLogger("dynamics").info("compiling the test stepper for %s", what)
        raise SceneError("test.stop", what, "stopped by the test")

    return fake


@pytest.mark.parametrize("argv,module,name", [
    (["impact", "supp-fig5", "--accuracy", "draft"], "elastocap.impact", "run_impact"),
    (["demo", "--accuracy", "draft"], "elastocap.statics.branches", "trace_branches"),
    (["overlay", "supp-fig5", "--accuracy", "draft", "--delta", "3:4:2"], "elastocap.overlay",
     "run_overlay"),
    (["figures", "--only", "supp-fig6", "--fast"], "elastocap.paper_figures", "run_figures"),
    (["sweep", "fig3-strip", "--x", "2:3:2", "--delta", "1:1.5:2", "--accuracy", "draft",
      "--workers", "1"], "elastocap.sweep.engine", "run_sweep"),
])
def test_compile_announcements_reach_every_long_command(tmp_path, monkeypatch, capsys, argv,
                                                       module, name):
    import importlib
    import logging

    # modules that bind these functions by name at import are imported before the patch
    importlib.import_module("elastocap.overlay")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(importlib.import_module(module), name, _stopping(argv[0]))
    assert main([*argv, "--progress", "text", "--out", "o"]) == 2
    err = capsys.readouterr().err
    assert f"elastocap: compiling the test stepper for {argv[0]}" in err
    assert not logging.getLogger("dynamics").handlers  # removed after the command
    if argv[0] == "sweep":  # the local workers' compilation is said up front
        assert "sweep: the local workers compile the impact stepper on first use" in err


def test_impact_reports_its_phases(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["impact", "supp-fig5", "--accuracy", "draft", "--set", "numerics.t_max=1.0",
                 "--progress", "text", "--json"]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("impact:")]
    assert err[0].startswith("impact: 0/2 steps running the impact of supp-fig5")
    assert err[-1] == "impact: 2/2 steps done"


FAST = ["--accuracy", "draft", "--progress", "text", "--json"]


@pytest.mark.parametrize("argv,first,last", [
    (["branches", "fig3-strip", "--range", "1.0", "1.2", *FAST],
     "branches: 0/2 steps tracing the branches of fig3-strip", "branches: 2/2 steps done"),
    (["overlay", "supp-fig5", "--set", "numerics.t_max=1.0", "--delta", "3:4:2", *FAST],
     "overlay: 0/1 steps tracing the statics of supp-fig5, then 2 impacts",
     "overlay: 1/1 steps done"),
    (["demo", "--set", "numerics.t_max=1.0", *FAST],
     "demo: 0/4 steps tracing the branches", "demo: 4/4 steps done"),
], ids=["branches-strip", "overlay", "demo"])
def test_long_commands_report_their_phases(tmp_path, monkeypatch, capsys, argv, first, last):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--out", "o"]) == 0
    name = argv[0]
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith(f"{name}:")]
    assert err[0].startswith(first), err
    assert err[-1] == last
    if name == "branches":  # the strip tracer's own lines, between the two
        assert any("traced deposition at Delta" in ln for ln in err[1:-1]), err
    if name == "demo":
        assert [ln.split(" steps ")[0] for ln in err] == [f"demo: {k}/4" for k in range(5)]


def test_figures_reports_each_figure(tmp_path, monkeypatch, capsys):
    """One line per figure and a last one (the drawing itself replaced: instant)."""
    import elastocap.paper_figures as pf

    monkeypatch.setattr(pf, "run_figures", lambda out, only, fast: {only: []})
    monkeypatch.chdir(tmp_path)
    assert main(["figures", "--only", "supp-fig6", "--fast", "--progress", "text",
                 "--out", "f"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == ["figures: 0/1 steps drawing supp-fig6", "figures: 1/1 steps done"]
