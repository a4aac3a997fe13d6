"""Results out: ``elastocap.sweep.load`` returns the store's runs as a DataFrame (checked
against the store's own rows), ``--export`` writes CSV / Parquet atomically, a missing
pandas is a clear error, and a refused export writes nothing."""

import json
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import sweep_fakes as fk

from elastocap.scene import load_scene
from elastocap.sweep import ResultStore, export_runs, load, run_sweep
from elastocap.sweep.executors import MissingExtraError

pd = pytest.importorskip("pandas")
STRIP = load_scene("fig3-strip", {"numerics.accuracy": "draft"})


@pytest.fixture
def store(tmp_path):
    path = tmp_path / "s.sqlite"
    with ThreadPoolExecutor(2) as ex:
        run_sweep(STRIP, [1.0, 2.0], we_sqrts=[1.0, 2.0, 3.0], store=path, refine_tol=0.2,
                  executor=ex, run_fn=fk.undecided_band_run)
    return path


def test_load_returns_every_run_as_the_store_has_it(store, tmp_path):
    df = load(store)
    with ResultStore(store) as st:
        rows = st.rows()
    assert len(df) == len(rows) > 6
    assert list(df["scene_digest"]) == [r["scene_digest"] for r in rows]
    assert list(df["outcome"]) == [r["outcome"] for r in rows]
    assert set(df["outcome"]) == {"open", "undecided", "encapsulated"}
    und = df[df["outcome"] == "undecided"]
    assert (und["reason"] == "the bundle crossed itself before coming to rest").all()
    np.testing.assert_array_equal(df["we_sqrt"].to_numpy(), [r["we_sqrt"] for r in rows])
    assert "final_positions" not in df and df["n_edges"].nunique() == 1
    # a typical analysis: the largest open and smallest encapsulated We^1/2 per line
    g = df.groupby(["x_over_leg", "outcome"])["we_sqrt"]
    assert g.max()[(1.0, "open")] < 1.53 <= g.min()[(1.0, "undecided")]
    # loading writes nothing: no -wal / -shm files next to a closed store
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]


def test_export_csv_and_parquet_round_trip(store, tmp_path):
    df = load(store)
    csv = export_runs(store, tmp_path / "runs.csv")
    back = pd.read_csv(csv)
    assert list(back.columns) == list(df.columns) and len(back) == len(df)
    np.testing.assert_array_equal(back["wetted_length"].to_numpy(),
                                  df["wetted_length"].to_numpy())  # full precision
    pytest.importorskip("pyarrow")
    pq = export_runs(store, tmp_path / "runs.parquet")
    back = pd.read_parquet(pq)
    assert list(back["scene_digest"]) == list(df["scene_digest"])
    # the flag stays a boolean column with its missing values
    assert df["decided_after_crossing"].dtype == "boolean"
    assert back["decided_after_crossing"].dtype == "boolean"
    assert back["decided_after_crossing"].equals(df["decided_after_crossing"])
    assert not list(tmp_path.glob(".*tmp"))  # the temporary files are gone


def test_missing_pandas_is_a_clear_error(store, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(MissingExtraError, match=r"pip install 'elastocap\[export\]'"):
        load(store)


def test_the_command_exports_and_refuses_bad_export_names_writing_nothing(tmp_path,
                                                                           monkeypatch, capsys):
    from elastocap.sweep.__main__ import main

    monkeypatch.chdir(tmp_path)
    code = main(["fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--export", "runs.xlsx"])
    err = capsys.readouterr().err
    assert code == 2 and "--export: got 'runs.xlsx'; expected a file name ending in .csv or " \
        ".parquet" in err
    (tmp_path / "f").write_text("a file")  # the one file here: nothing else may appear
    code = main(["fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--export", "f/runs.csv"])
    assert code == 2 and "this is a file; expected a folder" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "pandas", None)
    code = main(["fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--export", "runs.csv"])
    assert code == 2 and "elastocap[export]" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["f"]


@pytest.mark.slow
def test_the_command_writes_the_export(tmp_path, capsys):
    from elastocap.sweep.__main__ import main

    out = tmp_path / "o"
    code = main(["fig3-strip", "--x", "2:2:1", "--we", "1:3:2", "--workers", "1",
                 "--progress", "none", "--accuracy", "draft", "--set", "numerics.t_max=5.0",
                 "--out", str(out), "--export", str(tmp_path / "runs.csv"), "--json"])
    rep = json.loads(capsys.readouterr().out)
    assert code == 0 and str(tmp_path / "runs.csv") in rep["files"]
    assert len(pd.read_csv(tmp_path / "runs.csv")) == rep["counts"]["runs"] == 2


def test_load_refuses_what_is_not_a_store_and_writes_nothing(tmp_path):
    """An empty file and another SQLite database: StoreError naming the file, both left
    as they were (no tables added, no -wal / -shm)."""
    from elastocap.sweep.store import StoreError

    empty = tmp_path / "empty.sqlite"
    empty.write_bytes(b"")
    other = tmp_path / "other.sqlite"
    fk.execute_sql(other, "CREATE TABLE t (a)")
    before = other.read_bytes()
    for path in (empty, other):
        with pytest.raises(StoreError, match=f"store '{path}'"):
            load(path)
    assert empty.read_bytes() == b"" and other.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.sqlite", "other.sqlite"]


def test_load_refuses_a_run_with_an_outcome_no_run_has(store):
    from elastocap.sweep.store import StoreError

    fk.execute_sql(store, "UPDATE runs SET outcome = 'banana' WHERE id = (SELECT MIN(id) "
                   "FROM runs)")
    with pytest.raises(StoreError,
                       match="has outcome 'banana'; expected one of open, encapsulated, undecided"):
        load(store)
