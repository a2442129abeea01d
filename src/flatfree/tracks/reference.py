"""Reference signals on a time grid, and the 3DoF bicycle model's reference states.

A :class:`Reference` holds, on a uniform time grid, everything a controller needs to follow a
path at a speed: position, heading, speed, acceleration, yaw rate r = Vx kappa and its
derivative, curvature and its arc-length derivative, and the lateral-deviation reference with
its first two time derivatives. Signals are read by name: ``ref["vx"]``; the compiled loop
reads :attr:`Reference.table` (columns :class:`RS`) with :func:`sample_reference`.

Approximations (documented once, used everywhere here):

- the speed of the profile is the path speed of the CoG, taken as Vx (small sideslip:
  Vx = V cos(beta) ~ V);
- the reference yaw rate is the path's, r = Vx kappa (the sideslip rate beta_dot is neglected);
- with a lateral offset line, e_y reference is the offset d(s_path) measured from the path the
  vehicle is projected on, and its time derivatives follow the line's speed profile.

References
----------
[paper] d'Andrea-Novel, Menhour, Fliess, Mounier, "Some remarks on wheeled autonomous vehicles and
    the evolution of their control design", Section 2.1 (3DoF model) and 2.3 (flat outputs);
    corrected formulas in NOTES.md.
[Raj] R. Rajamani, Vehicle Dynamics and Control, 2nd ed., 2012, ch. 2-3 (linear bicycle model,
    steady-state cornering, understeer gradient).
"""

from __future__ import annotations

import dataclasses
import enum
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.interpolate import CubicSpline

from flatfree._validate import as_real, finite, positive, real_array, whole
from flatfree.tracks.geometry import Track, path_eval_many, progress, project_points
from flatfree.tracks.loaders import load_track
from flatfree.tracks.speed import (
    SpeedLimits,
    SpeedProfile,
    constant_speed_profile,
    speed_profile,
)
from flatfree.vehicles.params import VehicleParams

__all__ = [
    "RS",
    "Reference",
    "make_reference",
    "sample_reference",
    "LateralReference",
    "reference_states_3dof",
    "V_LOW",
]


class RS(enum.IntEnum):
    """Columns of :attr:`Reference.table` (all SI). ``ref["name"]`` uses the lower-case names."""

    T = 0  #: time [s]
    S = 1  #: arc length along the driven line, unwrapped over laps [m]
    S_PATH = 2  #: arc length along the projection path, unwrapped over laps [m]
    X = 3  #: x of the driven line [m]
    Y = 4  #: y [m]
    PSI = 5  #: heading of the driven line, unwrapped [rad]
    KAPPA = 6  #: curvature of the driven line [1/m]
    DKAPPA_DS = 7  #: d kappa / d s [1/m^2]
    VX = 8  #: longitudinal speed [m/s]
    AX = 9  #: d Vx / dt [m/s^2]
    R = 10  #: yaw rate Vx kappa [rad/s]
    R_DOT = 11  #: d r / dt = a_x kappa + Vx^2 d kappa/ds [rad/s^2]
    E_Y_REF = 12  #: lateral deviation reference from the path (> 0 left) [m]
    E_Y_REF_DOT = 13  #: its time derivative [m/s]
    E_Y_REF_DDOT = 14  #: its second time derivative [m/s^2]
    W_LEFT = 15  #: distance from the driven line to the left edge [m]
    W_RIGHT = 16  #: distance to the right edge [m]


_NAMES = tuple(m.name.lower() for m in RS)
N_RS = len(RS)
#: The most samples a reference's table may take (:func:`make_reference`; 17 columns of 8 bytes:
#: 1.4 GB, 2.8 h at the closed loop's 1 ms). A longer drive comes of a speed limit near zero
#: (``a_lat_max`` or ``mu`` of 1e-12, say) or of a huge lap count: refused with a ValueError
#: before the allocation, instead of numpy's memory error.
MAX_REFERENCE_SAMPLES = 10_000_000
#: Below this speed [m/s] the linear-tyre slip angles (V / Vx) are singular; the 3DoF reference
#: states use the quasi-steady values there (engineering choice, documented in the function).
V_LOW = 0.5


