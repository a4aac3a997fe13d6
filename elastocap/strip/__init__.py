"""Statics of the strip of the paper's Fig 3: gravity, a frictionless ground, a drop.

:class:`~elastocap.strip.problem.StripProblem` (the lifted part as a free-boundary
elastica), :func:`~elastocap.strip.branches.trace_strip_branches` (branches, folds,
stability), :mod:`elastocap.strip.barrier` (the energy barrier).
"""
