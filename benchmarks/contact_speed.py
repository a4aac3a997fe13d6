"""What self-contact costs, measured (CPU time: the machine is shared).

1. Contact-free impact steps: this working tree against a revision before self-contact
   existed (default ``8b8ded7``; or a checkout of one), CPU time per step of warm runs,
   both methods, supp-fig5 (Delta = 2.5, 4) and fig3-strip (x = 2), in fresh processes
   alternated ``--repeat`` times (2 runs each), medians and ratios: a run without
   ``rod.thickness`` generates no contact code, so the ratio should be 1 and the
   trajectories the same.
2. The same impacts with ``rod.thickness`` set against without, in one process: supp-fig5
   (Delta = 2.5, 4) and fig3-strip (x = 2, 3).  Goal: < 1.5x.
3. The witness: with ``rod.thickness`` set, does supp-fig5 at Delta >= 3.8 still show a
   crossing?  elastocap's crossing detector (``elastocap.crossings``, the run's
   ``rod_crossing_time`` / ``interface_crossing_time``) on the run's frames, and the
   smallest node-segment distance over the frames (``dynamics.contact.segment_distances``).
4. Sustained contact, this working tree against a revision of the contact code
   (``--against REV``, default ``HEAD``): fig3-strip at x = 3 (and x = 2) with and without
   ``rod.thickness``, in fresh processes alternated ``--repeat`` times, each timing one
   warm run of every case (CPU time); medians, the with/without ratio of each tree, the
   extra CPU time per contact step, and whether both trees give the same frames (bytes).
   With ``--many``: instead a strip that ends lying on itself over up to ~100 contacts (a
   run of the Fig 3d contact sweep at 200 edges); ``--many 6``: over up to ~150 (x = 6,
   300 edges).

Run: ``python benchmarks/contact_speed.py [--baseline REV|DIR] [--against REV] [--repeat K]
[--only 1|2|3|4] [--many [4.5|6]]``.
The thicknesses: supp-fig5 ``0.05`` (l_ec units), fig3-strip ``0.02`` (l_eg units, a strip
of ~70 um): choices of this benchmark, not the paper's (its model has no contact).
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

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
sys.path.insert(0, HERE)

from dynamics_speed import alternate_processes, export_revision  # noqa: E402

#: Contact-free impacts of section 1: both methods on supp-fig5 (Delta = 2.5, 4) and
#: fig3-strip (x = 2).
FREE_CASES = tuple((name, dict(ov, **{"numerics.integrator": method}))
                   for name, ov in (("supp-fig5", {}), ("supp-fig5", {"drop.wetted_length": 4.0}),
                                    ("fig3-strip", {"drop.distance_from_end": 2.0}))
                   for method in ("rattle", "implicit"))

#: One process of section 1: each case run once to compile / load, then ``inner`` timed
#: runs, each printed (CPU time of the run, its steps, the engine's loop time).
STEP_SNIPPET = """
import json, sys, time
from elastocap.impact import run_impact
from elastocap.scene import load_scene
import elastocap
assert elastocap.__file__.startswith(sys.argv[1]), (elastocap.__file__, sys.argv[1])
for name, ov in json.loads(sys.argv[2]):
    scene = load_scene(name, ov)
    run_impact(scene)
    runs = []
    for _ in range(int(sys.argv[3])):
        c = time.thread_time()
        r = run_impact(scene)
        cpu = time.thread_time() - c
        s = r.simulation
        runs.append(dict(cpu=cpu, steps=r.steps, loop=s.stats["run_time"]))
    print(json.dumps(dict(runs=runs, outcome=r.outcome, final_measure=r.final_measure,
                          t_end=r.t_end)))
