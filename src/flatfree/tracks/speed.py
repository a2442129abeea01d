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

References
----------
[FB] E. Velenis, P. Tsiotras, "Minimum-time travel for a vehicle with acceleration limits:
     theoretical analysis and receding-horizon implementation", JOTA 138, 2008 (forward-backward
     integration of the friction-limited speed profile).
[QSS] N. R. Kapania, J. Subosits, J. C. Gerdes, "A sequential two-step algorithm for fast
     generation of vehicle racing trajectories", J. Dyn. Sys. Meas. Control 138(9), 2016
     (lateral limit v = sqrt(mu g / |kappa|), forward and backward passes on a friction circle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from flatfree._validate import positive
from flatfree.tracks.geometry import Track
from flatfree.units import G

__all__ = ["SpeedLimits", "SpeedProfile", "speed_profile", "constant_speed_profile"]


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
    """

    a_lat_max: float = field(default=6.0, metadata={"unit": "m/s^2"})
    a_drive_max: float = field(default=3.0, metadata={"unit": "m/s^2"})
    a_brake_max: float = field(default=6.0, metadata={"unit": "m/s^2"})
    v_max: float = field(default=50.0, metadata={"unit": "m/s"})
    mu: float = field(default=1.0, metadata={"unit": "-"})

    def __post_init__(self) -> None:
        positive("a_lat_max", self.a_lat_max, "m/s^2")
        positive("a_drive_max", self.a_drive_max, "m/s^2")
        positive("a_brake_max", self.a_brake_max, "m/s^2")
        positive("v_max", self.v_max, "m/s")
        positive("mu", self.mu, "-")

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


@numba.njit(cache=True)
def _passes(kappa, ds, u_lat, ax_d, ax_b, ay, closed, u_first, u_last, max_sweeps):
    """Forward-backward passes on v^2 (u). ``u_lat`` holds the lateral/top-speed caps."""
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
    for sweeps in range(1, max_sweeps + 1):
        changed = False
        # forward (accelerating) pass
        steps = m if closed else n - 1
        for k in range(steps):
            i = (start + k) % m if closed else k
            j = (i + 1) % m if closed else i + 1
            cap = _accel_cap(u[i], kappa[i], kappa[j], ds, ax_d, ay)
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
    """

    track: Track = field(repr=False)
    s: np.ndarray = field(repr=False)
    v: np.ndarray = field(repr=False)
    a: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    limits: SpeedLimits | None = None

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


def speed_profile(
    track: Track,
    limits: SpeedLimits | None = None,
    *,
    v_start: float | None = None,
    v_end: float | None = None,
) -> SpeedProfile:
    """The fastest speed profile of ``track`` within ``limits`` [QSS] [FB].

    Parameters
    ----------
    track : Track
    limits : SpeedLimits, optional
        Default :class:`SpeedLimits()` (6 m/s^2 lateral, +3 / -6 m/s^2 longitudinal, 50 m/s).
    v_start, v_end : float, optional
        Speed at the start / end of an OPEN path [m/s] (default: unconstrained, a flying
        start/finish). Not allowed on a closed track, whose profile is periodic.

    Returns
    -------
    SpeedProfile
    """
    lim = limits if limits is not None else SpeedLimits()
    if track.closed and (v_start is not None or v_end is not None):
        raise ValueError("v_start/v_end: a closed track has a periodic profile; leave them None")
    u_first = np.inf if v_start is None else positive_or_zero("v_start", v_start) ** 2
    u_last = np.inf if v_end is None else positive_or_zero("v_end", v_end) ** 2
    kappa = np.ascontiguousarray(track.kappa)
    ay = lim.ay
    with np.errstate(divide="ignore"):
        u_lat = np.where(kappa != 0.0, ay / np.abs(kappa), np.inf)  # [QSS] v^2 |kappa| <= ay
    u_lat = np.minimum(u_lat, lim.v_max**2)
    u, _ = _passes(kappa, track.ds, u_lat, lim.ax_drive, lim.ax_brake, ay, track.closed,
                   u_first, u_last, 50)
    v = np.sqrt(u)
    a = (u[1:] - u[:-1]) / (2.0 * track.ds)
    t = _node_times(v, track.ds, f"speed profile of {track.name or 'track'}")
    return SpeedProfile(track=track, s=track.s.copy(), v=v, a=a, t=t, limits=lim)


def constant_speed_profile(track: Track, speed: float) -> SpeedProfile:
    """A constant speed [m/s] along ``track`` (no limits are checked)."""
    positive("speed", speed, "m/s")
    n = track.s.shape[0]
    v = np.full(n, float(speed))
    return SpeedProfile(track=track, s=track.s.copy(), v=v, a=np.zeros(n - 1),
                        t=track.s / float(speed), limits=None)


def positive_or_zero(name: str, value) -> float:
    """A finite speed >= 0 [m/s]."""
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} = {value!r} m/s: must be a finite number >= 0")
    return v
