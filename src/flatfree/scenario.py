"""Scenarios: one frozen, validated description of one closed-loop run, round-tripping through TOML.

A :class:`Scenario` names the vehicle and plant model, the reference (a track with a speed
profile, or a recording), the controller and its settings, the timing (plant step, control
period, logging), sensors, actuators, the road friction and faults, and the seed. Variants come
from ``dataclasses.replace`` (or :meth:`Scenario.with_`). A sweep is many scenarios.

TOML layout (every key optional except where a section says so; units in the key names)::

    name = "paper"
    vehicle = "peugeot406"          # bundled preset or a path to a vehicle TOML file
    plant = "10dof"                 # "10dof" (validation model) or "3dof" (design model)
    controller = "mfc-natural"      # "flatness", "mfc-flat", "mfc-natural"
    noise = true                    # false: every sensor noise-free (rates, delays kept)
    seed = 0

    [vehicle_overrides]             # VehicleParams fields, SI (the car's own: no mismatch)
    mass = 1600.0

    [reference]
    track = "Norisring"             # bundled name or CSV path; or  recording = "LVMS_23_01_04_B"
    line = "centerline"             # or "raceline"
    lateral_offset_m = 0.0
    laps = 1
    a_lat_max = 6.0                 # speed profile limits [m/s^2], [m/s], [-]
    a_drive_max = 3.0
    a_brake_max = 6.0
    v_max = 50.0
    mu = 1.0
    j_lat_max = inf                 # lateral jerk v^3 |dkappa/ds| [m/s^3]; inf = no limit
    drive_limit = false             # true: also within the car's drive limit (power, torque)
    # closed = false                # a track file's shape; default: detected from the file
    # smoothing_length_m = 20.0     # track smoothing cut-off [m]; default: the loader's

    [controller_settings]           # the chosen controller's own settings (checked by it)

    [timing]
    plant_dt_s = 0.001
    control_dt_s = 0.001
    log_dt_s = 0.01
    startup_s = 1.0
    # duration_s = 60.0             # default: until the path's end (Timing)

    [sensors.vx]                    # one table per measured channel (SENSOR_CHANNELS)
    noise_std = 0.05
    bias = 0.0
    # rate_hz = 100.0
    delay_s = 0.0

    [actuators]
    steer_tau_s = 0.0
    steer_delay_s = 0.0
    torque_tau_s = 0.0
    torque_delay_s = 0.0

    [road]
    mu = 1.0
    bank_deg = [[0.0, 0.0], [80.0, -9.2]]  # (s [m], bank [deg]) points; > 0 raises the left
    [[road.patch]]                  # friction patches along the reference path
    s_start_m = 500.0
    s_end_m = 600.0
    mu = 0.5

    [[fault]]
    kind = "nan_measurement"        # or "steer_limit" (value = the limit [rad], no channel)
    channel = "x"                   # a measured channel (flatfree.sensors.SENSOR_CHANNELS)
    t_start_s = 10.0
    duration_s = 0.05

A malformed file raises ``ValueError`` naming the file, the line and the field. A scenario
named ``...-noise-free`` (:mod:`flatfree.scenarios`) with ``noise = true`` is refused: its
results would carry a name that says the opposite.

File paths (``vehicle``, ``reference.track``, ``reference.recording``): a bundled name
(``"peugeot406"``, ``"Norisring"``, ``"LVMS_23_01_04_B"``) is a name, not a path, matched as the
loaders match it (:func:`flatfree.vehicles.params.bundled_name`,
:func:`flatfree.tracks._io.bundled_name`: case-insensitive, a track's ``.csv`` optional), and a
scenario holds it in its own spelling (``"monza"``: ``"Monza"``), unless the value names an
existing file in the current directory, which a loader reads first. A relative path in a file
read by :func:`load_scenario` is relative to that file's folder, as a loader reads a relative
path against the current directory: a value naming an existing file there is that file, then a
bundled name wins, then any other value that looks like a path (a folder separator or a file
suffix) is taken in that folder too, so that a missing file's error names where it was looked
for. The loaded scenario holds absolute paths.
:meth:`Scenario.save` (and ``flatfree run --out``) writes every file path absolute (a relative
one taken against the current directory, where a run would read it), so the saved file works
from any directory; :func:`scenario_to_toml` and :func:`scenario_from_toml` (text, no folder)
keep the file paths as they are.

Any field can also be changed by a *setting* ``"path=value"`` (:func:`scenario_with_settings`,
:meth:`Scenario.with_settings`, ``flatfree run --set``): the path is the field's dotted path in
this layout (``reference.j_lat_max``, ``sensors.y.markov_order``, ``controller_settings.kp_lat``)
and the value a TOML value (``15``, ``1.5e-3``, ``inf``, ``true``, ``"Monza"``, ``[1, 2]``), or a
bare string when it is not one (``reference.track=Monza``). An inline table given to a table
merges its keys into it (``reference={j_lat_max = 15, v_max = 40}``); nothing after the ``=``
puts a field, or a whole table (``timing=``), back to its default.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from flatfree._names import anchored
from flatfree._validate import (
    as_real,
    boolean,
    finite,
    nonnegative,
    positive,
    positive_or_inf,
    whole,
    whole_steps,
)
from flatfree.sensors import SENSOR_CHANNELS, SensorChannel, SensorSuite
from flatfree.vehicles.params import VehicleParams, load_vehicle
from flatfree.vehicles.params import bundled_name as bundled_vehicle

__all__ = [
    "CONTROLLERS",
    "PLANTS",
    "ReferenceSpec",
    "Timing",
    "ActuatorSpec",
    "FrictionPatch",
    "RoadSpec",
    "Fault",
    "Scenario",
    "load_scenario",
    "scenario_from_toml",
    "scenario_to_toml",
    "scenario_with_settings",
    "setting_path",
]

#: Controller names (the CLI's spelling).
CONTROLLERS = ("flatness", "mfc-flat", "mfc-natural")
PLANTS = ("10dof", "3dof")
LINES = ("centerline", "raceline")
FAULT_KINDS = ("nan_measurement", "steer_limit")
#: The name suffix of a scenario without sensor noise (flatfree.scenarios).
NOISE_FREE_SUFFIX = "-noise-free"


def _choice(name: str, value: Any, valid: tuple[str, ...]) -> str:
    if value not in valid:
        raise ValueError(f"{name} = {value!r}: must be one of {', '.join(valid)}")
    return value


def _bundled(value: Any, kind: str) -> str | None:
    """The bundled ``kind`` (``"vehicle"``, ``"track"``, ``"recording"``) that ``value`` names,
    in its own spelling, by the loaders' own lookup; None if none."""
    if kind == "vehicle":
        return bundled_vehicle(value)
    # late: importing flatfree.tracks loads its compiled kernels (the first Scenario with a
    # track or a recording pays it, an import of this module does not)
    from flatfree.tracks._io import bundled_name

    return bundled_name(value, kind)