@numba.njit(cache=True)
def sample_reference(table, t, out):
    """Linear interpolation of a uniformly timed reference table at time ``t`` into ``out``.

    O(1): the row is found from the uniform step. Times outside the table hold the end rows.
    """
    n = table.shape[0]
    t0 = table[0, 0]
    dt = table[1, 0] - t0
    x = (t - t0) / dt
    if x <= 0.0:
        for j in range(table.shape[1]):
            out[j] = table[0, j]
        return
    if x >= n - 1:
        for j in range(table.shape[1]):
            out[j] = table[n - 1, j]
        return
    i = int(x)
    w = x - i
    for j in range(table.shape[1]):
        out[j] = (1.0 - w) * table[i, j] + w * table[i + 1, j]


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Reference:
    """Reference signals on a uniform time grid.

    Attributes
    ----------
    name : str
    path : Track
        The path the vehicle is projected on (lateral deviation measured from it).
    line : Track
        The line to drive (``path`` itself, or an offset line).
    table : ndarray (n, len(RS)), read-only
        The signals, columns :class:`RS`.
    extras : dict of str -> ndarray
        Further signals on the same grid (e.g. ``delta_recorded`` for a recording).
    profile : SpeedProfile or None
        The speed profile the reference was built from.
    """

    name: str = ""
    path: Track = field(repr=False)
    line: Track = field(repr=False)
    table: np.ndarray = field(repr=False)
    extras: dict = field(default_factory=dict, repr=False)
    profile: SpeedProfile | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        tab = np.ascontiguousarray(self.table, dtype=float)
        if tab.ndim != 2 or tab.shape[1] != N_RS or tab.shape[0] < 2:
            raise ValueError(f"table: expected shape (>=2, {N_RS}), got {tab.shape}")
        dt = np.diff(tab[:, RS.T])
        if not (dt > 0).all() or not np.allclose(dt, dt[0], rtol=1e-9, atol=1e-12):
            raise ValueError("table: the time column must be uniform and increasing")
        tab.setflags(write=False)
        object.__setattr__(self, "table", tab)
        ex = {}
        for k, v in self.extras.items():
            a = np.ascontiguousarray(v, dtype=float)
            if a.shape != (tab.shape[0],):
                raise ValueError(f"extras[{k!r}]: expected {tab.shape[0]} values, got {a.shape}")
            a.setflags(write=False)
            ex[k] = a
        object.__setattr__(self, "extras", ex)

    def __getitem__(self, name: str) -> np.ndarray:
        if name in _NAMES:
            return self.table[:, _NAMES.index(name)]
        if name in self.extras:
            return self.extras[name]
        raise KeyError(f"no signal {name!r}; available: {', '.join(self.names)}")

    def __contains__(self, name: object) -> bool:
        """Whether ``name`` is one of :attr:`names` (``"vx" in ref``; without it Python tried
        ``ref[0]``, ``ref[1]``, ... and raised ``KeyError: no signal 0``)."""
        return name in _NAMES or name in self.extras

    @property
    def names(self) -> tuple[str, ...]:
        """All signal names."""
        return _NAMES + tuple(self.extras)

    @property
    def t(self) -> np.ndarray:
        """Time [s]."""
        return self.table[:, RS.T]

    @property
    def dt(self) -> float:
        """Time step [s]."""
        return float(self.table[1, RS.T] - self.table[0, RS.T])

    @property
    def duration(self) -> float:
        """Last time of the grid [s]."""
        return float(self.table[-1, RS.T])

    def __repr__(self) -> str:
        return (f"Reference(name={self.name!r}, n={self.table.shape[0]}, dt={self.dt:g} s, "
                f"duration={self.duration:.2f} s, path={self.path.name!r})")

    def at(self, t) -> dict[str, np.ndarray]:
        """All signals linearly interpolated at times ``t`` (array_like) [s]."""
        ta = np.atleast_1d(np.asarray(t, dtype=float))
        out = {n: np.interp(ta, self.t, self.table[:, j]) for j, n in enumerate(_NAMES)}
        for k, v in self.extras.items():
            out[k] = np.interp(ta, self.t, v)
        return out


def _offset_function(d, path: Track):
    """Return (d, d', d'', node values) as functions of the path arc length, or None for a
    zero offset. A function or node values are interpolated by a cubic spline (periodic on a
    closed track)."""
    # real_array as Track.offset: text, booleans, None, ragged and object arrays refused
    if callable(d):
        vals = real_array("lateral_offset(s)", d(path.s), "m")
    else:
        vals = real_array("lateral_offset", d, "m")
        if vals.ndim == 0:  # a constant
            c = finite("lateral_offset", d, "m")
            if c == 0.0:
                return None
            zero = np.zeros_like
            return (lambda s: np.full_like(s, c)), zero, zero, np.full_like(path.s, c)
    if vals.ndim == 0:  # a function that returned a constant
        vals = np.full_like(path.s, float(vals))
    if vals.shape != path.s.shape or not np.isfinite(vals).all():
        raise ValueError(f"lateral_offset: expected a finite scalar, {path.s.shape[0]} finite "
                         f"values (one per path node) or a function of s; got shape {vals.shape}")
    vals = vals.copy()
    if path.closed:
        if abs(vals[-1] - vals[0]) > 1e-9:
            raise ValueError(
                f"lateral_offset: on a closed track d(L) = {float(vals[-1])!r} m must equal "
                f"d(0) = {float(vals[0])!r} m"
            )
        vals[-1] = vals[0]
        cs = CubicSpline(path.s, vals, bc_type="periodic")
        length = path.length

        def wrap(f):
            return lambda s: f(np.mod(s, length))
        return wrap(cs), wrap(cs.derivative(1)), wrap(cs.derivative(2)), vals
    cs = CubicSpline(path.s, vals)
    return cs, cs.derivative(1), cs.derivative(2), vals


