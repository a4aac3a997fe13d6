"""What rod self-contact changes: supplementary Fig 5's selection threshold, outcomes and
final shapes, and the runs of Figs 4 and 5, each with and without a thickness.

The paper's rod has no thickness and passes through itself (supp-fig5 at Delta >= 3.8, the
D' run of Fig 5). This figure runs the same impacts with ``rod.thickness`` set to the
paper's strip thickness h = 55 um in each scene's length unit, and under both interface
policies (``drop.interface_contact``):

* **Delta*** of supp-fig5 (the smallest wetted length whose impact ends encapsulated) by
  the sweep's bisection (:func:`elastocap.sweep.run_sweep` on the line x = L/2, Delta in
  [3.50, 3.55], bracket < ``DSTAR_TOL``), one sweep per configuration and resolution, at
  the resolutions of ``DSTAR_PLAN`` (RATTLE, the automatic dt: 0.9 of the bending bound, so dt ~ h^2
  and the error is second order in h).
* **Outcomes and final shapes** of supp-fig5 at ``OUTCOME_DELTAS`` and 100 / 200 edges:
  outcome, final measure M, rest, the first self-crossing (the crossing detector), the
  closest approach of a node to a segment at rest and over the run, contact-line jumps.
* **Figs 4 and 5**: the runs of :mod:`elastocap.paper_figures.fig4_fig5` (fig3-strip,
  damping 0.1, Fig 3d's t_max) at the Fig 3d resolution and at 200 edges.

Every run is kept: the threshold runs in the sweep stores
``contact-comparison-CONFIG-nN.sqlite`` (one store holds one scene), the others in
``contact-comparison-runs.jsonl`` (keyed by the scene digest and the code fingerprint of
:mod:`elastocap.sweep.tasks`), so a second call recomputes nothing. Writes
``contact-comparison.json``, ``contact-supp-fig5.png``, ``contact-fig4-fig5.png`` and
``contact-fig5Dprime.png``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from elastocap.io import atomic_path, write_json
from elastocap.paper_figures import record
from elastocap.paper_figures.fig4_fig5 import FIG45_T_MAX, FIG45_T_MAX_LONG
from elastocap.scene import MAX_THICKNESS_OVER_LENGTH, build_scene, load_scene

#: The experiments' strip thickness h = 55 um (paper, main text and Methods) in each
#: scene's length unit: l_ec = 0.55 mm for supp-fig5 (h / l_ec = 0.1), l_eg = 3.5 mm for
#: fig3-strip (h / l_eg = 0.0157). The centre lines of two touching layers are h apart.
THICKNESS = {"supp-fig5": 0.1, "fig3-strip": 0.0157}
#: The second thickness of the sensitivity study (half the experiments').
THICKNESS_HALF = 0.05

#: The largest thickness supp-fig5 accepts below L / 10 (``rod.thickness <= L / 10``):
#: whether any admissible thickness moves the threshold.
THICKNESS_MAX = 0.45
#: Configurations of supp-fig5: name -> scene overrides.
CONFIGS = {
    "no-contact": {},
    "d0.1-ignore": {"rod.thickness": THICKNESS["supp-fig5"]},
    "d0.1-wet": {"rod.thickness": THICKNESS["supp-fig5"], "drop.interface_contact": "wet"},
    "d0.05-ignore": {"rod.thickness": THICKNESS_HALF},
}
#: The threshold's configurations: these and the largest admissible thickness.
DSTAR_CONFIGS = {**CONFIGS, "d0.45-ignore": {"rod.thickness": THICKNESS_MAX}}
#: Threshold configurations per resolution (edges). A RATTLE run at 2N costs 8x one at N
#: (4x the steps, each twice the work): at 400 edges about 28 s per impact (2 shared
#: cores), 7-10 min per bisection.
DSTAR_PLAN = {n: tuple(DSTAR_CONFIGS) for n in (100, 200, 400)}
#: The bisection's start (the bracket of the paper-model threshold at every resolution,
#: README: 3.527 at 100 edges) and the bracket width it stops below: 0.05 / 2^12 = 1.2e-5,
#: 15x smaller than the change of Delta* from 200 to 400 edges.
DSTAR_GRID = (3.50, 3.55)
DSTAR_TOL = 2e-5
#: supp-fig5 is centred: x = L / 2 from the free end.
SUPP_X = 2.3

OUTCOME_DELTAS = (3.0, 3.5, 3.8, 4.0, 4.5)
OUTCOME_EDGES = (100, 200)
#: Figs 4-5 resolutions besides the Fig 3d one (133 edges).
STRIP_EDGES_FINE = 200
#: A third resolution for D' with contact (see :func:`main`).
DPRIME_CHECK_EDGES = 300
#: Arc length (scene units) beyond which two points of the rod count as different arms:
#: the closest approach of such pairs is the gap between the arms (about the drop's radius,
#: sqrt(A / pi) = 0.69 on supp-fig5, so that points around one wrap are not counted).
ARM_ARC = 1.0
#: Gap tolerance at rest, relative to the thickness: the position stage ends with gaps at
#: 1e-13 h_min; 1e-9 d leaves room for round-off in the brute-force distance.
GAP_RTOL = 1e-9

RUNS_FILE = "contact-comparison-runs.jsonl"


def _code_digest() -> str:
    from elastocap.sweep.tasks import code_fingerprint

    return code_fingerprint()


def closest_approach(x: np.ndarray, thickness: float, length: float) -> float:
    """Smallest distance from a node to a segment of the rod ``x`` (n + 1, 2) among the
    pairs the self-contact constrains for ``thickness`` (more than pi d / 2 apart along the
    rod; :func:`dynamics.contact.segment_distances`, brute force). Scene units."""
    from dynamics.contact import segment_distances

    n = x.shape[0] - 1
    return float(segment_distances(np.ascontiguousarray(x, dtype=np.float64), thickness,
                                   np.full(n, length / n))[0])


def tangent_angles(x: np.ndarray) -> np.ndarray:
    """Tangent angle of each edge (n,), unwrapped, rotation removed (mean subtracted)."""
    e = np.diff(np.asarray(x, float), axis=0)
    th = np.unwrap(np.arctan2(e[:, 1], e[:, 0]))
    return th - th.mean()


def shape_difference(xa: np.ndarray, xb: np.ndarray) -> float:
    """RMS difference (rad) of the tangent-angle profiles of two rods of the same length,
    any number of edges (``xb``'s profile interpolated at ``xa``'s edge midpoints),
    rotation removed, minimised over the rod's symmetries (reversal of s, reflection)."""
    na, nb = len(xa) - 1, len(xb) - 1
    sa, sb = (np.arange(na) + 0.5) / na, (np.arange(nb) + 0.5) / nb
    ta, tb = tangent_angles(xa), tangent_angles(xb)
    best = math.inf
    for rev in (False, True):
        t = np.interp(sa, sb, tb[::-1] if rev else tb)
        for sign in (1.0, -1.0):
            u = sign * t
            best = min(best, float(np.sqrt(np.mean((ta - (u - u.mean())) ** 2))))
    return best


