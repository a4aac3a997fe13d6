"""Fixtures for the dynamics tests."""

import numpy as np
import pytest
from dyn_helpers import rod_from_angles


@pytest.fixture
def wavy_rod():
    """A free rod of 40 edges, length 4.6, gently curved (bending energy 0.18)."""
    n = 40
    h = 4.6 / n
    s = (np.arange(n) + 0.5) * h
    return rod_from_angles(0.3 * np.sin(2 * np.pi * s / 4.6), h)
