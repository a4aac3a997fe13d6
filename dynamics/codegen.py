"""What the generated steppers of both methods share: how an effect's kernel is imported
into a generated module, and the key of the sources it depends on.

Both methods (:mod:`dynamics.rattle`, :mod:`dynamics.midpoint`) generate, per combination
of effect kernels, the Python source of a module that imports exactly those kernels and
calls them in a fixed order, and load it through :func:`dynamics.cache.load_module`, so
that numba's on-disk cache applies to the compiled loop.  Generated code uses numba's
public API only (``numba.njit``).
"""

from __future__ import annotations

import importlib

from . import contact
from .cache import dependency_digest, is_compiled
from .effects import is_self_contact

__all__ = ["cold_kernel_groups", "compile_estimate", "kernel_ref", "stepper_depends"]

#: What a first compile costs beyond the stepper's own code (wall s of ``compile_time``,
#: fig3-strip and supp-fig5 impacts, 2-core machine at load about 1; "Compile cost" in
#: docs/guide/time-stepping.md): the package's kernels when numba's cache does not hold
#: them yet (a fresh install), 11.9-12.7 s for either method; self-contact linked into a
#: stepper, 6.6-8.5 s; the contact kernels when numba's cache does not hold them, 31-39 s.
KERNELS_COLD_S = 12.0
CONTACT_LINK_S = 7.5
CONTACT_KERNELS_S = 35.0


def cold_kernel_groups(effects) -> tuple[str, ...]:
    """The groups of kernels shared by several steppers that these effects need and numba's
    cache does not hold yet: ``("contact",)`` for self-contact's kernels, else ``()``
    (the names of their locks, :func:`dynamics.cache.compile_lock`)."""
    if any(is_self_contact(e) for e in effects) and not is_compiled(
            contact, ("_project_positions", "_project_velocities")):
        return ("contact",)
    return ()


def compile_estimate(base_s, per_effect_s, effects, kernels):
    """Seconds a first compile of a stepper is announced to take: ``base_s`` plus
    ``per_effect_s`` per effect other than self-contact, plus :data:`KERNELS_COLD_S` when
    numba's cache lacks one of ``kernels`` (``(module, function names)`` pairs, the
    method's own kernels), plus the cost of self-contact when the effects have it
    (:data:`CONTACT_LINK_S`, and :data:`CONTACT_KERNELS_S` when its kernels are not
    cached either)."""
    contact_effects = [e for e in effects if is_self_contact(e)]
    est = base_s + per_effect_s * (len(effects) - len(contact_effects))
    if not all(is_compiled(m, fns) for m, fns in kernels):
        est += KERNELS_COLD_S
    if contact_effects:
        est += CONTACT_LINK_S
        if "contact" in cold_kernel_groups(effects):
            est += CONTACT_KERNELS_S
    return est


def kernel_ref(effect):
    """(module, name) through which the generated module imports an effect's kernel."""
    k = getattr(effect, "kernel", None)
    k = getattr(k, "__func__", k)  # a dispatcher read through an instance is a bound method
    if k is None or not hasattr(k, "py_func"):
        raise TypeError(
            f"effect {getattr(effect, 'name', effect)!r}: kernel must be a numba "
            f"njit(cache=True) dispatcher, got {type(k).__name__}"
        )
    mod, name = k.__module__, k.__name__
    ok = False
    if mod != "__main__":
        try:
            ok = getattr(importlib.import_module(mod), name, None) is k
        except ImportError:
            ok = False
    if not ok:
        raise ValueError(
            f"effect {effect.name!r}: kernel {mod}.{name} is not importable by that name; "
            "define it at module level of an importable module (not in __main__ or inside "
            "a function) so the generated stepper can import and cache it"
        )
    return mod, name


def stepper_depends(refs):
    """:func:`dynamics.cache.dependency_digest` of what a generated stepper uses: the
    ``dynamics`` kernels and the effect kernels' modules with what they use."""
    return dependency_digest(["dynamics.bending", "dynamics.constraints", "dynamics.contact",
                              "dynamics.effects", "dynamics.rod",
                              *(r[1] for r in refs)])




