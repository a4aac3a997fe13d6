"""The cache of generated stepper modules: private, content-addressed, verified, bounded.

The steppers (:mod:`dynamics.rattle`, :mod:`dynamics.midpoint`) generate a Python module
per combination of effect kernels and import it from a file, so that numba's on-disk cache
(``cache=True``) applies to it and a second process loads the compiled machine code
instead of compiling again.  This module owns those files.

Location
    ``$DYNAMICS_CACHE_DIR``, else ``$XDG_CACHE_HOME/elastocap-dynamics``, else
    ``~/.cache/elastocap-dynamics``.  The directory is created with mode 0700 and used only
    if the current user owns it and neither group nor others may write to it; otherwise
    the next candidate is tried, and when none qualifies :class:`CacheError` says which
    were refused and why.  There is no fall-back to the shared temporary directory.
Keys
    A module's file name is ``<prefix>_<h>.py`` with ``h`` the first :data:`DIGEST_CHARS`
    hex digits of the SHA-256 of the file's bytes.  The file's first lines record the
    SHA-256 of the *contents* of every source file the generated code depends on (the
    ``dynamics`` kernels, the effect kernels' modules and what they use in their package),
    of the numba and Python versions: editing a kernel changes the name, touching it or
    cloning the repository again does not.
Import
    A file is written atomically (temporary file in the same directory, then
    :func:`os.replace`).  Before it is executed, its bytes are read once and checked: the
    hash must match the name, the file must be owned by the current user and not be
    writable by group or others.  The verified bytes are what is executed.  A file that
    fails a check is refused (:class:`CacheError`) and never executed.
Bounds
    Whenever a new module is written, modules older than :data:`MAX_AGE_DAYS` days are
    removed, and then the oldest ones until the directory holds at most :data:`MAX_BYTES`
    (modules plus numba's cache files beside them), never a module loaded by this process.
    ``elastocap cache clear`` (:func:`clear`) removes them all; ``elastocap cache info``
    (:func:`info`) reports the location, the count, the size and the limits.
One compile per stepper
    Processes that start together (a sweep's workers, a test run's workers) would each
    compile the same stepper.  :func:`compile_lock` holds an exclusive lock per module
    (``<module>.lock`` beside it, POSIX ``fcntl.flock``, released by the kernel when the
    holder dies) while one process compiles; the others wait, then load numba's cached
    code.  Kernels that several steppers call (self-contact's) have a lock of their own,
    taken first while numba's cache lacks them, so that processes compiling different
    steppers at once compile those kernels once.  Where ``fcntl`` is missing, or after
    :data:`COMPILE_LOCK_TIMEOUT` seconds, a process compiles without the lock.
numba's own files
    numba writes the compiled code of a generated module where its cache setting says:
    under ``$NUMBA_CACHE_DIR`` when the user sets it, else in ``__pycache__`` beside the
    module (inside this private directory).  This module never sets numba's configuration.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
import sys
import tempfile
import time
import types

import numba

__all__ = [
    "CacheError",
    "DIGEST_CHARS",
    "ENV_VAR",
    "MAX_AGE_DAYS",
    "MAX_BYTES",
    "cache_dir",
    "clear",
    "compile_lock",
    "dependency_digest",
    "evict",
    "info",
    "is_compiled",
    "load_module",
    "module_closure",
]

#: Environment variable naming the cache directory (tests point it at a temporary one).
ENV_VAR = "DYNAMICS_CACHE_DIR"
#: Modules whose file is older than this are removed when a new one is written: a stepper
#: unused for two months is most likely one of an older version of the code.
MAX_AGE_DAYS = 60
#: Size bound of the directory (generated modules and numba's files beside them).  One
#: stepper with numba's cache is 0.3-1.5 MB (measured: 71 MB held about 60 of them), so
#: 256 MB keeps some two hundred effect combinations and code versions.
MAX_BYTES = 256 * 2**20
#: Hex digits of the content hash in a module's name (80 bits: collisions are not a
#: concern, the check against the full file is exact for the digits kept).
DIGEST_CHARS = 20
#: Seconds a process waits for another one compiling the same stepper before it compiles
#: it too (the longest compile measured is about 30 s of CPU on a loaded machine).
COMPILE_LOCK_TIMEOUT = 600.0
#: Every file this module writes starts with this prefix.
PREFIX = "_dynamics_"
#: Name prefix of the lock files of shared kernel groups (:func:`compile_lock`).
KERNEL_LOCK_PREFIX = "kernels-"


class CacheError(OSError):
    """No private cache directory, or a cached file that fails its checks."""


def _unsafe(path: str) -> str | None:
    """Why the directory ``path`` is not a private cache directory (None when it is)."""
    try:
        st = os.stat(path)
    except OSError as err:
        return f"cannot stat it ({err.strerror})"
    if not stat.S_ISDIR(st.st_mode):
        return "not a directory"
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        return f"owned by uid {st.st_uid}, not by the current user (uid {os.getuid()})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"writable by group or others (mode {stat.S_IMODE(st.st_mode):04o})"
    if not os.access(path, os.W_OK | os.X_OK):
        return "not writable by the current user"
    return None


def _candidates() -> list[str]:
    env = os.environ.get(ENV_VAR)
    if env:
        # an explicit choice is the only candidate: never silently use another place
        return [env]
    cand = []
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        cand.append(os.path.join(xdg, "elastocap-dynamics"))
    cand.append(os.path.join(os.path.expanduser("~"), ".cache", "elastocap-dynamics"))
    return cand


def cache_dir(create: bool = True) -> str:
    """The private directory of generated modules (created with mode 0700 if absent; with
    ``create=False`` an absent one is returned as it is, where it would be made).

    Raises
    ------
    CacheError
        When no candidate is, or can be made, a directory owned by the current user that
        neither group nor others may write to.
    """
    refused = []
    for d in _candidates():
        d = os.path.abspath(d)
        if not create and not os.path.lexists(d):
            return d
        try:
            os.makedirs(d, mode=0o700, exist_ok=True)
        except OSError as err:
            refused.append(f"{d}: cannot create it ({err.strerror})")
            continue
        why = _unsafe(d)
        if why is None:
            return d
        refused.append(f"{d}: {why}")
    raise CacheError(
        "dynamics: no private directory for the generated steppers: "
        + "; ".join(refused)
        + f". Set {ENV_VAR} to a directory you own with mode 0700 (for example "
        "`mkdir -m 700 ~/.dynamics-cache`)."
    )


def module_closure(names) -> set[str]:
    """Source files of the modules ``names`` and of every module they use, directly or not,
    within their own top-level packages.

    A kernel's helpers in another module of its package (``elastocap.drop`` for the
    capillary kernel) are compiled into the generated stepper, so their change must
    change its key too; numpy, numba and the standard library are left out.
    """
    roots = {n.split(".")[0] for n in names}
    seen, files, todo = set(), set(), list(names)
    while todo:
        name = todo.pop()
        if name in seen or name.split(".")[0] not in roots:
            continue
        seen.add(name)
        mod = sys.modules.get(name)
        f = getattr(mod, "__file__", None)
        if mod is None or not f:
            continue
        files.add(os.path.abspath(f))
        for value in vars(mod).values():
            used = value.__name__ if isinstance(value, types.ModuleType) else getattr(
                value, "__module__", None)
            if isinstance(used, str):
                todo.append(used)
    return files


def dependency_digest(module_names) -> str:
    """SHA-256 (hex) of the contents of the sources :func:`module_closure` finds for
    ``module_names``, and of the numba and Python versions.

    Files are identified by their module-relative names (not absolute paths), so two
    checkouts of the same code share their cached steppers.
    """
    h = hashlib.sha256()
    h.update(f"numba {numba.__version__}; python {sys.version_info[:3]}\n".encode())
    for f in sorted(module_closure(module_names)):
        with open(f, "rb") as fh:
            data = fh.read()
        h.update(os.path.basename(f).encode() + b"\0" + hashlib.sha256(data).digest())
    return h.hexdigest()


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:DIGEST_CHARS]


#: Modules loaded by this process, by name (never evicted, never executed twice).
_LOADED: dict[str, types.ModuleType] = {}


def _write_atomic(path: str, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=PREFIX, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o600)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _read_verified(path: str, name_digest: str) -> bytes:
    """The bytes of ``path`` if it passes the checks; :class:`CacheError` otherwise."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        data = f.read()
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        raise CacheError(
            f"dynamics: refusing to import {path}: owned by uid {st.st_uid}, not by the "
            f"current user (uid {os.getuid()}). Remove it (`elastocap cache clear`)."
        )
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise CacheError(
            f"dynamics: refusing to import {path}: writable by group or others (mode "
            f"{stat.S_IMODE(st.st_mode):04o}). Remove it (`elastocap cache clear`)."
        )
    if _digest(data) != name_digest:
        raise CacheError(
            f"dynamics: refusing to import {path}: its content hash {_digest(data)} does "
            f"not match its name ({name_digest}). Remove it (`elastocap cache clear`)."
        )
    return data