def _line_to_path_map(path: Track, line: Track) -> CubicSpline:
    """s_path as a smooth function of s_line (foot points of the line nodes on the path)."""
    out, _ = project_points(path.geometry, path.closed, np.ascontiguousarray(line.x),
                            np.ascontiguousarray(line.y), np.ascontiguousarray(line.psi), 0)
    sp = out[:, 0].copy()
    if not path.closed:
        return CubicSpline(line.s, sp)
    for k in range(1, sp.shape[0]):  # unwrap across the start/finish line
        sp[k] = sp[k - 1] + progress(out[k, 0], out[k - 1, 0], path.length, True)
    sp -= path.length * math.floor(sp[0] / path.length + 0.5)  # sp[0] near 0
    pad = min(20, line.s.shape[0] - 2)  # periodic padding for smooth derivatives at the seam
    s_ext = np.concatenate([line.s[-pad - 1:-1] - line.length, line.s,
                            line.s[1:pad + 1] + line.length])
    sp_ext = np.concatenate([sp[-pad - 1:-1] - path.length, sp, sp[1:pad + 1] + path.length])
    return CubicSpline(s_ext, sp_ext)


_LIMIT_FIELDS = tuple(f.name for f in dataclasses.fields(SpeedLimits))


def _as_track(track) -> Track:
    """``track`` itself, or the track :func:`~flatfree.tracks.load_track` loads from a name or
    a path; ``ValueError`` naming it for anything else."""
    if isinstance(track, Track):
        return track
    if isinstance(track, (str, os.PathLike)):
        return load_track(track)
    raise ValueError(f"track = {track!r}: expected a Track, a bundled track's name or the path "
                     "of a track file (flatfree.tracks.load_track)")


def _as_speed(speed):
    """``speed`` as make_reference takes it: SpeedLimits (also from a mapping of its fields),
    a SpeedProfile, None, or a constant speed [m/s] as a float."""
    if speed is None or isinstance(speed, (SpeedLimits, SpeedProfile)):
        return speed
    if isinstance(speed, Mapping):
        unknown = [k for k in speed if k not in _LIMIT_FIELDS]
        if unknown:
            raise ValueError(f"speed = {dict(speed)!r}: unknown limit {unknown[0]!r}; "
                             f"SpeedLimits has {', '.join(_LIMIT_FIELDS)}")
        return SpeedLimits(**speed)  # each value validated there (ValueError naming it)
    if as_real(speed) is None:
        raise ValueError(f"speed = {speed!r}: expected SpeedLimits (or a mapping of its "
                         "fields), a SpeedProfile, a constant speed in m/s, or None")
    return positive("speed", speed, "m/s")


