"""Statics of the strip of the paper's Fig 3: gravity, a frictionless ground, a drop.

:class:`~elastocap.strip.problem.StripProblem` (the lifted part as a free-boundary
elastica, one contact topology, spectral), :func:`~elastocap.strip.branches.trace_strip_branches`
(its branches, folds, stability), :mod:`elastocap.strip.barrier` (energies of the wrapped
state against the impact's), :mod:`elastocap.strip.discrete` (the discrete strip with
z >= 0 at every node: any contact topology, active-set Newton, ground reactions) and
:mod:`elastocap.strip.mep` (the saddle between the open and the encapsulated state by a
string method, and the energy barrier).
"""
