"""The sweep benchmark script runs (fast mode) and reports consistent numbers."""

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "sweep_speed.py"


@pytest.mark.slow
def test_sweep_benchmark_fast_mode(capsys):
    spec = importlib.util.spec_from_file_location("sweep_speed", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.main(workers=2, fast=True, progress="none")
    # 3 x 3 grid plus refinement; every grid point lies on the strip
    assert out["impacts"] >= 9
    assert out["per_core_per_s"] == pytest.approx(out["impacts"] / out["wall_s"] / 2)
    assert "impacts per second per core" in capsys.readouterr().out