def make_reference(
    track: Track | str | os.PathLike,
    speed: SpeedLimits | Mapping | SpeedProfile | float | None = None,
    *,
    dt: float = 0.01,
    lateral_offset: float | np.ndarray | Callable = 0.0,
    laps: int = 1,
    v_start: float | None = None,
    v_end: float | None = None,
    name: str | None = None,
    vehicle: VehicleParams | None = None,
) -> Reference:
    """Reference signals to drive ``track`` on a uniform time grid.

    Parameters
    ----------
    track : Track, str or path
        The path; the vehicle's lateral deviation is measured from it. A bundled track's name
        (``"Monza"``) or a track file's path is loaded with
        :func:`~flatfree.tracks.load_track` (its defaults: the centerline).
    speed : SpeedLimits, mapping, SpeedProfile, float or None
        Limits for :func:`~flatfree.tracks.speed.speed_profile` (default ``SpeedLimits()``;
        a mapping of SpeedLimits' fields, ``{"a_lat_max": 3.0}``, is ``SpeedLimits(**it)``),
        a ready profile (of ``track``, without lateral offset), or a constant speed [m/s].
        Anything else raises ``ValueError``.
    dt : float
        Time step [s].
    lateral_offset : float, array_like (N+1,) or callable
        Offset d of the driven line from the path [m] (> 0 left): a constant, values at the
        path nodes, or a function of the path arc length. 0 (default): drive the path itself.
    laps : int
        Number of laps (closed tracks only; the periodic profile is repeated).
    v_start, v_end : float, optional
        Start / end speed of an open path [m/s] (see :func:`speed_profile`).
    name : str, optional
    vehicle : VehicleParams, optional
        Plan the speed profile within this car's drive limit too (torque, power, drag, rolling
        resistance: ``speed_profile(..., vehicle=...)``); only with ``speed`` given as limits
        (or None), an error otherwise.

    Returns
    -------
    Reference
        The time grid runs from 0 to the last multiple of ``dt`` within the drive.

    Notes
    -----
    s(t), Vx(t), a_x(t) are exact for the profile's constant acceleration per segment; the
    geometry comes from :func:`~flatfree.tracks.geometry.path_eval`; r = Vx kappa,
    r_dot = a_x kappa + Vx^2 dkappa/ds. With an offset d(s_p): e_y_ref = d,
    e_y_ref_dot = d' s_p_dot, e_y_ref_ddot = d'' s_p_dot^2 + d' s_p_ddot with
    s_p_dot = (ds_p/ds) Vx and s_p_ddot = (d^2 s_p/ds^2) Vx^2 + (ds_p/ds) a_x.
    """
    positive("dt", dt, "s")
    laps = whole("laps", laps, 1)
    track = _as_track(track)
    speed = _as_speed(speed)
    if vehicle is not None and not isinstance(vehicle, VehicleParams):
        raise ValueError(f"vehicle = {vehicle!r}: expected VehicleParams "
                         "(flatfree.load_vehicle(name)) or None")
    if laps > 1 and not track.closed:
        raise ValueError(f"laps = {laps}: only a closed track can be driven more than once")
    off = _offset_function(lateral_offset, track)
    line = track if off is None else track.offset(off[3])
    if vehicle is not None and not (speed is None or isinstance(speed, SpeedLimits)):
        raise ValueError(f"vehicle = {getattr(vehicle, 'name', vehicle)!r}: a drive limit "
                         "applies to a planned profile only (speed = SpeedLimits or None), not "
                         f"to speed = {speed!r}")
    if isinstance(speed, SpeedProfile):
        if off is not None or speed.track is not track:
            raise ValueError("speed: a SpeedProfile must belong to this track and needs "
                             "lateral_offset = 0 (pass SpeedLimits or a speed instead)")
        prof = speed
    elif speed is None or isinstance(speed, SpeedLimits):
        prof = speed_profile(line, speed, v_start=v_start, v_end=v_end, vehicle=vehicle)
    else:
        prof = constant_speed_profile(line, speed)
    total = prof.duration * laps
    if not total / dt < MAX_REFERENCE_SAMPLES:
        raise ValueError(
            f"the reference would last {total:.4g} s ({laps} lap(s) of {prof.duration:.4g} s) "
            f"at dt = {dt!r} s, more than {MAX_REFERENCE_SAMPLES:,} samples "
            f"({MAX_REFERENCE_SAMPLES * N_RS * 8 / 1e9:.1f} GB): the speed (speed = {speed!r}) "
            f"is too low or laps = {laps} too many")
    n = int(math.floor(total / dt + 1e-9)) + 1
    if n < 2:
        raise ValueError(f"dt = {dt!r} s: longer than the drive ({total:.3g} s)")
    t = np.arange(n) * dt
    lap = np.minimum(np.floor(t / prof.duration), laps - 1)
    tau = t - lap * prof.duration
    s_l, v, a = prof.state_at_time(tau)
    geo = path_eval_many(line.geometry, line.closed, s_l)
    tab = np.zeros((n, N_RS))
    tab[:, RS.T] = t
    tab[:, RS.S] = s_l + lap * line.length
    tab[:, RS.X] = geo[:, 0]
    tab[:, RS.Y] = geo[:, 1]
    tab[:, RS.PSI] = geo[:, 2] + lap * (line.psi[-1] - line.psi[0])
    kap = geo[:, 3]
    dkap = geo[:, 4]
    tab[:, RS.KAPPA] = kap
    tab[:, RS.DKAPPA_DS] = dkap
    tab[:, RS.VX] = v
    tab[:, RS.AX] = a
    tab[:, RS.R] = v * kap
    tab[:, RS.R_DOT] = a * kap + v * v * dkap
    tab[:, RS.W_LEFT] = geo[:, 5]
    tab[:, RS.W_RIGHT] = geo[:, 6]
    if off is None:
        tab[:, RS.S_PATH] = tab[:, RS.S]
    else:
        d, d1, d2, _ = off
        smap = _line_to_path_map(track, line)
        sp = smap(s_l)
        sp1 = smap(s_l, 1)
        sp2 = smap(s_l, 2)
        spd = sp1 * v
        spdd = sp2 * v * v + sp1 * a
        tab[:, RS.S_PATH] = sp + lap * track.length
        tab[:, RS.E_Y_REF] = d(sp)
        tab[:, RS.E_Y_REF_DOT] = d1(sp) * spd
        tab[:, RS.E_Y_REF_DDOT] = d2(sp) * spd * spd + d1(sp) * spdd
    return Reference(name=name if name is not None else track.name, path=track, line=line,
                     table=tab, profile=prof)


# ----------------------------------------------------------------------------------------------
# 3DoF reference states
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class LateralReference:
    """Reference states of the 3DoF bicycle model along a :class:`Reference` (all SI).

    Attributes
    ----------
    t, vx, ax : ndarray
        Time [s], longitudinal speed [m/s] and acceleration [m/s^2] (copied from the reference;
        method ``"path"``: ``V cos beta`` and its derivative).
    vy, vy_dot : ndarray
        Lateral speed of the CoG [m/s] and its derivative [m/s^2].
    r, r_dot : ndarray
        Yaw rate [rad/s] and yaw acceleration [rad/s^2] (= the reference's r and r_dot;
        method ``"path"``: ``V kappa - beta'`` and its derivative).
    delta : ndarray
        Front road-wheel steer angle that produces them in the model [rad].
    y1, y1_dot, y2, y2_dot, y2_ddot : ndarray
        Flat outputs of the paper, y1 = Vx, y2 = lf m Vy - Iz r [kg m^2/s], and derivatives.
    method : str
    """

    t: np.ndarray
    vx: np.ndarray
    ax: np.ndarray
    vy: np.ndarray
    vy_dot: np.ndarray
    r: np.ndarray
    r_dot: np.ndarray
    delta: np.ndarray
    y1: np.ndarray
    y1_dot: np.ndarray
    y2: np.ndarray
    y2_dot: np.ndarray
    y2_ddot: np.ndarray
    method: str = "dynamic"


