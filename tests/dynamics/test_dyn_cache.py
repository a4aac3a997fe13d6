"""The generated-code cache: private directory, content-addressed names, files checked
before they are executed, bounded size and age, clear/info."""

import os
import stat
import sys

import pytest
from lock_holder import lock_held_by_another_process

from dynamics import cache

SRC = "VALUE = 42\n"


@pytest.fixture
def tmp_cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_VAR, str(d))
    monkeypatch.setattr(cache, "_LOADED", {})
    yield d
    for m in [m for m in sys.modules if m.startswith(cache.PREFIX + "test_")]:
        sys.modules.pop(m)


def _module_file(d):
    (f,) = [p for p in d.iterdir() if p.suffix == ".py"]
    return f


def test_directory_is_private_and_name_is_the_content_hash(tmp_cache):
    mod = cache.load_module("test", SRC, "d" * 64)
    assert mod.VALUE == 42
    assert stat.S_IMODE(os.stat(tmp_cache).st_mode) == 0o700
    f = _module_file(tmp_cache)
    assert stat.S_IMODE(os.stat(f).st_mode) == 0o600
    import hashlib

    digest = hashlib.sha256(f.read_bytes()).hexdigest()[: cache.DIGEST_CHARS]
    assert f.name == f"{cache.PREFIX}test_{digest}.py"
    assert mod.__file__ == str(f)
    # the dependency digest enters the name: another digest, another file
    cache.load_module("test", SRC, "e" * 64)
    assert len([p for p in tmp_cache.iterdir() if p.suffix == ".py"]) == 2
    assert not [p for p in tmp_cache.iterdir() if p.suffix == ".tmp"]


def test_planted_file_with_a_wrong_hash_is_refused_and_not_executed(tmp_cache, tmp_path):
    cache.load_module("test", SRC, "d" * 64)
    f = _module_file(tmp_cache)
    marker = tmp_path / "executed"
    f.write_text(f"open({str(marker)!r}, 'w').close()\nVALUE = 42\n")
    os.chmod(f, 0o600)
    cache._LOADED.clear()
    sys.modules.pop(f.stem, None)
    with pytest.raises(cache.CacheError, match="content hash .* does not match its name"):
        cache.load_module("test", SRC, "d" * 64)
    assert not marker.exists()


def test_file_writable_by_others_is_refused(tmp_cache):
    cache.load_module("test", SRC, "d" * 64)
    f = _module_file(tmp_cache)
    os.chmod(f, 0o666)
    cache._LOADED.clear()
    with pytest.raises(cache.CacheError, match="writable by group or others"):
        cache.load_module("test", SRC, "d" * 64)


@pytest.mark.skipif(not hasattr(os, "getuid") or os.getuid() != 0,
                    reason="changing a file's owner needs root")
def test_file_of_another_owner_is_refused_even_with_the_right_hash(tmp_cache):
    cache.load_module("test", SRC, "d" * 64)
    f = _module_file(tmp_cache)
    os.chown(f, 12345, -1)
    cache._LOADED.clear()
    with pytest.raises(cache.CacheError, match="owned by uid 12345"):
        cache.load_module("test", SRC, "d" * 64)


def test_world_writable_directory_is_refused_without_fallback(tmp_path, monkeypatch):
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    monkeypatch.setenv(cache.ENV_VAR, str(shared))
    with pytest.raises(cache.CacheError,
                       match=r"shared: writable by group or others \(mode 0777\)"):
        cache.cache_dir()


