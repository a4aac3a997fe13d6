"""A child process holding a generated module's compile lock (the tests of
:func:`dynamics.cache.compile_lock` and of the driver that takes it)."""

import contextlib
import os
import subprocess
import sys

HOLD = """
import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o600)
fcntl.flock(fd, fcntl.LOCK_EX)
print("held", flush=True)
time.sleep(float(sys.argv[2]))
"""


@contextlib.contextmanager
def lock_held_by_another_process(mod, seconds):
    """A child process holding ``mod``'s compile lock (or the lock file at the path
    ``mod``) for ``seconds``; yields it."""
    lock = mod if isinstance(mod, str) else os.path.splitext(mod.__file__)[0] + ".lock"
    holder = subprocess.Popen([sys.executable, "-c", HOLD, lock, str(seconds)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        yield holder
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
