"""Scenes: TOML (or a built-in name) -> a validated, immutable :class:`Scene`.

A scene is dimensionless: lengths in the scene's unit (l_ec for the no-gravity scenes,
l_eg for the gravity ones), B, mu and gamma as given. Sections and keys::

    [rod]         length, bending_modulus = 1, mass_per_length = 1, thickness = 0 (the rod's
                  diameter for self-contact; 0 = off, the paper's model)
    [drop]        area, wetted_length, line_tension = 1,
                  center (arclength of the drop centre from S = 0; default L/2)
                  or distance_from_end (the paper's x: centre at S = L - x)
                  interface_contact = "ignore" | "wet" (when the drop's interface touches
                  the dry rod: the paper's model lets it pass and flags it, or the liquid
                  wets the touched point; docs/guide/interface-contact.md)
    [[drop.events]]  time, s1 and/or s2 (new contact arclengths: the secondary drop, Fig 5)
    [effects]     gravity = 0 (g; 0 = off), ground = false (frictionless z >= 0), damping = 0
    [spreading]   drop_radius, delta0, coefficient = 0.32 (lengths in scene units): converts
                  Delta <-> We^(1/2) by the paper's spreading law
    [numerics]    solver settings, see :data:`NUMERICS_KEYS`
    [experiment]  dimensional SI inputs (see :class:`elastocap.units.Experiment`) standing in
                  for [rod], [drop] and [spreading]; units g = mu = B = 1

Every error is a :class:`SceneError` naming the key, the value received and what is allowed.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import math
import numbers
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from elastocap import units
from elastocap.io import check_stem

__all__ = [
    "Scene",
    "SceneError",
    "Rod",
    "Drop",
    "DropEvent",
    "Effects",
    "Spreading",
    "Numerics",
    "builtin_scene_names",
    "load_scene",
    "parse_override",
]


class SceneError(ValueError):
    """Invalid scene input. ``key`` is the dotted key, ``value`` what was given."""

    def __init__(self, key: str, value: Any, allowed: str):
        self.key = key
        self.value = value
        self.allowed = allowed
        text = repr(value)
        if len(text) > 80:  # a huge number or table: its start and its length
            text = f"{text[:40]}... ({len(text)} characters)"
        super().__init__(f"{key}: got {text}; {allowed}")

    def __reduce__(self):  # pickles (a sweep worker's refusal reaches the sweep intact)
        return type(self), (self.key, self.value, self.allowed)


# ---------------------------------------------------------------------------------------------
# schema: section -> key -> (kind, default). kind: "pos" (finite > 0), "nonneg" (finite >= 0),
# "real" (finite), "bool", "int+" (integer >= 1), "str:<a|b|c>", "opt-pos" (None or > 0).
# REQUIRED marks a key with no default.
REQUIRED = object()

ROD_KEYS: dict[str, tuple[str, Any]] = {
    "length": ("pos", REQUIRED),
    "bending_modulus": ("pos", 1.0),
    "mass_per_length": ("pos", 1.0),
    "thickness": ("nonneg", 0.0),
}

#: Largest rod.thickness, relative to rod.length: the rod is slender.
MAX_THICKNESS_OVER_LENGTH = 0.1
DROP_KEYS: dict[str, tuple[str, Any]] = {
    "area": ("pos", REQUIRED),
    "wetted_length": ("pos", REQUIRED),
    "line_tension": ("pos", 1.0),
    "center": ("real", None),
    "distance_from_end": ("real", None),
    "events": ("events", ()),
    "interface_contact": ("str:ignore|wet", "ignore"),
}
EVENT_KEYS: dict[str, tuple[str, Any]] = {
    "time": ("nonneg", REQUIRED),
    "s1": ("real", None),
    "s2": ("real", None),
}
EFFECTS_KEYS: dict[str, tuple[str, Any]] = {
    "gravity": ("nonneg", 0.0),
    "ground": ("bool", False),
    "damping": ("nonneg", 0.0),
}
SPREADING_KEYS: dict[str, tuple[str, Any]] = {
    "drop_radius": ("pos", REQUIRED),
    "delta0": ("nonneg", REQUIRED),
    "coefficient": ("pos", units.SPREADING_COEFFICIENT),
}
#: Solver settings. Statics: Chebyshev points per segment, Newton tolerance, continuation
#: steps. Dynamics: edges, time step (0 = automatic, a fraction of the stable bound), final
#: time, rest criterion, and the time stepper (explicit RATTLE, or the implicit midpoint
#: rule). Accuracy presets map to these (see README, "What
#: accuracy costs").
NUMERICS_KEYS: dict[str, tuple[str, Any]] = {
    "accuracy": ("str:draft|default|publication", "default"),
    "cheb_points": ("int+", 0),
    "newton_tol": ("pos", 1e-11),
    "max_steps": ("int+", 2000),
    "n_edges": ("int+", 0),
    "dt": ("nonneg", 0.0),
    "t_max": ("pos", 200.0),
    "rest_kinetic": ("pos", 1e-6),
    "rest_time": ("pos", 1.0),
    "integrator": ("str:rattle|implicit", "rattle"),
}
#: Allowed ranges of the numerics keys the statics uses: (lo, hi, why). A value outside is
#: refused like any bad scene value (key, value and range named). cheb_points 0 means the
#: accuracy preset (16/24/40); above 128 the dense spectral operators cost seconds per
#: Newton step and round-off in the differentiation matrices (~N^2 eps) exceeds the
#: default tolerance. newton_tol below 1e-12 is under the round-off floor of the residual
#: at the default resolution (measured: at 1e-13 a branch point moves by 1e-6, at 1e-15 no
#: branch converges); above 1e-6 no number is worth reporting.
NUMERICS_RANGES: dict[str, tuple[float, float, str]] = {
    "cheb_points": (4, 128, "0 (the accuracy preset) or 4 <= cheb_points <= 128"),
    "newton_tol": (1e-12, 1e-6, "1e-12 <= newton_tol <= 1e-6 (below 1e-12 is under the "
                   "residual's round-off floor)"),
    "max_steps": (10, 100_000, "10 <= max_steps <= 100000"),
    # a fraction of the capillary energy gamma Delta: a rod moving with a percent of the
    # energy that drives it is not at rest (rest_kinetic = 1e9 read supp-fig5 at Delta = 4,
    # which encapsulates at t = 65, as open and at rest at t = 1)
    "rest_kinetic": (0.0, 1e-2, "0 < rest_kinetic <= 0.01 (a fraction of the capillary "
                     "energy gamma Delta)"),
}
EXPERIMENT_KEYS: dict[str, tuple[str, Any]] = {
    "drop_radius": ("pos", REQUIRED),
    "areal_mass": ("pos", REQUIRED),
    "length": ("pos", REQUIRED),
    "impact_distance": ("pos", REQUIRED),
    "surface_tension": ("pos", 0.072),
    "liquid_density": ("pos", 1000.0),
    "gravity": ("pos", 9.81),
    "width": ("pos", 2e-3),
    "impact_speed": ("nonneg", 0.0),
    "bending_modulus": ("opt-pos", None),
    "youngs_modulus": ("opt-pos", None),
    "thickness": ("opt-pos", None),
    "poisson_ratio": ("real", None),
    "delta0": ("opt-pos", None),
}
SECTIONS: dict[str, dict[str, tuple[str, Any]]] = {
    "rod": ROD_KEYS,
    "drop": DROP_KEYS,
    "effects": EFFECTS_KEYS,
    "spreading": SPREADING_KEYS,
    "numerics": NUMERICS_KEYS,
    "experiment": EXPERIMENT_KEYS,
}
TOP_KEYS = {"name", "description", *SECTIONS}


def _suggest(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1, cutoff=0.5)
    return f" Did you mean '{close[0]}'?" if close else ""


#: Largest whole number a count key accepts: counts are stored in 32-bit integers inside
#: the engines; the resource guards (:mod:`elastocap.cli_args`) refuse far smaller ones.
INT_MAX = 2**31 - 1


def _is_bool(value: Any) -> bool:
    import numpy as np

    return isinstance(value, bool | np.bool_)


def _check_value(key: str, kind: str, value: Any) -> Any:
    """Validate one value against its kind; return the normalised value (Python floats and
    ints, -0.0 as 0.0; numpy scalars are accepted like Python numbers)."""
    if kind in ("pos", "nonneg", "real", "opt-pos"):
        if kind == "opt-pos" and value is None:
            return None
        if _is_bool(value) or not isinstance(value, numbers.Real):
            raise SceneError(key, value, "expected a number")
        try:
            v = float(value)
        except OverflowError:
            v = math.inf
        if not math.isfinite(v):
            raise SceneError(key, value, "expected a finite number (not NaN or inf)")
        if kind in ("pos", "opt-pos") and v <= 0.0:
            raise SceneError(key, value, "expected a number > 0")
        if kind == "nonneg" and v < 0.0:
            raise SceneError(key, value, "expected a number >= 0")
        return v + 0.0  # -0.0 -> 0.0: equal physics, equal digests
    if kind == "bool":
        if not _is_bool(value):
            raise SceneError(key, value, "expected true or false")
        return bool(value)
    if kind == "int+":
        if _is_bool(value) or not isinstance(value, numbers.Integral):
            raise SceneError(key, value, "expected a whole number")
        if value < 0:
            raise SceneError(key, value, "expected a whole number >= 0 (0 = preset default)")
        if value > INT_MAX:
            raise SceneError(key, value, f"expected a whole number <= {INT_MAX}")
        return int(value)
    if kind.startswith("str:"):
        choices = kind[4:].split("|")
        if not isinstance(value, str) or value not in choices:
            raise SceneError(key, value, f"expected one of {', '.join(choices)}")
        return value
    raise AssertionError(kind)


def _plain(obj: Any) -> Any:
    """A copy of raw scene data with numpy scalars as Python values (so it saves as JSON)."""
    import numpy as np

    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _read_section(raw: Any, name: str, schema: dict[str, tuple[str, Any]]) -> dict[str, Any]:
    if not isinstance(raw, dict):
        raise SceneError(name, raw, "expected a table of keys")
    for k in raw:
        if k not in schema:
            raise SceneError(
                f"{name}.{k}",
                raw[k],
                f"unknown key; allowed keys in [{name}]: {', '.join(schema)}."
                + _suggest(k, schema),
            )
    out: dict[str, Any] = {}
    for k, (kind, default) in schema.items():
        if kind == "events":
            continue
        if k in raw:
            out[k] = _check_value(f"{name}.{k}", kind, raw[k])
        elif default is REQUIRED:
            raise SceneError(f"{name}.{k}", None, f"missing: [{name}] needs '{k}'")
        else:
            out[k] = default
    return out


# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rod:
    """An inextensible, naturally straight elastica. length L, bending_modulus B, mass per
    unit length mu (scene units)."""

    length: float
    bending_modulus: float = 1.0
    mass_per_length: float = 1.0
    #: Diameter for self-contact (scene units): non-adjacent parts of the rod stay this far
    #: apart (:class:`dynamics.SelfContact`); 0 = off (the paper's model, no contact).
    thickness: float = 0.0


@dataclass(frozen=True)
class DropEvent:
    """At ``time``, the contact arclengths jump to ``s1`` / ``s2`` (None = unchanged)."""

    time: float
    s1: float | None = None
    s2: float | None = None


@dataclass(frozen=True)
class Drop:
    """A quasi-static 2D drop of area A pinned at S1 = center - Delta/2, S2 = center + Delta/2."""

    area: float
    wetted_length: float
    center: float
    line_tension: float = 1.0
    events: tuple[DropEvent, ...] = ()
    #: What happens when the interface touches the rod outside [S1, S2]: "ignore" (the
    #: paper's model: it passes through, flagged) or "wet" (the contact line on that side
    #: jumps to the touched point, the area kept).
    interface_contact: str = "ignore"

    @property
    def s1(self) -> float:
        return self.center - 0.5 * self.wetted_length

    @property
    def s2(self) -> float:
        return self.center + 0.5 * self.wetted_length


@dataclass(frozen=True)
class Effects:
    """Effects the scene names. gravity g (0 = off), ground (frictionless z >= 0), damping
    (viscous drag coefficient per unit length, force -c v per length)."""

    gravity: float = 0.0
    ground: bool = False
    damping: float = 0.0

    def names(self) -> tuple[str, ...]:
        """The effects that are on, in a fixed order."""
        out = []
        if self.gravity > 0.0:
            out.append("gravity")
        if self.ground:
            out.append("ground")
        if self.damping > 0.0:
            out.append("damping")
        return tuple(out)


@dataclass(frozen=True)
class Spreading:
    """The paper's spreading law (Delta - delta0) / (2 R) = coefficient * We^(1/2), scene units."""

    drop_radius: float
    delta0: float
    coefficient: float = units.SPREADING_COEFFICIENT

    def delta(self, we_sqrt: float) -> float:
        return self.delta0 + 2.0 * self.drop_radius * self.coefficient * we_sqrt

    def we_sqrt(self, delta: float) -> float:
        return (delta - self.delta0) / (2.0 * self.drop_radius * self.coefficient)