def _final_caps(scene, sim) -> tuple[float, float]:
    """The wet interval (S1, S2) at the end of a run: the scene's, moved by every event."""
    s = {1: scene.drop.s1, 2: scene.drop.s2}
    for _t, _name, j, val in sim.events_fired:
        if j in s:
            s[j] = float(val)
    return s[1], s[2]


def run_record(scene) -> dict:
    """One impact (:func:`elastocap.impact.run_impact`) as plain data: outcome, measure, rest,
    crossings, contact statistics, closest approaches, the final shape and wet interval."""
    from elastocap.impact import run_impact

    res = run_impact(scene)
    sim = res.simulation
    L, d = scene.rod.length, scene.rod.thickness
    # without a thickness, distances among the pairs the experiments' thickness constrains
    d_ref = d or THICKNESS.get(scene.name, THICKNESS["supp-fig5"])
    touches = res.interface_touches or []
    s1, s2 = _final_caps(scene, sim)
    return {
        "outcome": res.outcome, "reason": res.undecided_reason, "status": res.status,
        "final_measure": res.final_measure, "at_rest": res.at_rest, "t_end": res.t_end,
        "decision_time": res.decision_time, "energy_rise": res.energy_rise,
        "rod_crossing_time": res.rod_crossing_time,
        "interface_crossing_time": res.interface_crossing_time,
        "interface_touches": len(touches),
        "first_touch": touches[0] if touches else None,
        "wet_jumps": sum(t.get("action") == "wetted" for t in touches),
        "thickness": d, "gap_reference_thickness": d_ref,
        "gap_at_rest": closest_approach(sim.positions[-1], d_ref, L),
        "gap_min_frames": min(closest_approach(p, d_ref, L) for p in sim.positions),
        # pairs more than ARM_ARC apart along the rod (the thickness whose exclusion arc
        # pi d / 2 is ARM_ARC)
        "arm_gap_at_rest": closest_approach(sim.positions[-1], 2.0 * ARM_ARC / math.pi, L),
        "arm_gap_min": min(closest_approach(p, 2.0 * ARM_ARC / math.pi, L)
                           for p in sim.positions),
        # among the pairs the largest admissible thickness (L / 10) would constrain: a run
        # in which this stays above L / 10 is the same run with any admissible thickness
        "gap_min_frames_max_thickness": min(closest_approach(p, MAX_THICKNESS_OVER_LENGTH * L, L)
                                            for p in sim.positions),
        "self_contact_steps": res.self_contact.get("steps", 0),
        "self_contact_gap_error": res.self_contact.get("gap_error"),
        "n_edges": res.settings.get("n_edges"), "dt": res.settings.get("dt"),
        "dt_retries": res.settings.get("dt_retries"),
        "steps": res.steps, "run_time_s": res.run_time_s,
        "final_s1": s1, "final_s2": s2,
        "final_positions": sim.positions[-1].tolist(),
    }


