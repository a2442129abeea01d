"""Vehicle and tyre parameter types, validated and frozen, and their TOML data files.

Conventions: ISO 8855 axes (x forward, y left, z up), reference point the CoG, SI units.
Every field declares its unit in ``field(metadata={"unit": ...})``; a preset file must state
the same unit next to every value, and cite a source for it (``source = "..."``).

The compiled kernels (numba) take parameters as flat ``float64`` arrays. ``VehicleParams.to_array``
and ``TireParams.to_array`` build them; ``VP`` and ``TP`` are the index enums of those arrays.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from flatfree._names import anchored, looks_like_path
from flatfree._names import bundled_name as _bundled_name
from flatfree._validate import finite, in_range, nonnegative, positive
from flatfree.units import G

__all__ = [
    "TireParams",
    "VehicleParams",
    "TP",
    "VP",
    "DRIVE_CODES",
    "bundled_name",
    "CORNERING_LAW_CODES",
    "load_tire",
    "load_vehicle",
    "vehicle_file",
    "vehicle_names",
    "tire_names",
]

#: Tolerance on lf + lr == wheelbase [m].
WHEELBASE_TOL_M = 1e-3

DRIVE_CODES = {"front": 0, "rear": 1}
#: How the cornering stiffness depends on load.
#: ``mf52``: K_y = p_Ky1 F_z0 sin(p_Ky4 atan(F_z / (p_Ky2 F_z0))) ([P12] eq. 4.E25, gamma = 0).
#: ``proportional``: K_y = p_Ky1 F_z (CommonRoad's tire_model.py [CR-tm], no load degression).
CORNERING_LAW_CODES = {"mf52": 0, "proportional": 1}


def _u(unit: str, default: Any = dataclasses.MISSING):
    """A dataclass field with a unit in its metadata."""
    if default is dataclasses.MISSING:
        return field(metadata={"unit": unit})
    return field(default=default, metadata={"unit": unit})


# --------------------------------------------------------------------------------------------
# Tyres
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class TireParams:
    """Magic Formula tyre coefficients (MF 5.2 / 6.x notation of [P12] section 4.3.2, camber 0).

    Sign convention of ISO 8855 / the ``.tir`` files: a positive slip angle alpha gives a
    negative lateral force (p_Ky1 < 0); a positive slip ratio kappa (driving) gives F_x > 0.
    Turn slip, pressure and camber terms are omitted; all scaling factors are 1 except those
    listed as ``lambda_*``. The road friction coefficient is *not* a tyre parameter: the tyre
    functions take a ``mu_scale`` = mu_road / mu_ref that multiplies the peak factors
    (lambda_mu_x, lambda_mu_y, [P12] 4.E13 and 4.E23; [TUM-svd]).

    References
    ----------
    [P12] H. B. Pacejka, Tire and Vehicle Dynamics, 3rd ed., 2012, eqs. (4.E1)-(4.E67).
    """

    name: str = field(default="", metadata={"unit": ""})
    cornering_law: str = field(default="mf52", metadata={"unit": ""})
    fz0: float = _u("N")  # nominal load F_z0
    # pure longitudinal slip (4.E9-4.E18)
    pcx1: float = _u("-", 0.0)
    pdx1: float = _u("-", 0.0)
    pdx2: float = _u("-", 0.0)
    pex1: float = _u("-", 0.0)
    pex2: float = _u("-", 0.0)
    pex3: float = _u("-", 0.0)
    pex4: float = _u("-", 0.0)
    pkx1: float = _u("-", 0.0)
    pkx2: float = _u("-", 0.0)
    pkx3: float = _u("-", 0.0)
    phx1: float = _u("-", 0.0)
    phx2: float = _u("-", 0.0)
    pvx1: float = _u("-", 0.0)
    pvx2: float = _u("-", 0.0)
    # pure lateral slip (4.E19-4.E30), gamma = 0
    pcy1: float = _u("-", 0.0)
    pdy1: float = _u("-", 0.0)
    pdy2: float = _u("-", 0.0)
    pey1: float = _u("-", 0.0)
    pey2: float = _u("-", 0.0)
    pey3: float = _u("-", 0.0)
    pky1: float = _u("-", 0.0)
    pky2: float = _u("-", 0.0)
    pky4: float = _u("-", 2.0)
    phy1: float = _u("-", 0.0)
    phy2: float = _u("-", 0.0)
    pvy1: float = _u("-", 0.0)
    pvy2: float = _u("-", 0.0)
    # combined slip (4.E50-4.E67)
    rbx1: float = _u("-", 0.0)
    rbx2: float = _u("-", 0.0)
    rcx1: float = _u("-", 1.0)
    rex1: float = _u("-", 0.0)
    rex2: float = _u("-", 0.0)
    rhx1: float = _u("-", 0.0)
    rby1: float = _u("-", 0.0)
    rby2: float = _u("-", 0.0)
    rby3: float = _u("-", 0.0)
    rcy1: float = _u("-", 1.0)
    rey1: float = _u("-", 0.0)
    rey2: float = _u("-", 0.0)
    rhy1: float = _u("-", 0.0)
    rhy2: float = _u("-", 0.0)
    rvy1: float = _u("-", 0.0)
    rvy2: float = _u("-", 0.0)
    rvy4: float = _u("-", 0.0)
    rvy5: float = _u("-", 0.0)
    rvy6: float = _u("-", 0.0)
    # scaling factors
    lambda_ky: float = _u("-", 1.0)  # cornering stiffness scale lambda_Kyalpha
    lambda_kx: float = _u("-", 1.0)  # slip stiffness scale lambda_Kxkappa
    # transient behaviour: relaxation lengths (used by models that integrate slip states)
    relaxation_length_x: float = _u("m", 0.0)
    relaxation_length_y: float = _u("m", 0.0)

    def __post_init__(self) -> None:
        if self.cornering_law not in CORNERING_LAW_CODES:
            raise ValueError(
                f"cornering_law = {self.cornering_law!r}: must be one of "
                f"{sorted(CORNERING_LAW_CODES)}"
            )
        positive("fz0", self.fz0, "N")
        for f in dataclasses.fields(self):
            if f.metadata.get("unit") not in ("", None):
                finite(f.name, getattr(self, f.name), f.metadata["unit"])
        positive("pcx1", self.pcx1)
        positive("pcy1", self.pcy1)
        if self.pdx1 == 0.0:
            raise ValueError("pdx1 = 0.0: the longitudinal peak factor must be nonzero")
        if self.pdy1 == 0.0:
            raise ValueError("pdy1 = 0.0: the lateral peak factor must be nonzero")
        if self.pkx1 <= 0.0:
            raise ValueError(f"pkx1 = {self.pkx1!r}: the slip stiffness factor must be > 0")
        if self.pky1 >= 0.0:
            raise ValueError(
                f"pky1 = {self.pky1!r}: the cornering stiffness factor must be < 0 "
                "(ISO sign: positive slip angle, negative force)"
            )
        if self.cornering_law == "mf52":
            positive("pky2", self.pky2)
        positive("lambda_ky", self.lambda_ky)
        positive("lambda_kx", self.lambda_kx)
        nonnegative("relaxation_length_x", self.relaxation_length_x, "m")
        nonnegative("relaxation_length_y", self.relaxation_length_y, "m")

    def to_array(self) -> np.ndarray:
        """The coefficients as a float64 array laid out by ``TP`` (for compiled kernels)."""
        out = np.empty(len(TP), dtype=np.float64)
        for member in TP:
            if member is TP.cornering_law:
                out[member] = CORNERING_LAW_CODES[self.cornering_law]
            else:
                out[member] = float(getattr(self, member.name))
        return out


_TIRE_ARRAY_FIELDS = [f.name for f in dataclasses.fields(TireParams) if f.name != "name"]
#: Index enum of ``TireParams.to_array()``.
TP = enum.IntEnum("TP", [(n, i) for i, n in enumerate(_TIRE_ARRAY_FIELDS)])


# --------------------------------------------------------------------------------------------
# Vehicles
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class VehicleParams:
    """Physical parameters of a car for the 3DoF design model and the 10DoF validation model.

    Frame and reference point: ISO 8855 body axes at the CoG. Lengths are positive distances.
    Per-corner quantities (springs, dampers) are for *one* corner of the named axle. Torque
    limits are totals at the wheels of the axle (drive) or of the car (brake).

    Build one with :func:`load_vehicle` (a bundled preset or a TOML file) or directly; variants
    come from ``dataclasses.replace``. Every value is validated: a bad one raises
    ``ValueError`` naming the field, the value and the unit.
    """

    name: str = field(default="", metadata={"unit": ""})
    drive: str = field(default="front", metadata={"unit": ""})  # "front" or "rear"
    tire_front: TireParams = field(metadata={"unit": ""})
    tire_rear: TireParams = field(metadata={"unit": ""})
    # masses and geometry
    mass: float = _u("kg")
    sprung_mass: float = _u("kg")
    lf: float = _u("m")  # CoG to front axle
    lr: float = _u("m")  # CoG to rear axle
    wheelbase: float = _u("m")
    track_front: float = _u("m")
    track_rear: float = _u("m")
    cog_height: float = _u("m")
    roll_center_height_front: float = _u("m", 0.0)
    roll_center_height_rear: float = _u("m", 0.0)
    # inertias
    iz: float = _u("kg m^2")  # yaw inertia of the whole car
    ix_s: float = _u("kg m^2")  # roll inertia of the sprung mass about its CoG
    iy_s: float = _u("kg m^2")  # pitch inertia of the sprung mass about its CoG
    # suspension, per corner
    spring_front: float = _u("N/m")
    spring_rear: float = _u("N/m")
    damper_front: float = _u("N s/m")
    damper_rear: float = _u("N s/m")
    # anti-roll bars, axle roll stiffness they add
    arb_front: float = _u("N m/rad", 0.0)
    arb_rear: float = _u("N m/rad", 0.0)
    # wheels
    wheel_radius: float = _u("m")  # effective rolling radius R_e
    wheel_inertia_front: float = _u("kg m^2")  # spin inertia of one front wheel
    wheel_inertia_rear: float = _u("kg m^2")  # spin inertia of one rear wheel
    # powertrain and brakes
    max_drive_torque: float = _u("N m")  # total at the wheels of the driven axle
    max_power: float = _u("W")  # drive torque is capped by max_power * R_e / v
    max_brake_torque: float = _u("N m")  # total over the four wheels
    brake_balance_front: float = _u("-")  # share of brake torque on the front axle
    # steering actuator
    max_steer: float = _u("rad")
    max_steer_rate: float = _u("rad/s")
    # resistances and aero
    rolling_resistance: float = _u("-", 0.0)  # f_r
    drag_area: float = _u("m^2", 0.0)  # C_d A
    lift_area_front: float = _u("m^2", 0.0)  # C_L,f A (negative = downforce)
    lift_area_rear: float = _u("m^2", 0.0)  # C_L,r A (negative = downforce)
    drag_height: float = _u("m", 0.0)  # height of the drag force above ground
    air_density: float = _u("kg/m^3", 1.225)  # [AWSIM], [OCD]

    def __post_init__(self) -> None:
        if self.drive not in DRIVE_CODES:
            raise ValueError(f"drive = {self.drive!r}: must be one of {sorted(DRIVE_CODES)}")
        for side in ("tire_front", "tire_rear"):
            if not isinstance(getattr(self, side), TireParams):
                raise ValueError(f"{side} = {getattr(self, side)!r}: expected a TireParams")
        for f in dataclasses.fields(self):
            unit = f.metadata.get("unit")
            if unit in ("", None):
                continue
            finite(f.name, getattr(self, f.name), unit)
        for name in (
            "mass", "sprung_mass", "lf", "lr", "wheelbase", "track_front", "track_rear",
            "cog_height", "iz", "ix_s", "iy_s", "spring_front", "spring_rear",
            "damper_front", "damper_rear", "wheel_radius", "wheel_inertia_front",
            "wheel_inertia_rear", "max_drive_torque", "max_power", "max_brake_torque",
            "max_steer", "max_steer_rate", "air_density",
        ):
            positive(name, getattr(self, name), self._unit(name))
        for name in (
            "arb_front", "arb_rear", "rolling_resistance", "drag_area", "drag_height",
            "roll_center_height_front", "roll_center_height_rear",
        ):
            nonnegative(name, getattr(self, name), self._unit(name))
        if self.sprung_mass > self.mass:
            raise ValueError(
                f"sprung_mass = {self.sprung_mass!r} kg: must not exceed mass = {self.mass!r} kg"
            )
        if abs(self.lf + self.lr - self.wheelbase) > WHEELBASE_TOL_M:
            raise ValueError(
                f"lf + lr = {self.lf + self.lr!r} m is inconsistent with "
                f"wheelbase = {self.wheelbase!r} m (tolerance {WHEELBASE_TOL_M} m)"
            )
        in_range("brake_balance_front", self.brake_balance_front, 0.0, 1.0, "-")
        in_range("max_steer", self.max_steer, 0.0, 0.5 * math.pi, "rad", lo_open=True)
        if self.cog_height >= min(self.track_front, self.track_rear):
            raise ValueError(
                f"cog_height = {self.cog_height!r} m: must be below the track width "
                f"({min(self.track_front, self.track_rear)} m) for a car that does not roll over "
                "at rest"
            )

    @classmethod
    def _unit(cls, name: str) -> str:
        return _FIELD_UNITS[name]

    # ----- derived quantities -----
    @property
    def static_axle_loads(self) -> tuple[float, float]:
        """Static vertical load on the front and rear axle [N] (m g lr / L, m g lf / L)."""
        w = self.mass * G
        length = self.lf + self.lr
        return w * self.lr / length, w * self.lf / length

    @property
    def yaw_index(self) -> float:
        """Iz / (m lf lr) [-]; below 1 the flatness controller has a singular speed (NOTES.md)."""
        return self.iz / (self.mass * self.lf * self.lr)

    def to_array(self) -> np.ndarray:
        """The scalar parameters as a float64 array laid out by ``VP`` (for compiled kernels).

        ``drive`` is stored as its code in ``DRIVE_CODES``; the tyres are not included (use
        ``tire_front.to_array()`` and ``tire_rear.to_array()``).
        """
        out = np.empty(len(VP), dtype=np.float64)
        for member in VP:
            if member is VP.drive:
                out[member] = DRIVE_CODES[self.drive]
            else:
                out[member] = float(getattr(self, member.name))
        return out


_VEHICLE_ARRAY_FIELDS = [
    f.name
    for f in dataclasses.fields(VehicleParams)
    if f.name not in ("name", "tire_front", "tire_rear")
]
#: Index enum of ``VehicleParams.to_array()``.
VP = enum.IntEnum("VP", [(n, i) for i, n in enumerate(_VEHICLE_ARRAY_FIELDS)])
_FIELD_UNITS = {f.name: f.metadata.get("unit", "") for f in dataclasses.fields(VehicleParams)}


# --------------------------------------------------------------------------------------------
# Data files
# --------------------------------------------------------------------------------------------
_DATA = resources.files("flatfree.vehicles") / "data"


def vehicle_names() -> list[str]:
    """Names of the bundled vehicle presets."""
    return sorted(p.name[:-5] for p in _DATA.iterdir() if p.name.endswith(".toml"))


def tire_names() -> list[str]:
    """Names of the bundled tyre coefficient sets."""
    return sorted(p.name[:-5] for p in (_DATA / "tires").iterdir() if p.name.endswith(".toml"))


def _read_toml(path_or_resource, what: str) -> dict:
    try:
        text = path_or_resource.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{what}: file not found: {path_or_resource}") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what}: {path_or_resource} is not a UTF-8 text file ({exc})"
                         ) from None
    except OSError as exc:  # a folder, no permission, ...
        raise ValueError(f"{what}: cannot read {path_or_resource} ({exc.strerror or exc})"
                         ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{what}: malformed TOML in {path_or_resource}: {exc}") from None


_NAMES = {"vehicle": vehicle_names, "tire": tire_names}


def bundled_name(name: Any, kind: str = "vehicle") -> str | None:
    """The bundled vehicle preset (``kind="vehicle"``) or tyre set (``"tire"``) that ``name``
    names, in its own spelling (``"Dallara_AV21"``, ``" peugeot406 "`` -> ``"dallara_av21"``,
    ``"peugeot406"``), else None.

    The one name lookup of the loaders (:func:`load_vehicle`, :func:`load_tire`), shared with
    the tracks' (:mod:`flatfree._names`): case-insensitive, surrounding blanks ignored; a
    ``.toml`` suffix is not (a loader reads a value naming an existing file, or looking like a
    path, :func:`flatfree._names.looks_like_path`, as that file first). Anything but a
    ``str`` or ``os.PathLike`` is no name (None).
    """
    if kind not in _NAMES:
        raise ValueError(f"kind = {kind!r}: must be one of {', '.join(_NAMES)}")
    return _bundled_name(name, (_NAMES[kind],))


def _resolve(name_or_path: str | Path, folder, kind: str, base: Path | None = None):
    """The file of ``name_or_path``: a path when it names an existing file or looks like one
    (:func:`flatfree._names.looks_like_path`: a missing one gives the reader's "file not
    found"), else a bundled name (:func:`bundled_name`). A reference written in a file of the
    folder ``base`` is read from there (:func:`flatfree._names.anchored`, the scenario files'
    rule; None: as given, from the current directory)."""
    return _resolve_named(name_or_path, folder, kind, base)[0]


def _resolve_named(name_or_path: str | Path, folder, kind: str, base: Path | None = None):
    """:func:`_resolve` and the bundled name it found (None: a path)."""
    if base is not None:
        name_or_path = anchored(name_or_path, base, lambda text: bundled_name(text, kind))
    p = Path(name_or_path)
    if p.is_file() or looks_like_path(str(name_or_path)):
        return p, None
    name = bundled_name(name_or_path, kind)
    if name is None:
        raise ValueError(f"unknown {'tire set' if kind == 'tire' else kind} "
                         f"{str(name_or_path)!r}; valid names: {', '.join(_NAMES[kind]())}")
    return folder / f"{name}.toml", name


def vehicle_file(name_or_path: str | Path) -> Path:
    """The TOML file :func:`load_vehicle` reads for ``name_or_path``, found without reading it:
    a bundled preset's, or the path as given (an existing file, or a value that looks like a
    path: a missing one is the reader's "file not found"). ``ValueError`` for an unknown name,
    with the loader's message (a name checked where it is written, read later)."""
    return _resolve(name_or_path, _DATA, "vehicle")


def _values(table: dict, cls, where: str) -> dict[str, Any]:
    """Read ``name = {value, unit, source}`` entries, checking names and units against ``cls``."""
    known = {f.name: f.metadata.get("unit", "") for f in dataclasses.fields(cls)}
    out: dict[str, Any] = {}
    for key, entry in table.items():
        if key not in known:
            raise ValueError(f"{where}: unknown parameter {key!r}")
        if not isinstance(entry, dict) or "value" not in entry:
            raise ValueError(
                f"{where}: parameter {key!r} must be a table {{ value = ..., unit = ..., "
                "source = ... }}"
            )
        unit = entry.get("unit", "-")
        if unit != known[key] and not (known[key] == "-" and unit == ""):
            raise ValueError(
                f"{where}: parameter {key!r} is given in {unit!r}, expected {known[key]!r}"
            )
        if not str(entry.get("source", "")).strip():
            raise ValueError(f"{where}: parameter {key!r} cites no source")
        out[key] = entry["value"]
    return out


def _require(values: dict, cls, where: str, skip: tuple[str, ...]) -> None:
    """Refuse a file that leaves out a parameter without a default."""
    missing = [
        f.name
        for f in dataclasses.fields(cls)
        if f.name not in skip
        and f.name not in values
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise ValueError(f"{where}: missing parameter(s) {', '.join(missing)}")


def load_tire(name_or_path: str | Path) -> TireParams:
    """Load a tyre coefficient set: a bundled name (see :func:`tire_names`) or a TOML path."""
    return _load_tire(name_or_path)


def _load_tire(name_or_path: str | Path, base: Path | None = None) -> TireParams:
    """:func:`load_tire`, a relative path taken in the folder ``base`` (None: the current
    directory)."""
    path = _resolve(name_or_path, _DATA / "tires", "tire", base)
    doc = _read_toml(path, f"tire {name_or_path}")
    where = f"tire file {path}"
    _known_keys(doc, _TIRE_KEYS, where)
    coeffs = _values(doc.get("coefficients", {}), TireParams, where)
    _require(coeffs, TireParams, where, skip=("name", "cornering_law"))
    try:
        return TireParams(
            name=str(doc.get("name", Path(str(path)).stem)),
            cornering_law=str(doc.get("cornering_law", "mf52")),
            **coeffs,
        )
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _known_keys(table: dict, valid: tuple[str, ...], where: str) -> None:
    """Refuse the keys of a file's ``table`` that the loader does not read (a misspelt key or
    table would otherwise be ignored, its values silently missing), naming them and the valid
    ones."""
    unknown = [k for k in table if k not in valid]
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; valid: "
                         f"{', '.join(valid)}")


#: The top-level keys of a tyre file (``coefficients``: the table of TireParams values).
_TIRE_KEYS = ("name", "cornering_law", "coefficients")
#: The top-level keys of a vehicle file, all required.
_VEHICLE_KEYS = ("name", "drive", "tire_front", "tire_rear", "params")
#: The keys of a vehicle file's tyre table ``{set = ..., source = ..., <coefficient> = ...}``.
_TIRE_ENTRY_KEYS = ("set", "source", *(f.name for f in dataclasses.fields(TireParams)))


def load_vehicle(name_or_path: str | Path, **overrides: Any) -> VehicleParams:
    """Load a vehicle preset: a bundled name (see :func:`vehicle_names`) or a TOML path.

    A file holds the keys ``name``, ``drive``, ``tire_front``, ``tire_rear`` and the table
    ``[params]``, and nothing else. A tyre is a bundled set name or a TOML path, relative to the
    vehicle file's folder (see :func:`_tire_from_doc`). A ``ValueError`` from a file names it.

    ``overrides`` replace parameters after loading (validated like the rest), e.g.
    ``load_vehicle("peugeot406", mass=1360.0)``. A preset is read once per process and shared
    (a VehicleParams is immutable); a file is read on every call.
    """
    path, name = _resolve_named(name_or_path, _DATA, "vehicle")
    params = _preset(name) if name is not None else _vehicle_from_file(path, name_or_path)
    unknown = sorted(set(overrides) - {f.name for f in dataclasses.fields(VehicleParams)})
    if unknown:
        raise ValueError(f"vehicle overrides {unknown}: not parameters of a vehicle; valid: "
                         f"{', '.join(f.name for f in dataclasses.fields(VehicleParams))}")
    return dataclasses.replace(params, **overrides) if overrides else params


@functools.cache
def _preset(name: str) -> VehicleParams:
    """A bundled preset, read once per process: the package's files do not change under a
    running process (an edit of a preset in an editable install is seen by the next one);
    reading the peugeot406 and its two tyre files took a millisecond or two of each run's
    preparation (benchmarks/profile_closed_loop.py part 4)."""
    return _vehicle_from_file(_DATA / f"{name}.toml", name)


def _vehicle_from_file(path, name_or_path) -> VehicleParams:
    """:func:`load_vehicle` of the file ``path`` (``name_or_path``: as given), no overrides."""
    doc = _read_toml(path, f"vehicle {name_or_path}")
    where = f"vehicle file {path}"
    _known_keys(doc, _VEHICLE_KEYS, where)
    for key in _VEHICLE_KEYS:
        if key not in doc:
            raise ValueError(f"{where}: missing key {key!r}")
    values = _values(doc["params"], VehicleParams, where)
    _require(values, VehicleParams, where, skip=("name", "drive", "tire_front", "tire_rear"))
    base = path.parent if isinstance(path, Path) else None  # None: a preset in a zip, no paths
    try:
        params = VehicleParams(
            name=str(doc["name"]),
            drive=str(doc["drive"]),
            tire_front=_tire_from_doc(doc["tire_front"], base, "tire_front"),
            tire_rear=_tire_from_doc(doc["tire_rear"], base, "tire_rear"),
            **values,
        )
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return params


def _tire_from_doc(spec, base: Path | None, side: str) -> TireParams:
    """The tyre ``side`` (``tire_front`` or ``tire_rear``) of a vehicle file in the folder
    ``base``: a bundled set name or a TOML path, a relative one taken in ``base`` (as a scenario
    file's paths, :mod:`flatfree.scenario`), or ``{set = ..., lambda_ky = ..., source = ...}``
    (a set and values that replace its own). A ``ValueError`` names ``side``."""
    table = spec if isinstance(spec, dict) else {"set": spec}
    _known_keys(table, _TIRE_ENTRY_KEYS, side)
    if not isinstance(table.get("set"), str):
        raise ValueError(f"{side}: tire entry {spec!r} is neither a set name or path nor a "
                         "table with one as 'set'")
    extra = {k: v for k, v in table.items() if k not in ("set", "source")}
    try:
        return dataclasses.replace(_load_tire(table["set"], base), **extra)
    except ValueError as exc:
        raise ValueError(f"{side}: {exc}") from None