@dataclass(frozen=True)
class Numerics:
    """Solver settings (0 for cheb_points, n_edges or dt = the accuracy preset's value)."""

    accuracy: str = "default"
    cheb_points: int = 0
    newton_tol: float = 1e-11
    max_steps: int = 2000
    n_edges: int = 0
    dt: float = 0.0
    t_max: float = 200.0
    rest_kinetic: float = 1e-6
    rest_time: float = 1.0
    integrator: str = "rattle"


def _refuse_change(*_args, **_kwargs):
    raise TypeError("a Scene is immutable, its data too: build another one with "
                    "Scene.with_overrides (or from a copy: json.loads(scene.to_json()))")


class _ReadOnly:
    """What the read-only TOML containers share: a copy is the object itself, a pickle
    rebuilds it read-only from the plain container (``_plain``)."""

    __slots__ = ()

    def __reduce__(self):
        return (type(self), (self._plain(self),))

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


class FrozenTable(_ReadOnly, dict):
    """A read-only copy of a TOML table (its tables and arrays read-only too): a ``dict``
    for every reader (``json.dumps``, ``==``, ``isinstance``), but any change raises
    ``TypeError``. Copies and pickles stay read-only."""

    __slots__ = ()
    _plain = dict

    def __init__(self, items=()):
        super().__init__((k, _frozen(v)) for k, v in dict(items).items())

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _refuse_change
    __ior__ = _refuse_change