class RunCache:
    """The runs of this figure, one JSON line each, keyed by scene digest and code
    fingerprint (as the sweep store keys its runs): a second figure run recomputes none."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.code = _code_digest()
        self.rows = {}
        if self.path.is_file():
            for line in self.path.read_text().splitlines():
                if line.strip():
                    row = json.loads(line)
                    self.rows[(row["scene_digest"], row["code_digest"])] = row["record"]

    def run(self, scene) -> dict:
        key = (scene.digest(), self.code)
        if key not in self.rows:
            from elastocap.jsonutil import jsonable

            rec = jsonable(run_record(scene))
            with open(self.path, "a") as f:
                f.write(json.dumps({"scene_digest": key[0], "code_digest": key[1],
                                    "record": rec}) + "\n")
            self.rows[key] = rec
        return self.rows[key]


# --------------------------------------------------------------------------- Delta*
def threshold(config: str, n_edges: int, out: Path, tol: float = DSTAR_TOL,
              grid=DSTAR_GRID) -> dict:
    """Delta* of supp-fig5 under ``config`` at ``n_edges``: the sweep's bisection on the
    line x = L / 2 (one store per configuration and resolution). Returns the line's boundary
    record with the final measures of its runs (to compare configurations run for run)."""
    from elastocap.sweep import run_sweep

    over = DSTAR_CONFIGS[config]
    scene = load_scene("supp-fig5", {**over, "numerics.n_edges": n_edges})
    res = run_sweep(scene, [SUPP_X], deltas=list(grid), refine_tol=tol, workers=1,
                    store=out / f"contact-comparison-{config}-n{n_edges}.sqlite")
    b = res.boundary[0]
    decided = b.status == "bracketed"
    return {
        "config": config, "n_edges": n_edges, "dt": res.resolutions[0].dt,
        "status": b.status, "low": b.low, "high": b.high,
        "delta_star": 0.5 * (b.low + b.high) if decided else None,
        "half_width": 0.5 * (b.high - b.low) if decided else None,
        "transitions": [t.to_dict() for t in b.transitions],
        "undecided_runs": sum(r["outcome"] == "undecided" for r in res.runs),
        "runs": len(res.runs),
        "measures": {f"{r['wetted_length']:.10f}": r["final_measure"] for r in res.runs},
        "rod_crossings": sum(r["rod_crossing_time"] is not None for r in res.runs),
        "interface_crossings": sum(r["interface_crossing_time"] is not None for r in res.runs),
    }


def convergence(values: dict[int, float], order: float = 2.0) -> dict:
    """Observed order and Richardson estimate from Delta* at three resolutions N, 2N, 4N."""
    ns = sorted(values)
    if len(ns) < 3 or any(values[n] is None for n in ns[-3:]):
        return {"observed_order": None, "richardson": None, "error_estimate": None}
    a, b, c = (values[n] for n in ns[-3:])
    # differences of one sign that shrink: p = log2 of their ratio (else no order)
    p = math.log2((a - b) / (b - c)) if (a - b) * (b - c) > 0 else None
    rich = c + (c - b) / (2.0**order - 1.0)
    return {"observed_order": p, "richardson": rich, "error_estimate": abs(c - rich),
            "resolutions": ns[-3:]}


# --------------------------------------------------------------------------- Figs 4-5
STRIP_CONFIGS = {
    "no-contact": {},
    "contact-ignore": {"rod.thickness": THICKNESS["fig3-strip"]},
    "contact-wet": {"rod.thickness": THICKNESS["fig3-strip"], "drop.interface_contact": "wet"},
}


def strip_scene(name: str, config: str, n_edges: int | None, fast: bool,
                t_max: float | None = None):
    """The Fig 4/5 run ``name`` (:data:`elastocap.paper_figures.fig4_fig5.RUNS`) under a
    contact configuration, at the Fig 3d resolution or ``n_edges`` (automatic dt), to the
    figure's t_max (``FIG45_T_MAX``) or ``t_max``."""
    from elastocap.paper_figures.fig4_fig5 import RUNS, run_scene

    scene = run_scene(RUNS[name], fast)
    over = dict(STRIP_CONFIGS[config])
    if t_max is not None:
        over["numerics.t_max"] = t_max
    if n_edges is not None:
        over.update({"numerics.n_edges": n_edges, "numerics.dt": 0.0})
    data = json.loads(json.dumps(scene.data))
    events = data["drop"].pop("events", None)
    scene = build_scene(data, scene.name).with_overrides(over)
    if events:
        data = json.loads(json.dumps(scene.data))
        data["drop"]["events"] = events
        scene = build_scene(data, scene.name)
    return scene


