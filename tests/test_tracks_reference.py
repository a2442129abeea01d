"""Reference signals, 3DoF reference states (sympy, closed forms), recording, maneuvers."""

from __future__ import annotations

import itertools
import math
import re

import numpy as np
import pytest
import sympy as sp

import flatfree.tracks as T

# A road car like the paper's (values of the order of the Peugeot 406 estimate; any positive
# set works, the tests compare against formulas, not against these numbers).
CAR = dict(cf=80_000.0, cr=70_000.0, mass=1_500.0, iz=2_500.0, lf=1.1, lr=1.6)


# ---------------------------------------------------------------------------------------------
# reference signals
# ---------------------------------------------------------------------------------------------
def test_circle_reference_closed_form():
    ref = T.circle_reference(40.0, 12.0, laps=2, dt=0.05)
    # geometry error of the fitted circle is < 1e-8 m (test_exact_circle_is_near_machine_precision)
    np.testing.assert_allclose(np.hypot(ref["x"], ref["y"] - 40.0), 40.0, atol=1e-7)
    np.testing.assert_allclose(ref["vx"], 12.0)
    np.testing.assert_allclose(ref["r"], 12.0 / 40.0, rtol=1e-8)
    np.testing.assert_allclose(ref["r_dot"], 0.0, atol=1e-8)
    np.testing.assert_allclose(ref["psi"], 12.0 / 40.0 * ref.t, atol=1e-7)  # unwrapped over laps
    np.testing.assert_allclose(ref["s"], 12.0 * ref.t, atol=1e-9)
    assert ref.duration == pytest.approx(2 * 2 * math.pi * 40.0 / 12.0, abs=0.05)


def test_reference_from_a_speed_profile_is_exact_in_time():
    """On a straight from standstill: s = a t^2 / 2, Vx = a t (exact per segment)."""
    trk = T.straight_track(100.0)
    ref = T.make_reference(trk, T.SpeedLimits(v_max=100.0), v_start=0.0, dt=0.1)
    t = ref.t
    acc = t <= math.sqrt(2 * 100.0 / 3.0) * 0.5  # well inside the accelerating part
    np.testing.assert_allclose(ref["s"][acc], 1.5 * t[acc] ** 2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ref["vx"][acc], 3.0 * t[acc], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ref["ax"][acc], 3.0, rtol=1e-9)


def _slalom(amp=1.5, wavelength=60.0):
    """y = A sin(k x), a smooth (analytic) open path, exact points every 0.25 m."""
    x = np.linspace(0.0, 300.0, 1201)
    return T.Track.from_points(x, amp * np.sin(2 * math.pi * x / wavelength),
                               smoothing_length=0.0, name="slalom")


def test_yaw_rate_derivative_is_consistent_on_a_smooth_reference():
    """Constant speed V on the slalom: r = V kappa(s(t)). The central difference of r differs
    from r_dot by at most dt^2/6 max|r'''| = dt^2/6 V^4 max|kappa'''(s)|; for y = A sin(kx)
    with slope A k = 0.16, |kappa'''| <= 1.5 A k^5 (leading term A k^5 plus the slope
    correction)."""
    amp, k, v, dt = 1.5, 2 * math.pi / 60.0, 15.0, 0.01
    ref = T.make_reference(_slalom(), v, dt=dt)
    fd = np.gradient(ref["r"], ref.t)
    bound = dt**2 / 6 * v**4 * 1.5 * amp * k**5
    np.testing.assert_allclose(fd[1:-1], ref["r_dot"][1:-1], atol=bound)
    assert np.abs(ref["r_dot"]).max() > 1000 * bound  # not trivially small


def test_sample_reference_kernel_matches_numpy_interp():
    ref = T.make_reference(T.load_track("IMS"), dt=0.02)
    rng = np.random.default_rng(5)
    out = np.empty(ref.table.shape[1])
    for t in rng.uniform(-1.0, ref.duration + 1.0, 50):
        T.sample_reference(ref.table, t, out)
        expect = [np.interp(t, ref.t, ref.table[:, j]) for j in range(ref.table.shape[1])]
        np.testing.assert_allclose(out, expect, rtol=1e-12, atol=1e-12)
    assert ref.at([1.0])["vx"][0] == pytest.approx(np.interp(1.0, ref.t, ref["vx"]))


