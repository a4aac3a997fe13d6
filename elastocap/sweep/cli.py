"""``elastocap sweep``: a phase diagram of impacts, resumable, on a local pool or a cluster.

``add_arguments(parser)`` registers the options on the subcommand's parser; ``run(args)``
runs it and returns the exit code (0; 1 if some runs raised). Bad input raises
:class:`~elastocap.scene.SceneError` or :class:`ValueError` naming the option, the value and
what is allowed, before anything is written (the command maps them to exit code 2).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from elastocap.cli_args import force_argument, load_scene_from_args, scene_arguments
from elastocap.io import atomic_path, check_output_folder, check_writable_file, write_text
from elastocap.jsonutil import jsonable
from elastocap.scene import SceneError, parse_override

__all__ = ["add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``elastocap sweep`` (the caller adds ``--json``)."""
    scene_arguments(parser)
    parser.add_argument(
        "--x",
        required=True,
        metavar="LO:HI:N",
        help="distances from the free end, in units of l_eg (scene units "
        "without gravity): N values from LO to HI",
    )
    grp = parser.add_mutually_exclusive_group(required=True)
    grp.add_argument(
        "--we",
        metavar="LO:HI:N",
        help="We^1/2 values (converted to Delta by the scene's spreading law)",
    )
    grp.add_argument(
        "--delta", metavar="LO:HI:N", help="wetted lengths Delta (scene units), instead of --we"
    )
    parser.add_argument(
        "--store",
        metavar="FILE",
        help="SQLite result store, shared and resumable (default: OUT/sweep.sqlite)",
    )
    parser.add_argument(
        "--workers", type=int, metavar="N", help="local worker processes (default: one per core)"
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on a dask cluster, e.g. tcp://10.0.0.1:8786 (needs the 'distributed' extra)",
    )
    parser.add_argument(
        "--refine",
        type=float,
        metavar="TOL",
        help="bisect the boundary on each x line to a bracket narrower than "
        "TOL (in We^1/2, or Delta with --delta)",
    )
    vgrp = parser.add_mutually_exclusive_group()
    vgrp.add_argument(
        "--verify",
        action="store_true",
        help="re-run both ends of every boundary bracket at 1.5x the edges and half the "
        "time step; report per line whether the bracket holds, and how far it moves",
    )
    vgrp.add_argument(
        "--converge",
        type=int,
        metavar="K",
        help="as --verify, and where a bracket moves, locate it at the finer level and "
        "verify that one at the next, up to K levels (1.5^K the edges)",
    )
    parser.add_argument(
        "--every-level",
        action="store_true",
        help="with --converge K: check a bracket that holds again at the next level too, "
        "up to K, so that every bracket is checked at K finer resolutions",
    )
    parser.add_argument(
        "--export",
        metavar="FILE",
        help="also write every run of the store as a table: FILE.csv or FILE.parquet "
        "(needs the 'export' extra: pandas, and pyarrow for parquet)",
    )
    parser.add_argument("--out", metavar="DIR", help="output directory (default: out/sweep-SCENE)")
    parser.add_argument(
        "--experiments",
        metavar="CSV",
        help="experimental points for the plot (columns x_over_leg, we_sqrt, outcome)",
    )
    parser.add_argument(
        "--progress",
        choices=("auto", "none", "text", "tqdm"),
        default="auto",
        help="progress on stderr (default: tqdm if installed)",
    )
    force_argument(parser)


