"""Figs 4 and 5: time sequences of the strip (rigid, floppy and no encapsulation; a secondary
drop extending the footprint mid-run).

Parameters are placed relative to the model's Fig 3d diagram (docs/guide/fig3d.md), as the
paper did: A = rigid encapsulation near the end (x = 1, We^1/2 = 1.5, above that line's
threshold and below its first undecided runs, where the rod crosses itself), B = floppy
encapsulation further from the end and faster (x = 3, We^1/2 = 2.5), C = no encapsulation
at the same x with a slower impact (x = 3, We^1/2 = 1.5), D = x = 5 at We^1/2 = 2.0, D' =
the same run with S2 moved by 0.45 l_eg (equivalent to We^1/2 = 3.6) at t = 0.5 (~9 ms),
the paper's secondary drop. Each run's record carries the Fig 3d threshold at its x (from
``fig3d.json`` in the same folder, written first by ``elastocap figures``).

Same damping and final time as Fig 3d (a run still moving then is repeated to
``FIG45_T_MAX_LONG``), and the same resolutions: every run is computed at each level of the
diagram (:func:`~elastocap.paper_figures.fig3d.fig3d_resolutions`: the
sweep's edges and its verification levels), so that its outcome is shown to hold under
refinement as the diagram's thresholds are. The frames drawn are the finest level's (to
Fig 3d's t_max); the record gives the outcome at every level and the level from which it no
longer changes.
"""


from __future__ import annotations

import json
from pathlib import Path

from elastocap.criteria import UNDECIDED
from elastocap.frames import frame_strip
from elastocap.impact import run_impact
from elastocap.io import write_json
from elastocap.paper_figures import record
from elastocap.paper_figures.fig3d import FIG3D_DAMPING, FIG3D_T_MAX, fig3d_resolutions
from elastocap.scene import load_scene

#: Final time of the runs: Fig 3d's; a run still moving then is repeated to
#: ``FIG45_T_MAX_LONG`` (damping 0.1 gives a decay time of mu / damping = 10: 400 is 40 of
#: them; the slow sliding of a strip folded on itself can outlast 100).
FIG45_T_MAX = FIG3D_T_MAX
FIG45_T_MAX_LONG = 400.0

RUNS = {
    "fig4A": {"x": 1.0, "we_sqrt": 1.5},
    "fig4B": {"x": 3.0, "we_sqrt": 2.5},
    "fig4C": {"x": 3.0, "we_sqrt": 1.5},
    "fig5D": {"x": 5.0, "we_sqrt": 2.0},
    "fig5Dprime": {"x": 5.0, "we_sqrt": 2.0, "s2_shift": 0.45, "t_event": 0.5},
}


def run_scene(spec, fast, level=None, t_max=FIG45_T_MAX):
    """The scene of the run ``spec`` (an entry of :data:`RUNS`) at the Fig 3d resolution
    ``level`` (a :class:`~elastocap.sweep.Resolution`; None: the sweep's own, level 0), to
    ``t_max``."""
    base = load_scene("fig3-strip")
    delta = base.spreading.delta(spec["we_sqrt"])
    accuracy = "draft" if fast else "default"
    res = level if level is not None else fig3d_resolutions(accuracy, fast=fast)[0]
    over = {
        "drop.distance_from_end": spec["x"],
        "drop.wetted_length": delta,
        "effects.damping": FIG3D_DAMPING,
        "numerics.t_max": t_max,
        "numerics.accuracy": accuracy,
        **res.overrides(),  # the diagram's discretization
    }
    scene = base.with_overrides(over)
    if "s2_shift" in spec:
        data = json.loads(json.dumps(scene.data))
        data["drop"]["events"] = [{"time": spec["t_event"], "s2": scene.drop.s2 + spec["s2_shift"]}]
        from elastocap.scene import build_scene

        scene = build_scene(data, scene.name)
    return scene


def settled_from(outcomes: list[str]) -> int | None:
    """The first level from which ``outcomes`` (one per level, coarse to fine) no longer
    change, if a refined run confirms it (at least the two finest agree and are decided);
    else None."""
    k = len(outcomes) - 1
    while k > 0 and outcomes[k - 1] == outcomes[-1]:
        k -= 1
    if k == len(outcomes) - 1 or outcomes[-1] == UNDECIDED:
        return None
    return k