def test_laps_repeat_the_periodic_profile():
    trk = T.load_track("Norisring")
    two = T.make_reference(trk, dt=0.05, laps=2)
    prof = two.profile
    lap = prof.duration
    second = two.t > lap
    s, v, _a = prof.state_at_time(two.t[second] - lap)  # exact one-lap profile
    np.testing.assert_allclose(two["vx"][second], v, rtol=1e-12)
    np.testing.assert_allclose(two["s"][second], s + trk.length, rtol=1e-12)
    geo = trk.at(s)
    np.testing.assert_allclose(two["psi"][second],
                               geo["psi"] + 2 * math.pi * trk.turning_number, atol=1e-9)
    assert np.all(np.diff(two["s"]) > 0)
    assert two.duration == pytest.approx(2 * lap, abs=0.05)


def test_constant_lateral_offset_on_a_circle():
    """The line 3 m inside a circle of radius 50 m is the circle of radius 47 m."""
    ref = T.make_reference(T.circle_track(50.0), 10.0, lateral_offset=3.0, dt=0.05)
    np.testing.assert_allclose(np.hypot(ref["x"], ref["y"] - 50.0), 47.0, atol=1e-7)
    np.testing.assert_allclose(ref["kappa"], 1 / 47.0, rtol=1e-7)
    np.testing.assert_allclose(ref["e_y_ref"], 3.0)
    np.testing.assert_allclose(ref["e_y_ref_dot"], 0.0)
    np.testing.assert_allclose(ref["s_path"], ref["s"] * 50.0 / 47.0, atol=1e-6)


def test_variable_lateral_offset_derivatives_on_a_straight():
    """d(s) = A sin(w s) from a straight path. The driven line has ds_line = sqrt(1 + d1^2) ds_p
    (d1 = dd/ds), so at constant speed V: q := s_p_dot = V / sqrt(1 + d1^2),
    q_dot = -V d1 d2 q / (1 + d1^2)^(3/2), e_dot = d1 q, e_ddot = d2 q^2 + d1 q_dot.
    Tolerances: a function d(s) is sampled at the path nodes (h = 1 m) and interpolated by a
    cubic spline, whose errors are <= 5/384 h^4 M, h^3 M / 24 and 3/8 h^2 M for the value, first
    and second derivative, M = max|d4| = A w^4 (Hall & Meyer, J. Approx. Theory 16, 1976);
    times q ~ V and q^2 ~ V^2."""
    amp, w, v = 0.6, 2 * math.pi / 80.0, 15.0
    ref = T.make_reference(T.straight_track(400.0), v, dt=0.02,
                           lateral_offset=lambda s: amp * np.sin(w * s))
    sp_ = ref["s_path"]
    d1 = amp * w * np.cos(w * sp_)
    d2 = -amp * w**2 * np.sin(w * sp_)
    q = v / np.sqrt(1 + d1**2)
    qdot = -v * d1 * d2 * q / (1 + d1**2) ** 1.5
    m4 = amp * w**4
    inner = slice(100, -100)  # away from the open ends of the spline
    np.testing.assert_allclose(ref["e_y_ref"][inner], amp * np.sin(w * sp_[inner]),
                               atol=5 / 384 * m4 + 1e-9)
    np.testing.assert_allclose(ref["e_y_ref_dot"][inner], (d1 * q)[inner], atol=v * m4 / 24)
    np.testing.assert_allclose(ref["e_y_ref_ddot"][inner], (d2 * q**2 + d1 * qdot)[inner],
                               atol=3 / 8 * v**2 * m4)
    np.testing.assert_allclose(ref["y"][inner], ref["e_y_ref"][inner], atol=5 / 384 * m4 + 1e-9)


# ---------------------------------------------------------------------------------------------
# 3DoF reference states
# ---------------------------------------------------------------------------------------------
def _paper_model():
    """The paper's 3DoF lateral equations (f + g u, Section 2.1) with I_r = 0, in sympy."""
    vx, vy, r, delta, cf, cr, m, iz, lf, lr = sp.symbols("vx vy r delta cf cr m iz lf lr",
                                                         real=True)
    alpha_f = (vy + lf * r) / vx
    alpha_r = (vy - lr * r) / vx
    vy_dot = -r * vx + (-cf * alpha_f - cr * alpha_r) / m + cf / m * delta
    r_dot = (-lf * cf * alpha_f + lr * cr * alpha_r) / iz + lf * cf / iz * delta
    return (vx, vy, r, delta, cf, cr, m, iz, lf, lr), vy_dot, r_dot