#: Decorator of the generated dispatch functions: inlined into their callers (a call with
#: its arrays reference-counted would cost more than the kernel calls it holds).
_DISPATCH = '@numba.njit(cache=True, inline="always")'


#: Functions every method's loop uses the same way, generated into each module (inlined).
#: ``_at_rest(ke, dt, rest)``: the rest criterion of :class:`dynamics.RestCriterion`
#: (``rest = [threshold, duration, time below so far]``), advanced by one step of kinetic
#: energy ``ke``; True once the rod has stayed below the threshold for the duration.
#: ``_record_constraint_error(x, edge_len, diag)``: the relative edge-length error of the
#: final state into ``diag[0]`` (the largest seen).
#: ``_copy1(dst, src)`` / ``_copy2(dst, src)``: ``dst[...] = src`` for arrays of one and two
#: dimensions and equal shapes, as loops.  numba compiles a slice assignment from an array
#: with a formatted shape-mismatch message (string formatting, about 3.5 s of compile
#: the first time in a process); the loops have none.
_SHARED = '''
@numba.njit(cache=True, inline="always")
def _copy1(dst, src):
    for i in range(dst.shape[0]):
        dst[i] = src[i]


@numba.njit(cache=True, inline="always")
def _copy2(dst, src):
    for i in range(dst.shape[0]):
        for j in range(dst.shape[1]):
            dst[i, j] = src[i, j]


@numba.njit(cache=True, inline="always")
def _at_rest(ke, dt, rest):
    if rest[0] > 0.0:
        if ke < rest[0]:
            rest[2] += dt
            if rest[2] >= rest[1]:
                return True
        else:
            rest[2] = 0.0
    return False


@numba.njit(cache=True, inline="always")
def _record_constraint_error(x, edge_len, diag):
    err0, edge = _constraint_error(x, edge_len)
    if err0 > diag[0]:
        diag[0] = err0
'''


