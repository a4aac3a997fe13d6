"""Safe output: atomic writes, safe file stems, and a run's ownership of its output folder.

- :func:`atomic_path` hands out a temporary name in the destination's folder (same suffix,
  so ``np.savez`` and ``savefig`` see the right format) and renames it onto the destination
  when the block succeeds; on an error the temporary file is removed and the destination is
  untouched. A killed process leaves at most a hidden ``.NAME.tmp-*`` file, never a cut file
  under the real name.
- :func:`check_stem` refuses a name that is not a plain file stem (separators, ``..``,
  control characters, a leading dot), so that no scene name ever becomes a path.
- :class:`OutputFolder` is a run's output folder: its permissions are checked when it is
  made (before the work starts); at the first write it removes the files that earlier runs
  of the same kind listed in the folder's manifest ``.elastocap-outputs.json`` (and nothing
  else); every file it writes goes through a temporary name and is listed in the manifest
  before it is written.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = [
    "MANIFEST",
    "OutputError",
    "OutputFolder",
    "atomic_path",
    "check_output_folder",
    "check_writable_file",
    "check_stem",
    "write_json",
    "write_text",
]

#: The manifest an :class:`OutputFolder` keeps: which files which kind of run wrote there.
MANIFEST = ".elastocap-outputs.json"
_STAGING_PREFIX = ".elastocap-staging-"
_TMP_MARK = ".tmp-"
#: A file stem: no separators, no control characters, no leading dot, at most 120 characters.
_STEM = re.compile(r"[^\x00-\x1f\x7f/\\:*?\"<>|]{1,120}")


class OutputError(ValueError):
    """An output folder or file name that cannot be used: ``key``, ``value``, what is allowed."""

    def __init__(self, key: str, value, allowed: str):
        self.key = key
        self.value = value
        self.allowed = allowed
        super().__init__(f"{key}: got {value!r}; {allowed}")

    def __reduce__(self):  # pickles, as the exceptions with a plain constructor do
        return type(self), (self.key, self.value, self.allowed)


def check_stem(name: str) -> str | None:
    """Why ``name`` is not a safe file stem (None when it is one)."""
    if not isinstance(name, str) or not name.strip():
        return "expected a non-empty name"
    if not _STEM.fullmatch(name):
        return (
            "expected a plain file stem of at most 120 characters, without path separators "
            "or the characters : * ? \" < > | (it names the output files)"
        )
    if name.startswith(".") or ".." in name:
        return "expected a plain file stem: no leading '.' and no '..' (it names the output files)"
    if name != name.strip():
        return "expected a name without leading or trailing spaces (it names the output files)"
    return None


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.stem}{_TMP_MARK}{secrets.token_hex(4)}{path.suffix}")


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """A temporary path beside ``path``; renamed onto ``path`` when the block succeeds.

    >>> with atomic_path("out/x.npz") as tmp:   # doctest: +SKIP
    ...     np.savez(tmp, a=a)
    """
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"{tmp}: the writer did not write its temporary file")
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) atomically to ``path``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    return path


def write_json(path, obj, indent: int | None = 2) -> Path:
    """Write ``obj`` as JSON atomically (numpy scalars and non-finite floats made plain)."""
    from elastocap.jsonutil import jsonable

    return write_text(path, json.dumps(jsonable(obj), indent=indent) + "\n")


def _nearest_existing(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe(folder: Path, key: str, value, what: str) -> None:
    """Create and remove a temporary file in ``folder``: the honest test of writability."""
    try:
        fd, name = tempfile.mkstemp(prefix=".elastocap-probe-", dir=folder)
    except OSError as err:
        raise OutputError(
            key, value, f"{what} is not writable ({err.strerror}); choose a folder you can write to"
        ) from None
    os.close(fd)
    os.unlink(name)


def _without_dotdot_in_new_part(path: Path) -> Path:
    """``path`` with ``name/..`` pairs removed from the part that does not exist yet.

    ``out/new/../b`` means ``out/b`` to the user, but making it folder by folder (as
    ``mkdir(parents=True)`` does) would leave an empty ``out/new`` behind. The existing
    part is left to the operating system (a symbolic link there keeps its meaning).
    """
    parts = path.parts
    k = len(parts)
    while k > 0 and not Path(*parts[:k]).exists():
        k -= 1
    new = parts[k:]
    if ".." not in new:
        return path
    head = Path(*parts[:k]) if k else Path(".")
    return head / os.path.normpath(os.path.join(*new))


def check_output_folder(path, key: str = "--out") -> Path:
    """Refuse, before any work, an output folder that cannot be written.

    ``path`` may exist (a writable folder) or not (its nearest existing ancestor must be a
    writable folder). Nothing is created; a probe file is made and removed. Returns the
    path to make, with ``name/..`` pairs of its new part removed.
    """
    path = _without_dotdot_in_new_part(Path(path))
    value = str(path)
    if path.exists() and not path.is_dir():
        raise OutputError(key, value, "this is a file; expected a folder (existing or new)")
    anc = _nearest_existing(path)
    if not anc.is_dir():
        raise OutputError(key, value, f"{str(anc)!r} is a file, so the folder cannot be made")
    _probe(anc, key, value, "the folder" if anc == path.absolute() else f"its parent {str(anc)!r}")
    return path


def check_writable_file(path, key: str) -> Path:
    """Refuse, before any work, a file that cannot be written (or made): its folder must be
    writable (a store also writes journal files beside it) and an existing file openable for
    writing. Nothing is changed (the file is opened for appending and closed)."""
    path = _without_dotdot_in_new_part(Path(path))
    if path.exists() and not path.is_file():
        raise OutputError(key, str(path), "not a file; give a file name")
    check_output_folder(path.parent if str(path.parent) else Path("."), key)
    if path.exists():
        try:
            with open(path, "ab"):
                pass
        except OSError as err:
            raise OutputError(
                key, str(path), f"not writable ({err.strerror}); give a file you can write"
            ) from None
    return path


class OutputFolder:
    """The output folder of one run (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The folder (created at the first write).
    kind : str
        What the run is (e.g. ``"branches"``, ``"impact-supp-fig5-delta3.5"``): the files
        an earlier run of the same kind listed in the manifest are removed at the first
        write. Runs of other kinds keep their files.
    key : str
        The option that named the folder, for error messages.
    """

    def __init__(self, path, kind: str, key: str = "--out"):
        self.path = check_output_folder(path, key)
        self.kind = kind
        self.key = key
        self.files: list[Path] = []
        self._claimed = False

    # ------------------------------------------------------------------ manifest
    def _manifest(self) -> dict:
        try:
            data = json.loads((self.path / MANIFEST).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}
        if not isinstance(data, dict) or not isinstance(data.get("runs"), dict):
            return {}
        return {
            k: [n for n in v if isinstance(n, str) and check_stem(n) is None]
            for k, v in data["runs"].items()
            if isinstance(v, list)
        }

    def _save_manifest(self, runs: dict) -> None:
        write_text(self.path / MANIFEST, json.dumps({"runs": runs}, indent=1, sort_keys=True))

    def _claim(self, keep=()) -> None:
        """First write: remove this kind's earlier outputs (but ``keep``) and stale staging,
        nothing else."""
        if self._claimed:
            return
        self.path.mkdir(parents=True, exist_ok=True)
        runs = self._manifest()
        for name in runs.pop(self.kind, []):
            f = self.path / name
            if name not in keep and f.is_file() and not f.is_symlink():
                f.unlink()
        for d in self.path.glob(_STAGING_PREFIX + "*"):
            if d.is_dir() and not d.is_symlink():
                shutil.rmtree(d, ignore_errors=True)
        runs[self.kind] = []
        self._save_manifest(runs)
        self._claimed = True

    def _register(self, name: str, keep=()) -> Path:
        problem = check_stem(name)
        if problem is not None:
            raise OutputError("output file", name, problem)
        self._claim(keep)
        runs = self._manifest()
        for other, names in runs.items():  # a file of another kind is now this run's
            if other != self.kind and name in names:
                names.remove(name)
        mine = runs.setdefault(self.kind, [])
        if name not in mine:
            mine.append(name)
        self._save_manifest(runs)
        path = self.path / name
        if path not in self.files:
            self.files.append(path)
        return path

    # ------------------------------------------------------------------ writing
    @contextlib.contextmanager
    def file(self, name: str) -> Iterator[Path]:
        """A temporary path for the output ``name``; renamed into place on success."""
        path = self._register(name)
        with atomic_path(path) as tmp:
            yield tmp

    @contextlib.contextmanager
    def staged(self) -> Iterator[Path]:
        """A temporary folder inside this one for writers that make several files; on
        success every file written there becomes an output (renamed into place)."""
        self._claim()
        stage = Path(tempfile.mkdtemp(prefix=_STAGING_PREFIX, dir=self.path))
        try:
            yield stage
            for f in sorted(stage.iterdir()):
                if f.is_file():
                    os.replace(f, self._register(f.name))
        finally:
            shutil.rmtree(stage, ignore_errors=True)

    def adopt(self, paths) -> list[Path]:
        """List files a writer put straight into this folder (resumable writers that read
        their own earlier output) as this run's outputs; returns their paths."""
        names = [Path(p).name for p in paths]
        for p in paths:
            if Path(p).absolute().parent != self.path.absolute():
                raise OutputError("output file", str(p), f"expected a file in {str(self.path)!r}")
        return [self._register(n, keep=set(names)) for n in names]

    def final(self, path) -> Path:
        """The output path of a file written under :meth:`staged` (same name, this folder)."""
        return self.path / Path(path).name

    def write_text(self, name: str, text: str) -> Path:
        with self.file(name) as tmp:
            with open(tmp, "w", encoding="utf-8") as f:
                f.write(text)
        return self.path / name

    def write_json(self, name: str, obj, indent: int | None = 2) -> Path:
        from elastocap.jsonutil import jsonable

        return self.write_text(name, json.dumps(jsonable(obj), indent=indent) + "\n")

    def savefig(self, fig_or_plot, name: str, **kwargs) -> Path:
        """Save a matplotlib figure atomically as ``name``; or call ``fig_or_plot(path)``,
        a plotting function that draws and saves (the toolkit's figures hold no pyplot
        state, see :mod:`elastocap.figure`, so nothing is left to close)."""
        with self.file(name) as tmp:
            if callable(fig_or_plot):
                fig_or_plot(tmp)
            else:
                fig_or_plot.savefig(tmp, **kwargs)
        return self.path / name
