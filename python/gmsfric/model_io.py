"""Saving and loading models: a versioned JSON document, SI values with their units stated.

``save_model(obj, path)`` writes a ``"gmsfric.model/1"`` document (format: ``docs/model-format.md``);
``load_model(path)`` reads

* a bare model document;
* any result JSON that embeds one under ``"gmsfric_model"`` (every ``--json`` of
  ``gmsfric identify`` and ``gmsfric paper``);
* a legacy ``gmsfric identify --json`` file (``"model"``, ``"parameters"``, ``"units"``): a static
  map gives a :class:`~gmsfric.models.StaticFriction`, pre-sliding blocks a
  :class:`~gmsfric.models.MaxwellSlip`, a plant a :class:`~gmsfric.system.Plant` (only with a stated
  force gain); every value is converted with :mod:`gmsfric.units`, an unknown unit is an error;
* result kinds with a registered reader (:func:`register_result_reader`; the loop's JSON becomes an
  axis model once its reader is registered).

Model kinds are a registry (:func:`register_kind`): ``static_map``, ``gms``, ``maxwell_slip``,
``lugre``, ``plant`` and ``bundle`` (named models together) are built in; an ``axis`` kind and its
effects can be added without touching this module.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import units as _units
from ._validate import show
from .errors import DataError, InvalidInputError
from .io import check_input_file, write_text_atomic
from .models import GMS, LuGre, MaxwellSlip, StaticFriction, Stribeck
from .results import dumps, jsonable
from .system import Plant

SCHEMA = "gmsfric.model/1"
SCHEMA_PREFIX = "gmsfric.model/"

__all__ = [
    "SCHEMA",
    "save_model",
    "load_model",
    "load_model_document",
    "model_to_dict",
    "model_from_dict",
    "register_kind",
    "register_result_reader",
    "Parameters",
    "ModelFormatError",
]


class ModelFormatError(DataError):
    """A model document (or the file holding it) cannot be turned into a model."""


# ------------------------------------------------------------------------------------------
# the registry

Encoded = tuple[dict[str, tuple[Any, str]], dict[str, Any]]
"""What an encoder returns: ``({name: (SI value or list of SI values, quantity)}, options)``."""


@dataclass(frozen=True)
class ModelKind:
    """A registered model kind: the Python type(s), and how to encode and decode them."""

    kind: str
    types: tuple[type, ...]
    encode: Callable[[Any], Encoded]
    decode: Callable[["Parameters"], Any]


_KINDS: dict[str, ModelKind] = {}
_RESULT_READERS: dict[str, Callable[[Mapping[str, Any], str], Any]] = {}


def register_kind(kind: str, types: type | tuple[type, ...], encode: Callable[[Any], Encoded], decode: Callable[["Parameters"], Any], *, replace: bool = False) -> None:
    """Register a model kind for :func:`save_model` / :func:`load_model`.

    Parameters
    ----------
    kind : str
        The document's ``"kind"`` (e.g. ``"axis"``).
    types : type or tuple of types
        Python types saved as this kind.
    encode : callable
        ``encode(obj) -> ({name: (SI value or list, quantity)}, options)``; quantities are those of
        :mod:`gmsfric.units` and decide the unit written beside each value.
    decode : callable
        ``decode(params: Parameters) -> obj``; ``params.get(name, quantity)`` returns SI values
        (converted from whatever unit the document states) and ``params.option(name)`` options.
    replace : bool
        Allow replacing an existing registration.
    """
    if not replace and kind in _KINDS:
        raise InvalidInputError(f"model kind {kind!r} is already registered")
    _KINDS[kind] = ModelKind(kind, types if isinstance(types, tuple) else (types,), encode, decode)


def register_result_reader(kind: str, reader: Callable[[Mapping[str, Any], str], Any], *, replace: bool = False) -> None:
    """Let :func:`load_model` read result JSONs of ``kind`` (the envelope's ``"kind"``, e.g.
    ``"loop"``) that carry no embedded model document: ``reader(document, source) -> model``."""
    if not replace and kind in _RESULT_READERS:
        raise InvalidInputError(f"a result reader for {kind!r} is already registered")
    _RESULT_READERS[kind] = reader


def _kind_of(obj: Any) -> ModelKind:
    for mk in _KINDS.values():
        if isinstance(obj, mk.types):
            return mk
    known = ", ".join(t.__name__ for mk in _KINDS.values() for t in mk.types)
    raise InvalidInputError(f"`model` must be a gmsfric model ({known}), got {type(obj).__name__}")


# ------------------------------------------------------------------------------------------
# reading parameters with their units

_MISSING = object()


class Parameters:
    """The parameters of a model document, read in SI (see :func:`register_kind`)."""

    def __init__(self, doc: Mapping[str, Any], source: str) -> None:
        self.source = source
        #: The whole model document (for kinds that read more than parameters and options).
        self.document = doc
        self.kind = str(doc.get("kind"))
        axis = doc.get("axis", "linear")
        if not isinstance(axis, str) or axis not in ("linear", "rotary"):
            raise ModelFormatError(f"{source}: \"axis\" must be \"linear\" or \"rotary\", got {show(axis)}")
        self.rotary = axis == "rotary"
        params = doc.get("parameters", {})
        if not isinstance(params, Mapping):
            raise ModelFormatError(f"{source}: \"parameters\" must be an object of {{name: {{\"value\", \"unit\"}}}}")
        self._params = params
        opts = doc.get("options", {})
        self._options = opts if isinstance(opts, Mapping) else {}
        self.used: set[str] = set()

    def has(self, name: str) -> bool:
        return name in self._params

    def get(self, name: str, quantity: str, *, vector: bool = False, default: Any = _MISSING) -> Any:
        """The SI value (a float, or a list of floats with ``vector``) of parameter ``name``."""
        if name not in self._params:
            if default is not _MISSING:
                return default
            raise ModelFormatError(f"{self.source}: {self.kind} parameter {name!r} is missing")
        self.used.add(name)
        entry = self._params[name]
        if not isinstance(entry, Mapping) or "value" not in entry or "unit" not in entry:
            raise ModelFormatError(f"{self.source}: parameter {name!r} must be {{\"value\": ..., \"unit\": ...}}")
        value = _finite_values(entry["value"], name, self.source, vector)
        try:
            factor = _units.factor(str(entry["unit"]), quantity, rotary=self.rotary, name=f"parameters[{name!r}].unit")
        except _units.UnitError as exc:
            raise _units.UnitError(f"{self.source}: {exc}") from None
        return [v * factor for v in value] if vector else value * factor

    def option(self, name: str, choices: Sequence[str], default: str) -> str:
        value = self._options.get(name, default)
        if value not in choices:
            raise ModelFormatError(f"{self.source}: option {name!r} must be one of {list(choices)}, got {value!r}")
        return str(value)

    def check_all_used(self) -> None:
        extra = sorted(set(self._params) - self.used)
        if extra:
            raise ModelFormatError(f"{self.source}: unknown {self.kind} parameter(s) {extra}")


def _finite_values(value: Any, name: str, source: str, vector: bool) -> Any:
    def one(x: Any) -> float:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise ModelFormatError(f"{source}: parameter {name!r} must be a finite number, got {x!r}")
        return float(x)

    if vector:
        if not isinstance(value, list) or not value:
            raise ModelFormatError(f"{source}: parameter {name!r} must be a non-empty list of numbers")
        return [one(x) for x in value]
    return one(value)


# ------------------------------------------------------------------------------------------
# built-in kinds

def _axis_of(p: Parameters) -> dict[str, Any]:
    return {"rotary": p.rotary}


def _stribeck_params(st: Stribeck) -> dict[str, tuple[Any, str]]:
    return {"fc": (st.fc, "force"), "fs": (st.fs, "force"), "vs": (st.vs, "velocity"), "delta": (st.delta, "dimensionless")}


def _stribeck_from(p: Parameters) -> Stribeck:
    return Stribeck(p.get("fc", "force"), p.get("fs", "force"), p.get("vs", "velocity"), p.get("delta", "dimensionless"))


def _enc_static(m: StaticFriction) -> Encoded:
    return {**_stribeck_params(m.stribeck), "sigma": (m.sigma, "damping"), "offset": (m.offset, "force"), "v_linear": (m.v_linear, "velocity")}, {}


def _dec_static(p: Parameters) -> StaticFriction:
    return StaticFriction(_stribeck_from(p), sigma=p.get("sigma", "damping", default=0.0), offset=p.get("offset", "force", default=0.0),
                          v_linear=p.get("v_linear", "velocity", default=0.0), **_axis_of(p))


def _gms_c_quantity(slip_law: str) -> str:
    return "force_rate" if slip_law == "time" else "inverse_position"


def _enc_gms(m: GMS) -> Encoded:
    params = {**_stribeck_params(m.stribeck), "k": (list(m.k), "stiffness"), "alpha": (list(m.alpha), "dimensionless"),
              "c": (m.c, _gms_c_quantity(m.slip_law)), "sigma": (m.sigma, "damping")}
    return params, {"slip_law": m.slip_law}


def _dec_gms(p: Parameters) -> GMS:
    law = p.option("slip_law", ("time", "displacement"), "time")
    return GMS(_stribeck_from(p), p.get("k", "stiffness", vector=True), p.get("alpha", "dimensionless", vector=True), p.get("c", _gms_c_quantity(law)),
               p.get("sigma", "damping", default=0.0), law, **_axis_of(p))  # type: ignore[arg-type]


def _enc_maxwell(m: MaxwellSlip) -> Encoded:
    return {"k": (list(m.k), "stiffness"), "w": (list(m.w), "force"), "sigma": (m.sigma, "damping")}, {}


def _dec_maxwell(p: Parameters) -> MaxwellSlip:
    return MaxwellSlip(p.get("k", "stiffness", vector=True), p.get("w", "force", vector=True), p.get("sigma", "damping", default=0.0), **_axis_of(p))


def _enc_lugre(m: LuGre) -> Encoded:
    return {**_stribeck_params(m.stribeck), "sigma0": (m.sigma0, "stiffness"), "sigma1": (m.sigma1, "damping"), "sigma2": (m.sigma2, "damping")}, {}


def _dec_lugre(p: Parameters) -> LuGre:
    return LuGre(_stribeck_from(p), p.get("sigma0", "stiffness"), p.get("sigma1", "damping", default=0.0), p.get("sigma2", "damping", default=0.0),
                 **_axis_of(p))


def _enc_plant(m: Plant) -> Encoded:
    return {"a": (m.a, "plant_gain"), "b": (m.b, "rate"), "c": (m.c, "rate_squared"), "delay": (m.delay, "time"), "force_gain": (m.force_gain, "force_gain")}, {}


def _dec_plant(p: Parameters) -> Plant:
    if not p.has("force_gain"):
        raise ModelFormatError(
            f"{p.source}: the plant states no force gain (force per drive unit), so friction cannot act on it; "
            "identify it with `gmsfric identify plant ... --force-gain G`"
        )
    return Plant(p.get("a", "plant_gain"), p.get("b", "rate"), p.get("c", "rate_squared"), p.get("delay", "time"), p.get("force_gain", "force_gain"),
                 rotary=p.rotary, drive=_drive_of(p))


def _drive_of(p: Parameters, prefix: str = "") -> str:
    """The SI drive unit (``"V"``, ``"A"``, or ``"N"`` / ``"N m"`` for a force command) the
    document states for the plant gain; the force gain must be per the same drive (a gain per
    volt beside a plant per newton would scale the friction by a factor the file hides)."""
    params = p.document.get("parameters", {})
    drives = {}
    for name, quantity in (("a", "plant_gain"), ("force_gain", "force_gain")):
        entry = params.get(prefix + name)
        unit = entry.get("unit") if isinstance(entry, Mapping) else None
        if isinstance(unit, str):
            try:
                drives[name] = _units.drive_of(unit, quantity, rotary=p.rotary)
            except _units.UnitError:
                pass  # reported by p.get
    if len(set(drives.values())) > 1:
        raise ModelFormatError(f"{p.source}: `{prefix}a` is per {drives['a']} but `{prefix}force_gain` per {drives['force_gain']}: "
                               "both must be per the same drive input")
    return drives.get("a", drives.get("force_gain", "V"))


register_kind("static_map", StaticFriction, _enc_static, _dec_static)
register_kind("gms", GMS, _enc_gms, _dec_gms)
register_kind("maxwell_slip", MaxwellSlip, _enc_maxwell, _dec_maxwell)
register_kind("lugre", LuGre, _enc_lugre, _dec_lugre)
register_kind("plant", Plant, _enc_plant, _dec_plant)


# ------------------------------------------------------------------------------------------
# documents

def _version() -> str:
    from . import __version__

    return __version__


def _own_axis(model: Any) -> bool | None:
    """Whether ``model`` states a rotary (True) or linear (False) axis; None if it states none."""
    units = getattr(model, "units", None)
    kind = getattr(units, "kind", None)
    if kind in ("linear", "rotary"):  # an axis model: its units say it
        return bool(kind == "rotary")
    own = getattr(model, "rotary", None)
    return bool(own) if isinstance(own, (bool, np.bool_)) else None


def _own_drive(model: Any) -> str | None:
    own = getattr(model, "drive", None)
    if isinstance(own, str) and own in _units.DRIVES:
        return own
    command = getattr(getattr(model, "units", None), "command", None)
    if isinstance(command, str):
        try:
            return _units.drive_base(command)
        except _units.UnitError:
            return None
    return None


def _axis_for(model: Any, rotary: bool | None, where: str = "`model`") -> bool:
    """The axis a model is written on: its own; ``rotary`` may only confirm it, never relabel it
    (an angle is never a length, a torque never a force)."""
    own = _own_axis(model)
    if rotary is not None and own is not None and bool(rotary) != own:
        kind = "rotary" if own else "linear"
        raise InvalidInputError(f"`rotary`={bool(rotary)} would relabel {where}, a {kind}-axis model, as {'rotary' if rotary else 'linear'}: "
                                f"an angle is never a length; if it is of a {'linear' if own else 'rotary'} axis, build it so "
                                f"(dataclasses.replace(model, rotary={not own}))")
    return own if own is not None else bool(rotary)


def _drive_for(model: Any, drive: str | None, where: str = "`model`") -> str:
    own = _own_drive(model)
    if drive is not None:
        choice_drive = str(drive)
        if choice_drive not in _units.DRIVES:
            raise InvalidInputError(f"`drive` must be one of {', '.join(repr(d) for d in _units.DRIVES)}, got {show(drive)}")
        if own is not None and isinstance(getattr(model, "drive", None), str) and own != choice_drive:
            raise InvalidInputError(f"`drive`={choice_drive!r} would relabel {where}, driven in {own}, as driven in {choice_drive}")
        return choice_drive
    return own or "V"


def model_to_dict(
    model: Any,
    *,
    rotary: bool | None = None,
    drive: str | None = None,
    covariance: tuple[Sequence[str], Any, Sequence[str]] | None = None,
    provenance: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The model document of ``model`` (a registered kind, or a ``{name: model}`` dict for a
    ``"bundle"``).

    Parameters
    ----------
    model : model object or dict of str -> model object
    rotary : bool, optional
        The axis is rotary: SI units are rad, N m, N m/rad ... instead of m, N, N/m.  Default: the
        model's own (``model.rotary``, an axis model's ``units.kind``); given, it must agree with
        it (a model is never relabeled).  For a kind that states no axis, it decides.
    drive : {"V", "A", "N", "N m"}, optional
        SI unit of the drive input (plant gain and force gain; ``"N"``, ``"N m"`` on a rotary
        axis, when the drive command is the force itself); default the plant's own
        (``Plant.drive``), else ``"V"``.
    covariance : (names, matrix, units), optional
        Covariance of identified parameters, in SI, with each name's SI unit.
    provenance : dict, optional
        Where the model comes from (input files, columns, units, command).

    Raises
    ------
    InvalidInputError
        Not a model, or ``rotary`` / ``drive`` contradicting the model's own.
    """
    if rotary is not None and not isinstance(rotary, (bool, np.bool_)):
        raise InvalidInputError(f"`rotary` must be True, False or None, got {show(rotary)}")
    head = {"schema": SCHEMA, "gmsfric_version": _version()}
    if isinstance(model, Mapping):
        if not model:
            raise InvalidInputError("`model`: a bundle needs at least one model")
        parts = {str(k): _body(v, _axis_for(v, rotary, f"`model[{k!r}]`"), _drive_for(v, drive, f"`model[{k!r}]`")) for k, v in model.items()}
        doc: dict[str, Any] = {**head, "kind": "bundle", "models": parts}
    else:
        doc = {**head, **_body(model, _axis_for(model, rotary), _drive_for(model, drive))}
    if covariance is not None:
        names, matrix, cov_units = covariance
        m = np.asarray(matrix, dtype=float)
        if m.shape != (len(names), len(names)) or len(cov_units) != len(names):
            raise InvalidInputError(f"`covariance`: {len(names)} names and units need a {len(names)}x{len(names)} matrix, got {m.shape}")
        doc["covariance"] = {"names": list(names), "units": list(cov_units), "matrix": jsonable(m)}
    if provenance is not None and not isinstance(provenance, Mapping):
        raise InvalidInputError(f"`provenance` must be a dict, got {show(provenance)}")
    doc["provenance"] = dict(provenance or {})
    return doc


