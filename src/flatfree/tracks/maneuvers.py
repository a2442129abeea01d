"""Classic maneuvers as references: constant-radius circle, straight line with a speed step,
ISO 3888-1 double lane change.

All paths start at the origin heading along +x (ISO 8855 ground frame, y to the left).

References
----------
[ISO3888-1] ISO 3888-1:2018, Passenger cars - Test track for a severe lane-change manoeuvre -
    Part 1: Double lane-change. Section lengths 15 / 30 / 25 / 25 / 15 m, lane widths
    1.1 b + 0.25, 1.2 b + 0.25, 1.3 b + 0.25 m (b = vehicle width), lateral offset 3.5 m. The
    standard text was not available to us: the geometry below follows its widely reproduced
    dimensions as implemented in Project Chrono's ISO 3888 helper (demo_VEH_HMMWV_DoubleLaneChange,
    BSD-3): the section-3 lane has its centre at b3/2 + 3.5 m left of the section-1 lane centre,
    and the section-5 lane shares its right boundary with the section-1 lane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flatfree._validate import nonnegative, positive
from flatfree.tracks.geometry import DEFAULT_DS, Track
from flatfree.tracks.reference import N_RS, RS, Reference, make_reference

__all__ = [
    "circle_track",
    "circle_reference",
    "straight_track",
    "speed_step_reference",
    "Gate",
    "iso3888_1_gates",
    "double_lane_change_track",
    "double_lane_change_reference",
]


def circle_track(radius: float, *, direction: str = "left", ds: float = DEFAULT_DS) -> Track:
    """A closed circle of ``radius`` [m] through the origin, heading +x at s = 0.

    ``direction="left"``: counter-clockwise (centre at (0, R), kappa = +1/R); ``"right"``:
    clockwise (kappa = -1/R). Built from exact points every ~ds/2, without smoothing.
    """
    r = positive("radius", radius, "m")
    sign = _direction(direction)
    n = max(int(math.ceil(2.0 * math.pi * r / (0.5 * ds))), 16)
    th = np.arange(n) * (2.0 * math.pi / n)
    x = r * np.sin(th)
    y = sign * r * (1.0 - np.cos(th))
    return Track.from_points(x, y, closed=True, ds=ds, smoothing_length=0.0,
                             name=f"circle R={r:g} m {direction}", source="circle_track")


def circle_reference(radius: float, speed: float, *, laps: int = 1, direction: str = "left",
                     dt: float = 0.01, ds: float = DEFAULT_DS) -> Reference:
    """Constant speed [m/s] on a constant-radius circle [m]: a_y = speed^2 / radius."""
    trk = circle_track(radius, direction=direction, ds=ds)
    return make_reference(trk, float(speed), dt=dt, laps=laps, name=trk.name)


def straight_track(length: float, *, ds: float = DEFAULT_DS) -> Track:
    """An open straight line from the origin along +x [m]."""
    length = positive("length", length, "m")
    n = max(int(math.ceil(length / ds)) + 1, 4)
    x = np.linspace(0.0, length, n)
    return Track.from_points(x, np.zeros_like(x), closed=False, ds=ds, smoothing_length=0.0,
                             name=f"straight {length:g} m", source="straight_track")


def speed_step_reference(
    v0: float,
    v1: float,
    *,
    t_step: float = 2.0,
    duration: float = 10.0,
    accel: float | None = None,
    dt: float = 0.01,
) -> Reference:
    """Straight line with a step of the speed reference from v0 to v1 [m/s] at ``t_step`` [s].

    ``accel=None``: a true step (Vx jumps; the reported a_x is 0 everywhere, the step's impulse
    is not represented). ``accel`` > 0 [m/s^2]: a ramp from v0 to v1 at that rate instead.
    The path is long enough for the whole drive plus 20 m.
    """
    v0 = nonnegative("v0", v0, "m/s")
    v1 = nonnegative("v1", v1, "m/s")
    positive("dt", dt, "s")
    t_step = nonnegative("t_step", t_step, "s")
    duration = positive("duration", duration, "s")
    if t_step >= duration:
        raise ValueError(f"t_step = {t_step} s: must be before duration = {duration} s")
    t = np.arange(int(math.floor(duration / dt + 1e-9)) + 1) * dt
    if accel is None:
        v = np.where(t < t_step, v0, v1)
        a = np.zeros_like(t)
        s = np.where(t < t_step, v0 * t, v0 * t_step + v1 * (t - t_step))
    else:
        acc = positive("accel", accel, "m/s^2") * math.copysign(1.0, v1 - v0)
        t_ramp = abs(v1 - v0) / abs(acc) if v1 != v0 else 0.0
        t1 = t_step + t_ramp
        v = np.where(t < t_step, v0, np.where(t < t1, v0 + acc * (t - t_step), v1))
        a = np.where((t >= t_step) & (t < t1), acc, 0.0)
        tr = np.clip(t - t_step, 0.0, t_ramp)
        s = (v0 * np.minimum(t, t_step) + v0 * tr + 0.5 * acc * tr * tr
             + v1 * np.maximum(t - t1, 0.0))
    trk = straight_track(float(s[-1]) + 20.0)
    tab = np.zeros((t.shape[0], N_RS))
    tab[:, RS.T] = t
    tab[:, RS.S] = s
    tab[:, RS.S_PATH] = s
    tab[:, RS.X] = s
    tab[:, RS.VX] = v
    tab[:, RS.AX] = a
    tab[:, RS.W_LEFT] = np.nan
    tab[:, RS.W_RIGHT] = np.nan
    return Reference(name=f"speed step {v0:g} -> {v1:g} m/s", path=trk, line=trk, table=tab)


@dataclass(frozen=True, slots=True)
class Gate:
    """A cone-lined lane section of the double lane change [m]."""

    x_start: float
    x_end: float
    y_right: float
    y_left: float

    @property
    def center(self) -> float:
        """Lane centre y [m]."""
        return 0.5 * (self.y_left + self.y_right)

    @property
    def width(self) -> float:
        """Lane width [m]."""
        return self.y_left - self.y_right


def _direction(direction: str) -> float:
    if direction not in ("left", "right"):
        raise ValueError(f"direction = {direction!r}: must be 'left' or 'right'")
    return 1.0 if direction == "left" else -1.0


def iso3888_1_gates(vehicle_width: float, *, lead_in: float = 50.0,
                    direction: str = "left") -> tuple[Gate, Gate, Gate]:
    """The three lanes of the ISO 3888-1 double lane change [ISO3888-1].

    Section 1 (lane A) starts at x = ``lead_in``: length 15 m, width 1.1 b + 0.25 m; section 2
    30 m; section 3 (lane B) 25 m, width 1.2 b + 0.25 m, centre (1.2 b + 0.25)/2 + 3.5 m to the
    side of lane A's centre; section 4 25 m; section 5 (lane C) 15 m, width 1.3 b + 0.25 m,
    right boundary in line with lane A's (for a left change; mirrored for ``"right"``).
    """
    b = positive("vehicle_width", vehicle_width, "m")
    x0 = nonnegative("lead_in", lead_in, "m")
    sign = _direction(direction)
    wa, wb, wc = 1.1 * b + 0.25, 1.2 * b + 0.25, 1.3 * b + 0.25  # [ISO3888-1]
    ya = 0.0
    yb = wb / 2.0 + 3.5  # [ISO3888-1] lateral offset 3.5 m, Chrono's convention
    yc = (wc - wa) / 2.0  # right boundaries of sections 1 and 5 aligned
    xa, xb, xc = x0, x0 + 15.0 + 30.0, x0 + 15.0 + 30.0 + 25.0 + 25.0
    gates = []
    for xs, length, yc_, w in ((xa, 15.0, ya, wa), (xb, 25.0, yb, wb), (xc, 15.0, yc, wc)):
        lo, hi = sign * yc_ - w / 2.0, sign * yc_ + w / 2.0
        gates.append(Gate(xs, xs + length, lo, hi))
    return tuple(gates)


def _septic(xi: np.ndarray) -> np.ndarray:
    """C3 smooth step 35 xi^4 - 84 xi^5 + 70 xi^6 - 20 xi^7 on [0, 1] (0 and 1 outside)."""
    z = np.clip(xi, 0.0, 1.0)
    return z**4 * (35.0 - 84.0 * z + 70.0 * z**2 - 20.0 * z**3)


def double_lane_change_track(vehicle_width: float, *, lead_in: float = 50.0,
                             run_out: float = 50.0, direction: str = "left",
                             ds: float = DEFAULT_DS) -> Track:
    """Path through the lane centres of :func:`iso3888_1_gates`.

    Straight in the gates; between them (sections 2 and 4) a C3 smooth step
    y = y0 + (y1 - y0)(35 xi^4 - 84 xi^5 + 70 xi^6 - 20 xi^7), so curvature and its
    derivative are continuous. Peak |kappa| ~ 7.5 |y1 - y0| / L^2 (L = 30 or 25 m): for
    b = 1.8 m about 0.039 1/m in section 2 and 0.052 1/m in section 4, so a_y = v^2 kappa
    reaches 6 m/s^2 near 10.8 m/s (39 km/h). A real driver cuts the corners within the lane
    widths; this centre-line path is the conservative reference.
    Widths: inside the gates, distance to the cones measured along y; NaN elsewhere (the
    standard defines no boundary there).
    """
    ga, gb, gc = iso3888_1_gates(vehicle_width, lead_in=lead_in, direction=direction)
    run_out = nonnegative("run_out", run_out, "m")
    x_end = gc.x_end + run_out
    x = np.linspace(0.0, x_end, int(math.ceil(x_end / 0.25)) + 1)
    y = (ga.center + (gb.center - ga.center) * _septic((x - ga.x_end) / (gb.x_start - ga.x_end))
         + (gc.center - gb.center) * _septic((x - gb.x_end) / (gc.x_start - gb.x_end)))
    wl = np.full_like(x, np.nan)
    wr = np.full_like(x, np.nan)
    for g in (ga, gb, gc):
        m = (x >= g.x_start) & (x <= g.x_end)
        wl[m] = g.y_left - y[m]
        wr[m] = y[m] - g.y_right
    return Track.from_points(x, y, w_left=wl, w_right=wr, closed=False, ds=ds,
                             smoothing_length=0.0,
                             name=f"ISO 3888-1 double lane change b={vehicle_width:g} m",
                             source="double_lane_change_track")


def double_lane_change_reference(speed: float, *, vehicle_width: float, lead_in: float = 50.0,
                                 run_out: float = 50.0, direction: str = "left",
                                 dt: float = 0.01, ds: float = DEFAULT_DS) -> Reference:
    """Constant ``speed`` [m/s] through the ISO 3888-1 double lane change (see
    :func:`double_lane_change_track`; the test is driven at a constant entry speed)."""
    trk = double_lane_change_track(vehicle_width, lead_in=lead_in, run_out=run_out,
                                   direction=direction, ds=ds)
    return make_reference(trk, float(speed), dt=dt, name=trk.name)