def _canonical(value: Any, kind: str) -> Any:
    """``value`` with a bundled name in its own spelling (``"monza"``: ``"Monza"``); a value
    naming an existing file (the loaders read it first), and anything else, as given, a path
    object as its text (so that a scenario equals itself read back from its TOML file). Looks
    up names and asks whether the file exists; reads nothing."""
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str) or os.path.isfile(value):
        return value
    name = _bundled(value, kind)
    return value if name is None else name


def _not_a_channel(name: Any) -> str:
    return f"{name!r} is not a measured channel; channels: {', '.join(SENSOR_CHANNELS)}"


@dataclass(frozen=True, slots=True, kw_only=True)
class ReferenceSpec:
    """What to follow: a track (with a speed profile) or a recording."""

    track: str | None = "Norisring"
    recording: str | None = None
    line: str = "centerline"
    lateral_offset_m: float = 0.0
    laps: int = 1
    a_lat_max: float = 6.0  # [m/s^2]
    a_drive_max: float = 3.0  # [m/s^2]
    a_brake_max: float = 6.0  # [m/s^2]
    v_max: float = 50.0  # [m/s]
    mu: float = 1.0  # [-] friction the speed profile plans with
    #: lateral-jerk limit of the speed profile, v^3 |dkappa/ds| <= j_lat_max [m/s^3]
    #: (tracks.SpeedLimits.j_lat_max); inf (default, TOML ``inf``): none, the paper's profile
    j_lat_max: float = math.inf
    #: plan the speed profile within the vehicle's drive limit too (torque, power, drag, rolling
    #: resistance; tracks.speed_profile(vehicle=...)). Default false: the friction ellipse only
    #: (the issue's "default speed profile"), which asks a low-powered car for speeds it cannot
    #: reach on the straights (peugeot406: speed error RMS ~2.3 m/s, 0.1-0.4 m/s with the limit;
    #: benchmarks/README.md "Closed loop")
    drive_limit: bool = False
    #: a track file's shape (tracks.load_track): a loop (true) or an open road (false); None
    #: (default, omitted in TOML) detects it from the file (a closing repeat of the first
    #: point, or the ends within 3 point spacings)
    closed: bool | None = None
    #: the track's smoothing cut-off wavelength [m] (tracks.load_track; 0: none); None
    #: (default): the loader's (20 m; 60 m for the LVMS centerline built from its bounds)
    smoothing_length_m: float | None = None

    def __post_init__(self) -> None:
        for k in ("track", "recording"):
            v = getattr(self, k)
            if v is not None and not isinstance(v, (str, os.PathLike)):
                raise ValueError(f"reference.{k} = {v!r}: expected a name or a file path")
            object.__setattr__(self, k, _canonical(v, k))
        if (self.track is None) == (self.recording is None):
            raise ValueError(
                f"reference: give exactly one of track ({self.track!r}) and recording "
                f"({self.recording!r})"
            )
        _choice("reference.line", self.line, LINES)
        finite("reference.lateral_offset_m", self.lateral_offset_m, "m")
        whole("reference.laps", self.laps, 1)
        boolean("reference.drive_limit", self.drive_limit)
        if self.closed is not None:
            boolean("reference.closed", self.closed)
        if self.smoothing_length_m is not None:  # 0: the points as given (load_track)
            nonnegative("reference.smoothing_length_m", self.smoothing_length_m, "m")
        if self.recording is not None:
            given = [k for k in _TRACK_FILE_KEYS if getattr(self, k) is not None]
            if given:
                raise ValueError(
                    f"reference.{given[0]} = {getattr(self, given[0])!r}: a track's setting; "
                    f"the reference is the recording {self.recording!r} (its path as driven)")
        for k, u in (("a_lat_max", "m/s^2"), ("a_drive_max", "m/s^2"),
                     ("a_brake_max", "m/s^2"), ("v_max", "m/s"), ("mu", "-")):
            positive(f"reference.{k}", getattr(self, k), u)
        positive_or_inf("reference.j_lat_max", self.j_lat_max, "m/s^3")


@dataclass(frozen=True, slots=True, kw_only=True)
class Timing:
    """Plant step, control period, logging period, start-up interval, duration (all seconds).

    ``duration_s`` (default None): how long the run may last. On the controllers' default
    reference schedule (``schedule = "path"``: the reference read at the car's arc length) a
    run ends where its reference path ends, so None gives it 1.5 times the reference's
    duration plus 5 s (a car slower than the profile still finishes), and a longer
    ``duration_s`` is capped at twice that horizon (:func:`flatfree.simulation.prepare`; the
    loop allocates its log for the whole duration). On the clock schedule
    (``schedule = "time"``) None is the reference's duration and a ``duration_s`` is kept.
    A ``duration_s`` shorter than one plant step (to the nearest step) is refused.

    The model-free controllers' estimator windows and denoisers are counts of samples, tuned
    at ``control_dt_s`` = 0.001 s: :meth:`Scenario.with_control_period` changes the period and
    rescales them to the same durations (changing ``control_dt_s`` alone keeps the counts, and
    the run warns when their durations are far from the tuned ones).
    """

    plant_dt_s: float = 0.001
    control_dt_s: float = 0.001
    log_dt_s: float = 0.01
    startup_s: float = 1.0
    duration_s: float | None = None

    def __post_init__(self) -> None:
        positive("timing.plant_dt_s", self.plant_dt_s, "s")
        positive("timing.control_dt_s", self.control_dt_s, "s")
        positive("timing.log_dt_s", self.log_dt_s, "s")
        nonnegative("timing.startup_s", self.startup_s, "s")
        if self.duration_s is not None:
            positive("timing.duration_s", self.duration_s, "s")
            # the run's steps, as simulation.prepare counts them (to the nearest): none, an
            # empty log reported as completed
            if whole_steps(self.duration_s, self.plant_dt_s)[0] < 1:
                raise ValueError(
                    f"timing.duration_s = {self.duration_s!r} s: shorter than one plant step "
                    f"(plant_dt_s = {self.plant_dt_s!r} s), the run would take none")
        for k in ("control_dt_s", "log_dt_s"):
            n, moved = whole_steps(getattr(self, k), self.plant_dt_s)
            if moved or n < 1:
                raise ValueError(
                    f"timing.{k} = {getattr(self, k)!r} s: must be a whole multiple of "
                    f"plant_dt_s = {self.plant_dt_s!r} s"
                )

    @property
    def control_every(self) -> int:
        """Plant steps per control period."""
        return round(self.control_dt_s / self.plant_dt_s)

    @property
    def log_every(self) -> int:
        """Plant steps per logged sample."""
        return round(self.log_dt_s / self.plant_dt_s)