def reference_states_3dof(
    ref: Reference,
    *,
    cf: float,
    cr: float,
    mass: float,
    iz: float,
    lf: float,
    lr: float,
    method: str = "dynamic",
) -> LateralReference:
    """The 3DoF model's lateral states (Vy, r), steer and flat outputs along a reference.

    Model: the paper's Section 2.1 with linear tyres, small angles and the wheel-inertia terms
    I_r/(mR) omega_dot neglected (NOTES.md: they are small) [paper] [Raj]:

        m (Vy_dot + Vx r) = Fyf + Fyr,       Iz r_dot = lf Fyf - lr Fyr,
        Fyf = Cf (delta - (Vy + lf r) / Vx), Fyr = -Cr (Vy - lr r) / Vx.

    Given Vx(t), r(t) = Vx kappa and r_dot(t) from the reference, eliminating Fyf gives the
    internal (zero) dynamics of Vy:

        Vy_dot = -A Vy + B,   A = L Cr / (lf m Vx),
        B = (L Cr lr r / Vx + Iz r_dot) / (lf m) - Vx r,        L = lf + lr,

    stable for Vx > 0, with the quasi-steady value Vy_qs = B / A = lr r + Vx (Iz r_dot -
    lf m Vx r) / (L Cr) (at constant speed and radius this is the steady sideslip
    beta_ss = lr/R - m lf Vx^2 / (L Cr R), [Raj] sec. 3). The steer then follows from the yaw
    and lateral balances: Fyf = (lr m (Vy_dot + Vx r) + Iz r_dot) / L,
    delta = (Vy + lf r) / Vx + Fyf / Cf.

    Parameters
    ----------
    ref : Reference
    cf, cr : float
        Front and rear axle cornering stiffness [N/rad] (> 0, paper convention).
    mass : float
        [kg]
    iz : float
        Yaw inertia [kg m^2].
    lf, lr : float
        CoG to front / rear axle [m].
    method : {"dynamic", "steady", "path"}
        ``"dynamic"`` (default): integrate the Vy dynamics above on the time grid (exponential
        integrator with mid-step coefficients, second order, stable at any step), starting from
        Vy_qs; the states then satisfy the model (with r prescribed) and y2_dot is exactly the
        model's -lf m Vx r - Cr L (Vy - lr r) / Vx (NOTES.md). ``"steady"``: Vy = Vy_qs and
        delta with Vy_dot = 0 in the lateral balance (steady-state cornering at each instant);
        vy_dot and y2_ddot are then numerical derivatives (numpy.gradient).
        ``"path"``: the model whose CoG follows the path exactly (below).
        Below ``V_LOW`` = 0.5 m/s every method uses the quasi-steady values (the slip angles are
        singular at Vx = 0).

    The ``"path"`` method. ``"dynamic"`` prescribes the yaw rate ``r = Vx kappa``; then the
    course of the CoG's velocity, ``chi = psi + beta``, turns at ``Vx kappa + beta'`` instead of
    the path's ``V kappa``, and the model's CoG leaves the path wherever beta changes. With the
    reference's speed taken as the CoG's speed along the path, ``V = ds/dt``, the model follows
    the path exactly when ``r = V kappa - beta'``, ``Vx = V cos beta``, ``Vy = V sin beta``.
    Eliminating Fyf between the two balances (``Vy' + Vx r = a sin beta + kappa V^2 cos beta``:
    beta' cancels) leaves the internal dynamics of beta, second order:

        Iz beta'' = Iz (V kappa)' - lf m (a sin beta + kappa V^2 cos beta)
                    - L Cr (tan beta - lr kappa / cos beta + lr beta' / (V cos beta)),

    a damped oscillator for V > 0 (small beta: stiffness L Cr / Iz, damping L Cr lr /
    (Iz V), so ``zeta = lr sqrt(L Cr / Iz) / (2 V)``: 0.24 for the peugeot406 at 30 m/s; the
    weakly damped yaw mode of a car whose CoG is held on its path). It is integrated on the
    time grid (classical RK4 with the inputs interpolated linearly, sub-stepped so that the
    step stays within RK4's stability at low speed), starting from its quasi-steady value
    (beta' = beta'' = 0) at the first sample and after every stretch below ``V_LOW``. Then
    ``vx = V cos beta`` (not the reference's V: they differ by 1 - cos beta, 6e-4 at 2 deg),
    ``ax = d(V cos beta)/dt``, ``r = V kappa - beta'``, ``r_dot = (V kappa)' - beta''``,
    ``vy_dot = a sin beta + V cos beta beta'``, and y2_dot, y2_ddot in the closed forms of the
    ``"dynamic"`` method. This is "the 3DoF model along the path" of the yaw error's definition
    (flatfree.metrics).

    Returns
    -------
    LateralReference
    """
    cf = positive("cf", cf, "N/rad")
    cr = positive("cr", cr, "N/rad")
    m = positive("mass", mass, "kg")
    iz = positive("iz", iz, "kg m^2")
    lf = positive("lf", lf, "m")
    lr = positive("lr", lr, "m")
    if method not in ("dynamic", "steady", "path"):
        raise ValueError(f"method = {method!r}: must be 'dynamic', 'steady' or 'path'")
    big_l = lf + lr
    if method == "path":
        return _path_states(ref, cf, cr, m, iz, lf, lr)
    t = ref["t"].copy()
    vx = ref["vx"].copy()
    ax = ref["ax"].copy()
    r = ref["r"].copy()
    r_dot = ref["r_dot"].copy()
    kap = ref["kappa"]
    # quasi-steady lateral speed and its ratio to Vx (finite at Vx = 0 since r = Vx kappa)
    beta_qs = lr * kap + (iz * r_dot - lf * m * vx * r) / (big_l * cr)  # = Vy_qs / Vx
    vy_qs = beta_qs * vx
    low = vx < V_LOW
    if method == "steady":
        vy = vy_qs
        vy_dot = np.gradient(vy, t)
        ratio = beta_qs + lf * kap  # (Vy + lf r) / Vx
        fyf = (lr * m * (vx * r) + iz * r_dot) / big_l  # Vy_dot = 0 in the balance
    else:
        vy = _integrate_vy(t, vx, r, r_dot, vy_qs, big_l * cr / (lf * m), iz / (lf * m), lr, low)
        a_coef = np.where(low, 0.0, big_l * cr / (lf * m * np.where(low, 1.0, vx)))
        b_coef = np.where(
            low, 0.0,
            (big_l * cr * lr * r / np.where(low, 1.0, vx) + iz * r_dot) / (lf * m) - vx * r,
        )
        vy_dot = b_coef - a_coef * vy
        if low.any():
            vy_dot = np.where(low, np.gradient(vy, t), vy_dot)
        ratio = np.where(low, beta_qs, vy / np.where(low, 1.0, vx)) + lf * kap
        fyf = (lr * m * (vy_dot + vx * r) + iz * r_dot) / big_l
    delta = ratio + fyf / cf
    y2 = lf * m * vy - iz * r  # NOTES.md: y2 = Lf m Vy - Iz r
    y2_dot = lf * m * vy_dot - iz * r_dot
    if method == "dynamic":
        y2_ddot = _y2_ddot_model(vx, ax, vy, vy_dot, r, r_dot, np.where(low, 1.0, vx), m, lf,
                                 lr, cr)
        if low.any():
            y2_ddot = np.where(low, np.gradient(y2_dot, t), y2_ddot)
    else:
        y2_ddot = np.gradient(y2_dot, t)
    return LateralReference(t=t, vx=vx, ax=ax, vy=vy, vy_dot=vy_dot, r=r, r_dot=r_dot,
                            delta=delta, y1=vx.copy(), y1_dot=ax.copy(), y2=y2, y2_dot=y2_dot,
                            y2_ddot=y2_ddot, method=method)