"""

THICK = {"supp-fig5": 0.05, "fig3-strip": 0.02}
CONTACT_CASES = (("supp-fig5", {}), ("supp-fig5", {"drop.wetted_length": 4.0}),
                 ("fig3-strip", {}), ("fig3-strip", {"drop.distance_from_end": 3.0}))


def section(title):
    print(f"\n=== {title}")


def _baseline_tree(rev):
    """A persistent export of revision ``rev`` (its numba and stepper caches survive between
    runs of this benchmark, so only the first run compiles it)."""
    sha = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short=12", rev],
                         capture_output=True, text=True, check=True).stdout.strip()
    dest = os.path.join(tempfile.gettempdir(), f"elastocap-baseline-{sha}")
    if not os.path.isdir(os.path.join(dest, "dynamics")):
        os.makedirs(dest, exist_ok=True)
        export_revision(sha, dest)
    return sha, dest


def contact_free_against(baseline, repeat, inner=2):
    """Section 1: CPU time per step of contact-free impacts, this working tree against
    ``baseline`` (a tree before self-contact existed: ``8b8ded7``), side by side: ``repeat``
    rounds of one fresh process per tree (order alternated), each timing ``inner`` warm runs
    of every case; medians over the ``repeat * inner`` runs."""
    if os.path.isdir(baseline):
        tree = os.path.abspath(baseline)
        sha = subprocess.run(["git", "-C", tree, "rev-parse", "--short=12", "HEAD"],
                             capture_output=True, text=True, check=True).stdout.strip()
    else:
        sha, tree = _baseline_tree(baseline)
    section(f"1. contact-free impact steps: {sha} against the working tree (CPU us per step, "
            f"warm, medians of {repeat * inner} runs)")
    cases = json.dumps([list(c) for c in FREE_CASES])
    trees = {sha: tree, "tree": ROOT}
    res = alternate_processes(trees, sha, STEP_SNIPPET, cases, inner, repeat)
    print(f"{'impact':34s} {'method':8s} {'steps':>7s} {sha + ' us/step':>14s} "
          f"{'tree us/step':>13s} {'ratio':>6s}  (engine loop, wall: {sha}, tree, ratio)  "
          "same trajectory")
    ratios = []
    for k, (name, ov) in enumerate(FREE_CASES):
        ov = dict(ov)
        method = ov.pop("numerics.integrator")
        label = name + "".join(f" {a.split('.')[-1]}={b}" for a, b in ov.items())
        per = {t: [x["cpu"] / x["steps"] * 1e6 for run in res[t] for x in run[k]["runs"]]
               for t in trees}
        loop = {t: [x["loop"] / x["steps"] * 1e6 for run in res[t] for x in run[k]["runs"]]
                for t in trees}
        med = {t: float(np.median(per[t])) for t in trees}
        medl = {t: float(np.median(loop[t])) for t in trees}
        old, new = (res[t][-1][k] for t in trees)
        same = (old["outcome"] == new["outcome"] and old["final_measure"] == new["final_measure"]
                and old["t_end"] == new["t_end"]
                and old["runs"][0]["steps"] == new["runs"][0]["steps"])
        ratios.append(med["tree"] / med[sha])
        print(f"{label:34s} {method:8s} {new['runs'][0]['steps']:7d} {med[sha]:14.3f} "
              f"{med['tree']:13.3f} {ratios[-1]:6.3f}  ({medl[sha]:.3f}, {medl['tree']:.3f}, "
              f"{medl['tree'] / medl[sha]:.3f})  {same}")
    print(f"ratio tree/{sha}: median {np.median(ratios):.3f}, range {min(ratios):.3f} - "
          f"{max(ratios):.3f}")


def _timed(scene, reps):
    from elastocap.impact import run_impact

    run_impact(scene)  # compile / load
    cpu = []
    r = None
    for _ in range(reps):
        c = time.thread_time()
        r = run_impact(scene)
        cpu.append(time.thread_time() - c)
    return min(cpu), r


def with_against_without(repeat):
    section("2. impacts with rod.thickness against without (min CPU s of each, medians "
            "over rounds)")
    from elastocap.scene import load_scene

    for name, ov in CONTACT_CASES:
        off = load_scene(name, ov)
        on = off.with_overrides({"rod.thickness": THICK[name]})
        t_off, t_on = [], []
        for _ in range(repeat):
            a, r_off = _timed(off, 1)
            b, r_on = _timed(on, 1)
            t_off.append(a)
            t_on.append(b)
        st = r_on.simulation.stats
        label = name + "".join(f" {a}={b}" for a, b in ov.items())
        m_off, m_on = float(np.median(t_off)), float(np.median(t_on))
        print(f"{label:36s} thickness {THICK[name]:g}: without {m_off:.3f} s ({r_off.steps} "
              f"steps, {r_off.outcome}, t_end {r_off.t_end:.2f})  with {m_on:.3f} s "
              f"({r_on.steps} steps, {r_on.outcome}, t_end {r_on.t_end:.2f})  ratio "
              f"{m_on / m_off:.2f}  contact steps {st['self_contact_steps']}, max active "
              f"{st['self_contact_max_active']}, list rebuilds {st['self_contact_rebuilds']}")


#: Cases of section 4: fig3-strip at x = 3 (folded on itself most of the run) and x = 2,
#: without and with the thickness.
SUSTAINED_CASES = tuple(("fig3-strip", dict(ov, **{"rod.thickness": th}))
                        for ov in ({"drop.distance_from_end": 3.0},
                                   {"drop.distance_from_end": 2.0})
                        for th in (0.0, THICK["fig3-strip"]))

#: ``--many``: a strip that ends lying on itself over up to ~100 contacts, a run of the
#: Fig 3d contact sweep (``elastocap figures --only fig3d-contact``: x = 4.5, We^1/2 =
#: 3.156, damping 0.1, t_max 150, the strip's thickness 0.0157) at its second level, 200
#: edges; ``--many 6``: one folded flat on itself over up to ~150 contacts, x = 6, We^1/2 =
#: 3.5, 300 edges (a run of that sweep's third level).
MANY_CASES = {
    "4.5": tuple(("fig3-strip", {"drop.distance_from_end": 4.5,
                                 "drop.wetted_length": 1.488958, "effects.damping": 0.1,
                                 "numerics.t_max": 150.0, "numerics.n_edges": 200,
                                 "numerics.dt": 0.00161035875, "rod.thickness": th})
                 for th in (0.0, 0.0157)),
    "6": tuple(("fig3-strip", {"drop.distance_from_end": 6.0,
                               "drop.wetted_length": 1.586396, "effects.damping": 0.1,
                               "numerics.t_max": 150.0, "numerics.n_edges": 300,
                               "numerics.dt": 0.000715715, "rod.thickness": th})
               for th in (0.0, 0.0157)),
}

#: One process of section 4: each case run once to compile / load, then timed once (CPU
#: time), with its contact steps and a digest of its frames.
SUSTAINED_SNIPPET = """
import hashlib, json, sys, time
from elastocap.impact import run_impact
from elastocap.scene import load_scene
import elastocap
assert elastocap.__file__.startswith(sys.argv[1]), (elastocap.__file__, sys.argv[1])
for name, ov in json.loads(sys.argv[2]):
    scene = load_scene(name, ov)
    # the warm-up compiles (or loads) the run's stepper: the same effects, a short run
    run_impact(load_scene(name, dict(ov, **{"numerics.t_max": 1.0})))
    c = time.thread_time()
    r = run_impact(scene)
    cpu = time.thread_time() - c
    s = r.simulation
    h = hashlib.sha256(s.positions.tobytes() + s.velocities.tobytes()).hexdigest()
    print(json.dumps(dict(runs=[dict(cpu=cpu, steps=r.steps)], outcome=r.outcome, frames=h,
                          contact_steps=s.stats.get("self_contact_steps", 0))))