@dataclass(frozen=True, slots=True, kw_only=True)
class ActuatorSpec:
    """Actuator dynamics; the limits come from the vehicle preset."""

    steer_tau_s: float = 0.0
    steer_delay_s: float = 0.0
    torque_tau_s: float = 0.0
    torque_delay_s: float = 0.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            nonnegative(f"actuators.{f.name}", getattr(self, f.name), "s")


@dataclass(frozen=True, slots=True, kw_only=True)
class FrictionPatch:
    """A stretch of road [s_start_m, s_end_m) along the reference path with friction ``mu``.

    ``s`` is the path's arc length; on a closed path it is taken modulo the lap, so a patch
    acts on every lap and must start within the lap (a run refuses one that starts at or
    beyond the path's length: it would never apply).
    """

    s_start_m: float
    s_end_m: float
    mu: float

    def __post_init__(self) -> None:
        nonnegative("road.patch.s_start_m", self.s_start_m, "m")
        if finite("road.patch.s_end_m", self.s_end_m, "m") <= self.s_start_m:
            raise ValueError(
                f"road.patch.s_end_m = {self.s_end_m!r} m: must exceed s_start_m = "
                f"{self.s_start_m!r} m"
            )
        positive("road.patch.mu", self.mu, "-")


@dataclass(frozen=True, slots=True, kw_only=True)
class RoadSpec:
    """Road friction (a base ``mu`` and patches along the path) and the road's bank.

    ``bank_deg``: the road's bank angle along the path as points ``(s [m], bank [deg])``,
    linearly interpolated between them and held beyond the first and last (on a closed track
    ``s`` is taken modulo the lap); ``bank > 0`` raises the left side, so a left-hand turn
    banked for speed has ``bank < 0`` (the 10DoF model's input ``bank``,
    :mod:`flatfree.models.tendof`, Model item 7; the 3DoF plant ignores it). Empty: a flat
    road. Degrees here, at the edge of a file a user writes; radians inside.
    """

    mu: float = 1.0
    patches: tuple[FrictionPatch, ...] = ()
    bank_deg: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        positive("road.mu", self.mu, "-")
        if not isinstance(self.patches, (tuple, list)):
            raise ValueError(f"road.patches = {self.patches!r}: expected a sequence of "
                             "FrictionPatch ([[road.patch]] tables in a file)")
        object.__setattr__(self, "patches", tuple(self.patches))
        if not isinstance(self.bank_deg, (tuple, list)):
            # a bare number reads as "a constant bank": say how to write one
            raise ValueError(f"road.bank_deg = {self.bank_deg!r}: expected a list of "
                             "(s [m], bank [deg]) points, e.g. [[0.0, 5.0]] for a constant "
                             "5 deg bank")
        points = []
        for k, pt in enumerate(self.bank_deg):
            pair = [as_real(v) for v in pt] if isinstance(pt, (tuple, list)) else []
            if len(pair) != 2 or None in pair:  # text and booleans are not numbers
                raise ValueError(f"road.bank_deg[{k}] = {pt!r}: expected a pair "
                                 "(s [m], bank [deg])")
            s_m, b = pair
            if not (math.isfinite(s_m) and math.isfinite(b) and abs(b) < 90.0):
                raise ValueError(f"road.bank_deg[{k}] = {pt!r}: s must be finite and the bank "
                                 "within (-90, 90) deg")
            if points and s_m <= points[-1][0]:
                raise ValueError(f"road.bank_deg[{k}] = {pt!r}: s must increase strictly "
                                 f"(the point before is at {points[-1][0]!r} m)")
            points.append((s_m, b))
        object.__setattr__(self, "bank_deg", tuple(points))


@dataclass(frozen=True, slots=True, kw_only=True)
class Fault:
    """A fault injected during the run.

    ``nan_measurement``: the measured ``channel`` reads NaN during the interval.
    ``steer_limit``: the steering range is limited to ``value`` [rad] during the interval; a
    steer beyond it when the fault starts is driven in at the actuator's rate limit
    (``max_steer_rate``), as the steering motor would, then held within it.
    A key of the other kind (a ``value`` for ``nan_measurement``, a ``channel`` for
    ``steer_limit``) is refused: the run would ignore it.
    """

    kind: str
    t_start_s: float
    duration_s: float
    channel: str | None = None
    value: float | None = None

    def __post_init__(self) -> None:
        _choice("fault.kind", self.kind, FAULT_KINDS)
        nonnegative("fault.t_start_s", self.t_start_s, "s")
        positive("fault.duration_s", self.duration_s, "s")
        # a key of the other kind: refused, not ignored
        other = {"nan_measurement": ("value", "the measured channel reads NaN"),
                 "steer_limit": ("channel", "it limits the steering range to value [rad]")}
        key, what = other[self.kind]
        if getattr(self, key) is not None:
            keys = ("kind, channel, t_start_s, duration_s" if self.kind == "nan_measurement"
                    else "kind, t_start_s, duration_s, value")
            raise ValueError(f"fault.{key} = {getattr(self, key)!r}: a {self.kind} fault takes "
                             f"no {key} ({what}); its keys: {keys}")
        if self.kind == "nan_measurement":
            if not self.channel:
                raise ValueError("fault.channel: a nan_measurement fault needs the channel name")
            if self.channel not in SENSOR_CHANNELS:
                raise ValueError(f"fault.channel: {_not_a_channel(self.channel)}")
        if self.kind == "steer_limit":
            if self.value is None:
                raise ValueError("fault.value: a steer_limit fault needs the limit [rad]")
            nonnegative("fault.value", self.value, "rad")