class FrozenArray(_ReadOnly, list):
    """A read-only TOML array (see :class:`FrozenTable`)."""

    __slots__ = ()
    _plain = list

    def __init__(self, items=()):
        super().__init__(_frozen(v) for v in items)

    __setitem__ = __delitem__ = append = extend = insert = remove = pop = clear = _refuse_change
    sort = reverse = __iadd__ = __imul__ = _refuse_change


def _frozen(value):
    if isinstance(value, dict):
        return value if isinstance(value, FrozenTable) else FrozenTable(value)
    if isinstance(value, list):
        return value if isinstance(value, FrozenArray) else FrozenArray(value)
    return value


@dataclass(frozen=True)
class Scene:
    """A validated, immutable scene. ``data`` is the resolved input table (overrides applied)
    from which the scene was built, read-only (:class:`FrozenTable`); it is what output
    files record."""

    name: str
    rod: Rod
    drop: Drop
    effects: Effects
    numerics: Numerics
    spreading: Spreading | None = None
    experiment: units.Experiment | None = None
    description: str = ""
    data: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        # a copy the caller cannot change under the scene (its digest, its runs)
        object.__setattr__(self, "data", _frozen(dict(self.data)))

    @property
    def distance_from_end(self) -> float:
        """The paper's x = L - center."""
        return self.rod.length - self.drop.center

    def to_json(self) -> str:
        """JSON of the resolved input (sorted keys): what a result file records."""
        return json.dumps(self.data, sort_keys=True, separators=(",", ":"))

    def canonical(self) -> dict:
        """The validated values (floats, defaults filled in): equal physics, equal dict,
        however the input was typed (``40`` or ``40.0``, a default written out or not)."""
        from dataclasses import asdict

        rod = asdict(self.rod)
        if not rod["thickness"]:
            rod.pop("thickness")  # absent and 0 are the same scene (and digest)
        drop = asdict(self.drop)
        if drop["interface_contact"] == "ignore":
            # the paper's model, the default: left out so that the digests of scenes that
            # do not name the key (and of the results stored under them) are unchanged
            del drop["interface_contact"]
        return {
            "rod": rod,
            "drop": drop,
            "effects": asdict(self.effects),
            "numerics": asdict(self.numerics),
            "spreading": None if self.spreading is None else asdict(self.spreading),
            "experiment": None if self.experiment is None else asdict(self.experiment),
        }

    def digest(self) -> str:
        """SHA-256 of the canonical validated values: equal scenes, equal digests."""
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def with_overrides(self, overrides: dict[str, Any]) -> Scene:
        """A new scene with dotted-key overrides applied and validated again."""
        return build_scene(_apply_overrides(self.data, overrides), self.name)

    def derived(self) -> dict[str, Any]:
        """Derived quantities: wet interval, drop cap on the flat rod, length scales."""
        from elastocap.drop import CapGeometry

        d = self.drop
        cap = CapGeometry.from_chord(d.area, d.wetted_length)
        B, gam = self.rod.bending_modulus, d.line_tension
        out: dict[str, Any] = {
            "s1": d.s1,
            "s2": d.s2,
            "distance_from_end": self.distance_from_end,
            "l_ec": math.sqrt(B / gam),
            "L_over_l_ec": self.rod.length / math.sqrt(B / gam),
            "area_over_l_ec2": d.area / (B / gam),
            "flat_cap": cap.to_dict(),
            "effects": list(self.effects.names()),
        }
        if self.effects.gravity > 0.0:
            leg = (B / (self.rod.mass_per_length * self.effects.gravity)) ** (1.0 / 3.0)
            out["l_eg"] = leg
            out["L_over_l_eg"] = self.rod.length / leg
            out["x_over_l_eg"] = self.distance_from_end / leg
        if self.spreading is not None:
            w = self.spreading.we_sqrt(d.wetted_length)
            # below delta0 no impact spreads the drop this little: no We^1/2, and why
            out["we_sqrt"] = w if w >= 0.0 else None
            if w < 0.0:
                out["we_sqrt_note"] = (f"Delta = {d.wetted_length:.6g} is below the spreading "
                                       f"law's delta0 = {self.spreading.delta0:.6g}: no "
                                       "impact speed gives it")
        if self.experiment is not None:
            e = self.experiment
            out["experiment"] = {
                "l_ec_m": e.l_ec,
                "l_eg_m": e.l_eg,
                "l_gc_m": e.l_gc,
                "weber": e.weber,
                "we_sqrt": math.sqrt(e.weber),
                "capillary_velocity_m_s": e.capillary_velocity,
                "delta_m": e.wetted_length(),
                "area_2d_m2": e.area_2d,
            }
        return out

    def summary(self) -> dict[str, Any]:
        """Scene and derived quantities as plain data (``elastocap show --json``)."""
        return {
            "name": self.name,
            "description": self.description,
            "rod": vars(self.rod).copy(),
            "drop": {
                "area": self.drop.area,
                "wetted_length": self.drop.wetted_length,
                "line_tension": self.drop.line_tension,
                "center": self.drop.center,
                "events": [vars(ev).copy() for ev in self.drop.events],
                "interface_contact": self.drop.interface_contact,
            },
            "effects": vars(self.effects).copy(),
            "spreading": None if self.spreading is None else vars(self.spreading).copy(),
            "numerics": vars(self.numerics).copy(),
            "derived": self.derived(),
        }


