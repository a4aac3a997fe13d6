"""Output safety: atomic writes, safe stems, a run's ownership of its folder, permissions
checked before the work."""

import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from elastocap.cli import main
from elastocap.io import (
    MANIFEST,
    OutputError,
    OutputFolder,
    atomic_path,
    check_output_folder,
    check_stem,
    write_text,
)

ROOT = os.geteuid() == 0 if hasattr(os, "geteuid") else False


def _tree(path):
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


# ------------------------------------------------------------------------------- atomic
def test_atomic_path_replaces_only_on_success(tmp_path):
    dst = tmp_path / "a.npz"
    with atomic_path(dst) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".npz" and tmp.name.startswith(".a")
        np.savez(tmp, x=np.arange(3))
        assert not dst.exists()  # nothing under the real name until the rename
    assert np.load(dst)["x"].tolist() == [0, 1, 2]
    write_text(tmp_path / "b.json", "old")
    with pytest.raises(RuntimeError):
        with atomic_path(tmp_path / "b.json") as tmp:
            tmp.write_text("half a fi")
            raise RuntimeError("killed")
    assert (tmp_path / "b.json").read_text() == "old"
    assert _tree(tmp_path) == ["a.npz", "b.json"]  # no temporary file left


def test_killed_writer_leaves_no_cut_file(tmp_path):
    """A process killed in the middle of a write leaves the old file whole (SIGKILL)."""
    import signal
    import subprocess
    import sys

    dst = tmp_path / "big.json"
    write_text(dst, "old")
    code = (
        "import os, signal, sys\n"
        "from elastocap.io import atomic_path\n"
        f"with atomic_path({str(dst)!r}) as tmp:\n"
        "    with open(tmp, 'w') as f:\n"
        "        f.write('x' * 100000)\n"
        "        f.flush()\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True)
    assert proc.returncode == -signal.SIGKILL
    assert dst.read_text() == "old"


# ------------------------------------------------------------------------------- stems
@pytest.mark.parametrize(
    "name", ["../../x", "a/b", "a\\b", "..", ".", ".hidden", "", " ", "a\x00b", "C:x", "x" * 121]
)
def test_unsafe_stems_refused(name):
    assert check_stem(name) is not None


@pytest.mark.parametrize("name", ["supp-fig5", "fig3 strip", "Δ=3.5", "a.b_c+d"])
def test_safe_stems_accepted(name):
    assert check_stem(name) is None


def test_scene_named_as_a_path_writes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "w").mkdir()
    scene = tmp_path / "w" / "evil.toml"
    scene.write_text(
        'name = "../../x"\n[rod]\nlength = 4.6\n[drop]\narea = 1.0\nwetted_length = 2.5\n'
    )
    before = _tree(tmp_path.parent)
    for argv in (["branches", str(scene)], ["demo", str(scene), "--out", "D"],
                 ["impact", str(scene)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("elastocap: error: name: got '../../x'") and err.count("\n") == 1
    assert _tree(tmp_path.parent) == before


# ------------------------------------------------------------------------------- ownership
def test_folder_removes_only_its_own_earlier_outputs(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "mine-by-user.txt").write_text("keep")
    f = OutputFolder(out, "branches")
    for k in range(4):
        f.write_text(f"branch_{k}.npz", str(k))
    g = OutputFolder(out, "impact-a")
    g.write_text("impact-a.json", "{}")
    # a second run of the same kind, with fewer files: the stale ones go, nothing else
    h = OutputFolder(out, "branches")
    h.write_text("branch_0.npz", "new")
    assert _tree(out) == sorted([MANIFEST, "branch_0.npz", "impact-a.json", "mine-by-user.txt"])
    assert (out / "branch_0.npz").read_text() == "new"
    runs = json.loads((out / MANIFEST).read_text())["runs"]
    assert runs == {"branches": ["branch_0.npz"], "impact-a": ["impact-a.json"]}


@pytest.mark.parametrize("given, made", [
    ("X/a/../b", "X/b"), ("X/a/b/../../c", "X/c"), ("X/a/..", "X"), ("X/a/./b/..", "X/a")])
def test_dotdot_in_a_new_folder_leaves_no_stray_folder(tmp_path, given, made):
    """``X/a/../b`` means ``X/b``: making it folder by folder would leave an empty ``X/a``."""
    (tmp_path / "X").mkdir()
    f = OutputFolder(tmp_path / given, "branches")
    f.write_text("branches.json", "{}")
    assert (tmp_path / made / "branches.json").is_file()
    assert {str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_dir()} == (
        {"X", made} if made != "X" else {"X"})


@settings(max_examples=30)
@given(parts=st.lists(st.sampled_from(["a", "b", "X", "..", "."]), min_size=1, max_size=7))
def test_any_dotdot_path_makes_its_target_and_only_the_folders_on_the_way(parts):
    """Paths of new and existing names, ``.`` and ``..``: the folder made is the one the
    path names (``os.path.normpath`` of it, no link on the way), and every folder made lies
    on the way to it."""
    with tempfile.TemporaryDirectory() as root:
        root = Path(root)
        (root / "X").mkdir()
        target = os.path.normpath(os.path.join("X", *parts))
        assume(not target.startswith(".."))
        before = set(root.rglob("*"))
        f = OutputFolder(root / "X" / os.path.join(*parts), "branches")
        f.write_text("branches.json", "{}")
        assert (root / target / "branches.json").is_file()
        made = {p.relative_to(root) for p in root.rglob("*") if p.is_dir()} - {
            p.relative_to(root) for p in before}
        on_the_way = {Path(target), *Path(target).parents}
        assert made <= on_the_way, (parts, made)


def test_dotdot_through_an_existing_link_keeps_its_meaning(tmp_path):
    """In the existing part of the path ``..`` is the operating system's: through a symbolic
    link it leads to the link target's parent, which the tidy must not change."""
    (tmp_path / "real" / "inner").mkdir(parents=True)
    (tmp_path / "X").mkdir()
    (tmp_path / "X" / "link").symlink_to(tmp_path / "real" / "inner")
    f = OutputFolder(tmp_path / "X" / "link" / ".." / "new", "branches")
    f.write_text("branches.json", "{}")
    assert (tmp_path / "real" / "new" / "branches.json").is_file()
    assert not (tmp_path / "X" / "new").exists()


def test_manifest_cannot_point_outside(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (out / MANIFEST).write_text(json.dumps({"runs": {"branches": ["../victim.txt", "/etc/x"]}}))
    OutputFolder(out, "branches").write_text("branches.json", "{}")
    assert victim.read_text() == "keep"


def test_stale_branch_files_removed_on_rerun(tmp_path):
    """Re-running into the same folder with fewer branches leaves no stale branch_K."""
    from elastocap.scene import load_scene
    from elastocap.statics.branches import BranchSet, trace_branches

    bs = trace_branches(
        load_scene("supp-fig5", ["numerics.accuracy=draft"]), error_estimates=False
    )
    assert len(bs.branches) >= 3
    bs.save(tmp_path)
    n = len(bs.branches)
    assert (tmp_path / f"branch_{n - 1}.npz").is_file()
    (tmp_path / "notes.txt").write_text("mine")
    fewer = BranchSet(bs.scene, bs.parameter, bs.prange, bs.problem, bs.branches[:2],
                      bs.labels[:2], metadata=bs.metadata)
    fewer.save(tmp_path)
    names = {p.name for p in tmp_path.iterdir()}
    assert {f"branch_{k}.npz" for k in range(2, n)} & names == set()
    assert {"branch_0.npz", "branch_1.npz", "branches.json", "notes.txt"} <= names
    listed = [b["file"] for b in json.loads((tmp_path / "branches.json").read_text())["branches"]]
    assert listed == ["branch_0.npz", "branch_1.npz"]


# ------------------------------------------------------------------------------- permissions
def test_out_is_a_file_refused_before_work(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "f").write_text("x")
    for argv in (["impact", "supp-fig5", "--out", "f"], ["branches", "supp-fig5", "--out", "f"],
                 ["figures", "--only", "supp-fig6", "--out", "f"],
                 ["overlay", "supp-fig5", "--delta", "3:4:2", "--out", "f/sub"],
                 ["demo", "--out", "f"],
                 ["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2", "--out", "f"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("elastocap: error: --out: got 'f"), err
        assert err.count("\n") == 1
    assert _tree(tmp_path) == ["f"]


def test_unwritable_folder_refused(tmp_path, monkeypatch):
    """The probe file cannot be made: refused with the reason (simulated for root, whom
    the mode bits do not stop)."""

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", denied)
    with pytest.raises(OutputError, match=r"--out: got .*not writable \(Permission denied\)"):
        check_output_folder(tmp_path / "new")


@pytest.mark.skipif(ROOT, reason="root is not stopped by a read-only mode")
def test_read_only_folder_and_store_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    ro = tmp_path / "ro"
    ro.mkdir()
    store = tmp_path / "s.sqlite"
    store.write_bytes(b"")
    ro.chmod(0o555)
    store.chmod(0o444)
    try:
        assert main(["impact", "supp-fig5", "--out", "ro"]) == 2
        assert "--out: got 'ro'; the folder is not writable" in capsys.readouterr().err
        assert main(["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2",
                     "--store", str(store), "--out", "o"]) == 2
        assert "--store" in capsys.readouterr().err
    finally:
        ro.chmod(0o755)
    assert list(ro.iterdir()) == []


def test_unwritable_store_refused_before_any_run(tmp_path, monkeypatch, capsys):
    """An existing store that cannot be opened for writing: refused by ``sweep`` before any
    run, naming --store (simulated for root)."""
    import elastocap.io

    monkeypatch.chdir(tmp_path)
    store = tmp_path / "s.sqlite"
    store.write_bytes(b"")

    def denied(path, mode="r", *a, **k):
        if "a" in mode:
            raise PermissionError(13, "Permission denied")
        return open(path, mode, *a, **k)

    monkeypatch.setattr(elastocap.io, "open", denied, raising=False)
    assert main(["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2", "--store",
                 "s.sqlite", "--out", "o"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("elastocap: error: --store: got 's.sqlite'; not writable") and (
        err.count("\n") == 1
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]


def test_figures_only_one_leaves_the_others(tmp_path, monkeypatch, capsys):
    """Each figure owns its files: ``figures --only a`` removes a's stale files, keeps b's.
    (The figure modules are replaced by a fake that writes what it is told.)"""
    import elastocap.paper_figures as pf

    writes = {"a": ["a.png", "a-old.json"], "b": ["b.png"]}

    def fake(out, only=None, fast=False):
        out.mkdir(parents=True, exist_ok=True)  # as run_figures does
        for n in writes[only]:
            (out / n).write_text(only)
        return {only: [out / n for n in writes[only]]}

    monkeypatch.setattr(pf, "FIGURES", {"a": "a", "b": "b"})
    monkeypatch.setattr(pf, "run_figures", fake)
    monkeypatch.chdir(tmp_path)
    assert main(["figures", "--out", "F", "--progress", "none"]) == 0
    writes["a"] = ["a.png"]
    assert main(["figures", "--only", "a", "--out", "F", "--progress", "none"]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in (tmp_path / "F").iterdir()) == [MANIFEST, "a.png", "b.png"]
