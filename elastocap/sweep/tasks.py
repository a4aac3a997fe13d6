"""The work a sweep sends to its workers: one impact, returned as plain data.

A run function takes ``(scene_name, scene_json)`` -- the resolved scene as canonical JSON,
which is all that defines the run -- and returns a dict with the result columns of the
store (:data:`RESULT_KEYS`). It must be importable by the workers (a module-level
function). Its ``runner`` attribute names it in the store's key; tests inject cheap ones.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import json
from pathlib import Path

__all__ = [
    "RESULT_KEYS",
    "code_files",
    "code_fingerprint",
    "loaded_code_fingerprint",
    "run_impact_task",
    "runner_name",
]

#: What a run function returns (the store's per-run result columns).
RESULT_KEYS = (
    "outcome",
    "reason",
    "companion_outcome",
    "n_edges",
    "dt",
    "final_measure",
    "companion_measure",
    "t_end",
    "steps",
    "wall_time_s",
    "status",
    "message",
    "rod_crossing_time",
    "interface_crossing_time",
    "decided_after_crossing",
    "contact_steps",
    "contact_max_active",
    "contact_gap_error",
    "final_positions",
    "settings_json",
    "version",
    "code_digest",
)


#: Modules whose code decides an impact's result; the fingerprint covers them and
#: everything they import from ``elastocap`` and ``dynamics``, transitively.
CODE_ROOTS = ("elastocap.impact", "elastocap.criteria", "elastocap.scene")
_PACKAGES = ("elastocap", "dynamics")


def _module_file(name: str) -> Path | None:
    """The source file of module ``name`` of our packages, found without importing."""
    top, *rest = name.split(".")
    spec = importlib.util.find_spec(top)  # a top-level find imports nothing
    if spec is None or not spec.submodule_search_locations:
        return None
    base = Path(next(iter(spec.submodule_search_locations))).joinpath(*rest)
    for cand in (base / "__init__.py", base.with_suffix(".py")):
        if cand.is_file():
            return cand
    return None


def _imported_modules(path: Path, name: str) -> set[str]:
    """Modules of our packages imported anywhere in a file (function-level imports too)."""
    tree = ast.parse(path.read_text())
    pkg = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = pkg.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            # "from pkg import name": name may be a submodule or an attribute
            mods = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        out |= {m for m in mods if m.split(".")[0] in _PACKAGES}
    return out


def code_files(roots=CODE_ROOTS) -> dict[str, Path]:
    """Module name -> source file: the ``roots`` modules and every module of ``elastocap`` /
    ``dynamics`` they import, transitively (found by reading the imports, not by importing),
    with their packages' ``__init__``."""
    files: dict[str, Path] = {}
    todo = list(roots)
    while todo:
        name = todo.pop()
        if name in files:
            continue
        path = _module_file(name)
        if path is None:
            continue  # an attribute imported with "from pkg import name", not a module
        files[name] = path
        parts = name.split(".")
        todo += [".".join(parts[:k]) for k in range(1, len(parts))]  # parent packages
        todo += sorted(_imported_modules(path, name))
    return files


def code_fingerprint(roots=CODE_ROOTS) -> str:
    """SHA-256 (16 hex digits) of the sources, as they are on disk now, of
    :func:`code_files`: the code an impact runs. Edits elsewhere (the sweep machinery, the
    command line, figures, other subpackages) leave it unchanged."""
    files = code_files(roots)
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode() + b"\0" + files[name].read_bytes() + b"\0")
    return h.hexdigest()[:16]


@functools.cache
def loaded_code_fingerprint() -> str:
    """:func:`code_fingerprint` once per process, at its first run: the code a (long-lived)
    worker has loaded, which a later edit on disk does not change."""
    return code_fingerprint()


def runner_name(run_fn) -> str:
    """The name under which ``run_fn``'s results are stored."""
    return getattr(run_fn, "runner", None) or f"{run_fn.__module__}.{run_fn.__qualname__}"


def run_impact_task(scene_name: str, scene_json: str) -> dict:
    """One impact (:func:`elastocap.impact.run_impact`) and both criteria, as plain data.

    Parameters
    ----------
    scene_name : str
    scene_json : str
        ``Scene.to_json()`` of the run's scene.

    Returns
    -------
    dict
        :data:`RESULT_KEYS`; ``final_positions`` is the final shape (n + 1, 2) in scene
        units, ``outcome`` the paper's lab-frame criterion ("open", "encapsulated" or
        "undecided", the last with its ``reason``), ``n_edges`` and ``dt`` the
        discretization the run used, ``companion_outcome``
        :func:`elastocap.criteria.companion_outcome` (undecided where ``outcome`` is),
        ``version`` and ``code_digest`` the
        worker's (checked against the sweep's: a cluster must run the same code).
    """
    # imported here: the sweep orchestrator never needs numba, and a worker imports it only
    # after its initializer has set NUMBA_NUM_THREADS
    from elastocap._version import __version__
    from elastocap.criteria import companion_outcome, companion_reading
    from elastocap.impact import run_impact
    from elastocap.scene import build_scene

    scene = build_scene(json.loads(scene_json), scene_name)
    try:
        res = run_impact(scene)
    except Exception as err:
        # re-raised as a plain RuntimeError naming the type: the store records every failure
        # the same way, and an exception from elsewhere that does not unpickle cannot make
        # the pool read it as a dead worker (the toolkit's own errors all pickle)
        raise RuntimeError(f"{type(err).__name__}: {err}") from None
    if res.outcome == "failed":  # a numerical failure: the sweep records it with the reason
        raise RuntimeError(f"impact failed: {res.message}")
    final = res.simulation.positions[-1]
    comp = companion_outcome(final, scene)
    settings = dict(res.settings)
    return {
        "outcome": res.outcome,
        # an undecided run says why (None for a decided one)
        "reason": res.undecided_reason,
        # undecided where the run is (its measure is kept)
        "companion_outcome": companion_reading(res.outcome, comp.outcome),
        "n_edges": settings.get("n_edges"),
        "dt": settings.get("dt"),
        "final_measure": res.final_measure,
        "companion_measure": comp.measure,
        "t_end": res.t_end,
        "steps": res.steps,
        "wall_time_s": res.wall_time_s,
        "status": res.status,
        "message": res.message,
        "rod_crossing_time": res.rod_crossing_time,
        "interface_crossing_time": res.interface_crossing_time,
        "decided_after_crossing": res.decided_after_crossing,
        # None without a thickness (ImpactResult.self_contact is then empty)
        "contact_steps": res.self_contact.get("steps"),
        "contact_max_active": res.self_contact.get("max_active"),
        "contact_gap_error": res.self_contact.get("gap_error"),
        "final_positions": final.copy(),
        "settings_json": json.dumps(settings, sort_keys=True, default=str),
        "version": __version__,
        "code_digest": loaded_code_fingerprint(),
    }


run_impact_task.runner = "impact"
#: The run function's code identity, stored in the key (a callable: the sweep evaluates it
#: when it starts, on the sources as they are then).
run_impact_task.code_digest = code_fingerprint
