"""The ``elastocap`` command: parsing and printing only; the work is in the library.

Every subcommand takes ``--json`` (one JSON object on stdout). Bad input exits with code 2
and a one-line message on stderr, and writes nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from elastocap._version import __version__
from elastocap.cli_args import load_scene_from_args as _load
from elastocap.cli_args import scene_arguments as _scene_args
from elastocap.jsonutil import jsonable
from elastocap.scene import SceneError, builtin_scene_names, load_scene

DEFAULT_SCENE = "supp-fig5"


class UsageError(Exception):
    """A command-line input error: exit code 2, message on stderr."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would print usage and exit itself
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
    return Path(args.out) if args.out else Path("out") / default_name


def _trace(args):
    from elastocap.statics.branches import trace_branches

    scene = _load(args)
    prange = tuple(args.range) if args.range else None
    if scene.effects.gravity > 0 or scene.effects.ground:
        if args.param == "drop.wetted_length" and scene.effects.ground:
            # the strip on the ground, every contact topology (discrete strip)
            from elastocap.strip.contact_branches import trace_contact_branches

            progress = None
            if not args.json:
                def progress(label, br):
                    print(f"  traced {label}: {len(br.segments)} segments, {br.status}",
                          file=sys.stderr)
            return trace_contact_branches(scene, args.param, prange, progress=progress)
        # other parameters: one contact topology, the lift-off point as a free boundary
        from elastocap.strip.branches import trace_strip_branches

        return trace_strip_branches(scene, args.param, prange)
    return trace_branches(scene, args.param, prange)


def _fold_report(bs) -> dict:
    """The special points of a branch set (its summary without the per-branch lines)."""
    return {k: v for k, v in bs.summary().items() if k != "branches"}


def _print_folds(bs) -> None:
    if hasattr(bs, "report_lines"):
        print("\n".join(bs.report_lines()))
        return
    print(
        f"{bs.scene.name}: {len(bs.branches)} branches in {bs.parameter} over "
        f"[{bs.prange[0]:.6g}, {bs.prange[1]:.6g}] (N={bs.metadata['N']}, "
        f"{bs.metadata['wall_time_s']:.2f} s)"
    )
    note = bs.metadata.get("range_note")
    if note:
        print(f"  note: {note}")
    for f in bs.folds:
        err = f.get("error_estimate")
        err = "(not estimated)" if err is None else f"± {err:.1e}"
        print(
            f"  fold          {f['value']:.12f}  {err}  measure "
            f"{f['measure']:+.6f}  stability {f['stability_change']}"
        )
    for b in bs.branch_points:
        print(
            f"  branch point  {b['value']:.12f}            measure {b['measure']:+.6f}  "
            f"stability {b['stability_change']}"
        )
    for m in bs.maxwell_points:
        print(
            f"  equal energy  {m['value']:.12f}            measures "
            + ", ".join(f"{v:+.6f}" for v in m["measures"])
        )
    for e in getattr(bs, "endpoints", []):
        if e.get("kind") == "admissible_boundary":
            print(f"  branch end    {e['value']:.12f}            on the admissible boundary: "
                  f"{e['reason']}")
    for u in getattr(bs, "unlocated", []):
        print(f"  NOT LOCATED   {u['kind']} near {u['value']:.6g}: {u['reason']}; "
              f"{u['what_to_try']}")


def _trace_or_fail(args):
    """``_trace``; a statics failure (no branch found) is a diagnosed exit 1, not bad input."""
    from elastocap.statics.branches import StaticsError

    try:
        return _trace(args)
    except StaticsError as err:
        print(f"elastocap: statics failed: {err}", file=sys.stderr)
        return None


