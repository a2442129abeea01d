"""Power-aware speed profile (tracks/speed.py ``vehicle=``): exact on a straight, never above the
friction profile nor the drive limit, the flying lap's top speed, backward compatible."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import flatfree.tracks as T
from flatfree.simulation import flying_lap_speed
from flatfree.tracks.speed import drive_acceleration, top_speed
from flatfree.units import G
from flatfree.vehicles import load_vehicle

PEUGEOT = load_vehicle("peugeot406")
DALLARA = load_vehicle("dallara_av21")


def resistances(veh):
    """(m, F_drive,max, P, k_drag, F_roll) written out from the VehicleParams fields."""
    return (veh.mass, veh.max_drive_torque / veh.wheel_radius, veh.max_power,
            0.5 * veh.air_density * veh.drag_area, veh.rolling_resistance * veh.mass * G)


# ------------------------------------------------------------------------------------------
# the drive model
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("veh", [PEUGEOT, DALLARA], ids=["peugeot406", "dallara_av21"])
def test_drive_acceleration_is_the_flying_lap_model(veh):
    m, fmax, p, k, fr = resistances(veh)
    v = np.array([[0.0, 5.0, 13.0], [20.0, 40.0, 60.0]])
    # the two branches of F_drive = min(torque / R_e, P / v), written out
    expect = np.where(v * fmax < p, fmax, p / np.maximum(v, 1e-3))
    expect = (expect - k * v**2 - fr) / m
    got = drive_acceleration(v, veh)
    assert got.shape == v.shape
    # the same expressions in another order: rounding only (1e-13 relative of ~10 m/s^2 terms)
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-13 * (fmax / m))


@pytest.mark.parametrize("veh", [PEUGEOT, DALLARA], ids=["peugeot406", "dallara_av21"])
def test_top_speed_is_the_root_of_the_power_balance(veh):
    _, fmax, p, k, fr = resistances(veh)
    # above P / F_max the balance P / v = k v^2 + f_r m g is the cubic k v^3 + F_roll v - P = 0
    roots = np.roots([k, 0.0, fr, -p])
    v_star = float(max(r.real for r in roots if abs(r.imag) < 1e-9 and r.real > 0))
    assert v_star > p / fmax  # the power branch holds there
    vt = top_speed(veh)
    assert vt == pytest.approx(v_star, rel=1e-12)  # np.roots: ~1e-15 relative; 1e-12 margin
    # and it is the last float with a_p >= 0
    assert drive_acceleration(vt, veh) >= 0.0
    assert drive_acceleration(np.nextafter(vt, np.inf), veh) < 0.0


# ------------------------------------------------------------------------------------------
# (a) backward compatible
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["Norisring", "Monza"])
def test_default_path_unchanged_bit_for_bit(name):
    """No vehicle = the friction-only profile (also checked against the code before the change
    on every bundled track/raceline x three limit sets, during development); a vehicle whose
    engine never binds goes through the power cap and still gives the same bits."""
    trk = T.load_track(name)
    lim = T.SpeedLimits(a_lat_max=9.0, a_drive_max=5.0, a_brake_max=10.0, v_max=80.0)
    ref = T.speed_profile(trk, lim)
    same = T.speed_profile(trk, lim, vehicle=None)
    strong = dataclasses.replace(PEUGEOT, max_drive_torque=1e9, max_power=1e12,
                                 drag_area=0.0, rolling_resistance=0.0)
    assert top_speed(strong) == math.inf
    never_binds = T.speed_profile(trk, lim, vehicle=strong)
    for prof in (same, never_binds):
        assert np.array_equal(prof.v, ref.v)
        assert np.array_equal(prof.a, ref.a)
        assert np.array_equal(prof.t, ref.t)
    assert same.vehicle is None and never_binds.vehicle is strong
    # the dallara_av21 (353 kW, 790 kg) gives > 3 m/s^2 up to 50 m/s: the default limits bind
    dal = T.speed_profile(trk, vehicle=DALLARA)
    assert np.array_equal(dal.v, T.speed_profile(trk).v)


# ------------------------------------------------------------------------------------------
# (b) exact on a straight
# ------------------------------------------------------------------------------------------
AX = 3.0  # default drive limit [m/s^2]
STRAIGHT_LIMITS = T.SpeedLimits(a_drive_max=AX, v_max=200.0)


def exact_straight(veh, v0: float, length: float):
    """v(s) of d(v^2)/ds = 2 min(AX, a_p(v)) from v(0) = v0 (v0 < 25 m/s).

    Below the speed v1 where a_p(v1) = AX (the friction limit binds) v^2 = v0^2 + 2 AX s in
    closed form; from there the power branch P / v (v1 > P / F_max is asserted) is smooth and
    solved with DOP853 at rtol 1e-13.
    """
    m, fmax, p, k, fr = resistances(veh)

    def ap(v):
        return (p / v - k * v * v - fr) / m

    v1 = brentq(lambda v: ap(v) - AX, p / fmax, 60.0, xtol=1e-14, rtol=1e-15)
    assert v1 > p / fmax and v1 > v0
    s1 = (v1 * v1 - v0 * v0) / (2 * AX)
    sol = solve_ivp(lambda s, w: [2.0 * ap(math.sqrt(w[0]))], (s1, length), [v1 * v1],
                    method="DOP853", rtol=1e-13, atol=1e-12, dense_output=True)

    def v_of_s(s):
        out = np.sqrt(v0 * v0 + 2 * AX * np.minimum(s, s1))
        hi = s > s1
        out[hi] = np.sqrt(sol.sol(s[hi])[0])
        return out

    # d a_p / dv at v1 (for the kink bound)
    dap = -p / (m * v1 * v1) - 2 * k * v1 / m
    return v_of_s, v1, dap


def test_heun_in_v2_is_second_order_on_the_power_limited_straight():
    """Start at 25 m/s > v1: the drive limit is a_p (smooth) everywhere."""
    m, _, p, k, fr = resistances(PEUGEOT)
    length, v0 = 1500.0, 25.0
    assert drive_acceleration(v0, PEUGEOT) < AX
    sol = solve_ivp(lambda s, w: [2.0 * (p / math.sqrt(w[0]) - k * w[0] - fr) / m],
                    (0.0, length), [v0 * v0], method="DOP853", rtol=1e-13, atol=1e-12,
                    dense_output=True)
    err = []
    for ds in (2.0, 1.0, 0.5):
        prof = T.speed_profile(T.straight_track(length, ds=ds), STRAIGHT_LIMITS, v_start=v0,
                               vehicle=PEUGEOT)
        err.append(np.abs(prof.v - np.sqrt(sol.sol(prof.s)[0])).max())
    order = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    # Heun is second order; measured 1.99 / 2.00 (the reference is ~1e-11 accurate)
    assert ((order > 1.9) & (order < 2.1)).all(), order
    # measured 2.05e-6 m/s on the 1 m grid; 5e-6 is the stated accuracy of the module docstring
    assert err[1] < 5e-6


@pytest.mark.parametrize("ds", [2.0, 1.0])
def test_straight_from_rest_follows_the_exact_solution(ds):
    length = 1500.0
    v_exact, v1, dap = exact_straight(PEUGEOT, 0.0, length)
    prof = T.speed_profile(T.straight_track(length, ds=ds), STRAIGHT_LIMITS, v_start=0.0,
                           vehicle=PEUGEOT)
    err = np.abs(prof.v - v_exact(prof.s)).max()
    # Error budget. (1) The kink at v1, where min(AX, a_p) switches branch: d(v^2)/ds is
    # continuous but its slope jumps by c = 2 |a_p'(v1)| AX / v1; the trapezoid (Heun) step over
    # the segment holding the kink is off by c ds^2 theta (1 - theta) / 2 <= c ds^2 / 8 in v^2
    # (theta: where the kink lies in the segment), i.e. c ds^2 / (16 v1) in v; downstream the
    # power-limited ODE is contracting, so this is the largest the error gets. The analysis is
    # leading order in ds; the next order is ds |a_p'| / v1 ~ 2 % here: +10 %. (2) The smooth
    # part: second order, < 5e-6 m/s at ds = 1 m (previous test), scaled by ds^2.
    c = 2.0 * abs(dap) * AX / v1
    tol = 1.1 * c * ds**2 / (16.0 * v1) + 5e-6 * ds**2
    assert err <= tol, (err, tol)
    # the bound is not loose where the kink falls mid-segment (ds = 2: theta = 0.49; measured
    # 5.79e-4 against 6.7e-4), and the profile really is power-limited (not the 3 m/s^2 line)
    assert prof.v[-1] < 0.995 * top_speed(PEUGEOT) < math.sqrt(2 * AX * length)
    if ds == 2.0:
        assert err > 0.5 * tol


# ------------------------------------------------------------------------------------------
# (c), (d): below the friction profile, within the drive limit at every node
# ------------------------------------------------------------------------------------------
def check_friction_limits(prof, slack=1e-9):
    """The friction-ellipse definition of speed.py's docstring (as tests/test_tracks_speed.py)."""
    lim = prof.limits
    v, a, k = prof.v, prof.a, prof.track.kappa
    assert (v <= lim.v_max * (1 + slack)).all()
    assert (np.abs(v**2 * k) <= lim.ay * (1 + slack)).all()
    amax = np.where(a > 0, lim.ax_drive, lim.ax_brake)
    for j in (slice(None, -1), slice(1, None)):
        assert ((a / amax) ** 2 + (v[j] ** 2 * k[j] / lim.ay) ** 2 <= 1 + 4 * slack).all()


