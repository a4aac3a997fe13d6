"""Every branch of a scene in one parameter: the one result type of the statics.

:class:`BranchSet` is what ``elastocap branches`` and ``elastocap folds`` compute for both
models of the toolkit, the free rod (:func:`elastocap.statics.branches.trace_branches`)
and the strip on the ground (:func:`elastocap.strip.trace.trace_contact_branches`): plain
data (a scene, a parameter range, a list of :class:`continuation.Branch` with their
observables and special points, the special points by kind, metadata) with one
``summary``, ``save``, ``load``, ``plot`` and ``report``. What differs between the models
is named by ``metadata["model"]`` and supplied by that model's :class:`BranchModel`: how to
rebuild the discretized problem from the saved metadata, the diagram and the report lines.
Model-specific results that are not special points (the strip's window of bistability,
its contact events and kind changes) are plain data under ``results``.

Files (:meth:`BranchSet.save`): ``branch_K.npz`` (+ ``branch_K.json``) per branch,
written by :meth:`continuation.Branch.save`, and ``branches.json`` (the summary, the
model-specific results, ``format``). JSON numbers are numbers or ``null`` (a value that
was not computed or is not finite), never strings. :meth:`BranchSet.load` reads them back
without recomputing anything, so ``elastocap plot DIR`` redraws either model.
"""

from __future__ import annotations

import importlib
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from continuation import Branch
from elastocap.jsonutil import is_finite_number, jsonable
from elastocap.scene import Scene

__all__ = ["BranchModel", "BranchSet", "finite_or_none"]


@dataclass(frozen=True)
class BranchModel:
    """What one model adds to a :class:`BranchSet`.

    Attributes
    ----------
    name : str
        The value of ``metadata["model"]``.
    problem : callable ``(scene, metadata) -> problem``
        Rebuilds the discretized problem of a loaded branch set from its metadata.
    plot : callable ``(bs, path) -> matplotlib Figure``
        The branch diagram.
    report_lines : callable ``(bs) -> list of str``
        The human-readable report (the CLI without ``--json``).
    """

    name: str
    problem: Callable
    plot: Callable
    report_lines: Callable


#: Where each model's :class:`BranchModel` lives (module, attribute); imported on use.
MODELS = {"free_rod": ("elastocap.statics.branches", "FREE_ROD"),
          "strip": ("elastocap.strip.trace", "STRIP")}
# The format an earlier free-rod-only release wrote; read as the free rod.
_FREE_ROD_FORMAT = "elastocap.statics.BranchSet/1"


def model(name: str) -> BranchModel:
    """The :class:`BranchModel` called ``name`` (a key of :data:`MODELS`)."""
    if name not in MODELS:
        raise ValueError(f"model: got {name!r}; expected one of {', '.join(MODELS)}")
    mod, attr = MODELS[name]
    return getattr(importlib.import_module(mod), attr)


def finite_or_none(obj):
    """:func:`elastocap.jsonutil.jsonable` of ``obj`` with every non-finite number (and the
    strings ``"nan"``, ``"inf"``, ``"-inf"`` standing for one) replaced by None."""
    return _null_nonfinite(jsonable(obj))