@dataclass(frozen=True, slots=True, kw_only=True)
class Scenario:
    """One closed-loop run, fully described (see the module docstring for the TOML layout).

    Besides each field's own check: a bundled car, track or recording is held in its own
    spelling (module docstring, "File paths"); a sensor table and a ``nan_measurement`` fault
    name a measured channel (:data:`flatfree.sensors.SENSOR_CHANNELS`); a name ending in
    ``-noise-free`` refuses ``noise = true``. ``ValueError`` naming the field and the value.

    ``vehicle_overrides`` change the car itself: the plant and every model built from it (the
    flatness controller's design model, the flat-output MFC's m, Iz, lf, the yaw error's
    reference sideslip), so they make no plant/model mismatch; the flatness controller's
    ``cf_scale`` / ``cr_scale`` settings do (``paper-mismatch``).
    """

    name: str = "custom"
    description: str = ""
    vehicle: str = "peugeot406"
    vehicle_overrides: Mapping[str, float] = field(default_factory=dict)
    plant: str = "10dof"
    controller: str = "mfc-natural"
    controller_settings: Mapping[str, Any] = field(default_factory=dict)
    reference: ReferenceSpec = field(default_factory=ReferenceSpec)
    timing: Timing = field(default_factory=Timing)
    sensors: SensorSuite = field(default_factory=SensorSuite)
    noise: bool = True
    actuators: ActuatorSpec = field(default_factory=ActuatorSpec)
    road: RoadSpec = field(default_factory=RoadSpec)
    faults: tuple[Fault, ...] = ()
    seed: int = 0

    def __post_init__(self) -> None:
        for k in ("name", "description"):
            if not isinstance(getattr(self, k), str):
                raise ValueError(f"{k} = {getattr(self, k)!r}: expected a text")
        if not isinstance(self.vehicle, (str, os.PathLike)):
            raise ValueError(f"vehicle = {self.vehicle!r}: expected a preset name or a file path")
        object.__setattr__(self, "vehicle", _canonical(self.vehicle, "vehicle"))
        _choice("plant", self.plant, PLANTS)
        _choice("controller", self.controller, CONTROLLERS)
        # an integral float too (a TOML 3.0), as laps; an integer exactly, however large
        object.__setattr__(self, "seed", whole("seed", self.seed, 0))
        boolean("noise", self.noise)
        if self.noise and self.name.endswith(NOISE_FREE_SUFFIX):
            raise ValueError(
                f"noise = true: the scenario's name {self.name!r} says noise-free; run "
                f"{self.name.removesuffix(NOISE_FREE_SUFFIX)!r} for the noisy variant, or "
                "rename it (name = ...)")
        for k, v in self.vehicle_overrides.items():
            if isinstance(v, bool) or not isinstance(v, (int, float, str)):
                raise ValueError(f"vehicle_overrides.{k} = {v!r}: expected a number")
        for f, cls in (("reference", ReferenceSpec), ("timing", Timing),
                       ("sensors", SensorSuite), ("actuators", ActuatorSpec),
                       ("road", RoadSpec)):
            if not isinstance(getattr(self, f), cls):
                raise ValueError(f"{f} = {getattr(self, f)!r}: expected a {cls.__name__}")
        for ch in self.sensors.channels:  # a channel the loop does not measure is a typo
            if ch not in SENSOR_CHANNELS:
                raise ValueError(f"sensors.{ch}: {_not_a_channel(ch)}")
        object.__setattr__(self, "vehicle_overrides",
                           MappingProxyType(dict(self.vehicle_overrides)))
        object.__setattr__(self, "controller_settings",
                           MappingProxyType(dict(self.controller_settings)))
        if isinstance(self.faults, (Fault, str, bytes, Mapping)) or not isinstance(
                self.faults, Iterable):
            raise ValueError(f"faults = {self.faults!r}: expected a sequence of Fault "
                             "(faults=(Fault(...),))")
        object.__setattr__(self, "faults", tuple(self.faults))  # once: an iterator too
        for i, f in enumerate(self.faults):
            if not isinstance(f, Fault):
                raise ValueError(f"faults[{i}] = {f!r}: expected a Fault "
                                 "(flatfree.scenario.Fault(kind=..., t_start_s=..., ...))")

    def with_(self, **changes: Any) -> Scenario:
        """A copy with top-level fields replaced (validated)."""
        return dataclasses.replace(self, **changes)

    def with_settings(self, settings: Sequence[str] | Mapping[str, Any]) -> Scenario:
        """A copy with fields at any depth changed by settings ``"path=value"``.

        ``sc.with_settings(["reference.j_lat_max=15", "sensors.y.markov_order=2"])``; see
        :func:`scenario_with_settings`.
        """
        return scenario_with_settings(self, settings)

    def with_control_period(self, dt: float) -> Scenario:
        """A copy whose controller runs every ``dt`` [s] (``timing.control_dt_s``, a whole
        multiple of ``timing.plant_dt_s``) with the same estimator windows and denoisers in
        time: the controller's sample counts are rescaled from the present control period
        (:func:`flatfree.controllers.vehicle.rescale_sample_counts`) and written into
        ``controller_settings``. Setting ``timing.control_dt_s`` alone keeps the counts, so the
        windows' durations change with the period (a warning says so when they are far from
        the tuned ones)."""
        from flatfree.controllers.vehicle import (
            rescale_sample_counts,
            sample_counts,
            settings_from_mapping,
        )

        timing = dataclasses.replace(self.timing, control_dt_s=dt)
        settings = settings_from_mapping(self.controller, self.controller_settings)
        counts = sample_counts(rescale_sample_counts(settings, timing.control_dt_s,
                                                     from_dt=self.timing.control_dt_s))
        return dataclasses.replace(self, timing=timing,
                                   controller_settings={**self.controller_settings, **counts})

    def load_vehicle(self) -> VehicleParams:
        """The car the scenario runs: its preset or file with ``vehicle_overrides`` applied
        (:func:`flatfree.vehicles.load_vehicle`; ``ValueError`` naming what is wrong)."""
        return load_vehicle(self.vehicle, **dict(self.vehicle_overrides))

    @property
    def effective_sensors(self) -> SensorSuite:
        """The sensors as used: noise-free when ``noise`` is false."""
        return self.sensors if self.noise else self.sensors.noise_free()

    # ----- TOML -----
    def to_toml(self) -> str:
        """The scenario as TOML text (read back by :func:`scenario_from_toml`)."""
        return scenario_to_toml(self)

    def save(self, path: str | Path) -> Path:
        """Write the scenario to a TOML file, its file paths absolute (module docstring: a
        relative path is taken against the current directory), so the file works from any
        directory; bundled names stay names."""
        path = Path(path)
        path.write_text(scenario_to_toml(_anchor_files(self, Path.cwd())), encoding="utf-8")
        return path


# ------------------------------------------------------------------------------------------
# TOML <-> Scenario
# ------------------------------------------------------------------------------------------
_TOP_KEYS = ("name", "description", "vehicle", "plant", "controller", "noise", "seed")
_TABLES = ("vehicle_overrides", "controller_settings", "reference", "timing", "sensors",
           "actuators", "road", "fault")


def _plain(obj) -> dict[str, Any]:
    """A flat dataclass as a dict without None values (a path as its text)."""
    return {f.name: os.fspath(v) if isinstance(v, os.PathLike) else v
            for f in dataclasses.fields(obj) if (v := getattr(obj, f.name)) is not None}


def _anchored(value: Any, folder: Path, kind: str) -> Any:
    """``value``, a bundled name or a file path, as a loader reads it from ``folder``
    (precedence: module docstring; :func:`flatfree._names.anchored`)."""
    return anchored(value, folder, lambda text: _bundled(text, kind))


def _anchor_files(sc: Scenario, folder: Path) -> Scenario:
    """``sc`` with its relative file paths made absolute against ``folder``."""
    ref = sc.reference
    return dataclasses.replace(
        sc, vehicle=_anchored(sc.vehicle, folder, "vehicle"),
        reference=dataclasses.replace(ref, track=_anchored(ref.track, folder, "track"),
                                      recording=_anchored(ref.recording, folder, "recording")))