CASES = [("Norisring", PEUGEOT, None), ("LVMS", PEUGEOT, None), ("Spa", PEUGEOT, None),
         ("Monza", DALLARA, T.SpeedLimits(v_max=90.0))]


@pytest.mark.parametrize("name,veh,lim", CASES, ids=[c[0] + "-" + c[1].name for c in CASES])
def test_never_above_the_friction_profile_and_within_the_drive_limit(name, veh, lim):
    trk = T.load_track(name)
    fric = T.speed_profile(trk, lim)
    prof = T.speed_profile(trk, lim, vehicle=veh)
    # (c) the drive limit only removes speed; both passes are monotone in the node values, so
    # this holds exactly up to rounding of the square roots (1e-12 relative)
    assert (prof.v <= fric.v * (1 + 1e-12)).all()
    assert prof.v[0] == prof.v[-1]  # periodic
    check_friction_limits(prof)
    assert (prof.v <= top_speed(veh) * (1 + 1e-12)).all()
    # (d) the drive limit a_d(v) = min(a_x,max, a_p(v)) at every node. The segment after node i:
    # its constant acceleration is the Heun mean of a_d at v_i and at the predicted end speed,
    # both <= a_d(v_i) since a_d decreases with v: exact (rounding: 1e-12 m/s^2).
    a_d = np.minimum(prof.limits.ax_drive, drive_acceleration(prof.v, veh))
    a = prof.a
    assert (a <= a_d[:-1] + 1e-12).all()
    # the segment before node j: the predicted end speed is >= v_j, so a <= (a_d(v_i) +
    # a_d(v_j)) / 2 = a_d(v_j) + (a_d(v_i) - a_d(v_j)) / 2: a discretisation slack of half the
    # change of a_d over one segment (exact bound, + rounding)
    slack = 0.5 * np.maximum(a_d[:-1] - a_d[1:], 0.0)
    assert (a <= a_d[1:] + slack + 1e-12).all()
    # that slack is small on a 1 m grid: |a_d'| dv <= 0.17 1/s x 0.15 m/s / 2 ~ 0.013 m/s^2
    # (peugeot406 at the 3 m/s^2 -> power switch, ~20 m/s; less for the dallara_av21)
    powered = a > a_d[1:]  # segments where the power limit binds at the end node
    assert slack[powered].max(initial=0.0) < 0.02
    # the POWER limit really binds (a_p below the friction limit, segment at a_d(v_j) or
    # above) on >= 100 segments (100 m): the check is not vacuous. Measured: peugeot406 75-80 %
    # of the accelerating segments; dallara_av21 on Monza at v_max = 90 m/s 152 (> 70 m/s only)
    a_p = drive_acceleration(prof.v[1:], veh)
    power_bound = (a > 0) & (a >= a_d[1:] - 1e-9) & (a_p < prof.limits.ax_drive - 0.1)
    assert power_bound.sum() >= 100
    assert prof.duration > fric.duration


