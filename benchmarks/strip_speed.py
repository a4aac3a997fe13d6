"""Speed of `elastocap branches fig3-strip --set drop.distance_from_end=X`, side by side.

    python3 benchmarks/strip_speed.py [--x 2] [--n N] [--repeat 3] [--baseline SRC]
                                      [--save DIR] [--profile]

Runs the command itself (``python -m elastocap branches fig3-strip --set
drop.distance_from_end=X [--set numerics.n_edges=N] --json --out TMP``; default resolution:
n = 198 edges, refined at 297 for the error estimates) in a child process, ``--repeat``
times, and prints for each run its CPU time (user + system of the child, from
``os.wait4``: on a shared, loaded machine the comparable number) and its wall time, then
the medians. With ``--baseline SRC`` (another source tree, e.g. ``git archive main
elastocap continuation dynamics | tar -x -C /tmp/base``) the runs of the two trees
alternate (this tree, the baseline, this tree, ...), and the medians of both and their
ratios (baseline / this tree) are printed, with the window each computed.
``--save DIR`` keeps each run's JSON report as ``DIR/{tree}-x{X}-{k}.json`` (tree ``this``
or ``baseline``), to compare the two trees' folds, events and windows.
``--profile`` runs the trace once in this process under cProfile instead and prints the
25 most expensive functions (cumulative).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def run_cli(src: Path, x: float, n: int | None, save: Path | None = None) -> dict:
    """One run of the command from source tree ``src``: cpu, wall (s) and the window; the
    JSON report written to ``save`` if given."""
    with tempfile.TemporaryDirectory(prefix="strip-speed-") as tmp:
        argv = [sys.executable, "-m", "elastocap", "branches", "fig3-strip", "--set",
                f"drop.distance_from_end={x:g}", "--json", "--out", str(Path(tmp) / "b")]
        if n is not None:
            argv[7:7] = ["--set", f"numerics.n_edges={n}"]
        env = {**os.environ, "PYTHONPATH": str(src)}
        t = time.perf_counter()
        proc = subprocess.Popen(argv, cwd=tmp, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True)
        out = proc.stdout.read()
        _pid, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{src}: the command failed (exit {proc.returncode})")
    rep = json.loads(out)
    if save is not None:
        save.write_text(out)
    w = rep["window"]
    return {"cpu": ru.ru_utime + ru.ru_stime, "wall": wall,
            "open_max": w["open_max"]["value"], "open_max_err": w["open_max"]["error_estimate"],
            "encapsulated_min": w["encapsulated_min"]["value"]}


def _line(name, r):
    return (f"  {name:10s} {r['cpu']:8.1f} s CPU {r['wall']:8.1f} s wall   open_max "
            f"{r['open_max']}  encapsulated_min {r['encapsulated_min']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--x", type=float, nargs="+", default=[2.0])
    ap.add_argument("--n", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--baseline", metavar="SRC", default=None)
    ap.add_argument("--save", metavar="DIR", default=None)
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args()
    if a.profile:
        from elastocap.scene import load_scene
        from elastocap.strip.trace import trace_contact_branches

        for x in a.x:
            sc = load_scene("fig3-strip", {"drop.distance_from_end": x})
            pr = cProfile.Profile()
            c = time.process_time()
            pr.enable()
            trace_contact_branches(sc, n=a.n)
            pr.disable()
            print(f"x = {x:g}: {time.process_time() - c:.1f} s CPU (with the profiler)")
            pstats.Stats(pr, stream=sys.stdout).sort_stats("cumulative").print_stats(25)
        return
    trees = [("this tree", HERE)]
    if a.baseline:
        trees.append(("baseline", Path(a.baseline).resolve()))
    for x in a.x:
        print(f"x = {x:g}, n = {a.n or 'default (198, refined at 297)'}: "
              f"{a.repeat} runs per tree, alternating", flush=True)
        runs = {name: [] for name, _ in trees}
        for k in range(a.repeat):
            for name, src in trees:
                save = None
                if a.save:
                    Path(a.save).mkdir(parents=True, exist_ok=True)
                    save = Path(a.save) / f"{name.split()[0]}-x{x:g}-{k}.json"
                r = run_cli(src, x, a.n, save)
                runs[name].append(r)
                print(_line(name, r), flush=True)
        med = {name: {k: statistics.median(r[k] for r in rs) for k in ("cpu", "wall")}
               for name, rs in runs.items()}
        for name in runs:
            print(f"  median {name}: {med[name]['cpu']:.1f} s CPU, {med[name]['wall']:.1f} s "
                  "wall")
        if a.baseline:
            m0, m1 = med["this tree"], med["baseline"]
            print(f"  ratio baseline / this tree: {m1['cpu'] / m0['cpu']:.2f}x CPU, "
                  f"{m1['wall'] / m0['wall']:.2f}x wall", flush=True)


if __name__ == "__main__":
    main()