def test_no_private_home_cache_gives_an_error_not_the_temporary_directory(tmp_path,
                                                                         monkeypatch):
    # HOME unusable (here a plain file, so nothing can be created under it), TMPDIR set:
    # the cache must not move to the shared temporary directory
    home = tmp_path / "home"
    home.write_text("")
    monkeypatch.delenv(cache.ENV_VAR, raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    with pytest.raises(cache.CacheError, match="Set DYNAMICS_CACHE_DIR"):
        cache.cache_dir()
    assert not (tmp_path / "elastocap-dynamics").exists()


def _fake_module(d, name, size, mtime):
    f = d / f"{cache.PREFIX}{name}.py"
    f.write_bytes(b"x" * size)
    pyc = d / "__pycache__"
    pyc.mkdir(exist_ok=True)
    g = pyc / f"{cache.PREFIX}{name}.run-12.py312.nbc"
    g.write_bytes(b"y" * size)
    for p in (f, g):
        os.utime(p, (mtime, mtime))


def test_eviction_by_age_then_by_size_oldest_first(tmp_cache):
    cache.cache_dir()
    now = 1.0e9
    day = 86400.0
    _fake_module(tmp_cache, "old", 10, now - (cache.MAX_AGE_DAYS + 1) * day)
    _fake_module(tmp_cache, "a", 100, now - 3 * day)
    _fake_module(tmp_cache, "b", 100, now - 2 * day)
    _fake_module(tmp_cache, "c", 100, now - 1 * day)
    _fake_module(tmp_cache, "kept", 100, now - 10 * day)
    # 4 modules of 200 bytes remain after the age limit; a bound of 450 keeps two of them
    removed = cache.evict(keep={f"{cache.PREFIX}kept"}, max_bytes=450, now=now)
    assert removed == [f"{cache.PREFIX}old", f"{cache.PREFIX}a", f"{cache.PREFIX}b"]
    left = sorted(p.name for p in tmp_cache.rglob(f"{cache.PREFIX}*"))
    assert left == sorted([f"{cache.PREFIX}c.py", f"{cache.PREFIX}c.run-12.py312.nbc",
                           f"{cache.PREFIX}kept.py", f"{cache.PREFIX}kept.run-12.py312.nbc"])


def test_clear_and_info(tmp_cache):
    cache.load_module("test", SRC, "d" * 64)
    cache.load_module("test", SRC, "e" * 64)
    other = tmp_cache / "not-ours.txt"
    other.write_text("kept")
    i = cache.info()
    assert i["directory"] == str(tmp_cache) and i["modules"] == 2 and i["bytes"] > 0
    assert i["max_bytes"] == cache.MAX_BYTES
    assert cache.clear() == 2
    assert cache.info()["modules"] == 0
    assert other.exists()  # only the cache's own files are removed


def test_cli_cache_info_and_clear(tmp_cache, capsys):
    import json

    from elastocap.cli import main

    cache.load_module("test", SRC, "d" * 64)
    assert main(["cache", "info", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["directory"] == str(tmp_cache) and rep["modules"] == 1
    assert main(["cache", "clear"]) == 0
    assert "removed 1 generated stepper(s)" in capsys.readouterr().out
    assert not [p for p in tmp_cache.iterdir() if p.suffix == ".py"]


def test_cache_info_and_clear_create_nothing(tmp_path, monkeypatch, capsys):
    from elastocap.cli import main

    where = tmp_path / "not-yet"
    monkeypatch.setenv(cache.ENV_VAR, str(where))
    assert main(["cache", "info"]) == 0 and main(["cache", "clear"]) == 0
    assert f"generated steppers: {where}" in capsys.readouterr().out
    assert not where.exists()


def test_cli_cache_refuses_a_shared_directory(tmp_path, monkeypatch, capsys):
    from elastocap.cli import main

    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    monkeypatch.setenv(cache.ENV_VAR, str(shared))
    assert main(["cache", "info"]) == 2
    assert "writable by group or others" in capsys.readouterr().err


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX file locks")
def test_a_second_process_waits_for_the_one_compiling_then_goes_on(tmp_cache):
    """While another process holds a module's compile lock, :func:`cache.compile_lock`
    waits (saying so once) and enters when the holder ends; uncontended, it enters at
    once.  The lock file belongs to the module: eviction and ``clear`` remove it."""
    import time

    mod = cache.load_module("test", SRC, "d" * 64)
    said = []
    with lock_held_by_another_process(mod, 2.0):
        t0 = time.monotonic()
        with cache.compile_lock(mod, on_wait=lambda: said.append(1)) as waited:
            # entered when the holder ended (the kernel released its lock), not before
            entered = time.monotonic() - t0
        assert waited and said == [1] and entered > 1.0
    with cache.compile_lock(mod, on_wait=lambda: said.append(2)) as waited:
        assert not waited and said == [1]
    lock = os.path.splitext(mod.__file__)[0] + ".lock"
    assert os.path.exists(lock)
    assert cache.clear() == 1
    assert not os.path.exists(lock)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX file locks")
def test_a_kernel_groups_lock_lives_in_the_cache_and_clear_removes_it(tmp_cache):
    """Kernels several steppers share have a lock by name, in the cache directory (not
    beside a module of the package, which may be read-only); ``clear`` removes it and
    counts no module for it."""
    import time

    lock = os.path.join(cache.cache_dir(), "kernels-contact.lock")
    said = []
    with lock_held_by_another_process(lock, 1.5):
        t0 = time.monotonic()
        with cache.compile_lock("contact", on_wait=lambda: said.append(1)) as waited:
            entered = time.monotonic() - t0
        assert waited and said == [1] and entered > 1.0
    assert os.stat(lock).st_mode & 0o777 == 0o600
    assert cache.info()["modules"] == 0
    assert cache.clear() == 0 and not os.path.exists(lock)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX file locks")
def test_a_lock_held_past_the_timeout_is_passed_by(tmp_cache):
    mod = cache.load_module("test", SRC, "d" * 64)
    with lock_held_by_another_process(mod, 30) as holder:
        with cache.compile_lock(mod, timeout=0.2) as waited:
            assert waited and holder.poll() is None


def test_is_compiled_reads_the_numba_cache_files_of_a_package_module(tmp_path, monkeypatch):
    """numba names a cached function ``<file stem>.<function>-<line>.py<ver>*.nbc``; for a
    module of a package the stem is the last part of its name (``dynamics.contact`` ->
    ``contact.``), under ``$NUMBA_CACHE_DIR`` in a folder of numba's choosing."""
    import types

    mod = types.ModuleType("somepkg.kernels")
    mod.f = mod.g = object()  # not dispatchers: nothing compiled in this process
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    sub = tmp_path / "some" / "path"
    sub.mkdir(parents=True)
    (sub / "kernels.f-12.py311.1.nbc").write_bytes(b"")
    assert cache.is_compiled(mod, ("f",))
    assert not cache.is_compiled(mod, ("f", "g"))
    (sub / "kernels.g-30.py311.1.nbc").write_bytes(b"")
    assert cache.is_compiled(mod, ("f", "g"))
    # another module's stem does not count
    other = types.ModuleType("somepkg.other")
    other.f = object()
    assert not cache.is_compiled(other, ("f",))


def test_is_compiled_reads_numbas_user_wide_cache_for_a_read_only_install(tmp_path,
                                                                         monkeypatch):
    """Where ``__pycache__`` beside the module cannot be written (a read-only installation:
    here a folder that does not exist), numba caches in ``$XDG_CACHE_HOME/numba``, in a
    folder named after the module's folder and a hash of its path."""
    import types

    mod = types.ModuleType("somepkg.kernels")
    mod.__file__ = str(tmp_path / "ro" / "somepkg" / "kernels.py")
    mod.f = object()
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert not cache.is_compiled(mod, ("f",))
    other = tmp_path / "xdg" / "numba" / "otherpkg_0123abcd"
    other.mkdir(parents=True)
    (other / "kernels.f-12.py311.1.nbc").write_bytes(b"")
    assert not cache.is_compiled(mod, ("f",))  # another folder's module of that name
    sub = tmp_path / "xdg" / "numba" / "somepkg_4567ef89"
    sub.mkdir(parents=True)
    (sub / "kernels.f-12.py311.1.nbc").write_bytes(b"")
    assert cache.is_compiled(mod, ("f",))


def test_compile_estimate_adds_what_numba_has_not_cached(monkeypatch):
    """The announced estimate of a first compile: the stepper's base and effects, the
    package's kernels when numba's cache lacks them, self-contact's link and its kernels
    when those are not cached either (measured costs in ``dynamics.codegen``)."""
    from dynamics import Gravity, SelfContact, codegen, contact

    cached = set()
    monkeypatch.setattr(codegen, "is_compiled", lambda mod, fns: mod in cached)
    own = ((cache, ("f",)),)  # a stand-in for the method's own kernels
    g, sc = Gravity(1.0), SelfContact(0.1)
    est = codegen.compile_estimate
    assert est(5.0, 2.0, (g,), own) == 5.0 + 2.0 + codegen.KERNELS_COLD_S
    cached.add(cache)
    assert est(5.0, 2.0, (g,), own) == 7.0
    # self-contact is not counted as an effect: its link and its kernels are
    assert est(5.0, 2.0, (g, sc), own) == (7.0 + codegen.CONTACT_LINK_S
                                           + codegen.CONTACT_KERNELS_S)
    cached.add(contact)
    assert est(5.0, 2.0, (g, sc), own) == 7.0 + codegen.CONTACT_LINK_S
