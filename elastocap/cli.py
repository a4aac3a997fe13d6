"""The ``elastocap`` command: parsing and printing only; the work is in the library.

Every subcommand takes ``--json`` (one JSON object on stdout). Bad input exits with code 2
and a one-line message on stderr, and writes nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from elastocap._version import __version__
from elastocap.cli_args import check_resources, force_argument, run_suffix
from elastocap.cli_args import load_scene_from_args as _load
from elastocap.cli_args import scene_arguments as _scene_args
from elastocap.io import OutputFolder
from elastocap.jsonutil import is_finite_number, jsonable
from elastocap.scene import SceneError, builtin_scene_names, load_scene

DEFAULT_SCENE = "supp-fig5"


class UsageError(Exception):
    """A command-line input error: exit code 2, message on stderr."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would print usage and exit itself
        if message.endswith("expected one argument"):
            # a value that starts with "-" (a negative bound) reads as an option
            message += " (a value starting with '-' is written with '=', e.g. --range=-1)"
        raise UsageError(message)


def _print_json(obj) -> None:
    print(json.dumps(jsonable(obj), indent=2, sort_keys=False))


def _fmt_block(title: str, d: dict, indent: int = 2) -> list[str]:
    lines = [f"{title}:"]
    for k, v in d.items():
        if isinstance(v, dict):
            lines += [" " * indent + line for line in _fmt_block(k, v, indent)]
        elif isinstance(v, float):
            lines.append(" " * indent + f"{k:<22} {v:.10g}")
        else:
            lines.append(" " * indent + f"{k:<22} {v}")
    return lines


def cmd_scenes(args) -> int:
    names = builtin_scene_names()
    if args.json:
        _print_json(
            {"scenes": [{"name": n, "description": load_scene(n).description} for n in names]}
        )
    else:
        for n in names:
            desc = load_scene(n).description.split(". ")[0]
            print(f"{n:<18} {desc}")
    return 0


def cmd_show(args) -> int:
    scene = _load(args)
    summary = scene.summary()
    summary["version"] = __version__
    if args.json:
        _print_json(summary)
        return 0
    print(f"scene {scene.name}  (elastocap {__version__})")
    if scene.description:
        print("  " + " ".join(scene.description.split()))
    for key in ("rod", "drop", "effects", "spreading", "numerics", "derived"):
        if summary[key] is not None:
            print("\n".join(_fmt_block(key, summary[key])))
    return 0


def _out_dir(args, default_name: str) -> Path:
    if args.out is not None and not args.out.strip():
        raise UsageError(f"--out: got {args.out!r}; expected a folder (omit --out for "
                         f"out/{default_name})")
    return Path(args.out) if args.out else Path("out") / default_name


def _out_folder(args, default_name: str, kind: str) -> OutputFolder:
    """The run's output folder, its permissions checked now (before the work)."""
    return OutputFolder(_out_dir(args, default_name), kind)


def _stem_value(v: float) -> str:
    """A parameter value as it appears in a file name (6 significant digits)."""
    return f"{v:.6g}"


def _inexact(**values) -> dict:
    """The values whose :func:`_stem_value` does not read back as the value (their exact
    ``repr``): for the name's digest, so that values equal to 6 digits name different
    files."""
    return {k: repr(float(v)) for k, v in values.items() if float(_stem_value(v)) != v}


def _progress(args, label: str):
    """The command's progress reporter on stderr (``--progress``; none without the option)."""
    from elastocap.progress import make_progress

    return make_progress(getattr(args, "progress", "none"), label=label, unit="steps",
                         every=0.0)


def _trace(args, scene=None, progress=None, step=(0, 0)):
    from elastocap.progress import NoProgress, heartbeat
    from elastocap.statics.branches import trace_branches

    scene = _load(args) if scene is None else scene
    check_resources(scene, "statics", getattr(args, "force", False))
    progress = NoProgress() if progress is None else progress
    prange = tuple(args.range) if args.range else None
    note = f"tracing the branches of {scene.name} in {args.param} (compiles on first use)"
    strip = scene.effects.gravity > 0 or scene.effects.ground
    # bad input is refused before the first progress line (one line on stderr)
    if strip:
        # the strip on the ground: one model (the discrete strip, every contact topology)
        from elastocap.strip.trace import check_trace_request, trace_contact_branches
    else:
        from elastocap.statics.branches import check_trace_request
    check_trace_request(scene, args.param, prange)
    with heartbeat(progress, *step, note):
        if strip:
            return trace_contact_branches(scene, args.param, prange,
                                          progress=lambda line: progress(*step, line))
        return trace_branches(scene, args.param, prange)


