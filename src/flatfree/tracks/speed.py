"""Speed profile along a path: lateral limit, forward-backward pass on a friction ellipse.

The profile is defined at the nodes of a :class:`~flatfree.tracks.geometry.Track` (uniform arc
length step ds). Between two nodes the acceleration is constant,
a_i = (v_{i+1}^2 - v_i^2) / (2 ds), so v(s) is continuous and v^2 is piecewise linear in s.
Every segment satisfies, at BOTH of its end nodes j in {i, i+1}:

    (a_i / a_x,max)^2 + (v_j^2 kappa_j / a_y,max)^2 <= 1,     v_j <= v_max,

with a_x,max the drive limit when a_i > 0 and the brake limit when a_i < 0. The limits are
those of :class:`SpeedLimits`, each longitudinal and lateral limit capped by mu g.

The forward pass raises no node above what the previous node allows while accelerating; the
backward pass does the same for braking; on a closed track both passes wrap around the loop
and repeat until nothing changes (the result is then periodic). The maximal feasible profile
is the result (the classic "forward-backward" or "quasi-steady-state" method).

Power-aware drive limit (optional, ``speed_profile(..., vehicle=...)``). The friction ellipse
knows the tyres, not the engine. Given a :class:`~flatfree.vehicles.VehicleParams`, the forward
(accelerating) pass also keeps every segment within what the powertrain can give against the
driving resistances ([VM] 1.9, the same model as ``flatfree.simulation.flying_lap_speed``):

    a_p(v) = (F_drive(v) - 1/2 rho C_d A v^2 - f_r m g) / m,
    F_drive(v) = min(max_drive_torque / R_e, max_power / v),

(:func:`drive_acceleration`), and a_drive(v) = min(a_x,max, a_p(v)). The engine limit is a
separate cut of the ellipse, not a smaller ellipse: the segment's end speed is the smaller of
the friction-ellipse cap above (lateral load at both end nodes) and the power cap, the
solution of d(v^2)/ds = 2 a_drive(v) over the segment taken with ONE Heun step in v^2:

    w* = v_i^2 + 2 ds a_drive(v_i),   v_{i+1}^2 <= v_i^2 + ds (a_drive(v_i) + a_drive(sqrt w*)).

Because a_drive decreases with v, the segment's constant acceleration is then <= a_drive(v_i)
(exactly) and exceeds a_drive(v_{i+1}) by at most (a_drive(v_i) - a_drive(v_{i+1})) / 2.
Accuracy against the exact solution of d(v^2)/ds = 2 a_drive(v) on a straight (peugeot406,
tests/test_speed_power.py): second order, 2.1e-6 m/s on a 1 m grid where a_p is smooth; where
a_drive switches from the friction limit to the power limit its slope in s jumps by c, and the
one segment holding that kink adds at most c ds^2 / (16 v) (1.5e-4 m/s at 1 m; measured 1.46e-4
for the worst placement of the kink in the segment, 1.7e-5 from rest). Every node is also capped
at the car's top speed v_top (a_p(v_top) = 0): above it the car could only coast down, and on a
closed track the periodic fixed point would be approached only geometrically. The braking pass
is unchanged: it ignores drag and rolling resistance, which would only help the car slow down,
so the braking side stays conservative (feasible with the brakes alone).

Lateral-jerk limit (optional, ``SpeedLimits(j_lat_max=...)``, default off). The friction
ellipse bounds the lateral acceleration v^2 kappa but not how fast it changes: on a rough path
(curvature changing fast along s) the profile can ask for a swing of lateral acceleration the
car cannot follow (benchmarks/README.md, "Yaw error: what the targets allow together": LVMS
smoothed at 20 m, 11 m/s^2 in 0.6 s at 30 m/s). Along the path, with v' = dv/ds = a_x / v,

    d(v^2 kappa)/dt = v d(v^2 kappa)/ds = v^3 dkappa/ds  +  2 v a_x kappa.          (J)

The limit keeps the first term, the lateral jerk of steady travel (constant speed), within
j_lat_max at every node by a node cap applied with the lateral caps, before the passes (which
then keep the longitudinal limits):

    v_j^3 |dkappa/ds|_j <= j_lat_max,   i.e.   u_j = v_j^2 <= (j_lat_max / |dkappa/ds|_j)^(2/3),

(:func:`jerk_speed_cap`), with dkappa/ds the track's own node derivative
:attr:`Track.dkappa_ds` (the analytic derivative of the fitted spline's curvature, the slope
that the track's Hermite curvature interpolation uses; a centred difference of the node
curvatures, O(ds^2), differs from it by up to 2.4 % of the largest |dkappa/ds| of a bundled
track, Spa, at 1 m nodes). ``inf`` (the default) skips the cap entirely, so the default
profile is the friction-ellipse profile bit for bit.

What the cap neglects. (a) The second term of (J), 2 v a_x kappa = 2 a_x (v^2 kappa) / v: the
jerk of speeding up or slowing down in a curve. The cap cannot hold it without coupling to the
passes (a_x is what they compute), and it is bounded by the ellipse: at a node, (a_x / a_x,max)^2
+ (v^2 kappa / a_y,max)^2 <= 1 gives |a_x v^2 kappa| <= a_x,max a_y,max / 2, so

    |2 v a_x kappa| <= a_x,max a_y,max / v        (6 * 6 / v with the defaults: 1.2 m/s^3 at
                                                   30 m/s, 4.8 m/s^3 at 7.5 m/s),

and the bound is nearly reached (98.0-99.6 % of it at the worst segment of each bundled
track: slow corners, braking or driving at 45 degrees on the ellipse; figures of this
docstring from ``benchmarks/jerk_limit.py``).
On the profile's segments the finite difference of v^2 kappa in time is exactly the discrete
(J): 2 vbar a_i kbar + ubar vbar (kappa_{i+1} - kappa_i) / ds (bars: segment means), and the
ellipse at both end nodes bounds the first part by a_x,max a_y,max vbar / min(v_i, v_(i+1))^2
(tests/test_speed_jerk.py checks this and the total on LVMS smoothed at 20 m). Measured with
j_lat_max = 15 m/s^3: at most 3.8 m/s^3 anywhere on the bundled tracks (slow corners), at most
1.6 m/s^3 on segments where the steady term is within 10 % of the limit (with 5 m/s^3: 3.9
where it is). The two terms add, and the car's jerk exceeds the cap's, only when it drives
while |kappa| grows or brakes while |kappa| falls; braking into a corner and driving out of
one they have opposite signs.
(b) Between nodes: the cap binds at the nodes, the segment's steady term ubar vbar Delta
kappa / ds exceeds j_lat_max by at most 0.4 % at 15 m/s^3 and 0.9 % at 5 (measured on the
bundled tracks, 1 m nodes). (c) Everything of the
car: the jerk is that of a point on the path at the profile's speed; the car's sideslip, yaw
and tyre lags add their own transients.

Choice of a value. :data:`J_LAT_HANDLING` = 15 m/s^3 (module constant, a suggestion, not a
default). An order of magnitude from the car: the linear 3DoF model of the peugeot406 at the
static cornering stiffnesses (C_f / C_r = 97,700 / 73,800 N/rad) lags a ramp of lateral
acceleration by its mean delay T = -G'(0)/G(0) of the steer-to-a_y transfer function, 0.22 s
at 20 m/s, 0.33 s at 30 m/s; a controller that follows an a_y ramp of slope j falls behind by
about j T, which has to fit in the friction the profile leaves unused, mu g - a_lat,max =
3.8 m/s^2 with the defaults: j <~ 12-17 m/s^3 (an order of magnitude, not a stability
proof). The steer-rate limit, 0.4 rad/s, allows j = 0.4 / (L/v^2 + K_us) ~ 50-100 m/s^3 at
20-30 m/s: not the binding limit. Measured (noise-free closed loop, the first 10 s of LVMS
smoothed at 20 m, 2026-11-22, limits from 8 to 30 m/s^3 tried): ``paper`` completes with
j_lat_max from 8 to 18 m/s^3 and leaves the track with 19 to 30 or none; ``paper-imu``
completes with 8 to 20 and leaves with 21 to 30 or none. No bundled track's default profile
exceeds 21 m/s^3, and 15 m/s^3 costs at most 0.31 s a lap (Spa, 0.12 % of its 247.4 s). For
comparison, the limit of UN R79 for automatically commanded steering [R79] (a comfort and
automation rule, not a handling limit) is 5 m/s^3, which costs 0.5-14 s a lap here (IMS to Spa).

References
----------
[FB] E. Velenis, P. Tsiotras, "Minimum-time travel for a vehicle with acceleration limits:
     theoretical analysis and receding-horizon implementation", JOTA 138, 2008 (forward-backward
     integration of the friction-limited speed profile).
[QSS] N. R. Kapania, J. Subosits, J. C. Gerdes, "A sequential two-step algorithm for fast
     generation of vehicle racing trajectories", J. Dyn. Sys. Meas. Control 138(9), 2016
     (lateral limit v = sqrt(mu g / |kappa|), forward and backward passes on a friction circle).
[VM] docs/VEHICLE_MODEL.md 1.9 (aerodynamic drag 1/2 rho C_d A v^2, rolling
     resistance f_r m g); the power cap of the drive torque:
     :class:`flatfree.actuators.ActuatorParams`.
[R79] UN Regulation No. 79 (steering equipment), 03 series, automatically commanded steering
     functions (ACSF) of categories B1 and C: lateral jerk, as the 500 ms moving average of the
     derivative of the filtered lateral acceleration, at most 5 m/s^3 (the value as listed by
     the criticality-metrics catalogue, https://criticality-metrics.readthedocs.io, "Lateral
     Jerk": 0.5 g/s [UNECE79]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from flatfree._validate import nonnegative, positive, positive_or_inf
from flatfree.tracks.geometry import Track
from flatfree.units import G
from flatfree.vehicles.params import VehicleParams

__all__ = [
    "J_LAT_HANDLING",
    "SpeedLimits",
    "SpeedProfile",
    "constant_speed_profile",
    "drive_acceleration",
    "jerk_speed_cap",
    "speed_profile",
    "top_speed",
]

#: A lateral-jerk limit for :attr:`SpeedLimits.j_lat_max` [m/s^3] that keeps a rough path
#: drivable at a small cost in lap time (module docstring, "Choice of a value": the friction
#: reserve over the car's a_y lag, and closed-loop runs on LVMS smoothed at 20 m). Not a
#: default: the default profile has no jerk limit.
J_LAT_HANDLING = 15.0

#: Speed floor of the power cap max_power / v [m/s] (the same floor as
#: ``flatfree.simulation.flying_lap_speed``): below it the torque limit binds for any real car.
_V_FLOOR = 1e-3
#: Index of the drive-model array built by :func:`_drive_array`.
_M, _FDRIVE, _PMAX, _KDRAG, _FROLL, _UTOP = range(6)


@dataclass(frozen=True, slots=True, kw_only=True)
class SpeedLimits:
    """Limits of a speed profile (all SI, all > 0).

    The defaults load the car like the paper's test track (Section 4 of the seed paper, recorded
    on a track "with strong lateral and longitudinal loads"; NOTES.md, issue 4): lateral
    acceleration up to 6 m/s^2, longitudinal from -6 to +3 m/s^2.

    Attributes
    ----------
    a_lat_max : float
        Largest lateral acceleration |v^2 kappa| [m/s^2].
    a_drive_max : float
        Largest forward acceleration [m/s^2].
    a_brake_max : float
        Largest deceleration, a positive number [m/s^2].
    v_max : float
        Top speed [m/s]. Default 50 m/s (180 km/h), a team choice for a road car on a race track.
    mu : float
        Road friction coefficient [-]; every acceleration limit is capped by mu g.
    j_lat_max : float
        Largest lateral jerk of steady travel along the path, v^3 |d kappa/ds| at the nodes
        [m/s^3] (module docstring, "Lateral-jerk limit"). Default ``inf``: off, the
        friction-ellipse profile bit for bit. :data:`J_LAT_HANDLING` (15 m/s^3) keeps a rough
        path drivable at a small cost in lap time (module docstring: its cost on the bundled
        tracks).
    """

    a_lat_max: float = field(default=6.0, metadata={"unit": "m/s^2"})
    a_drive_max: float = field(default=3.0, metadata={"unit": "m/s^2"})
    a_brake_max: float = field(default=6.0, metadata={"unit": "m/s^2"})
    v_max: float = field(default=50.0, metadata={"unit": "m/s"})
    mu: float = field(default=1.0, metadata={"unit": "-"})
    j_lat_max: float = field(default=math.inf, metadata={"unit": "m/s^3"})

    def __post_init__(self) -> None:
        positive("a_lat_max", self.a_lat_max, "m/s^2")
        positive("a_drive_max", self.a_drive_max, "m/s^2")
        positive("a_brake_max", self.a_brake_max, "m/s^2")
        positive("v_max", self.v_max, "m/s")
        positive("mu", self.mu, "-")
        positive_or_inf("j_lat_max", self.j_lat_max, "m/s^3")

    @property
    def ay(self) -> float:
        """Effective lateral limit min(a_lat_max, mu g) [m/s^2]."""
        return min(self.a_lat_max, self.mu * G)

    @property
    def ax_drive(self) -> float:
        """Effective drive limit min(a_drive_max, mu g) [m/s^2]."""
        return min(self.a_drive_max, self.mu * G)

    @property
    def ax_brake(self) -> float:
        """Effective brake limit min(a_brake_max, mu g) [m/s^2] (positive)."""
        return min(self.a_brake_max, self.mu * G)


@numba.njit(cache=True, inline="always")
def _accel_cap(u0, k0, k1, ds, ax, ay):
    """Largest v1^2 reachable from v0^2 = u0 over ds, ellipse at both nodes (see module doc).

    Node 0: a <= ax sqrt(1 - (u0 k0 / ay)^2).  Node 1: with A = 1/(2 ds ax)^2, B = (k1/ay)^2,
    A (u1 - u0)^2 + B u1^2 <= 1, whose upper root is (A u0 + sqrt(A + B - A B u0^2)) / (A + B).
    If u0 already exceeds the lateral limit of node 1 the segment must brake: no cap here.
    """
    r0 = u0 * abs(k0) / ay
    cap0 = u0 + 2.0 * ds * ax * math.sqrt(max(1.0 - r0 * r0, 0.0))
    b = (k1 / ay) ** 2
    if b * u0 * u0 >= 1.0:
        return np.inf
    a = 1.0 / (2.0 * ds * ax) ** 2
    cap1 = (a * u0 + math.sqrt(a + b - a * b * u0 * u0)) / (a + b)
    return min(cap0, cap1)


@numba.njit(cache=True, inline="always")
def _drive_acc(v, drv):
    """Power-limited drive acceleration a_p(v) [m/s^2] of the drive model ``drv`` (module doc)."""
    f_drive = min(drv[_FDRIVE], drv[_PMAX] / max(v, _V_FLOOR))  # torque limit, power cap
    # [VM] 1.9: drag 1/2 rho C_d A v^2, rolling resistance f_r m g
    return (f_drive - drv[_KDRAG] * v * v - drv[_FROLL]) / drv[_M]


@numba.njit(cache=True)
def _drive_acc_many(v, drv):
    out = np.empty_like(v)
    for i in range(v.shape[0]):
        out[i] = _drive_acc(v[i], drv)
    return out


@numba.njit(cache=True, inline="always")
def _power_cap(u0, ds, ax, drv):
    """Largest v1^2 the powertrain reaches from v0^2 = u0 over ds: one Heun step in v^2 of
    d(v^2)/ds = 2 min(ax, a_p(v)) (module doc)."""
    a0 = min(ax, _drive_acc(math.sqrt(u0), drv))
    w1 = u0 + 2.0 * ds * a0  # predictor
    a1 = min(ax, _drive_acc(math.sqrt(max(w1, 0.0)), drv))
    cap = u0 + ds * (a0 + a1)  # corrector (trapezoidal rule in s)
    if cap < u0 <= drv[_UTOP]:
        # at or below v_top the exact solution never decreases; only rounding near v_top
        # (a_p ~ 0) gets here, and it must not shave a little off the speed at every node
        cap = u0
    return max(cap, 0.0)


@numba.njit(cache=True)
def _top_speed(drv):
    """Largest v with a_p(v) >= 0 (bisection to adjacent floats; a_p decreases with v).

    0 if a_p(0) <= 0; inf if a_p stays positive up to 1e6 m/s (no drag, no rolling resistance).
    """
    if _drive_acc(0.0, drv) <= 0.0:
        return 0.0
    hi = 1.0
    while _drive_acc(hi, drv) >= 0.0:
        hi *= 2.0
        if hi > 1e6:
            return np.inf
    lo = 0.0
    for _ in range(2000):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if _drive_acc(mid, drv) >= 0.0:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _passes(kappa, ds, u_lat, ax_d, ax_b, ay, closed, u_first, u_last, max_sweeps, drv):
    """Forward-backward passes on v^2 (u). ``u_lat`` holds the lateral/top-speed caps;
    ``drv`` the drive model (see :func:`_drive_array`) or an empty array (friction only)."""
    power = drv.shape[0] > 0
    n = kappa.shape[0]  # nodes; on a closed track node n-1 is node 0 again
    u = u_lat.copy()
    if not closed:
        u[0] = min(u[0], u_first)
        u[n - 1] = min(u[n - 1], u_last)
    m = n - 1 if closed else n  # distinct nodes
    start = 0
    if closed:  # start the sweeps at the slowest corner
        best = np.inf
        for i in range(m):
            if u_lat[i] < best:
                best = u_lat[i]
                start = i
    sweeps = 0
    for sweeps in range(1, max_sweeps + 1):  # noqa: B007 (the count is returned)
        changed = False
        # forward (accelerating) pass
        steps = m if closed else n - 1
        for k in range(steps):
            i = (start + k) % m if closed else k
            j = (i + 1) % m if closed else i + 1
            cap = _accel_cap(u[i], kappa[i], kappa[j], ds, ax_d, ay)
            if power:
                cap = min(cap, _power_cap(u[i], ds, ax_d, drv))
            if cap < u[j]:
                if u[j] - cap > 1e-12 * (1.0 + u[j]):
                    changed = True
                u[j] = cap
        # backward (braking) pass: the same law with the path reversed
        for k in range(steps):
            if closed:
                j = (start - k) % m
                i = (j - 1) % m
            else:
                j = n - 1 - k
                i = j - 1
            cap = _accel_cap(u[j], kappa[j], kappa[i], ds, ax_b, ay)
            if cap < u[i]:
                if u[i] - cap > 1e-12 * (1.0 + u[i]):
                    changed = True
                u[i] = cap
        # one forward + one backward sweep is exact on an open path (the backward pass only
        # lowers nodes into braking segments); a loop repeats until the profile is periodic
        if not closed or not changed:
            break
    if closed:
        u[n - 1] = u[0]
    return u, sweeps


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SpeedProfile:
    """Speed at the nodes of a track, with the constant segment accelerations and node times.

    Attributes
    ----------
    track : Track
    s : ndarray (N+1,)
        Node arc length [m].
    v : ndarray (N+1,)
        Speed at the nodes [m/s] (continuous in s).
    a : ndarray (N,)
        Constant acceleration on each segment [m/s^2].
    t : ndarray (N+1,)
        Time at the nodes [s], t[0] = 0; exact for constant acceleration per segment:
        dt_i = 2 ds / (v_i + v_{i+1}).
    limits : SpeedLimits or None
        The limits it was built for (None for a prescribed profile).
    vehicle : VehicleParams or None
        The vehicle whose drive limit it respects (None: friction limits only).
    """

    track: Track = field(repr=False)
    s: np.ndarray = field(repr=False)
    v: np.ndarray = field(repr=False)
    a: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    limits: SpeedLimits | None = None
    vehicle: VehicleParams | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("s", "v", "a", "t"):
            arr = np.ascontiguousarray(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def duration(self) -> float:
        """Time to cover the whole path (a lap on a closed track) [s]."""
        return float(self.t[-1])

    @property
    def a_lat(self) -> np.ndarray:
        """Lateral acceleration v^2 kappa at the nodes [m/s^2]."""
        return self.v**2 * self.track.kappa

    def state_at_time(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Arc length [m], speed [m/s] and acceleration [m/s^2] at times ``t`` (array_like,
        within one pass of the path).

        Exact inversion of s(t) = s_i + v_i tau + a_i tau^2 / 2 on each segment.
        """
        ta = np.atleast_1d(np.asarray(t, dtype=float))
        i = np.clip(np.searchsorted(self.t, ta, side="right") - 1, 0, len(self.a) - 1)
        tau = ta - self.t[i]
        a = self.a[i]
        v = self.v[i] + a * tau
        s = self.s[i] + self.v[i] * tau + 0.5 * a * tau * tau
        return s, v, a