def _path_states(ref: Reference, cf: float, cr: float, m: float, iz: float, lf: float,
                 lr: float) -> LateralReference:
    """``reference_states_3dof(..., method="path")`` (see there)."""
    big_l = lf + lr
    t = ref["t"].copy()
    v = ref["vx"].copy()  # the CoG's speed along the path, ds/dt
    a = ref["ax"].copy()
    kap = ref["kappa"].copy()
    rk_dot = ref["r_dot"].copy()  # (V kappa)'
    low = v < V_LOW
    _check_beta_path_substeps(t, v, low, iz, lr, cr * big_l)
    beta, beta_d, beta_dd = _integrate_beta_path(t, v, a, kap, rk_dot, m, iz, lf, lr, cr, low)
    cb = np.cos(beta)
    sb = np.sin(beta)
    vx = v * cb
    vy = v * sb
    ax = a * cb - vy * beta_d
    r = v * kap - beta_d
    r_dot = rk_dot - beta_dd
    vy_dot = a * sb + vx * beta_d
    vxs = np.where(low, 1.0, vx)
    fyr = -cr * (vy - lr * r) / vxs
    fyf = m * (vy_dot + vx * r) - fyr
    delta = (vy + lf * r) / vxs + fyf / cf
    y2 = lf * m * vy - iz * r
    y2_dot = lf * m * vy_dot - iz * r_dot
    y2_ddot = _y2_ddot_model(vx, ax, vy, vy_dot, r, r_dot, vxs, m, lf, lr, cr)
    if low.any():
        # quasi-steady below V_LOW (as the other methods): there the integration holds beta at
        # its quasi-steady value with beta' = 0 (so r is the kinematic V kappa already);
        # numerical derivatives, the steer of the steady lateral balance
        vy_dot = np.where(low, np.gradient(vy, t), vy_dot)
        fyf_qs = (lr * m * (v * v * kap) + iz * rk_dot) / big_l
        delta = np.where(low, beta + lf * kap + fyf_qs / cf, delta)
        y2_dot = np.where(low, np.gradient(y2, t), y2_dot)
        y2_ddot = np.where(low, np.gradient(y2_dot, t), y2_ddot)
    return LateralReference(t=t, vx=vx, ax=ax, vy=vy, vy_dot=vy_dot, r=r, r_dot=r_dot,
                            delta=delta, y1=vx.copy(), y1_dot=ax.copy(), y2=y2, y2_dot=y2_dot,
                            y2_ddot=y2_ddot, method="path")


