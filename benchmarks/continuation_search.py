"""The branch search side by side with another checkout (run:
``python3 benchmarks/continuation_search.py [--other /path/to/checkout | --base REV]
[--repeat 5]``).

``--base REV`` measures against a git revision of this repository: it is checked out into
a temporary ``git worktree`` (removed afterwards). Run it with the other cores as quiet as
you can: CPU time is less sensitive to load than wall time, but not immune to it.

Each scene is traced in a fresh subprocess per code version, alternating versions, after
one warm-up each (numba compiled and cached). Each subprocess draws the diagram twice: the
first diagram also loads the compiled kernels from numba's cache (reported as the
first-diagram CPU time), the second is the one timed: median CPU time
(``time.process_time`` of the tracing process: on a shared machine it is what the search
costs, while the wall time also counts the other jobs) and median wall time of the whole
diagram (search, every branch, folds with error estimates), the number of branches and
folds, and the largest difference between the two versions' folds. Scenes:
supp-fig5 and scenes of the property family (A 0.5..1.9, L 3..8, the drop off centre, one
in the cusp region). Prints a table with the ratios this/other; ``--other`` defaults to
/work/main. The search's own statistics (seeds tried) are printed for this version.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
SCENES = [
    ("supp-fig5", {}),
    ("A=1.0", {"drop.area": 1.0}),
    ("A=1.2 L=5", {"drop.area": 1.2, "rod.length": 5.0}),
    ("A=1.74", {"drop.area": 1.74}),
    ("A=0.6 L=8 x=3", {"drop.area": 0.6, "rod.length": 8.0, "drop.distance_from_end": 3.0}),
    ("A=1.9 L=3", {"drop.area": 1.9, "rod.length": 3.0, "drop.wetted_length": 1.0}),
    ("A=1.742 L=5.63 c=1.88", {"drop.area": 1.742, "rod.length": 5.63, "drop.center": 1.88,
                               "drop.wetted_length": 1.0}),
]
CHILD = r"""
import json, sys, time
from elastocap.scene import load_scene
from elastocap.statics.branches import trace_branches
ov = json.loads(sys.argv[1])
sc = load_scene("supp-fig5", ov)
c = time.process_time()
trace_branches(sc)  # the process's first diagram: loads the compiled kernels from the cache
first = time.process_time() - c
t, c = time.perf_counter(), time.process_time()
bs = trace_branches(sc)
dt, dc = time.perf_counter() - t, time.process_time() - c
st = bs.metadata.get("search", {}).get("stats", {})
print(json.dumps({"t": dt, "cpu": dc, "cpu_first": first, "branches": len(bs.branches),
                  "folds": len(bs.folds),
                  "fold_values": [f["value"] for f in bs.folds],
                  "seeds": st.get("seeds_tried"),
                  "fold_curve_starts": bs.metadata.get("search", {}).get("fold_curve_starts")}))
"""


def run(root: Path, ov: dict) -> dict:
    env = dict(os.environ, PYTHONPATH=str(root))
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(ov)], env=env, cwd="/tmp",
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--other", default="/work/main")
    ap.add_argument("--base", default=None,
                    help="a git revision to compare with (checked out in a temporary "
                    "worktree; overrides --other)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=None,
                    help="names of the scenes to run (default: all)")
    args = ap.parse_args()
    scenes = [sc for sc in SCENES if args.scenes is None or sc[0] in args.scenes]
    if args.base is not None:
        tmp = tempfile.mkdtemp(prefix="search-base-")
        wt = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(HERE), "worktree", "add", "--detach", str(wt),
                        args.base], check=True, capture_output=True)
        try:
            compare(HERE, wt, args.repeat, scenes)
        finally:
            subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force",
                            str(wt)], check=False, capture_output=True)
            shutil.rmtree(tmp, ignore_errors=True)
        return
    compare(HERE, Path(args.other), args.repeat, scenes)


def compare(here: Path, other: Path, repeat: int, scenes):
    print(f"this: {here}\nother: {other}\n")
    print("| scene | this CPU [s] | other CPU [s] | CPU ratio | this wall [s] | other wall [s] "
          "| wall ratio | this / other first-diagram CPU [s] | this branches/folds "
          "| other branches/folds | max fold difference | seeds tried (this) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---:|", flush=True)
    for name, ov in scenes:
        run(here, ov), run(other, ov)  # warm-up (numba caches)
        a, b = [], []
        for _ in range(repeat):
            a.append(run(here, ov))
            b.append(run(other, ov))
        ta = statistics.median(r["t"] for r in a)
        tb = statistics.median(r["t"] for r in b)
        ca = statistics.median(r["cpu"] for r in a)
        cb = statistics.median(r.get("cpu", float("nan")) for r in b)
        fa = statistics.median(r.get("cpu_first", float("nan")) for r in a)
        fb = statistics.median(r.get("cpu_first", float("nan")) for r in b)
        print(f"| {name} | {ca:.2f} | {cb:.2f} | {ca / cb:.2f} | {ta:.2f} | {tb:.2f} | "
              f"{ta / tb:.2f} | {fa:.2f} / {fb:.2f} | {a[0]['branches']}/{a[0]['folds']} | "
              f"{b[0]['branches']}/{b[0]['folds']} | {_fold_difference(a[0], b[0])} | "
              f"{a[0]['seeds']} |", flush=True)


def _fold_difference(a: dict, b: dict) -> str:
    fa, fb = a.get("fold_values", []), b.get("fold_values", [])
    if len(fa) != len(fb):
        return "different counts"
    return f"{max((abs(x - y) for x, y in zip(fa, fb, strict=True)), default=0.0):.1e}"


if __name__ == "__main__":
    main()