def load_module(prefix: str, source: str, depends: str) -> types.ModuleType:
    """Import the generated module ``source`` from the cache (writing it first if absent).

    Parameters
    ----------
    prefix : str
        Name prefix (``"rattle"``, ``"midpoint"``); the file is
        ``_dynamics_<prefix>_<hash>.py``.
    source : str
        The module's Python source.
    depends : str
        :func:`dependency_digest` of what the source uses; recorded in the file's header,
        so that it enters the content hash.

    Returns
    -------
    module
        Registered in ``sys.modules`` under its file name (numba's cache needs it).
    """
    text = (f"# Generated by dynamics ({prefix} stepper); do not edit.\n"
            f"# depends on sources with digest {depends}\n" + source)
    data = text.encode()
    digest = _digest(data)
    modname = f"{PREFIX}{prefix}_{digest}"
    if modname in _LOADED:
        return _LOADED[modname]
    d = cache_dir()
    path = os.path.join(d, modname + ".py")
    if not os.path.lexists(path):
        _write_atomic(path, data)
        evict(keep=set(_LOADED) | {modname})
    verified = _read_verified(path, digest)
    module = types.ModuleType(modname)
    module.__file__ = path
    code = compile(verified, path, "exec")
    sys.modules[modname] = module
    try:
        exec(code, module.__dict__)
    except BaseException:
        sys.modules.pop(modname, None)
        raise
    _LOADED[modname] = module
    return module


