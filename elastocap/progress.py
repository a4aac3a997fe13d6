"""A tiny progress protocol: none, text, or tqdm when installed.

A progress object is called as ``progress(done, total, note)`` whenever a unit of work
finishes or starts (a sweep's run, a command's phase: compiling, tracing, a figure), and
``progress.close()`` at the end. ``total`` may grow (a sweep's refinement adds runs as it
goes); ``total = 0`` means not known. The library never prints; only these objects do, on
stderr. ``label`` and ``unit`` say what is counted (``sweep: 3/10 runs``).
"""

from __future__ import annotations

import sys
import time
from typing import Protocol

__all__ = ["NoProgress", "Progress", "TextProgress", "TqdmProgress", "heartbeat", "make_progress"]


class Progress(Protocol):
    def __call__(self, done: int, total: int, note: str = "") -> None: ...

    def close(self) -> None: ...


class NoProgress:
    """Silent."""

    def __call__(self, done: int, total: int, note: str = "") -> None:
        pass

    def close(self) -> None:
        pass


class TextProgress:
    """One line per ``every`` seconds (and at the end) on ``stream``: done/total and note."""

    #: 2 s between lines: readable in a log, and negligible next to a run (~1 s).
    def __init__(self, stream=None, every: float = 2.0, label: str = "sweep",
                 unit: str = "runs"):
        self.stream = sys.stderr if stream is None else stream
        self.every = every
        self.label = label
        self.unit = unit
        self._last = -1e300
        self._state = None
        self._written = False

    def __call__(self, done: int, total: int, note: str = "") -> None:
        self._state = (done, total, note)
        self._written = False
        now = time.monotonic()
        if now - self._last >= self.every:
            self._last = now
            self._write()

    def _write(self) -> None:
        done, total, note = self._state
        count = f"{done}/{total}" if total else f"{done}"
        self.stream.write(f"{self.label}: {count} {self.unit} {note}".rstrip() + "\n")
        self.stream.flush()
        self._written = True

    def close(self) -> None:
        if self._state is not None and not self._written:
            self._write()


class TqdmProgress:
    """A tqdm bar on stderr (needs the ``progress`` extra)."""

    def __init__(self, label: str = "sweep", unit: str = "run"):
        from tqdm import tqdm

        self._bar = tqdm(total=None, unit=unit, desc=label, file=sys.stderr)

    def __call__(self, done: int, total: int, note: str = "") -> None:
        bar = self._bar
        if (total or None) != bar.total:
            bar.total = total or None
        bar.set_postfix_str(note, refresh=False)
        bar.update(done - bar.n)

    def close(self) -> None:
        self._bar.close()


def make_progress(kind: str = "none", label: str = "sweep", unit: str = "runs",
                  every: float = 2.0) -> Progress:
    """``"none"``, ``"text"``, ``"tqdm"`` or ``"auto"`` (tqdm when installed and stderr is a
    terminal, else text: a log file gets lines, not bar redraws). ``every``: seconds between
    text lines (0: a line per call)."""
    if kind == "none":
        return NoProgress()
    if kind == "text" or (kind == "auto" and not sys.stderr.isatty()):
        return TextProgress(every=every, label=label, unit=unit)
    if kind in ("tqdm", "auto"):
        try:
            return TqdmProgress(label=label, unit=unit.rstrip("s") or unit)
        except ImportError:
            if kind == "tqdm":
                raise ValueError(
                    "--progress: got 'tqdm'; tqdm is not installed (pip install "
                    "'elastocap[progress]'); use text or none"
                ) from None
            return TextProgress(every=every, label=label, unit=unit)
    raise ValueError(f"--progress: got {kind!r}; expected one of none, text, tqdm, auto")


class heartbeat:  # noqa: N801 (a context manager used like a function)
    """Report a phase of unknown length: ``progress(done, total, note)`` now, then again
    every ``every`` seconds with the elapsed time, until the block ends.

    >>> with heartbeat(progress, 0, 3, "tracing branches"):   # doctest: +SKIP
    ...     trace_branches(scene)
    """

    def __init__(self, progress: Progress, done: int, total: int, note: str,
                 every: float = 10.0):
        import threading

        self.progress, self.done, self.total, self.note = progress, done, total, note
        self.every = every
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, daemon=True)

    def _beat(self) -> None:
        t0 = time.monotonic()
        while not self._stop.wait(self.every):
            self.progress(self.done, self.total,
                          f"{self.note} ({time.monotonic() - t0:.0f} s)")

    def __enter__(self):
        self.progress(self.done, self.total, self.note)
        if not isinstance(self.progress, NoProgress):
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