def scenario_to_toml(sc: Scenario) -> str:
    """Serialise a scenario (inverse of :func:`scenario_from_toml`)."""
    import tomli_w

    doc: dict[str, Any] = {k: getattr(sc, k) for k in _TOP_KEYS}
    doc["vehicle"] = os.fspath(sc.vehicle)
    if sc.vehicle_overrides:
        doc["vehicle_overrides"] = dict(sc.vehicle_overrides)
    if sc.controller_settings:
        doc["controller_settings"] = dict(sc.controller_settings)
    doc["reference"] = _plain(sc.reference)
    doc["timing"] = _plain(sc.timing)
    if sc.sensors.channels:
        doc["sensors"] = {k: _plain(c) for k, c in sc.sensors.channels.items()}
    doc["actuators"] = _plain(sc.actuators)
    road: dict[str, Any] = {"mu": sc.road.mu}
    if sc.road.bank_deg:
        road["bank_deg"] = [list(pt) for pt in sc.road.bank_deg]
    if sc.road.patches:
        road["patch"] = [_plain(p) for p in sc.road.patches]
    doc["road"] = road
    if sc.faults:
        doc["fault"] = [_plain(f) for f in sc.faults]
    return tomli_w.dumps(doc)


def _line_of(text: str, table: str | None, key: str | None, index: int = 0) -> int | None:
    """Line number (1-based) where ``key`` is set inside ``table`` (None: top level); in an
    array of tables, inside its ``index``-th table (0-based)."""
    current: str | None = None
    seen = 0 if table is None else -1  # the table's headers so far, minus one
    header = re.compile(r"^\s*\[\[?\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
    assign = re.compile(r"^\s*([A-Za-z0-9_\-\"'.]+)\s*=")
    for i, line in enumerate(text.splitlines(), start=1):
        m = header.match(line)
        if m:
            current = m.group(1).strip()
            if current == table:
                seen += 1
                if key is None and seen == index:
                    return i
            continue
        m = assign.match(line)
        if (m and key is not None and current == table and seen == index
                and m.group(1).strip("\"'") == key):
            return i
    return None


class _FieldError(ValueError):
    """A validation error of a scenario document: the message, and the field it names."""

    def __init__(self, message: str, field: str | None, detail: str) -> None:
        super().__init__(message)
        self.field = field  # dotted path (None: no field found in the message)
        self.detail = detail  # "field ...: ..." without the source and the line


class _Where:
    """Turns a validation error into one that names the file, the line and the field."""

    def __init__(self, text: str, source: str) -> None:
        self.text = text
        self.source = source

    def error(self, exc: Exception, table: str | None, key: str | None,
              index: int | None = None) -> ValueError:
        """``index``: the table's place (0-based) in an array of tables (``[[fault]]``)."""
        line = (_line_of(self.text, table, key, index or 0)
                or _line_of(self.text, table, None, index or 0))
        fld = key if table is None else f"{table}.{key}" if key else table
        at = f", line {line}" if line else ""
        which = f" ([[{table}]] table {index + 1})" if index is not None else ""
        detail = f"field {fld}{which}: {exc}"
        return _FieldError(f"{self.source}{at}: {detail}", fld, detail)

    def tables(self, values: Any, name: str) -> list:
        """The tables of an array of tables (``[[fault]]``, ``[[road.patch]]``)."""
        if not isinstance(values, list) or not all(isinstance(v, dict) for v in values):
            table, _, key = name.rpartition(".")
            raise self.error(ValueError(f"expected an array of tables [[{name}]]"),
                             table or None, key)
        return values

    def build(self, cls, table: str, values: Mapping[str, Any], prefix: str | None = None,
              index: int | None = None):
        prefix = prefix or table
        known = {f.name for f in dataclasses.fields(cls)}
        for key in values:
            if key not in known:
                raise self.error(
                    ValueError(f"unknown key; valid keys: {', '.join(sorted(known))}"),
                    prefix, key, index)
        missing = [f.name for f in dataclasses.fields(cls) if f.name not in values
                   and f.default is dataclasses.MISSING
                   and f.default_factory is dataclasses.MISSING]
        if missing:
            raise self.error(ValueError(f"missing key{'s' if len(missing) > 1 else ''} "
                                        f"{', '.join(missing)}"), prefix, None, index)
        try:
            return cls(**values)
        except (TypeError, ValueError) as exc:
            key = _field_in_message(str(exc), values)
            raise self.error(exc, prefix, key, index) from None


def _nth(i: int, tables: list) -> int | None:
    """A table's place in its array for the messages: None when it is the only one."""
    return i if len(tables) > 1 else None


def _field_in_message(msg: str, values: Mapping[str, Any]) -> str | None:
    """The key of ``values`` that a validation message names first."""
    best: tuple[int, str] | None = None
    for key in values:
        m = re.search(rf"(^|[\s.]){re.escape(key)}\b", msg)
        if m and (best is None or m.start() < best[0]):
            best = (m.start(), key)
    return best[1] if best else None


def scenario_from_toml(text: str, source: str = "<scenario>", *,
                       base_dir: str | Path | None = None) -> Scenario:
    """Parse TOML text into a :class:`Scenario`; errors name the line and the field.

    ``base_dir``: the folder relative file paths in the text are relative to
    (:func:`load_scenario` passes the file's folder; module docstring); they come back
    absolute. None: the values are kept as written (a relative path is then read against the
    current directory when the scenario runs).

    Besides the scenario's own checks, the controller's settings (for the text's controller)
    and the ``[vehicle_overrides]`` (on its car, read for them) are checked as a run checks
    them, so that a mistake there is a ``ValueError`` naming the source, the line and the
    field rather than the run's error. A car without overrides is not read here (a missing
    car file is the run's error).
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: malformed TOML: {exc}") from None
    where = _Where(text, source)
    sc = _scenario_from_doc(doc, where, base_dir)
    # what a scenario leaves to the run, checked here so that the error names the source, the
    # line and the field: the controller's settings, and the text's vehicle_overrides (on
    # its car, which is read then; a car without overrides is read by the run)
    for table, values, top, exc in _part_errors(sc, vehicle=bool(sc.vehicle_overrides)):
        # a key quoted first ("['alpha_lat'] unknown ...; valid keys: cf_scale, ..."), else
        # the one the message names first ("alpha_lat = '48.9' ...")
        key = next((k for k in values if repr(k) in str(exc)), None) or _field_in_message(
            str(exc), values)
        raise (where.error(exc, table, key) if key is not None
               else where.error(exc, None, top)) from None
    return sc


def _scenario_from_doc(doc: dict[str, Any], where: _Where,
                       base_dir: str | Path | None = None) -> Scenario:
    """The :class:`Scenario` of a scenario document (TOML parsed: plain tables and values);
    ``where`` names the errors, ``base_dir`` as in :func:`scenario_from_toml`."""
    for key in doc:
        if key not in _TOP_KEYS and key not in _TABLES:
            raise where.error(ValueError(
                f"unknown key; valid keys: {', '.join(_TOP_KEYS + _TABLES)}"), None, key)

    def table(name: str) -> dict:
        value = doc.get(name, {})
        if not isinstance(value, dict):
            raise where.error(ValueError("expected a table"), None, name)
        return value

    kwargs: dict[str, Any] = {k: doc[k] for k in _TOP_KEYS if k in doc}
    kwargs["vehicle_overrides"] = table("vehicle_overrides")
    kwargs["controller_settings"] = table("controller_settings")
    ref_values = _reference_values(table("reference"))
    if base_dir is not None:  # the file's folder first (the scenario then checks the names)
        folder = Path(base_dir)
        if "vehicle" in kwargs:
            kwargs["vehicle"] = _anchored(kwargs["vehicle"], folder, "vehicle")
        for k in ("track", "recording"):
            if k in ref_values:
                ref_values[k] = _anchored(ref_values[k], folder, k)
    kwargs["reference"] = where.build(ReferenceSpec, "reference", ref_values)
    kwargs["timing"] = where.build(Timing, "timing", table("timing"))
    channels = {}
    for ch, values in table("sensors").items():
        if not isinstance(values, dict):
            raise where.error(ValueError("expected a table"), "sensors", ch)
        if ch not in SENSOR_CHANNELS:
            raise where.error(ValueError(_not_a_channel(ch)), f"sensors.{ch}", None)
        channels[ch] = where.build(SensorChannel, f"sensors.{ch}", values)
    kwargs["sensors"] = SensorSuite(channels)
    kwargs["actuators"] = where.build(ActuatorSpec, "actuators", table("actuators"))
    road = dict(table("road"))
    if "patches" in road:  # the field's name in RoadSpec, not in the file
        raise where.error(ValueError("unknown key; friction patches are [[road.patch]] "
                                     "tables"), "road", "patches")
    patches = where.tables(road.pop("patch", []), "road.patch")
    kwargs["road"] = where.build(RoadSpec, "road", {
        **road,
        "patches": tuple(where.build(FrictionPatch, "road.patch", p, index=_nth(i, patches))
                         for i, p in enumerate(patches)),
    })
    faults = where.tables(doc.get("fault", []), "fault")
    # each fault's kind is checked before its keys, so that a fault with an unknown kind and a
    # missing key is reported by its kind (the first thing wrong with it)
    for i, f in enumerate(faults):
        if "kind" in f:
            try:
                _choice("fault.kind", f["kind"], FAULT_KINDS)
            except ValueError as exc:
                raise where.error(exc, "fault", "kind", _nth(i, faults)) from None
    kwargs["faults"] = tuple(where.build(Fault, "fault", f, index=_nth(i, faults))
                             for i, f in enumerate(faults))
    try:
        sc = Scenario(**kwargs)
    except (TypeError, ValueError) as exc:
        key = _field_in_message(str(exc), dict.fromkeys(_TOP_KEYS))
        raise where.error(exc, None, key) from None
    return sc


#: The reference settings that describe a track file (ReferenceSpec): dropped when the track
#: or the recording is replaced (scenario_with_settings, the CLI's --track and --recording).
_TRACK_FILE_KEYS = ("closed", "smoothing_length_m")


def _reference_values(reference: dict) -> dict:
    ref = dict(reference)
    if "recording" in ref and "track" not in ref:
        ref["track"] = None  # a recording replaces the default track
    return ref


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario TOML file; its relative file paths are relative to its folder (module
    docstring) and come back absolute.

    Checked as :func:`scenario_from_toml` checks a text (the controller's settings and the
    ``[vehicle_overrides]`` too); the errors name the file, the line and the field."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"scenario file not found: {path}") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"scenario file {path}: not a UTF-8 text file ({exc})") from None
    except OSError as exc:  # a folder, no permission, ...
        raise ValueError(f"scenario file {path}: cannot read it ({exc.strerror or exc})"
                         ) from None
    return scenario_from_toml(text, source=str(path), base_dir=path.parent)


# ------------------------------------------------------------------------------------------
# settings "path=value"
# ------------------------------------------------------------------------------------------
#: Arrays of tables: several entries, which one path cannot address.
_TABLE_ARRAYS = (("fault",), ("road", "patch"))
#: The dataclass whose fields a table holds (the annotations of its fields type the values).
_SECTIONS: dict[str, type] = {"reference": ReferenceSpec, "timing": Timing,
                              "actuators": ActuatorSpec, "road": RoadSpec}


@dataclass(frozen=True, slots=True)
class _Setting:
    label: str  # as the user wrote it: "path=value" (or path=repr(value) from a mapping)
    path: tuple[str, ...]
    value: Any
    text: str | None  # the value's text of a "path=value" string (None: from a mapping)
    #: how the messages name a setting the user gave as something else, e.g. the command
    #: line's option "--noise" (None: "setting LABEL")
    shown: str | None = None


def _parse_value(text: str) -> Any:
    """A TOML value (``15``, ``inf``, ``true``, ``"a"``, ``[1, 2]``), else the text itself."""
    try:
        doc = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        return text
    return doc["v"] if set(doc) == {"v"} else text


def _split_path(path: str, label: str) -> tuple[str, ...]:
    parts = tuple(p.strip() for p in path.split("."))
    if not all(parts):
        raise ValueError(f"setting {label}: the path {path.strip()!r} has an empty part; "
                         "expected a dotted path like reference.j_lat_max")
    return parts


def setting_path(setting: str) -> str:
    """The dotted field path of a setting ``"path=value"`` as :func:`scenario_with_settings`
    reads it (``" reference . track = Monza"``: ``"reference.track"``); ``ValueError`` for a
    malformed one, as there."""
    (st,) = _settings([setting])
    return ".".join(st.path)


def _changed_paths(setting: str) -> list[str]:
    """The dotted paths a setting ``"path=value"`` changes: its path, or each key of an inline
    table it merges into a table (``reference={j_lat_max = 15}``: ``reference.j_lat_max``;
    :func:`_expand`); ``ValueError`` for a malformed one."""
    return [".".join(st.path) for st in _expand(*_settings([setting]))]


def _settings(settings: Sequence[str] | Mapping[str, Any]) -> list[_Setting]:
    if isinstance(settings, Mapping):
        return [_Setting(f"{k}={v!r}", _split_path(str(k), f"{k}={v!r}"), v, None)
                for k, v in settings.items()]
    if isinstance(settings, (str, bytes)) or not isinstance(settings, Sequence):
        raise TypeError(f"settings = {settings!r}: expected a sequence of 'path=value' "
                        "strings or a mapping {path: value}")
    out = []
    for s in settings:
        if not isinstance(s, str):
            raise TypeError(f"setting {s!r}: expected a string 'path=value'")
        path, eq, text = s.partition("=")
        if not eq:
            raise ValueError(f"setting {s}: expected FIELD=VALUE, e.g. reference.j_lat_max=15")
        text = text.strip()
        # nothing after the "=": the field's default, as a mapping's None (TOML has no null)
        value = None if text == "" else _parse_value(text)
        out.append(_Setting(s, _split_path(path, s), value, text))
    return out


def _annotation(path: tuple[str, ...]) -> str:
    """The annotation of the dataclass field at ``path`` ("" for a free key or no field)."""
    if len(path) == 1:
        cls, name = Scenario, path[0]
    elif len(path) == 2 and path[0] in _SECTIONS:
        cls, name = _SECTIONS[path[0]], path[1]
    elif len(path) == 3 and path[0] == "sensors":
        cls, name = SensorChannel, path[2]
    else:
        return ""
    return str(next((f.type for f in dataclasses.fields(cls) if f.name == name), ""))


def _typed(st: _Setting) -> Any:
    """The setting's value for its field: a string field takes the text as written (``name=2024``
    is the name "2024"), a float field stores an integer as a float. (A number field's
    validation refuses text and booleans: :mod:`flatfree._validate`.)"""
    value, ann = st.value, _annotation(st.path)
    if value is None:  # the field's default (a mapping's None, or nothing after the "=")
        return None
    if ann in ("str", "str | None") and st.text is not None and not isinstance(value, str):
        return st.text  # a number or boolean the TOML parser read: the text as written
    if ann in ("float", "float | None") and type(value) is int:
        return float(value)
    return value


def _is_table(path: tuple[str, ...]) -> bool:
    """Whether ``path`` is a table of a scenario (``reference``, ``sensors``, ``sensors.vx``,
    ...), present in it or not; the arrays of tables excluded."""
    return ((len(path) == 1 and path[0] in _TABLES and path not in _TABLE_ARRAYS)
            or (len(path) == 2 and path[0] == "sensors"))


def _expand(st: _Setting) -> list[_Setting]:
    """A setting of a table to an inline table as the settings of its keys, in order
    (``reference={j_lat_max = 15}``: ``reference.j_lat_max = 15``; a nested table likewise),
    so that the table keeps its other fields; an empty table ``{}`` is the table's defaults,
    as nothing after the ``=``. Each keeps the setting's label, for the messages."""
    if not _is_table(st.path) or not isinstance(st.value, Mapping):
        return [st]
    if not st.value:
        return [dataclasses.replace(st, value=None, text="")]
    out = []
    for key, value in st.value.items():
        out.extend(_expand(_Setting(st.label, (*st.path, str(key)), value, None, st.shown)))
    return out


