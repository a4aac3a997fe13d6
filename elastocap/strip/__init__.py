"""Statics of the strip of the paper's Fig 3: gravity, a frictionless ground, a drop.

One model, the discrete strip with z >= 0 at every node (any contact topology; its energy is
the dynamic model's, term for term): :mod:`elastocap.strip.model` (energy, exact
derivatives, geometry), :mod:`elastocap.strip.solve` (active-set Newton, descent,
stability), :mod:`elastocap.strip.trace` (every branch in Delta: seeds, continuation at a
fixed contact set, contact events, folds, the stable window), :mod:`elastocap.strip.barrier`
(string method, index-1 saddle, barrier graph over every traced saddle) and
:mod:`elastocap.strip.plot`.
"""
