"""Regenerate every work-precision table and plot (docs/img/wp-*.png).

Run: ``python3 benchmarks/wp_all.py`` (about 20 min on 2 cores: the Delta* bisection at
200 edges dominates), ``--fast`` for a smoke run of each part (< 1 min, nothing saved), or
``--plot`` to redraw the plots from the records in out/wp/.
Parts: statics (fold error vs time, LGL and Chebyshev), dynamics (final shape, beam
frequency, Delta* vs N and dt), presets (draft/default/publication), peers (PyElastica when
installed), AUTO-07p on the supp-fig5 fold (when bifpy is installed; about 3.5 min).
"""

from __future__ import annotations

import sys
import time

import wp_auto_elastica
import wp_dynamics
import wp_peers
import wp_presets
import wp_statics


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    fast = "--fast" in argv
    if "--plot" in argv:
        from wp_common import load_record

        wp_statics._report_ms(load_record("statics"))
        wp_dynamics.report(
            {k: load_record(f"dynamics-{k}") for k in ("frequency", "shape", "threshold")}
        )
        return 0
    t0 = time.perf_counter()
    for name, mod in (
        ("statics", wp_statics),
        ("dynamics", wp_dynamics),
        ("presets", wp_presets),
        ("peers", wp_peers),
        ("auto-elastica", wp_auto_elastica),
    ):
        t = time.perf_counter()
        print(f"\n# {name}", flush=True)
        if mod is wp_auto_elastica:
            mod.main(["--quick"] if fast else [])
        else:
            mod.main(fast=fast)
        print(f"[{name}: {time.perf_counter() - t:.0f} s]", flush=True)
    print(f"\n[all: {time.perf_counter() - t0:.0f} s]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
