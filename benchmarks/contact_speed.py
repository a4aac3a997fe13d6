"""What self-contact costs, measured (CPU time: the machine is shared).

1. Contact-free impact runs: this working tree against a git revision (default ``main``),
   each in fresh processes alternated ``--repeat`` times, medians of the per-process
   minima (the cases of ``dynamics_speed.py`` section 3b, plus a midpoint run): a run
   without ``rod.thickness`` generates no contact code, so the ratio should be 1.
2. The same impacts with ``rod.thickness`` set against without, in one process: supp-fig5
   (Delta = 2.5, 4) and fig3-strip (x = 2, 3).  Goal: < 1.5x.
3. The witness: with ``rod.thickness`` set, does supp-fig5 at Delta >= 3.8 still show a
   crossing?  elastocap's crossing detector (``elastocap.crossings``, the run's
   ``rod_crossing_time`` / ``interface_crossing_time``) on the run's frames, and the
   smallest node-segment distance over the frames (``dynamics.contact.segment_distances``).

Run: ``python benchmarks/contact_speed.py [--baseline REV] [--repeat K] [--only 1|2|3]``.
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

from dynamics_speed import IMPACT_SNIPPET, _export_revision  # noqa: E402

FREE_CASES = (("supp-fig5", {}), ("supp-fig5", {"drop.wetted_length": 4.0}),
              ("fig3-strip", {}), ("supp-fig5", {"numerics.integrator": "implicit"}))

THICK = {"supp-fig5": 0.05, "fig3-strip": 0.02}
CONTACT_CASES = (("supp-fig5", {}), ("supp-fig5", {"drop.wetted_length": 4.0}),
                 ("fig3-strip", {}), ("fig3-strip", {"drop.distance_from_end": 3.0}))


def section(title):
    print(f"\n=== {title}")


def contact_free_against(baseline, repeat, inner=2):
    section(f"1. contact-free impacts: {baseline} against the working tree (CPU s)")
    cases = json.dumps([list(c) for c in FREE_CASES])
    with tempfile.TemporaryDirectory() as tmp:
        _export_revision(baseline, tmp)
        trees = {baseline: tmp, "working tree": ROOT}
        res = {k: [] for k in trees}
        for r in range(repeat):
            for label in (trees if r % 2 == 0 else list(trees)[::-1]):
                env = dict(os.environ, PYTHONPATH=trees[label])
                if label == baseline:
                    env["DYNAMICS_CACHE_DIR"] = os.path.join(tmp, "_stepper_cache")
                out = subprocess.run([sys.executable, "-c", IMPACT_SNIPPET, trees[label],
                                      cases, str(inner)], env=env, cwd=trees[label],
                                     capture_output=True, text=True)
                if out.returncode:
                    print(out.stderr[-2000:])
                    raise SystemExit(1)
                res[label].append([json.loads(line) for line in out.stdout.splitlines()])
    for k, (name, ov) in enumerate(FREE_CASES):
        label = name + "".join(f" {a}={b}" for a, b in ov.items())
        rows = {t: [run[k] for run in res[t]] for t in trees}
        med = {t: float(np.median([x["cpu"] for x in rows[t]])) for t in trees}
        old, new = (rows[t][-1] for t in trees)
        print(f"{label:40s} {baseline} {med[baseline]:.3f}  tree {med['working tree']:.3f}  "
              f"ratio tree/{baseline} {med['working tree'] / med[baseline]:.3f}  "
              f"({old['steps']} steps; same outcome {old['outcome'] == new['outcome']}, same "
              f"final measure {old['final_measure'] == new['final_measure']})")


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
    ap.add_argument("--baseline", default="main")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", type=int, choices=(1, 2, 3))
    a = ap.parse_args()
    if a.only in (None, 1):
        contact_free_against(a.baseline, a.repeat)
    if a.only in (None, 2):
        with_against_without(a.repeat)
    if a.only in (None, 3):
        witness()


if __name__ == "__main__":
    main()