def _warn_statics(bs) -> None:
    """The warnings of a traced branch set on stderr: what the model leaves out of the
    scene (a thickness), and one line per special point bracketed but not located (the
    report and the JSON list them too, under ``unlocated``)."""
    if bs.metadata.get("contact_note"):
        print(f"elastocap: warning: {bs.metadata['contact_note']}", file=sys.stderr)
    for u in getattr(bs, "unlocated", ()):
        hint = f"; {u['what_to_try']}" if u.get("what_to_try") else ""
        print(f"elastocap: warning: {u.get('kind', 'point')} near {u['value']:.6g} not "
              f"located: {u.get('reason', 'no reason recorded')}{hint}", file=sys.stderr)


def _warn_undecided(delta, outcome, reason) -> None:
    """The warning line of an undecided impact among several (``impact`` says it alone)."""
    if outcome == "undecided":
        print(f"elastocap: warning: impact at Δ = {delta:g}: outcome undecided: {reason}",
              file=sys.stderr)


def _fold_report(bs) -> dict:
    """The special points of a branch set (its summary without the per-branch lines)."""
    return {k: v for k, v in bs.summary().items() if k != "branches"}


def _print_folds(bs) -> None:
    print(bs.report())


def _trace_or_fail(args, scene=None, progress=None, step=(0, 0)):
    """``_trace``; a statics failure (no branch found) is a diagnosed exit 1, not bad input."""
    from elastocap.statics.branches import StaticsError

    try:
        return _trace(args, scene, progress, step)
    except StaticsError as err:
        print(f"elastocap: statics failed: {err}", file=sys.stderr)
        return None


def cmd_branches(args) -> int:
    scene = _load(args)
    # the default folder tells apart runs of one scene in another --set, --param, --range
    suffix = run_suffix(args, scene, extra={
        "param": None if args.param == "drop.wetted_length" else args.param,
        "range": list(args.range) if args.range else None})
    folder = _out_folder(args, f"branches-{scene.name}{suffix}", "branches")
    progress = _progress(args, "branches")
    bs = _trace_or_fail(args, scene, progress, (0, 2))
    if bs is None:
        return 1
    _warn_statics(bs)
    progress(1, 2, f"{len(bs.branches)} branches traced; writing the files and the figure")
    paths = bs.save(folder)
    paths.append(folder.savefig(lambda path: bs.plot(path), "branches.png"))
    progress(2, 2, "done")
    progress.close()
    out = folder.path
    if args.json:
        rep = _fold_report(bs)
        rep["files"] = [str(p) for p in paths]
        _print_json(rep)
    else:
        _print_folds(bs)
        print(f"wrote {len(paths)} files to {out}/")
    return 0


def _folds_curve(args, expected, rtol) -> int:
    """``folds SCENE --curve KEY LO HI``: fold curves, cusps, the bistability region."""
    from elastocap.statics.bistability import fold_curve_report, plot_bistability
    from elastocap.testing import compare_folds

    key, lo, hi = args.curve
    try:
        lo, hi = float(lo), float(hi)
    except ValueError:
        raise UsageError(f"--curve: got {args.curve}; expected KEY LO HI (numbers)") from None
    scene = _load(args)
    # checked before the work: a file, or a folder that cannot be written, is refused now
    folder = (_out_folder(args, "", f"fold-curves-{scene.name}") if args.out is not None
              else None)
    rep = fold_curve_report(scene, key, (lo, hi))
    bs, curves = rep.pop("_objects")
    files = []
    if folder is not None:
        files = [str(folder.write_json(f"fold-curves-{scene.name}.json", rep)),
                 str(folder.savefig(lambda path: plot_bistability(scene, bs, curves, key, path),
                                    f"fold-curves-{scene.name}.png"))]
        rep["files"] = files
    ok = True
    if expected is not None:
        ok, table = compare_folds(rep["cusps"], expected, rtol, rep["unlocated"])
        table = table.replace("all folds match", "all cusps match").replace(
            "folds differ", "cusps differ")
    if args.json:
        _print_json({**({"match": ok, "rtol": rtol} if expected is not None else {}), **rep})
    elif expected is not None:
        print(table)
    else:
        print(f"{scene.name}: {len(curves)} fold curves in {key} over [{lo:g}, {hi:g}] "
              f"(N={rep['metadata']['N']}, {rep['metadata']['wall_time_s']:.2f} s)")
        for c in rep["cusps"]:
            err = c["error_estimate"]
            print(f"  cusp          {key} = {c['value']:.12f}  "
                  f"{'(not estimated)' if err is None else f'± {err:.1e}'}  "
                  f"at Δ = {c['drop.wetted_length']:.10f}")
        for u in rep["unlocated"]:
            print(f"  NOT LOCATED   cusp near {u['value']:.6g}: {u['reason']}; "
                  f"{u['what_to_try']}")
        for f in files:
            print(f"wrote {f}")
    return 0 if ok else 1


