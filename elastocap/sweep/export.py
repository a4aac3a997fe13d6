"""Results out: the runs of a store as a pandas DataFrame, or a CSV / Parquet file.

``load(store)`` reads every run of a store (read-only: it writes nothing, not even SQLite's
``-wal`` / ``-shm`` files) into a :class:`pandas.DataFrame`, one row per run, with the
store's columns (:data:`elastocap.sweep.store.COLUMNS`; the final shape only with
``positions=True``). pandas is an optional dependency: ``pip install 'elastocap[export]'``
(which also brings pyarrow, for Parquet).
"""

from __future__ import annotations

from pathlib import Path

from elastocap.io import atomic_path, check_writable_file
from elastocap.sweep.executors import MissingExtraError
from elastocap.sweep.store import (
    COLUMNS,
    OUTCOMES,
    ResultStore,
    StoreError,
    decode_positions,
)

__all__ = ["EXPORT_SUFFIXES", "check_export", "export_runs", "load"]

EXPORT_SUFFIXES = (".csv", ".parquet")


def _pandas(what: str):
    try:
        import pandas
    except ImportError:
        raise MissingExtraError(
            f"{what}: needs pandas, which is not installed; install the extra: "
            "pip install 'elastocap[export]'") from None
    return pandas


def check_export(path) -> Path:
    """Refuse (ValueError / MissingExtraError, before anything is written) an export file
    this installation cannot write: suffix other than .csv / .parquet, no pandas, no
    pyarrow for Parquet, a directory, or a place that cannot be written."""
    path = Path(path)
    if path.suffix.lower() not in EXPORT_SUFFIXES:
        raise ValueError(f"--export: got {str(path)!r}; expected a file name ending in "
                         f"{' or '.join(EXPORT_SUFFIXES)}")
    if path.is_dir():
        raise ValueError(f"--export: got {str(path)!r}; a directory, expected a file name")
    path = check_writable_file(path, "--export")  # its folder may be new: made when written
    try:
        _pandas("--export")
        if path.suffix.lower() == ".parquet":
            try:
                import pyarrow  # noqa: F401
            except ImportError:
                raise MissingExtraError(
                    "--export: Parquet needs pyarrow, which is not installed; install the "
                    "extra: pip install 'elastocap[export]', or export .csv") from None
    except MissingExtraError as err:
        raise ValueError(str(err)) from None
    return path


def load(store, positions: bool = False):
    """The runs of a store as a :class:`pandas.DataFrame` (one row per run, in the order
    they were stored).

    Parameters
    ----------
    store : str, Path or ResultStore
    positions : bool
        Include ``final_positions`` (an (n + 1, 2) array per row).

    Raises
    ------
    MissingExtraError
        pandas is not installed (the message names the extra).
    StoreError
        Not a store (or no such file).
    """
    pd = _pandas("elastocap.sweep.load")
    path = Path(store.path if isinstance(store, ResultStore) else store)
    names = ["id", *(n for n, _ in COLUMNS if positions or n != "final_positions")]
    with ResultStore.reader(path) as st:  # refuses a file that is not a store
        rows = st.table(names)
    df = pd.DataFrame.from_records(rows, columns=names)
    for c in ("contact_steps", "contact_max_active"):  # missing without a thickness
        df[c] = df[c].astype("Int64")
    bad = df[~df["outcome"].isin(OUTCOMES)]
    if len(bad):  # a store sweeps write never holds these: a damaged or edited file
        raise StoreError(f"store {str(path)!r}: run id {int(bad['id'].iloc[0])} has outcome "
                         f"{bad['outcome'].iloc[0]!r}; expected one of {', '.join(OUTCOMES)}")
    if positions:
        df["final_positions"] = [decode_positions(b) for b in df["final_positions"]]
    # an undecided run is undecided under both criteria (stores written before the run
    # function said so hold the companion criterion's raw reading; its measure is kept)
    df.loc[df["outcome"] == "undecided", "companion_outcome"] = "undecided"
    # true, false, or missing (a failed run): pandas' nullable boolean, which Parquet
    # keeps as a boolean column with nulls
    df["decided_after_crossing"] = df["decided_after_crossing"].map(
        lambda v: None if v is None or v != v else bool(v)).astype("boolean")
    return df


def export_runs(store, path) -> Path:
    """Write :func:`load` ``(store)`` to ``path`` (.csv or .parquet), atomically: into a
    temporary file next to it, then renamed over it."""
    path = check_export(path)
    df = load(store)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".csv":
            df.to_csv(tmp, index=False)
        else:
            df.to_parquet(tmp, index=False)
    return path