def _node_times(v: np.ndarray, ds: float, where: str) -> np.ndarray:
    vsum = v[:-1] + v[1:]
    if (vsum <= 0.0).any():
        i = int(np.flatnonzero(vsum <= 0.0)[0])
        raise ValueError(f"{where}: zero speed on the segment s = {i * ds:.1f} m; the path "
                         "cannot be traversed (raise v_start/v_end or the limits)")
    return np.concatenate([[0.0], np.cumsum(2.0 * ds / vsum)])


def _drive_array(vehicle) -> np.ndarray:
    """The drive model of ``vehicle`` as a float array (m, F_drive,max, P_max, k_drag, F_roll,
    v_top^2)."""
    if not isinstance(vehicle, VehicleParams):  # house style: ValueError naming the field
        raise ValueError(
            f"vehicle = {vehicle!r}: expected a flatfree.vehicles.VehicleParams "
            "(e.g. load_vehicle('peugeot406'))")
    m = vehicle.mass
    drv = np.empty(6)
    drv[_M] = m
    drv[_FDRIVE] = vehicle.max_drive_torque / vehicle.wheel_radius  # actuator torque limit
    drv[_PMAX] = vehicle.max_power  # drive force capped by max_power / v
    drv[_KDRAG] = 0.5 * vehicle.air_density * vehicle.drag_area  # [VM] 1.9: 1/2 rho C_d A
    drv[_FROLL] = vehicle.rolling_resistance * m * G  # [VM] 1.9: f_r m g
    drv[_UTOP] = _top_speed(drv) ** 2  # reads the entries above only
    return drv


