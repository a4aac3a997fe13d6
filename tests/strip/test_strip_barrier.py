"""Energies of the encapsulated strip and the figure (fast mode), with numbers."""

from __future__ import annotations

import json
import math

import numpy as np

from elastocap.drop import cap_geometry
from elastocap.scene import load_scene
from elastocap.strip.barrier import flat_energy, kinetic_energy, tip_angle_path
from elastocap.strip.branches import strip_problem_for


def test_kinetic_energy_in_scene_units():
    # (1/2) rho V U^2 in SI for the paper's drop, over mu_hat g l_eg^2 (mu_hat = 51.8 g/m^2
    # x 2 mm, l_eg = 3.4996 mm); V = A l_eg^3 (the paper's A = V / l_eg in 2D units)
    scene = load_scene("fig3-strip")
    rho, gamma, R, U, g = 1000.0, 0.072, 1.55e-3, 0.5, 9.81
    leg, mu_hat = 3.4996e-3, 51.8e-3 * 2e-3
    we = rho * U**2 * R / gamma
    e_si = 0.5 * rho * (0.36 * leg**3) * U**2
    e_unit = mu_hat * g * leg**2
    # the scene rounds gamma_hat* = 40.5 to 40 (Methods): 1.5% apart
    assert abs(kinetic_energy(scene, we) / (e_si / e_unit) - 1.0) < 0.02
    # the coefficient: E_k = A gamma We / (2 w R) = 28.4 We
    assert abs(kinetic_energy(scene, 1.0) - 28.44) < 0.01


def test_flat_energy_is_the_cap_on_a_straight_strip():
    # the semicircle: d = 2 r, A = pi r^2 / 2, lambda = pi r
    r = 0.5
    assert abs(flat_energy(math.pi * r * r / 2, 40.0, 2 * r) - 40.0 * math.pi * r) < 1e-12
    assert flat_energy(0.36, 40.0, 1.16) == 40.0 * cap_geometry(0.36, 1.16)[3]


def test_tip_angle_path_leaves_at_S1():
    scene = load_scene("fig3-strip")
    P = strip_problem_for(scene)
    from elastocap.statics.branches import newton
    from elastocap.strip.branches import seeds

    u = next(v for v in (newton(P, s, 1.16, 1e-10, max_iter=40) for s in seeds(P))
             if v is not None and v[-1] < P.s1)
    path = tip_angle_path(P, u)
    # starts on the equilibrium (couple 0) and unwinds with a restoring couple C < 0
    assert abs(path["couple"][0]) < 1e-8
    assert np.all(path["couple"][1:] < 0)
    assert np.all(np.diff(path["energy"]) > 0)  # the wrapped state is a local minimum
    assert path["edge"] == "lift_off_at_S1"
    # measured at N = 14: the edge is reached at theta(L) = 2.6772 rad (from 3.5049), 0.19
    # energy units above the wrapped state
    assert abs(path["edge_tip_angle"] - 2.6772) < 1e-3
    assert 0.15 < path["edge_energy"] - path["energy"][0] < 0.25
    assert path["edge_energy"] > path["energy"].max()


def test_energy_barrier_figure_fast(tmp_path):
    from elastocap.paper_figures.energy_barrier import main

    paths = main(tmp_path, fast=True)
    assert all(p.exists() for p in paths)
    data = json.loads((tmp_path / "energy_barrier.json").read_text())
    row = data["x2"]
    # the wrapped state at x = 2 exists for 0.924 < Delta < 1.278 (events, see
    # test_strip_statics); its energy is below the release state's by 7-23 units
    assert 0.92 < row["delta"][0] < 0.94 and 1.25 < row["delta"][-1] < 1.28
    assert all(r > 5.0 for r in row["release"])
    assert all(k > r for k, r in zip(row["kinetic"], row["release"], strict=True))
    ok = [r for r in data["region"] if r["x_lo"] is not None]
    assert ok and all(1.4 < r["x_lo"] < r["x_hi"] < 2.4 for r in ok)