def _body(model: Any, rotary: bool, drive: str) -> dict[str, Any]:
    mk = _kind_of(model)
    params, options = mk.encode(model)
    out: dict[str, Any] = {"kind": mk.kind, "axis": "rotary" if rotary else "linear", "parameters": {}}
    for name, (value, quantity) in params.items():
        out["parameters"][name] = {"value": jsonable(value), "unit": _units.si_unit(quantity, rotary, drive=drive)}
    if options:
        out["options"] = dict(options)
    return out


def model_from_dict(doc: Mapping[str, Any], *, source: str = "<document>", part: str | None = None) -> Any:
    """The model of a document: a model document, a result embedding one, a legacy identify JSON
    or a result kind with a registered reader (see the module docstring)."""
    if not isinstance(doc, Mapping):
        raise ModelFormatError(f"{source}: expected a JSON object, got {type(doc).__name__}")
    schema = doc.get("schema")
    if isinstance(schema, str) and schema.startswith(SCHEMA_PREFIX):
        return _decode_model(doc, source, part)
    if "gmsfric_model" in doc:
        return model_from_dict(doc["gmsfric_model"], source=f"{source} (gmsfric_model)", part=part)
    kind = doc.get("kind")
    if isinstance(kind, str) and kind in _RESULT_READERS:
        return _RESULT_READERS[kind](doc, source)
    if isinstance(doc.get("model"), str) and isinstance(doc.get("parameters"), Mapping):
        return _legacy_identify(doc, source)
    if isinstance(kind, str) or ("final" in doc and "baseline" in doc):
        what = kind or "loop"
        raise ModelFormatError(f"{source}: a {what!r} result holds no model document and no reader is registered for it "
                               f"(gmsfric.model_io.register_result_reader)")
    raise ModelFormatError(f"{source}: not a gmsfric model document, nor a result or `gmsfric identify --json` file")