def cmd_folds(args) -> int:
    from elastocap.testing import DEFAULT_RTOL, check_rtol, compare_folds, load_folds

    rtol = check_rtol(DEFAULT_RTOL if args.rtol is None else args.rtol, "--rtol")
    if args.rtol is not None and not args.check:
        raise UsageError(f"--rtol: got {args.rtol!r}; it is the tolerance of --check FILE, "
                         "which is not given")
    if args.curve:
        # bad reference file: exit 2 before any work
        expected = load_folds(args.check, key="cusps") if args.check else None
        return _folds_curve(args, expected, rtol)
    if args.out:
        raise UsageError("--out: only with --curve (use `elastocap branches --out` for "
                         "branch files)")
    # a bad file, or one made for another scene or parameter: exit 2 before any work
    expected = load_folds(args.check, made_for={"scene": _load(args).name,
                                                "parameter": args.param}) \
        if args.check else None
    progress = _progress(args, "folds")
    bs = _trace_or_fail(args, progress=progress, step=(0, 1))
    if bs is None:
        return 1
    progress(1, 1, f"folds located: {len(bs.folds)}")
    progress.close()
    _warn_statics(bs)
    if expected is not None:
        ok, table = compare_folds(bs.folds, expected, rtol, getattr(bs, "unlocated", ()))
        if args.json:
            _print_json({"match": ok, "rtol": rtol, "expected": expected, **_fold_report(bs)})
        else:
            print(table)
        return 0 if ok else 1
    if args.json:
        _print_json(_fold_report(bs))
    else:
        _print_folds(bs)
    return 0


def _announce_compiles():
    """Show dynamics' announcements of a first compilation on stderr (a logging handler
    on the "dynamics" logger, for this command only)."""
    import logging

    logger = logging.getLogger("dynamics")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("elastocap: %(message)s"))
    logger.addHandler(handler)
    if logger.level == logging.NOTSET or logger.level > logging.INFO:
        logger.setLevel(logging.INFO)
    return logger, handler


class _CompilesAnnounced:
    """``with _CompilesAnnounced():`` the announcements of a first compilation (the
    "dynamics" logger) reach stderr for the duration of a command."""

    def __enter__(self):
        self.logger, self.handler = _announce_compiles()
        return self

    def __exit__(self, *exc):
        self.logger.removeHandler(self.handler)
        return False


