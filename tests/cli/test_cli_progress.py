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