#: The most RK4 sub-steps :func:`_integrate_beta_path` may take (a lap of a bundled track with
#: the peugeot406 takes one per sample, 6.2e3-2.5e4; a yaw inertia of 1e-6 kg m^2 asked 3.2e12
#: and the run hung in ``prepare``).
MAX_BETA_SUBSTEPS = 10**7


def _check_beta_path_substeps(t, v, low, iz, lr, lcr) -> None:
    """``ValueError`` naming the yaw inertia when the sideslip dynamics are too fast to
    integrate along the reference (:data:`MAX_BETA_SUBSTEPS` of
    :func:`_beta_path_substeps`, the rule :func:`_integrate_beta_path` steps by)."""
    total, rate = _beta_path_total_substeps(t, v, low, iz, lr, lcr)
    if total > max(MAX_BETA_SUBSTEPS, 50 * t.size):
        raise ValueError(
            f"iz = {iz!r} kg m^2: the 3DoF model's sideslip dynamics along the reference are "
            f"that fast (up to {rate:.3g} 1/s with Cr L = {lcr:.4g} N and lr = {lr:g} m) "
            f"that integrating them needs {total:.3g} RK4 sub-steps: a yaw inertia that small "
            "is not a car's (the peugeot406's is 2620 kg m^2)")


@numba.njit(cache=True)
def _beta_path_substeps(h, vmin, iz, lr, lcr, w_stiff):
    """RK4 sub-steps of a grid step ``h`` [s] of the beta dynamics, as a float (``vmin`` the
    step's lower speed, ``w_stiff = sqrt(lcr / iz)``): h (damping + sqrt(stiffness)) <= 0.5
    a sub-step, inside RK4's stability region."""
    rate = lcr * lr / (iz * vmin) + w_stiff
    return max(1.0, math.ceil(h * rate / 0.5))


@numba.njit(cache=True)
def _beta_path_total_substeps(t, v, low, iz, lr, lcr):
    """The sub-steps :func:`_integrate_beta_path` takes on the grid, and the largest rate
    [1/s] of its steps (0 without one)."""
    w_stiff = math.sqrt(lcr / iz)
    total = 0.0
    top = 0.0
    for k in range(t.shape[0] - 1):
        if low[k] or low[k + 1]:
            continue
        vmin = min(v[k], v[k + 1])
        top = max(top, lcr * lr / (iz * vmin) + w_stiff)
        total += _beta_path_substeps(t[k + 1] - t[k], vmin, iz, lr, lcr, w_stiff)
    return total, top


def _y2_ddot_model(vx, ax, vy, vy_dot, r, r_dot, vxs, m, lf, lr, cr):
    """d/dt of the 3DoF model's y2_dot = -lf m Vx r - Cr L (Vy - lr r) / Vx (NOTES.md), with
    ``vxs`` the speed to divide by (1 where the caller replaces the low-speed samples)."""
    return -lf * m * (ax * r + vx * r_dot) - cr * (lf + lr) * (
        (vy_dot - lr * r_dot) / vxs - (vy - lr * r) * ax / (vxs * vxs))


@numba.njit(cache=True)
def _beta_path_ddot(b, bd, v, a, kap, rkd, m, iz, lf, lcr, lr):
    """beta'' of the path-following 3DoF model (reference_states_3dof, method "path")."""
    cb = math.cos(b)
    return rkd - (lf * m * (a * math.sin(b) + kap * v * v * cb)
                  + lcr * (math.tan(b) - lr * kap / cb + lr * bd / (v * cb))) / iz


@numba.njit(cache=True)
def _beta_path_ddot_at(f, k, b, bd, v, a, kap, rkd, m, iz, lf, lcr, lr):
    """:func:`_beta_path_ddot` with the inputs interpolated linearly at the fraction ``f`` of
    the grid step from sample ``k`` to ``k + 1``."""
    return _beta_path_ddot(b, bd, v[k] + f * (v[k + 1] - v[k]), a[k] + f * (a[k + 1] - a[k]),
                           kap[k] + f * (kap[k + 1] - kap[k]),
                           rkd[k] + f * (rkd[k + 1] - rkd[k]), m, iz, lf, lcr, lr)