def cmd_impact(args) -> int:
    from dynamics.cache import CacheError
    from elastocap.impact import run_impact

    scene = _load(args)
    if args.frames is not None and not 2 <= args.frames <= 200:
        raise UsageError(f"--frames: got {args.frames}; expected an integer from 2 to 200")
    check_resources(scene, "impact", args.force)
    # the values that distinguish impacts of one scene: Delta and the drop's place x, and
    # a digest of every other value set by --set / --accuracy (none: no digest)
    stem = (
        f"impact-{scene.name}-delta{_stem_value(scene.drop.wetted_length)}"
        f"-x{_stem_value(scene.distance_from_end)}"
        + run_suffix(args, scene, named=("drop.wetted_length", "drop.distance_from_end",
                                         "drop.center", "drop.s1", "drop.s2"),
                     extra=_inexact(delta=scene.drop.wetted_length, x=scene.distance_from_end))
    )
    folder = _out_folder(args, f"impact-{scene.name}", stem)
    from elastocap.progress import heartbeat

    progress = _progress(args, "impact")
    logger, handler = _announce_compiles()
    try:
        with heartbeat(progress, 0, 2, f"running the impact of {scene.name}"):
            res = run_impact(scene)
    except CacheError as err:
        raise UsageError(str(err)) from None
    finally:
        logger.removeHandler(handler)
    progress(1, 2, f"{res.outcome} after {res.steps} steps; writing the files and the figure")
    rep = res.to_dict()
    from elastocap.frames import frame_strip

    meta = {**rep, "scene": scene.data, "scene_name": scene.name,
            "parameters": {"drop.wetted_length": scene.drop.wetted_length,
                           "drop.distance_from_end": scene.distance_from_end}}
    with folder.file(f"{stem}.npz") as tmp:
        res.simulation.save_npz(tmp, context=jsonable(meta))
    js = folder.write_json(f"{stem}.json", meta)
    png = folder.savefig(
        lambda path: frame_strip(res, scene, path, k=args.frames or 8), f"{stem}-frames.png"
    )
    rep["files"] = [str(folder.path / f"{stem}.npz"), str(js), str(png)]
    progress(2, 2, "done")
    progress.close()
    if args.json:
        _print_json(rep)
    else:
        print(f"{scene.name}: {res.outcome} ({res.criterion})")
        print(
            f"  final measure {res.final_measure:.6f}, t_end {res.t_end:.4g}, {res.steps} "
            f"steps, run {res.run_time_s:.2f} s (+ compile/load {res.compile_time_s:.2f} s), "
            f"{res.status}"
        )
        for r in res.settings.get("rest_repeats", []):
            print(f"  at rest at t = {r['t_end']:.4g} on a turn of a slow swing (half-period "
                  f"{r['swing_half_period']:.3g}): run again with a rest test of kinetic "
                  f"energy {r['rest_kinetic']:.3g} for {r['rest_time']:.4g}")
        if res.self_contact:  # rod.thickness > 0
            c = res.self_contact
            made = res.simulation.stats.get("steps_all_runs", res.steps)
            print(f"  self-contact: touching in {c['steps']} of {made} steps, up to "
                  f"{c['max_active']} "
                  f"contacts at once, gap error {c['gap_error']:.2g} of the thickness, "
                  f"{c['failures']} failures")
        crossed = []
        if res.rod_crossing_time is not None:
            why = ("its self-contact did not hold it" if res.self_contact
                   else "without rod.thickness the model has no self-contact")
            crossed.append(f"the rod crosses itself at t = {res.rod_crossing_time:.6g} "
                           f"({why})")
        if res.interface_crossing_time is not None:
            crossed.append(f"the drop's interface crosses the rod at t = "
                           f"{res.interface_crossing_time:.6g} (drop.interface_contact = "
                           f"{res.interface_contact})")
        if crossed:
            print("  flagged: " + "; ".join(crossed))
        for f in rep.get("files", []):
            print(f"  wrote {f}")
    if res.interface_touches:  # the drop's interface met the rod (drop.interface_contact)
        from elastocap.impact import touch_note

        scale = scene.drop.line_tension * scene.drop.wetted_length
        print(f"elastocap: warning: drop.interface_contact = {res.interface_contact}: "
              + touch_note(res.interface_touches, scale), file=sys.stderr)
    if res.outcome == "undecided":
        print(f"elastocap: warning: outcome undecided: {res.undecided_reason}", file=sys.stderr)
    if res.outcome == "failed":  # a numerical failure: diagnosed, exit 1 (not bad input)
        print(f"elastocap: impact failed: {res.message}", file=sys.stderr)
        return 1
    return 0


def cmd_figures(args) -> int:
    from elastocap.paper_figures import FIGURES, run_figures

    if args.only and args.only not in FIGURES:
        raise UsageError(f"--only: got {args.only!r}; expected one of {', '.join(FIGURES)}")
    folder = _out_folder(args, "figures", "figures")
    from elastocap.progress import heartbeat

    written = {}
    names = [n for n in FIGURES if not args.only or n == args.only]
    progress = _progress(args, "figures")
    for k, name in enumerate(names):
        # figures that resume from their own earlier output write straight into the folder
        with heartbeat(progress, k, len(names), f"drawing {name}"), _CompilesAnnounced():
            paths = run_figures(folder.path, only=name, fast=args.fast)[name]
        # each figure owns its own files: --only one figure leaves the others alone
        written[name] = OutputFolder(folder.path, f"figure-{name}").adopt(paths)
    progress(len(names), len(names), "done")
    progress.close()
    if args.json:
        _print_json({"figures": {k: [str(p) for p in v] for k, v in written.items()}})
    else:
        for k, v in written.items():
            print(f"{k}: " + ", ".join(str(p) for p in v))
    return 0


