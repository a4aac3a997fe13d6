"""Fig 3 strip: where the lifted, encapsulated equilibrium exists, and its energies.

Panel (a): in the plane (x / l_eg, We^(1/2)) of the paper's Fig 3d, the band of drop
positions in which the encapsulated strip (flat on [0, s_c], lifted and wrapped on [s_c, L])
is an equilibrium, with the events that bound it (the lift-off point reaching the contact
line S1 on the left, the folded-back tail touching the ground on the right). Panel (b): at
x = 2, energies against We^(1/2): released by encapsulation (e_flat - e_wrapped), stored
in gravity, needed to unwrap to the topology edge, and the drop's kinetic energy at
impact (units mu g l_eg^2 = B / l_eg).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from elastocap.paper_figures import record
from elastocap.scene import load_scene
from elastocap.strip.barrier import barrier_table, existence_region


def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes ``energy_barrier.png`` and ``energy_barrier.json``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # the default resolution in both modes: it is also the fastest (draft N = 10 finds an
    # extra, unstable, under-resolved branch grazing the ground and spends 400 steps on it)
    scene = load_scene("fig3-strip")
    deltas = np.linspace(0.9, 1.5, 7 if fast else 25)
    region = existence_region(scene, deltas)
    table = barrier_table(scene, [2.0], n_delta=4 if fast else 10)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    ok = [r for r in region if math.isfinite(r["x_lo"])]
    ws = np.array([r["we_sqrt"] for r in ok])
    xlo = np.array([r["x_lo"] for r in ok])
    xhi = np.array([r["x_hi"] for r in ok])
    ax1.fill_betweenx(ws, xlo, xhi, color="tab:blue", alpha=0.25,
                      label="encapsulated, lifted: stable equilibrium")
    ax1.plot(xlo, ws, "b-", label=r"lift-off point reaches $S_1$")
    ax1.plot(xhi, ws, "r-", label="tail touches the ground (floppy)")
    ax1.set_xlabel(r"$x/\ell_{eg}$")
    ax1.set_ylabel(r"$\mathrm{We}^{1/2}$ (spreading law)")
    ax1.set_xlim(0, 6)
    ax1.set_ylim(0, 4)
    ax1.legend(fontsize=7, loc="upper right")
    ax1.set_title("(a) where the lifted wrapped state exists", fontsize=9)
    row = table[0]
    w = np.array(row["we_sqrt"])
    ax2.semilogy(w, row["release"], "o-", label=r"$E_\mathrm{flat} - E_\mathrm{wrapped}$ (released)")
    ax2.semilogy(w, row["e_gravity"], "s-", label="gravity energy of the wrapped state")
    ax2.semilogy(w, np.maximum(row["unwrap"], 1e-4), "^-",
                 label="unwrap to the topology edge")
    ax2.semilogy(w, row["kinetic"], "k--", label="drop kinetic energy at impact")
    ax2.set_xlabel(r"$\mathrm{We}^{1/2}$")
    ax2.set_ylabel(r"energy $/\ (\mu g \ell_{eg}^2)$")
    ax2.legend(fontsize=7)
    ax2.set_title(r"(b) $x = 2\,\ell_{eg}$", fontsize=9)
    fig.tight_layout()
    png = out / "energy_barrier.png"
    fig.savefig(png, dpi=120)
    plt.close(fig)

    def clean(v):
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [clean(x) for x in v]
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            return None
        return v

    js = out / "energy_barrier.json"
    js.write_text(json.dumps(record(clean({
        "units": "energies in mu g l_eg^2 = B / l_eg; lengths in l_eg",
        "region": region,
        "x2": table[0],
        "not_handled": "open state and floppy/rolled encapsulated states (other contact "
                       "topologies); see elastocap.strip.branches.NOT_HANDLED",
    }), scene, fast=fast), indent=1))
    return [png, js]
