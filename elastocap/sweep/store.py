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
* **Two sweeps never compute the same run.** Before a run is submitted its key is claimed
  in the ``claims`` table (owner, pid, host and a lease, renewed while the run is in
  flight) in the same transaction that finds it missing from ``runs``; another sweep
  waits for a claimed run instead of computing it, and takes the claim over when its lease
  has expired or its owner (on this host) is no longer alive.
* **Failures are recorded, not hidden.** A run that raised, or whose worker died on every
  attempt, is written to ``failures`` with the reason; it is not a result, so a later
  sweep tries it again (and a success replaces the failure).
* **One resolution and one scene per store.** ``meta`` records the discretization of the
  sweep that made the store (edges and time step of its base level) and its scene's values
  (but the swept keys); a sweep at another base resolution, or of another scene (another
  ``--set``), is refused before anything is written (:meth:`ResultStore.check`). Runs of the finer
  verification levels carry their ``level``, ``n_edges`` and ``dt`` in their rows.
* **Refused input writes nothing.** :meth:`ResultStore.check` opens an existing file
  without creating ``-wal`` / ``-shm`` files (``immutable`` when none exist).

WAL needs a local file system (not NFS); put the store on a local disk.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import socket
import sqlite3
import time
from pathlib import Path

import numpy as np

__all__ = ["COLUMNS", "OUTCOMES", "SCHEMA_VERSION", "ResultStore", "StoreError",
           "select_list"]

#: Bump when the table layout changes; a store with another version is refused, except
#: those :data:`MIGRATIONS` can bring up to date (done when a sweep opens it for writing).
SCHEMA_VERSION = 3
#: The outcome classes of a run ("undecided" carries a ``reason``).
OUTCOMES = ("open", "encapsulated", "undecided")
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
    ("level", "INTEGER NOT NULL"),
    ("n_edges", "INTEGER"),
    ("dt", "REAL"),
    ("outcome", "TEXT NOT NULL"),
    ("reason", "TEXT"),
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
    # what the rod's self-contact did (NULL without a thickness, or in a row of version 2):
    # steps with contacts, the most at once, the largest gap error in thicknesses
    ("contact_steps", "INTEGER"),
    ("contact_max_active", "INTEGER"),
    ("contact_gap_error", "REAL"),
    ("final_positions", "BLOB"),
    ("settings_json", "TEXT"),
    ("host", "TEXT"),
    ("created_utc", "TEXT NOT NULL"),
)
_NAMES = tuple(c for c, _ in COLUMNS)
_KEY = ("scene_digest", "version", "code_digest", "runner")
#: Columns of ``failures``: the run's key and point, and why it has no result.
FAILURE_COLUMNS: tuple[tuple[str, str], ...] = (
    *COLUMNS[:4],
    ("scene_name", "TEXT NOT NULL"),
    ("x", "REAL NOT NULL"),
    ("x_over_leg", "REAL NOT NULL"),
    ("we_sqrt", "REAL"),
    ("wetted_length", "REAL NOT NULL"),
    ("level", "INTEGER NOT NULL"),
    ("error", "TEXT NOT NULL"),
    ("attempts", "INTEGER NOT NULL"),
    ("host", "TEXT"),
    ("created_utc", "TEXT NOT NULL"),
)
_FNAMES = tuple(c for c, _ in FAILURE_COLUMNS)
_KEY_WHERE = " AND ".join(f"{k} = ?" for k in _KEY)


class StoreError(ValueError):
    """The file is not a store this version can use (the message says what to do)."""


#: Schema version -> the statements that bring a store of that version to the next one.
MIGRATIONS: dict[int, tuple[str, ...]] = {
    2: ("ALTER TABLE runs ADD COLUMN contact_steps INTEGER",
        "ALTER TABLE runs ADD COLUMN contact_max_active INTEGER",
        "ALTER TABLE runs ADD COLUMN contact_gap_error REAL"),
}


