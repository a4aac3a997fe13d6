"""Speed at converged resolution: a publication-resolution fig3-strip impact, both methods,
side by side with a baseline tree (not a test).

The scene: ``fig3-strip`` at x = 4, Delta = 1.25, damping 0.1, ``--accuracy publication``
(367 edges).  Cases, each a whole ``elastocap.impact.run_impact`` (the command line's path):

- RATTLE at its automatic dt (0.7 of the explicit bound b), and at half of it: the
  reference of the accuracy column;
- the midpoint method (``numerics.integrator = "implicit"``) at dt = k b, k in ``--ks``
  (default 1, 2, 4, 8, 16; 8 is its automatic dt with a ground).

Each case runs in a child process per tree (``--baseline DIR``, e.g. an export of main),
the trees alternated case by case, ``--repeat`` rounds after one warm-up child per tree and
method (warm numba and stepper caches, so a child only loads its stepper: reported apart,
as ``compile``).  Times are CPU seconds (the machine is shared): ``loop``, the CPU time of
the compiled time loop (the method's ``Run.advance``, read by ``time.process_time`` in the
child); ``child``, the whole process (``os.wait4``).  Medians over the rounds; the ratio
is this tree / baseline.

Accuracy: the measure M(t) and the end position x(L, t) of every run, on its frames (every
0.05), interpolated by cubic splines onto the frames of the reference run (RATTLE at half
its automatic dt, this tree) over the time both runs cover; the largest differences up to
t = 2 (the first swing), up to t = 5 and over the whole run, and the differences of the
final values (``dM end``, ``dx end``).  At the end, which cases are as accurate as RATTLE
at its automatic dt over the first swing and at the final state, and the cheapest of
them.

With ``--contact``: the same comparison (this tree only, ``--contact-repeat`` rounds) with
self-contact (``rod.thickness = 0.0157``) at x = 3 and x = 4 (``contact steps``: the
steps with a contact pair active).

Run: ``python benchmarks/publication_speed.py --baseline /tmp/base-pub [--repeat 3]
[--ks 1,2,4,8,16] [--contact] [--only-contact]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.interpolate import CubicSpline

from elastocap.impact import DT_FRACTION_GROUND, impact_settings
from elastocap.scene import load_scene

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))

#: The publication-resolution scene of issue 16 (367 edges).
SCENE = "fig3-strip"
BASE = {"drop.distance_from_end": 4.0, "drop.wetted_length": 1.25, "effects.damping": 0.1,
        "numerics.accuracy": "publication"}
#: Self-contact: a strip thickness at which fig3-strip's arms press on each other.
THICKNESS = 0.0157

#: The child: ``argv[1]`` the tree (checked to be the one imported), ``argv[2]`` the scene
#: overrides (JSON), ``argv[3]`` an .npz for the frames' M(t), x(L, t).  Prints one JSON.
SNIPPET = """
import json, sys, time
import numpy as np
tree, ov, out = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3]
import elastocap
assert elastocap.__file__.startswith(tree), (elastocap.__file__, tree)
import dynamics.midpoint, dynamics.rattle
from elastocap.impact import run_impact
from elastocap.scene import load_scene
loop = [0.0]
for mod in (dynamics.rattle, dynamics.midpoint):
    def advance(self, *a, _f=mod.Run.advance):
        t = time.process_time()
        r = _f(self, *a)
        loop[0] += time.process_time() - t
        return r
    mod.Run.advance = advance
r = run_impact(load_scene(sys.argv[4], ov))
sim = r.simulation
np.savez(out, t=sim.times, M=r.measure_history, xL=sim.positions[:, -1, 0])
st = sim.stats
print(json.dumps(dict(
    outcome=r.outcome, M=r.final_measure, xL=r.end_position, steps=r.steps, t_end=r.t_end,
    dt=r.settings["dt"], dt_max=r.settings["dt_max"], loop=loop[0],
    run_time=r.run_time_s, compile=r.compile_time_s, rise=r.energy_rise,
    it=st.get("iterations_mean", float("nan")),
    fac=st.get("jacobians", 0) / max(r.steps, 1), rejected=st.get("rejected_steps", 0),
    status=r.status, retries=r.settings.get("dt_retries", 0),
    contact_steps=st.get("self_contact_steps", 0))))