# ---------------------------------------------------------------------------------------------
def _events(raw: Any, L: float) -> tuple[DropEvent, ...]:
    if not isinstance(raw, list):
        raise SceneError("drop.events", raw, "expected an array of tables [[drop.events]]")
    out = []
    for i, ev in enumerate(raw):
        sec = _read_section(ev, f"drop.events[{i}]", EVENT_KEYS)
        if sec["s1"] is None and sec["s2"] is None:
            raise SceneError(f"drop.events[{i}]", ev, "an event needs a new 's1' and/or 's2'")
        for k in ("s1", "s2"):
            v = sec[k]
            if v is not None and not (0.0 <= v <= L):
                raise SceneError(
                    f"drop.events[{i}].{k}", v, f"expected 0 <= {k} <= rod.length = {L}"
                )
        out.append(DropEvent(sec["time"], sec["s1"], sec["s2"]))
    times = [e.time for e in out]
    if times != sorted(times):
        raise SceneError("drop.events", times, "events must be listed in increasing time")
    for a, b in zip(out, out[1:], strict=False):
        for k in ("s1", "s2"):
            if a.time == b.time and getattr(a, k) is not None and getattr(b, k) is not None:
                raise SceneError("drop.events", times,
                                 f"two events at time {a.time:g} both set {k}: give one")
    return tuple(out)