def _null_nonfinite(v):
    if isinstance(v, dict):
        return {k: _null_nonfinite(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_null_nonfinite(x) for x in v]
    if (isinstance(v, float) and not math.isfinite(v)) or v in ("nan", "inf", "-inf"):
        return None
    return v


@dataclass
class BranchSet:
    """All branches of a scene in one parameter, with their special points.

    Attributes
    ----------
    scene : Scene
    parameter : str
        The continued scene key (e.g. ``drop.wetted_length``).
    prange : (float, float)
        The searched range of the parameter.
    problem : object
        The discretized problem the branches solve (rebuilt by :meth:`load`).
    branches : list of continuation.Branch
        States, observables (``observables``), stability index (``stability``: 0 =
        stable) and special points of each branch.
    labels : list of str
        One per branch: how it was found.
    folds : list of dict
        Every located fold: ``value``, ``measure``, ``energy``, ``stability_change``,
        ``error_estimate`` (a number, or None when not estimated), ``branch``, and what
        the model adds (the strip: ``kind`` smooth or contact, ``node``, ``event``).
    unlocated : list of dict
        Special points that could not be located or confirmed (``kind``, ``value``,
        ``reason``, ``what_to_try``); never reported as folds.
    branch_points, maxwell_points, admissibility_changes, endpoints : list of dict
    results : dict
        Model-specific plain data (the strip: ``window``, ``kind_changes``, ``events``,
        ``open_branch_end``).
    metadata : dict
        ``model`` (a key of :data:`MODELS`), the scene's resolved data, resolution,
        tolerances, version and timing.
    """

    scene: Scene
    parameter: str
    prange: tuple
    problem: object = None
    branches: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    folds: list = field(default_factory=list)
    branch_points: list = field(default_factory=list)
    maxwell_points: list = field(default_factory=list)
    admissibility_changes: list = field(default_factory=list)
    endpoints: list = field(default_factory=list)
    metadata: dict = field(default_factory=dict)
    unlocated: list = field(default_factory=list)
    results: dict = field(default_factory=dict)

    #: ``format`` of the ``branches.json`` that :meth:`save` writes and :meth:`load` reads.
    FORMAT = "elastocap.BranchSet/1"
    #: The lists of special points, by kind (saved and loaded as they are).
    SPECIAL = ("folds", "branch_points", "maxwell_points", "admissibility_changes",
               "endpoints", "unlocated")

    @property
    def model(self) -> BranchModel:
        """This set's :class:`BranchModel` (from ``metadata["model"]``, default the free
        rod)."""
        return model(self.metadata.get("model", "free_rod"))

    def summary(self) -> dict:
        """Plain data for ``--json``: special points by kind, the model's results and one
        line per branch; non-finite numbers are None."""
        lines = []
        for br, lab in zip(self.branches, self.labels, strict=True):
            line = {
                "label": lab,
                "points": len(br),
                "range": [float(br.p.min()), float(br.p.max())] if len(br) else None,
                "stable_points": int(np.sum(br.stability == 0)),
                "status": br.status,
                "message": br.message,
            }
            if "end_status" in br.metadata:
                line["end_status"] = br.metadata["end_status"]
            lines.append(line)
        out = {"scene": self.scene.name, "parameter": self.parameter,
               "range": list(self.prange),
               **{key: getattr(self, key) for key in self.SPECIAL},
               **self.results, "branches": lines, "metadata": self.metadata}
        return finite_or_none(out)

    def save(self, out_dir) -> list:
        """Write ``branch_K.npz`` (+ ``branch_K.json``) per branch and ``branches.json``.

        ``out_dir`` is a folder path or an :class:`elastocap.io.OutputFolder`. Every file is
        written atomically; the folder's earlier branch files are removed first (only those
        an earlier save listed), so no stale ``branch_K`` survives a run with fewer branches.
        The branches record their parameter by its scene key. Returns the paths written.
        """
        from elastocap.io import OutputFolder

        folder = out_dir if isinstance(out_dir, OutputFolder) else OutputFolder(
            out_dir, "branches", key="out_dir")
        files = []
        with folder.staged() as stage:
            for k, br in enumerate(self.branches):
                meta = {**br.metadata, "label": self.labels[k], "scene": self.scene.data,
                        "statics": self.metadata}
                replace(br, parameter=self.parameter,
                        metadata=finite_or_none(meta)).save(
                    stage / f"branch_{k}.npz")
                files.append(f"branch_{k}.npz")
            summary = self.summary()
            summary["format"] = self.FORMAT
            summary["metadata"] = {**summary["metadata"], "scene": jsonable(self.scene.data),
                                   "scene_name": self.scene.name}
            for line, name in zip(summary["branches"], files, strict=True):
                line["file"] = name
            (stage / "branches.json").write_text(
                json.dumps(summary, indent=2, allow_nan=False), encoding="utf-8")
        # Branch.save writes a JSON summary beside each .npz
        sidecars = [f.removesuffix(".npz") + ".json" for f in files]
        return [folder.final(stage / f) for f in files + sidecars + ["branches.json"]]

    @classmethod
    def load(cls, folder) -> BranchSet:
        """Read a branch set written by :meth:`save` (no recomputation: the scene, the
        discretization and every branch and special point come from the files).

        Raises ValueError naming the file when the folder is not a complete branch set
        (e.g. a missing ``branch_K.npz``).
        """
        from elastocap.scene import build_scene

        root = Path(folder)
        js = root / "branches.json" if root.is_dir() else root
        root = js.parent
        try:
            data = json.loads(js.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ValueError(f"{str(js)!r}: no such file (a branches folder has "
                             "branches.json)") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise ValueError(f"{str(js)!r}: not a readable branches.json ({err})") from None
        fmt = data.get("format") if isinstance(data, dict) else None
        if fmt not in (cls.FORMAT, _FREE_ROD_FORMAT):
            raise ValueError(f"{str(js)!r}: not a branch set; BranchSet.load reads the "
                             f"branches.json that BranchSet.save writes (format "
                             f"{cls.FORMAT!r})")
        meta = data["metadata"]
        name = meta.get("model", "free_rod")
        if name not in MODELS:
            raise ValueError(f"{str(js)!r}: metadata.model is {name!r}; this version reads "
                             f"{', '.join(MODELS)}")
        scene = build_scene(meta["scene"], meta["scene_name"])
        bs = cls(scene, meta["parameter"], tuple(meta["range"]),
                 model(name).problem(scene, meta))
        for line in data["branches"]:
            path = root / line["file"]
            if not path.is_file():
                raise ValueError(f"{str(path)!r}: missing (listed in {str(js)!r})")
            bs.branches.append(Branch.load(path))
            bs.labels.append(line["label"])
        for key in cls.SPECIAL:
            items = data.get(key, [])
            for k, item in enumerate(items):
                v = item.get("value") if isinstance(item, dict) else None
                if v is not None and not is_finite_number(v):
                    raise ValueError(f"{str(js)!r}: {key}[{k}].value = {v!r}; BranchSet.save "
                                     "writes finite values only")
            setattr(bs, key, items)
        known = {"scene", "parameter", "range", "branches", "metadata", "format",
                 *cls.SPECIAL}
        bs.results = {k: v for k, v in data.items() if k not in known}
        bs.metadata = meta
        return bs

    def plot(self, path=None):
        """The model's branch diagram; saved to ``path`` if given. Returns the figure."""
        return self.model.plot(self, path)

    def report_lines(self) -> list[str]:
        """The model's human-readable report, one line per item."""
        return self.model.report_lines(self)

    def report(self) -> str:
        """:meth:`report_lines` as one string."""
        return "\n".join(self.report_lines())
