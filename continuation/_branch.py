"""Results as data: :class:`Branch` and :class:`SpecialPoint`, with .npz + JSON storage."""

from __future__ import annotations

import contextlib
import json
import math
import os
import secrets
import zipfile
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np


def _replace_atomically(path: Path, write) -> None:
    """``write(f)`` into a temporary file beside ``path``, then rename it to ``path``: a
    reader (or a killed writer) never sees half a file."""
    tmp = path.with_name(f".{path.name}.tmp-{secrets.token_hex(6)}")
    try:
        with open(tmp, "xb") as f:  # the user's usual file mode (umask), unlike mkstemp
            write(f)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise

SCHEMA_VERSION = 1


def same_value(a, b) -> bool:
    """Equality of plain result data: arrays by shape and elements, NaN equal to NaN (an
    unestimated precision equals itself), dicts, lists and tuples item by item."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return False
        try:
            return bool(np.array_equal(a, b, equal_nan=True))
        except TypeError:  # not numeric: NaN cannot occur
            return bool(np.array_equal(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_value(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return (type(a) is type(b) and len(a) == len(b)
                and all(same_value(x, y) for x, y in zip(a, b, strict=True)))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def _same_fields(a, b) -> bool:
    return all(same_value(getattr(a, f.name), getattr(b, f.name)) for f in fields(a))

# Status codes of a branch end. The message always says what happened and what to try.
MAX_STEPS = 0        # ran max_steps
PARAMETER_BOUND = 1  # reached p_min or p_max (last point is exactly on the bound)
STEP_TOO_SMALL = 2   # the corrector failed at ds_min
START_FAILED = 3     # Newton at the start did not converge or the start is singular
STOPPED = 4          # a terminal event or the callback stopped the run
NON_FINITE = 5       # the problem returned NaN/inf
LOOP_CLOSED = 6      # the branch came back to its start (an isola)

STATUS_NAMES = {
    MAX_STEPS: "max_steps",
    PARAMETER_BOUND: "parameter_bound",
    STEP_TOO_SMALL: "step_too_small",
    START_FAILED: "start_failed",
    STOPPED: "stopped",
    NON_FINITE: "non_finite",
    LOOP_CLOSED: "loop_closed",
}


#: The library's own version (recorded in every branch's metadata). The library knows
#: nothing of the application that ships it; the application records its own version.
__version__ = "1.1"


def package_version() -> str:
    """The version of this library, as recorded in branch metadata."""
    return __version__


@dataclass(eq=False)
class SpecialPoint:
    """A special point on a branch.

    Attributes
    ----------
    kind : str
        ``"fold"``, ``"branch_point"``, ``"stability"`` (the stability index
        changes), ``"event"`` (a user function crosses zero), ``"endpoint"``.
    index : int
        Index of the branch point just after the special point (it lies between
        ``index - 1`` and ``index``); for endpoints the point itself.
    p : float
        Parameter value (located, or the last point for unlocated kinds).
    u : ndarray or None
        State at the special point.
    precision : float
        For located points, the size of the last Newton correction of p (or the
        arclength bracket of a bisection); for detected-only points, the width
        of the bracketing parameter interval. NaN when not estimated (``null`` in
        the JSON that :meth:`Branch.to_dict` writes).
    located : bool
        True if the point solves its defining system (not just bracketed).
    name : str
        Event name (events) or a short description.
    data : dict
        Extra data: ``tangent`` (ndarray n+1), ``kernel`` (branch points: the
        second null direction), ``stability`` (before, after), ...
    """

    kind: str
    index: int
    p: float
    u: np.ndarray | None = None
    precision: float = float("nan")
    located: bool = False
    name: str = ""
    data: dict = field(default_factory=dict)

    def __eq__(self, other) -> bool:
        # field by field, arrays by value (the generated == would ask an array for its
        # truth value and raise)
        if type(other) is not type(self):
            return NotImplemented
        return _same_fields(self, other)

    __hash__ = None

    def __repr__(self) -> str:
        loc = "located" if self.located else "bracketed"
        nm = f" {self.name!r}" if self.name else ""
        return (f"SpecialPoint({self.kind}{nm}, index={self.index}, p={self.p:.12g}, "
                f"{loc}, precision={self.precision:.1e})")


@dataclass(eq=False)
class Branch:
    """A computed branch: per-point columns plus special points.

    Attributes
    ----------
    p : ndarray, shape (m,)
        Continuation parameter at each point.
    u : ndarray, shape (m, n) or None
        States (None if ``store_states=False``).
    tangent : ndarray, shape (m, n + 1) or None
        Unit tangents (du/ds, dp/ds) in the weighted norm.
    ds : ndarray, shape (m,)
        Step that led to each point (0 at the start).
    newton_iterations : ndarray of int, shape (m,)
    stability : ndarray of int, shape (m,)
        Number of negative eigenvalues of the (projected) Hessian; -1 if unknown.
    observables : dict[str, ndarray (m,)]
    special_points : list[SpecialPoint]
    status : int
        Termination code (``continuation.MAX_STEPS`` ...).
    message : str
        What stopped the run and what to try.
    parameter : str
        Name of the continuation parameter (``"p"``; ``"q"`` for fold curves).
    metadata : dict
        Problem name, settings, package version, ...
    """

    p: np.ndarray
    u: np.ndarray | None
    tangent: np.ndarray | None
    ds: np.ndarray
    newton_iterations: np.ndarray
    stability: np.ndarray
    observables: dict
    special_points: list
    status: int
    message: str
    parameter: str = "p"
    metadata: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """True unless the run failed (start failed or non-finite values)."""
        return self.status not in (START_FAILED, NON_FINITE)

    def __len__(self) -> int:
        return int(self.p.size)

    def __repr__(self) -> str:
        kinds = {}
        for sp in self.special_points:
            kinds[sp.kind] = kinds.get(sp.kind, 0) + 1
        return (f"Branch({len(self)} points, {self.parameter} in "
                f"[{np.min(self.p):.6g}, {np.max(self.p):.6g}], special={kinds}, "
                f"status={STATUS_NAMES.get(self.status, self.status)!r})"
                if len(self) else f"Branch(empty, status={self.status}, {self.message!r})")

    def points(self, kind: str) -> list:
        """Special points of one kind, in branch order."""
        return [sp for sp in self.special_points if sp.kind == kind]

    @property
    def folds(self) -> list:
        return self.points("fold")

    @property
    def branch_points(self) -> list:
        return self.points("branch_point")

    def __eq__(self, other) -> bool:
        # field by field, arrays by value (as SpecialPoint)
        if type(other) is not type(self):
            return NotImplemented
        return _same_fields(self, other)

    __hash__ = None

    # ------------------------------------------------------------------ storage
    def to_dict(self) -> dict:
        """JSON-able summary (no state arrays)."""
        return _jsonable({
            "schema_version": SCHEMA_VERSION,
            "parameter": self.parameter,
            "n_points": len(self),
            "status": int(self.status),
            "status_name": STATUS_NAMES.get(self.status, str(self.status)),
            "message": self.message,
            "metadata": self.metadata,
            "special_points": [
                {"kind": s.kind, "index": int(s.index), "p": float(s.p),
                 "precision": float(s.precision), "located": bool(s.located), "name": s.name,
                 "data": {k: v for k, v in s.data.items() if not isinstance(v, np.ndarray)}}
                for s in self.special_points
            ],
        })

    def save(self, path) -> Path:
        """Write ``path`` (.npz, JSON metadata inside) and a ``.json`` summary beside it.

        Returns the path of the .npz file.
        """
        path = Path(path).with_suffix(".npz")
        arrays = {
            "p": self.p, "ds": self.ds, "newton_iterations": self.newton_iterations,
            "stability": self.stability,
        }
        if self.u is not None:
            arrays["u"] = self.u
        if self.tangent is not None:
            arrays["tangent"] = self.tangent
        for k, v in self.observables.items():
            arrays[f"obs:{k}"] = v
        for i, s in enumerate(self.special_points):
            if s.u is not None:
                arrays[f"sp{i}:u"] = s.u
            for k, v in s.data.items():
                if isinstance(v, np.ndarray):
                    arrays[f"sp{i}:{k}"] = v
        summary = self.to_dict()
        arrays["metadata_json"] = np.array(json.dumps(summary, allow_nan=False))
        _replace_atomically(path, lambda f: np.savez(f, **arrays))
        text = json.dumps(summary, indent=2, allow_nan=False).encode()
        _replace_atomically(path.with_suffix(".json"), lambda f: f.write(text))
        return path

    @classmethod
    def load(cls, path) -> Branch:
        """Read a branch written by :meth:`save`; refuses incomplete files, naming the gaps."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        try:
            return cls._load(path)
        except (EOFError, OSError, zipfile.BadZipFile, KeyError, json.JSONDecodeError) as err:
            raise ValueError(f"Branch.load({str(path)!r}): not a readable branch file "
                             f"({type(err).__name__}: {err})") from None

    @classmethod
    def _load(cls, path: Path) -> Branch:
        # the file opened here: numpy leaves it open when it cannot read it
        with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as z:
            files = set(z.files)
            required = {"p", "ds", "newton_iterations", "stability", "metadata_json"}
            missing = sorted(required - files)
            if missing:
                raise ValueError(
                    f"Branch.load({str(path)!r}): missing arrays {missing}; this is not a "
                    "complete file written by Branch.save (or it was written by another tool)."
                )
            meta = json.loads(str(z["metadata_json"]))
            if meta.get("schema_version") != SCHEMA_VERSION:
                raise ValueError(
                    f"Branch.load({str(path)!r}): schema_version={meta.get('schema_version')!r}, "
                    f"this library reads {SCHEMA_VERSION}."
                )
            obs = {k[4:]: z[k] for k in z.files if k.startswith("obs:")}
            sps = []
            for i, d in enumerate(meta["special_points"]):
                data = dict(d["data"])
                for k in z.files:
                    if k.startswith(f"sp{i}:") and k != f"sp{i}:u":
                        data[k.split(":", 1)[1]] = z[k]
                sps.append(SpecialPoint(
                    kind=d["kind"], index=d["index"], p=d["p"],
                    u=z[f"sp{i}:u"] if f"sp{i}:u" in files else None,
                    precision=math.nan if d["precision"] is None else d["precision"],
                    located=d["located"], name=d["name"], data=data))
            if not np.all(np.isfinite(z["p"])):
                raise ValueError(f"Branch.load({str(path)!r}): the parameter values p hold "
                                 "NaN or inf; Branch.save never writes them")
            return cls(
                p=z["p"], u=z["u"] if "u" in files else None,
                tangent=z["tangent"] if "tangent" in files else None,
                ds=z["ds"], newton_iterations=z["newton_iterations"], stability=z["stability"],
                observables=obs, special_points=sps, status=meta["status"],
                message=meta["message"], parameter=meta["parameter"],
                metadata=meta["metadata"],
            )

    # ------------------------------------------------------------------ plotting
    def plot(self, ax=None, y=None, label=None, color=None, **kw):
        """Plot the branch: stable solid, unstable dashed, special points marked.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Created if None (matplotlib is imported only here).
        y : str, callable or None
            An observable name, a function ``(u, p) -> float`` of the states,
            or None for the first observable (else ``max|u|``).
        label, color : passed to matplotlib.

        Returns
        -------
        ax
        """
        try:
            import matplotlib.pyplot as plt
        except ImportError:
            raise ImportError("Branch.plot needs matplotlib (an optional dependency of "
                              "continuation): pip install matplotlib") from None

        if ax is None:
            _, ax = plt.subplots()
        yv = self._yvalues(y)
        st = self.stability
        unstable = st > 0
        color = color or f"C{len(ax.lines) % 10}"
        # Split into runs of equal stability; adjacent runs share an end point
        # so the curve has no gaps.
        start = 0
        first = True
        for i in range(1, len(self) + 1):
            if i == len(self) or unstable[i] != unstable[start]:
                sl = slice(start, min(i + 1, len(self)))
                ax.plot(self.p[sl], yv[sl], ls="--" if unstable[start] else "-", color=color,
                        label=label if first else None, **kw)
                first = False
                start = i
        markers = {"fold": "o", "branch_point": "s", "stability": "d", "event": "^",
                   "endpoint": "x"}
        for s in self.special_points:
            if s.kind == "endpoint":
                continue
            yi = self._y_at(y, s, yv)
            ax.plot([s.p], [yi], markers.get(s.kind, "*"), color=color, mfc="none", ms=7)
        ax.set_xlabel(self.parameter)
        ax.set_ylabel(y if isinstance(y, str) else (self._default_y() or "max|u|"))
        return ax

    def _default_y(self):
        return next(iter(self.observables), None)

    def _yvalues(self, y):
        if y is None:
            y = self._default_y()
        if isinstance(y, str):
            if y not in self.observables:
                raise ValueError(f"Branch.plot: y={y!r} is not an observable; available: "
                                 f"{sorted(self.observables)}")
            return np.asarray(self.observables[y])
        if self.u is None:
            raise ValueError("Branch.plot: the branch has no stored states (store_states="
                             "False); pass y as an observable name.")
        if y is None:
            return np.max(np.abs(self.u), axis=1)
        return np.array([y(ui, pi) for ui, pi in zip(self.u, self.p, strict=True)])

    def _y_at(self, y, s, yv):
        if callable(y) and s.u is not None:
            return y(s.u, s.p)
        if y is None and not self.observables and s.u is not None:
            return np.max(np.abs(s.u))
        name = y if isinstance(y, str) else self._default_y()
        if name is not None and name in s.data.get("observables", {}):
            return s.data["observables"][name]
        i = min(max(s.index, 0), len(yv) - 1)
        j = max(i - 1, 0)
        # Linear interpolation in p between the bracketing points.
        if self.p[i] != self.p[j]:
            w = (s.p - self.p[j]) / (self.p[i] - self.p[j])
            if 0 <= w <= 1:
                return yv[j] + w * (yv[i] - yv[j])
        return yv[i]


def _jsonable(v):
    """Plain JSON data: numpy scalars as Python numbers, NaN and +-inf as ``None`` (JSON
    has neither; a special point's ``precision`` ``None`` means not estimated)."""
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating | float):
        v = float(v)
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    return v