def _assign(doc: dict[str, Any], st: _Setting, explicit: set[tuple[str, ...]]) -> None:
    """Set ``st`` in the scenario document ``doc`` (in place)."""
    path = st.path
    for arr in _TABLE_ARRAYS:
        if path[:len(arr)] == arr:
            name = ".".join(arr)
            value = st.value
            if path == arr and (value is None or (isinstance(value, list) and all(
                    isinstance(v, Mapping) for v in value))):
                # the whole array: none (nothing after the =, or []) or its tables, replaced
                node = doc
                for key in arr[:-1]:
                    node = node.setdefault(key, {})
                if value:
                    node[arr[-1]] = [dict(v) for v in value]
                else:
                    node.pop(arr[-1], None)
                return
            raise ValueError(f"{_labels([st])}: {name} is an array of tables ([[{name}]]): "
                             f"a setting replaces all of it ({name}=[{{KEY = VALUE, ...}}, "
                             f"...]) or clears it ({name}= or {name}=[]), and cannot address "
                             "one entry's field")
    node = doc
    for i, key in enumerate(path[:-1]):
        prefix = path[:i + 1]
        dotted = ".".join(prefix)
        if key not in node:  # a table the scenario does not hold (or a setting reset)
            if i == 0 and not _is_table(prefix):
                valid = ", ".join(t for t in _TABLES if t != "fault")
                raise ValueError(f"{_labels([st])}: {dotted} is not a table of a scenario; "
                                 f"tables: {valid}")
            if i > 0 and not _is_table(prefix):
                raise ValueError(f"{_labels([st])}: {'.'.join(prefix[:-1])} has no table "
                                 f"{key!r}")
            node[key] = {}
        elif not isinstance(node[key], dict):
            raise ValueError(f"{_labels([st])}: {dotted} = {node[key]!r} is not a table, "
                             f"so it has no field {path[i + 1]!r}")
        node = node[key]
    key, dotted = path[-1], ".".join(path)
    value = _typed(st)
    if _is_table(path) and value is not None:  # (an inline table was merged: _expand)
        raise ValueError(f"{_labels([st])}: {dotted} is a table: set one of its fields "
                         f"({dotted}.FIELD=VALUE), several in an inline table "
                         f"({dotted}={{FIELD = VALUE, ...}}), or nothing after the = for "
                         "its defaults")
    if value is None:
        # back to the default (a mapping's None; TOML has no null); a table's: all of it
        node.pop(key, None)
    else:
        try:
            import tomli_w

            value = tomllib.loads(tomli_w.dumps({"v": value}))["v"]  # as a TOML file holds it
        except (TypeError, ValueError):
            raise ValueError(f"{_labels([st])}: {dotted} = {value!r}: not a TOML value "
                             "(number, boolean, string, array or table)") from None
        node[key] = value
    # a track replaces the recording and a recording the track (as --track, --recording do),
    # unless both are set; the settings that describe the old track's file go with it (a
    # recording refuses them, another file has its own shape) unless set here too
    other = {("reference", "track"): "recording", ("reference", "recording"): "track"}
    if path in other:
        for k in (other[path], *_TRACK_FILE_KEYS):
            if ("reference", k) not in explicit:
                node.pop(k, None)


