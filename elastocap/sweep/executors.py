"""Executors for sweeps, all :class:`concurrent.futures.Executor`.

* Local (default): a spawn-context :class:`~concurrent.futures.ProcessPoolExecutor`, one
  worker per core, each worker with one numba thread and one BLAS thread (the runs are the
  parallelism; threads inside a worker would only compete for the same cores). Spawn, not
  fork: numba's and the BLAS thread pools are not fork-safe.
* Cluster: ``scheduler="tcp://host:8786"`` -> ``dask.distributed.Client(address)
  .get_executor()``; dask is imported only then (the ``distributed`` extra). Start dask
  workers with ``--nthreads 1`` and ``NUMBA_NUM_THREADS=1`` in their environment.

Workers only compute and return plain data; the process running the sweep writes the store.

A local worker ends with the process that started it: killing a sweep, by SIGTERM or
SIGKILL, leaves no worker computing. On Linux the kernel kills the worker (``prctl
PR_SET_PDEATHSIG``), which works while the worker is inside a compiled time stepper, and a
stepper holds the GIL for a whole run, so no thread of the worker could notice. The signal
fires when the *thread* that started the worker ends, and a
:class:`~concurrent.futures.ProcessPoolExecutor` starts workers from the thread that
submits to it: open and use a pool from one thread, as :func:`elastocap.sweep.run_sweep`
does. Elsewhere a thread of the worker polls the parent's pid every
:data:`PARENT_POLL_S`; it runs between compiled calls only.

A local pool whose worker died (killed, out of memory) is replaced by
:meth:`SweepExecutor.restart`; the sweep then retries the runs that were in flight.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import numbers
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass

__all__ = ["MissingExtraError", "SweepExecutor", "open_executor", "worker_info"]

#: Environment of a local worker: one thread for numba's parallel layer and for BLAS.
WORKER_ENV = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
#: Futures kept in flight per worker slot: 2 keeps every worker fed while the sweep writes
#: results, and bounds what a killed sweep loses to the runs actually executing.
IN_FLIGHT_PER_SLOT = 2
#: Seconds between a local worker's checks that its parent is alive (a check is one
#: getppid call; 0.5 s bounds how long an orphaned worker keeps a core busy).
PARENT_POLL_S = 0.5


def check_not_importing_main() -> None:
    """Refuse to open a local pool from the top level of a script that a spawned worker is
    importing. The local workers are started with "spawn", which runs the main script again
    in each worker as ``__mp_main__``; a sweep at its top level would start in every worker
    (and wait there for the runs the parent's sweep has claimed: a hang). The refusal ends
    such a worker at once, and the parent's sweep stops (:class:`WorkerStartError`)."""
    import inspect

    frame = inspect.currentframe()
    while frame is not None:
        if frame.f_code.co_name == "<module>" and frame.f_globals.get("__name__") == "__mp_main__":
            raise WorkerStartError(
                "a local sweep was started while a worker process imported the main script "
                "(workers are started with 'spawn', which runs the script again): put the "
                "sweep under `if __name__ == \"__main__\":`")
        frame = frame.f_back


class WorkerStartError(RuntimeError):
    """The local workers cannot start (see :func:`check_not_importing_main`)."""


class MissingExtraError(ImportError):
    """An optional dependency is missing; the message names the extra to install."""


def _watch_parent(parent_pid: int) -> None:
    while True:
        if os.getppid() != parent_pid:  # re-parented: the sweep is gone
            os._exit(1)
        time.sleep(PARENT_POLL_S)


#: ``prctl`` option: the signal a process gets when its parent thread ends (linux/prctl.h).
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when its parent ends (Linux); False elsewhere
    or if the call fails. Called only inside a worker, which is this module's own process."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _init_worker(parent_pid: int | None = None) -> None:
    """Initializer of a local worker: runs before any task, so before numba is imported by
    elastocap's run function. Arranges for the worker to end with its parent."""
    os.environ.update(WORKER_ENV)
    if "numba" in sys.modules:  # the parent's main script imported it at top level
        import numba

        numba.set_num_threads(1)
    if parent_pid is None:
        return
    if _die_with_parent():
        if os.getppid() != parent_pid:  # the parent ended before the request was made
            os._exit(1)
        return
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True,
                     name="elastocap-parent-watch").start()


