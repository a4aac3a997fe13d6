"""elastocap: a thin elastic strip wrapping a drop (capillary origami), statics and dynamics.

Units: every quantity is dimensionless unless a docstring says otherwise; scenes fix the
units through the rod's bending modulus B, mass per length mu and the line tension gamma
(see :mod:`elastocap.units` for the conversion from a dimensional experiment).

The main API, imported on first use (``import elastocap`` stays cheap)::

    import elastocap as ec
    scene = ec.load_scene("supp-fig5", {"drop.area": 1.2})
    bs = ec.trace_branches(scene)            # every equilibrium branch, folds located
    ec.assert_folds(bs, "reference.json")    # in a user's CI
    res = ec.run_impact(scene)               # an impact run to rest
    ov = ec.run_overlay(scene, [3.0, 4.0])   # impacts classified against the statics
    sw = ec.run_sweep(scene, xs, deltas=ds)  # a phase diagram, resumable with store=
"""

from importlib import import_module

from elastocap._version import __version__

#: public name -> module that defines it
_API = {
    "load_scene": "elastocap.scene",
    "Scene": "elastocap.scene",
    "SceneError": "elastocap.scene",
    "trace_branches": "elastocap.statics.branches",
    "find_folds": "elastocap.statics.branches",
    "BranchSet": "elastocap.branchset",
    "run_impact": "elastocap.impact",
    "run_overlay": "elastocap.overlay",
    "run_sweep": "elastocap.sweep.engine",
    "assert_folds": "elastocap.testing",
}

__all__ = ["__version__", *_API]


def __getattr__(name):
    if name in _API:
        value = getattr(import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'elastocap' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API))