def _culprits(items: list[_Setting], fld: str | None) -> list[_Setting]:
    """The settings a validation error of field ``fld`` is about (all when unclear)."""
    if fld:
        f = tuple(fld.split("."))
        hit = [s for s in items if f[:len(s.path)] == s.path or s.path[:len(f)] == f]
        if not hit:  # e.g. timing.control_dt_s no longer a multiple of a new plant_dt_s
            hit = [s for s in items if s.path[:len(f) - 1] == f[:-1] and len(f) > 1]
        if hit:
            return hit
    return items


def scenario_with_settings(sc: Scenario,
                           settings: Sequence[str] | Mapping[str, Any]) -> Scenario:
    """A copy of ``sc`` with fields at any depth changed by settings ``"path=value"``.

    Parameters
    ----------
    sc : Scenario
        The scenario to change.
    settings : sequence of str, or mapping
        Each a string ``"path=value"`` or, from a mapping, ``{path: value}``. ``path`` is the
        field's dotted path in the scenario's TOML layout (module docstring): ``seed``,
        ``reference.j_lat_max``, ``sensors.y.noise_std``, ``controller_settings.alpha_lat``,
        ``vehicle_overrides.mass``, ``road.mu``. In a string the value is read as a TOML
        value (``15``, ``1.5e-3``, ``inf``, ``true``, ``"Monza"``, ``[[0, 0], [80, -9.2]]``,
        ``{noise_std = 0.1}``) or, when it is not one, taken as a bare string
        (``reference.track=Monza``); a string field takes the text as written (``name=2024``);
        nothing after the ``=`` (``reference.closed=``) puts the field back to its default
        (``reference.closed`` and ``reference.smoothing_length_m``: None, the loader's choice;
        an empty text is ``name=""``), and a table's (``timing=``, ``sensors.y=``,
        ``controller_settings=``) every field of it (a free table, ``sensors`` and a channel:
        empty, every channel exact, the controller's defaults).
        An inline table given to a table *merges* its keys into it, each as its own setting
        ``table.key=value`` (``reference={j_lat_max = 15}`` is ``reference.j_lat_max=15``: the
        reference's track and other fields are kept); an empty one, ``{}``, is the table's
        defaults, as nothing after the ``=``.
        A mapping's values are taken as they are (``None``: the field's default; a dict for a
        table: merged likewise). Applied in order (a later setting of the same path wins),
        then validated together.

    Returns
    -------
    Scenario
        The changed scenario, validated as :func:`scenario_from_toml` validates a file.

    Notes
    -----
    A table the scenario does not hold is created by a setting of one of its fields
    (``controller_settings``, ``vehicle_overrides``, ``sensors.<channel>``: a new channel
    starts exact; any other after its ``TABLE=``: from its defaults). Setting
    ``reference.track`` drops the scenario's recording and ``reference.recording`` its
    track, as ``flatfree run --track`` / ``--recording`` do (setting both is an error). The
    arrays of tables ``[[fault]]`` and ``[[road.patch]]`` are set whole: an array of inline
    tables replaces them (``fault=[{kind = "nan_measurement", channel = "x", t_start_s = 2,
    duration_s = 0.05}]``), nothing after the ``=`` or ``[]`` clears them; one entry's field
    cannot be addressed. An integer given to a float field is stored as a float.

    Raises
    ------
    ValueError
        A malformed setting (no ``=``, an empty path part), a path into a value that is not a
        table or into an entry of an array of tables, a value of the wrong type, or any
        validation error of the resulting scenario (NaN is refused wherever a number is
        checked): the message names the setting as written, the field and the value.
    """
    return _with_settings(sc, _settings(settings))


