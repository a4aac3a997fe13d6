"""continuation: generic pseudo-arclength continuation of F(u, p) = 0 (numpy/scipy only)."""