def is_compiled(module, functions) -> bool:
    """Whether numba's on-disk cache holds compiled code for each of ``functions`` of a
    ``module``, a generated one or one of a package.  Used to announce a first compilation
    and estimate its cost; a wrong answer costs only the announcement.  Functions this
    process has compiled or loaded already (a numba dispatcher's ``signatures``) are
    compiled without a look at the disk.

    numba names a cached function's data file ``<file stem>.<function>-<line>.py<ver>*.nbc``
    and looks for it (numba's caching documentation) under ``$NUMBA_CACHE_DIR`` when that is
    set, else in ``__pycache__`` beside the module when that can be written, else in the
    user-wide cache ``$XDG_CACHE_HOME/numba`` (default ``~/.cache/numba``), in a folder named
    after the module's folder (a read-only installation)."""
    if all(getattr(getattr(module, f, None), "signatures", None) for f in functions):
        return True
    import glob

    name = module.__name__.rpartition(".")[2]
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        found = glob.glob(os.path.join(glob.escape(numba_dir), "**", f"{name}.*.nbc"),
                          recursive=True)
        return _has(found, name, functions)
    src = os.path.dirname(os.path.abspath(module.__file__))
    pyc = os.path.join(src, "__pycache__")
    if os.access(pyc if os.path.isdir(pyc) else src, os.W_OK):
        found = [f for f in (os.listdir(pyc) if os.path.isdir(pyc) else ())
                 if f.startswith(name + ".") and f.endswith(".nbc")]
    else:
        user = os.path.join(os.environ.get("XDG_CACHE_HOME")
                            or os.path.expanduser(os.path.join("~", ".cache")), "numba")
        found = glob.glob(os.path.join(glob.escape(user), glob.escape(os.path.basename(src))
                                       + "_*", f"{name}.*.nbc"))
    return _has(found, name, functions)


def _has(found, name, functions) -> bool:
    """Whether the numba cache files ``found`` of module stem ``name`` cover ``functions``."""
    have = {os.path.basename(f)[len(name) + 1:].split("-", 1)[0] for f in found}
    return all(f in have for f in functions)


