"""The SQLite result store: one row per run, the unique key, atomic rows, concurrent
writers (separate processes) without corruption or duplicates."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sweep_fakes as fk

from elastocap.sweep.store import COLUMNS, ResultStore, StoreError


def _row(i: int, **kw) -> dict:
    row = {
        "scene_digest": f"{i:064x}",
        "version": "9.9",
        "runner": "test",
        "scene_name": "s",
        "scene_json": "{}",
        "x": float(i),
        "x_over_leg": float(i),
        "we_sqrt": 0.5 * i,
        "wetted_length": 1.0 + i,
        "outcome": "open",
        "companion_outcome": "encapsulated",
        "final_measure": 0.25,
        "status": "completed",
        "final_positions": np.arange(6.0).reshape(3, 2) * i,
        "decided_after_crossing": True,
    }
    row.update(kw)
    return row


def test_round_trip_and_unique_key(tmp_path):
    with ResultStore(tmp_path / "s.sqlite") as st:
        assert st.put(_row(1)) is True
        assert st.put(_row(1, outcome="encapsulated")) is False  # same key: kept, not replaced
        assert st.put(_row(1, version="9.10")) is True  # another version is another run
        assert st.count() == 2
        r = st.get(f"{1:064x}", "9.9", "test")
        assert r["outcome"] == "open" and r["companion_outcome"] == "encapsulated"
        np.testing.assert_array_equal(r["final_positions"], np.arange(6.0).reshape(3, 2))
        assert r["decided_after_crossing"] is True
        assert r["created_utc"].endswith("+00:00") and r["host"]
        assert st.integrity() == "ok"
        mode = st._con.execute("PRAGMA journal_mode").fetchone()[0]
        assert mode == "wal"
        got = st.get_many([f"{i:064x}" for i in range(3)], "9.9", "test")
        assert list(got) == [f"{1:064x}"]
        assert {n for n, _ in COLUMNS} <= set(st.rows()[0]) | {"final_positions"}


def test_incomplete_row_is_refused_and_nothing_written(tmp_path):
    with ResultStore(tmp_path / "s.sqlite") as st:
        bad = _row(2)
        del bad["outcome"]
        with pytest.raises(ValueError, match="row: missing outcome"):
            st.put(bad)
        assert st.count() == 0


def test_other_schema_and_non_sqlite_files_are_refused(tmp_path):
    p = tmp_path / "s.sqlite"
    ResultStore(p).close()
    fk.execute_sql(p, "UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    with pytest.raises(StoreError, match="schema version 99, this elastocap writes version 3"):
        ResultStore(p)
    with pytest.raises(StoreError, match="schema version 99"):
        ResultStore.check(p)
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"not a database at all" * 100)
    with pytest.raises(StoreError, match="not a usable sweep store"):
        ResultStore(junk)
    with pytest.raises(StoreError, match="not a usable sweep store"):
        ResultStore.check(junk)
    other = tmp_path / "other.sqlite"
    fk.execute_sql(other, "CREATE TABLE t (a)")
    with pytest.raises(StoreError, match="without the sweep tables"):
        ResultStore.check(other)
    ResultStore.check(tmp_path / "new.sqlite")  # a missing file is fine, and not created
    assert not (tmp_path / "new.sqlite").exists()


def test_a_store_of_the_previous_layout_is_read_and_brought_up_to_date(tmp_path):
    """Version 2 lacked the self-contact columns: read as missing (nothing written), and
    added, rows kept, when a sweep opens the store to write."""
    pd = pytest.importorskip("pandas")
    from elastocap.sweep import load

    p = tmp_path / "s.sqlite"
    with ResultStore(p) as st:
        st.put(_row(1))
    for c in ("contact_steps", "contact_max_active", "contact_gap_error"):
        fk.execute_sql(p, f"ALTER TABLE runs DROP COLUMN {c}")
    fk.execute_sql(p, "UPDATE meta SET value = '2' WHERE key = 'schema_version'")
    before = sorted(x.name for x in tmp_path.iterdir())
    ResultStore.check(p)
    df = load(p)
    assert len(df) == 1 and df["outcome"][0] == "open"
    assert df["contact_steps"].isna().all() and df["contact_gap_error"].isna().all()
    assert str(df["contact_steps"].dtype) == "Int64" and isinstance(df, pd.DataFrame)
    reader = ResultStore.reader(p)  # reports and plots
    try:
        (r,) = reader.rows()
        assert r["outcome"] == "open" and r["contact_steps"] is None
        assert reader.rows(positions=True)[0]["final_positions"].shape == (3, 2)
    finally:
        reader.close()
    assert sorted(x.name for x in tmp_path.iterdir()) == before  # read-only
    with ResultStore(p) as st:
        (old,) = st.rows()
        assert old["outcome"] == "open" and old["contact_steps"] is None
        assert st.put(_row(2, contact_steps=7, contact_max_active=2, contact_gap_error=1e-15))
        new = st.get(f"{2:064x}", "9.9", "test")
        assert (new["contact_steps"], new["contact_max_active"]) == (7, 2)
        version = st._con.execute(
            "SELECT value FROM meta WHERE key = 'schema_version'").fetchone()[0]
        assert version == "3"
    fk.execute_sql(p, "UPDATE meta SET value = '1' WHERE key = 'schema_version'")
    with pytest.raises(StoreError, match="schema version 1, this elastocap writes version 3"):
        ResultStore(p)


WRITER = textwrap.dedent(
    """
    import sys
    import numpy as np
    from elastocap.sweep.store import ResultStore
    path, start = sys.argv[1], int(sys.argv[2])
    st = ResultStore(path)
    inserted = 0
    for i in range(start, start + 60):
        inserted += st.put({
            "scene_digest": f"{i:064x}", "version": "9.9", "runner": "test",
            "scene_name": "s", "scene_json": "{}", "x": float(i), "x_over_leg": float(i),
            "wetted_length": 1.0, "outcome": "open", "companion_outcome": "open",
            "status": "completed", "final_positions": np.zeros((50, 2)) + i,
        })
    print(inserted)
    """
)


def test_concurrent_writers_do_not_corrupt_or_duplicate(tmp_path):
    """Four processes write 60 runs each, overlapping by 30 (keys 0..149), at the same time
    into one new store: every key once, the file sound, insert counts adding up."""
    p = tmp_path / "shared.sqlite"
    env = {**os.environ, "PYTHONWARNINGS": "error"}
    procs = [
        subprocess.Popen([sys.executable, "-c", WRITER, str(p), str(start)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        for start in (0, 30, 60, 90)
    ]
    outs = [pr.communicate(timeout=120) for pr in procs]
    assert all(pr.returncode == 0 for pr in procs), [o[1] for o in outs]
    inserted = sum(int(o[0]) for o in outs)
    with ResultStore(p) as st:
        assert st.integrity() == "ok"
        n, distinct = st._con.execute(
            "SELECT COUNT(*), COUNT(DISTINCT scene_digest) FROM runs").fetchone()
        assert n == distinct == 150 == inserted
        for r in st.rows(positions=True):
            assert r["final_positions"].shape == (50, 2)
            assert np.all(r["final_positions"] == int(r["scene_digest"], 16))


def test_a_store_holds_one_scene_and_one_resolution(tmp_path):
    """A sweep of another scene (another --set) on an existing store is refused before any
    write, naming the values that differ; a time step typed from its printed digits is the
    same resolution (floats to 1e-12)."""
    from elastocap.scene import load_scene
    from elastocap.sweep.engine import store_resolution, sweep_resolutions
    from elastocap.sweep.grid import grid_points

    def recorded(over):
        scene = load_scene("supp-fig5", {"numerics.accuracy": "draft", **over})
        points = grid_points(scene, [2.3], deltas=[3.0, 4.0])[0]
        return store_resolution(sweep_resolutions(scene, points), scene)

    path = tmp_path / "s.sqlite"
    made = recorded({"effects.damping": 0.25})
    with ResultStore(path) as st:
        st.ensure_resolution(made)
    before = path.read_bytes()
    ResultStore.check(path, recorded({"effects.damping": 0.25}))  # the same scene
    # the sweep sets the swept keys at every point: they are not the scene's
    ResultStore.check(path, recorded({"effects.damping": 0.25, "drop.wetted_length": 1.0}))
    with pytest.raises(StoreError, match=r"another scene \(effects\.damping = 0\.25 there, "
                                         r"0\.3 here\); one store holds one scene"):
        ResultStore.check(path, recorded({"effects.damping": 0.3}))
    with pytest.raises(StoreError, match="another scene"):
        with ResultStore(path) as st:
            st.ensure_resolution(recorded({"effects.damping": 0.25, "drop.area": 1.4}))
    ResultStore.check(path, dict(made, dt=float(f"{made['dt']:.13g}")))  # typed digits
    with pytest.raises(StoreError, match="one store holds one resolution"):
        ResultStore.check(path, dict(made, dt=made["dt"] * (1 + 1e-9)))
    assert path.read_bytes() == before