"""


def child(tree, scene, ov, npz):
    """(result dict, child CPU s) of one run_impact in a fresh process."""
    env = dict(os.environ, PYTHONPATH=tree)
    p = subprocess.Popen([sys.executable, "-c", SNIPPET, tree, json.dumps(ov), npz, scene],
                         env=env, cwd=tree, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    out, err = p.communicate()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{ov} in {tree} failed:\n{err.decode()[-3000:]}")
    res = json.loads(out.decode().strip().splitlines()[-1])
    res["child"] = ru.ru_utime + ru.ru_stime
    return res


def cases(base, ks, dt_max):
    """[(label, overrides)]: RATTLE automatic and at half of it, midpoint at k b."""
    rattle_dt = DT_FRACTION_GROUND * dt_max
    out = [("rattle auto", dict(base)),
           ("rattle half (ref)", dict(base, **{"numerics.dt": 0.5 * rattle_dt}))]
    out += [(f"midpoint {k:g}b", dict(base, **{"numerics.integrator": "implicit",
                                               "numerics.dt": k * dt_max})) for k in ks]
    return out


#: Windows of the accuracy columns (time units from the release): the first swing (on
#: fig3-strip at x = 4 the strip lies flat, M ~ 0, until it lifts off at t ~ 0.9, swings to
#: M = -0.6 at t ~ 1.6 and back by t ~ 2.7), then longer; the whole run.  The ground's
#: contact changes make the error O(dt) and the trajectories dt-sensitive after them
#: (RATTLE at dt and dt/2 differ by 1.1e-2 in M by t = 2, 8.8e-2 over the run), so the
#: longer windows measure that sensitivity, not the order of the scheme.
WINDOWS = (2.0, 5.0, np.inf)


def accuracy(ref, run):
    """Largest |dM(t)|, |dx(L,t)| on the reference's frames in each window of WINDOWS that
    both runs cover (cubic splines through each run's frames), and the final
    differences."""
    t_hi = min(ref["t"][-1], run["t"][-1])
    out = {}
    # frames at equal spacing except the appended final (rest) frame: unique times
    t, u = np.unique(run["t"], return_index=True)
    for key in ("M", "xL"):
        f = CubicSpline(t, run[key][u])
        for w in WINDOWS:
            sel = ref["t"] <= min(w, t_hi)
            err = np.abs(f(ref["t"][sel]) - ref[key][sel])
            out[key, w] = float(err.max())
        out[key, "end"] = float(run[key][-1] - ref[key][-1])
    return out


def load(npz):
    with np.load(npz) as z:
        return {k: z[k] for k in z.files}


def bench(trees, scene, base, ks, repeat, tmp, title):
    st = impact_settings(load_scene(scene, base))
    cs = cases(base, ks, st["dt_max"])
    print(f"\n== {title}: {scene} {base}, {st['n_edges']} edges, explicit bound b = "
          f"{st['dt_max']:.4g}", flush=True)
    # warm-up: one short child per tree and method (stepper generated/compiled, cached)
    for label, tree in trees.items():
        for integ in ("rattle", "implicit"):
            ov = dict(base, **{"numerics.integrator": integ, "numerics.t_max": 0.05})
            r = child(tree, scene, ov, os.path.join(tmp, "warm.npz"))
            print(f"warm-up {label} {integ}: compile {r['compile']:.1f} s", flush=True)
    res = {(c, lab): [] for c, _ in cs for lab in trees}
    for rnd in range(repeat):
        for ci, (c, ov) in enumerate(cs):
            order = list(trees) if (rnd + ci) % 2 == 0 else list(trees)[::-1]
            for lab in order:
                npz = os.path.join(tmp, f"{len(res[c, lab])}-{ci}-{lab.replace(' ', '_')}.npz")
                r = child(trees[lab], scene, ov, npz)
                r["npz"] = npz
                res[c, lab].append(r)
                print(f"  round {rnd + 1} {c:18s} {lab:10s} loop {r['loop']:7.3f} s "
                      f"steps {r['steps']:7d} it {r['it']:.2f} M {r['M']:.5f} "
                      f"x(L) {r['xL']:.5f} contact steps {r['contact_steps']} "
                      f"{r['outcome']} ({r['status']})", flush=True)
    ref = load(res[cs[1][0], "this tree"][0]["npz"])
    print(f"\nCPU s, medians of {repeat}; accuracy against '{cs[1][0]}' of this tree "
          f"(load average at the end {os.getloadavg()[0]:.1f})")
    acc_hdr = "".join(f"{f'{k}(t<={w:g})':>12s}" for k in ("dM", "dx") for w in WINDOWS)
    hdr = (f"{'case':18s} {'tree':10s} {'dt/b':>5s} {'steps':>7s} {'loop s':>7s} "
           f"{'compile':>7s} {'child':>6s} {'it':>5s} {'fac':>5s} {'rej':>4s} "
           f"{'M end':>9s} {'x(L) end':>9s}{acc_hdr} {'dM end':>8s} {'dx end':>8s} "
           f"{'rise':>7s} outcome")
    print(hdr.replace("(t<=inf)", "(all)"))
    table = {}
    for c, _ov in cs:
        for lab in trees:
            rs = res[c, lab]
            med = {k: float(np.median([r[k] for r in rs]))
                   for k in ("loop", "compile", "child")}
            r = rs[0]
            acc = accuracy(ref, load(r["npz"]))
            table[c, lab] = (med, r, acc)
            cols = "".join(f"{acc[k, w]:12.1e}" for k in ("M", "xL") for w in WINDOWS)
            print(f"{c:18s} {lab:10s} {r['dt'] / r['dt_max']:5.2f} {r['steps']:7d} "
                  f"{med['loop']:7.3f} {med['compile']:7.2f} {med['child']:6.1f} "
                  f"{r['it']:5.2f} {r['fac']:5.2f} {r['rejected']:4d} {r['M']:9.5f} "
                  f"{r['xL']:9.5f}{cols} {acc['M', 'end']:+8.1e} {acc['xL', 'end']:+8.1e} "
                  f"{r['rise']:7.1e} {r['outcome']} ({r['status']})")
    if len(trees) > 1:
        print("\nratio this tree / baseline (loop CPU s); same trajectory?")
        for c, _ov in cs:
            a, b = table[c, "this tree"], table[c, "baseline"]
            same = np.array_equal(load(a[1]["npz"])["M"], load(b[1]["npz"])["M"])
            print(f"{c:18s} {a[0]['loop'] / b[0]['loop']:6.2f}   "
                  f"{'bit-identical M(t)' if same else 'differs'}")
    print()
    for line in verdict(table, [c for c, _ in cs]):
        print(line)
    return table


def verdict(table, labels, tree="this tree"):
    """Which cases are as accurate as RATTLE at its automatic dt (the first case), and the
    cheapest of them: on the first window (the first swing) and on the final state (what
    an outcome reads)."""
    ref = table[labels[0], tree]
    out = []
    for what, keys in ((f"up to t = {WINDOWS[0]:g}", [("M", WINDOWS[0]), ("xL", WINDOWS[0])]),
                       ("at the end", [("M", "end"), ("xL", "end")])):
        ok = [c for c in labels[2:] if table[c, tree][1]["status"] == "at_rest"
              and all(abs(table[c, tree][2][k]) <= abs(ref[2][k]) for k in keys)]
        tol = ", ".join(f"|d{k[0]}| <= {abs(ref[2][k]):.1e}" for k in keys)
        if ok:
            best = min(ok, key=lambda c: table[c, tree][0]["loop"])
            out.append(f"as accurate as '{labels[0]}' {what} ({tol}): {', '.join(ok)}; "
                       f"the cheapest, {best}, {table[best, tree][0]['loop']:.2f} s against "
                       f"{ref[0]['loop']:.2f} s")
        else:
            out.append(f"as accurate as '{labels[0]}' {what} ({tol}): none of the midpoint "
                       f"runs ({ref[0]['loop']:.2f} s)")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="folder holding the baseline tree (elastocap, "
                    "continuation, dynamics), e.g. an export of main")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ks", default="1,2,4,8,16",
                    help="midpoint time steps, multiples of the explicit bound")
    ap.add_argument("--contact", action="store_true",
                    help="also self-contact at x = 3 and 4 (this tree only)")
    ap.add_argument("--only-contact", action="store_true")
    ap.add_argument("--contact-repeat", type=int, default=1)
    ap.add_argument("--contact-ks", default="2,4,8,16")
    args = ap.parse_args(argv)
    ks = [float(k) for k in args.ks.split(",")]
    trees = {"this tree": ROOT}
    if args.baseline:
        trees["baseline"] = os.path.abspath(args.baseline)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        if not args.only_contact:
            bench(trees, SCENE, BASE, ks, args.repeat, tmp, "publication impact")
        if args.contact or args.only_contact:
            cks = [float(k) for k in args.contact_ks.split(",")]
            for x in (3.0, 4.0):
                base = dict(BASE, **{"drop.distance_from_end": x, "rod.thickness": THICKNESS})
                bench({"this tree": ROOT}, SCENE, base, cks, args.contact_repeat, tmp,
                      f"self-contact, x = {x:g}")
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