def strip_runs(cache: RunCache, names, edges, fast: bool):
    """The Fig 4/5 runs under every configuration at each resolution (None: Fig 3d's), and
    again to ``FIG45_T_MAX_LONG`` where a run had not come to rest by Fig 3d's t_max.

    Returns ``{(name, config, n, t_max): record}`` and the rows for the JSON (the record
    without the final shape, with the companion criterion's outcome on the final shape and,
    at the finer resolution, the shape difference to the coarser one)."""
    from elastocap.criteria import companion_outcome

    runs, rows = {}, []
    for n in edges:
        for name in names:
            for c in STRIP_CONFIGS:
                t_max = FIG45_T_MAX
                while True:
                    sc = strip_scene(name, c, n, fast, t_max=t_max)
                    rec = cache.run(sc)
                    runs[(name, c, n, t_max)] = rec
                    row = {k: v for k, v in rec.items() if k != "final_positions"}
                    comp = companion_outcome(np.asarray(rec["final_positions"]), sc)
                    row.update(run=name, config=c, resolution=n, t_max=t_max,
                               companion_outcome=comp.outcome)
                    rows.append(row)
                    if rec["at_rest"] or t_max >= FIG45_T_MAX_LONG:
                        break
                    t_max = FIG45_T_MAX_LONG
    for row in rows:
        coarse = runs.get((row["run"], row["config"], edges[0], row["t_max"]))
        if row["resolution"] != edges[0] and coarse is not None:
            fine = runs[(row["run"], row["config"], row["resolution"], row["t_max"])]
            row["shape_vs_coarser"] = shape_difference(np.asarray(fine["final_positions"]),
                                                       np.asarray(coarse["final_positions"]))
    return runs, rows