def drive_acceleration(v, vehicle: VehicleParams) -> np.ndarray:
    """Largest forward acceleration the powertrain of ``vehicle`` gives at speed ``v`` [m/s^2].

    a_p(v) = (min(max_drive_torque / R_e, max_power / v) - 1/2 rho C_d A v^2 - f_r m g) / m

    on a level road, tyres not slipping (no friction limit: :func:`speed_profile` takes the
    smaller of this and its friction ellipse). The power cap uses max(v, 1e-3 m/s), so a_p(0)
    is the torque-limited value. Negative above the car's top speed (:func:`top_speed`).
    This is the model of ``flatfree.simulation.flying_lap_speed`` (same expressions).

    Parameters
    ----------
    v : array_like
        Speed(s) >= 0 [m/s].
    vehicle : VehicleParams
        Uses mass, wheel_radius, max_drive_torque, max_power, air_density, drag_area,
        rolling_resistance.

    Returns
    -------
    ndarray
        a_p(v), the shape of ``v`` [m/s^2].

    References
    ----------
    .. [VM] docs/VEHICLE_MODEL.md 1.9 (drag, rolling resistance); the power cap:
       :class:`flatfree.actuators.ActuatorParams`.
    """
    drv = _drive_array(vehicle)
    va = np.asarray(v, dtype=float)
    if not (np.isfinite(va).all() and (va >= 0.0).all()):
        raise ValueError(f"v = {v!r} m/s: every speed must be finite and >= 0")
    flat = np.ascontiguousarray(va.reshape(-1))
    return _drive_acc_many(flat, drv).reshape(va.shape)