def _validate(args):
    """Everything that can be refused, refused before any file is touched."""
    from elastocap.sweep.engine import (
        SWEPT_KEYS,
        check_sweep_resources,
        check_verify_levels,
        plan_sweep,
        store_resolution,
    )
    from elastocap.sweep.executors import MissingExtraError, check_scheduler, check_workers
    from elastocap.sweep.export import check_export
    from elastocap.sweep.grid import parse_range
    from elastocap.sweep.plot import load_experiments
    from elastocap.sweep.store import ResultStore, StoreError

    xs = parse_range(args.x, "--x")
    we = parse_range(args.we, "--we") if args.we is not None else None
    if we is not None and we[0] < 0.0:
        raise SceneError("--we", args.we, "expected We^1/2 >= 0 (the square root of the Weber "
                         "number of the impact)")
    delta = parse_range(args.delta, "--delta") if args.delta is not None else None
    for text in args.overrides:
        key, value = parse_override(text)
        if key in SWEPT_KEYS:
            raise SceneError(
                key, value, "set by the sweep on every point (--x, --we/--delta); remove this --set"
            )
    scene = load_scene_from_args(args)
    if "experiment" in scene.data:
        raise SceneError(
            "scene",
            args.scene,
            "an [experiment] scene fixes x and Delta through "
            "its SI inputs; sweep a dimensionless scene such as fig3-strip",
        )
    if we is not None and scene.spreading is None:
        raise ValueError(
            f"--we: got {args.we!r}; scene {scene.name!r} has no [spreading] law "
            "to convert We^1/2 to Delta; use --delta"
        )
    if args.workers is not None:
        check_workers(args.workers)
    if args.scheduler is not None:
        try:
            check_scheduler(args.scheduler)
        except MissingExtraError as err:
            raise ValueError(str(err)) from None
    if args.refine is not None and not (args.refine > 0 and math.isfinite(args.refine)):
        raise ValueError(f"--refine: got {args.refine!r}; expected a finite number > 0")
    levels = 0
    if args.converge is not None:
        levels = check_verify_levels(args.converge, minimum=1)
    elif args.verify:
        levels = 1
    if args.every_level and args.converge is None:
        raise ValueError("--every-level: needs --converge K (the levels to check every "
                         "bracket at)")
    export = check_export(args.export) if args.export else None
    experiments = load_experiments(args.experiments) if args.experiments else None
    out = Path(args.out) if args.out else Path("out") / f"sweep-{scene.name}"
    store = Path(args.store) if args.store else out / "sweep.sqlite"
    # a file, or not writable: refused before any run
    out = check_output_folder(out, "--out")
    store = check_writable_file(store, "--store")
    points, _, resolutions = plan_sweep(scene, xs, we_sqrts=we, deltas=delta,
                                        verify_levels=levels)
    # every run's memory and time steps at the finest level, smallest and largest Delta
    check_sweep_resources(scene, points, resolutions, getattr(args, "force", False))
    try:
        ResultStore.check(store, store_resolution(resolutions, scene))
    except StoreError as err:
        raise ValueError(f"--store: {err}") from None
    return scene, xs, we, delta, experiments, out, store, levels, export


def _print_text(rep: dict, files: list[str]) -> None:
    c = rep["counts"]
    var = "We^1/2" if rep["variable"] == "we_sqrt" else "Delta"
    res = rep["resolution"]
    print(
        f"{rep['scene']}: {c['runs']} runs ({c['computed']} computed, {c['cached']} from the "
        f"store), {c['skipped']} skipped, {c['failed']} failed, {c['undecided']} undecided, "
        f"{c['disagreements']} where the criteria disagree; {rep['wall_time_s']:.1f} s on "
        f"{rep['executor']}; resolution {res['n_edges']} edges, dt {res['dt']:.4g}"
    )
    if c.get("self_contact") is not None:
        print(f"  the rod touched itself in {c['self_contact']} of {c['runs']} runs")
    for s in rep["skipped"][:5]:
        print(
            f"  skipped x = {s['x_over_leg']:.6g}"
            + (f", We^1/2 = {s['we_sqrt']:.6g}" if s["we_sqrt"] is not None else "")
            + f", Delta = {s['wetted_length']:.6g}: {s['reason']}"
        )
    if c["skipped"] > 5:
        print(f"  ... {c['skipped'] - 5} more skipped (see --json)")
    for f in rep["failed"]:
        print(f"  FAILED x = {f['x_over_leg']:.6g}, Delta = {f['wetted_length']:.6g} "
              f"(level {f['level']}): {f['error']}")
    print(f"boundary in {var} (x in {rep['x_unit']}):")
    for b in rep["boundary"]:
        lo, hi = b["low"], b["high"]
        br = (
            f"[{lo:.6g}, {hi:.6g}]"
            if lo is not None and hi is not None
            else f"below {hi:.6g}"
            if hi is not None
            else f"above {lo:.6g}"
            if lo is not None
            else "-"
        )
        extra = ""
        if b["status"] == "non-monotonic":
            extra = "  changes at " + ", ".join(
                f"[{t['low']:.6g}, {t['high']:.6g}] {t['outcome_low']}->{t['outcome_high']}"
                for t in b["transitions"]
            )
        if b["status"] in ("undecided", "failed"):
            extra += f"  (decided runs: {b['decided_status']}"
            if b["undecided"]:
                extra += f"; {len(b['undecided'])} undecided, e.g. {b['undecided'][0]['reason']}"
            if b["failed"]:
                extra += f"; {len(b['failed'])} failed"
            extra += ")"
        if b.get("level"):
            extra += f"  [level {b['level']}: {b['n_edges']} edges]"
        v = b.get("verification")
        if v is not None:
            extra += "  " + _verification_text(v)
        print(f"  x = {b['x']:<8.6g} {b['status']:<17} {br}{extra}")
    for f in files:
        print(f"wrote {f}")