def build_scene(data: dict, name: str = "scene") -> Scene:
    """Validate a raw scene table (as parsed from TOML) into a :class:`Scene`."""
    if not isinstance(data, dict):
        raise SceneError("scene", data, "expected a TOML table")
    data = _plain(data)
    for k in data:
        if k not in TOP_KEYS:
            raise SceneError(
                k,
                data[k],
                f"unknown section; allowed: {', '.join(sorted(TOP_KEYS))}." + _suggest(k, TOP_KEYS),
            )
    name = data.get("name", name)
    if not isinstance(name, str):
        raise SceneError("name", name, "expected a string (it names the output files)")
    problem = check_stem(name)
    if problem is not None:
        raise SceneError("name", name, problem)
    description = data.get("description", "")
    if not isinstance(description, str):
        raise SceneError("description", description, "expected a string")
    experiment = None
    raw_rod = data.get("rod")
    raw_drop = data.get("drop")
    raw_spr = data.get("spreading")
    if "experiment" in data:
        exp_sec = _read_section(data["experiment"], "experiment", EXPERIMENT_KEYS)
        try:
            experiment = units.Experiment(**exp_sec)
            dim = experiment.dimensionless()
        except ValueError as err:
            # "key: got ..." from elastocap.units names the experiment key at fault
            text = str(err)
            key, _, rest = text.partition(": ")
            if key in exp_sec and rest:
                raise SceneError(f"experiment.{key}", exp_sec[key],
                                 rest.split("; ", 1)[-1] if rest.startswith("got ") else rest
                                 ) from None
            raise SceneError("experiment", data["experiment"],
                             text.removeprefix("experiment: ")) from None
        if raw_rod is not None:
            raise SceneError("rod", raw_rod, "give either [experiment] or [rod], not both")
        if raw_spr is not None:
            raise SceneError(
                "spreading", raw_spr, "give either [experiment] or [spreading], not both"
            )
        drop_extra = dict(raw_drop or {})
        for k in ("area", "wetted_length", "line_tension", "center", "distance_from_end"):
            if k in drop_extra:
                raise SceneError(
                    f"drop.{k}", drop_extra[k], "set by [experiment]; change the experiment instead"
                )
        raw_rod = {"length": dim.length}
        if experiment.thickness is not None:
            # the strip's thickness h in scene units (h / l_eg): self-contact on
            raw_rod["thickness"] = experiment.thickness / dim.length_unit
        raw_drop = {
            "area": dim.area,
            "wetted_length": dim.wetted_length,
            "line_tension": dim.line_tension,
            "distance_from_end": dim.distance_from_end,
            **drop_extra,
        }
        raw_spr = {"drop_radius": dim.drop_radius, "delta0": dim.delta0}
        eff = data.get("effects", {})
        if not isinstance(eff, dict):
            raise SceneError("effects", eff, "expected a table of keys [effects]")
        eff = dict(eff)
        if "gravity" in eff and eff["gravity"] != 1.0:
            raise SceneError(
                "effects.gravity", eff["gravity"], "an [experiment] scene uses units with g = 1"
            )
        eff["gravity"] = 1.0
        data_effects = eff
    else:
        data_effects = data.get("effects", {})
    if raw_rod is None:
        raise SceneError("rod", None, "missing: a scene needs [rod] (or [experiment])")
    if raw_drop is None:
        raise SceneError("drop", None, "missing: a scene needs [drop] (or [experiment])")
    try:
        rod, drop, effects, numerics, spreading = _sections(raw_rod, raw_drop, raw_spr,
                                                            data_effects, data)
    except SceneError as err:
        if experiment is None:
            raise
        raise _from_experiment(err, data["experiment"]) from None
    return Scene(
        name=name,
        rod=rod,
        drop=drop,
        effects=effects,
        numerics=numerics,
        spreading=spreading,
        experiment=experiment,
        description=description,
        data=data,
    )


