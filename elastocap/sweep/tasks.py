"""The work a sweep sends to its workers: one impact, returned as plain data.

A run function takes ``(scene_name, scene_json)`` -- the resolved scene as canonical JSON,
which is all that defines the run -- and returns a dict with the result columns of the
store (:data:`RESULT_KEYS`). It must be importable by the workers (a module-level
function). Its ``runner`` attribute names it in the store's key; tests inject cheap ones.
"""

from __future__ import annotations

import json

__all__ = ["RESULT_KEYS", "run_impact_task", "runner_name"]

#: What a run function returns (the store's per-run result columns).
RESULT_KEYS = (
    "outcome",
    "companion_outcome",
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
    "final_positions",
    "settings_json",
)


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
        units, ``outcome`` the paper's lab-frame criterion, ``companion_outcome``
        :func:`elastocap.criteria.companion_outcome`.
    """
    # imported here: the sweep orchestrator never needs numba, and a worker imports it only
    # after its initializer has set NUMBA_NUM_THREADS
    from elastocap.criteria import companion_outcome
    from elastocap.impact import run_impact
    from elastocap.scene import build_scene

    scene = build_scene(json.loads(scene_json), scene_name)
    res = run_impact(scene)
    final = res.simulation.positions[-1]
    comp = companion_outcome(final, scene)
    return {
        "outcome": res.outcome,
        "companion_outcome": comp.outcome,
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
        "final_positions": final.copy(),
        "settings_json": json.dumps(res.settings, sort_keys=True),
    }


run_impact_task.runner = "impact"