def _with_settings(sc: Scenario, settings: list[_Setting]) -> Scenario:
    """:func:`scenario_with_settings` of parsed settings (:func:`_settings`; ``flatfree run``
    adds its ``--noise`` as one, named so in the messages)."""
    items = [leaf for st in settings for leaf in _expand(st)]
    if not items:
        return sc
    explicit = {s.path for s in items if s.value is not None}
    both = [s for s in items if s.path in (("reference", "track"), ("reference", "recording"))
            and s.value is not None]
    if {s.path for s in both} == {("reference", "track"), ("reference", "recording")}:
        raise ValueError(f"{_labels(both)}: give one of reference.track and "
                         "reference.recording, not both")
    # the scenario as a TOML file holds it: fresh plain tables, each value as read from TOML
    # (the settings' values too: _assign), validated as a file is, once
    doc = tomllib.loads(scenario_to_toml(sc))
    for st in items:
        _assign(doc, st, explicit)
    try:
        out = _scenario_from_doc(doc, _Where("", "settings"))  # no text: no line numbers
    except _FieldError as exc:
        raise ValueError(f"{_labels(_culprits(items, exc.field))}: {exc.detail}") from None
    _check_parts(out, items)
    return out


def _labels(items: list[_Setting]) -> str:
    """The settings as the messages name them: ``setting a=1`` / ``settings a=1, b=2``, an
    option as itself (``--noise``); an inline table's keys, which share a label, once."""
    shown = list(dict.fromkeys(s.shown for s in items if s.shown is not None))
    labels = list(dict.fromkeys(s.label for s in items if s.shown is None))
    if labels:
        shown.append(f"setting{'s' if len(labels) > 1 else ''} {', '.join(labels)}")
    return ", ".join(shown)


def _controller_error(sc: Scenario) -> Exception | None:
    """The error of the scenario's controller settings for its controller (None: none)."""
    from flatfree.controllers.vehicle import settings_from_mapping

    try:
        settings_from_mapping(sc.controller, sc.controller_settings)
    except (TypeError, ValueError) as exc:
        return exc
    return None


def _vehicle_error(sc: Scenario) -> Exception | None:
    """The error of loading the scenario's car with its overrides (None: none)."""
    try:
        sc.load_vehicle()
    except (TypeError, ValueError) as exc:
        return exc
    return None


def _part_errors(sc: Scenario, controller: bool = True, vehicle: bool = True):
    """The errors of the parts a scenario leaves to the run, each as ``(table, its values,
    the top-level key, error)``: the controller's settings, the car with its overrides."""
    if controller and (exc := _controller_error(sc)) is not None:
        yield ("controller_settings", sc.controller_settings, "controller",
               ValueError(f"controller {sc.controller}: {exc}"))
    if vehicle and (exc := _vehicle_error(sc)) is not None:
        text = str(exc)  # the loader's message of a file names the vehicle already
        yield ("vehicle_overrides", sc.vehicle_overrides, "vehicle", ValueError(
            text if text.startswith(f"vehicle {sc.vehicle}") else f"vehicle {sc.vehicle}: {text}"))


def _check_parts(sc: Scenario, items: list[_Setting]) -> None:
    """Check the controller's settings and the vehicle when a setting changed them (a scenario
    leaves these to the run; here the error can name the setting, as :func:`load_scenario`'s
    names the file)."""
    ctrl = [s for s in items if s.path[0] in ("controller", "controller_settings")]
    veh = [s for s in items if s.path[0] in ("vehicle", "vehicle_overrides")]
    for table, _, _, exc in _part_errors(sc, controller=bool(ctrl), vehicle=bool(veh)):
        if table == "controller_settings":
            hint = ("; the scenario's controller_settings belong to its controller: also set "
                    "controller_settings= (nothing after the =) to start from the new one's "
                    "defaults"
                    if any(s.path == ("controller",) for s in ctrl) else "")
            raise ValueError(f"{_labels(ctrl)}: {exc}{hint}") from None
        raise ValueError(f"{_labels(veh)}: {exc}") from None