def _decode_model(doc: Mapping[str, Any], source: str, part: str | None) -> Any:
    schema = str(doc["schema"])
    if schema != SCHEMA:
        raise ModelFormatError(f"{source}: unsupported model schema {schema!r}; this gmsfric reads {SCHEMA!r}")
    kind = doc.get("kind")
    if part is not None and not isinstance(part, str):
        raise InvalidInputError(f"`part` must be the name of a model of the bundle, got {show(part)}")
    if isinstance(kind, str) and kind == "bundle":
        models = doc.get("models")
        if not isinstance(models, Mapping) or not models:
            raise ModelFormatError(f"{source}: a bundle needs a non-empty \"models\" object")
        if part is not None:
            if part not in models:
                raise ModelFormatError(f"{source}: no model {part!r} in the bundle; it holds {', '.join(models)}")
            return _decode_body(models[part], f"{source} [{part}]")
        return {str(k): _decode_body(v, f"{source} [{k}]") for k, v in models.items()}
    if part is not None:
        raise ModelFormatError(f"{source}: `part` {part!r} given but the document holds one {show(kind)} model")
    return _decode_body(doc, source)


def _decode_body(doc: Any, source: str) -> Any:
    if not isinstance(doc, Mapping):
        raise ModelFormatError(f"{source}: a model must be a JSON object")
    kind = doc.get("kind")
    if not isinstance(kind, str) or kind not in _KINDS:
        raise ModelFormatError(f"{source}: unknown model kind {show(kind)}; known: {', '.join(_KINDS)}")
    p = Parameters(doc, source)
    try:
        model = _KINDS[str(kind)].decode(p)
    except ModelFormatError:
        raise
    except _units.UnitError:
        raise
    except InvalidInputError as exc:
        raise ModelFormatError(f"{source}: invalid {kind} parameters: {exc}") from None
    p.check_all_used()
    return model