# --------------------------------------------------------------------------- drawing
def _draw_rod(ax, rec, scene, color, lw=1.4, label=None):
    from elastocap.frames import interface_points

    x = np.asarray(rec["final_positions"])
    n = len(x) - 1
    s_nodes = np.linspace(0.0, scene.rod.length, n + 1)
    iface, _ = interface_points(x, s_nodes, scene.drop.area, rec["final_s1"], rec["final_s2"],
                                scene.drop.line_tension)
    ax.plot(iface[:, 0], iface[:, 1], color=color, lw=0.6, alpha=0.6)
    ax.plot(x[:, 0], x[:, 1], color=color, lw=lw, label=label, solid_capstyle="round")
    return x


def _label(rec) -> str:
    out = {"open": "open", "encapsulated": "enc.", "undecided": "undec."}.get(rec["outcome"],
                                                                          rec["outcome"])
    return f"{out}, $M$ = {rec['final_measure']:.3f}"


def plot_supp(records: dict, deltas, configs, n_edges: int, path: Path):
    """Final shapes of supp-fig5 at each Delta (rows) under each configuration (columns)."""
    from elastocap.figure import new_figure

    colors = {"no-contact": "k", "d0.1-ignore": "tab:blue", "d0.1-wet": "tab:red",
              "d0.05-ignore": "tab:green"}
    heads = {"no-contact": "no thickness", "d0.1-ignore": r"$d$ = 0.1, ignore",
             "d0.1-wet": r"$d$ = 0.1, wet", "d0.05-ignore": r"$d$ = 0.05, ignore"}
    fig = new_figure((2.1 * len(configs), 1.9 * len(deltas) + 0.5))
    axes = fig.subplots(len(deltas), len(configs), squeeze=False)
    for i, delta in enumerate(deltas):
        for j, cfg in enumerate(configs):
            ax = axes[i, j]
            rec = records[(cfg, delta, n_edges)]
            scene = load_scene("supp-fig5", {**CONFIGS[cfg], "drop.wetted_length": delta})
            _draw_rod(ax, rec, scene, colors[cfg])
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            cross = ("" if rec["rod_crossing_time"] is None
                     else f", crossed at $t$ = {rec['rod_crossing_time']:.3g}")
            ax.set_title(_label(rec) + cross, fontsize=7, loc="left", pad=2)
            if j == 0:
                ax.set_ylabel(rf"$\Delta$ = {delta:g}", fontsize=8)
            if i == 0:
                ax.text(0.5, 1.28, heads[cfg], transform=ax.transAxes, ha="center",
                        fontsize=8)
    fig.suptitle(f"supp-fig5: final shapes at rest with and without rod contact "
                 f"({n_edges} edges)", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, bbox_inches="tight")


def plot_strip(records: dict, names, configs, path: Path, fast: bool):
    """Final shapes of the Fig 4/5 runs (columns), the configurations overlaid."""
    from elastocap.criteria import companion_outcome
    from elastocap.figure import new_figure

    colors = {"no-contact": "k", "contact-ignore": "tab:blue", "contact-wet": "tab:red"}
    styles = {"no-contact": "-", "contact-ignore": "--", "contact-wet": ":"}
    fig = new_figure((2.6 * len(names), 2.4))
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    for ax, name in zip(axes, names, strict=True):
        lines = []
        sc = strip_scene(name, "no-contact", None, fast)
        # the part of the strip near the free end, as the frame strips show it
        crop = min(sc.rod.length, sc.distance_from_end + sc.drop.wetted_length + 2.0)
        for cfg in configs:
            rec = records[(name, cfg)]
            x = np.asarray(rec["final_positions"])
            s = np.linspace(0.0, sc.rod.length, len(x))
            x = x[s >= sc.rod.length - crop]
            ax.plot(x[:, 0], x[:, 1], color=colors[cfg], ls=styles[cfg], lw=1.3)
            comp = companion_outcome(np.asarray(rec["final_positions"]), sc).outcome
            lines.append(f"{cfg}: {rec['outcome']}"
                         + ("" if comp == rec["outcome"] else f" ({comp}, frame-indep.)"))
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(name.replace("prime", "′"), fontsize=8, loc="left", pad=2)
        ax.set_xlabel("\n".join(lines), fontsize=6)
    handles = [axes[0].plot([], [], color=colors[c], ls=styles[c])[0] for c in configs]
    fig.legend(handles, [{"no-contact": "no thickness", "contact-ignore": r"$h/\ell_{eg}$ = "
                          f"{THICKNESS['fig3-strip']:g}, ignore", "contact-wet":
                          rf"$h/\ell_{{eg}}$ = {THICKNESS['fig3-strip']:g}, wet"}[c]
                         for c in configs], loc="lower center", ncol=len(configs), fontsize=7,
               frameon=False)
    fig.suptitle("Figs 4 and 5: final shapes with and without rod contact", fontsize=9)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, bbox_inches="tight")