def cmd_overlay(args) -> int:
    from elastocap.overlay import run_overlay
    from elastocap.sweep.grid import parse_range

    scene = _load(args)
    deltas = parse_range(args.delta, "--delta")
    if len({_stem_value(d) for d in deltas}) < len(deltas):
        raise UsageError(f"--delta: got {args.delta}; its values must differ in their first 6 "
                         "significant digits (each impact's frames are a file named by Δ)")
    if deltas.max() > scene.rod.length:
        raise UsageError(
            f"--delta: got {args.delta}; expected values <= rod.length = {scene.rod.length}"
        )
    for d in (deltas.min(), deltas.max()):  # the edge count follows 1/Delta
        check_resources(scene.with_overrides({"drop.wetted_length": float(d)}), "impact",
                        args.force)
    check_resources(scene, "statics", args.force)
    stem = (f"overlay-{scene.name}-delta{_stem_value(deltas.min())}-"
            f"{_stem_value(deltas.max())}-{len(deltas)}"
            + run_suffix(args, scene, named=("drop.wetted_length",),
                         extra=_inexact(**{f"delta{k}": d for k, d in enumerate(deltas)})))
    folder = _out_folder(args, f"overlay-{scene.name}", stem)
    from elastocap.progress import heartbeat

    progress = _progress(args, "overlay")
    with heartbeat(progress, 0, 1, f"tracing the statics of {scene.name}, then {len(deltas)} "
                   "impacts (compiles on first use)"), _CompilesAnnounced():
        res = run_overlay(scene, deltas, None)
    progress(1, 1, "done")
    progress.close()
    for r in res["runs"]:
        _warn_undecided(r["wetted_length"], r["outcome"], r["undecided_reason"])
    from elastocap.overlay import plot_overlay

    res["files"] = [
        str(folder.savefig(lambda path: plot_overlay(res["branch_set"], res["runs"],
                                                     res["results"], path), f"{stem}.png")),
        str(folder.write_json(f"{stem}.json", {"scene": scene.data, "scene_name": scene.name,
                                               "parameter": "drop.wetted_length",
                                               "runs": res["runs"],
                                               "folds": res["branch_set"].folds})),
    ]
    if args.json:
        _print_json(
            {"runs": res["runs"], "files": res.get("files", []), "folds": res["branch_set"].folds}
        )
    else:
        for r in res["runs"]:
            print(
                f"  Δ = {r['wetted_length']:.4f}: {r['outcome']:<12} M = "
                f"{r['final_measure']:+.5f} -> "
                + (f"{r['branch_reached']} (shape distance {r['shape_distance']:.2e})"
                   if r["branch_reached"] else f"no equilibrium reached: {r['reach_note']}")
            )
        for f in res.get("files", []):
            print(f"wrote {f}")
    return 0


def cmd_demo(args) -> int:
    """The quick-start tour: branches of the default scene, two impacts on either side of
    the selection threshold, and the overlay of the impacts on the equilibria."""
    from elastocap.frames import frame_strip
    from elastocap.impact import run_impact
    from elastocap.overlay import reached_equilibrium
    from elastocap.statics.branches import trace_branches
    from elastocap.statics.plot import plot_branch_set

    scene = _load(args)
    check_resources(scene, "statics", args.force)
    check_resources(scene, "impact", args.force)
    folder = _out_folder(args, "demo", f"demo-{scene.name}")
    out = folder.path
    say = (lambda *a: None) if args.json else print
    say(f"elastocap {__version__}: the tour of scene {scene.name!r} -> {out}/")
    from elastocap.progress import heartbeat

    progress = _progress(args, "demo")
    with heartbeat(progress, 0, 4, "tracing the branches (compiles on first use)"), \
            _CompilesAnnounced():
        bs = trace_branches(scene)
    _print_folds(bs) if not args.json else None
    png = folder.savefig(lambda path: plot_branch_set(bs, path), f"{scene.name}-branches.png")
    files = [str(png)]
    fold = min((f["value"] for f in bs.folds), default=0.5 * scene.rod.length)
    deltas = [round(0.72 * fold, 3), round(min(scene.rod.length, 1.15 * fold), 3)]
    runs, results = [], []
    for d in deltas:
        sc = scene.with_overrides({"drop.wetted_length": d})
        check_resources(sc, "impact", args.force)
        with heartbeat(progress, 1 + len(runs), 4, f"impact at Δ = {d:g}"), \
                _CompilesAnnounced():
            r = run_impact(sc)
        reached = reached_equilibrium(bs, d, r)
        _warn_undecided(d, r.outcome, r.undecided_reason)
        runs.append(
            {
                "wetted_length": d,
                "outcome": r.outcome,
                "undecided_reason": r.undecided_reason,
                "final_measure": r.final_measure,
                **reached,
                "t_end": r.t_end,
                "wall_time_s": r.wall_time_s,
            }
        )
        results.append(r)
        strip = folder.savefig(lambda path, r=r, sc=sc: frame_strip(r, sc, path, k=8),
                               f"{scene.name}-impact-delta{_stem_value(d)}.png")
        files.append(str(strip))
        say(
            f"  impact at Δ = {d:g}: {r.outcome} (M = {r.final_measure:+.4f}, reaches "
            f"{reached['branch_reached'] or 'no equilibrium: ' + str(reached['reach_note'])}, "
            f"{r.wall_time_s:.1f} s)"
        )
    from elastocap.overlay import plot_overlay

    progress(3, 4, "drawing the overlay")
    ov = folder.savefig(lambda path: plot_overlay(bs, runs, results, path),
                        f"{scene.name}-overlay.png")
    files.append(str(ov))
    progress(4, 4, "done")
    progress.close()
    if args.json:
        _print_json({**_fold_report(bs), "impacts": runs, "files": files})
    else:
        for f in files:
            print(f"wrote {f}")
    return 0


