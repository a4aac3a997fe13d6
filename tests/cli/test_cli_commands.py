"""The command line never lies: every subcommand and every option of the parser is run
in-process on a small scene; the README's command table is checked against the parser;
saved results reload and redraw without recomputing."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from elastocap.cli import command_options, main

DRAFT = ["--accuracy", "draft", "--progress", "none"]
SHORT = ["--set", "numerics.t_max=3.0"]
#: The digest in the impact names of DRAFT + SHORT runs (t_max and accuracy are not in the
#: name): a stable digest, the same on every machine and run.
SFX = "-s7ca8da1"

#: Each documented command, run in this order in one folder (later ones read earlier
#: outputs). Together they use every option of every subcommand but those in EXEMPT.
DOCUMENTED = [
    ["scenes", "--json"],
    ["show", "supp-fig5", "--set", "drop.area=1.2", "--accuracy", "draft", "--json"],
    ["branches", "supp-fig5", *DRAFT, "--param", "drop.wetted_length", "--range", "2.0", "4.6",
     "--set", "drop.line_tension=1.0", "--out", "b", "--force", "--json"],
    ["folds", "supp-fig5", *DRAFT, "--param", "drop.wetted_length", "--range", "2.0", "4.6",
     "--set", "drop.line_tension=1.0", "--json"],
    ["folds", "supp-fig5", *DRAFT, "--range", "2.0", "4.6", "--check", "b/branches.json",
     "--rtol", "1e-8", "--force"],
    ["folds", "supp-fig5", *DRAFT, "--curve", "drop.area", "1.3", "1.5", "--out", "fc",
     "--json"],
    ["impact", "supp-fig5", *DRAFT, *SHORT, "--frames", "3", "--out", "i", "--json"],
    ["impact", "supp-fig5", *DRAFT, *SHORT, "--set", "drop.wetted_length=3.0", "--out", "i",
     "--force"],
    ["overlay", "supp-fig5", *DRAFT, *SHORT, "--delta", "3.0:4.0:2", "--out", "o", "--force",
     "--json"],
    ["sweep", "fig3-strip", "--x", "2:3:2", "--delta", "1.0:1.5:2", "--set",
     "numerics.accuracy=draft", "--set", "numerics.t_max=5.0", "--workers", "1", "--progress",
     "none", "--out", "s", "--store", "s/store.sqlite", "--verify", "--export",
     "s/runs.csv", "--force", "--json"],
    ["sweep", "fig3-strip", "--x", "2:3:2", "--we", "0.5:1.5:2", "--refine", "1.0",
     "--accuracy", "draft", "--set", "numerics.t_max=5.0", "--workers", "1", "--progress",
     "none", "--experiments", "exp.csv", "--out", "s2"],
    ["figures", "--only", "supp-fig6", "--fast", "--out", "f", "--progress", "none", "--json"],
    ["demo", "supp-fig5", *DRAFT, *SHORT, "--out", "d", "--force", "--json"],
    ["plot", "b", "--json"],
    ["plot", f"i/impact-supp-fig5-delta2.5-x2.3{SFX}.npz", "--frames", "4", "--out", "replot"],
    ["plot", "s", "--json"],
    ["cache", "info", "--json"],
]
#: Options not run here, each with where it is tested.
EXEMPT = {
    ("sweep", "--scheduler"): "a dask cluster: tests/sweep (a real LocalCluster)",
    ("sweep", "--converge"): "levels of verification: tests/sweep/test_sweep_resolution.py",
    ("sweep", "--every-level"): "with --converge: tests/sweep/test_sweep_threshold.py",
}


def _options_used(argv):
    return {a for a in argv[1:] if a.startswith("--")}


def test_documented_commands_cover_every_subcommand_and_option():
    opts = command_options()
    used = {}
    for argv in DOCUMENTED:
        used.setdefault(argv[0], set()).update(_options_used(argv))
    assert set(used) == set(opts), set(opts) ^ set(used)
    missing = [(c, o) for c, os_ in opts.items() for o in os_
               if o not in used[c] and (c, o) not in EXEMPT]
    assert not missing, missing
    unknown = [(c, o) for c, os_ in used.items() for o in os_ if o not in opts[c]]
    assert not unknown, unknown


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """Every documented command, run in one folder: (argv, exit code, stdout, stderr)."""
    import contextlib
    import io
    import os

    work = tmp_path_factory.mktemp("cmds")
    (work / "exp.csv").write_text("x_over_leg,we_sqrt,outcome\n2.0,1.0,open\n")
    old = os.getcwd()
    os.chdir(work)
    results = []
    try:
        for argv in DOCUMENTED:
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(list(argv))
            results.append((argv, code, out.getvalue(), err.getvalue()))
    finally:
        os.chdir(old)
    return work, results


def test_every_documented_command_runs(ran):
    _, results = ran
    bad = [(" ".join(a), c, e[-300:]) for a, c, _, e in results if c != 0]
    assert not bad, bad
    for argv, _, out, _ in results:
        if "--json" in argv:
            json.loads(out)  # one JSON object on stdout


def test_outputs_are_where_the_command_says(ran):
    work, results = ran
    by = {}
    for a, _, o, _ in results:
        if "--json" in a:
            by.setdefault(" ".join(a[:2]), json.loads(o))  # the first run of each
    for f in by["branches supp-fig5"]["files"] + by["impact supp-fig5"]["files"]:
        assert (work / f).is_file() and (work / f).stat().st_size > 0, f
    # the files listed include every branch file the command wrote (its manifest)
    listed = {Path(f).name for f in by["branches supp-fig5"]["files"]}
    folder = Path(by["branches supp-fig5"]["files"][0]).parent
    folder = folder if folder.is_absolute() else work / folder
    written = json.loads((folder / ".elastocap-outputs.json").read_text())["runs"]["branches"]
    assert set(written) <= listed and any(n.endswith(".json") and n.startswith("branch_")
                                          for n in listed)
    # impact names carry the values that distinguish runs: two Deltas, two sets of files
    names = sorted(p.name for p in (work / "i").iterdir() if not p.name.startswith("."))
    assert names == sorted(
        f"impact-supp-fig5-delta{d}-x2.3{SFX}{ext}"
        for d in ("2.5", "3") for ext in (".npz", ".json", "-frames.png")
    )
    meta = json.loads((work / "i" / f"impact-supp-fig5-delta3-x2.3{SFX}.json").read_text())
    assert meta["parameters"]["drop.wetted_length"] == 3.0
    assert meta["scene"]["drop"]["wetted_length"] == 3.0
    # the branches record their parameter by its scene key
    br = json.loads((work / "b" / "branch_0.json").read_text())
    assert br["parameter"] == "drop.wetted_length"
    assert by["branches supp-fig5"]["parameter"] == "drop.wetted_length"
    # no temporary or staging file is left anywhere
    leftovers = [p for p in work.rglob(".*") if ".tmp-" in p.name or "staging" in p.name]
    assert not leftovers


def test_impact_default_out_is_written(tmp_path, monkeypatch, capsys):
    """``impact --help`` promises a default --out: it is written there."""
    monkeypatch.chdir(tmp_path)
    assert main(["impact", "supp-fig5", *DRAFT, *SHORT, "--json"]) == 0
    files = json.loads(capsys.readouterr().out)["files"]
    assert all(f.startswith("out/impact-supp-fig5/") for f in files)
    assert all((tmp_path / f).is_file() for f in files)


def test_redraw_is_the_same_figure_without_recomputing(ran, monkeypatch):
    """``plot`` rebuilds the figures from the files alone: the tracer and the impact engine
    are not called, and the frame strip is pixel-identical to the one the run drew."""
    import matplotlib.image as mpimg

    import elastocap.impact
    import elastocap.statics.branches

    work, _ = ran

    def forbidden(*a, **k):
        raise AssertionError("recomputed")

    monkeypatch.setattr(elastocap.statics.branches, "trace_branches", forbidden)
    monkeypatch.setattr(elastocap.impact, "run_impact", forbidden)
    monkeypatch.chdir(work)
    assert main(["plot", f"i/impact-supp-fig5-delta2.5-x2.3{SFX}.npz", "--frames", "3",
                 "--out", "again"]) == 0
    a = mpimg.imread(work / "i" / f"impact-supp-fig5-delta2.5-x2.3{SFX}-frames.png")
    b = mpimg.imread(work / "again" / f"impact-supp-fig5-delta2.5-x2.3{SFX}-frames.png")
    assert a.shape == b.shape and np.array_equal(a, b)
    assert main(["plot", "b", "--out", "again"]) == 0
    assert (work / "again" / "branches.png").stat().st_size > 0


def test_branch_set_reloads_identically(ran):
    from elastocap.statics.branches import BranchSet
    from elastocap.testing import assert_folds

    work, results = ran
    rep = json.loads(next(o for a, _, o, _ in results if a[0] == "branches"))
    bs = BranchSet.load(work / "b")
    assert bs.parameter == "drop.wetted_length" and bs.scene.name == "supp-fig5"
    saved = json.loads((work / "b" / "branches.json").read_text())
    assert len(bs.branches) == len(saved["branches"]) >= 3
    assert [f["value"] for f in bs.folds] == [f["value"] for f in rep["folds"]]
    assert all(b.parameter == "drop.wetted_length" for b in bs.branches)
    # the reloaded problem is the traced one: each stored point still solves it (residual)
    br = bs.branches[0]
    i = len(br) // 2
    assert np.max(np.abs(bs.problem.residual(br.u[i], float(br.p[i])))) < 1e-8
    # assert_folds takes the reloaded set, the saved JSON, and a JSON round trip of the list
    assert_folds(bs, work / "b" / "branches.json")
    assert_folds(json.loads(json.dumps(rep["folds"])), bs)


def test_plot_refuses_what_it_cannot_redraw(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.txt").write_text("x")
    for argv in (["plot", "nope"], ["plot", "x.txt"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("elastocap: error: PATH: got ") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.txt"]


def test_plot_refuses_damaged_files_and_never_writes_into_what_it_reads(tmp_path, monkeypatch,
                                                                        capsys):
    """A truncated impact .npz, a sweep.json with an outcome no run has, an SQLite file
    that is not a store (left byte for byte as it was): one-line errors, exit 2, nothing
    written."""
    import sqlite3

    monkeypatch.chdir(tmp_path)
    assert main(["impact", "supp-fig5", "--accuracy", "draft", "--set", "numerics.t_max=1",
                 "--out", "i", "--progress", "none"]) == 0
    capsys.readouterr()
    npz = next((tmp_path / "i").glob("*.npz"))
    (tmp_path / "trunc.npz").write_bytes(npz.read_bytes()[:4000])
    sw = tmp_path / "sw"
    sw.mkdir()
    (sw / "sweep.json").write_text(json.dumps(
        {"scene": "fig3-strip", "runs": [{"x": 1.0, "we_sqrt": 1.0, "outcome": "banana"}]}))
    con = sqlite3.connect(tmp_path / "mine.sqlite")
    con.execute("CREATE TABLE t (a)")
    con.commit()
    con.close()
    before = (tmp_path / "mine.sqlite").read_bytes()
    for argv, text in ((["plot", "trunc.npz", "--out", "o"], "not a readable .npz file"),
                       (["plot", "sw", "--out", "o"], "runs[0]: outcome = 'banana'"),
                       (["plot", "mine.sqlite", "--out", "o"], "without the sweep tables")):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("elastocap: error: PATH: ") and text in err, err
        assert err.count("\n") == 1
    assert not (tmp_path / "o").exists()
    assert (tmp_path / "mine.sqlite").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["i", "mine.sqlite", "sw",
                                                           "trunc.npz"]


# ------------------------------------------------------------------------------- README
def _readme_commands(text):
    """The lines of the fenced block after the heading ``## Commands``: command -> options."""
    m = re.search(r"^## Commands\s*$(.*?)^```[^\n]*\n(.*?)^```", text, re.M | re.S)
    assert m, "README.md has no fenced block under a heading '## Commands'"
    table, current = {}, None
    for line in m.group(2).splitlines():
        head = re.match(r"\s*(?:\$\s*)?elastocap\s+([a-z][a-z-]*)", line)
        if head:
            current = head.group(1)
            table.setdefault(current, set())
        if current is not None:
            table[current].update(re.findall(r"(?<![\w-])--[a-z][a-z-]*", line))
    return table


