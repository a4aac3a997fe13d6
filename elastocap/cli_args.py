"""Command-line options shared by every command that takes a scene (used by elastocap.cli
and elastocap.sweep.cli): the scene, ``--set KEY=VALUE`` and ``--accuracy``."""

from __future__ import annotations

import argparse

from elastocap.scene import Numerics, Scene, SceneError, load_scene

__all__ = [
    "MEMORY_LIMIT",
    "STEPS_LIMIT",
    "check_resources",
    "force_argument",
    "impact_estimate",
    "load_scene_from_args",
    "run_suffix",
    "scene_arguments",
    "statics_estimate",
]


def scene_arguments(p: argparse.ArgumentParser, default: str | None = None) -> None:
    """Add the scene (positional; optional when ``default`` is given), --set, --accuracy."""
    if default is None:
        p.add_argument("scene", help="built-in scene name or path to a TOML file")
    else:
        p.add_argument("scene", nargs="?", default=default, help=f"scene (default: {default})")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scene key, e.g. --set drop.area=1.0 (repeatable)",
    )
    p.add_argument(
        "--accuracy",
        choices=("draft", "default", "publication"),
        help="resolution and tolerance preset (same as --set numerics.accuracy=...)",
    )


def load_scene_from_args(args) -> Scene:
    """The scene of a command: name or path, --set overrides, --accuracy."""
    over = list(args.overrides)
    if getattr(args, "accuracy", None):
        for o in over:
            key, _, value = o.partition("=")
            if key.strip() == "numerics.accuracy" and value.strip().strip("'\"") != args.accuracy:
                raise SceneError("--accuracy", args.accuracy,
                                 f"--set {o.strip()} says otherwise; give one of the two")
        over.append(f"numerics.accuracy={args.accuracy}")
    return load_scene(args.scene, over)


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


#: Hex digits of the digest in a run's file or folder name (``-s`` + these).
SUFFIX_DIGITS = 7


def run_suffix(args, scene: Scene, named=(), extra=None) -> str:
    """The part of an output name that tells apart runs of one scene which differ in values
    the name does not already carry: ``""`` when the scene's validated values equal the
    named scene's (``args.scene`` without ``--set``/``--accuracy``; for a scene file, the
    built-in scene of its name, else none) outside the ``named``
    keys and ``extra`` is empty; else ``"-s"`` + the first SUFFIX_DIGITS hex digits of the
    SHA-256 of the differing values (``canonical`` scene values, so ``0.1``, ``0.10`` and
    ``1e-1`` name the same run) and of ``extra`` (other options that change the result,
    e.g. ``--param``, ``--range``). The same command gives the same name (its re-run
    replaces its own outputs); runs that differ never share one."""
    import hashlib
    import json

    from elastocap.scene import builtin_scene_names

    # a scene file is held against the built-in scene of its name (its values may differ
    # under the same name), or against no scene at all: every value goes into the digest
    if args.scene in builtin_scene_names():
        base = _flat(load_scene(args.scene).canonical())
    elif scene.name in builtin_scene_names():
        base = _flat(load_scene(scene.name).canonical())
    else:
        base = {}
    mine = _flat(scene.canonical())
    diff = {k: mine.get(k) for k in sorted(set(base) | set(mine))
            if k not in named and base.get(k) != mine.get(k)}
    extra = {k: v for k, v in (extra or {}).items() if v is not None}
    if not diff and not extra:
        return ""
    text = json.dumps({"scene": diff, "options": extra}, sort_keys=True, default=repr,
                      separators=(",", ":"))
    return "-s" + hashlib.sha256(text.encode()).hexdigest()[:SUFFIX_DIGITS]


# ---------------------------------------------------------------------------------------------
# Resource guards: a run is estimated before it starts and refused, naming the key that makes
# it large, when it would need more than these (unless --force).

#: Memory a run may need (bytes): 2 GB.
MEMORY_LIMIT = 2 * 1024**3
#: Time steps an impact may take (the first attempt; an automatic dt may halve on retries).
STEPS_LIMIT = 10**8


def force_argument(p: argparse.ArgumentParser) -> None:
    """Add ``--force``: run even when the resource guards estimate a run above the limits."""
    p.add_argument(
        "--force",
        action="store_true",
        help=f"run even if the estimate exceeds {MEMORY_LIMIT / 1024**3:g} GB of memory or "
        f"{STEPS_LIMIT:.0e} time steps",
    )


def _gb(nbytes: float) -> str:
    return f"{nbytes / 1024**3:.3g} GB"


