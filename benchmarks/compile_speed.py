"""What compiling costs: the first impact of a fresh install, and one new stepper.

Each case runs in a child process whose numba cache (``NUMBA_CACHE_DIR``) and generated
stepper cache (``DYNAMICS_CACHE_DIR``) are fresh temporary folders; its CPU time (user +
system, from ``os.wait4``) and wall time are read by this process.

1. ``first impact``: ``run_impact`` of ``supp-fig5`` with every cache empty, what a fresh
   install pays (the CLI's ``elastocap impact supp-fig5`` adds only the output).
   ``first contact impact``: the same for ``fig3-strip`` with ``rod.thickness = 0.02``
   (self-contact: the contact kernels compile too), to t = 1.
2. ``cli first impact`` / ``cli second impact``: ``elastocap impact supp-fig5 --json``
   as the quick start runs it (output files and figure included), with every cache
   empty, then again in a second process on the caches the first filled; besides CPU and
   wall time, the compile time the command reports (``compile_time_s``: generating,
   loading and compiling the stepper).
3. ``new stepper``: the package's numba kernels already cached (a first child compiles
   them, through a different effect combination), a child compiles the RATTLE and the
   midpoint stepper of a strip on the ground (capillary + gravity + ground + damping,
   fig3-strip) and of a bare rod (bending only), one step each (left out with
   ``--first-only``).

4. ``--classification``: what the output frames' classification costs once compiled
   (the turning measures and the crossing detector, vectorised numpy in this tree): in a
   child process with warm caches, each impact of ``CLASSIFY_CASES`` once to compile, then
   once timed: the CPU of the whole ``run_impact``, of its time loop (``run_time``) and of
   the calls of ``turning_measures`` and ``first_crossing_frames`` it makes.

With ``--baseline REV`` (a git revision, or a folder holding a checkout) the same cases run
from that tree too, in alternated order, ``--repeat`` rounds: medians and the ratio
(this tree / baseline) are printed.

Run: ``python benchmarks/compile_speed.py [--baseline REV|DIR] [--repeat K] [--first-only]
[--classification]``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
sys.path.insert(0, HERE)

from dynamics_speed import export_revision  # noqa: E402

#: The child's code: ``argv[1]`` the tree (checked to be the one imported), ``argv[2]``
#: the case.
SNIPPET = """
import sys
import numpy as np
tree, case = sys.argv[1], sys.argv[2]
import elastocap
assert elastocap.__file__.startswith(tree), (elastocap.__file__, tree)
from elastocap.impact import run_impact
from elastocap.scene import load_scene
if case == "first-impact":
    run_impact(load_scene("supp-fig5"))
elif case == "first-contact-impact":
    run_impact(load_scene("fig3-strip", {"rod.thickness": 0.02, "numerics.t_max": 1.0}))
elif case == "warm-kernels":
    run_impact(load_scene("supp-fig5", {"numerics.t_max": 1.0}))
    run_impact(load_scene("supp-fig5", {"numerics.t_max": 1.0,
                                        "numerics.integrator": "implicit"}))
else:
    from dynamics import Rod, simulate, stable_dt
    method, what = case.split(":")
    n, L, B, effects = 40, 1.0, 1.0, ()
    if what == "strip":
        from elastocap.impact import build_effects
        scene = load_scene("fig3-strip")
        n, L, B = 100, scene.rod.length, scene.rod.bending_modulus
        effects = build_effects(scene).effects
    x = np.zeros((n + 1, 2))
    x[:, 0] = np.linspace(0.0, L, n + 1)
    rod = Rod(x, np.zeros_like(x), np.full(n, L / n), 1.0, B)
    dt = 0.5 * stable_dt(rod.edge_len, rod.mu, rod.B)
    simulate(rod, effects, method=method, dt=dt, t_end=dt)