def cmd_branches(args) -> int:
    from elastocap.statics.plot import plot_branch_set

    bs = _trace_or_fail(args)
    if bs is None:
        return 1
    out = _out_dir(args, f"branches-{bs.scene.name}")
    paths = bs.save(out)
    png = out / "branches.png"
    if type(bs).__name__ == "ContactBranchSet":
        from elastocap.strip.plot import plot_contact_branch_set

        plot_contact_branch_set(bs, png)
    elif type(bs).__name__ == "StripBranchSet":
        from elastocap.strip.plot import plot_strip_branch_set

        plot_strip_branch_set(bs, png)
    else:
        plot_branch_set(bs, png)
    paths.append(png)
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
    import os
    import tempfile

    from elastocap.statics.bistability import fold_curve_report, plot_bistability
    from elastocap.testing import compare_folds

    key, lo, hi = args.curve
    try:
        lo, hi = float(lo), float(hi)
    except ValueError:
        raise UsageError(f"--curve: got {args.curve}; expected KEY LO HI (numbers)") from None
    scene = _load(args)
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():
        raise UsageError(f"--out: got {str(out)!r}; expected a directory")
    rep = fold_curve_report(scene, key, (lo, hi))
    bs, curves = rep.pop("_objects")
    files = []
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        js = out / f"fold-curves-{scene.name}.json"
        png = out / f"fold-curves-{scene.name}.png"
        for path, write in ((js, lambda f: f.write(json.dumps(jsonable(rep), indent=2))),):
            fd, tmp = tempfile.mkstemp(dir=out, suffix=".tmp")
            with os.fdopen(fd, "w") as f:
                write(f)
            os.replace(tmp, path)
        fd, tmp = tempfile.mkstemp(dir=out, suffix=".png")
        os.close(fd)
        plot_bistability(scene, bs, curves, key, tmp)
        os.replace(tmp, png)
        files = [str(js), str(png)]
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
    from elastocap.testing import DEFAULT_RTOL, compare_folds, load_folds

    rtol = DEFAULT_RTOL if args.rtol is None else args.rtol
    if not (rtol > 0 and math.isfinite(rtol)):
        raise UsageError(f"--rtol: got {rtol!r}; expected a finite number > 0")
    if args.curve:
        # bad reference file: exit 2 before any work
        expected = load_folds(args.check, "cusps") if args.check else None
        return _folds_curve(args, expected, rtol)
    if args.out:
        raise UsageError("--out: only with --curve (use `elastocap branches --out` for "
                         "branch files)")
    expected = load_folds(args.check) if args.check else None  # bad file: exit 2 before work
    bs = _trace_or_fail(args)
    if bs is None:
        return 1
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


def cmd_impact(args) -> int:
    from elastocap.impact import run_impact

    scene = _load(args)
    if args.frames is not None and args.frames < 2:
        raise UsageError(f"--frames: got {args.frames}; expected an integer >= 2")
    res = run_impact(scene)
    rep = res.to_dict()
    if args.out:
        from elastocap.frames import frame_strip

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        npz = out / f"impact-{scene.name}.npz"
        meta = {**rep, "scene": scene.data}
        res.simulation.save_npz(npz, context=jsonable(meta))
        (out / f"impact-{scene.name}.json").write_text(json.dumps(jsonable(meta), indent=2))
        png = out / f"impact-{scene.name}-frames.png"
        frame_strip(res, scene, png, k=args.frames or 8)
        rep["files"] = [str(npz), str(out / f"impact-{scene.name}.json"), str(png)]
    if args.json:
        _print_json(rep)
    else:
        print(f"{scene.name}: {res.outcome} ({res.criterion})")
        print(
            f"  final measure {res.final_measure:.6f}, t_end {res.t_end:.4g}, {res.steps} "
            f"steps, {res.wall_time_s:.2f} s, {res.status}"
        )
        if res.rod_crossing_time is not None or res.interface_crossing_time is not None:
            print(
                f"  flagged: rod crosses itself at t = {res.rod_crossing_time}, interface "
                f"crosses the rod at t = {res.interface_crossing_time} (the model has no "
                "contact between them)"
            )
        for f in rep.get("files", []):
            print(f"  wrote {f}")
    if res.outcome == "failed":  # a numerical failure: diagnosed, exit 1 (not bad input)
        print(f"elastocap: impact failed: {res.message}", file=sys.stderr)
        return 1
    return 0


