"""Output names carry every value that tells runs apart: runs that differ never overwrite
each other; the same command run again replaces its own outputs."""

import argparse
import json

from elastocap.cli import build_parser, main
from elastocap.cli_args import load_scene_from_args, run_suffix
from elastocap.scene import load_scene

FAST = ["--accuracy", "draft", "--progress", "none", "--set", "numerics.t_max=1.0"]


def _suffix(argv, **kw):
    args = build_parser().parse_args(argv)
    return run_suffix(args, load_scene_from_args(args), **kw)


def test_suffix_is_stable_and_tells_values_apart():
    named = ("drop.wetted_length", "drop.center")
    plain = _suffix(["impact", "supp-fig5"], named=named)
    assert plain == ""  # the scene as named: no digest, the name alone says it all
    # a value the name carries makes no digest
    assert _suffix(["impact", "supp-fig5", "--set", "drop.wetted_length=3"], named=named) == ""
    a = _suffix(["impact", "supp-fig5", "--set", "effects.damping=0.1"], named=named)
    assert a.startswith("-s") and len(a) == 9
    # the same values typed otherwise: the same digest; another value: another one
    assert _suffix(["impact", "supp-fig5", "--set", "effects.damping=1e-1"], named=named) == a
    assert _suffix(["impact", "supp-fig5", "--set", "effects.damping=0.2"], named=named) != a
    assert _suffix(["impact", "supp-fig5", "--set", "drop.area=1.2"], named=named) != a
    # setting a key to its default is the scene as named
    assert _suffix(["impact", "supp-fig5", "--set", "drop.area=1.5"], named=named) == ""
    args = argparse.Namespace(scene="supp-fig5", overrides=[], accuracy=None)
    sc = load_scene_from_args(args)
    assert run_suffix(args, sc, extra={"range": [2.0, 4.0]}) != run_suffix(
        args, sc, extra={"range": [2.0, 4.5]})
    assert run_suffix(args, sc, extra={"param": None, "range": None}) == ""


def test_distinct_impacts_never_overwrite_and_a_rerun_replaces(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)

    def run(*extra):
        assert main(["impact", "supp-fig5", *FAST, "--out", "i", "--json", *extra]) == 0
        return json.loads(capsys.readouterr().out)["files"]

    first = run()
    other = run("--set", "effects.damping=0.1")  # same Delta and x, another damping
    assert not set(first) & set(other)
    meta = json.loads((tmp_path / first[1]).read_text())
    # the first run's files are intact: the scene's own damping, not the second run's
    assert meta["scene"]["effects"]["damping"] == load_scene("supp-fig5").effects.damping != 0.1
    files = sorted(p.name for p in (tmp_path / "i").iterdir())
    again = run()
    assert again == first
    assert sorted(p.name for p in (tmp_path / "i").iterdir()) == files


def test_values_equal_to_six_digits_name_different_files(tmp_path, monkeypatch, capsys):
    """The name prints Δ and x to 6 significant digits; a value that does not read back
    from its 6 digits goes into the digest, exactly."""
    monkeypatch.chdir(tmp_path)

    def run(*extra):
        assert main(["impact", "supp-fig5", *FAST, "--out", "i", "--json", *extra]) == 0
        return json.loads(capsys.readouterr().out)

    runs = [run("--set", "drop.wetted_length=2.5"),
            run("--set", "drop.wetted_length=2.5000001"),
            run("--set", "drop.center=2.30000001")]
    names = [r["files"] for r in runs]
    assert all(f[0].startswith("i/impact-supp-fig5-delta2.5-x2.3") for f in names)
    assert len({f for n in names for f in n}) == sum(len(n) for n in names)
    assert runs[0]["final_measure"] != runs[1]["final_measure"]
    # the digest of the exact values is FAST's alone
    assert names[0][0].split("-s")[-1] == run("--set", "numerics.n_edges=0")["files"][0].split(
        "-s")[-1]
    assert run("--set", "drop.wetted_length=2.5000001")["files"] == names[1]  # a rerun
    argv = ["overlay", "supp-fig5", "--delta", "3:3.000001:2", "--out", "o"]
    assert main(argv) == 2
    assert "--delta: got 3:3.000001:2; its values must differ" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_scene_file_named_as_a_built_in_scene_never_overwrites_its_runs(tmp_path,
                                                                          monkeypatch, capsys):
    """A copy of supp-fig5 (same ``name``) with another damping: its own digest; the exact
    copy names the built-in scene's files (the same run); a file scene of its own name is
    digested whole."""
    from importlib import resources

    monkeypatch.chdir(tmp_path)
    text = (resources.files("elastocap") / "scenes" / "supp-fig5.toml").read_text()
    (tmp_path / "same.toml").write_text(text)
    (tmp_path / "damped.toml").write_text(text.replace("damping = 0.2", "damping = 0.5"))
    (tmp_path / "mine.toml").write_text(text.replace('name = "supp-fig5"', 'name = "mine"'))
    names = {s: _suffix(["impact", s]) for s in ("supp-fig5", "same.toml", "damped.toml")}
    assert names["supp-fig5"] == names["same.toml"] == ""
    assert names["damped.toml"].startswith("-s")
    assert _suffix(["impact", "mine.toml"]).startswith("-s")


def test_distinct_overlays_never_overwrite(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)

    def run(*extra):
        argv = ["overlay", "supp-fig5", "--delta", "3.0:4.0:2", *FAST, "--out", "o", "--json"]
        assert main([*argv, *extra]) == 0
        return json.loads(capsys.readouterr().out)["files"]

    first = run()
    other = run("--set", "effects.damping=0.1")
    assert first and other and not set(first) & set(other)
    assert all((tmp_path / f).is_file() for f in first + other)  # both runs' files kept


def test_branches_default_folder_follows_param_range_and_set(tmp_path, monkeypatch):
    """The default branches folder carries a digest of --set, --param and --range (checked
    on the folder the command would use, without tracing)."""
    import elastocap.cli as cli

    seen = []

    class Stop(Exception):
        pass

    def fake_out_folder(args, default_name, kind):
        seen.append(default_name)
        raise Stop

    monkeypatch.setattr(cli, "_out_folder", fake_out_folder)
    for argv in (["branches", "supp-fig5"], ["branches", "supp-fig5", "--range", "2", "4"],
                 ["branches", "supp-fig5", "--param", "drop.area"],
                 ["branches", "supp-fig5", "--set", "drop.area=1.2"],
                 ["branches", "supp-fig5", "--range", "2", "4"]):
        try:
            main(argv)
        except Stop:
            pass
    assert seen[0] == "branches-supp-fig5"
    assert len(set(seen[:4])) == 4 and all(s.startswith("branches-supp-fig5-s") for s in
                                           seen[1:4])
    assert seen[4] == seen[1]
