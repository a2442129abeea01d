"""MfcNaturalSettings.curvature_term: the path's kinematic term -Vx^2 kappa taken out of the
lateral loop's F and added back by the law at once.

The plant here is the lateral ultra-local model itself, e_y'' = F0 + alpha delta - v^2 kappa,
integrated exactly over each control period (delta and kappa held, ZOH), so the reference values
are exact: with the term the estimator's F is the constant F0, which the nu = 2 estimator
recovers to round-off; without it F holds -v^2 kappa too and follows a ramp of curvature with
the window's lag.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flatfree.actuators import ActuatorParams
from flatfree.controllers.intelligent import IPAR
from flatfree.controllers.vehicle import (
    _CURV_FF,
    CREF,
    MEAS,
    MfcNaturalSettings,
    NaturalOutputController,
    build_mfc,
    lateral_f_hat,
    vehicle_step,
)

DT = 0.001
V = 20.0  # [m/s]
ALPHA = 50.0  # [(m/s^2)/rad], the plant's and the controller's
F0 = 0.7  # [m/s^2], the constant rest of the plant's F
# an ideal steer (no rate limit within reach, no lag): the controller's model of the actuators
# is then the plant's
ACT = ActuatorParams(max_steer=0.6, max_steer_rate=100.0, max_drive_torque=5000.0,
                     max_power=1e6, max_brake_torque=5000.0, wheel_radius=0.3)


def _kappa(k: int) -> float:
    """A ramp of curvature to 0.01 1/m over 2 s, then constant."""
    return 0.01 * min(k * DT, 2.0) / 2.0


def _run(term: bool, n: int = 3000, steer0: float = 0.0):
    s = MfcNaturalSettings(alpha_lat=ALPHA, yaw_damping=0.0, wn_lat_speed=0.0,
                           correction_max=math.inf, curvature_term=term)
    c = NaturalOutputController(dt=DT, actuators=ACT, settings=s)
    c.reset(steer0=steer0)
    e = ed = 0.0
    rows = []
    for k in range(n):
        kap = _kappa(k)
        _, d = c.step(vx=V, r=0.0, e_y=e, kappa=kap, vx_ref=V)
        a = F0 + ALPHA * d - V * V * kap
        e += ed * DT + 0.5 * a * DT * DT
        ed += a * DT
        z = c._arrays  # the estimate itself: the controller does not publish it
        rows.append((e, d, lateral_f_hat(z.kind, z.p_lat, z.s_lat, z.coef), F0 - V * V * kap))
    return np.array(rows)


def test_with_the_term_f_is_exact_on_a_ramp_of_curvature():
    with_term = _run(True)
    without = _run(False)
    ramp = slice(500, 2000)  # the window full, the curvature still ramping
    # lateral_f_hat gives F of e_y'' = F + alpha delta whatever the setting: F0 - v^2 kappa
    err_with = with_term[ramp, 2] - with_term[ramp, 3]
    err_without = without[ramp, 2] - without[ramp, 3]
    assert np.max(np.abs(err_with)) < 1e-9
    # without it F lags the ramp, d(v^2 kappa)/dt = 2 m/s^3, by the window's 50 ms
    assert np.min(np.abs(err_without)) > 0.09
    # and the lateral error follows: the exact F leaves only the start's transient
    assert np.max(np.abs(with_term[1500:2000, 0])) < 1e-5
    assert np.max(np.abs(without[1500:2000, 0])) > 1e-3


def test_the_steer_is_held_while_the_window_fills():
    # on a curve from the first step: the term must not jump the start's steer
    rows = _run(True, n=150, steer0=0.05)
    n_hold = MfcNaturalSettings().window_lat - 1
    assert np.all(rows[:n_hold, 1] == 0.05)
    assert rows[n_hold, 1] != 0.05  # the law runs from there


def test_a_nonfinite_deviation_holds_the_law_and_keeps_the_term_current():
    # a lost position holds the iPD's output; the term follows the curvature on (the path
    # goes on turning while the position is lost): over the gap the steer moves by exactly
    # the term's change, Vx^2 (kappa_k - kappa_before) / alpha
    s = MfcNaturalSettings(alpha_lat=ALPHA, curvature_term=True)
    c = NaturalOutputController(dt=DT, actuators=ACT, settings=s)
    c.reset()
    d = 0.0
    for k in range(300):
        _, d = c.step(vx=V, r=V * _kappa(k), e_y=0.001, kappa=_kappa(k), vx_ref=V,
                      applied_steer=d)
    before = d
    held = []
    for k in range(300, 350):
        _, d = c.step(vx=V, r=V * _kappa(k), e_y=math.nan, kappa=_kappa(k), vx_ref=V,
                      applied_steer=d)
        held.append(d)
    term = [V * V * (_kappa(k) - _kappa(299)) / ALPHA for k in range(300, 350)]
    assert term[-1] > 1e-3  # the curvature ramps on over the gap
    assert np.allclose(np.array(held) - before, term, rtol=0.0, atol=1e-12)
    # ... on a constant curvature that is the steer applied last (to rounding: (d - t) + t)
    c.reset()
    d = 0.0
    for _ in range(300):
        _, d = c.step(vx=V, r=0.1, e_y=0.001, kappa=0.005, vx_ref=V, applied_steer=d)
    held = [c.step(vx=V, r=0.1, e_y=math.nan, kappa=0.005, vx_ref=V, applied_steer=d)[1]
            for _ in range(50)]
    assert np.allclose(held, d, rtol=0.0, atol=1e-15)
    # ... and a NaN speed keeps the last finite term (no jump by Vx^2 kappa / alpha)
    _, d2 = c.step(vx=math.nan, r=0.1, e_y=0.001, kappa=0.005, vx_ref=V, applied_steer=d)
    assert math.isfinite(d2)
    assert abs(d2 - d) < 0.01


def _kernel_step(z, *, vx, e_y, kappa, applied):
    """One raw vehicle_step (no shell: its clip to max_steer would hide the kernel's)."""
    meas = np.full(len(MEAS), math.nan)
    meas[MEAS.VX], meas[MEAS.R], meas[MEAS.E_Y] = vx, 0.0, e_y
    cref = np.zeros(len(CREF))
    cref[CREF.VX], cref[CREF.KAPPA] = vx, kappa
    return vehicle_step(z.kind, z.p_lon, z.s_lon, z.p_lat, z.s_lat, z.coef, z.f_lon, z.f_lat,
                        z.f_yaw, meas, cref, 0.0, applied)[1]


def _arrays(steer0: float = 0.0):
    s = MfcNaturalSettings(alpha_lat=ALPHA, curvature_term=True, yaw_damping=0.0)
    return build_mfc("mfc-natural", s, dt=DT, actuators=ACT, steer0=steer0)


def test_the_steer_stays_within_its_range():
    # a curvature whose term alone (V^2 kappa / alpha = 1.6 rad) exceeds the steer range, the
    # law's output at its limit and a hold on a lost position that moves the term on: the
    # kernel's own output stays within the range, and the range itself is kept exactly
    z = _arrays()
    lim = (z.p_lat[IPAR.U_MIN], z.p_lat[IPAR.U_MAX])
    d = 0.0
    for k in range(400):
        kappa = 0.2 if k < 300 else 0.1 + 0.001 * k  # the term moves on over the NaN below
        d = _kernel_step(z, vx=V, e_y=math.nan if k >= 300 else 0.0, kappa=kappa, applied=d)
        assert -ACT.max_steer <= d <= ACT.max_steer, (k, d)
    assert d == ACT.max_steer
    assert (z.p_lat[IPAR.U_MIN], z.p_lat[IPAR.U_MAX]) == lim
    # a finite but absurd speed does not take the range with it
    _kernel_step(z, vx=1e10, e_y=0.0, kappa=0.01, applied=d)
    assert (z.p_lat[IPAR.U_MIN], z.p_lat[IPAR.U_MAX]) == lim


def test_the_start_steer_is_held_before_a_first_finite_deviation():
    # no finite e_y yet on a curve that tightens: the start's steer (a term one period late
    # would add 0.018 rad a step here, up to the steer's range), and so on while the window
    # then fills
    steer0 = 0.05
    z = _arrays(steer0)
    out = [_kernel_step(z, vx=30.0, e_y=math.nan, kappa=0.001 * k, applied=steer0)
           for k in range(50)]
    out += [_kernel_step(z, vx=30.0, e_y=0.0, kappa=0.05, applied=steer0) for _ in range(50)]
    assert np.allclose(out, steer0, rtol=0.0, atol=1e-15)  # to rounding: (steer0 - t) + t


def test_below_steer_min_speed_the_steer_applied_last_is_held():
    z = _arrays()
    d = 0.0
    for _ in range(200):  # past the window: the law runs at 20 m/s on a curve
        d = _kernel_step(z, vx=V, e_y=0.001, kappa=0.005, applied=d)
    assert d != 0.0
    # slower than steer_min_speed (1 m/s), the curvature and the term changing: held
    held = [_kernel_step(z, vx=0.5, e_y=0.001, kappa=0.005 + 0.001 * k, applied=d)
            for k in range(20)]
    assert np.allclose(held, d, rtol=0.0, atol=1e-15)


def test_reset_starts_the_term_again():
    z = _arrays()

    def run():
        d, out = 0.0, []
        for k in range(300):
            d = _kernel_step(z, vx=V, e_y=0.001 * math.sin(0.01 * k), kappa=_kappa(k), applied=d)
            out.append(d)
        return out

    first = run()
    assert z.coef[_CURV_FF] != 0.0
    z.reset()
    assert run() == first


def test_the_term_needs_the_applied_steer():
    with pytest.raises(ValueError, match="curvature_term.*feed_applied"):
        MfcNaturalSettings(curvature_term=True, feed_applied=False)
    with pytest.raises(ValueError, match="curvature_term"):
        MfcNaturalSettings(curvature_term=1)