# ------------------------------------------------------------------------------------------
# legacy `gmsfric identify --json` files (parameters in the data's units + a "units" map)

_LEGACY = {
    "static_map": ("vs", "velocity", {"fc": "force", "fs": "force", "vs": "velocity", "sigma": "damping", "delta": "dimensionless"}),
    "presliding": ("w1", "force", {}),
    "plant": ("a", "plant_gain", {"a": "plant_gain", "b": "rate", "c": "rate_squared", "delay": "time", "force_gain": "force_gain"}),
}


def _legacy_identify(doc: Mapping[str, Any], source: str) -> Any:
    model = str(doc["model"])
    key = "plant" if model == "revised_plant" else model
    if key not in _LEGACY:
        raise ModelFormatError(f"{source}: unknown identified model {model!r} (expected static_map, presliding, plant or revised_plant)")
    raw = dict(doc["parameters"])
    if key == "plant" and "force_gain" in doc and "force_gain" not in raw:
        raw["force_gain"] = doc["force_gain"]
    units_doc = doc.get("units")
    unit_map: Mapping[str, Any] = units_doc if isinstance(units_doc, Mapping) else {}
    axis_param, axis_quantity, quantities = _LEGACY[key]
    if key == "presliding":
        quantities = {n: ("stiffness" if n.startswith("k") else "force") for n in raw}

    def value(name: str) -> float:
        entry = raw[name]
        v = entry.get("value") if isinstance(entry, Mapping) else entry
        return _finite_values(v, name, source, False)  # type: ignore[no-any-return]

    def unit(name: str) -> str:
        u = unit_map.get(name)
        if not isinstance(u, str):
            raise ModelFormatError(f"{source}: no unit stated for {name!r} (\"units\": {{{name!r}: ...}}); a unit is never assumed")
        return u

    if axis_param not in raw:
        raise ModelFormatError(f"{source}: {model} parameter {axis_param!r} is missing")
    try:
        rotary = _units.is_rotary(unit(axis_param), axis_quantity, name=f"units[{axis_param!r}]")
        si = {n: _units.to_si(value(n), unit(n), q, rotary=rotary, name=f"units[{n!r}]") for n, q in quantities.items() if n in raw and raw[n] is not None}
    except _units.UnitError as exc:
        raise _units.UnitError(f"{source}: {exc}") from None
    try:
        if key == "static_map":
            missing = [n for n in ("fc", "fs", "vs", "sigma", "delta") if n not in si]
            if missing:
                raise ModelFormatError(f"{source}: static_map parameter(s) {missing} missing")
            return StaticFriction(Stribeck(si["fc"], si["fs"], si["vs"], si["delta"]), sigma=si["sigma"], rotary=rotary)
        if key == "presliding":
            idx = sorted(int(n[1:]) for n in si if n[0] == "k" and n[1:].isdigit())
            wdx = sorted(int(n[1:]) for n in si if n[0] == "w" and n[1:].isdigit())
            if not idx or idx != wdx or set(si) != {f"k{i}" for i in idx} | {f"w{i}" for i in idx}:
                raise ModelFormatError(f"{source}: pre-sliding blocks must be k1..kN and w1..wN, got {sorted(raw)}")
            return MaxwellSlip([si[f"k{i}"] for i in idx], [si[f"w{i}"] for i in idx], rotary=rotary)
        if "force_gain" not in si:
            raise ModelFormatError(f"{source}: the plant states no force gain (force per drive unit), so friction cannot act on it; "
                                   "identify it with `gmsfric identify plant ... --force-gain G`")
        missing = [n for n in ("a", "b", "c", "delay") if n not in si]
        if missing:
            raise ModelFormatError(f"{source}: plant parameter(s) {missing} missing")
        drive = _units.drive_of(unit("a"), "plant_gain", rotary=rotary, name="units['a']")
        if _units.drive_of(unit("force_gain"), "force_gain", rotary=rotary, name="units['force_gain']") != drive:
            raise ModelFormatError(f"{source}: `a` is in {unit('a')} but `force_gain` in {unit('force_gain')}: both must be per the same drive input")
        return Plant(si["a"], si["b"], si["c"], si["delay"], si["force_gain"], rotary=rotary, drive=drive)
    except ModelFormatError:
        raise
    except InvalidInputError as exc:
        raise ModelFormatError(f"{source}: invalid {model} parameters: {exc}") from None


