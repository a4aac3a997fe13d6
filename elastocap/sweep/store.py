"""The sweep result store: one SQLite file, a row per run, safe to resume and to share.

Guarantees and how they are met:

* **A resumed sweep never duplicates.** Each run has the UNIQUE key (scene_digest,
  version, code_digest, runner): the SHA-256 of the resolved scene (every parameter,
  numerics included), the package version, a fingerprint of the physics source code that
  computed it (so a fix made without a version bump is never served stale results) and the
  name of the run function.
  Rows are written with ``INSERT OR IGNORE``: a second writer of the same run is a no-op.
* **Re-running skips stored runs.** Before submitting, a sweep looks its runs up by key.
* **A killed sweep loses at most the runs in flight, and no row is half-written.** One
  transaction per run (``BEGIN IMMEDIATE ... COMMIT``); SQLite's journal rolls back an
  interrupted one. ``synchronous = FULL``: a committed run survives a power cut too.
* **Several sweeps may write concurrently.** WAL mode (readers never block the writer) and
  a busy timeout: writers queue for the write lock instead of failing. Only the process
  that orchestrates a sweep writes; workers (local or on a cluster) return plain data.

WAL needs a local file system (not NFS); put the store on a local disk.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import socket
import sqlite3
import time
from pathlib import Path

import numpy as np

__all__ = ["COLUMNS", "SCHEMA_VERSION", "ResultStore", "StoreError"]

#: Bump when the table layout changes; a store with another version is refused.
SCHEMA_VERSION = 1
#: Seconds a writer waits for the write lock held by another sweep before failing: one
#: transaction takes milliseconds, so 60 s only trips on a stuck writer.
BUSY_TIMEOUT_S = 60.0

#: Columns of ``runs`` (name, SQL type) after the id; the key is the first three.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("scene_digest", "TEXT NOT NULL"),
    ("version", "TEXT NOT NULL"),
    ("code_digest", "TEXT NOT NULL"),
    ("runner", "TEXT NOT NULL"),
    ("scene_name", "TEXT NOT NULL"),
    ("scene_json", "TEXT NOT NULL"),
    ("x", "REAL NOT NULL"),
    ("x_over_leg", "REAL NOT NULL"),
    ("we_sqrt", "REAL"),
    ("wetted_length", "REAL NOT NULL"),
    ("outcome", "TEXT NOT NULL"),
    ("companion_outcome", "TEXT NOT NULL"),
    ("final_measure", "REAL"),
    ("companion_measure", "REAL"),
    ("t_end", "REAL"),
    ("steps", "INTEGER"),
    ("wall_time_s", "REAL"),
    ("status", "TEXT NOT NULL"),
    ("message", "TEXT"),
    ("rod_crossing_time", "REAL"),
    ("interface_crossing_time", "REAL"),
    ("decided_after_crossing", "INTEGER"),
    ("final_positions", "BLOB"),
    ("settings_json", "TEXT"),
    ("host", "TEXT"),
    ("created_utc", "TEXT NOT NULL"),
)
_NAMES = tuple(c for c, _ in COLUMNS)
_KEY = ("scene_digest", "version", "code_digest", "runner")


class StoreError(ValueError):
    """The file is not a store this version can use (the message says what to do)."""


def _schema_sql() -> str:
    cols = ",\n  ".join(f"{n} {t}" for n, t in COLUMNS)
    return (
        "CREATE TABLE IF NOT EXISTS runs (\n  id INTEGER PRIMARY KEY,\n  "
        f"{cols},\n  UNIQUE ({', '.join(_KEY)})\n);\n"
        "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);\n"
    )


def _utc_now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="milliseconds")


def _encode_positions(pos) -> bytes | None:
    if pos is None:
        return None
    a = np.ascontiguousarray(pos, dtype="<f8")
    return a.tobytes()


def decode_positions(blob: bytes | None) -> np.ndarray | None:
    """Final positions (n + 1, 2) from the ``final_positions`` column."""
    if blob is None:
        return None
    return np.frombuffer(blob, dtype="<f8").reshape(-1, 2).copy()


class ResultStore:
    """A sweep store in one SQLite file (created if missing).

    Parameters
    ----------
    path : str or Path
        The file; its directory is created if needed.

    Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._con = sqlite3.connect(
            str(self.path),
            timeout=BUSY_TIMEOUT_S,
            isolation_level=None,
            check_same_thread=False,
        )
        try:
            self._setup()
        except sqlite3.DatabaseError as err:
            self._con.close()
            raise StoreError(
                f"{self.path}: not a usable sweep store ({err}); give another --store file"
            ) from None

    @staticmethod
    def check(path: str | Path) -> None:
        """Refuse an existing file that is not a usable store, without writing anything (a
        missing file is fine: it will be created)."""
        path = Path(path)
        if not path.exists():
            return
        if not path.is_file():
            raise StoreError(f"store {str(path)!r}: not a file; give a file name")
        try:
            con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
            try:
                tables = {r[0] for r in con.execute(
                    "SELECT name FROM sqlite_master WHERE type = 'table'")}
                if tables and not {"runs", "meta"} <= tables:
                    raise StoreError(f"store {str(path)!r}: an SQLite file without the sweep "
                                     "tables (runs, meta); give another file")
                if "meta" in tables:
                    row = con.execute(
                        "SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
                    if row is None or row[0] != str(SCHEMA_VERSION):
                        raise StoreError(
                            f"store {str(path)!r}: schema version {row and row[0]}, this "
                            f"elastocap writes version {SCHEMA_VERSION}; give a new file")
            finally:
                con.close()
        except sqlite3.DatabaseError as err:
            raise StoreError(f"store {str(path)!r}: not a usable sweep store ({err}); give "
                             "another file") from None

    def _setup(self) -> None:
        con = self._con
        con.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
        # switching to WAL needs a moment alone with the file; another process creating the
        # same store at the same instant can hold it: retry for up to BUSY_TIMEOUT_S
        deadline = time.monotonic() + BUSY_TIMEOUT_S
        while True:
            try:
                mode = con.execute("PRAGMA journal_mode = WAL").fetchone()[0]
                break
            except sqlite3.OperationalError as err:
                if "locked" not in str(err) or time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
        if str(mode).lower() != "wal":
            raise StoreError(
                f"{self.path}: SQLite refused WAL mode (got {mode!r}); the file "
                "system may not support it (NFS?): put the store on a local disk"
            )
        con.execute("PRAGMA synchronous = FULL")
        with self._transaction():
            for stmt in _schema_sql().split(";\n"):
                if stmt.strip():
                    con.execute(stmt)
            row = con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
            if row is None:
                con.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
            elif row[0] != str(SCHEMA_VERSION):
                raise StoreError(
                    f"store {str(self.path)!r}: schema version {row[0]}, this elastocap "
                    f"writes version {SCHEMA_VERSION}; give a new file"
                )

    @contextlib.contextmanager
    def _transaction(self):
        con = self._con
        con.execute("BEGIN IMMEDIATE")
        try:
            yield con
        except BaseException:
            con.execute("ROLLBACK")
            raise
        con.execute("COMMIT")

    # -------------------------------------------------------------------------- writing
    def put(self, row: dict) -> bool:
        """Write one run in its own transaction. Returns False if the key was already stored
        (by this or another sweep): the stored row is kept, nothing is written. A missing
        ``code_digest`` is stored as "" (run functions without a code identity)."""
        row = {"code_digest": "", **row}
        missing = [
            n for n, t in COLUMNS if "NOT NULL" in t and n != "created_utc" and row.get(n) is None
        ]
        if missing:
            raise ValueError(f"row: missing {', '.join(missing)}")
        vals = dict(row)
        vals["final_positions"] = _encode_positions(vals.get("final_positions"))
        if isinstance(vals.get("settings_json"), dict):
            vals["settings_json"] = json.dumps(vals["settings_json"], sort_keys=True)
        vals.setdefault("host", socket.gethostname())
        vals["created_utc"] = vals.get("created_utc") or _utc_now()
        if vals.get("decided_after_crossing") is not None:
            vals["decided_after_crossing"] = int(bool(vals["decided_after_crossing"]))
        for k in ("final_measure", "companion_measure", "t_end", "wall_time_s"):
            v = vals.get(k)
            if v is not None and not math.isfinite(float(v)):
                vals[k] = None  # SQLite stores NaN as NULL anyway; say so explicitly
        sql = (
            f"INSERT OR IGNORE INTO runs ({', '.join(_NAMES)}) VALUES "
            f"({', '.join('?' for _ in _NAMES)})"
        )
        with self._transaction() as con:
            cur = con.execute(sql, tuple(vals.get(n) for n in _NAMES))
            return cur.rowcount == 1

    # -------------------------------------------------------------------------- reading
    def _rows(self, cur) -> list[dict]:
        names = [d[0] for d in cur.description]
        out = []
        for r in cur.fetchall():
            d = dict(zip(names, r, strict=True))
            if "final_positions" in d:
                d["final_positions"] = decode_positions(d["final_positions"])
            if d.get("decided_after_crossing") is not None:
                d["decided_after_crossing"] = bool(d["decided_after_crossing"])
            out.append(d)
        return out

    def get_many(self, digests, version: str, runner: str, code_digest: str = "") -> dict:
        """Stored rows by scene digest for one (version, runner, code digest); missing ones
        are absent from the dict."""
        digests = list(dict.fromkeys(digests))
        out: dict[str, dict] = {}
        # 500 per query: below SQLite's default limit of 999 bound parameters
        for i in range(0, len(digests), 500):
            chunk = digests[i : i + 500]
            cur = self._con.execute(
                "SELECT * FROM runs WHERE version = ? AND runner = ? AND code_digest = ? AND "
                f"scene_digest IN "
                f"({', '.join('?' for _ in chunk)})",
                (version, runner, code_digest, *chunk),
            )
            for r in self._rows(cur):
                out[r["scene_digest"]] = r
        return out

    def get(self, digest: str, version: str, runner: str, code_digest: str = "") -> dict | None:
        return self.get_many([digest], version, runner, code_digest).get(digest)

    def rows(
        self, *, version: str | None = None, runner: str | None = None, positions: bool = False
    ) -> list[dict]:
        """All rows (optionally of one version / runner), in insertion order."""
        cols = (
            "*" if positions else ", ".join(["id", *(n for n in _NAMES if n != "final_positions")])
        )
        where, args = [], []
        if version is not None:
            where.append("version = ?")
            args.append(version)
        if runner is not None:
            where.append("runner = ?")
            args.append(runner)
        sql = f"SELECT {cols} FROM runs" + (" WHERE " + " AND ".join(where) if where else "")
        return self._rows(self._con.execute(sql + " ORDER BY id", args))

    def count(self) -> int:
        return int(self._con.execute("SELECT COUNT(*) FROM runs").fetchone()[0])

    def integrity(self) -> str:
        """SQLite's ``PRAGMA integrity_check`` ("ok" for a sound file)."""
        return str(self._con.execute("PRAGMA integrity_check").fetchone()[0])

    def close(self) -> None:
        self._con.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