def test_steady_states_match_a_sympy_solution_of_the_paper_model():
    syms, vy_dot, r_dot = _paper_model()
    vx, vy, r, delta, cf, cr, m, iz, lf, lr = syms
    rd = sp.Symbol("rd", real=True)
    sol = sp.solve([sp.Eq(vy_dot, 0), sp.Eq(r_dot, rd)], [vy, delta], dict=True)[0]
    f_vy = sp.lambdify((vx, r, rd, cf, cr, m, iz, lf, lr), sol[vy])
    f_delta = sp.lambdify((vx, r, rd, cf, cr, m, iz, lf, lr), sol[delta])
    ref = T.make_reference(T.load_track("Norisring"), dt=0.05)
    lat = T.reference_states_3dof(ref, method="steady", **CAR)
    args = (ref["vx"], ref["r"], ref["r_dot"], CAR["cf"], CAR["cr"], CAR["mass"], CAR["iz"],
            CAR["lf"], CAR["lr"])
    np.testing.assert_allclose(lat.vy, f_vy(*args), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(lat.delta, f_delta(*args), rtol=1e-9, atol=1e-12)


def test_dynamic_states_satisfy_the_paper_model_and_notes_y2_dot():
    syms, vy_dot, r_dot = _paper_model()
    f = sp.lambdify(syms, [vy_dot, r_dot])
    ref = T.make_reference(T.load_track("Norisring"), dt=0.02)
    lat = T.reference_states_3dof(ref, **CAR)
    c = CAR
    vy_dot_m, r_dot_m = f(lat.vx, lat.vy, lat.r, lat.delta, c["cf"], c["cr"], c["mass"], c["iz"],
                          c["lf"], c["lr"])
    # algebraic identities: only rounding (values ~1 m/s^2, rad/s^2)
    np.testing.assert_allclose(vy_dot_m, lat.vy_dot, atol=1e-9)
    np.testing.assert_allclose(r_dot_m, lat.r_dot, atol=1e-9)
    # NOTES.md: y2_dot = -Lf m Vx r - Cr (Lf+Lr) (Vy - Lr r) / Vx
    notes = (-c["lf"] * c["mass"] * lat.vx * lat.r
             - c["cr"] * (c["lf"] + c["lr"]) * (lat.vy - c["lr"] * lat.r) / lat.vx)
    np.testing.assert_allclose(lat.y2_dot, notes, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(lat.y2, c["lf"] * c["mass"] * lat.vy - c["iz"] * lat.r)
    # the integrated Vy's consistency with its derivative: see the slalom test below (a max
    # error here is not informative: a_x, hence vy', jumps every few samples on this profile)


@pytest.mark.parametrize("method", ["dynamic", "path"])
def test_integrated_vy_is_consistent_with_its_derivative_to_second_order(method):
    """Constant speed on the smooth slalom: the central difference of the integrated Vy differs
    from the returned Vy' by O(dt^2), both being second-order approximations of the same
    solution: the max difference (away from the ends) falls by 4 when dt halves (measured
    3.96-4.00; a one-sample lag or an Euler step would leave O(1) or O(dt))."""
    errs = []
    for dt in (0.02, 0.01, 0.005):
        lat = T.reference_states_3dof(T.make_reference(_slalom(), 15.0, dt=dt), method=method,
                                      **CAR)
        n = lat.t.size
        inner = slice(n // 10, n - n // 10)
        errs.append(np.abs(np.gradient(lat.vy, lat.t) - lat.vy_dot)[inner].max())
        assert errs[-1] < 1e-2 * np.abs(lat.vy_dot).max()
    for coarse, fine in itertools.pairwise(errs):
        assert 3.5 < coarse / fine < 4.5, errs


def test_constant_cornering_matches_rajamani_closed_forms():
    """Steady circle: beta = lr/R - m lf V^2 / (L Cr R), delta = L/R + K_us V^2/R with
    K_us = (m/L)(lr/Cf - lf/Cr) (VEHICLE_MODEL.md sec. 5.5, [Raj] ch. 3); both methods."""
    radius, v = 60.0, 14.0
    ref = T.circle_reference(radius, v, dt=0.02)
    c = CAR
    big_l = c["lf"] + c["lr"]
    beta = c["lr"] / radius - c["mass"] * c["lf"] * v**2 / (big_l * c["cr"] * radius)
    k_us = c["mass"] / big_l * (c["lr"] / c["cf"] - c["lf"] / c["cr"])
    for method in ("steady", "dynamic"):
        lat = T.reference_states_3dof(ref, method=method, **c)
        # circle geometry: kappa = 1/R within 1e-10 relative
        np.testing.assert_allclose(lat.vy, beta * v, rtol=1e-8)
        np.testing.assert_allclose(lat.delta, big_l / radius + k_us * v**2 / radius, rtol=1e-8)
        np.testing.assert_allclose(lat.y2_dot, 0.0, atol=1e-5)


def test_dynamic_integrator_is_second_order():
    """Constant speed on the smooth slalom: the differences between successive halvings of dt
    shrink by 4 (second order). (A path whose curvature has kinks, such as the C3 lane change,
    converges too but less regularly.)"""
    trk = _slalom()
    dts = [0.04, 0.02, 0.01, 0.005]
    vy = [T.reference_states_3dof(T.make_reference(trk, 15.0, dt=dt), **CAR).vy for dt in dts]
    diffs = [np.abs(a - b[::2][: a.size]).max() for a, b in itertools.pairwise(vy)]
    ratios = [diffs[0] / diffs[1], diffs[1] / diffs[2]]
    assert all(3.8 < q < 4.2 for q in ratios), (diffs, ratios)


def _drive_paper_model(ref, lat):
    """The paper's 3DoF model (pose, Vx, Vy, r; linear tyres) integrated with scipy from the
    reference's start, driven by ``lat``'s steer and longitudinal acceleration (cubic splines);
    returns the CoG's distance across the path from the reference point at each sample."""
    from scipy.integrate import solve_ivp
    from scipy.interpolate import CubicSpline

    c = CAR
    steer = CubicSpline(lat.t, lat.delta)
    accel = CubicSpline(lat.t, lat.ax)

    def rhs(tt, x):
        _, _, psi, vx, vy, r = x
        fyf = c["cf"] * (float(steer(tt)) - (vy + c["lf"] * r) / vx)
        fyr = -c["cr"] * (vy - c["lr"] * r) / vx
        return [vx * math.cos(psi) - vy * math.sin(psi), vx * math.sin(psi) + vy * math.cos(psi),
                r, float(accel(tt)), (fyf + fyr) / c["mass"] - vx * r,
                (c["lf"] * fyf - c["lr"] * fyr) / c["iz"]]

    beta0 = math.atan2(lat.vy[0], lat.vx[0])
    x0 = [ref["x"][0], ref["y"][0], ref["psi"][0] - beta0, lat.vx[0], lat.vy[0], lat.r[0]]
    sol = solve_ivp(rhs, (lat.t[0], lat.t[-1]), x0, t_eval=lat.t, method="DOP853", rtol=1e-11,
                    atol=1e-11)
    assert sol.success
    return np.abs(-(sol.y[0] - ref["x"]) * np.sin(ref["psi"])
                  + (sol.y[1] - ref["y"]) * np.cos(ref["psi"]))


def test_path_states_keep_the_paper_model_on_the_path():
    """method "path": the paper's 3DoF model driven by the returned steer and acceleration keeps
    its CoG on the slalom over 20 s (measured 0.19 mm at dt 0.01; 1 mm asked); with "dynamic"
    (r = V kappa prescribed) the same model ends 1.5 m off, which is what the method fixes."""
    ref = T.make_reference(_slalom(), 15.0, dt=0.01)
    dev_path = _drive_paper_model(ref, T.reference_states_3dof(ref, method="path", **CAR))
    dev_dyn = _drive_paper_model(ref, T.reference_states_3dof(ref, **CAR))
    assert dev_path.max() < 1e-3, dev_path.max()
    assert dev_dyn.max() > 0.5, dev_dyn.max()


def test_path_states_satisfy_the_paper_model_and_the_path_kinematics():
    """On Norisring with braking and acceleration: the paper's lateral equations (sympy) hold
    with the returned steer to rounding, the CoG's speed is the reference's, its course turns
    at V kappa (central differences of beta, O(dt^2)), and y2_dot is NOTES.md's closed form."""
    syms, vy_dot, r_dot = _paper_model()
    f = sp.lambdify(syms, [vy_dot, r_dot])
    ref = T.make_reference(T.load_track("Norisring"), dt=0.01)
    lat = T.reference_states_3dof(ref, method="path", **CAR)
    assert lat.method == "path"
    c = CAR
    vy_dot_m, r_dot_m = f(lat.vx, lat.vy, lat.r, lat.delta, c["cf"], c["cr"], c["mass"], c["iz"],
                          c["lf"], c["lr"])
    np.testing.assert_allclose(vy_dot_m, lat.vy_dot, atol=1e-9)
    np.testing.assert_allclose(r_dot_m, lat.r_dot, atol=1e-9)
    np.testing.assert_allclose(np.hypot(lat.vx, lat.vy), ref["vx"], rtol=1e-13)
    beta = np.arctan2(lat.vy, lat.vx)
    course_rate = lat.r + np.gradient(beta, lat.t)
    v_kappa = ref["vx"] * ref["kappa"]
    # measured 7.5e-5 rad/s against max |V kappa| 0.78
    assert np.abs(course_rate - v_kappa)[1:-1].max() < 1e-3 * np.abs(v_kappa).max()
    notes = (-c["lf"] * c["mass"] * lat.vx * lat.r
             - c["cr"] * (c["lf"] + c["lr"]) * (lat.vy - c["lr"] * lat.r) / lat.vx)
    np.testing.assert_allclose(lat.y2_dot, notes, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(lat.y1, lat.vx)
    # vx and its returned derivative agree: the central difference is the mean of vx' over
    # [t - dt, t + dt], so it lies within the range of ax there up to the sampling of that
    # range (where ax is smooth, fd - ax = dt^2/6 ax'' + ..., i.e. a sixth of ax's second
    # difference); exact where ax is constant
    fd = np.gradient(lat.vx, lat.t)[1:-1]
    win = np.stack([lat.ax[:-2], lat.ax[1:-1], lat.ax[2:]])
    slack = np.abs(np.diff(lat.ax, 2)) / 6.0 * 1.01 + 1e-9
    assert np.all(fd >= win.min(axis=0) - slack) and np.all(fd <= win.max(axis=0) + slack)


def test_path_states_on_a_circle_solve_the_exact_steady_balance():
    """Constant V on a circle: beta'' = beta' = 0 leaves lf m V^2 cos(b) / R + L Cr (tan b -
    lr / (R cos b)) = 0, solved here with scipy's brentq; it is the small-angle closed form
    of Rajamani to O(beta^2 / R)."""
    from scipy.optimize import brentq

    radius, v = 60.0, 14.0
    ref = T.circle_reference(radius, v, dt=0.02)
    c = CAR
    big_l = c["lf"] + c["lr"]

    def balance(b):
        return (c["lf"] * c["mass"] * v * v * math.cos(b) / radius
                + big_l * c["cr"] * (math.tan(b) - c["lr"] / (radius * math.cos(b))))

    beta = brentq(balance, -0.5, 0.5, xtol=1e-15)
    lat = T.reference_states_3dof(ref, method="path", **c)
    np.testing.assert_allclose(np.arctan2(lat.vy, lat.vx), beta, rtol=1e-8)
    small = c["lr"] / radius - c["mass"] * c["lf"] * v**2 / (big_l * c["cr"] * radius)
    # the cosines' b^2 / 2: |beta - small| ~ b^2 / 2 (lr / R + m lf V^2 / (L Cr R))
    lead = beta**2 / 2 * (c["lr"] + c["mass"] * c["lf"] * v**2 / (big_l * c["cr"])) / radius
    assert 0.5 * lead < abs(beta - small) < 1.5 * lead
    np.testing.assert_allclose(lat.r, v / radius, rtol=1e-8)


def test_path_integrator_converges():
    """Halving dt on the slalom: the differences between successive solutions shrink by 4 or
    more (RK4 with linearly interpolated inputs: second order at least)."""
    b = []
    for dt in (0.04, 0.02, 0.01, 0.005):
        lat = T.reference_states_3dof(T.make_reference(_slalom(), 15.0, dt=dt), method="path",
                                      **CAR)
        b.append(np.arctan2(lat.vy, lat.vx))
    diffs = [np.abs(a - c2[::2][: a.size]).max() for a, c2 in itertools.pairwise(b)]
    assert all(d1 / d2 > 3.8 for d1, d2 in itertools.pairwise(diffs)), diffs


def test_standstill_start_is_finite():
    ref = T.make_reference(T.straight_track(60.0), v_start=0.0, v_end=0.0, dt=0.05)
    for method in ("dynamic", "steady", "path"):
        lat = T.reference_states_3dof(ref, method=method, **CAR)
        for arr in (lat.vy, lat.r, lat.delta, lat.y2_dot, lat.y2_ddot):
            assert np.isfinite(arr).all(), method
    with pytest.raises(ValueError, match=r"cf = -1.0 N/rad"):
        T.reference_states_3dof(ref, **{**CAR, "cf": -1.0})


# ---------------------------------------------------------------------------------------------
# recording
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def lvms():
    return T.load_recording("lvms_23_01_04_b")


def test_recording_selection(lvms):
    assert len(lvms) == 16791 and lvms.sample_time == pytest.approx(0.04, abs=1e-6)
    on = lvms.on_track()
    # PROVENANCE.md: outside the track bounds until t ~ 102 s; stops at ~430 s
    assert 100.0 < on.t[0] < 105.0 and 425.0 < on.t[-1] < 432.0
    assert on.inside_bounds().all() and (on["vx"] > 1.0).all()
    mv = lvms.moving()
    assert mv.t[0] < on.t[0] and mv.t[-1] == pytest.approx(on.t[-1])
    part = lvms.select(200.0, 210.0)
    assert part.t[0] >= 200.0 and part.t[-1] <= 210.0


def test_recording_smoothing_removes_the_position_jitter(lvms):
    """PROVENANCE.md: |v_xy - v| has median 0.29 and p95 2.1 m/s from 25 Hz jitter."""
    on = lvms.on_track()
    raw = np.hypot(np.gradient(on["x"], on.t), np.gradient(on["y"], on.t))
    sm = on.smoothed()
    assert np.percentile(np.abs(raw - on["vx"]), 95) > 1.5
    assert np.percentile(np.abs(sm["v_xy"] - on["vx"]), 95) < 0.5


def test_recording_reference(lvms):
    on = lvms.on_track()
    ref = on.reference()
    np.testing.assert_array_equal(ref["delta_recorded"], on["delta"])
    assert ref.dt == pytest.approx(0.04)
    # two and a bit laps of an oval overlap: the local search keeps s increasing (a global
    # nearest point would jump between laps)
    assert ref.path.length > 2 * 2400.0
    assert (np.diff(ref["s"]) > -1e-6).all()
    assert ref["s"][-1] == pytest.approx(ref.path.length, abs=5.0)
    # consistent with the recorded signals (PROVENANCE: phi ~ atan2 within 0.03 deg median;
    # omega ~ dphi/dt within 0.0035 rad/s median)
    assert np.degrees(np.median(np.abs(ref["psi"] - ref["psi_recorded"]))) < 0.2
    assert np.median(np.abs(ref["r"] - ref["r_recorded"])) < 0.01
    assert np.median(np.hypot(ref["x"] - ref["x_recorded"], ref["y"] - ref["y_recorded"])) < 0.1
    # the recorded steer follows the path curvature (kinematic steer L kappa; PROVENANCE:
    # delta ~ 1.1 atan(L omega / vx) with correlation 0.90-0.98); L = 2.9718 m (VEHICLE_MODEL 4.3)
    assert np.corrcoef(ref["delta_recorded"], 2.9718 * ref["kappa"])[0, 1] > 0.8
    # resampling to another step keeps the signals
    ref100 = on.select(200.0, 260.0).reference(dt=0.01)
    assert ref100.dt == pytest.approx(0.01)
    assert np.isfinite(ref100.table[:, : T.RS.W_LEFT]).all()
    assert np.isnan(ref100["w_left"]).all()  # a driven path has no known widths


def test_load_track_accepts_the_recording_name():
    trk = T.load_track("LVMS_23_01_04_B")
    assert not trk.closed and trk.length > 4800.0


# ---------------------------------------------------------------------------------------------
# maneuvers
# ---------------------------------------------------------------------------------------------
def test_iso3888_gates_and_path():
    b = 1.8
    ga, gb, gc = T.iso3888_1_gates(b, lead_in=50.0)
    assert (ga.width, gb.width, gc.width) == pytest.approx((1.1 * b + 0.25, 1.2 * b + 0.25,
                                                            1.3 * b + 0.25))
    assert (ga.x_end - ga.x_start, gb.x_start - ga.x_end, gb.x_end - gb.x_start,
            gc.x_start - gb.x_end, gc.x_end - gc.x_start) == pytest.approx((15, 30, 25, 25, 15))
    assert gb.y_right == pytest.approx(3.5) and gc.y_right == pytest.approx(ga.y_right)
    trk = T.double_lane_change_track(b)
    for g in (ga, gb, gc):
        m = (trk.x >= g.x_start) & (trk.x <= g.x_end)
        # straight through the lane; at the lane ends the C3 step's 4th derivative jumps by
        # 840 |dy| / L^4 ~ 0.01 1/m^3, which the quintic fit through 0.25 m samples smears by
        # ~ h^4 * jump = 4e-5 * 0.01 (position)
        np.testing.assert_allclose(trk.y[m], g.center, atol=1e-6)
    # curvature = y'' / (1 + y'^2)^1.5 of the C3 step y = y0 + dy p(xi), p = 35 xi^4 - 84 xi^5
    # + 70 xi^6 - 20 xi^7; the fit's second derivative is off by ~ h^2 * jump = 6e-4 at most
    x = trk.x
    y1 = np.zeros_like(x)
    y2 = np.zeros_like(x)
    for g0, g1 in ((ga, gb), (gb, gc)):
        span = g1.x_start - g0.x_end
        xi = np.clip((x - g0.x_end) / span, 0.0, 1.0)
        dy = g1.center - g0.center
        y1 += dy / span * (140 * xi**3 - 420 * xi**4 + 420 * xi**5 - 140 * xi**6)
        y2 += dy / span**2 * (420 * xi**2 - 1680 * xi**3 + 2100 * xi**4 - 840 * xi**5)
    np.testing.assert_allclose(trk.kappa, y2 / (1 + y1**2) ** 1.5, atol=6e-4)
    np.testing.assert_allclose(trk.psi, np.arctan(y1), atol=1e-6)
    right = T.double_lane_change_track(b, direction="right")
    np.testing.assert_allclose(right.y, -trk.y, atol=1e-12)


def test_speed_step_reference():
    ref = T.speed_step_reference(10.0, 15.0, t_step=2.0, duration=6.0)
    t, v = ref.t, ref["vx"]
    np.testing.assert_allclose(v[t < 2.0], 10.0)
    np.testing.assert_allclose(v[t >= 2.0], 15.0)
    np.testing.assert_allclose(ref["s"], np.where(t < 2, 10 * t, 20 + 15 * (t - 2)), atol=1e-12)
    ramp = T.speed_step_reference(10.0, 15.0, t_step=2.0, duration=6.0, accel=2.0)
    np.testing.assert_allclose(np.gradient(ramp["s"], ramp.t)[1:-1], ramp["vx"][1:-1], atol=0.01)
    assert ramp["vx"][-1] == 15.0 and ramp["ax"].max() == 2.0
    assert ramp.path.length > ramp["s"][-1]


def test_reference_argument_errors():
    circle = T.circle_track(30.0)
    with pytest.raises(ValueError, match=r"expected a finite scalar, \d+ finite values"):
        T.make_reference(circle, 10.0, lateral_offset=np.zeros(5))
    with pytest.raises(ValueError, match=r"d\(L\) = .* must equal d\(0\)"):
        T.make_reference(circle, 10.0, lateral_offset=lambda s: 0.01 * s)
    with pytest.raises(ValueError, match="only a closed track"):
        T.make_reference(T.straight_track(50.0), 10.0, laps=2)
    with pytest.raises(ValueError, match=r"dt = -0.1 s"):
        T.make_reference(circle, 10.0, dt=-0.1)
    ref = T.make_reference(circle, 10.0, dt=0.1)
    with pytest.raises(KeyError, match="no signal 'speed'"):
        ref["speed"]
    assert set(ref.names) >= {"vx", "r_dot", "e_y_ref_ddot", "kappa"}


@pytest.mark.parametrize(
    "offset, text",
    [
        ("1.5", "lateral_offset = '1.5' m: expected real numbers, got dtype <U3"),
        (True, "lateral_offset = True m: expected real numbers, got dtype bool"),
        (None, "lateral_offset = None m: expected real numbers, got dtype object"),
        (math.inf, "lateral_offset = inf m: must be finite"),
        ([0.0, None, 1.0],
         "lateral_offset = [0.0, None, 1.0] m: expected real numbers, got dtype object"),
        ([[0.0, 1.0], [2.0]], ("lateral_offset [m]: expected an array of real numbers of one "
                               "shape, got [[0.0, 1.0], [2.0]]")),
        (lambda s: "1", "lateral_offset(s) = '1' m: expected real numbers, got dtype <U1"),
    ],
)
def test_lateral_offset_takes_real_numbers_only(offset, text):
    """lateral_offset on the shared validators, as Track.offset: "1.5" and True used to pass
    as float() took them (Track.offset("1.5") refused), a ragged list with numpy's bare
    message."""
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        T.make_reference(T.circle_track(30.0), 10.0, lateral_offset=offset, dt=0.1)
    with pytest.raises(ValueError, match="^d = '1.5': expected real numbers"):
        T.circle_track(30.0).offset("1.5")


def test_lateral_offset_numbers_of_any_kind_give_the_same_reference():
    """An int, a NumPy number and a 0-d array are the float constant, bit for bit; a list or an
    int array of node values are the float64 array's."""
    circle = T.circle_track(30.0)

    def table(offset):
        return T.make_reference(circle, 10.0, lateral_offset=offset, dt=0.1).table

    want = table(2.0)
    for same in (2, np.float64(2.0), np.int64(2), np.array(2.0)):
        np.testing.assert_array_equal(table(same), want)
    nodes = np.round(np.cos(2 * np.pi * circle.s / circle.length))  # whole metres: -1, 0, 1
    want = table(nodes)
    for same in (list(nodes), nodes.astype(np.int64), lambda s: nodes):
        np.testing.assert_array_equal(table(same), want)


def test_make_reference_loads_a_track_given_by_name_or_path(tmp_path):
    """``make_reference("Monza", ...)`` used to fail with AttributeError: a bundled track's name
    or a track file's path is loaded with load_track (its defaults), the same reference."""
    lim = T.SpeedLimits(a_lat_max=3.0)
    want = T.make_reference(T.load_track("Norisring"), lim, dt=0.05)
    got = T.make_reference("norisring", lim, dt=0.05)
    np.testing.assert_array_equal(got.table, want.table)
    assert got.name == want.name == "Norisring"
    theta = np.linspace(0.0, 2.0 * np.pi, 120, endpoint=False)
    path = tmp_path / "ring.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{60.0 * math.cos(a)!r},{60.0 * math.sin(a)!r}\n"
                                          for a in theta))
    want = T.make_reference(T.load_track(path), 12.0, dt=0.05)
    for given in (path, str(path)):
        np.testing.assert_array_equal(T.make_reference(given, 12.0, dt=0.05).table, want.table)
    with pytest.raises(ValueError, match="no-such-track"):
        T.make_reference("no-such-track", lim)


def test_make_reference_takes_a_mapping_of_speed_limits():
    """A mapping of SpeedLimits' fields is SpeedLimits(**it) (it used to fail in float());
    an unknown key or a bad value is a ValueError naming it."""
    circle = T.circle_track(40.0)
    want = T.make_reference(circle, T.SpeedLimits(a_lat_max=3.0, v_max=20.0), dt=0.05)
    got = T.make_reference(circle, {"a_lat_max": 3, "v_max": 20.0}, dt=0.05)
    np.testing.assert_array_equal(got.table, want.table)
    with pytest.raises(ValueError, match=r"unknown limit 'a_lat'; SpeedLimits has a_lat_max, "):
        T.make_reference(circle, {"a_lat": 3.0})
    with pytest.raises(ValueError, match=r"a_lat_max = '3' m/s\^2: expected a real number"):
        T.make_reference(circle, {"a_lat_max": "3"})


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(track=None), r"track = None: expected a Track, a bundled track's name or the path"),
    (dict(track=42), r"track = 42: expected a Track"),
    (dict(speed="20"), (r"speed = '20': expected SpeedLimits \(or a mapping of its fields\), "
                        r"a SpeedProfile, a constant speed in m/s, or None")),
    (dict(speed=[10.0]), r"speed = \[10\.0\]: expected SpeedLimits"),
    (dict(speed=-3.0), r"speed = -3\.0 m/s: must be > 0"),
    (dict(laps="2"), r"laps = '2': must be an integer >= 1"),
    (dict(laps=None), r"laps = None: must be an integer >= 1"),
    (dict(speed=None, vehicle="peugeot406"), r"vehicle = 'peugeot406': expected VehicleParams"),
    # a drive too long to tabulate is refused before numpy's memory error (a near-zero limit,
    # a huge lap count): the circle of radius 40 m at a_lat 1e-12 m/s^2, v = sqrt(a R), takes
    # 2 pi R / v = 3.974e7 s a lap
    (dict(speed=T.SpeedLimits(a_lat_max=1e-12)),
     r"would last 3\.974e\+07 s \(1 lap\(s\) of .* more than 10,000,000 samples .*=1e-12"),
    (dict(laps=10**9), r"1000000000 lap\(s\) of 25\.13 s.*laps = 1000000000 too many"),
])
def test_make_reference_refuses_bad_arguments_naming_them(kwargs, message):
    args = {"track": T.circle_track(40.0), "speed": 10.0, **kwargs}
    with pytest.raises(ValueError, match=message):
        T.make_reference(args.pop("track"), args.pop("speed"), **args)


def test_in_asks_for_a_signal_name():
    """``"x" in ref`` raised KeyError: no signal 0 (Python's fallback iterated ref[0], ...)."""
    ref = T.make_reference(T.load_track("IMS"), dt=0.02)
    assert "vx" in ref and "kappa" in ref and "nope" not in ref and 0 not in ref
    assert all(n in ref for n in ref.names)