# ------------------------------------------------------------------------------------------
# files


def save_model(
    model: Any,
    path: str | Path,
    *,
    rotary: bool | None = None,
    drive: str | None = None,
    covariance: tuple[Sequence[str], Any, Sequence[str]] | None = None,
    provenance: Mapping[str, Any] | None = None,
) -> Path:
    """Write the model document of ``model`` to ``path`` (atomically); returns the path.
    Arguments as :func:`model_to_dict`.  A model that carries its own covariance, units and
    provenance (an axis model) keeps them; ``provenance`` given is merged into its own.

    Raises
    ------
    InvalidInputError
        ``path`` is a directory, its directory does not exist, or ``rotary`` / ``drive``
        contradict the model (checked before anything is written).
    """
    from .io import check_output_path

    target = check_output_path(path, name="path")
    if rotary is not None and not isinstance(rotary, (bool, np.bool_)):
        raise InvalidInputError(f"`rotary` must be True, False or None, got {show(rotary)}")
    if hasattr(model, "model_document") and covariance is None:
        # Models that carry their own covariance, units and provenance (AxisModel) write them;
        # `rotary` and `drive` may only confirm their own.
        _axis_for(model, rotary)
        _drive_for(model, drive)
        doc = model.model_document()
        if provenance is not None:
            if not isinstance(provenance, Mapping):
                raise InvalidInputError(f"`provenance` must be a dict, got {show(provenance)}")
            doc["provenance"] = {**dict(doc.get("provenance") or {}), **dict(provenance)}
    else:
        doc = model_to_dict(model, rotary=rotary, drive=drive, covariance=covariance, provenance=provenance)
    write_text_atomic(target, dumps(doc) + "\n")
    return Path(path)