def worker_info() -> dict:
    """Thread settings seen inside a worker (for tests and ``--workers`` diagnostics)."""
    import numba

    return {
        "pid": os.getpid(),
        "NUMBA_NUM_THREADS": os.environ.get("NUMBA_NUM_THREADS"),
        "numba_threads": int(numba.get_num_threads()),
    }


@dataclass
class SweepExecutor:
    """An executor and how many runs to keep in flight on it.

    Attributes
    ----------
    executor : concurrent.futures.Executor
    slots : int
        Parallel workers (threads) behind it.
    description : str
        For messages, e.g. "local pool, 2 workers".
    """

    executor: Executor
    slots: int
    description: str
    #: Makes a fresh executor of the same kind (None: this one cannot be replaced).
    factory: Callable[[], Executor] | None = None

    def restart(self) -> bool:
        """Replace a broken executor by a fresh one; False if it cannot be replaced."""
        if self.factory is None:
            return False
        old = self.executor
        self.executor = self.factory()
        old.shutdown(wait=False, cancel_futures=True)
        return True

    @property
    def max_in_flight(self) -> int:
        return max(1, IN_FLIGHT_PER_SLOT * self.slots)


#: Local worker processes allowed per usable core. Each worker is a process of its own that
#: imports numba and loads the compiled stepper (about 200 MB); beyond one per core they only
#: share the cores, so a count far above it is a typing error, not a request.
WORKERS_PER_CORE_MAX = 4


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def check_workers(workers) -> int:
    """``workers`` as an integer from 1 to ``WORKERS_PER_CORE_MAX`` per usable core
    (None = one per core)."""
    cores = usable_cores()
    if workers is None:
        return cores
    top = WORKERS_PER_CORE_MAX * cores
    # any integer type (numpy's too), as a plain int
    if (isinstance(workers, bool) or not isinstance(workers, numbers.Integral)
            or not 1 <= workers <= top):
        raise ValueError(
            f"--workers: got {workers!r}; expected an integer from 1 to {top} "
            f"({WORKERS_PER_CORE_MAX} per core of the {cores} this process may use: "
            "each worker is a process of its own, and more than one per core only share them)")
    return int(workers)


def check_scheduler(address: str) -> None:
    """Refuse a malformed address, and a missing dask.distributed, before any work."""
    if not isinstance(address, str) or "://" not in address:
        raise ValueError(
            f"--scheduler: got {address!r}; expected a dask scheduler address "
            "such as tcp://127.0.0.1:8786"
        )
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise MissingExtraError(
            f"--scheduler {address}: needs dask.distributed, which is not installed; "
            "install the extra: pip install 'elastocap[distributed]'"
        ) from None


@contextlib.contextmanager
def open_executor(workers: int | None = None, scheduler: str | None = None):
    """Yield a :class:`SweepExecutor`; shut it down (or disconnect) on exit.

    Parameters
    ----------
    workers : int, optional
        Local worker processes (default: one per core). Ignored with ``scheduler``.
    scheduler : str, optional
        A dask scheduler address (``tcp://...``): run on that cluster.
    """
    if scheduler is not None:
        check_scheduler(scheduler)
        from distributed import Client

        try:
            # 30 s: dask's own default connect timeout, said out loud
            client = Client(scheduler, timeout=30)
        except (OSError, TimeoutError) as err:
            raise ValueError(f"--scheduler: got {scheduler!r}; could not connect to a dask "
                             f"scheduler there ({type(err).__name__}: {err})") from None
        try:
            slots = max(1, sum(client.nthreads().values()))
            yield SweepExecutor(
                client.get_executor(), slots, f"dask cluster {scheduler}, {slots} worker threads"
            )
        finally:
            client.close()
        return
    n = check_workers(workers)
    check_not_importing_main()

    def factory():
        return ProcessPoolExecutor(
            max_workers=n,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
            initargs=(os.getpid(),),
        )

    ex = SweepExecutor(factory(), n, f"local pool, {n} worker{'s' * (n != 1)}", factory)
    try:
        yield ex
    finally:
        ex.executor.shutdown(wait=True, cancel_futures=True)