def _migration(version) -> list[str] | None:
    """The statements that bring a store of this recorded schema version up to date
    (``[]`` for the current one), or None when none can (the store is refused)."""
    try:
        v = int(version)
    except (TypeError, ValueError):
        return None
    stmts = []
    while v in MIGRATIONS:
        stmts += MIGRATIONS[v]
        v += 1
    return stmts if v == SCHEMA_VERSION else None


def _version_error(path, version) -> StoreError:
    """The refusal of a store whose recorded schema version no migration brings up to
    date."""
    return StoreError(f"store {str(path)!r}: schema version {version}, this elastocap "
                      f"writes version {SCHEMA_VERSION}; give a new file")


def select_list(con: sqlite3.Connection, names) -> str:
    """The SELECT list of the columns ``names`` of ``runs``, a column that a store of an
    older layout lacks read as NULL (such a store is read as it is, not migrated)."""
    have = {r[1] for r in con.execute("PRAGMA table_info(runs)")}
    return ", ".join(n if n in have else f"NULL AS {n}" for n in names)


def _schema_sql() -> str:
    cols = ",\n  ".join(f"{n} {t}" for n, t in COLUMNS)
    return (
        "CREATE TABLE IF NOT EXISTS runs (\n  id INTEGER PRIMARY KEY,\n  "
        f"{cols},\n  UNIQUE ({', '.join(_KEY)})\n);\n"
        "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);\n"
        "CREATE TABLE IF NOT EXISTS failures (\n  "
        + ",\n  ".join(f"{n} {t}" for n, t in FAILURE_COLUMNS)
        + f",\n  PRIMARY KEY ({', '.join(_KEY)})\n);\n"
        "CREATE TABLE IF NOT EXISTS claims (\n  "
        + ",\n  ".join(f"{n} {t}" for n, t in COLUMNS[:4])
        + ",\n  owner TEXT NOT NULL,\n  pid INTEGER NOT NULL,\n  host TEXT NOT NULL,\n"
        f"  lease_until REAL NOT NULL,\n  PRIMARY KEY ({', '.join(_KEY)})\n);\n"
    )


#: What must agree between a store's recorded resolution and a sweep's.
RESOLUTION_KEYS = ("n_edges", "dt", "integrator")