"""

NEW_STEPPER_CASES = ("rattle:strip", "midpoint:strip", "rattle:bare", "midpoint:bare")

#: Impacts whose classification is timed (``--classification``): supp-fig5 open (1062
#: frames of 100 edges) and encapsulated (crossings found), fig3-strip at 450 edges (4001
#: frames) and undamped at x = 3 (4001 frames of 198 edges, the rod crossing itself).
CLASSIFY_CASES = (("supp-fig5", {}), ("supp-fig5", {"drop.wetted_length": 4.0}),
                  ("fig3-strip", {"numerics.n_edges": 450}),
                  ("fig3-strip", {"drop.distance_from_end": 3.0}))

#: The child of ``--classification``: ``argv[1]`` the tree, ``argv[2]`` the cases (JSON);
#: one JSON line per case.
CLASSIFY_SNIPPET = """
import json, sys, time
import elastocap
assert elastocap.__file__.startswith(sys.argv[1]), (elastocap.__file__, sys.argv[1])
import elastocap.impact as imp
from elastocap.scene import load_scene
spent = [0.0]
def timed(f):
    def g(*a):
        c = time.thread_time()
        try:
            return f(*a)
        finally:
            spent[0] += time.thread_time() - c
    return g
imp.first_crossing_frames = timed(imp.first_crossing_frames)
imp.turning_measures = timed(imp.turning_measures)
for name, ov in json.loads(sys.argv[2]):
    scene = load_scene(name, ov)
    imp.run_impact(scene)
    spent[0] = 0.0
    c = time.thread_time()
    r = imp.run_impact(scene)
    total = time.thread_time() - c
    print(json.dumps(dict(total=total, loop=r.run_time_s, classify=spent[0],
                          frames=len(r.simulation.times), outcome=r.outcome,
                          rod=r.rod_crossing_time, interface=r.interface_crossing_time,
                          measure=r.final_measure)))
