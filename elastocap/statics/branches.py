"""Tracing every equilibrium branch of a scene: search, continuation, special points.

Completeness strategy (a systematic search with deflation): on a grid of K parameter values
spanning the range, Newton is started from a family of seed shapes (uniformly curved rods with
total turning M pi, M from -2.5 to 2.5, plus asymmetric perturbations), **deflated** against
every solution already known at that value (Farrell, Birkisson & Funke 2015), so that a seed
that would fall back on a known solution is pushed to a new one or fails. Every new solution
starts a branch continued both ways; every branch crossing a grid value records its exact
solution there (continuation events), so the next seeds are deflated against it; every simple
branch point is switched. A branch missed by this procedure would have to avoid all K grid
values (an isola narrower than the grid spacing) and every deflated seed basin; the tests
check that doubling K and the seed family finds nothing new for supp-fig5.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from continuation import (
    Branch,
    ContinuationSettings,
    continue_branch,
    locate_fold,
    switch_branch,
)
from elastocap._version import __version__
from elastocap.jsonutil import jsonable
from elastocap.scene import Scene, SceneError
from elastocap.statics.wet_elastica import PARAMETERS, WetElasticaProblem

__all__ = [
    "ACCURACY_N",
    "BranchSet",
    "find_folds",
    "newton",
    "problem_for",
    "trace_branches",
]

#: LGL intervals on the wet part per accuracy preset. Measured on supp-fig5 (README,
#: "Statics accuracy"): fold error 1.4e-9 at N = 16, 2e-14 at N = 24, round-off at N = 40.
#: (N = 12 reaches 5e-7 on the fold but finds a spurious fold on the inadmissible inverted
#: branch, which a finer resolution does not confirm: 16 is the smallest safe draft.)
ACCURACY_N = {"draft": 16, "default": 24, "publication": 40}
# Contact lines closer than this fraction of Delta end a branch: the chord direction, and so
# the cap, is undefined when they meet.
_CHORD_STOP = 1e-3
# Grid values used by the search, and the seed family (see module docstring).
# 4 values x 14 seeds finds all 5 branches of supp-fig5; the tests check that 11 values x 63
# seeds find nothing more (and the README quotes the timing of the default).
_SEARCH_GRID = 4
_SEED_TURNS = tuple(np.linspace(-2.4, 2.4, 7))
_SEED_ASYM = (0.0, 0.8)


def _check_statics_scene(scene: Scene) -> None:
    if scene.effects.gravity > 0.0 or scene.effects.ground:
        raise SceneError(
            "effects",
            {"gravity": scene.effects.gravity, "ground": scene.effects.ground},
            "statics handles the free rod without gravity or ground; set effects.gravity=0 "
            "and effects.ground=false (the contact statics of the strip scene is not built yet)",
        )


def problem_for(
    scene: Scene, parameter: str = "drop.wetted_length", N: int | None = None, nodes="lgl"
) -> WetElasticaProblem:
    """The discretized equilibrium problem of a scene, continued in ``parameter``."""
    _check_statics_scene(scene)
    if parameter not in PARAMETERS:
        raise SceneError("--param", parameter, f"expected one of {', '.join(PARAMETERS)}")
    if N is None:
        N = scene.numerics.cheb_points or ACCURACY_N[scene.numerics.accuracy]
    if N < 4:
        raise SceneError("numerics.cheb_points", N, "expected at least 4 intervals")
    d = scene.drop
    return WetElasticaProblem(
        N,
        d.wetted_length,
        d.area,
        d.line_tension,
        scene.rod.bending_modulus,
        scene.rod.length,
        d.center,
        parameter,
        nodes,
    )


def newton(problem, u, p, tol=1e-11, max_iter=40, deflate=(), max_step=0.5):
    """Damped Newton for F(u, p) = 0 at fixed p, optionally deflated.

    Parameters
    ----------
    deflate : sequence of ndarray
        Known solutions; the deflation operator prod (1/|u - u_i|^2 + 1) keeps Newton away
        from them (Farrell et al. 2015; shift 1, power 2).
    max_step : float
        Largest change of any angle per iteration (radians): damping for far seeds.

    Returns
    -------
    ndarray or None
        The solution, or None when Newton did not converge.
    """
    u = np.array(u, dtype=float)
    n_th = problem.N + 1
    r_first = None
    for it in range(max_iter):
        with np.errstate(all="ignore"):
            r = problem.residual(u, p)
        if not np.all(np.isfinite(r)):
            return None
        rn = float(np.max(np.abs(r)))
        if rn <= tol:
            return u
        r_first = rn if r_first is None else r_first
        # a residual 1e6 times the first one: diverging (a seed far from any solution); no
        # decrease by half after 12 damped iterations: wandering (deflation pushed it off)
        if rn > 1e6 * r_first or (it >= 12 and rn > 0.5 * r_first):
            return None
        try:
            du = np.linalg.solve(problem.jacobian(u, p), -r)
        except np.linalg.LinAlgError:
            return None
        if deflate:
            # Sherman-Morrison: the deflated step is the plain step scaled by
            # 1 / (1 - grad(ln m) . du)
            gl = np.zeros_like(u)
            for ui in deflate:
                e = u[:n_th] - ui[:n_th]
                r2 = float(e @ e)
                if r2 == 0.0:
                    return None
                gl[:n_th] += (-2.0 / (r2 * r2)) * e / (1.0 / r2 + 1.0)
            den = 1.0 - float(gl @ du)
            if den == 0.0:
                return None
            du = du / den
        big = np.max(np.abs(du[:n_th]))
        if not np.isfinite(big):
            return None
        u = u + (du if big <= max_step else du * (max_step / big))
    return None


@dataclass
class BranchSet:
    """All branches of a scene in one parameter, with their special points.

    Attributes
    ----------
    branches : list of continuation.Branch
    labels : list of str
        One per branch: ``"primary"`` (through the nearly flat state), or ``"branch k"``.
    folds : list of dict
        Every limit point: value, measure, stability_change, error_estimate, branch.
    branch_points, maxwell_points, endpoints : list of dict
    metadata : dict
        Scene (resolved TOML data), parameter, range, N, nodes, tolerances, version, timing.
    """

    scene: Scene
    parameter: str
    prange: tuple[float, float]
    problem: WetElasticaProblem
    branches: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    folds: list = field(default_factory=list)
    branch_points: list = field(default_factory=list)
    maxwell_points: list = field(default_factory=list)
    admissibility_changes: list = field(default_factory=list)
    endpoints: list = field(default_factory=list)
    metadata: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """Plain data for ``--json``: special points by kind and one line per branch."""
        return {
            "scene": self.scene.name,
            "parameter": self.parameter,
            "range": list(self.prange),
            "folds": self.folds,
            "branch_points": self.branch_points,
            "maxwell_points": self.maxwell_points,
            "admissibility_changes": self.admissibility_changes,
            "endpoints": self.endpoints,
            "branches": [
                {
                    "label": lab,
                    "points": len(br),
                    "range": [float(br.p.min()), float(br.p.max())] if len(br) else None,
                    "stable_points": int(np.sum(br.stability == 0)),
                    "status": br.status,
                    "message": br.message,
                }
                for br, lab in zip(self.branches, self.labels, strict=True)
            ],
            "metadata": self.metadata,
        }

    #: ``format`` of the ``branches.json`` that :meth:`save` writes and :meth:`load` reads.
    FORMAT = "elastocap.statics.BranchSet/1"

    def save(self, out_dir) -> list:
        """Write ``branch_K.npz`` (+ ``branch_K.json``) per branch and ``branches.json``.

        ``out_dir`` is a folder path or an :class:`elastocap.io.OutputFolder`. Every file is
        written atomically; the folder's earlier branch files are removed first (only those
        an earlier save listed), so no stale ``branch_K`` survives a run with fewer branches.
        The branches record their parameter by its scene key (e.g. ``drop.wetted_length``).
        Returns the paths written.
        """
        import json
        from dataclasses import replace

        from elastocap.io import OutputFolder

        folder = out_dir if isinstance(out_dir, OutputFolder) else OutputFolder(
            out_dir, "branches", key="out_dir")
        paths = []
        files = []
        with folder.staged() as stage:
            for k, br in enumerate(self.branches):
                meta = {**br.metadata, "label": self.labels[k], "scene": self.scene.data,
                        "statics": self.metadata}
                br.metadata.update(meta)
                replace(br, parameter=self.parameter, metadata=meta).save(
                    stage / f"branch_{k}.npz")
                files.append(f"branch_{k}.npz")
            summary = self.summary()
            summary["format"] = self.FORMAT
            for line, name in zip(summary["branches"], files, strict=True):
                line["file"] = name
            (stage / "branches.json").write_text(
                json.dumps(jsonable(summary), indent=2), encoding="utf-8")
        paths = [folder.final(stage / f) for f in files] + [folder.final(stage / "branches.json")]
        return paths

    @classmethod
    def load(cls, folder) -> BranchSet:
        """Read a branch set written by :meth:`save` (no recomputation: the scene, the
        discretization and every branch and special point come from the files).

        Raises ValueError naming the file when the folder is not a complete free-rod branch
        set (e.g. a strip's contact branch set, or a missing ``branch_K.npz``).
        """
        import json
        from pathlib import Path

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
        if not isinstance(data, dict) or data.get("format") != cls.FORMAT:
            what = ("a strip's contact branch set" if isinstance(data, dict) and "solver" in data
                    else "not a free-rod branch set")
            raise ValueError(f"{str(js)!r}: {what}; BranchSet.load reads the branches.json "
                             f"of a free-rod trace (format {cls.FORMAT!r})")
        meta = data["metadata"]
        scene = build_scene(meta["scene"], meta["scene_name"])
        problem = problem_for(scene, meta["parameter"], meta["N"], meta["nodes"])
        bs = cls(scene, meta["parameter"], tuple(meta["range"]), problem)
        for line in data["branches"]:
            path = root / line["file"]
            if not path.is_file():
                raise ValueError(f"{str(path)!r}: missing (listed in {str(js)!r})")
            bs.branches.append(Branch.load(path))
            bs.labels.append(line["label"])
        for key in ("folds", "branch_points", "maxwell_points", "admissibility_changes",
                    "endpoints"):
            setattr(bs, key, cls._numbers_back(data.get(key, [])))
        bs.metadata = meta
        return bs

    @staticmethod
    def _numbers_back(obj):
        """Undo :func:`elastocap.jsonutil.jsonable` on non-finite floats ("nan", "inf")."""
        if isinstance(obj, dict):
            return {k: BranchSet._numbers_back(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [BranchSet._numbers_back(v) for v in obj]
        if isinstance(obj, str) and obj in ("nan", "inf", "-inf"):
            return float(obj)
        return obj


def _settings(scene: Scene, lo: float, hi: float, span: float) -> ContinuationSettings:
    # ds_max = 2% of the range: fine enough to see every fold of supp-fig5 and to draw
    # smooth curves; folds are then located exactly, not read off the steps.
    return ContinuationSettings(
        ds0=0.01 * span,
        ds_min=1e-9 * span,
        ds_max=0.02 * span,
        max_steps=scene.numerics.max_steps,
        p_min=lo,
        p_max=hi,
        direction=0,
        newton_tol=scene.numerics.newton_tol,
        max_turn=0.2,
        check_jacobian=False,
    )


def _seeds(problem, turns=_SEED_TURNS, asym=_SEED_ASYM):
    xi = problem.xi
    out = []
    for m in turns:
        for b in asym:
            th = 0.5 * math.pi * m * xi + b * (xi * xi - 1.0 / 3.0)
            out.append(np.concatenate([th, [0.0]]))
    return out


def _same(u, v, tol=1e-6):
    n = len(u) - 1
    return float(np.max(np.abs(u[:n] - v[:n]))) <= tol


def trace_branches(
    scene: Scene,
    parameter: str = "drop.wetted_length",
    prange: tuple[float, float] | None = None,
    *,
    N: int | None = None,
    nodes: str = "lgl",
    grid: int = _SEARCH_GRID,
    seed_turns=_SEED_TURNS,
    seed_asymmetries=_SEED_ASYM,
    error_estimates: bool = True,
) -> BranchSet:
    """Every equilibrium branch of ``scene`` in ``parameter`` over ``prange``.

    Parameters
    ----------
    scene : Scene
        A scene without gravity or ground.
    parameter : str
        Scene key continued (``drop.wetted_length``, ``drop.area``, ``drop.line_tension``,
        ``rod.bending_modulus``, ``rod.length``, ``drop.center``, ``drop.distance_from_end``).
    prange : (lo, hi), optional
        Default for Delta: (0.02 L, L); otherwise 0.5x to 2x the scene's value.
    N : int, optional
        LGL intervals on the wet part (default from ``numerics``).
    grid : int
        Number of parameter values of the search.
    seed_turns, seed_asymmetries : sequences of float
        Seed shapes: total turning M pi (M in seed_turns) plus b (xi^2 - 1/3) asymmetry.
    error_estimates : bool
        Relocate each fold at a finer resolution to estimate its discretization error.

    Returns
    -------
    BranchSet
    """
    t0 = time.perf_counter()
    problem = problem_for(scene, parameter, N, nodes)
    p_scene = problem.get(parameter)
    L = scene.rod.length
    if prange is None:
        if parameter == "drop.wetted_length":
            prange = (0.02 * L, L)
        else:
            prange = (0.5 * p_scene, 2.0 * p_scene)
    lo, hi = float(prange[0]), float(prange[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise SceneError("--range", list(prange), "expected two finite numbers LO < HI")
    if parameter == "drop.wetted_length" and (lo <= 0.0 or hi > L * (1 + 1e-12)):
        raise SceneError("--range", [lo, hi], f"expected 0 < LO < HI <= rod.length = {L}")
    span = hi - lo
    settings = _settings(scene, lo, hi, span)
    grid_p = np.linspace(lo, hi, grid + 2)[1:-1]
    known: dict[int, list] = {k: [] for k in range(len(grid_p))}

    def chord_event(u, p):
        S = problem.state(u, p)
        return S.d - _CHORD_STOP * problem.params["delta"]

    def admissible_event(u, p):
        # +1/2 admissible, -1/2 not: the sign change is located to the bisection tolerance
        return problem.observables(u, p)["admissible"] - 0.5

    events = {"contact_lines_meet": chord_event, "admissibility": admissible_event}
    for k, pk in enumerate(grid_p):
        events[f"grid{k}"] = lambda u, p, pk=pk: p - pk
    result = BranchSet(scene, parameter, (lo, hi), problem)

    def record(br: Branch) -> bool:
        """Register the grid crossings of a new branch; False if it duplicates a known one."""
        if any(_on_branch(problem, br, old) for old in result.branches):
            return False
        for sp in br.points("event"):
            if sp.name.startswith("grid") and sp.u is not None:
                k = int(sp.name[4:])
                if not any(_same(sp.u, v) for v in known[k]):
                    known[k].append(sp.u)
        return True

    def trace(u, p, label):
        problem.set(parameter, p)
        br = continue_branch(problem, u, p, settings, events=events, stop_on=["contact_lines_meet"])
        if len(br) and record(br):
            result.branches.append(br)
            result.labels.append(label)
            return br
        return None

    # 1. the primary branch: from the flat rod at the scene's own parameter value
    problem.set(parameter, p_scene if lo <= p_scene <= hi else 0.5 * (lo + hi))
    p_start = problem.get(parameter)
    u_flat = newton(problem, np.zeros(problem.N + 2), p_start, settings.newton_tol)
    if u_flat is not None:
        trace(u_flat, p_start, "primary")
    # 2. deflated seeds on the grid
    for k, pk in enumerate(grid_p):
        for seed in _seeds(problem, seed_turns, seed_asymmetries):
            problem.set(parameter, pk)
            # 25 iterations: converging seeds need < 15 (angles move <= 0.5 rad each)
            u = newton(problem, seed, pk, settings.newton_tol, max_iter=25, deflate=known[k])
            if u is None or any(_same(u, v) for v in known[k]):
                continue
            trace(u, pk, f"branch {len(result.branches)}")
            known[k].append(u)
    # 3. branch switching at every simple branch point (new branches may have more)
    done = 0
    while done < len(result.branches):
        br = result.branches[done]
        done += 1
        for bp in br.branch_points:
            if not bp.located or "kernel" not in bp.data:
                continue
            problem.set(parameter, bp.p)
            nb = switch_branch(problem, bp, settings, events=events, stop_on=["contact_lines_meet"])
            if len(nb) and record(nb):
                result.branches.append(nb)
                result.labels.append(f"branch {len(result.branches) - 1}")
    _collect_special_points(result, error_estimates)
    result.metadata = {
        "scene": scene.data,
        "scene_name": scene.name,
        "parameter": parameter,
        "range": [lo, hi],
        "N": problem.N,
        "nodes": nodes,
        "newton_tol": settings.newton_tol,
        "locate_tol": settings.locate_tol,
        "search_grid": [float(v) for v in grid_p],
        "seeds": len(seed_turns) * len(seed_asymmetries),
        # the dry arms are straight and unloaded: these keys only move them
        "equilibrium_independent_of_parameter": parameter
        in ("rod.length", "drop.center", "drop.distance_from_end"),
        "version": __version__,
        "wall_time_s": time.perf_counter() - t0,
    }
    return result


def _on_branch(problem, new: Branch, old: Branch) -> bool:
    """True if ``new`` is ``old``: its points at a quarter and three quarters of its length
    (away from a branch point it may start from) both lie on ``old``."""
    if new.u is None or old.u is None or not len(new) or not len(old):
        return False
    return all(
        _point_on(problem, float(new.p[m]), new.u[m], old)
        for m in sorted({len(new) // 4, (3 * len(new)) // 4})
    )


def _point_on(problem, pm, um, old: Branch) -> bool:
    """True if the solution (pm, um) lies on branch ``old``."""
    par = problem.parameter
    for i in range(len(old) - 1):
        a, b = old.p[i], old.p[i + 1]
        if (a - pm) * (b - pm) > 0.0 or a == b:
            continue
        w = (pm - a) / (b - a)
        guess = (1 - w) * old.u[i] + w * old.u[i + 1]
        # linear interpolation along a step of <= 3% of the range: within 0.2 rad of the
        # branch, well inside Newton's basin; farther means another branch
        if np.max(np.abs(guess[:-1] - um[:-1])) > 0.2:
            continue
        problem.set(par, pm)
        u = newton(problem, guess, pm, 1e-11)
        if u is not None and _same(u, um, 1e-6):
            return True
    return False


def _stability_change(br: Branch, idx: int) -> str:
    a = int(br.stability[max(idx - 1, 0)])
    b = int(br.stability[min(idx, len(br) - 1)])
    return f"{a}->{b}"


def _fold_error(problem: WetElasticaProblem, sp) -> float:
    """|p_N - p_N2| with N2 = N + max(8, N/2): the fold relocated at a finer resolution.

    For spectral convergence the finer value is far more accurate, so this difference
    estimates (slightly over-estimates) the error of the value reported at N.
    """
    N2 = problem.N + max(8, problem.N // 2)
    fine = WetElasticaProblem(
        N2,
        *(problem.params[k] for k in ("delta", "area", "gamma", "B", "L", "center")),
        problem.parameter,
        problem.nodes,
    )
    fine.set(problem.parameter, sp.p)
    Mi = problem.interp_matrix(fine.xi)
    th = Mi @ sp.u[: problem.N + 1]
    u2 = np.concatenate([th, [0.0]])
    v = sp.data.get("kernel")
    v2 = None
    if v is not None and len(v) >= problem.N + 1:
        v2 = np.concatenate([Mi @ np.asarray(v)[: problem.N + 1], [0.0]])
    fine_sp = locate_fold(fine, u2, sp.p, v=v2)
    if not fine_sp.located:
        return math.nan
    return abs(fine_sp.p - sp.p)


def _collect_special_points(result: BranchSet, error_estimates: bool) -> None:
    problem = result.problem
    par = result.parameter
    for b, br in enumerate(result.branches):
        for sp in br.special_points:
            obs = {}
            if sp.u is not None:
                problem.set(par, sp.p)
                obs = problem.observables(sp.u, sp.p)
            if sp.kind == "fold":
                err = math.nan
                if error_estimates and sp.located:
                    problem.set(par, sp.p)
                    err = _fold_error(problem, sp)
                result.folds.append(
                    {
                        "value": float(sp.p),
                        "measure": float(obs.get("measure", math.nan)),
                        "energy": float(obs.get("energy", math.nan)),
                        "stability_change": _stability_change(br, sp.index),
                        "error_estimate": err,
                        "located": bool(sp.located),
                        "branch": b,
                        **(
                            {"message": sp.data["message"]}
                            if not sp.located and "message" in sp.data
                            else {}
                        ),
                    }
                )
            elif sp.kind == "branch_point":
                result.branch_points.append(
                    {
                        "value": float(sp.p),
                        "measure": float(obs.get("measure", math.nan)),
                        "stability_change": _stability_change(br, sp.index),
                        "located": bool(sp.located),
                        "branch": b,
                    }
                )
            elif sp.kind == "event" and sp.name == "admissibility":
                # where the drawn shape starts or stops crossing itself or the interface
                result.admissibility_changes.append(
                    {
                        "value": float(sp.p),
                        "measure": float(obs.get("measure", math.nan)),
                        "precision": float(sp.precision),
                        "branch": b,
                    }
                )
            elif sp.kind == "endpoint" or (sp.kind == "event" and sp.name == "contact_lines_meet"):
                reason = "contact lines meet" if sp.kind == "event" else br.message
                result.endpoints.append(
                    {
                        "value": float(sp.p),
                        "measure": float(obs.get("measure", math.nan)),
                        "kind": "contact_lines_meet" if sp.kind == "event" else "endpoint",
                        "reason": reason,
                        "branch": b,
                    }
                )
    # dedupe mirror images / the same point reached from two branches
    result.folds = _dedupe(result.folds)
    result.admissibility_changes = _dedupe(result.admissibility_changes)
    result.branch_points = _dedupe(result.branch_points)
    result.folds.sort(key=lambda f: f["value"])
    result.maxwell_points = _maxwell_points(result)


def _dedupe(points):
    out = []
    for f in points:
        if not any(
            abs(f["value"] - g["value"]) <= 1e-8 * max(1.0, abs(g["value"]))
            and abs(f["measure"] - g["measure"]) <= 1e-6
            for g in out
        ):
            out.append(f)
    return out


def _stable_runs(br: Branch):
    """Index ranges [a, b] of consecutive stable points along which p is monotone."""
    runs = []
    n = len(br)
    i = 0
    while i < n:
        if br.stability[i] != 0:
            i += 1
            continue
        j = i
        while j + 1 < n and br.stability[j + 1] == 0:
            if j > i and (br.p[j + 1] - br.p[j]) * (br.p[j] - br.p[j - 1]) < 0:
                break
            j += 1
        if j > i:
            runs.append((i, j))
        i = j + 1
    return runs


def _solve_on_run(problem, br, i, j, p):
    """The state of branch ``br`` at parameter ``p`` within the monotone run [i, j]."""
    ps = br.p[i : j + 1]
    order = np.argsort(ps)
    ps = ps[order]
    us = br.u[i : j + 1][order]
    k = int(np.clip(np.searchsorted(ps, p), 1, len(ps) - 1))
    w = 0.0 if ps[k] == ps[k - 1] else (p - ps[k - 1]) / (ps[k] - ps[k - 1])
    problem.set(problem.parameter, p)
    return newton(problem, (1 - w) * us[k - 1] + w * us[k], p, 1e-12)


def _energy_gap(problem, run_a, run_c, p):
    ua = _solve_on_run(problem, *run_a, p)
    uc = _solve_on_run(problem, *run_c, p)
    if ua is None or uc is None:
        return math.nan
    problem.set(problem.parameter, p)
    return problem.energy(ua, p) - problem.energy(uc, p)


def _maxwell_points(result: BranchSet) -> list:
    """Parameter values where two stable equilibria have equal energy (the global minimum
    passes from one branch to the other), located by Brent on Newton-corrected energies."""
    problem = result.problem
    runs = [
        (b, (br, i, j))
        for b, br in enumerate(result.branches)
        if br.u is not None
        for i, j in _stable_runs(br)
    ]
    out = []
    for a in range(len(runs)):
        for c in range(a + 1, len(runs)):
            (ba, ra), (bc, rc) = runs[a], runs[c]
            pa = ra[0].p[ra[1] : ra[2] + 1]
            pc = rc[0].p[rc[1] : rc[2] + 1]
            lo, hi = max(pa.min(), pc.min()), min(pa.max(), pc.max())
            if not lo < hi:
                continue
            samples = np.linspace(lo, hi, 9)
            vals = [_energy_gap(problem, ra, rc, p) for p in samples]
            finite = [v for v in vals if math.isfinite(v)]
            if finite and max(abs(v) for v in finite) < 1e-9:
                continue  # mirror images: equal energies everywhere
            for k in range(len(samples) - 1):
                v0, v1 = vals[k], vals[k + 1]
                if not (math.isfinite(v0) and math.isfinite(v1) and v0 * v1 < 0):
                    continue
                pm = brentq(
                    lambda p, ra=ra, rc=rc: _energy_gap(problem, ra, rc, p),
                    samples[k],
                    samples[k + 1],
                    xtol=1e-13,
                    rtol=1e-14,
                )
                ua = _solve_on_run(problem, *ra, pm)
                uc = _solve_on_run(problem, *rc, pm)
                out.append(
                    {
                        "value": float(pm),
                        "energy": float(problem.energy(ua, pm)),
                        "branches": [ba, bc],
                        "measures": [
                            float(problem.observables(ua, pm)["measure"]),
                            float(problem.observables(uc, pm)["measure"]),
                        ],
                    }
                )
    return out


def find_folds(scene: Scene, parameter: str = "drop.wetted_length", prange=None, **kw) -> list:
    """The limit points of every branch (see :func:`trace_branches`)."""
    return trace_branches(scene, parameter, prange, **kw).folds