def test_readme_command_table_matches_the_parser():
    readme = Path(__file__).resolve().parents[2] / "README.md"
    table = _readme_commands(readme.read_text(encoding="utf-8"))
    opts = command_options()
    assert set(opts) <= set(table), f"missing from the README: {set(opts) - set(table)}"
    assert set(table) <= set(opts), f"not commands: {set(table) - set(opts)}"
    wrong = {c: sorted(o - set(opts[c])) for c, o in table.items() if o - set(opts[c])}
    assert not wrong, f"options the parser does not have: {wrong}"


def test_readme_table_reader_on_a_sample():
    sample = (
        "# x\n## Commands\n\n```\nelastocap scenes [--json]\nelastocap overlay SCENE "
        "--delta LO:HI:N\n          [--out DIR]\n```\n"
    )
    assert _readme_commands(sample) == {"scenes": {"--json"}, "overlay": {"--delta", "--out"}}


# ------------------------------------------------------------------------------- packaging
def test_python_dash_m_and_cheap_import(tmp_path):
    code = subprocess.run([sys.executable, "-m", "elastocap", "--help"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert code.returncode == 0 and "overlay" in code.stdout and "plot" in code.stdout
    probe = ("import sys, elastocap; heavy = [m for m in ('numpy', 'numba', 'scipy', "
             "'matplotlib') if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True,
                         text=True)
    assert out.stdout.strip() == "[]", out


def test_main_api_exported():
    import elastocap

    for name in ("load_scene", "trace_branches", "find_folds", "run_impact", "run_overlay",
                 "run_sweep", "assert_folds"):
        assert callable(getattr(elastocap, name)), name
        assert name in elastocap.__all__ and name in dir(elastocap)
    with pytest.raises(AttributeError):
        elastocap.nope  # noqa: B018


def test_license_and_citation():
    root = Path(__file__).resolve().parents[2]
    assert (root / "LICENSE").read_text().startswith("MIT License")
    cff = (root / "CITATION.cff").read_text()
    assert "10.1073/pnas.1101738108" in cff and "cff-version: 1.2.0" in cff
    assert (root / "CHANGELOG.md").is_file()