def _sections(raw_rod, raw_drop, raw_spr, data_effects, data):
    """The scene's rod, drop, effects, numerics and spreading law from their raw tables,
    each checked (a SceneError names the key)."""
    spreading = None
    rod = Rod(**_read_section(raw_rod, "rod", ROD_KEYS))
    # the limit itself is allowed whatever the rounding of the product (0.1 x 4.6 < 0.46)
    if rod.thickness > MAX_THICKNESS_OVER_LENGTH * rod.length * (1.0 + 1e-12):
        raise SceneError("rod.thickness", rod.thickness,
                         f"expected 0 <= thickness <= {MAX_THICKNESS_OVER_LENGTH:g} x "
                         f"rod.length = {MAX_THICKNESS_OVER_LENGTH * rod.length:g} (a slender "
                         "rod; 0 = no self-contact)")
    dsec = _read_section(raw_drop, "drop", DROP_KEYS)
    L = rod.length
    if dsec["center"] is not None and dsec["distance_from_end"] is not None:
        raise SceneError(
            "drop.center",
            dsec["center"],
            "give either drop.center or drop.distance_from_end, not both",
        )
    if dsec["distance_from_end"] is not None:
        center = L - dsec["distance_from_end"]
        pos_key, pos_val = "drop.distance_from_end", dsec["distance_from_end"]
    elif dsec["center"] is not None:
        center = dsec["center"]
        pos_key, pos_val = "drop.center", center
    else:
        center = 0.5 * L
        pos_key, pos_val = "drop.center", center
    delta = dsec["wetted_length"]
    if delta > L:
        raise SceneError(
            "drop.wetted_length", delta, f"expected 0 < wetted_length <= rod.length = {L}"
        )
    s1, s2 = center - 0.5 * delta, center + 0.5 * delta
    # 1e-12 L: a wet interval that ends at the rod's end up to round-off is accepted
    tol = 1e-12 * L
    if s1 < -tol or s2 > L + tol:
        raise SceneError(
            pos_key,
            pos_val,
            f"the wet interval [S1, S2] = [{s1:.6g}, {s2:.6g}] must lie inside "
            f"[0, rod.length = {L}]",
        )
    events = _events(raw_drop.get("events", []), L)
    for i, ev in enumerate(events):
        n1 = s1 if ev.s1 is None else ev.s1
        n2 = s2 if ev.s2 is None else ev.s2
        if not n1 < n2:
            raise SceneError(
                f"drop.events[{i}]", vars(ev),
                f"needs s1 < s2 after the event (s1={n1}, s2={n2})"
            )
        s1, s2 = n1, n2
    drop = Drop(dsec["area"], delta, center, dsec["line_tension"], events,
                dsec["interface_contact"])
    effects = Effects(**_read_section(data_effects, "effects", EFFECTS_KEYS))
    nsec = _read_section(data.get("numerics", {}), "numerics", NUMERICS_KEYS)
    for k, (lo, hi, allowed) in NUMERICS_RANGES.items():
        v = nsec[k]
        if k == "cheb_points" and v == 0:
            continue
        if not lo <= v <= hi:
            raise SceneError(f"numerics.{k}", v, f"expected {allowed}")
    numerics = Numerics(**nsec)
    if raw_spr is not None:
        spreading = Spreading(**_read_section(raw_spr, "spreading", SPREADING_KEYS))
    return rod, drop, effects, numerics, spreading