def _load_impact(npz: Path):
    """An impact result and its scene from the ``.npz`` that ``elastocap impact`` writes."""
    from dynamics import SimulationResult
    from elastocap.geometry import turning_measures
    from elastocap.impact import ImpactResult
    from elastocap.scene import build_scene

    try:
        ctx = SimulationResult.load_npz_context(npz)
        sim = SimulationResult.load_npz(npz)
    except (OSError, ValueError, KeyError) as err:
        raise UsageError(f"PATH: got {str(npz)!r}; not an impact file ({err})") from None
    if not isinstance(ctx, dict) or "scene" not in ctx or "outcome" not in ctx:
        raise UsageError(f"PATH: got {str(npz)!r}; not an impact file written by elastocap "
                         "impact (no scene recorded)")
    scene = build_scene(ctx["scene"], ctx.get("scene_name", npz.stem))
    bad = _impact_file_problem(ctx, sim)
    if bad:
        raise UsageError(f"PATH: got {str(npz)!r}; not an impact file as elastocap impact "
                         f"writes it: {bad}")
    fields = {k: ctx[k] for k in ImpactResult.__dataclass_fields__ if k in ctx}
    res = ImpactResult(**fields, simulation=sim, measure_history=turning_measures(sim.positions))
    return res, scene


def _impact_file_problem(ctx: dict, sim) -> str:
    """What makes a loaded impact file inconsistent ("" when nothing): an outcome the run
    cannot have, a node count other than its settings', non-finite frames."""
    from elastocap.criteria import OUTCOMES

    if ctx.get("outcome") not in OUTCOMES:
        return f"outcome {ctx.get('outcome')!r} (expected one of {', '.join(OUTCOMES)})"
    n = (ctx.get("settings") or {}).get("n_edges")
    if isinstance(n, int) and sim.positions.shape[1] != n + 1:
        return (f"positions of {sim.positions.shape[1]} nodes where its settings say "
                f"{n} edges")
    import numpy as np

    if not np.all(np.isfinite(sim.positions)):
        return "non-finite positions"
    fm = ctx.get("final_measure")
    if ctx["outcome"] != "failed" and not is_finite_number(fm):
        return f"final_measure {fm!r} (expected a finite number)"
    return ""


def cmd_plot(args) -> int:
    """Redraw a saved result without recomputing it."""
    path = Path(args.path)
    if args.frames is not None and not 2 <= args.frames <= 200:
        raise UsageError(f"--frames: got {args.frames}; expected an integer from 2 to 200")
    if path.is_dir() and (path / "branches.json").is_file():
        kind, src = "branches", path / "branches.json"
    elif path.is_dir() and (path / "sweep.json").is_file():
        kind, src = "sweep", path / "sweep.json"
    elif path.is_file() and path.name == "branches.json":
        kind, src = "branches", path
    elif path.is_file() and path.suffix == ".npz" and not path.name.startswith("branch_"):
        kind, src = "impact", path
    elif path.is_file() and path.name == "sweep.json":
        kind, src = "sweep", path
    elif path.is_file() and path.suffix == ".sqlite":
        # the report its run wrote beside the store, else one rebuilt from the store alone
        src = path.parent / "sweep.json"
        kind, src = ("sweep", src) if src.is_file() else ("store", path)
    else:
        raise UsageError(
            f"PATH: got {str(path)!r}; expected a branches folder (with branches.json), an "
            "impact .npz, a sweep folder (with sweep.json) or a sweep store (.sqlite)"
        )
    # read and check the input before anything is written
    if kind == "branches":
        from elastocap.branchset import BranchSet

        try:
            bs = BranchSet.load(src)
        except ValueError as err:
            raise UsageError(f"PATH: {err}") from None
        draw, name = bs.plot, "branches.png"
        info = {"kind": kind, "scene": bs.scene.name, "branches": len(bs.branches)}
    elif kind == "impact":
        from elastocap.frames import frame_strip

        res, scene = _load_impact(src)
        def draw(p):
            return frame_strip(res, scene, p, k=args.frames or 8)

        name = f"{src.stem}-frames.png"
        info = {"kind": kind, "scene": scene.name, "outcome": res.outcome}
    else:
        from elastocap.sweep.plot import check_report, plot_phase_diagram
        from elastocap.sweep.store import StoreError

        if kind == "store":
            from elastocap.sweep.engine import report_from_store

            try:
                report = report_from_store(src)
            except StoreError as err:
                raise UsageError(f"PATH: {err}") from None
        else:
            try:
                report = json.loads(src.read_text(encoding="utf-8"))
            except (OSError, ValueError) as err:
                raise UsageError(f"PATH: got {str(src)!r}; not a readable sweep.json "
                                 f"({err})") from None
        check_report(report, str(src))  # a store's rows too: a damaged row is refused
        def draw(p):
            return plot_phase_diagram(report, p)

        name = "phase-diagram.png"
        info = {"kind": "sweep", "scene": report.get("scene")}
    folder = OutputFolder(args.out or src.parent, f"plot-{kind}-{src.stem}")
    png = folder.savefig(draw, name)
    if args.json:
        _print_json({**info, "files": [str(png)]})
    else:
        print(f"redrew {info['kind']} of {info['scene']}: wrote {png}")
    return 0


