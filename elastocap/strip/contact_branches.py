"""All equilibrium branches of the strip on the ground in Delta, every contact topology.

What ``elastocap branches fig3-strip`` runs (parameter ``drop.wetted_length``). The strip is
the discrete one of :mod:`elastocap.strip.discrete` (z >= 0 at every node, frictionless
ground): the part lying on the ground, the lift-off point, a free end touching down again
and the drop's footprint resting on the ground are all contact sets of the same problem, so
no topology is excluded (the spectral solver of :mod:`elastocap.strip.branches` holds one).

Search
    At each of ``SEED_DELTAS`` inside the range, two seeds: a quasi-static
    deposition (descent from the flat strip, :func:`~elastocap.strip.mep.open_state`) and
    the strip folded over the drop (:func:`~elastocap.strip.mep.wrapped_state`). A seed that
    lies on a branch already traced is skipped (Newton at the seed's Delta from the nearest
    traced point of the same contact set lands on it to ``_SAME``).
Trace
    Each new seed is followed both ways by
    :func:`~elastocap.strip.discrete_branches.trace_discrete_branch`: pseudo-arclength
    continuation at a fixed contact set, the lift-offs and touch-downs located as events
    and the trace restarted with the new set, until Delta leaves the range or the strip
    has wrapped the whole drop (contact lines meeting).
Special points
    Smooth folds (located by the package's minimally augmented system) and contact folds:
    events at which Delta turns back from one contact set to the next (nonsmooth; the
    stability index changes there too). The stable (index 0) states found give the
    ``window``: the largest Delta of a stable open state and the smallest Delta of a stable
    encapsulated state (the paper's criterion, Methods), over admissible states only (the
    strip does not cross itself and the interface does not cross it).
Discretization error
    Folds and window ends are computed again at ``REFINE`` times the edges; the estimate
    of each is its distance to the nearest special point of the same kind and stability
    change at the finer resolution (folds tied to a node lifting off move by about an edge
    h; see the README on how these converge).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from continuation import ContinuationSettings
from elastocap._version import __version__
from elastocap.drop import cap_geometry, wet_polygon_area
from elastocap.scene import Scene, SceneError
from elastocap.statics.shape import arc_points, count_crossings
from elastocap.strip._blas import blas_threads
from elastocap.strip.barrier import flat_energy
from elastocap.strip.discrete import DiscreteStrip, discrete_strip_for, solve_equilibrium
from elastocap.strip.discrete_branches import _DEFAULTS, DiscreteBranch, trace_discrete_branch
from elastocap.strip.mep import is_encapsulated, open_state, wrapped_state

__all__ = ["NOT_HANDLED", "ContactBranchSet", "point_measures", "solved_crossings",
           "strip_and_interface", "trace_contact_branches"]

#: Seeds of each kind at these Deltas (length) inside the range (its midpoint if none):
#: fixed, so that the branches found do not depend on where the range starts. With 4
#: seeds spread over the range, x = 3, n = 143 found an open branch ending at a smooth fold
#: at Delta = 1.4451 when the range started at 0.3 and missed it from 0.5.
SEED_DELTAS = tuple(round(0.4 + 0.2 * k, 10) for k in range(9))
#: The error estimate's resolution: this many times the edges (rounded).
REFINE = 1.5
#: Segments per traced direction. At x = 2, n = 143 the open branch turns into the
#: encapsulated one through ~90 events (the lift-off point and the drop's footprint
#: crossing nodes one by one); 1000 leaves room for n ~ 10^3.
MAX_SEGMENTS = 1000
# Continuation steps per segment: after a smooth fold the index-1 branch of x = 3 runs
# ~1 in Delta at one contact set (400 steps were not enough).
_MAX_STEPS = 2000
# A seed is on a traced branch when Newton from the traced point lands within this of it
# (max norm of u; Newton converges to ~1e-12, distinct equilibria differ by >~ 1e-3).
_SAME = 1e-7

#: What this solver does not compute (also in every summary).
NOT_HANDLED = (
    "rod-rod contact (the strip may cross itself: such states are marked inadmissible, "
    "not excluded); branches not reached from the seeds (deposition and fold at "
    f"Delta = {', '.join(f'{d:g}' for d in SEED_DELTAS)}); only drop.wetted_length "
    "(other parameters use the single-topology spectral solver, elastocap.strip.branches)"
)


# --------------------------------------------------------------------------- observables
def strip_and_interface(strip: DiscreteStrip, u):
    """Node positions (n + 1, 2), the drop's interface (k, 2) from X(S1) to X(S2), and the
    chord d (length)."""
    X = strip.positions(u)
    s = strip.s_nodes
    p1 = np.array([np.interp(strip.s1, s, X[:, 0]), np.interp(strip.s1, s, X[:, 1])])
    p2 = np.array([np.interp(strip.s2, s, X[:, 0]), np.interp(strip.s2, s, X[:, 1])])
    d = float(np.hypot(*(p2 - p1)))
    a1 = strip.area - wet_polygon_area(X, s, strip.s1, strip.s2)
    tau = cap_geometry(a1, d)[0] if d > 0.0 else math.pi
    return X, arc_points(p1, p2, tau), d


def point_measures(strip: DiscreteStrip, u, flat: float | None = None) -> dict:
    """Observables of one state of the discrete strip.

    Keys: ``energy`` (energy units), ``energy_above_flat`` (energy minus gamma lambda of the
    drop on the straight strip at the same Delta), ``measure`` (theta(L)/pi: the turning of
    the strip, 0 flat, ~1 folded over), ``encapsulated`` (1.0/0.0, the paper's criterion:
    the free end left of the impact centre), ``tip_height`` z(L) (length), ``chord`` d
    (length), ``contacts`` (nodes at z <= 1e-12), ``rod_crossings`` and
    ``interface_crossings`` (counts), ``admissible`` (1.0 when both are 0).
    """
    X, iface, d = strip_and_interface(strip, u)
    rod_x = int(count_crossings(X, X, True, 0, len(X)))
    if_x = int(count_crossings(iface, X, False, 1, len(iface) - 2))
    e = strip.energy(u)
    if flat is None:
        flat = flat_energy(strip.area, strip.gamma, strip.delta)
    return {
        "energy": float(e),
        "energy_above_flat": float(e - flat),
        "measure": float(u[-1] / math.pi),
        "encapsulated": float(is_encapsulated(strip, u)),
        "tip_height": float(X[-1, 1]),
        "chord": d,
        "contacts": int(np.sum(X[:, 1] <= 1e-12)),
        "rod_crossings": rod_x,
        "interface_crossings": if_x,
        "admissible": float(rod_x == 0 and if_x == 0),
    }


# --------------------------------------------------------------------------- result
@dataclass
class ContactBranchSet:
    """Branches of the strip on the ground in Delta, with contact handled.

    Attributes
    ----------
    scene : Scene
    parameter : str
        ``"drop.wetted_length"``.
    prange : (float, float)
        Range of Delta (length).
    n : int
        Edges of the discrete strip.
    branches : list of DiscreteBranch
        Each a chain of fixed-contact-set segments; the two directions from a seed are two
        entries (``labels`` say which).
    labels : list of str
    points : list of dict of ndarray
        Per branch, the observables of :func:`point_measures` at every point, plus
        ``delta`` and ``index`` (the stability index: negative eigenvalues of the energy's
        Hessian on the tangent space of the contacts; 0 = stable).
    folds : list of dict
        Smooth and contact folds: ``value`` (Delta), ``kind`` (``"smooth"`` or
        ``"contact"``), ``node`` and ``event`` (contact folds), ``stability_change``
        (index before, after along the trace), ``measure``, ``energy``, ``branch``,
        ``error_estimate`` (length; NaN without refinement).
    window : dict
        ``open_max`` / ``encapsulated_min``: the largest Delta of a stable admissible open
        state and the smallest of a stable admissible encapsulated state (``value``,
        ``error_estimate``), ``bistable`` (open_max > encapsulated_min).
    events : list of dict
        Every active-set change (``delta``, ``kind``, ``node``, ``branch``).
    kind_changes : list of dict
        Where the paper's verdict flips along a branch without a fold (``value``,
        ``index``, ``from``, ``admissible``, ``branch``), located to ~1e-12 in Delta.
    branch_points, maxwell_points : list
        Empty (not searched for here; kept for the CLI's common report).
    metadata : dict
        Scene, resolution, tolerances, version, timing.
    """

    scene: Scene
    parameter: str
    prange: tuple
    n: int
    branches: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    points: list = field(default_factory=list)
    folds: list = field(default_factory=list)
    window: dict = field(default_factory=dict)
    events: list = field(default_factory=list)
    branch_points: list = field(default_factory=list)
    maxwell_points: list = field(default_factory=list)
    metadata: dict = field(default_factory=dict)
    kind_changes: list = field(default_factory=list)

    def summary(self) -> dict:
        """Plain data for ``--json``: special points, window, one line per branch."""
        lines = []
        for lab, br, pts in zip(self.labels, self.branches, self.points, strict=True):
            d = pts["delta"]
            lines.append({
                "label": lab,
                "points": int(d.size),
                "range": [float(d.min()), float(d.max())] if d.size else None,
                "stable_points": int(np.sum(pts["index"] == 0)),
                "segments": len(br.segments),
                "events": len(br.events),
                "status": br.status,
                "message": br.message,
            })
        return {
            "scene": self.scene.name,
            "parameter": self.parameter,
            "range": list(self.prange),
            "solver": "discrete strip, every contact topology (elastocap.strip.contact_branches)",
            "folds": self.folds,
            "window": self.window,
            "kind_changes": self.kind_changes,
            "branch_points": self.branch_points,
            "maxwell_points": self.maxwell_points,
            "events": len(self.events),
            "branches": lines,
            "not_handled": NOT_HANDLED,
            "metadata": self.metadata,
        }

    def save(self, out_dir) -> list:
        """Write ``branch_K.npz`` per branch (points, states, metadata) and ``branches.json``."""
        import json

        from elastocap.jsonutil import jsonable

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = []
        meta = json.dumps(jsonable({**self.metadata, "scene": self.scene.data}))
        for k, (br, pts) in enumerate(zip(self.branches, self.points, strict=True)):
            u = np.concatenate([s.u for s in br.segments]) if br.segments else np.empty(0)
            held = (np.concatenate([np.repeat(s.active[None], s.delta.size, 0)
                                    for s in br.segments]) if br.segments else np.empty(0))
            p = out / f"branch_{k}.npz"
            np.savez(p, u=u, held=held, label=self.labels[k], metadata=meta,
                     **{key: np.asarray(v) for key, v in pts.items()})
            paths.append(p)
        js = out / "branches.json"
        js.write_text(json.dumps(jsonable(self.summary()), indent=2))
        paths.append(js)
        return paths

    def report_lines(self) -> list[str]:
        """Human-readable report (the CLI without ``--json``)."""
        m = self.metadata
        out = [f"{self.scene.name}: {len(self.branches)} branches in {self.parameter} over "
               f"[{self.prange[0]:.6g}, {self.prange[1]:.6g}] (discrete strip, n = {self.n}"
               f" edges, {len(self.events)} contact events, {m['wall_time_s']:.1f} s)"]
        nf = m.get("n_edges_refined")

        def err(e):
            if nf is None:
                return "(not estimated)"
            return f"± {e:.1e}" if e == e else f"(no match at n = {nf})"

        for f in self.folds:
            what = "smooth fold " if f["kind"] == "smooth" else \
                f"contact fold ({f['event']} of node {f['node']})"
            out.append(f"  {what:38s} Delta {f['value']:.9f} {err(f['error_estimate']):22s}"
                       f" stability {f['stability_change']}  measure {f['measure']:+.4f}"
                       + ("" if f["admissible"] else "  (strip crosses itself)"))
        w = self.window
        for key, name in (("open_max", "stable open state up to"),
                          ("encapsulated_min", "stable encapsulated state from")):
            v = w.get(key)
            if v and v["value"] is not None:
                out.append(f"  {name:32s} Delta {v['value']:.9f} {err(v['error_estimate'])}")
        line = f"  bistable at n = {self.n}: {w.get('bistable')}"
        if w.get("width") is not None:
            line += f" (width {w['width']:+.2e})"
        if nf is not None:
            wr = w.get("width_refined")
            line += f"; at n = {nf}: {w.get('bistable_refined')}" + (
                f" (width {wr:+.2e})" if wr is not None else "")
        out.append(line)
        return out


# --------------------------------------------------------------------------- driver
def _check(scene: Scene, parameter: str, prange):
    if not (scene.effects.gravity > 0.0 and scene.effects.ground):
        raise SceneError("effects", {"gravity": scene.effects.gravity,
                                     "ground": scene.effects.ground},
                         "the strip on the ground needs gravity > 0 and ground = true")
    if parameter != "drop.wetted_length":
        raise SceneError("--param", parameter, "the contact-handling strip solver traces "
                         "drop.wetted_length only")
    x = scene.distance_from_end
    if prange is None:
        prange = (0.3, min(2.2, 1.95 * x))
    lo, hi = (float(v) for v in prange)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise SceneError("--range", list(prange), "expected two finite numbers 0 < LO < HI")
    if hi >= 2.0 * x:
        raise SceneError("--range", [lo, hi],
                         f"expected HI < 2 x = {2.0 * x} (the drop off the free end)")
    return lo, hi


def solved_crossings(strip: DiscreteStrip, branches):
    """Each place a traced segment crosses the strip's Delta, solved there exactly.

    Yields (segment, j, Equilibrium): Newton at the segment's contact set from its traced
    point j nearest the crossing (converged or not: check ``success``).
    """
    d0 = strip.delta
    for br in branches:
        for seg in br.segments:
            d = seg.delta
            if d.size < 2 or not d.min() <= d0 <= d.max():
                continue
            for i in range(d.size - 1):
                if d[i] == d[i + 1] or (d[i] - d0) * (d[i + 1] - d0) > 0.0:
                    continue
                j = i if abs(d[i] - d0) <= abs(d[i + 1] - d0) else i + 1
                yield seg, j, solve_equilibrium(strip, seg.u[j], active=seg.active,
                                                tol=1e-11, max_iter=30)


def _on_branch(strip: DiscreteStrip, u_seed, br: DiscreteBranch) -> bool:
    """Does the state ``u_seed`` at the strip's Delta lie on the traced branch ``br``?"""
    return any(eq.success and float(np.max(np.abs(eq.u - u_seed))) <= _SAME
               for _seg, _j, eq in solved_crossings(strip, [br]))


def _branch_points(strip: DiscreteStrip, br: DiscreteBranch) -> dict:
    rows = []
    for seg in br.segments:
        for d, u, idx in zip(seg.delta, seg.u, seg.index, strict=True):
            m = point_measures(strip.with_(delta=float(d)), u)
            m["delta"] = float(d)
            m["index"] = int(idx)
            rows.append(m)
    keys = rows[0].keys() if rows else ("delta", "index")
    return {k: np.array([r[k] for r in rows]) for k in keys}


def _special(strip: DiscreteStrip, branches, labels) -> tuple[list, list]:
    folds, events = [], []
    for b, br in enumerate(branches):
        for f in br.folds:
            if f["u"] is None:
                continue
            m = point_measures(strip.with_(delta=f["delta"]), f["u"])
            folds.append({"value": f["delta"], "kind": "smooth", "node": None, "event": None,
                          "stability_change": list(f["index"]) if f["index"] else None,
                          "measure": m["measure"], "energy": m["energy"],
                          "encapsulated": bool(m["encapsulated"]),
                          "admissible": bool(m["admissible"]), "branch": labels[b],
                          "located": f["located"]})
        for tp in br.turning_points:
            ev = next(e for e in br.events if e.delta == tp["delta"] and e.node == tp["node"])
            m = point_measures(strip.with_(delta=ev.delta), ev.u)
            folds.append({"value": tp["delta"], "kind": "contact", "node": tp["node"],
                          "event": tp["kind"], "stability_change": list(tp["index"]),
                          "measure": m["measure"], "energy": m["energy"],
                          "encapsulated": bool(m["encapsulated"]),
                          "admissible": bool(m["admissible"]), "branch": labels[b],
                          "located": True})
        for e in br.events:
            events.append({"delta": e.delta, "kind": e.kind, "node": e.node,
                           "branch": labels[b]})
    # the two directions from one seed can meet the same fold (a seed between two folds
    # on a closed stretch is not possible, but a branch traced from two seeds is skipped;
    # keep the list unique anyway)
    uniq = {}
    for f in folds:
        uniq.setdefault((round(f["value"], 10), f["kind"], f["node"]), f)
    return sorted(uniq.values(), key=lambda f: f["value"]), events


def _kind_changes(strip: DiscreteStrip, branches, labels) -> list:
    """Where the paper's criterion flips along a branch, located to ~1e-12 in Delta.

    Between two consecutive traced points of a segment whose verdicts differ, Delta is
    bisected, each state solved by Newton at the segment's contact set from the nearer
    point; the criterion x(S_c) - x(L) is continuous along the branch, so the flip is where
    the free end passes above the impact centre. Returns dicts ``value``, ``index`` (the
    stability index there), ``branch``.
    """
    out = []
    for b, br in enumerate(branches):
        for seg in br.segments:
            enc = [is_encapsulated(strip.with_(delta=float(d)), u)
                   for d, u in zip(seg.delta, seg.u, strict=True)]
            for i in range(len(enc) - 1):
                if enc[i] == enc[i + 1] or seg.delta[i] == seg.delta[i + 1]:
                    continue
                a, c = float(seg.delta[i]), float(seg.delta[i + 1])
                ua = seg.u[i]
                ea = enc[i]
                ok = True
                for _ in range(60):
                    if abs(c - a) <= 1e-12 * (1.0 + abs(a)):
                        break
                    m = 0.5 * (a + c)
                    eq = solve_equilibrium(strip.with_(delta=m), ua, active=seg.active,
                                           tol=1e-11, max_iter=30)
                    if not eq.success:
                        ok = False
                        break
                    if is_encapsulated(strip.with_(delta=m), eq.u) == ea:
                        a, ua = m, eq.u
                    else:
                        c = m
                if ok:
                    m = point_measures(strip.with_(delta=a), ua)
                    out.append({"value": 0.5 * (a + c), "index": int(seg.index[i]),
                                "from": "encapsulated" if ea else "open",
                                "admissible": bool(m["admissible"]), "branch": labels[b]})
    return out


def _window(points, folds=(), kind_changes=()) -> dict:
    """Largest Delta of a stable open state, smallest of a stable encapsulated one.

    A stable stretch of a branch ends at a located special point: a fold, a contact fold
    where the index changes, or a kind change (the verdict flips on a stable stretch, no
    fold); those count with the traced stable points, and ``how`` says which one gave
    each end (``"smooth_fold"``, ``"contact_fold"``, ``"kind_change"``, or ``"range"``: a
    traced point, the stable stretch reaching the range's end).
    """
    opens, encs = [], []
    for pts in points:
        ok = (pts["index"] == 0) & (pts["admissible"] == 1.0)
        enc = pts["encapsulated"] == 1.0
        if np.any(ok & ~enc):
            opens.append((float(pts["delta"][ok & ~enc].max()), "range"))
        if np.any(ok & enc):
            encs.append((float(pts["delta"][ok & enc].min()), "range"))
    for f in folds:
        if f["admissible"] and f["stability_change"] and 0 in f["stability_change"]:
            (encs if f["encapsulated"] else opens).append((f["value"], f"{f['kind']}_fold"))
    for k in kind_changes:
        if k["index"] == 0 and k["admissible"]:
            opens.append((k["value"], "kind_change"))
            encs.append((k["value"], "kind_change"))
    # at a tie a located special point names the end (an event is also a traced point)
    top = max(opens, key=lambda t: (t[0], t[1] != "range")) if opens else None
    bot = min(encs, key=lambda t: (t[0], t[1] == "range")) if encs else None
    return {
        "open_max": {"value": top[0] if top else None, "how": top[1] if top else None,
                     "error_estimate": math.nan},
        "encapsulated_min": {"value": bot[0] if bot else None,
                             "how": bot[1] if bot else None, "error_estimate": math.nan},
        "bistable": bool(top and bot and top[0] > bot[0]),
        "width": (top[0] - bot[0]) if top and bot else None,
    }


def _trace_all(strip: DiscreteStrip, lo: float, hi: float, progress=None):
    grid = [d for d in SEED_DELTAS if lo < d < hi] or [0.5 * (lo + hi)]
    branches, labels = [], []
    for kind, seed in (("deposition", open_state), ("fold", wrapped_state)):
        for d in grid:
            s = strip.with_(delta=float(d))
            eq = seed(s)
            if not eq.success:
                continue
            if any(_on_branch(s, eq.u, br) for br in branches):
                continue
            for direction in (-1, 1):
                st = ContinuationSettings(**{**_DEFAULTS, "direction": direction,
                                             "max_steps": _MAX_STEPS})
                br = trace_discrete_branch(s, eq, (lo, hi), st, restart=True,
                                           max_segments=MAX_SEGMENTS)
                branches.append(br)
                labels.append(f"{kind} at Delta = {d:.4g}, "
                              f"{'down' if direction < 0 else 'up'}")
                if progress is not None:
                    progress(labels[-1], br)
    return branches, labels


def _nearest(value, candidates):
    return min((abs(value - c) for c in candidates), default=math.nan)


def trace_contact_branches(scene: Scene, parameter: str = "drop.wetted_length", prange=None,
                           n: int | None = None, refine: bool = True,
                           progress=None, n_refined: int | None = None) -> ContactBranchSet:
    """Search, trace and classify the branches of a strip-on-the-ground scene in Delta.

    Parameters
    ----------
    scene : Scene
        With gravity > 0 and the ground (``fig3-strip``).
    parameter : str
        Must be ``"drop.wetted_length"``.
    prange : (lo, hi), optional
        Delta range (length); default (0.3, min(2.2, 1.95 x)).
    n : int, optional
        Edges; default the scene's impact resolution (``numerics.n_edges`` or the accuracy
        preset's).
    refine : bool
        Repeat at ``REFINE`` n edges for the error estimates (about 2-3x the time).
    progress : callable(label, branch), optional
        Called after each traced direction.
    n_refined : int, optional
        Edges of the refined run (default ``round(REFINE * n)``).

    Returns
    -------
    ContactBranchSet
    """
    lo, hi = _check(scene, parameter, prange)
    t0 = time.perf_counter()
    strip = discrete_strip_for(scene, n)
    with blas_threads(1):
        branches, labels = _trace_all(strip, lo, hi, progress)
        points = [_branch_points(strip, br) for br in branches]
        folds, events = _special(strip, branches, labels)
        kinds = _kind_changes(strip, branches, labels)
        window = _window(points, folds, kinds)
        n_fine = None
        if refine:
            n_fine = int(n_refined) if n_refined is not None else int(round(REFINE * strip.n))
            if n_fine == strip.n:
                raise ValueError(f"n_refined: got {n_fine}; expected it to differ from n = "
                                 f"{strip.n}")
            fine = strip.with_(n=n_fine)
            fb, fl = _trace_all(fine, lo, hi)
            ffolds, _ = _special(fine, fb, fl)
            fwin = _window([_branch_points(fine, br) for br in fb], ffolds,
                           _kind_changes(fine, fb, fl))
            for f in folds:
                same = [g["value"] for g in ffolds if g["kind"] == f["kind"]
                        and g["stability_change"] == f["stability_change"]]
                f["error_estimate"] = _nearest(f["value"], same)
            for key in ("open_max", "encapsulated_min"):
                a, b = window[key]["value"], fwin[key]["value"]
                if a is not None and b is not None:
                    window[key]["error_estimate"] = abs(a - b)
                window[key]["value_refined"] = b
                window[key]["how_refined"] = fwin[key]["how"]
            window["bistable_refined"] = fwin["bistable"]
            window["width_refined"] = fwin["width"]
        else:
            for f in folds:
                f["error_estimate"] = math.nan
    bs = ContactBranchSet(scene, parameter, (lo, hi), strip.n, branches, labels, points,
                          folds, window, events, kind_changes=kinds)
    bs.metadata = {
        "scene": scene.name,
        "parameter": parameter,
        "range": [lo, hi],
        "N": strip.n,
        "n_edges": strip.n,
        "n_edges_refined": n_fine,
        "solver": "discrete strip (elastocap.strip.discrete), pseudo-arclength at fixed "
                  "contact sets with located lift-off/touch-down events",
        "seed_deltas": [d for d in SEED_DELTAS if lo < d < hi] or [0.5 * (lo + hi)],
        "continuation": {k: v for k, v in _DEFAULTS.items()},
        "contact_event_tol": "reaction or gap at a located event below 1e-13 (force, length)",
        "version": __version__,
        "wall_time_s": time.perf_counter() - t0,
    }
    return bs