def _same_value(a, b) -> bool:
    """Equal, floats to 1e-12 relative (a time step typed from its printed digits)."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or abs(a - b) <= 1e-12 * max(abs(a), abs(b))
    return a == b


def _same_resolution(path, stored: dict, wanted: dict) -> None:
    """Refuse a sweep whose resolution, or scene (where both record one), differs from
    what made the store."""
    diff = [k for k in RESOLUTION_KEYS if not _same_value(stored.get(k), wanted.get(k))]
    if diff:
        have = ", ".join(f"{k} = {stored.get(k)!r}" for k in RESOLUTION_KEYS)
        want = ", ".join(f"{k} = {wanted.get(k)!r}" for k in RESOLUTION_KEYS)
        raise StoreError(
            f"store {str(path)!r}: made at {have}, this sweep runs at {want}; one store "
            "holds one resolution: give another --store, or --set numerics.n_edges="
            f"{stored.get('n_edges')} (and numerics.dt={stored.get('dt')!r}) to add to "
            "this one")
    have, want = stored.get("scene"), wanted.get("scene")
    if have is not None and want is not None:
        keys = sorted(set(have) | set(want))
        diff = [k for k in keys if not _same_value(have.get(k), want.get(k))]
        if diff:
            shown = "; ".join(f"{k} = {have.get(k)!r} there, {want.get(k)!r} here"
                              for k in diff[:3])
            raise StoreError(
                f"store {str(path)!r}: made by a sweep of another scene ({shown}"
                f"{'; ...' if len(diff) > 3 else ''}); one store holds one scene: give "
                "another --store")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, someone else's
        return True
    return True


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

    @classmethod
    def reader(cls, path: str | Path) -> ResultStore:
        """An existing store opened read-only, for reports and plots: nothing is written and
        no file is created (an SQLite file that is not a store stays untouched).  Only the
        reading methods (:meth:`rows`, :meth:`failures`, :meth:`resolution`, ...) work."""
        path = Path(path)
        if not path.is_file():
            raise StoreError(f"store {str(path)!r}: no such file")
        cls.check(path)
        try:
            con = cls._open_readonly(path)
            tables = {r[0] for r in con.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.DatabaseError as err:
            raise StoreError(f"store {str(path)!r}: not a usable sweep store ({err})") from None
        if not {"runs", "meta", "failures"} <= tables:
            con.close()
            raise StoreError(f"store {str(path)!r}: not a sweep store (no runs, meta and "
                             "failures tables)")
        self = cls.__new__(cls)
        self.path = path
        self._con = con
        return self

    @staticmethod
    def _open_readonly(path: Path) -> sqlite3.Connection:
        """A read-only connection that creates no file: read-only on the live WAL when a
        writer has it open (its -wal and -shm exist), else ``immutable`` (SQLite then
        neither locks nor creates -wal / -shm)."""
        uri = path.resolve().as_uri()
        live = Path(f"{path}-wal").exists() and Path(f"{path}-shm").exists()
        return sqlite3.connect(f"{uri}?mode=ro" if live else f"{uri}?immutable=1", uri=True)

    @staticmethod
    def check(path: str | Path, resolution: dict | None = None) -> None:
        """Refuse an existing file that is not a usable store, or whose recorded resolution
        differs from ``resolution`` (see :meth:`ensure_resolution`), without writing
        anything (a missing file is fine: it will be created)."""
        path = Path(path)
        if not path.exists():
            return
        if not path.is_file():
            raise StoreError(f"store {str(path)!r}: not a file; give a file name")
        try:
            con = ResultStore._open_readonly(path)
            try:
                tables = {r[0] for r in con.execute(
                    "SELECT name FROM sqlite_master WHERE type = 'table'")}
                if tables and not {"runs", "meta"} <= tables:
                    raise StoreError(f"store {str(path)!r}: an SQLite file without the sweep "
                                     "tables (runs, meta); give another file")
                if "meta" in tables:
                    row = con.execute(
                        "SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
                    if row is None or _migration(row[0]) is None:
                        raise _version_error(path, row and row[0])
                    if resolution is not None:
                        row = con.execute(
                            "SELECT value FROM meta WHERE key = 'resolution'").fetchone()
                        if row is not None:
                            _same_resolution(path, json.loads(row[0]), resolution)
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
            tables = {r[0] for r in con.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
            row = (con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
                   if "meta" in tables else None)
            stmts = [] if row is None else _migration(row[0])
            if stmts is None:
                raise _version_error(self.path, row[0])
            if stmts:  # an older layout: brought up to date in this transaction
                for stmt in stmts:
                    con.execute(stmt)
                con.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'",
                            (str(SCHEMA_VERSION),))
            for stmt in _schema_sql().split(";\n"):
                if stmt.strip():
                    con.execute(stmt)
            if row is None:
                con.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))

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
    def ensure_resolution(self, resolution: dict) -> None:
        """Record the sweep's base resolution (``n_edges``, ``dt``, ``integrator``, and
        anything else given) in a new store; refuse (:class:`StoreError`) a store made at
        another one."""
        with self._transaction() as con:
            row = con.execute("SELECT value FROM meta WHERE key = 'resolution'").fetchone()
            if row is None:
                con.execute("INSERT INTO meta VALUES ('resolution', ?)",
                            (json.dumps(resolution, sort_keys=True),))
            else:
                _same_resolution(self.path, json.loads(row[0]), resolution)

    def resolution(self) -> dict | None:
        """The base resolution recorded by :meth:`ensure_resolution` (None if none yet)."""
        row = self._con.execute("SELECT value FROM meta WHERE key = 'resolution'").fetchone()
        return None if row is None else json.loads(row[0])

    def put(self, row: dict, owner: str | None = None) -> bool:
        """Write one run in its own transaction. Returns False if the key was already stored
        (by this or another sweep): the stored row is kept, nothing is written. A missing
        ``code_digest`` is stored as "" (run functions without a code identity), a missing
        ``level`` as 0. The run's claim by ``owner`` and any recorded failure of it are
        removed in the same transaction."""
        row = {"code_digest": "", "level": 0, **row}
        missing = [
            n for n, t in COLUMNS if "NOT NULL" in t and n != "created_utc" and row.get(n) is None
        ]
        if missing:
            raise ValueError(f"row: missing {', '.join(missing)}")
        for k in ("outcome", "companion_outcome"):
            if row[k] not in OUTCOMES:
                raise ValueError(f"row: {k} {row[k]!r}; expected one of {', '.join(OUTCOMES)}")
        vals = dict(row)
        vals["final_positions"] = _encode_positions(vals.get("final_positions"))
        if isinstance(vals.get("settings_json"), dict):
            vals["settings_json"] = json.dumps(vals["settings_json"], sort_keys=True)
        vals.setdefault("host", socket.gethostname())
        vals["created_utc"] = vals.get("created_utc") or _utc_now()
        if vals.get("decided_after_crossing") is not None:
            vals["decided_after_crossing"] = int(bool(vals["decided_after_crossing"]))
        for k in ("final_measure", "companion_measure", "t_end", "wall_time_s",
                  "contact_gap_error"):
            v = vals.get(k)
            if v is not None and not math.isfinite(float(v)):
                vals[k] = None  # SQLite stores NaN as NULL anyway; say so explicitly
        sql = (
            f"INSERT OR IGNORE INTO runs ({', '.join(_NAMES)}) VALUES "
            f"({', '.join('?' for _ in _NAMES)})"
        )
        key = tuple(vals[k] for k in _KEY)
        with self._transaction() as con:
            cur = con.execute(sql, tuple(vals.get(n) for n in _NAMES))
            con.execute(f"DELETE FROM failures WHERE {_KEY_WHERE}", key)
            if owner is not None:
                con.execute(f"DELETE FROM claims WHERE {_KEY_WHERE} AND owner = ?", (*key, owner))
            return cur.rowcount == 1

    def record_failure(self, row: dict, owner: str | None = None) -> None:
        """Record that a run has no result (``error`` says why; ``attempts`` how often it
        was tried), replacing an earlier failure of it, and drop ``owner``'s claim."""
        vals = {"code_digest": "", "level": 0, "attempts": 1, **row}
        vals.setdefault("host", socket.gethostname())
        vals["created_utc"] = vals.get("created_utc") or _utc_now()
        missing = [n for n, t in FAILURE_COLUMNS
                   if "NOT NULL" in t and n != "created_utc" and vals.get(n) is None]
        if missing:
            raise ValueError(f"failure: missing {', '.join(missing)}")
        key = tuple(vals[k] for k in _KEY)
        with self._transaction() as con:
            con.execute(f"INSERT OR REPLACE INTO failures ({', '.join(_FNAMES)}) VALUES "
                        f"({', '.join('?' for _ in _FNAMES)})", tuple(vals[n] for n in _FNAMES))
            if owner is not None:
                con.execute(f"DELETE FROM claims WHERE {_KEY_WHERE} AND owner = ?", (*key, owner))

    def claim(self, digests, version: str, runner: str, code_digest: str, owner: str,
              lease_s: float) -> tuple[dict, set, set]:
        """Claim the runs ``digests`` for ``owner`` in one transaction.

        Returns
        -------
        stored : dict digest -> row
            Already in ``runs`` (nothing to do).
        mine : set of digest
            Claimed now by ``owner`` (new claims, claims ``owner`` already held, and claims
            taken over: lease expired, or the owning process on this host is gone).
        theirs : set of digest
            Held by another live owner: wait for its row (see :meth:`get_many`).
        """
        digests = list(dict.fromkeys(digests))
        host, pid, now = socket.gethostname(), os.getpid(), time.time()
        stored: dict[str, dict] = {}
        mine: set[str] = set()
        theirs: set[str] = set()
        with self._transaction() as con:
            for i in range(0, len(digests), 500):
                chunk = digests[i : i + 500]
                qs = ", ".join("?" for _ in chunk)
                cur = con.execute(
                    "SELECT * FROM runs WHERE version = ? AND runner = ? AND code_digest = ? "
                    f"AND scene_digest IN ({qs})", (version, runner, code_digest, *chunk))
                for r in self._rows(cur):
                    stored[r["scene_digest"]] = r
                held = {r[0]: r[1:] for r in con.execute(
                    "SELECT scene_digest, owner, pid, host, lease_until FROM claims WHERE "
                    f"version = ? AND runner = ? AND code_digest = ? AND scene_digest IN ({qs})",
                    (version, runner, code_digest, *chunk))}
                for d in chunk:
                    if d in stored:
                        continue
                    h = held.get(d)
                    if h is not None and h[0] != owner and h[3] > now and not (
                            h[2] == host and not _pid_alive(h[1])):
                        theirs.add(d)
                        continue
                    con.execute(
                        "INSERT OR REPLACE INTO claims VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        (d, version, code_digest, runner, owner, pid, host, now + lease_s))
                    mine.add(d)
        return stored, mine, theirs

    def renew(self, digests, version: str, runner: str, code_digest: str, owner: str,
              lease_s: float) -> None:
        """Extend ``owner``'s leases on ``digests`` to now + ``lease_s``."""
        until = time.time() + lease_s
        with self._transaction() as con:
            con.executemany(
                "UPDATE claims SET lease_until = ? WHERE scene_digest = ? AND version = ? AND "
                "runner = ? AND code_digest = ? AND owner = ?",
                [(until, d, version, runner, code_digest, owner) for d in digests])

    def release(self, owner: str) -> None:
        """Drop every claim ``owner`` still holds (a sweep that ends or is interrupted)."""
        with self._transaction() as con:
            con.execute("DELETE FROM claims WHERE owner = ?", (owner,))

    def claims(self) -> list[dict]:
        """The claims table (for diagnostics and tests)."""
        cur = self._con.execute("SELECT * FROM claims ORDER BY lease_until")
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur.fetchall()]

    def failures(self) -> list[dict]:
        """Recorded failures (runs without a result), oldest first."""
        cur = self._con.execute("SELECT * FROM failures ORDER BY created_utc")
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur.fetchall()]

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
        cols = select_list(self._con, ["id", *(n for n in _NAMES
                                               if positions or n != "final_positions")])
        where, args = [], []
        if version is not None:
            where.append("version = ?")
            args.append(version)
        if runner is not None:
            where.append("runner = ?")
            args.append(runner)
        sql = f"SELECT {cols} FROM runs" + (" WHERE " + " AND ".join(where) if where else "")
        return self._rows(self._con.execute(sql + " ORDER BY id", args))

    def table(self, names) -> list[tuple]:
        """The columns ``names`` of every row, as stored (no decoding), in insertion order;
        a column this store's schema lacks reads as None (:func:`select_list`)."""
        try:
            cur = self._con.execute(f"SELECT {select_list(self._con, names)} FROM runs "
                                    "ORDER BY id")
            return cur.fetchall()
        except sqlite3.DatabaseError as err:
            raise StoreError(f"store {str(self.path)!r}: not a usable sweep store "
                             f"({err})") from None

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