def top_speed(vehicle: VehicleParams) -> float:
    """Top speed of ``vehicle`` on a level road [m/s]: the largest v with
    :func:`drive_acceleration` ``(v) >= 0`` (to the last float; ``inf`` without any drag or
    rolling resistance)."""
    return float(_top_speed(_drive_array(vehicle)))


def speed_profile(
    track: Track,
    limits: SpeedLimits | None = None,
    *,
    v_start: float | None = None,
    v_end: float | None = None,
    vehicle: VehicleParams | None = None,
) -> SpeedProfile:
    """The fastest speed profile of ``track`` within ``limits`` [QSS] [FB], optionally within
    the drive limit of ``vehicle``.

    Parameters
    ----------
    track : Track
    limits : SpeedLimits, optional
        Default :class:`SpeedLimits()` (6 m/s^2 lateral, +3 / -6 m/s^2 longitudinal, 50 m/s,
        no lateral-jerk limit). A finite ``j_lat_max`` also caps every node at
        :func:`jerk_speed_cap` before the passes (module docstring, "Lateral-jerk limit").
    v_start, v_end : float, optional
        Speed at the start / end of an OPEN path [m/s] (default: unconstrained, a flying
        start/finish). Not allowed on a closed track, whose profile is periodic.
    vehicle : VehicleParams, optional
        Also keep every accelerating segment within the car's drive acceleration
        :func:`drive_acceleration` (torque and power limits against drag and rolling
        resistance, one Heun step in v^2 per segment; see the module docstring) and every node
        (``v_start`` too) at or below :func:`top_speed`. Braking is unchanged (drag ignored:
        conservative).
        None (default): friction limits only, the results of the friction-only profile bit
        for bit.

    Returns
    -------
    SpeedProfile

    Raises
    ------
    ValueError
        ``vehicle`` is not a VehicleParams, or its drive force cannot overcome the rolling
        resistance from rest; bad ``v_start``/``v_end``; a path that cannot be traversed.
    """
    lim = limits if limits is not None else SpeedLimits()
    if track.closed and (v_start is not None or v_end is not None):
        raise ValueError("v_start/v_end: a closed track has a periodic profile; leave them None")
    u_first = np.inf if v_start is None else nonnegative("v_start", v_start, "m/s") ** 2
    u_last = np.inf if v_end is None else nonnegative("v_end", v_end, "m/s") ** 2
    if vehicle is None:
        drv = np.empty(0)
    else:
        drv = _drive_array(vehicle)
        if _drive_acc(0.0, drv) <= 0.0:
            raise ValueError(
                f"vehicle.max_drive_torque = {vehicle.max_drive_torque!r} N m: the drive force "
                f"{drv[_FDRIVE]:.4g} N does not overcome the rolling resistance "
                f"{drv[_FROLL]:.4g} N; the car cannot move off")
    kappa = np.ascontiguousarray(track.kappa)
    ay = lim.ay
    with np.errstate(divide="ignore"):
        u_lat = np.where(kappa != 0.0, ay / np.abs(kappa), np.inf)  # [QSS] v^2 |kappa| <= ay
    u_lat = np.minimum(u_lat, lim.v_max**2)
    if math.isfinite(lim.j_lat_max):  # inf (default): the cap is all inf, a no-op; skip it
        u_lat = np.minimum(u_lat, jerk_speed_cap(track, lim.j_lat_max) ** 2)
    if vehicle is not None:
        u_lat = np.minimum(u_lat, drv[_UTOP])  # the car's top speed (module doc)
    u, _ = _passes(kappa, track.ds, u_lat, lim.ax_drive, lim.ax_brake, ay, track.closed,
                   u_first, u_last, 50, drv)
    v = np.sqrt(u)
    a = (u[1:] - u[:-1]) / (2.0 * track.ds)
    t = _node_times(v, track.ds, f"speed profile of {track.name or 'track'}")
    return SpeedProfile(track=track, s=track.s.copy(), v=v, a=a, t=t, limits=lim,
                        vehicle=vehicle)