# The scene keys an [experiment] derives, and the experiment inputs each one follows from
# (units.Experiment.dimensionless; l_eg = (B / (mu g))^(1/3) is the unit of length). A
# refusal of a derived key names these, since the user never wrote the derived key.
_LENGTH_UNIT = ("bending_modulus", "youngs_modulus", "thickness", "poisson_ratio", "areal_mass",
                "gravity")
EXPERIMENT_DERIVED = {
    "rod.length": ("length",) + _LENGTH_UNIT,
    "rod.thickness": ("thickness",) + _LENGTH_UNIT,
    "drop.area": ("drop_radius",) + _LENGTH_UNIT,
    "drop.wetted_length": ("impact_speed", "drop_radius", "delta0", "surface_tension",
                           "liquid_density") + _LENGTH_UNIT,
    "drop.line_tension": ("surface_tension",) + _LENGTH_UNIT,
    "drop.distance_from_end": ("impact_distance",) + _LENGTH_UNIT,
    "spreading.drop_radius": ("drop_radius",) + _LENGTH_UNIT,
    "spreading.delta0": ("delta0", "drop_radius") + _LENGTH_UNIT,
}


def _from_experiment(err: SceneError, given: dict) -> SceneError:
    """``err``, a refusal of a key an [experiment] derives, with the inputs it follows from:
    ``drop.wetted_length: got 1.3e6; ... (derived from [experiment]: impact_speed = 9e3,
    drop_radius = 0.00155, ...)``."""
    inputs = [k for k in EXPERIMENT_DERIVED.get(err.key, ()) if given.get(k) is not None]
    if not inputs:
        return err
    shown = ", ".join(f"{k} = {given[k]!r}" for k in inputs[:4])
    more = f" and {len(inputs) - 4} more" if len(inputs) > 4 else ""
    return SceneError(err.key, err.value,
                      f"{err.allowed} (derived from [experiment]: {shown}{more})")


# ---------------------------------------------------------------------------------------------
def parse_override(text: str) -> tuple[str, Any]:
    """Parse ``KEY=VALUE`` (VALUE as a TOML value; a bare word is taken as a string)."""
    if "=" not in text:
        raise SceneError("--set", text, "expected KEY=VALUE, e.g. drop.area=1.0")
    key, _, val = text.partition("=")
    key = key.strip()
    val = val.strip()
    try:
        value = tomllib.loads(f"v = {val}")["v"]
    except tomllib.TOMLDecodeError:
        value = val
    except RecursionError:
        raise SceneError(key, _short(val), "nested too deeply; expected a number, "
                         "true/false or a word") from None
    except ValueError:  # an integer beyond Python's digit limit (4300)
        raise SceneError(key, _short(val), "too many digits; expected a number") from None
    return key, value