# --------------------------------------------------------------------------- main
def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes ``contact-comparison.json``, ``contact-supp-fig5.png``,
    ``contact-fig4-fig5.png``, ``contact-fig5Dprime.png`` (not in fast mode) and the stores
    of its runs. ``fast``: 50 edges, two configurations, one Delta, fig4B only."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cache = RunCache(out / RUNS_FILE)
    if fast:  # smoke size: draft edges, two configurations, a coarse bracket
        configs, tol = ("no-contact", "d0.1-ignore"), 0.01
        plan = {50: configs}
        deltas, out_edges = (4.0,), (50,)
        strip_names, strip_edges = ("fig4B",), (None,)
    else:
        configs, plan, tol = tuple(CONFIGS), DSTAR_PLAN, DSTAR_TOL
        deltas, out_edges = OUTCOME_DELTAS, OUTCOME_EDGES
        strip_names, strip_edges = ("fig4A", "fig4B", "fig4C", "fig5D", "fig5Dprime"), \
            (None, STRIP_EDGES_FINE)

    # 1. Delta* per configuration and resolution
    dstar = [threshold(c, n, out, tol=tol) for n, cs in plan.items() for c in cs]
    base = {r["n_edges"]: r for r in dstar if r["config"] == "no-contact"}
    for r in dstar:  # did contact act on any run of the bisection? (same Delta, same M)
        ref = base[r["n_edges"]]["measures"]
        shared = [k for k in r["measures"] if k in ref]
        r["runs_shared_with_no_contact"] = len(shared)
        r["max_measure_difference_vs_no_contact"] = max(
            (abs(r["measures"][k] - ref[k]) for k in shared), default=None)
    conv = {c: convergence({r["n_edges"]: r["delta_star"] for r in dstar if r["config"] == c})
            for c in {r["config"]: None for r in dstar}}
    # the runs at the ends of each resolution's no-contact bracket: how close do the arms
    # come there (which thickness would act on the threshold)?
    bracket_runs = []
    for n, r in sorted(base.items()):
        if r["status"] != "bracketed":
            continue
        for side in ("low", "high"):
            sc = load_scene("supp-fig5", {"drop.wetted_length": r[side], "numerics.n_edges": n})
            rec = cache.run(sc)
            bracket_runs.append({"n_edges": n, "side": side, "wetted_length": r[side],
                                 **{k: rec[k] for k in (
                                     "outcome", "final_measure", "arm_gap_min",
                                     "gap_min_frames_max_thickness", "rod_crossing_time",
                                     "interface_crossing_time")}})

    # 2. outcomes and final shapes
    supp = {}
    for n in out_edges:
        for delta in deltas:
            for c in configs:
                sc = load_scene("supp-fig5", {**CONFIGS[c], "drop.wetted_length": delta,
                                              "numerics.n_edges": n})
                supp[(c, delta, n)] = cache.run(sc)
    outcomes = []
    for (c, delta, n), rec in supp.items():
        row = {k: v for k, v in rec.items() if k != "final_positions"}
        row.update(config=c, wetted_length=delta, n_edges=n)
        coarse = supp.get((c, delta, n // 2))
        row["shape_vs_half_edges"] = (None if coarse is None else shape_difference(
            np.asarray(rec["final_positions"]), np.asarray(coarse["final_positions"])))
        nc = supp.get(("no-contact", delta, n))
        row["shape_vs_no_contact"] = None if c == "no-contact" else shape_difference(
            np.asarray(rec["final_positions"]), np.asarray(nc["final_positions"]))
        # the same run bit for bit (contact never acted; "wet" never jumped)
        row["same_final_shape_as_no_contact"] = bool(np.array_equal(
            np.asarray(rec["final_positions"]), np.asarray(nc["final_positions"])))
        if rec["thickness"]:
            row["gap_at_rest_ok"] = rec["gap_at_rest"] >= rec["thickness"] * (1 - GAP_RTOL)
        outcomes.append(row)

    # 3. Figs 4 and 5
    strip, strip_rows = strip_runs(cache, strip_names, strip_edges, fast)

    files = []
    png = out / "contact-supp-fig5.png"
    plot_supp(supp, deltas, configs, out_edges[-1], png)
    files.append(png)
    png2 = out / "contact-fig4-fig5.png"
    # each run's final shape: to Fig 3d's t_max, or to FIG45_T_MAX_LONG where it was repeated
    last = {(nm, c): strip.get((nm, c, strip_edges[-1], FIG45_T_MAX_LONG),
                               strip[(nm, c, strip_edges[-1], FIG45_T_MAX)])
            for nm in strip_names for c in STRIP_CONFIGS}
    plot_strip(last, strip_names, tuple(STRIP_CONFIGS), png2, fast)
    files.append(png2)
    if not fast:
        # D' with contact as a frame strip (as fig5Dprime.png without): run again for its
        # frames (the cache keeps final shapes only)
        from elastocap.criteria import companion_outcome
        from elastocap.frames import frame_strip
        from elastocap.impact import run_impact

        # at 200 edges: the 133-edge run ends in another shape, 200 and 300 agree
        sc = strip_scene("fig5Dprime", "contact-ignore", STRIP_EDGES_FINE, fast,
                         t_max=FIG45_T_MAX_LONG)
        res = run_impact(sc)
        png3 = out / "contact-fig5Dprime.png"
        frame_strip(res, sc, png3, k=8,
                    title=rf"fig5Dprime with contact ($h/\ell_{{eg}}$ = "
                    rf"{THICKNESS['fig3-strip']:g}, {STRIP_EDGES_FINE} edges): {res.outcome} "
                    "(paper's criterion), "
                    f"{companion_outcome(res.simulation.positions[-1], sc).outcome} "
                    "(frame-independent)")
        files.append(png3)
    js = out / "contact-comparison.json"
    scene = load_scene("supp-fig5")

    def write(extra):
        write_json(js, record({"delta_star": dstar, "convergence": conv,
                               "bracket_runs": bracket_runs, "outcomes": outcomes,
                               "fig4_fig5": strip_rows, "fig5Dprime_check": extra},
                              scene, fast=fast, thickness=THICKNESS,
                              thickness_half=THICKNESS_HALF, configs=CONFIGS,
                              strip_configs=STRIP_CONFIGS, dstar_grid=DSTAR_GRID, dstar_tol=tol,
                              dstar_plan=plan, dstar_configs=DSTAR_CONFIGS,
                              outcome_edges=out_edges, strip_edges=strip_edges,
                              strip_t_max=(FIG45_T_MAX, FIG45_T_MAX_LONG),
                              gap_rtol=GAP_RTOL, code_digest=cache.code), indent=1)

    write(None)  # everything above, before the costly check below
    if not fast:
        # D' with contact reaches different final shapes at 133 and 200 edges: a third
        # resolution (about 10 min), appended to the record when it is done
        from elastocap.criteria import companion_outcome

        sc = strip_scene("fig5Dprime", "contact-ignore", DPRIME_CHECK_EDGES, fast,
                         t_max=FIG45_T_MAX_LONG)
        rec = cache.run(sc)
        x = np.asarray(rec["final_positions"])
        row = {k: v for k, v in rec.items() if k != "final_positions"}
        row["companion_outcome"] = companion_outcome(x, sc).outcome
        row["shape_vs"] = {str(n or "fig3d"): shape_difference(x, np.asarray(
            strip[("fig5Dprime", "contact-ignore", n, FIG45_T_MAX_LONG)]["final_positions"]))
            for n in strip_edges if ("fig5Dprime", "contact-ignore", n, FIG45_T_MAX_LONG)
            in strip}
        write(row)
    files.append(js)
    return files
