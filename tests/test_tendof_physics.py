"""10DoF validation model against reference values: closed forms, the 3DoF model, CommonRoad MB.

Each test states its reference, what differs between the model and the reference, and the
tolerance with its justification.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from flatfree.models.bicycle3dof import Bicycle3DoFParams
from flatfree.models.bicycle3dof import simulate as simulate_3dof
from flatfree.models.tendof import MP, TenDoF, TenDoFState, Wheel
from flatfree.tires import cornering_stiffness, fy0
from flatfree.units import G
from flatfree.vehicles import load_vehicle

S = TenDoFState


def _planar(name: str):
    """The preset without drag, rolling resistance and aero lift: the bicycle formulas and
    CommonRoad MB have none of them."""
    return dataclasses.replace(load_vehicle(name), drag_area=0.0, rolling_resistance=0.0,
                               lift_area_front=0.0, lift_area_rear=0.0)


def _axle_stiffness(vp) -> tuple[float, float]:
    """Per-axle cornering stiffness at static load [N/rad] (flatfree.tires, VM 2.5)."""
    fzf, fzr = vp.static_axle_loads
    return (2.0 * cornering_stiffness(vp.tire_front, 0.5 * fzf),
            2.0 * cornering_stiffness(vp.tire_rear, 0.5 * fzr))


# --------------------------------------------------------------------------------------------
# Steady-state cornering (VEHICLE_MODEL.md 5.5)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "speed"), [("peugeot406", 20.0), ("peugeot406", 30.0),
                                             ("bmw320i", 20.0)])
def test_steady_cornering_matches_the_understeer_formula(name, speed):
    """r = vx delta / (L + K_us vx^2) within 3 % at a_y = 1 m/s^2 (issue 2 criterion).

    K_us = (m/L)(l_r/C_f - l_f/C_r) with the tyres' cornering stiffness at static load
    (Rajamani Ch. 3; 406: 1.08e-3 rad/(m/s^2), bmw320i: 0 since its C is proportional to load).
    The 10DoF differs by the Magic Formula's curvature (secant 0.1 % below the tangent at
    alpha ~ 0.005 rad), lateral load transfer on the load-degressive 406 tyre (-0.3 %),
    roll and a slow speed loss from cornering drag: measured 0.0-0.3 %. Also the steady
    sideslip beta = l_r/R - m l_f vx^2 / (L C_r R) (VM 5.5) within 3 % of |beta| + 1e-4 rad.
    """
    vp = _planar(name)
    m = TenDoF(vp)
    cf, cr = _axle_stiffness(vp)
    wb = vp.wheelbase
    k_us = vp.mass / wb * (vp.lr / cf - vp.lf / cr)
    delta = 1.0 * (wb + k_us * speed**2) / speed**2  # a_y = 1 m/s^2 by the formula
    u = m.inputs(0.0, delta, n=5000)
    x = m.simulate(m.initial_state(speed), u)[-1]
    vx, r = x[S.vx], x[S.r]
    assert 0.9 < m.diagnostics(x, u[-1])["ay"] < 1.1
    assert r == pytest.approx(vx * delta / (wb + k_us * vx**2), rel=0.03)
    radius = vx / r
    beta_ref = vp.lr / radius - vp.mass * vp.lf * vx**2 / (wb * cr * radius)
    beta = math.atan2(x[S.vy], vx)
    assert abs(beta - beta_ref) <= 0.03 * abs(beta_ref) + 1e-4


@pytest.mark.parametrize("name", ["peugeot406", "dallara_av21"])
def test_steady_roll_and_lateral_load_transfer(name):
    """Steady roll and per-axle lateral load transfer follow the quasi-static closed forms.

    References (VEHICLE_MODEL.md 1.4, 1.5, 5.3-5.4): K_phi phi = m_s h' (a_y + g sin phi),
    and per axle (F_z,right - F_z,left)/2 = [K_phi,i phi + m_s (share_i) a_y h_rc,i
    + m_u,i a_y R_e] / T_i, with K_phi,i = k_i T_i^2/2 + K_arb,i, share_f = l_r/L. The
    dallara_av21 has roll centres at 0.2 m, so the link (geometric) transfer is checked too.
    After 4 s at constant steer the roll mode (2-4 Hz, damped) has settled; what is left is
    the slow speed loss. Measured: roll 2.8e-4 (406) and 2.9e-5 (Dallara), axle transfers
    2.6e-4 / 2.7e-4 and 1.3e-5 / 2.1e-5; tolerance 1e-3, below the smallest term it checks
    (the unsprung masses' m_u,i a_y R_e / T_i, 4 % of the 406's transfer).
    """
    vp = _planar(name)
    m = TenDoF(vp)
    p = m.params
    u = m.inputs(0.0, 0.02, n=4000)
    x = m.simulate(m.initial_state(20.0), u)[-1]
    d = m.diagnostics(x, u[-1])
    ay, phi = d["ay"], x[S.roll]
    assert ay > 2.0
    k_f = vp.spring_front * vp.track_front**2 / 2 + vp.arb_front
    k_r = vp.spring_rear * vp.track_rear**2 / 2 + vp.arb_rear
    m_s, h_roll = vp.sprung_mass, p[MP.h_roll]
    assert (k_f + k_r) * phi == pytest.approx(m_s * h_roll * (ay + G * math.sin(phi)), rel=1e-3)
    m_ua = 0.5 * (vp.mass - vp.sprung_mass)
    fz = d["fz"]
    for (left, right), k_i, share, h_rc, track in (
        ((Wheel.fl, Wheel.fr), k_f, vp.lr / vp.wheelbase, vp.roll_center_height_front,
         vp.track_front),
        ((Wheel.rl, Wheel.rr), k_r, vp.lf / vp.wheelbase, vp.roll_center_height_rear,
         vp.track_rear),
    ):
        ref = (k_i * phi + m_s * share * ay * h_rc + m_ua * ay * vp.wheel_radius) / track
        assert 0.5 * (fz[right] - fz[left]) == pytest.approx(ref, rel=1e-3)


# --------------------------------------------------------------------------------------------
# 3DoF and 10DoF in the linear range
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["peugeot406", "bmw320i"])
def test_3dof_and_10dof_agree_on_a_step_steer(name):
    """Step steer at 20 m/s to a_y ~ 3 m/s^2: yaw rate within 5 %, sideslip within 2 mrad,
    speed within 2 %, at every instant of 3 s.

    Both models share m, I_z, l_f, l_r, R_e, the wheel inertias and the tyres' cornering
    stiffness at static load (Bicycle3DoFParams.from_vehicle); drag and rolling resistance
    are off, no torque (the 3DoF with its rolling closure). What differs, and its size here:
    (i) the 10DoF's Magic Formula is below its tangent at the operating slip angles
    (alpha ~ 0.014-0.028 rad): computed below from flatfree.tires as 1-4 %; since K_us v^2
    << L at 20 m/s a uniform stiffness loss changes r by much less than that (and beta
    by about that fraction of alpha_r, < 1.2 mrad); (ii) lateral load transfer on the
    load-degressive 406 tyre (-1 to -2 % front axle); (iii) roll, pitch, suspension, relaxed
    tyre slip and wheel spin transients; (iv) cornering drag slows the 10DoF (~1 %). Each is a
    few per cent at most, hence 5 % on r, 2 mrad on beta and 2 % on vx.
    """
    vp = _planar(name)
    m = TenDoF(vp)
    b = Bicycle3DoFParams.from_vehicle(vp)
    v0, n = 20.0, 3000
    delta = 3.0 * (b.wheelbase + b.understeer_gradient * v0**2) / v0**2
    xs = m.simulate(m.initial_state(v0), m.inputs(0.0, delta, n=n))
    x3 = simulate_3dof(b, np.array([0.0, 0.0, 0.0, v0, 0.0, 0.0]), np.tile([0.0, delta], (n, 1)),
                       1e-3, rolling=True)
    r10, r3 = xs[:, S.r], x3[:, 5]
    assert 2.5 < r3[-1] * v0 < 3.5
    # the justification of (i): MF secant over tangent at the final slip angles
    d = m.diagnostics(xs[-1], m.inputs(0.0, delta))
    fzf, fzr = vp.static_axle_loads
    for tire, fz, alpha in ((vp.tire_front, 0.5 * fzf, d["alpha"][0]),
                            (vp.tire_rear, 0.5 * fzr, d["alpha"][2])):
        secant = -fy0(alpha, fz, tire) / (cornering_stiffness(tire, fz) * alpha)
        assert 0.95 < secant < 1.0
    assert np.max(np.abs(r10 - r3)) <= 0.05 * abs(r3[-1])
    beta10 = np.arctan2(xs[:, S.vy], xs[:, S.vx])
    beta3 = np.arctan2(x3[:, 4], x3[:, 3])
    assert np.max(np.abs(beta10 - beta3)) <= 2e-3
    np.testing.assert_allclose(xs[:, S.vx], x3[:, 3], rtol=0.02)


# --------------------------------------------------------------------------------------------
# CommonRoad multi-body model (peer)
# --------------------------------------------------------------------------------------------
def test_cross_validation_with_commonroad_mb():
    """bmw320i vs CommonRoad MB (parameter set 2): step steer at 20 m/s to ~3 m/s^2.

    Both start at 20 m/s straight, steer ramps at MB's 0.4 rad/s rate limit to 0.0193 rad and is
    held, no drive or brake; RK4 at 1 ms for 3 s. Steady yaw rate and lateral acceleration
    agree within 3 % (measured: flatfree 1.73 % and 1.79 % below MB; the issue 2 criterion is
    10 %). The difference is the deterministic model difference listed below, not noise, so
    3 % is a regression bound of it.

    Axes: MB uses SAE z-down axes, but its planar states (vx, vy, yaw rate) mirror an ISO
    model's one to one (VEHICLE_MODEL.md section 0), so r and a_y compare directly.

    What differs: MB has unsprung masses with their own roll, heave and lateral DoF, a
    vertical tyre spring (K_zt), a compliant roll-axis joint, camber from roll and suspension
    travel, and evaluates its tyre with the raw CommonRoad coefficients (S_Hy, S_Vy switched by
    sgn(camber), S_Vx inside the sine, pure-slip F_x0/F_y0 from separate calls) while flatfree
    uses the symmetrised set; MB has no drag or rolling resistance (switched off here),
    no tyre relaxation, a sprung-mass CoG height h_s = 0.614 m (flatfree derives 0.605 m from
    m h = m_s h_s + m_u R_e), and g = 9.81 instead of 9.80665. MB steers with a rate input.
    """
    from vehiclemodels.init_mb import init_mb
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
    from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

    p = parameters_vehicle2()
    v0, target, rate, dt, n = 20.0, 0.0193, 0.4, 1e-3, 3000

    def f(x: np.ndarray, u: list[float]) -> np.ndarray:
        return np.array(vehicle_dynamics_mb(list(x), u, p))  # MB clamps a copy in place

    x = np.array(init_mb([0.0, 0.0, 0.0, v0, 0.0, 0.0, 0.0], p))
    for _ in range(n):
        sr = min(rate, (target - x[2]) / dt) if x[2] < target else 0.0
        u = [sr, 0.0]
        k1 = f(x, u)
        k2 = f(x + 0.5 * dt * k1, u)
        k3 = f(x + 0.5 * dt * k2, u)
        k4 = f(x + dt * k3, u)
        x = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    fx = f(x, [0.0, 0.0])
    r_mb = x[5]
    ay_mb = fx[10] + x[5] * x[3]  # v_y' + r v_x

    m = TenDoF(_planar("bmw320i"))
    delta = np.minimum(rate * dt * (np.arange(n) + 0.5), target)  # MB's ramp, mid-step
    xs = m.simulate(m.initial_state(v0), m.inputs(0.0, delta))
    ay = m.diagnostics(xs[-1], m.inputs(0.0, target))["ay"]
    assert 2.5 < ay_mb < 3.5
    assert xs[-1, S.r] == pytest.approx(r_mb, rel=0.03)
    assert ay == pytest.approx(ay_mb, rel=0.03)


# --------------------------------------------------------------------------------------------
# Coast-down (VEHICLE_MODEL.md 5.6)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["peugeot406", "dallara_av21"])
def test_coast_down_follows_drag_and_rolling_resistance(name):
    """From 30 m/s without torque: v(t) and the stopping distance of the closed form.

    m_eff v' = -F_0 - C v^2, F_0 = f_r m g, C = 1/2 rho C_d A (+ f_r 1/2 rho |C_L| A with
    downforce, the dallara_av21), m_eff = m + sum I_w / R_e^2 (VEHICLE_MODEL.md 5.6):
    v(t) = sqrt(F_0/C) tan(atan(v0 sqrt(C/F_0)) - t sqrt(F_0 C)/m_eff),
    s_stop = m_eff/(2C) ln(1 + C v0^2/F_0). Measured: v within 4.1e-5 (406) and 1.2e-4
    (Dallara) of v(t) while v >= 2 m/s, s_stop within 1.7e-5 and 2.1e-5 (below about 0.1 m/s
    the smooth sign of the rolling resistance, 0.1 rad/s wide, lengthens the last
    centimetres). Tolerance 1e-3 on both (the issue 2 criterion is 2 %): dropping the
    Dallara's f_r 1/2 rho |C_L| A term from C moves v by 11 % and s_stop by -1.9 %. At rest
    2 s after t_stop: |vx| < 1 cm/s.
    """
    vp = load_vehicle(name)
    m = TenDoF(vp)
    v0, dt = 30.0, 1e-3
    f0 = vp.rolling_resistance * vp.mass * G
    c = 0.5 * vp.air_density * (vp.drag_area + vp.rolling_resistance
                                * abs(vp.lift_area_front + vp.lift_area_rear))
    meff = vp.mass + 2.0 * (vp.wheel_inertia_front + vp.wheel_inertia_rear) / vp.wheel_radius**2
    phi0 = math.atan(v0 * math.sqrt(c / f0))
    t_stop = meff / math.sqrt(f0 * c) * phi0
    n = int(t_stop / dt) + 3000
    xs = m.simulate(m.initial_state(v0), m.inputs(0.0, 0.0, n=n), dt)
    t = np.arange(n + 1) * dt
    v_ref = math.sqrt(f0 / c) * np.tan(np.maximum(phi0 - t * math.sqrt(f0 * c) / meff, 0.0))
    keep = v_ref >= 2.0
    np.testing.assert_allclose(xs[keep, S.vx], v_ref[keep], rtol=1e-3)
    assert np.max(np.abs(xs[-1000:, S.vx])) < 0.01  # at rest 2 s after t_stop
    s_stop = meff / (2.0 * c) * math.log(1.0 + c * v0**2 / f0)
    assert xs[-1, S.x] == pytest.approx(s_stop, rel=1e-3)


# --------------------------------------------------------------------------------------------
# Braking in a turn: load transfer and effective cornering stiffness (paper Figure 3)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["peugeot406", "bmw320i"])
def test_braking_in_a_turn_moves_load_and_cornering_stiffness_to_the_front(name):
    """Steady turn at 25 m/s (a_y ~ 2 m/s^2), then braking at ~3 m/s^2 for 4 s, steer held.

    Load (reference: the quasi-static pitch balance, VEHICLE_MODEL.md 1.4-1.5 and 5.2,
    including the sprung mass's gravity moment at the pitch angle):
    dF_z,front = (-m a_x h - F_D h_a + m_s g h_s sin theta) / L, and the rear loses as much;
    the model's pitch and heave equations give exactly this once theta'' = z'' = 0 and the
    filtered a_x equals a_x. Checked after 4 s of braking: the brake step excites the pitch
    mode (406: 1.25 Hz, zeta ~ 0.29), whose residual after 2 s is still 1.2 % of the transfer
    on the 406 (0.2 % on the bmw320i) -- that oscillation, not a missing term, was why the full
    reference looked off by 1.2 % there (and, for the bmw320i, why the bare -m a_x h / L looked
    better: its drag and gravity terms, -29.5 N and +27.7 N, nearly cancel at 18.7 m/s). After
    4 s, measured: 1.1e-4 / 4.5e-5 (406 front / rear), 5e-6 (bmw320i). Tolerance 1e-3, while
    the drag and gravity terms are each > 1 % of the transfer (asserted): dropping either, or
    both (bare reference: 2.7 % / 1.9 % off), fails.

    Effective axle cornering stiffness C = -(F_y,l + F_y,r) / mean(alpha) (the paper's
    Figure 3), before braking and after 2 s of it: the front rises and the rear falls. Its
    relative change must equal the change of sum_j C_alpha(F_z,j)
    (flatfree.tires.cornering_stiffness at the measured wheel loads: the tyre's load
    sensitivity) within 2.5 percentage points, which bounds what that prediction
    leaves out: combined slip at the braking slips |kappa| <= 0.025 lowers F_y by at most
    1 - cos(r_Cy1 atan(r_By1 0.025)) <= 1.5 % (406: r_Cy1 1.081, r_By1 6.461), and the Magic
    Formula's secant, 1 - F_y/(C_alpha alpha) ~ (1/3 + C^2/6)(B alpha)^2 <= 2.4 % at
    B alpha <= 0.2 (alpha <= 0.02 rad), changes by about 1 point between the two slip-angle
    levels. (At a_y ~ 4 m/s^2 the secant term alone reaches 2.5 points for the bmw320i: the
    test keeps a_y moderate so that the load sensitivity is what it measures.)
    """
    vp = load_vehicle(name)
    m = TenDoF(vp)
    n1, n2 = 3000, 2000
    delta = 0.012 if name == "peugeot406" else 0.009
    n3 = 2000  # braking continues to 4 s for the load-transfer check
    tb = -vp.mass * 3.0 * vp.wheel_radius
    # cruise torque for 25 m/s: drag and rolling resistance
    cruise = vp.wheel_radius * (0.5 * vp.air_density * vp.drag_area * 25.0**2
                                + vp.rolling_resistance * vp.mass * G)
    tw = np.r_[np.full(n1, cruise), np.full(n2 + n3, tb)]
    u = m.inputs(tw, delta)
    xs = m.simulate(m.initial_state(25.0), u)
    d = m.diagnostics(xs[1:], u)
    kb, ka = n1 - 1, n1 + n2 - 1  # just before braking, after 2 s of braking
    kl = n1 + n2 + n3 - 1  # after 4 s of braking
    assert d["ay"][kb] > 1.8 and d["ax"][ka] < -2.5 and xs[ka + 1, S.vx] > 15.0
    assert d["ax"][kl] < -2.5 and xs[kl + 1, S.vx] > 10.0

    # load transfer
    x = xs[kl + 1]
    fd = 0.5 * vp.air_density * vp.drag_area * x[S.vx] ** 2
    theta = x[S.pitch]
    inertia = -vp.mass * d["ax"][kl] * vp.cog_height / vp.wheelbase
    drag = -fd * vp.drag_height / vp.wheelbase
    gravity = vp.sprung_mass * G * m.params[MP.h_s] * math.sin(theta) / vp.wheelbase
    ref = inertia + drag + gravity
    assert abs(drag) > 0.01 * ref and abs(gravity) > 0.01 * ref  # the check sees both terms
    front = d["fz"][kl][:2].sum() - vp.static_axle_loads[0]
    rear = d["fz"][kl][2:].sum() - vp.static_axle_loads[1]
    assert front == pytest.approx(ref, rel=1e-3)
    assert rear == pytest.approx(-ref, rel=1e-3)

    def stiffness(k: int, wheels: slice) -> float:
        return float(-np.sum(d["fy"][k][wheels]) / np.mean(d["alpha"][k][wheels]))

    def predicted(k: int, wheels: slice, tire) -> float:
        return sum(cornering_stiffness(tire, fz) for fz in d["fz"][k][wheels])

    for wheels, tire, sign in ((slice(0, 2), vp.tire_front, 1.0),
                               (slice(2, 4), vp.tire_rear, -1.0)):
        change = stiffness(ka, wheels) / stiffness(kb, wheels) - 1.0
        change_ref = predicted(ka, wheels, tire) / predicted(kb, wheels, tire) - 1.0
        assert sign * change > 0.04  # front up, rear down, by several per cent
        assert change == pytest.approx(change_ref, abs=0.025)


@pytest.mark.parametrize("name", ["peugeot406", "dallara_av21"])
def test_drive_speed_is_the_driven_wheels_speed_in_their_torque_shares(name):
    """The drive torque's power is tw sum_i s_i Omega_i with the shares of rhs_kernel's open
    differentials; drive_speed is R_e sum_i s_i Omega_i: only the driven axle counts, one
    spinning wheel adds half its spin."""
    from flatfree.models.tendof import drive_speed

    vp = load_vehicle(name)
    m = TenDoF(vp)
    x = np.zeros(len(TenDoFState))
    x[TenDoFState.vx] = 20.0
    re = vp.wheel_radius
    omegas = np.array([20.0, 20.0, 20.0, 20.0]) / re
    driven = [Wheel.fl, Wheel.fr] if vp.drive == "front" else [Wheel.rl, Wheel.rr]
    other = [Wheel.rl, Wheel.rr] if vp.drive == "front" else [Wheel.fl, Wheel.fr]
    omegas[driven[0]] = 60.0 / re  # one driven wheel spinning at 3x the road speed
    omegas[other[1]] = 5.0 / re  # a locked-ish undriven wheel does not count
    x[TenDoFState.omega_fl:TenDoFState.omega_fl + 4] = omegas
    assert drive_speed(x, m.params) == pytest.approx(0.5 * (60.0 + 20.0), rel=1e-15)


def test_a_banked_turn_at_its_neutral_speed_needs_no_lateral_tyre_force():
    """On a road banked by b the model's gravity has the in-plane part -g sin b along body y
    (Model, item 7): a left-hand turn of in-plane curvature kappa driven at v with
    v^2 kappa = g sin |b| (b < 0: the right side up) is held by gravity alone, so the car turns
    with the kinematic steer L kappa at zero slip angles and a steady yaw rate v kappa. The same
    inputs on a flat road need ~1 deg of slip angle. (With kappa the in-plane curvature of a
    horizontal circle, cos b / R, this is the classical v^2 / R = g tan b.)"""
    vp = load_vehicle("peugeot406")
    m = TenDoF(vp)
    v, kappa = 20.0, 0.01
    bank = -math.asin(v * v * kappa / G)  # -24.1 deg
    r = v * kappa
    x0 = m.initial_state(v, vy=vp.lr * r, r=r)  # kinematic turn: no rear slip angle
    # the road's tangent is the CoG's course, at the sideslip atan(lr kappa) from the heading
    e_road = -math.atan(vp.lr * kappa)
    n = 4000  # 4 s at 1 ms
    # the resistance of the road (rolling on the normal load, drag) as drive torque
    tw = vp.wheel_radius * (vp.rolling_resistance * vp.mass * G * math.cos(bank)
                            + 0.5 * vp.air_density * vp.drag_area * v * v)
    u_bank = m.inputs(tw, vp.wheelbase * kappa, bank=bank, e_psi_road=e_road)
    banked = m.simulate(x0, np.tile(u_bank, (n, 1)))
    flat = m.simulate(x0, m.inputs(tw, vp.wheelbase * kappa, n=n))
    end_b = m.diagnostics(banked[-1], u_bank)
    end_f = m.diagnostics(flat[-1], m.inputs(tw, vp.wheelbase * kappa))
    assert np.max(np.abs(end_f["alpha"])) > math.radians(0.5)
    assert np.max(np.abs(end_b["alpha"])) < 0.05 * np.max(np.abs(end_f["alpha"]))
    assert abs(np.sum(end_b["fy"])) < 0.01 * vp.mass * v * v * kappa
    # gravity across the road does no work: the speed holds on the resistance's torque
    assert math.hypot(banked[-1, TenDoFState.vx], banked[-1, TenDoFState.vy]) == pytest.approx(
        v, rel=2e-3)
    assert banked[-1, TenDoFState.r] == pytest.approx(r, rel=0.01)
    # the wheels carry the normal part of the weight only (static loads and transfers)
    assert np.sum(end_b["fz"]) == pytest.approx(vp.mass * G * math.cos(bank), rel=0.01)


def test_on_a_bank_a_car_without_steer_drifts_down_the_slope():
    """Sign convention: bank > 0 raises the left side (like the roll phi), so a car going
    straight with no steer drifts to the right (vy < 0, y falling while heading along +x)
    and rolls towards the low side is held by its tyres, which push up the slope (F_y > 0)."""
    vp = load_vehicle("peugeot406")
    m = TenDoF(vp)
    xs = m.simulate(m.initial_state(20.0), m.inputs(300.0, 0.0, bank=math.radians(10.0), n=1000))
    assert xs[-1, TenDoFState.vy] < -0.05 and xs[-1, TenDoFState.y] < -0.05
    d = m.diagnostics(xs[-1], m.inputs(300.0, 0.0, bank=math.radians(10.0)))
    assert np.sum(d["fy"]) > 0.0
    # the low (right) side carries more load
    assert d["fz"][Wheel.fr] + d["fz"][Wheel.rr] > d["fz"][Wheel.fl] + d["fz"][Wheel.rl]