# ------------------------------------------------------------------------------------------
# (e) the flying lap's top speed on Norisring
# ------------------------------------------------------------------------------------------
def test_norisring_top_speed_is_the_flying_lap_speed():
    trk = T.load_track("Norisring")
    fric = T.speed_profile(trk)
    prof = T.speed_profile(trk, vehicle=PEUGEOT)
    fly = flying_lap_speed(trk.s, fric.v, PEUGEOT, closed=True)
    i = int(np.argmax(fly))
    assert int(np.argmax(prof.v)) == i  # the same node: the braking point of the long straight
    # On the straight both are the same Heun recursion in v^2 of the same ODE on the same grid;
    # they differ only upstream, where flying_lap_speed accelerates at a_p without the 3 m/s^2
    # friction limit (kink error <= 1.5e-4 m/s at 1 m, test above) or the friction ellipse, and
    # the power-limited ODE shrinks such differences on the way: 1e-4 m/s. Measured: equal.
    assert prof.v[i] == pytest.approx(fly[i], abs=1e-4)
    # the friction-only profile asks for far more (47.4 vs 40.2 m/s)
    assert fric.v.max() > prof.v[i] + 5.0
    # everywhere: the profile respects the ellipse also when accelerating below the reference,
    # which flying_lap_speed does not, so it is never faster (rounding: 1e-12 relative)
    assert (prof.v <= fly * (1 + 1e-12)).all()