"""


def sustained_against(against, repeat, many=None):
    """Section 4: the with/without ratio of sustained contact, the working tree against
    revision ``against``, side by side in alternated fresh processes (``many``, a key of
    :data:`MANY_CASES`: that strip lying on itself instead)."""
    sha, tree = _baseline_tree(against)
    section(f"4. sustained contact: {sha} against the working tree (CPU s of a warm run, "
            f"medians of {repeat} alternated processes per tree)")
    all_cases = MANY_CASES[many] if many else SUSTAINED_CASES
    cases = json.dumps([list(c) for c in all_cases])
    trees = {sha: tree, "tree": ROOT}
    res = alternate_processes(trees, sha, SUSTAINED_SNIPPET, cases, 1, repeat)
    med = {t: [float(np.median([run[k]["runs"][0]["cpu"] for run in res[t]]))
               for k in range(len(all_cases))] for t in trees}
    for k in range(0, len(all_cases), 2):
        ov = all_cases[k][1]
        label = f"fig3-strip x={ov['drop.distance_from_end']:g}"
        last = {t: (res[t][-1][k], res[t][-1][k + 1]) for t in trees}
        same = all(last[sha][i]["frames"] == last["tree"][i]["frames"] for i in (0, 1))
        line = [f"{label:16s} steps {last['tree'][1]['runs'][0]['steps']}:"]
        for t in trees:
            off, on = med[t][k], med[t][k + 1]
            nc = last[t][1]["contact_steps"]
            extra = (on - off) / nc * 1e6 if nc else float("nan")
            line.append(f"{t}: without {off:.3f} s, with {on:.3f} s, ratio {on / off:.2f}, "
                        f"{nc} contact steps, {extra:.1f} us more each, outcome "
                        f"{last[t][1]['outcome']};")
        line.append(f"with: tree/{sha} {med['tree'][k + 1] / med[sha][k + 1]:.3f}; same frames "
                    f"{same}")
        print(" ".join(line))


def witness():
    section("3. supp-fig5 at Delta >= 3.8 with rod.thickness: crossings (elastocap's "
            "detector) and the closest approach")
    from dynamics.contact import segment_distances
    from elastocap.impact import run_impact
    from elastocap.scene import load_scene

    for delta in (3.8, 4.0, 4.3):
        for thick in (0.0, THICK["supp-fig5"]):
            sc = load_scene("supp-fig5", {"drop.wetted_length": delta,
                                          "rod.thickness": thick})
            r = run_impact(sc)
            sim = r.simulation
            el = np.full(sim.positions.shape[1] - 1, sc.rod.length / (sim.positions.shape[1] - 1))
            dmin = min(segment_distances(p, max(thick, 1e-3), el)[0] for p in sim.positions)
            print(f"Delta {delta:.1f} thickness {thick:<5g} outcome {r.outcome:12s} t_end "
                  f"{r.t_end:7.2f}  rod crossing at {r.rod_crossing_time}  interface crossing "
                  f"at {r.interface_crossing_time}  closest node-segment approach "
                  f"{dmin:.4g}" + (f" ({dmin / thick:.6f} x thickness)" if thick else ""))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="8b8ded7",
                    help="git revision or a checkout of one (section 1; default: the last "
                         "revision before self-contact)")
    ap.add_argument("--against", default="HEAD",
                    help="git revision of the contact code to compare with (section 4)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", type=int, choices=(1, 2, 3, 4))
    ap.add_argument("--many", nargs="?", const="4.5", choices=tuple(MANY_CASES),
                    help="section 4 on a strip lying on itself: x = 4.5 (the default, up to "
                         "~100 contacts) or 6 (up to ~150)")
    a = ap.parse_args()
    if a.only in (None, 1):
        contact_free_against(a.baseline, a.repeat)
    if a.only in (None, 2):
        with_against_without(a.repeat)
    if a.only in (None, 3):
        witness()
    if a.only in (None, 4):
        sustained_against(a.against, a.repeat, a.many)


if __name__ == "__main__":
    main()