def jerk_speed_cap(track: Track, j_lat_max: float) -> np.ndarray:
    """Node speed cap of the lateral-jerk limit [m/s]: v <= (j_lat_max / |d kappa/ds|)^(1/3).

    The speed at which steady travel along ``track`` (constant speed) changes its lateral
    acceleration v^2 kappa at the rate ``j_lat_max`` [m/s^3]: d(v^2 kappa)/dt = v^3 d kappa/ds.
    d kappa/ds is the track's own node value :attr:`Track.dkappa_ds` (the analytic derivative
    of the fitted spline's curvature, not a finite difference); ``inf`` where it is 0. See the
    module docstring ("Lateral-jerk limit") for what the cap leaves out.

    Parameters
    ----------
    track : Track
    j_lat_max : float
        Lateral-jerk limit [m/s^3], > 0 (``inf``: no cap, all ``inf``).

    Returns
    -------
    ndarray (N+1,)
        The cap at the nodes [m/s].
    """
    j = positive_or_inf("j_lat_max", j_lat_max, "m/s^3")
    dk = np.abs(track.dkappa_ds)
    with np.errstate(divide="ignore", over="ignore"):
        # v^3 |dkappa/ds| <= j_lat_max; the cube root (not ** (1/3)) is exact on cubes
        return np.where(dk > 0.0, np.cbrt(j / dk), np.inf)


def constant_speed_profile(track: Track, speed: float) -> SpeedProfile:
    """A constant speed [m/s] along ``track`` (no limits are checked)."""
    positive("speed", speed, "m/s")
    n = track.s.shape[0]
    v = np.full(n, float(speed))
    return SpeedProfile(track=track, s=track.s.copy(), v=v, a=np.zeros(n - 1),
                        t=track.s / float(speed), limits=None)