def render(template: str, refs, imports: str = "") -> str:
    """The source of a stepper module: ``template`` with the calls of the effects.

    Parameters
    ----------
    template : str
        Python source of the method's functions (a :class:`string.Template`): ``$pargs``
        and ``$fargs`` stand for the effects' parameters, one argument ``, params``: the
        tuple of every effect's parameter array, in the order of ``refs`` (one argument
        whatever the number of effects, see below).  The template calls the generated
        dispatch functions below and reads the flags.
    refs : sequence of (kind, module, name, stiffness, native)
        Per effect: its kind, where its kernel is imported from, the (module, name) of its
        optional stiffness hook (or None), and whether the method handles the effect
        itself instead of calling its kernel: False, True (a ground: its height is read
        by ``_ground_height``, its kernel called through ``_ground``) or ``"contact"``
        (the rod's self-contact, both methods; its thickness is read by
        ``_contact_thickness``).
    imports : str
        The method's own import lines.

    Generated, each ``numba.njit(cache=True, inline="always")``:

    ``_external_forces(x, v, t, edge_len, mass, F, energy$fargs)``
        Adds each force effect's force to ``F``; its energy to ``energy[1 + k]``.
    ``_damp(x, v, t, edge_len, mass, h$pargs)``
        Each damping effect over ``h``.
    ``_constrain(x, v, t, edge_len, winv, stage$pargs)``
        Each constraint effect not handled natively, at ``stage``.
    ``_stiffness(x, v, t, edge_len, mass, K, U, C$fargs) -> int``
        The stiffness hooks of the force effects (low-rank parts in consecutive blocks of
        ``U`` and ``C``); returns the total rank.
    ``_ground(x, v, t, edge_len, winv, stage$pargs)``
        The natively handled ground's kernel at ``stage`` (RATTLE calls it; the midpoint
        method does not).
    ``_ground_height(t$pargs) -> float``
        The height of the natively handled ground (0.0 without one).
    ``_contact_thickness(t$pargs) -> float``
        The thickness of the self-contact (0.0 without one).

    ``_at_rest(ke, dt, rest) -> bool`` and ``_record_constraint_error(x, edge_len, diag)``
        The rest criterion and the final constraint-error check (:data:`_SHARED`).

    Flags: ``HAS_DAMPING``, ``HAS_CONSTRAINTS`` (non-native), ``HAS_GROUND`` (native),
    ``HAS_STIFFNESS``, ``HAS_CONTACT`` (native self-contact).  Without a self-contact the
    template's ``if HAS_CONTACT:`` blocks are compiled out (a global constant to numba).
    """
    import string

    kernel_imports = []
    forces, damps, cons, stiff, ground, contact, holds = [], [], [], [], [], [], []
    for j, (kind, mod, name, hook, native) in enumerate(refs):
        p = f"params[{j}]"
        if native == "contact":
            contact.append(p)
            continue
        if native:
            ground.append(p)
            kernel_imports.append(f"from {mod} import {name} as _k{j}")
            holds.append(f"    _k{j}(x, v, t, {p}, edge_len, winv, stage)")
            continue
        kernel_imports.append(f"from {mod} import {name} as _k{j}")
        if kind == "force":
            forces.append(f"    energy[{len(forces) + 1}] = _k{j}(x, v, t, {p}, edge_len, "
                          "mass, F)")
            if hook is not None:
                kernel_imports.append(f"from {hook[0]} import {hook[1]} as _s{j}")
                stiff += [
                    f"    k = _s{j}(x, v, t, {p}, edge_len, mass, K, U[r:r + STIFFNESS_RANK],",
                    "             C[r:r + STIFFNESS_RANK, r:r + STIFFNESS_RANK])",
                    "    if k < 0 or k > STIFFNESS_RANK:",
                    "        raise ValueError('a stiffness hook returned a rank outside "
                    "[0, STIFFNESS_RANK]')",
                    "    r += k"]
        elif kind == "damping":
            damps.append(f"    _k{j}(x, v, t, {p}, edge_len, mass, h)")
        else:
            cons.append(f"    _k{j}(x, v, t, {p}, edge_len, winv, stage)")
    # one argument, the tuple of all effects' parameter arrays, whatever the number of
    # effects: a call with more than 30 arguments is compiled by CPython as a call with
    # ``*args`` (CALL_FUNCTION_EX), which numba cannot inline
    pargs = fargs = ", params"
    head = [
        "import numba",
        "import numpy as np",
        "from dynamics.constraints import constraint_error as _constraint_error",
        "from dynamics.effects import STIFFNESS_RANK",
        imports.rstrip(),
        *kernel_imports,
        "",
        f"HAS_DAMPING = {bool(damps)}",
        f"HAS_CONSTRAINTS = {bool(cons)}",
        f"HAS_GROUND = {bool(ground)}",
        f"HAS_STIFFNESS = {bool(stiff)}",
        f"HAS_CONTACT = {bool(contact)}",
        "", "",
        _DISPATCH,
        f"def _external_forces(x, v, t, edge_len, mass, F, energy{fargs}):",
        *forces, "    return None", "", "",
        _DISPATCH,
        f"def _damp(x, v, t, edge_len, mass, h{pargs}):",
        *damps, "    return None", "", "",
        _DISPATCH,
        f"def _constrain(x, v, t, edge_len, winv, stage{pargs}):",
        *cons, "    return None", "", "",
        _DISPATCH,
        f"def _stiffness(x, v, t, edge_len, mass, K, U, C{fargs}):",
        "    r = 0", *stiff, "    return r", "", "",
        _DISPATCH,
        f"def _ground(x, v, t, edge_len, winv, stage{pargs}):",
        *holds, "    return None", "", "",
        _DISPATCH,
        f"def _ground_height(t{pargs}):",
        f"    return {ground[0] + '[0]' if ground else '0.0'}",
        "", "",
        _DISPATCH,
        f"def _contact_thickness(t{pargs}):",
        f"    return {contact[0] + '[0]' if contact else '0.0'}",
        "", "",
        _SHARED,
    ]
    return "\n".join(head) + string.Template(template).substitute(pargs=pargs, fargs=fargs)