def cmd_figures(args) -> int:
    from elastocap.paper_figures import FIGURES, run_figures

    if args.only and args.only not in FIGURES:
        raise UsageError(f"--only: got {args.only!r}; expected one of {', '.join(FIGURES)}")
    out = _out_dir(args, "figures")
    written = run_figures(out, only=args.only, fast=args.fast)
    if args.json:
        _print_json({"figures": {k: [str(p) for p in v] for k, v in written.items()}})
    else:
        for k, v in written.items():
            print(f"{k}: " + ", ".join(str(p) for p in v))
    return 0


def cmd_overlay(args) -> int:
    from elastocap.overlay import parse_range, run_overlay

    scene = _load(args)
    deltas = parse_range(args.delta, "--delta")
    if deltas.max() > scene.rod.length:
        raise UsageError(
            f"--delta: got {args.delta}; expected values <= rod.length = {scene.rod.length}"
        )
    res = run_overlay(scene, deltas, _out_dir(args, f"overlay-{scene.name}"))
    if args.json:
        _print_json(
            {"runs": res["runs"], "files": res.get("files", []), "folds": res["branch_set"].folds}
        )
    else:
        for r in res["runs"]:
            print(
                f"  Δ = {r['wetted_length']:.4f}: {r['outcome']:<12} M = "
                f"{r['final_measure']:+.5f} -> {r['branch_reached']} (shape distance "
                f"{r['shape_distance']:.2e})"
            )
        for f in res.get("files", []):
            print(f"wrote {f}")
    return 0


def cmd_demo(args) -> int:
    """The quick-start tour: branches of the default scene, two impacts on either side of
    the selection threshold, and the overlay of the impacts on the equilibria."""
    from elastocap.frames import frame_strip
    from elastocap.impact import run_impact
    from elastocap.overlay import classify_final_state
    from elastocap.statics.branches import trace_branches
    from elastocap.statics.plot import plot_branch_set

    scene = _load(args)
    out = _out_dir(args, "demo")
    out.mkdir(parents=True, exist_ok=True)
    say = (lambda *a: None) if args.json else print
    say(f"elastocap {__version__}: the tour of scene {scene.name!r} -> {out}/")
    bs = trace_branches(scene)
    _print_folds(bs) if not args.json else None
    png = out / f"{scene.name}-branches.png"
    plot_branch_set(bs, png)
    files = [str(png)]
    fold = min((f["value"] for f in bs.folds), default=0.5 * scene.rod.length)
    deltas = [round(0.72 * fold, 3), round(min(scene.rod.length, 1.15 * fold), 3)]
    runs, results = [], []
    for d in deltas:
        sc = scene.with_overrides({"drop.wetted_length": d})
        r = run_impact(sc)
        reached = classify_final_state(bs, d, r.simulation.positions[-1])
        runs.append(
            {
                "wetted_length": d,
                "outcome": r.outcome,
                "final_measure": r.final_measure,
                "branch_reached": reached and reached["label"],
                "t_end": r.t_end,
                "wall_time_s": r.wall_time_s,
            }
        )
        results.append(r)
        strip = out / f"{scene.name}-impact-delta{d:g}.png"
        frame_strip(r, sc, strip, k=8)
        files.append(str(strip))
        say(
            f"  impact at Δ = {d:g}: {r.outcome} (M = {r.final_measure:+.4f}, reaches "
            f"{reached and reached['label']}, {r.wall_time_s:.1f} s)"
        )
    from elastocap.overlay import plot_overlay

    ov = out / f"{scene.name}-overlay.png"
    plot_overlay(bs, runs, results, ov)
    files.append(str(ov))
    if args.json:
        _print_json({**_fold_report(bs), "impacts": runs, "files": files})
    else:
        for f in files:
            print(f"wrote {f}")
    return 0


def cmd_sweep(args) -> int:
    from elastocap.sweep.cli import run

    return run(args)


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
            p.add_argument("--out", metavar="DIR", help="output directory (default: out/...)")
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
        if name == "figures":
            p.add_argument("--only", metavar="NAME", help="one figure (e.g. supp-fig6)")
            p.add_argument("--fast", action="store_true", help="coarse and quick (for tests)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit code (0 ok, 1 check failed, 2 bad input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        return int(args.func(args))
    except (UsageError, SceneError, ValueError) as err:
        print(f"elastocap: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`: not an error of ours
        sys.stderr.close()
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