def _override_dict(texts) -> dict[str, Any]:
    """``KEY=VALUE`` texts as a dict; a key given twice with different values, or both
    ways of placing the drop, is refused (which one was meant is not knowable)."""
    out: dict[str, Any] = {}
    for text in texts:
        key, value = parse_override(text)
        if key in out and out[key] != value:
            raise SceneError(key, value, f"set twice (also to {out[key]!r}); give it once")
        out[key] = value
    if "drop.center" in out and "drop.distance_from_end" in out:
        raise SceneError("drop.distance_from_end", out["drop.distance_from_end"],
                         f"drop.center is set too (to {out['drop.center']!r}); give either "
                         "drop.center or drop.distance_from_end, not both")
    return out


def _short(text: str, n: int = 40) -> str:
    """A long input shortened for an error message (its length said)."""
    return text if len(text) <= n else f"{text[:n]}... ({len(text)} characters)"


def _apply_overrides(data: dict, overrides: dict[str, Any]) -> dict:
    out = json.loads(json.dumps(data))  # a deep copy of plain TOML data
    for key, value in overrides.items():
        parts = key.split(".")
        if len(parts) != 2 or not all(parts):
            raise SceneError(key, value, "expected SECTION.KEY, e.g. drop.area")
        sec, k = parts
        if sec not in SECTIONS:
            raise SceneError(
                key,
                value,
                f"unknown section '{sec}'; allowed: {', '.join(SECTIONS)}."
                + _suggest(sec, SECTIONS),
            )
        if sec == "drop" and k == "events":
            raise SceneError(
                key,
                value,
                "events cannot be set by an override (they are a list of tables); write "
                "[[drop.events]] tables (time, s1 and/or s2) in a scene file",
            )
        if k not in SECTIONS[sec]:
            raise SceneError(
                key,
                value,
                f"unknown key; allowed keys in [{sec}]: {', '.join(SECTIONS[sec])}."
                + _suggest(k, SECTIONS[sec]),
            )
        table = out.setdefault(sec, {})
        # the drop's position is one choice of two: setting one replaces the other
        if sec == "drop" and k in ("center", "distance_from_end"):
            table.pop("center", None)
            table.pop("distance_from_end", None)
        table[k] = _plain(value)
    return out


def builtin_scene_names() -> list[str]:
    """Names of the scenes shipped inside the package."""
    files = resources.files("elastocap") / "scenes"
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml"))


def _read_toml(text: str, origin: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError("scene", origin, f"not valid TOML: {err}") from None
    except RecursionError:
        raise SceneError(
            "scene", origin, "not a usable scene: its tables or arrays are nested too deeply"
        ) from None
    except ValueError:  # an integer beyond Python's digit limit (4300)
        raise SceneError(
            "scene", origin, "not a usable scene: a number has too many digits"
        ) from None


def _read_file(path: Path) -> str:
    """The UTF-8 text of a scene file; unreadable or non-UTF-8 files are refused by name."""
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise SceneError("scene", str(path), f"cannot read the file ({err.strerror})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise SceneError(
            "scene",
            str(path),
            f"not UTF-8 text (byte 0x{raw[err.start]:02x} at offset {err.start}); a scene "
            "file is UTF-8 TOML",
        ) from None


def load_scene(source: str | Path, overrides: dict[str, Any] | list[str] | None = None) -> Scene:
    """Load a scene by built-in name or TOML path, apply ``--set`` overrides, validate.

    Parameters
    ----------
    source : str or Path
        A built-in name (see :func:`builtin_scene_names`) or a path to a TOML file.
    overrides : dict or list of "KEY=VALUE", optional
        Dotted-key overrides, validated like the file.
    """
    name = str(source)
    builtin = builtin_scene_names()
    if name in builtin:
        text = (resources.files("elastocap") / "scenes" / f"{name}.toml").read_text()
        data = _read_toml(text, name)
    else:
        path = Path(name)
        if not path.is_file():
            raise SceneError(
                "scene",
                name,
                f"not a built-in scene ({', '.join(builtin)}) nor a TOML file."
                + _suggest(name, builtin),
            )
        data = _read_toml(_read_file(path), name)
        name = path.stem
    if overrides:
        if isinstance(overrides, list):
            overrides = _override_dict(overrides)
        data = _apply_overrides(data, overrides)
    return build_scene(data, name)
