"""Fig 3d: the numerical phase diagram of the strip, x/l_eg against We^1/2.

The paper's strip model has no dissipation but the perfectly inelastic ground: its runs do
not come to rest (measured: all 712 runs of a 20 x 20 sweep still moving at t = 200), and
the outcome at t_max is then erratic along a line of x. This figure adds a small viscous
damping, 0.1 (the order of the supp-fig5 value), an explicit and documented choice
(docs/guide/phase-diagrams.md), so that every run ends at rest; the paper's criterion is
used, and the points where the frame-independent companion criterion disagrees are ringed.

Every run uses one resolution (:func:`elastocap.sweep.sweep_resolutions`: the accuracy
preset's edges at the sweep's largest Delta); each line's threshold (its first change from
open) is checked at 1.5x the edges and half the time step, and again at each following
level up to ``FIG3D_LEVELS``, and where it moves, located at that level and checked at the
next. The frame-independent criterion's thresholds are computed on the same store and
drawn too. Figs 4 and 5 (:mod:`elastocap.paper_figures.fig4_fig5`) run at
every level of the same resolutions (:func:`fig3d_resolutions`).

The figure ``fig3d-contact`` (:mod:`elastocap.paper_figures.fig3d_contact`) is the same
diagram with rod self-contact: the strip's thickness ``FIG3D_THICKNESS`` (the paper's
h = 55 um over l_eg = 3.5 mm) and a final time ``FIG3D_CONTACT_T_MAX``, since strips folded
onto themselves slide on each other longer before they rest.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from elastocap.io import atomic_path, write_json
from elastocap.paper_figures import record
from elastocap.scene import load_scene
from elastocap.sweep import plot_phase_diagram, run_sweep, sweep_resolutions
from elastocap.sweep.grid import grid_points

#: The damping added to the strip scene for this figure (see the module docstring).
FIG3D_DAMPING = 0.1
#: Final time. The kinetic energy of a damped run decays as exp(-t c / mu) = exp(-0.1 t):
#: from the impact's order 1 to the rest threshold takes about 100 time units (at x = 6,
#: We^1/2 = 1, 133 edges the strip rests at t = 101.2). At t_max = 100, 17 of 184 runs at
#: 133 edges were still moving, most at x >= 4.5, where they set the lines' first change
#: from open.
FIG3D_T_MAX = 200.0
#: The diagram: x/l_eg = 0.5 ... 6 in steps of 0.5; We^1/2 = 0.5 ... 4 in steps of 0.5,
#: then every boundary bisected to a bracket <= 0.05.
FIG3D_X = tuple(float(v) for v in np.linspace(0.5, 6.0, 12))
FIG3D_WE = tuple(float(v) for v in np.linspace(0.5, 4.0, 8))
FIG3D_TOL = 0.05
#: Verification levels: every line's threshold is checked at each of 3 finer levels (1.5x,
#: 2.25x and 3.375x the edges of the sweep; as ``--converge 3 --every-level``), and where it
#: moves, located at that level and checked at the next.
FIG3D_LEVELS = 3
#: The contact diagram's strip thickness in l_eg: h = 55 um, l_eg = 3.4996 mm.
FIG3D_THICKNESS = 0.0157
#: The contact diagram's final time: at t = 100, 61 of 239 runs at 133 edges were still
#: moving (folded strips sliding on each other), at 150 the 12 of 176 listed in the guide.
FIG3D_CONTACT_T_MAX = 150.0
#: The contact diagram's verification levels: 200, 300 and 450 edges, as without contact.
#: A strip lying on itself at 300 edges (x = 6, 158 contacts) runs in 37 s of CPU with the
#: banded contact solve (``dynamics.contact``), against 229 s with the dense one alone.
FIG3D_CONTACT_LEVELS = 3


def fig3d_overrides(accuracy: str, contact: bool = False) -> list[str]:
    """The ``--set`` overrides of the figure's scene (recorded in its title and JSON);
    ``contact``: with rod self-contact (the ``fig3d-contact`` figure)."""
    if contact:
        return [f"numerics.accuracy={accuracy}", f"effects.damping={FIG3D_DAMPING}",
                f"numerics.t_max={FIG3D_CONTACT_T_MAX}", f"rod.thickness={FIG3D_THICKNESS}"]
    return [f"numerics.accuracy={accuracy}", f"effects.damping={FIG3D_DAMPING}",
            f"numerics.t_max={FIG3D_T_MAX}"]


def fig3d_scene(accuracy: str, contact: bool = False):
    return load_scene("fig3-strip", fig3d_overrides(accuracy, contact))


def fig3d_resolutions(accuracy: str, fast: bool = False, contact: bool = False):
    """The :class:`~elastocap.sweep.Resolution` of every level of the figure: level 0, which
    every run of the sweep uses, and the verification levels (none in ``fast`` mode)."""
    scene = fig3d_scene(accuracy, contact)
    xs, we = ([3.0], [1.0, 2.5]) if fast else (FIG3D_X, FIG3D_WE)
    levels = 0 if fast else (FIG3D_CONTACT_LEVELS if contact else FIG3D_LEVELS)
    return sweep_resolutions(scene, grid_points(scene, xs, we_sqrts=we)[0], levels)


def fig3d_sweeps(store, accuracy: str, fast: bool = False, contact: bool = False,
                 **executor):
    """The figure's two sweeps into ``store``: the paper's criterion, then the
    frame-independent one on the same store (its runs are shared; only its own bisection
    and verification runs are new). ``executor``: ``workers=`` or ``scheduler=``, as
    :func:`~elastocap.sweep.run_sweep` takes them. Returns both sweep results."""
    scene = fig3d_scene(accuracy, contact)
    if fast:
        xs, we, refine, levels = [3.0], [1.0, 2.5], None, 0
    else:
        xs, we, refine = FIG3D_X, FIG3D_WE, FIG3D_TOL
        levels = FIG3D_CONTACT_LEVELS if contact else FIG3D_LEVELS
    common = dict(we_sqrts=we, store=store, refine_tol=refine, verify_levels=levels,
                  verify_every_level=bool(levels),
                  overrides=fig3d_overrides(accuracy, contact),
                  **executor)
    res = run_sweep(scene, xs, **common)
    comp = run_sweep(scene, xs, criterion="companion_outcome", **common)
    return res, comp


def _name(contact: bool) -> str:
    return "fig3d-contact" if contact else "fig3d"


def main(out_dir, fast: bool = False, workers: int | None = None,
         accuracy: str | None = None, contact: bool = False) -> list[Path]:
    """Sweep, refine, verify and plot; writes ``fig3d.png``, ``fig3d.json`` and
    ``fig3d-ACCURACY.sqlite`` (the store), or with ``contact`` ``fig3d-contact.png``,
    ``fig3d-contact.json`` and ``fig3d-contact-ACCURACY.sqlite``. ``fast``: one line, two
    runs, draft, no verification (a smoke test)."""
    out = Path(out_dir)
    accuracy = accuracy or ("draft" if fast else "default")
    scene = fig3d_scene(accuracy, contact)
    name = _name(contact)
    res, comp = fig3d_sweeps(out / f"{name}-{accuracy}.sqlite", accuracy, fast, contact,
                             workers=workers)
    body = res.to_dict()
    cd = comp.to_dict()
    body["companion"] = {"criterion": "companion_outcome", "boundary": cd["boundary"],
                         "counts": cd["counts"], "wall_time_s": comp.wall_time_s}
    png = _draw(out, body, contact)
    js = out / f"{name}.json"
    write_json(js, record(body, scene, fast=fast), indent=1)
    return [png, js]


def _draw(out: Path, body: dict, contact: bool = False) -> Path:
    """The figure's PNG from its JSON body (the sweep's report with its companion)."""
    comp = {**{k: v for k, v in body.items() if k not in ("runs", "companion")},
            **body["companion"]}
    png = out / f"{_name(contact)}.png"
    with_contact = (f", rod self-contact (thickness {FIG3D_THICKNESS})" if contact else "")
    with atomic_path(png) as tmp:
        plot_phase_diagram(body, tmp, companion=comp,
                           title=f"Fig 3d (model): fig3-strip, damping {FIG3D_DAMPING}"
                           f"{with_contact}; points and threshold: the paper's lab-frame "
                           "criterion")
    return png


def redraw(out_dir, contact: bool = False) -> list[Path]:
    """Redraw the figure's PNG from ``out_dir``'s JSON without running an impact
    (``python3 -m elastocap.paper_figures.fig3d DIR --redraw [--contact]``)."""
    out = Path(out_dir)
    name = _name(contact)
    js = out / f"{name}.json"
    if not js.is_file():
        raise FileNotFoundError(f"{name}: no {js}; make it with elastocap figures --only {name}")
    return [_draw(out, json.loads(js.read_text()), contact)]


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="Fig 3d: the phase diagram of the strip")
    ap.add_argument("out", help="output folder")
    ap.add_argument("--fast", action="store_true", help="one line, two runs (a smoke test)")
    ap.add_argument("--redraw", action="store_true",
                    help="redraw DIR/fig3d.png from DIR/fig3d.json without running impacts")
    ap.add_argument("--contact", action="store_true",
                    help="the diagram with rod self-contact (fig3d-contact)")
    a = ap.parse_args()
    for p in (redraw(a.out, a.contact) if a.redraw else main(a.out, a.fast, contact=a.contact)):
        print(p)