"""


def child(tree, case, numba_dir, stepper_dir, out_dir=None):
    """(CPU s, wall s, compile s) of one child process: ``case`` the snippet's case, or
    with ``out_dir`` the command line's ``impact`` of ``case`` (a scene) into it, whose
    reported compile time is read from its JSON (NaN for the snippet's cases)."""
    env = dict(os.environ, PYTHONPATH=tree, NUMBA_CACHE_DIR=numba_dir,
               DYNAMICS_CACHE_DIR=stepper_dir)
    if out_dir is None:
        cmd = [sys.executable, "-c", SNIPPET, tree, case]
    else:
        cmd = [sys.executable, "-m", "elastocap", "impact", case, "--out", out_dir,
               "--progress", "none", "--json"]
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, env=env, cwd=tree, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    out, err = p.communicate()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{case} in {tree} failed:\n{err.decode()[-3000:]}")
    comp = json.loads(out)["compile_time_s"] if out_dir is not None else float("nan")
    return ru.ru_utime + ru.ru_stime, wall, comp


def one_round(tree, cases):
    """{case: (cpu, wall, compile)} for one tree, fresh caches."""
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        res["first impact"] = child(tree, "first-impact", os.path.join(tmp, "n0"),
                                    os.path.join(tmp, "s0"))
        res["first contact impact"] = child(tree, "first-contact-impact",
                                            os.path.join(tmp, "nk"), os.path.join(tmp, "sk"))
        # the command line, cold then warm (the second process on the caches of the first)
        nd, sd, od = (os.path.join(tmp, k) for k in ("nc", "sc", "oc"))
        res["cli first impact"] = child(tree, "supp-fig5", nd, sd, od)
        res["cli second impact"] = child(tree, "supp-fig5", nd, sd, od)
        if not cases:
            return res
        kernels = os.path.join(tmp, "n1")
        child(tree, "warm-kernels", kernels, os.path.join(tmp, "s1"))
        for k, case in enumerate(cases):
            # a copy of the warmed kernel cache per case: each compiles its stepper cold
            nd = os.path.join(tmp, f"n1-{k}")
            shutil.copytree(kernels, nd)
            res[f"new stepper {case}"] = child(tree, case, nd, os.path.join(tmp, f"s2-{k}"))
    return res


def classification(trees, repeat):
    """``--classification``: per tree and case, medians over ``repeat`` processes."""
    cases = json.dumps([list(c) for c in CLASSIFY_CASES])
    res = {k: [] for k in trees}
    for r in range(repeat):
        for label in (trees if r % 2 == 0 else list(trees)[::-1]):
            env = dict(os.environ, PYTHONPATH=trees[label])
            with tempfile.TemporaryDirectory() as tmp:
                env["DYNAMICS_CACHE_DIR"] = os.path.join(tmp, "s")
                out = subprocess.run([sys.executable, "-c", CLASSIFY_SNIPPET, trees[label],
                                      cases], env=env, cwd=trees[label], capture_output=True,
                                     text=True)
            if out.returncode:
                raise SystemExit(f"{label}: {out.stderr[-3000:]}")
            res[label].append([json.loads(line) for line in out.stdout.splitlines()])
    print(f"\nClassification once compiled: CPU s of run_impact [wall s of its time loop] "
          f"(of the measures and crossings), medians of {repeat} processes; load average "
          f"at the end {os.getloadavg()[0]:.1f}")
    for k, (name, ov) in enumerate(CLASSIFY_CASES):
        label = name + "".join(f" {a}={b}" for a, b in ov.items())
        line = f"{label:38s}"
        for t in trees:
            rows = [run[k] for run in res[t]]
            med = {q: float(np.median([x[q] for x in rows])) for q in
                   ("total", "loop", "classify")}
            line += (f"  {t}: {med['total']:.3f} [{med['loop']:.3f}] "
                     f"({med['classify'] * 1e3:.1f} ms)")
        last = {t: res[t][-1][k] for t in trees}
        print(line)
        print(f"{'':38s}  frames {last['this tree']['frames']}; outcome, crossing times, "
              "final measure: " + "; ".join(
                  f"{t}: {v['outcome']}, {v['rod']}, {v['interface']}, {v['measure']!r}"
                  for t, v in last.items()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="git revision or folder to compare against")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--first-only", action="store_true",
                    help="only the first impact and the command line's two impacts")
    ap.add_argument("--classification", action="store_true",
                    help="only the cost of the classification once compiled")
    args = ap.parse_args(argv)
    cases = () if args.first_only else NEW_STEPPER_CASES
    trees = {"this tree": ROOT}
    tmp = None
    if args.baseline:
        if os.path.isdir(args.baseline):
            trees["baseline"] = os.path.abspath(args.baseline)
        else:
            tmp = tempfile.mkdtemp(prefix="compile-base-")
            export_revision(args.baseline, tmp)
            trees["baseline"] = tmp
    results = {k: [] for k in trees}
    try:
        if args.classification:
            classification(trees, args.repeat)
            return
        for r in range(args.repeat):
            for label in (trees if r % 2 == 0 else list(trees)[::-1]):
                results[label].append(one_round(trees[label], cases))
                print(f"round {r + 1} {label}: " + ", ".join(
                    f"{c} {v[0]:.1f}" for c, v in results[label][-1].items()), flush=True)
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"\nCPU s (wall s) [reported compile s], medians of {args.repeat} rounds, fresh "
          f"caches per case; load average at the end {os.getloadavg()[0]:.1f}")
    head = f"{'case':30s}" + "".join(f"{k:>30s}" for k in trees)
    print(head + ("   ratio CPU, wall, compile" if len(trees) > 1 else ""))
    for c in results["this tree"][0]:
        med = {k: [float(np.median([r[c][j] for r in results[k]])) for j in range(3)]
               for k in trees}
        line = f"{c:30s}" + "".join(
            f"{m[0]:14.1f} ({m[1]:5.1f})" + (f" [{m[2]:5.1f}]" if m[2] == m[2] else " " * 8)
            for m in med.values())
        if len(trees) > 1:
            a, b = med["this tree"], med["baseline"]
            line += "   " + ", ".join(f"{a[j] / b[j]:.2f}" for j in range(3) if a[j] == a[j])
        print(line)

if __name__ == "__main__":
    main()
