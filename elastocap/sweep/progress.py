"""A tiny progress protocol for sweeps: none, text, or tqdm when installed.

A progress object is called as ``progress(done, total, note)`` whenever a run finishes (or
is found in the store), and ``progress.close()`` at the end. ``total`` may grow (refinement
adds runs as it goes). The sweep never prints; only these objects do, on stderr.
"""

from __future__ import annotations

import sys
import time
from typing import Protocol

__all__ = ["NoProgress", "Progress", "TextProgress", "TqdmProgress", "make_progress"]


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
    def __init__(self, stream=None, every: float = 2.0):
        self.stream = sys.stderr if stream is None else stream
        self.every = every
        self._last = -1e300
        self._state = None

    def __call__(self, done: int, total: int, note: str = "") -> None:
        self._state = (done, total, note)
        now = time.monotonic()
        if now - self._last >= self.every:
            self._last = now
            self._write()

    def _write(self) -> None:
        done, total, note = self._state
        self.stream.write(f"sweep: {done}/{total} runs {note}\n")
        self.stream.flush()

    def close(self) -> None:
        if self._state is not None:
            self._write()


class TqdmProgress:
    """A tqdm bar on stderr (needs the ``progress`` extra)."""

    def __init__(self):
        from tqdm import tqdm

        self._bar = tqdm(total=0, unit="run", desc="sweep", file=sys.stderr)

    def __call__(self, done: int, total: int, note: str = "") -> None:
        bar = self._bar
        if total != bar.total:
            bar.total = total
        bar.set_postfix_str(note, refresh=False)
        bar.update(done - bar.n)

    def close(self) -> None:
        self._bar.close()


def make_progress(kind: str = "none") -> Progress:
    """``"none"``, ``"text"``, ``"tqdm"`` or ``"auto"`` (tqdm when installed and stderr is a
    terminal, else text: a log file gets lines, not bar redraws)."""
    if kind == "none":
        return NoProgress()
    if kind == "text" or (kind == "auto" and not sys.stderr.isatty()):
        return TextProgress()
    if kind in ("tqdm", "auto"):
        try:
            return TqdmProgress()
        except ImportError:
            if kind == "tqdm":
                raise ValueError(
                    "--progress: got 'tqdm'; tqdm is not installed (pip install "
                    "'elastocap[progress]'); use text or none"
                ) from None
            return TextProgress()
    raise ValueError(f"--progress: got {kind!r}; expected one of none, text, tqdm, auto")