def _verification_text(v: dict) -> str:
    s = v["status"]
    what = "" if v.get("checked", "bracket") == "bracket" else "threshold "
    levels = len(v.get("checks", []))
    if s == "holds":
        return (f"{what}verified: holds at 1.5x the edges"
                + (f" and at {levels - 1} finer level(s)" if levels > 1 else ""))
    if s == "holds-at-finer":
        return (f"{what}verified: holds from level {v['holds_at_level']} on "
                "(NOT at the sweep's)")
    if s == "not-applicable":
        return f"NOT verified: {v.get('reason', '')}"
    if v.get("shift") is not None:
        return f"NOT verified: {s}, the bracket midpoint moves by {v['shift']:+.4g}"
    return f"NOT verified: {s}"


def run(args) -> int:
    """Run ``elastocap sweep``; return 0, or 1 when some runs raised (reported)."""
    from elastocap.sweep.engine import run_sweep
    from elastocap.sweep.plot import plot_phase_diagram
    from elastocap.sweep.progress import make_progress

    scene, xs, we, delta, experiments, out, store, levels, export = _validate(args)
    progress = make_progress(args.progress)
    if args.progress != "none" and args.scheduler is None and args.workers != 0:
        # the local workers' compilation is not visible here: say that it happens
        print("sweep: the local workers compile the impact stepper on first use (up to "
              "about a minute each on a cold cache; cached after)", file=sys.stderr)
    result = run_sweep(
        scene,
        xs,
        we_sqrts=we,
        deltas=delta,
        store=store,
        refine_tol=args.refine,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=progress,
        verify_levels=levels,
        verify_every_level=args.every_level,
        overrides=list(args.overrides)
        + ([f"numerics.accuracy={args.accuracy}"] if getattr(args, "accuracy", None) else []),
        force=getattr(args, "force", False),
    )
    rep = jsonable(result.to_dict())
    out.mkdir(parents=True, exist_ok=True)
    png = out / "phase-diagram.png"
    with atomic_path(png) as tmp:
        plot_phase_diagram(rep, tmp, experiments=experiments)
    js = out / "sweep.json"
    files = [str(store), str(js), str(png)]
    if export is not None:
        from elastocap.sweep.export import export_runs

        export_runs(store, export)
        files.append(str(export))
    rep["files"] = files
    write_text(js, json.dumps(rep, indent=1))
    if getattr(args, "json", False):
        print(json.dumps(rep, indent=1))
    else:
        _print_text(rep, files)
    if rep["failed"]:
        print(
            f"elastocap: {len(rep['failed'])} runs failed (recorded with the reason in the "
            "store's failures table); the next run of the same sweep retries them",
            file=sys.stderr,
        )
        return 1
    return 0