def _threshold_at(out: Path, x: float) -> dict | None:
    """The Fig 3d line x's threshold from ``out/fig3d.json`` (written just before this figure
    by ``elastocap figures``), with its verification status; None without that file."""
    path = out / "fig3d.json"
    if not path.is_file():
        return None
    for b in json.loads(path.read_text()).get("boundary", []):
        if abs(b["x"] - x) < 1e-9:
            v = b.get("verification") or {}
            return {"low": b.get("threshold_low"), "high": b.get("threshold_high"),
                    "to": b.get("threshold_to"), "n_edges": b.get("n_edges"),
                    "verification": v.get("status"), "line_status": b.get("status")}
    return None


def _level_row(res, scene, level, t_max) -> dict:
    from elastocap.criteria import companion_outcome, companion_reading

    comp = companion_outcome(res.simulation.positions[-1], scene)
    # as in a sweep (criteria.companion_reading); what it would read is kept
    return {"level": level.level, "n_edges": level.n_edges, "dt": level.dt, "t_max": t_max,
            "outcome": res.outcome,
            "companion_outcome": companion_reading(res.outcome, comp.outcome),
            "companion_would_read": comp.outcome,
            "reason": res.undecided_reason, "final_measure": res.final_measure,
            "status": res.status, "at_rest": res.at_rest, "t_end": res.t_end,
            "steps": res.steps, "rod_crossing_time": res.rod_crossing_time,
            "run_time_s": res.run_time_s}


def _level_runs(spec, fast, level):
    """The run at one level to Fig 3d's t_max, and again to ``FIG45_T_MAX_LONG`` if it was
    still moving then: (the first run's result and scene, the rows; the last row decides)."""
    rows, first = [], None
    for t_max in (FIG45_T_MAX, FIG45_T_MAX_LONG):
        scene = run_scene(spec, fast, level, t_max)
        res = run_impact(scene)
        first = first or (res, scene)
        rows.append(_level_row(res, scene, level, t_max))
        if res.at_rest:
            break
    return first, rows


def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes one frame strip per run (its finest level) and ``fig4_fig5.json`` (outcomes
    under both criteria at every level)."""
    out = Path(out_dir)
    files, summary = [], {}
    names = ["fig4B"] if fast else list(RUNS)
    levels = fig3d_resolutions("draft" if fast else "default", fast=fast)
    for name in names:
        spec = RUNS[name]
        rows, repeated = [], []
        for level in levels:
            (res, scene), runs = _level_runs(spec, fast, level)
            rows.append(runs[-1])
            repeated += runs[:-1]
        fine = rows[-1]
        held = settled_from([r["outcome"] for r in rows])
        held_comp = settled_from([r["companion_outcome"] for r in rows])
        png = out / f"{name}.png"
        event = (rf", $S_2 \to S_2 + {spec['s2_shift']}\,\ell_{{eg}}$ at $t$ = {spec['t_event']}"
                 if "s2_shift" in spec else "")
        verdict = fine["outcome"] + (f" from {rows[held]['n_edges']} edges on" if held is not None
                                     else ", not confirmed by refinement")
        if fine["t_max"] != FIG45_T_MAX:
            verdict += f" (at rest at t = {fine['t_end']:.0f})"
        frame_strip(res, scene, png, k=8,
                    title=rf"{name}: $x = {spec['x']:g}\,\ell_{{eg}}$, "
                    rf"$\mathrm{{We}}^{{1/2}}$ = {spec['we_sqrt']:g}{event}, "
                    f"{fine['n_edges']} edges: {verdict}")
        files.append(png)
        summary[name] = {**spec, **{k: fine[k] for k in (
                             "outcome", "companion_outcome", "reason", "final_measure",
                             "status", "t_end", "t_max", "n_edges")},
                         "settled_from_edges": None if held is None else rows[held]["n_edges"],
                         "companion_settled_from_edges":
                             None if held_comp is None else rows[held_comp]["n_edges"],
                         "levels": rows, "still_moving_at_fig3d_t_max": repeated,
                         "fig3d_threshold": _threshold_at(out, spec["x"])}
    js = out / "fig4_fig5.json"
    write_json(js, record(summary, scene, fast=fast,
                          resolutions=[lv.to_dict() for lv in levels]), indent=1)
    return [*files, js]