@numba.njit(cache=True)
def _beta_path_small_angle(v, kap, rkd, m, iz, lf, lcr, lr):
    """The quasi-steady beta (beta' = beta'' = 0) of the small-angle model: beta'' = 0 with
    sin b = tan b = b, cos b = 1 and a_x sin b neglected."""
    return lr * kap + (iz * rkd - lf * m * v * v * kap) / lcr


@numba.njit(cache=True)
def _beta_path_qs(v, a, kap, rkd, m, iz, lf, lcr, lr):
    """The quasi-steady beta (beta' = beta'' = 0) by Newton's method from the small-angle one."""
    b = _beta_path_small_angle(v, kap, rkd, m, iz, lf, lcr, lr)
    for _ in range(8):
        f = _beta_path_ddot(b, 0.0, v, a, kap, rkd, m, iz, lf, lcr, lr)
        db = 1e-7
        df = (_beta_path_ddot(b + db, 0.0, v, a, kap, rkd, m, iz, lf, lcr, lr) - f) / db
        if df == 0.0:
            break
        step = f / df
        b -= step
        if abs(step) < 1e-15:
            break
    return b


@numba.njit(cache=True)
def _integrate_beta_path(t, v, a, kap, rkd, m, iz, lf, lr, cr, low):
    """RK4 of the path-following beta dynamics on the grid ``t`` (see reference_states_3dof):
    inputs interpolated linearly within a step; sub-steps keep h (damping + sqrt(stiffness))
    <= 0.5, inside RK4's stability region. Returns beta, beta', beta'' at the samples."""
    n = t.shape[0]
    lcr = (lf + lr) * cr
    beta = np.empty(n)
    bdot = np.empty(n)
    bdd = np.empty(n)
    b = 0.0
    bd = 0.0
    restart = True
    w_stiff = math.sqrt(lcr / iz)
    for k in range(n):
        if low[k]:
            beta[k] = _beta_path_small_angle(v[k], kap[k], rkd[k], m, iz, lf, lcr, lr)
            bdot[k] = 0.0
            bdd[k] = 0.0
            restart = True
            continue
        if restart:
            b = _beta_path_qs(v[k], a[k], kap[k], rkd[k], m, iz, lf, lcr, lr)
            bd = 0.0
            restart = False
        beta[k] = b
        bdot[k] = bd
        bdd[k] = _beta_path_ddot(b, bd, v[k], a[k], kap[k], rkd[k], m, iz, lf, lcr, lr)
        if k == n - 1 or low[k + 1]:
            continue
        h = t[k + 1] - t[k]
        nsub = int(_beta_path_substeps(h, min(v[k], v[k + 1]), iz, lr, lcr, w_stiff))
        hs = h / nsub
        for j in range(nsub):
            f0 = j / nsub
            fm = (j + 0.5) / nsub
            f1 = (j + 1.0) / nsub
            d1 = _beta_path_ddot_at(f0, k, b, bd, v, a, kap, rkd, m, iz, lf, lcr, lr)
            b2 = b + 0.5 * hs * bd
            bd2 = bd + 0.5 * hs * d1
            d2 = _beta_path_ddot_at(fm, k, b2, bd2, v, a, kap, rkd, m, iz, lf, lcr, lr)
            b3 = b + 0.5 * hs * bd2
            bd3 = bd + 0.5 * hs * d2
            d3 = _beta_path_ddot_at(fm, k, b3, bd3, v, a, kap, rkd, m, iz, lf, lcr, lr)
            b4 = b + hs * bd3
            bd4 = bd + hs * d3
            d4 = _beta_path_ddot_at(f1, k, b4, bd4, v, a, kap, rkd, m, iz, lf, lcr, lr)
            b += hs / 6.0 * (bd + 2.0 * bd2 + 2.0 * bd3 + bd4)
            bd += hs / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
    return beta, bdot, bdd


@numba.njit(cache=True)
def _integrate_vy(t, vx, r, r_dot, vy_qs, lcr_over_lfm, iz_over_lfm, lr, low):
    """Exponential integrator of Vy_dot = -A Vy + B with mid-step A, B (see the caller)."""
    vy = np.empty_like(vx)
    vy[0] = vy_qs[0]
    for k in range(len(t) - 1):
        h = t[k + 1] - t[k]
        vm = 0.5 * (vx[k] + vx[k + 1])
        if low[k + 1] or vm < V_LOW:
            vy[k + 1] = vy_qs[k + 1]
            continue
        rm = 0.5 * (r[k] + r[k + 1])
        rdm = 0.5 * (r_dot[k] + r_dot[k + 1])
        a = lcr_over_lfm / vm
        b = lcr_over_lfm * lr * rm / vm + iz_over_lfm * rdm - vm * rm
        eq = b / a
        vy[k + 1] = eq + (vy[k] - eq) * math.exp(-a * h)
    return vy