@contextlib.contextmanager
def compile_lock(module, on_wait=None, timeout: float = COMPILE_LOCK_TIMEOUT):
    """Hold the compile lock of a generated ``module``, or of a group of kernels that
    several steppers share, for the ``with`` block.

    Parameters
    ----------
    module : module or str
        A module returned by :func:`load_module` (its lock is ``<module>.lock`` beside
        it), or the name of a group of shared kernels (``kernels-<name>.lock`` in the
        cache directory). A process takes the locks of groups before a module's, so that
        two processes never wait for each other.
    on_wait : callable, optional
        Called once, with no argument, when another process holds the lock (to say why
        this one waits).
    timeout : float
        Seconds to wait before going on without the lock.

    Yields
    ------
    bool
        Whether this process waited for another one.
    """
    try:
        import fcntl
    except ImportError:  # no POSIX file locks: compile without
        yield False
        return
    if isinstance(module, str):
        path = os.path.join(cache_dir(), f"{KERNEL_LOCK_PREFIX}{module}.lock")
    else:
        path = os.path.splitext(module.__file__)[0] + ".lock"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    waited = False
    try:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                locked = True
                break
            except BlockingIOError:
                if not waited and on_wait is not None:
                    on_wait()
                waited = True
                if time.monotonic() > deadline:
                    locked = False
                    break
                time.sleep(0.05)
        try:
            yield waited
        finally:
            if locked:
                fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def _entries(d: str) -> dict[str, list[str]]:
    """Files of each cached module: ``{modname: [paths]}`` (the module and numba's files
    for it in ``__pycache__``), plus leftover temporary files under the key ``""``."""
    out: dict[str, list[str]] = {}
    try:
        names = os.listdir(d)
    except FileNotFoundError:
        return out
    for f in names:
        if f.startswith(PREFIX) and f.endswith(".py"):
            out.setdefault(f[:-3], []).append(os.path.join(d, f))
        elif f.startswith(PREFIX) and f.endswith(".lock"):
            out.setdefault(f[:-5], []).append(os.path.join(d, f))
        elif f.startswith(PREFIX) and f.endswith(".tmp"):
            out.setdefault("", []).append(os.path.join(d, f))
    pyc = os.path.join(d, "__pycache__")
    if os.path.isdir(pyc):
        for f in os.listdir(pyc):
            mod = f.split(".", 1)[0]
            if mod.startswith(PREFIX):
                out.setdefault(mod, []).append(os.path.join(pyc, f))
    return out


def _size(paths) -> int:
    n = 0
    for p in paths:
        try:
            n += os.lstat(p).st_size
        except OSError:
            pass
    return n


def _mtime(paths) -> float:
    try:
        return max(os.lstat(p).st_mtime for p in paths)
    except (OSError, ValueError):
        return 0.0


def _remove(paths) -> None:
    for p in paths:
        try:
            os.unlink(p)
        except OSError:
            pass


def evict(keep=(), max_bytes: int = MAX_BYTES, max_age_days: float = MAX_AGE_DAYS,
          now: float | None = None) -> list[str]:
    """Remove cached modules older than ``max_age_days``, then the oldest until the cache
    holds at most ``max_bytes``; never those named in ``keep``.  Returns the removed names.

    A module's age is that of its newest file (numba rewrites its index when it compiles a
    new specialisation), so a module in use stays.
    """
    d = cache_dir()
    now = time.time() if now is None else now
    entries = _entries(d)
    removed = []
    tmp = entries.pop("", [])
    _remove([p for p in tmp if now - _mtime([p]) > 3600.0])  # a writer's crash leftovers
    ages = sorted(((_mtime(p), m) for m, p in entries.items() if m not in keep))
    total = sum(_size(p) for p in entries.values())
    for mtime, m in ages:
        if now - mtime > max_age_days * 86400.0 or total > max_bytes:
            total -= _size(entries[m])
            _remove(entries[m])
            removed.append(m)
    return removed


def clear() -> int:
    """Remove every cached module and numba's files for them; returns how many (creates
    nothing)."""
    d = cache_dir(create=False)
    entries = _entries(d)
    n = len([m for m in entries if m])
    for paths in entries.values():
        _remove(paths)
    if os.path.isdir(d):
        _remove([os.path.join(d, f) for f in os.listdir(d)
                 if f.startswith(KERNEL_LOCK_PREFIX) and f.endswith(".lock")])
    for m in [m for m in _LOADED]:
        _LOADED.pop(m)
    return n


def info() -> dict:
    """Location, number of cached modules, their size and the limits (plain data); creates
    nothing."""
    d = cache_dir(create=False)
    entries = _entries(d)
    entries.pop("", None)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    return {
        "directory": d,
        "modules": len(entries),
        "bytes": sum(_size(p) for p in entries.values()),
        "max_bytes": MAX_BYTES,
        "max_age_days": MAX_AGE_DAYS,
        "numba_cache_dir": numba_dir or None,
        "numba_files": ("under NUMBA_CACHE_DIR" if numba_dir
                        else "in __pycache__ beside each module"),
    }