def _read_json(path: str | Path) -> Any:
    p = check_input_file(path, role="model file")
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ModelFormatError(f"{p}: not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise ModelFormatError(f"{p}: not JSON: {exc}") from None
    except RecursionError:
        raise ModelFormatError(f"{p}: JSON nested too deeply") from None


def load_model(path: str | Path, *, part: str | None = None) -> Any:
    """The model saved in ``path`` (see the module docstring for what is read).

    Parameters
    ----------
    path : str or Path
    part : str, optional
        For a bundle (e.g. ``gmsfric paper --json``): the name of the model to return; without it
        a bundle gives a ``{name: model}`` dict.

    Returns
    -------
    StaticFriction, GMS, MaxwellSlip, LuGre, Plant, a registered kind, or a dict of them

    Raises
    ------
    DataError
        Unreadable file, not JSON, no model in it, a missing or invalid parameter.
    UnitError
        A unit that is unknown or not of its parameter's quantity.
    """
    return model_from_dict(_read_json(path), source=str(path), part=part)


def load_model_document(path: str | Path) -> dict[str, Any]:
    """The model document in ``path`` (bare, or embedded under ``"gmsfric_model"``), checked by
    loading it; gives access to its covariance and provenance."""
    doc = _read_json(path)
    if isinstance(doc, Mapping) and "gmsfric_model" in doc:
        doc = doc["gmsfric_model"]
    if not (isinstance(doc, Mapping) and str(doc.get("schema", "")).startswith(SCHEMA_PREFIX)):
        raise ModelFormatError(f"{path}: holds no model document")
    model_from_dict(doc, source=str(path))
    return dict(doc)
