"""Figs 4 and 5: time sequences of the strip (rigid, floppy and no encapsulation; a secondary
drop extending the footprint mid-run).

Parameters are placed relative to the model's Fig 3d diagram (docs/guide/fig3d.md), as the
paper did: A = rigid encapsulation near the end (x = 1, We^1/2 = 1.5, above that line's
threshold 1.00-1.03 and below its first undecided runs, where the rod crosses itself: at
We^1/2 = 2.0 it does, and the run is undecided), B = floppy encapsulation further from the
end and faster (x = 3, We^1/2 = 2.5), C = no encapsulation at the same x with a slower
impact (x = 3, We^1/2 = 1.5, below the threshold 1.56-1.59); D = x = 5 at We^1/2 = 2.0
(below that line's threshold 2.25-2.28, into undecided runs), D' = the same run with S2
moved by 0.45 l_eg (equivalent to We^1/2 = 3.6) at t = 0.5 (~9 ms), the paper's secondary
drop. Each run's record carries the Fig 3d threshold at its x (from ``fig3d.json`` in the
same folder, written first by ``elastocap figures``).
Same damping, final time and resolution as Fig 3d (:func:`fig3d_resolution`: the edges
every run of the diagram uses), so that the runs sit against that diagram's boundary.
"""

from __future__ import annotations

import json
from pathlib import Path

from elastocap.frames import frame_strip
from elastocap.impact import run_impact
from elastocap.io import write_json
from elastocap.paper_figures import record
from elastocap.paper_figures.fig3d import FIG3D_DAMPING, FIG3D_T_MAX, fig3d_resolution
from elastocap.scene import load_scene

RUNS = {
    "fig4A": {"x": 1.0, "we_sqrt": 1.5},
    "fig4B": {"x": 3.0, "we_sqrt": 2.5},
    "fig4C": {"x": 3.0, "we_sqrt": 1.5},
    "fig5D": {"x": 5.0, "we_sqrt": 2.0},
    "fig5Dprime": {"x": 5.0, "we_sqrt": 2.0, "s2_shift": 0.45, "t_event": 0.5},
}


def _scene(spec, fast):
    base = load_scene("fig3-strip")
    delta = base.spreading.delta(spec["we_sqrt"])
    accuracy = "draft" if fast else "default"
    res = fig3d_resolution(accuracy, fast=fast)
    over = {
        "drop.distance_from_end": spec["x"],
        "drop.wetted_length": delta,
        "effects.damping": FIG3D_DAMPING,
        "numerics.t_max": FIG3D_T_MAX,  # as Fig 3d: runs end at rest
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


def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes one frame strip per run and ``fig4_fig5.json`` (outcomes, both criteria)."""
    out = Path(out_dir)
    files, summary = [], {}
    names = ["fig4B"] if fast else list(RUNS)
    for name in names:
        spec = RUNS[name]
        scene = _scene(spec, fast)
        res = run_impact(scene)
        png = out / f"{name}.png"
        event = (rf", $S_2 \to S_2 + {spec['s2_shift']}\,\ell_{{eg}}$ at $t$ = {spec['t_event']}"
                 if "s2_shift" in spec else "")
        frame_strip(res, scene, png, k=8,
                    title=rf"{name}: $x = {spec['x']:g}\,\ell_{{eg}}$, "
                    rf"$\mathrm{{We}}^{{1/2}}$ = {spec['we_sqrt']:g}{event}: {res.outcome}")
        files.append(png)
        from elastocap.criteria import companion_outcome

        comp = companion_outcome(res.simulation.positions[-1], scene)
        summary[name] = {**spec, "outcome": res.outcome, "companion_outcome": comp.outcome,
                         "reason": res.undecided_reason,
                         "final_measure": res.final_measure, "status": res.status,
                         "t_end": res.t_end, "n_edges": res.settings.get("n_edges"),
                         "fig3d_threshold": _threshold_at(out, spec["x"])}
    js = out / "fig4_fig5.json"
    write_json(js, record(summary, scene, fast=fast), indent=1)
    return [*files, js]