def cmd_sweep(args) -> int:
    from elastocap.sweep.cli import run

    with _CompilesAnnounced():  # what compiles in this process (a dask cluster's, local ones)
        return run(args)


def cmd_cache(args) -> int:
    """``cache info`` / ``cache clear``: the generated-stepper cache of dynamics."""
    from dynamics import cache

    try:
        if args.action == "clear":
            n = cache.clear()
            rep = {"directory": cache.cache_dir(create=False), "removed_modules": n}
        else:
            rep = cache.info()
    except cache.CacheError as err:
        raise UsageError(str(err)) from None
    if args.json:
        _print_json(rep)
    elif args.action == "clear":
        print(f"removed {rep['removed_modules']} generated stepper(s) from {rep['directory']}")
    else:
        print(f"generated steppers: {rep['directory']}")
        print(f"  {rep['modules']} module(s), {rep['bytes'] / 2**20:.1f} MB (limit "
              f"{rep['max_bytes'] / 2**20:.0f} MB, {rep['max_age_days']} days unused)")
        print(f"  numba's compiled code: {rep['numba_files']}")
    return 0


COMMANDS: dict[str, tuple[Callable, str]] = {
    "scenes": (cmd_scenes, "list the built-in scenes"),
    "show": (cmd_show, "print a validated scene and its derived quantities"),
    "branches": (cmd_branches, "trace every equilibrium branch; write .npz, JSON and a PNG"),
    "folds": (cmd_folds, "locate the folds (limit points); --check a reference file"),
    "impact": (cmd_impact, "run an impact to rest; its outcome and measures"),
    "overlay": (cmd_overlay, "impacts drawn on the equilibria; which branch each reaches"),
    "sweep": (cmd_sweep, "phase diagram of impacts over (x, We^1/2) or (x, Delta); resumable"),
    "figures": (cmd_figures, "regenerate the paper's figures"),
    "demo": (cmd_demo, "the quick-start tour on the default scene"),
    "cache": (cmd_cache, "the cache of compiled time steppers: info, or clear it"),
    "plot": (cmd_plot, "redraw a saved result (branches folder, impact .npz, sweep) "
             "without recomputing"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="elastocap", description="Elasto-capillary continuation and dynamics.")
    parser.add_argument("--version", action="version", version=f"elastocap {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (func, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(func=func)
        p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
        if name == "sweep":
            from elastocap.sweep.cli import add_arguments as sweep_arguments

            sweep_arguments(p)
        if name in ("show", "branches", "folds", "impact", "overlay"):
            _scene_args(p)
        elif name == "demo":
            _scene_args(p, default=DEFAULT_SCENE)
        if name in ("branches", "folds"):
            p.add_argument(
                "--param",
                default="drop.wetted_length",
                metavar="KEY",
                help="scene key to continue in (default drop.wetted_length)",
            )
            p.add_argument(
                "--range",
                nargs=2,
                type=float,
                metavar=("LO", "HI"),
                help="parameter range (default: (0.02 L, L) for the wetted length; "
                "(0.3, min(2.2, 1.95 x)) on the ground)",
            )
        if name in ("branches", "figures", "demo", "impact", "overlay"):
            default_out = {"branches": "out/branches-SCENE[-sDIGEST]", "figures": "out/figures",
                           "demo": "out/demo", "impact": "out/impact-SCENE",
                           "overlay": "out/overlay-SCENE"}[name]
            names = {
                "impact": "; files impact-SCENE-deltaD-xX[-sDIGEST].npz/.json/-frames.png",
                "branches": "",
            }.get(name)
            digest = ("" if names is None else
                      f"{names}; -sDIGEST (7 hex digits) appears when --set/--accuracy"
                      + ("/--param/--range" if name == "branches" else "")
                      + " change other values than the name's, or the name's values are "
                      "not exact to 6 digits; the same for the same values")
            p.add_argument(
                "--out", metavar="DIR",
                help=f"output directory (default: {default_out}){digest}"
            )
        if name in ("branches", "folds", "demo", "impact", "overlay"):
            force_argument(p)
        if name in ("branches", "folds", "demo", "impact", "overlay", "figures"):
            p.add_argument(
                "--progress",
                choices=("auto", "none", "text", "tqdm"),
                default="auto",
                help="progress on stderr (default: a tqdm bar on a terminal, text lines "
                "otherwise)",
            )
        if name == "overlay":
            p.add_argument(
                "--delta",
                required=True,
                metavar="LO:HI:N",
                help="wetted lengths Delta of the impacts: N values from LO to HI",
            )
        if name == "folds":
            p.add_argument(
                "--check",
                metavar="FILE",
                help="compare with a reference (the JSON of `folds --json`): "
                "exit 0 if every fold matches, 1 otherwise",
            )
            p.add_argument(
                "--rtol",
                type=float,
                default=None,
                help="relative tolerance of --check (default 1e-8)",
            )
            p.add_argument(
                "--curve",
                nargs=3,
                metavar=("KEY", "LO", "HI"),
                help="fold curves: continue every fold in KEY (e.g. drop.area) over [LO, HI]; "
                "locate every cusp; --out DIR writes the JSON and the bistability map; "
                "--check pins the cusps",
            )
            p.add_argument("--out", metavar="DIR",
                           help="with --curve: output directory for JSON and PNG")
        if name == "impact":
            p.add_argument(
                "--frames",
                type=int,
                metavar="K",
                help="frames in the PNG strip written with --out (default 8)",
            )
        if name == "cache":
            p.add_argument("action", choices=("info", "clear"), help="what to do")
        if name == "plot":
            p.add_argument("path", metavar="PATH", help="a branches folder, an impact .npz, "
                           "a sweep folder, or a sweep store (.sqlite; without its "
                           "sweep.json the diagram is rebuilt from the stored runs)")
            p.add_argument("--out", metavar="DIR",
                           help="where to write the figure (default: beside PATH)")
            p.add_argument("--frames", type=int, metavar="K",
                           help="frames of an impact's strip (default 8)")
        if name == "figures":
            p.add_argument("--only", metavar="NAME", help="one figure (e.g. supp-fig6)")
            p.add_argument("--fast", action="store_true", help="coarse and quick (for tests)")
    return parser


def command_options(parser: argparse.ArgumentParser | None = None) -> dict[str, list[str]]:
    """Every subcommand of the parser and its options (``--x`` forms, ``-h`` left out): what
    the tests check the documented commands and the README's command table against."""
    parser = build_parser() if parser is None else parser
    out: dict[str, list[str]] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[name] = [
                    opt
                    for a in sub._actions
                    for opt in a.option_strings
                    if opt.startswith("--") and opt != "--help"
                ]
    return out


def _set_note(err, args) -> str:
    """For a refusal of a key the command line did not set (a check of derived or related
    values), the ``--set`` values it follows from: `` (with --set rod.length=1e300)``."""
    given = [o.strip() for o in getattr(args, "overrides", None) or ()]
    key = getattr(err, "key", None)
    if not (isinstance(err, SceneError) and given) or key.startswith("-") or any(
            o.split("=", 1)[0].strip() == key for o in given):
        return ""
    shown = [o if len(o) <= 60 else o[:57] + "..." for o in given[:3]]
    more = f" and {len(given) - 3} more" if len(given) > 3 else ""
    return f" (with --set {', '.join(shown)}{more})"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit code (0 ok, 1 check failed, 2 bad input, 130
    interrupted)."""
    parser = build_parser()
    args = None
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        return int(args.func(args))
    except (UsageError, SceneError, ValueError) as err:
        if type(err).__name__ == "LinAlgError":  # numpy's: a numerical failure, not input
            print(f"elastocap: error: numerical failure in a linear solve of "
                  f"`{getattr(args, 'command', '?')}`: {err}. Try another resolution "
                  "(numerics.*) or a narrower --range/--delta; if it persists, report the "
                  "command.", file=sys.stderr)
            return 1
        print(f"elastocap: error: {err}{_set_note(err, args)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`: not an error of ours
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's code for SIGINT
        resume = (" (the runs finished so far are in the store: the same command resumes)"
                  if getattr(args, "command", None) == "sweep" else "")
        print(f"elastocap: interrupted{resume}", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