def impact_estimate(scene: Scene) -> dict:
    """Edges, time step, steps, frames and memory of an impact run, estimated up front
    without allocating anything of the run's size.

    Returns a dict with ``n_edges``, ``edge_key`` (the scene key that sets the edge count),
    ``dt``, ``steps``, ``frames``, ``memory_bytes``, ``refusal`` (None, or the
    (key, value, allowed) of the first limit exceeded) and ``invalid`` (the same for a run
    that cannot be made at all, whatever ``--force``).
    """
    from elastocap.impact import (
        FRAME_SPACING,
        MAX_FRAMES,
        edge_count,
        impact_settings,
    )
    from elastocap.impact import edge_key as impact_edge_key

    num = scene.numerics
    n = edge_count(scene)
    edge_key, edge_val = impact_edge_key(scene) or ("numerics.accuracy", num.accuracy)
    frames = min(MAX_FRAMES, int(num.t_max / FRAME_SPACING) + 1)
    # stored trajectory: positions and velocities (frames x (n+1) x 2 doubles each), plus
    # about 64 doubles per edge of working arrays
    memory = 8.0 * (4.0 * frames * (n + 1) + 64.0 * (n + 1))
    est = {"n_edges": n, "edge_key": edge_key, "frames": frames, "memory_bytes": memory,
           "dt": None, "steps": None, "refusal": None, "invalid": None}
    if memory > MEMORY_LIMIT:
        est["refusal"] = (
            edge_key,
            edge_val,
            f"an impact at {n:.4g} edges would need about {_gb(memory)} ({frames} frames of "
            f"positions and velocities), above the {_gb(MEMORY_LIMIT)} limit; use fewer "
            "edges, or pass --force",
        )
        return est
    if frames < 2:  # not a resource: no --force makes this run possible
        est["invalid"] = est["refusal"] = (
            "numerics.t_max",
            num.t_max,
            f"expected t_max >= {FRAME_SPACING:g} (an impact records a frame every "
            f"{FRAME_SPACING:g} time units and needs at least two)",
        )
        return est
    st = impact_settings(scene)
    dt = st["dt"]
    steps = num.t_max / dt
    est["dt"], est["steps"] = dt, steps
    if steps < 2:  # not a resource: a run of one step says nothing
        auto = "" if num.dt else (
            f" (the automatic time step of this rod at {n} edges, rod.bending_modulus = "
            f"{scene.rod.bending_modulus:g})"
        )
        est["invalid"] = est["refusal"] = (
            "numerics.t_max",
            num.t_max,
            f"expected t_max >= 2 dt = {2 * dt:.4g}{auto}",
        )
    elif steps > STEPS_LIMIT:
        default_t_max = Numerics().t_max
        if num.dt:
            key, val, fix = "numerics.dt", num.dt, "a larger dt (or 0 for automatic)"
        elif num.t_max > default_t_max and default_t_max / dt <= STEPS_LIMIT:
            key, val, fix = "numerics.t_max", num.t_max, "a smaller t_max"
        else:
            key, val, fix = edge_key, edge_val, "fewer edges (the stable dt scales as h^2)"
        est["refusal"] = (
            key,
            val,
            f"an impact would take about {steps:.3g} time steps (t_max = {num.t_max:g}, "
            f"dt = {dt:.3g} at {n:.4g} edges), above the {STEPS_LIMIT:.0e} limit; use {fix}, or "
            "pass --force",
        )
    return est


def statics_estimate(scene: Scene) -> dict:
    """Memory of a statics run (dense Jacobians of the collocation, and the stored branches),
    estimated up front. Returns ``memory_bytes`` and ``refusal`` (None or key, value, allowed).
    """
    num = scene.numerics
    if scene.effects.ground:
        from elastocap.impact import edge_count, edge_key

        # a float: a tiny Delta asks for more edges than an int converts to a float
        n = float(edge_count(scene))
        key, val = edge_key(scene) or ("numerics.n_edges", num.n_edges)
    else:
        from elastocap.statics.branches import ACCURACY_N, check_statics_scene

        check_statics_scene(scene)  # out of the resolved ranges: refused before any work

        n = num.cheb_points or ACCURACY_N[num.accuracy]
        key, val = "numerics.cheb_points", num.cheb_points
    # a few dense (n+2)^2 matrices, and up to ~10 branches of max_steps states and tangents
    # (n + 2) * (n + 2), not ** 2: inf, not an OverflowError, at an absurd n
    memory = 8.0 * (8.0 * (n + 2) * (n + 2) + 10.0 * 2.0 * num.max_steps * (n + 2))
    refusal = None
    if memory > MEMORY_LIMIT:
        if 8.0 * 8.0 * (n + 2) * (n + 2) <= MEMORY_LIMIT / 2:
            key, val = "numerics.max_steps", num.max_steps
        refusal = (
            key,
            val,
            f"the statics would need about {_gb(memory)} at {n:.4g} points and up to "
            f"{num.max_steps} continuation steps, above the {_gb(MEMORY_LIMIT)} limit; lower "
            "it, or pass --force",
        )
    return {"n": n, "memory_bytes": memory, "refusal": refusal}


def check_resources(scene: Scene, kind: str, force: bool = False) -> dict:
    """Refuse (SceneError naming the key) a run estimated above the limits, unless ``force``.

    ``kind`` is ``"impact"`` or ``"statics"``. Returns the estimate.
    """
    est = impact_estimate(scene) if kind == "impact" else statics_estimate(scene)
    if est.get("invalid") is not None:
        raise SceneError(*est["invalid"])
    if est["refusal"] is not None and not force:
        raise SceneError(*est["refusal"])
    return est