# ------------------------------------------------------------------------------------------
# (f) bad input
# ------------------------------------------------------------------------------------------
def test_bad_vehicle_raises_naming_the_field():
    trk = T.straight_track(100.0)
    for bad in ("peugeot406", {"mass": 1500.0}, 3.0):
        with pytest.raises(ValueError, match="^vehicle = .*VehicleParams"):
            T.speed_profile(trk, vehicle=bad)
        with pytest.raises(ValueError, match="^vehicle = "):
            drive_acceleration(10.0, bad)
    weak = dataclasses.replace(PEUGEOT, max_drive_torque=1.0)  # 3.2 N against 177 N rolling
    with pytest.raises(ValueError, match=r"max_drive_torque = 1\.0 N m.*cannot move off"):
        T.speed_profile(trk, vehicle=weak)
    for v in (-1.0, np.nan, [1.0, np.inf]):
        with pytest.raises(ValueError, match="^v = .* m/s"):
            drive_acceleration(v, PEUGEOT)


def test_make_reference_plans_within_the_drive_limit():
    """make_reference(vehicle=...) is speed_profile(vehicle=...) on the same track; a drive
    limit on a prescribed speed is refused (it would be silently ignored)."""
    from flatfree.tracks import load_track, make_reference, speed_profile

    veh = load_vehicle("peugeot406")
    trk = load_track("Norisring")
    ref = make_reference(trk, dt=0.01, vehicle=veh)
    prof = speed_profile(trk, vehicle=veh)
    # the reference samples that profile in time: its speeds are the profile's state at the
    # reference's times (measured: equal to the last bit)
    np.testing.assert_array_equal(ref["vx"], prof.state_at_time(ref.t)[1])
    assert ref["vx"].max() < make_reference(trk, dt=0.01)["vx"].max() - 5.0
    with pytest.raises(ValueError, match="vehicle"):
        make_reference(trk, 20.0, vehicle=veh)
