"""Flatness maps of the 3DoF model (paper Section 2.3): sympy, round trips, the singular speed."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
import sympy as sp
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from flatfree.controllers.flatness import (
    MAP_MARGIN,
    SAFE_MARGIN,
    FlatStatus,
    check_reference_speeds,
    decoupling_matrices,
    det_delta,
    det_delta_kernel,
    flat_output_rates,
    flat_outputs,
    input_from_flat,
    input_from_flat_kernel,
    safe_speed,
    singular_band,
    singular_speed,
    singularity_ratio,
    state_from_flat,
    state_from_flat_kernel,
)
from flatfree.models.bicycle3dof import Bicycle3DoFParams, vector_field

# Hand-written parameter sets (independent of the tyre module):
# 406-like (VEHICLE_MODEL.md 4.2), yaw index 0.998 -> vx* ~ 0.58 m/s;
P406 = Bicycle3DoFParams(
    m=1500.0, iz=2620.0, lf=1.08, lr=1.62, cf=97_700.0, cr=73_800.0,
    wheel_radius=0.31, wheel_inertia_front=1.8, wheel_inertia_rear=1.8,
)
# Dallara-like (VEHICLE_MODEL.md 4.3), yaw index 0.59 -> vx* ~ 10.8 m/s;
DALLARA = Bicycle3DoFParams(
    m=790.0, iz=1000.0, lf=1.724, lr=1.248, cf=75_300.0, cr=102_100.0,
    wheel_radius=0.31, wheel_inertia_front=2.3, wheel_inertia_rear=2.7,
)
# and a car with Iz > lf lr m (yaw index 1.3): no singular speed.
HIGH_IZ = dataclasses.replace(P406, iz=1.3 * 1500.0 * 1.08 * 1.62)
PARAM_SETS = [P406, DALLARA, HIGH_IZ]


# --------------------------------------------------------------------------------------------
# The paper's model typed in sympy as printed (Section 2.1), and the flatness derivation
# --------------------------------------------------------------------------------------------
class Sym:
    m, iz, lf, lr, cf, cr, rw, jf, jr = sp.symbols("m I_z l_f l_r C_f C_r R J_f J_r",
                                                   positive=True)
    vx, y1 = sp.symbols("V_x y_1", positive=True)
    vy, r, tw, d, wf, wr, y2, y2d, y1d, y2dd = sp.symbols(
        "V_y r T_w delta wdot_f wdot_r y_2 y2dot y1dot y2ddot", real=True)
    L = lf + lr


@pytest.fixture(scope="module")
def derivation():
    S = Sym
    x = sp.Matrix([S.vx, S.vy, S.r])
    u = sp.Matrix([S.tw, S.d])
    f = sp.Matrix([  # paper f(x, t)
        S.r * S.vy - S.jf * S.wf / (S.m * S.rw) - S.jr * S.wr / (S.m * S.rw),
        -S.r * S.vx + (-S.cf * (S.vy + S.lf * S.r) / S.vx - S.cr * (S.vy - S.lr * S.r) / S.vx)
        / S.m,
        (-S.lf * S.cf * (S.vy + S.lf * S.r) / S.vx + S.lr * S.cr * (S.vy - S.lr * S.r) / S.vx)
        / S.iz,
    ])
    g = sp.Matrix([  # paper g(x, t), I_r w_dot_f -> J_f w_dot_f
        [1 / (S.m * S.rw), S.cf / S.m * (S.vy + S.lf * S.r) / S.vx],
        [0, (S.cf * S.rw - S.jf * S.wf) / (S.m * S.rw)],
        [0, (S.lf * S.cf * S.rw - S.lf * S.jf * S.wf) / (S.iz * S.rw)],
    ])
    xdot = f + g * u
    y2 = S.lf * S.m * S.vy - S.iz * S.r  # paper eq. (flatness_outputs)
    y2dot = sp.simplify((sp.Matrix([y2]).jacobian(x) * xdot)[0])
    y1dot = xdot[0]
    y2ddot = sp.expand((sp.Matrix([y2dot]).jacobian(x) * xdot)[0])
    rates = sp.Matrix([y1dot, y2ddot])
    delta_m = rates.jacobian(u)
    phi = rates.subs({S.tw: 0, S.d: 0})
    # map A: solve y2 = ..., y2dot = ... for (vy, r) at vx = y1
    sol = sp.solve([sp.Eq(S.y2, y2), sp.Eq(S.y2d, y2dot.subs(S.vx, S.y1))], [S.vy, S.r],
                   dict=True)[0]
    return dict(x=x, u=u, f=f, g=g, y2=y2, y2dot=y2dot, y2ddot=y2ddot, delta=delta_m, phi=phi,
                A_vy=sol[S.vy], A_r=sol[S.r])


def _pvals(p: Bicycle3DoFParams) -> dict:
    S = Sym
    return {S.m: p.m, S.iz: p.iz, S.lf: p.lf, S.lr: p.lr, S.cf: p.cf, S.cr: p.cr,
            S.rw: p.wheel_radius, S.jf: p.wheel_inertia_front, S.jr: p.wheel_inertia_rear}


# --------------------------------------------------------------------------------------------
# Symbolic identities: the code's closed forms are the paper's, as corrected in NOTES.md
# --------------------------------------------------------------------------------------------
def test_y2dot_is_free_of_steer_and_wheel_terms(derivation):
    """y2' = -lf m vx r - Cr L (vy - lr r)/vx (NOTES.md): delta, T_w and w_dot cancel."""
    S = Sym
    notes = -S.lf * S.m * S.vx * S.r - S.cr * S.L * (S.vy - S.lr * S.r) / S.vx
    assert sp.simplify(derivation["y2dot"] - notes) == 0
    for s in (S.d, S.tw, S.wf, S.wr):
        assert not derivation["y2dot"].has(s)


def test_map_a_is_the_papers_printed_formula(derivation):
    """Solving the two flat-output equations for (vy, r) gives the paper's printed A exactly."""
    S = Sym
    den = S.cr * S.L * (S.iz - S.lr * S.lf * S.m) + (S.lf * S.m * S.y1) ** 2
    q = (S.lf * S.m * S.y1 * S.y2d + S.cr * S.L * S.y2) / den
    paper_vy = S.y2 / (S.lf * S.m) - S.iz / (S.lf * S.m) * q  # paper eq. (x_A_y1_y2_y2p)
    paper_r = -q
    assert sp.simplify(derivation["A_vy"] - paper_vy) == 0
    assert sp.simplify(derivation["A_r"] - paper_r) == 0


def test_det_delta_is_the_papers_printed_formula(derivation):
    """det(Delta) from the derivation equals the paper's eq. (delta_matrice) with L = lf + lr,
    identically in (vx, vy, r) (NOTES.md: printed correctly); its speed factor vanishes at
    vx*^2 = Cr L (lf lr m - Iz)/(lf m)^2, NOT at the printed condition's (Iz - lf m) (typo)."""
    S = Sym
    det = derivation["delta"].det()
    paper = ((S.jf * S.wf - S.cf * S.rw)
             * (S.lf**2 * S.vx**2 * S.m**2 - S.cr * S.L * S.lr * S.lf * S.m + S.cr * S.iz * S.L)
             / (S.iz * S.rw**2 * S.vx * S.m**2))
    assert sp.simplify(det - paper) == 0
    factor = S.lf**2 * S.m**2 * S.vx**2 + S.cr * S.L * (S.iz - S.lf * S.lr * S.m)
    assert sp.simplify(det * S.iz * S.rw**2 * S.vx * S.m**2
                       / (S.jf * S.wf - S.cf * S.rw) - factor) == 0
    printed_condition = S.cr * S.L * (S.iz - S.lf * S.m) + S.lf**2 * S.m**2 * S.vx**2
    assert sp.simplify(factor - printed_condition) != 0
    vstar = sp.sqrt(S.cr * S.L * (S.lf * S.lr * S.m - S.iz)) / (S.lf * S.m)  # NOTES.md
    assert sp.simplify(factor.subs(S.vx, vstar)) == 0


# --------------------------------------------------------------------------------------------
# Numerical agreement of the compiled maps with the derivation
# --------------------------------------------------------------------------------------------
def _outside_band(p, v, margin=MAP_MARGIN) -> bool:
    band = singular_band(p, margin)
    return band is None or not (band[0] * 0.999 < v < band[1] * 1.001)


def _random_state(rng, p, vmin=0.3, vmax=60.0):
    """A state inside the model's validity domain: the paper's small slip angles,
    |(vy + lf r)/vx| <= 0.15 and |(vy - lr r)/vx| <= 0.15 rad, |r| <= 1.2 rad/s, and outside
    the refused speed band. (Far outside that domain, e.g. 80 deg slip at 0.5 m/s, B asks for
    1e4 rad of steer and 1e9 N m: conditioning there is meaningless.)"""
    L = p.lf + p.lr
    while True:
        vx = rng.uniform(vmin, vmax)
        sf, sr = rng.uniform(-0.15, 0.15, size=2)
        r = vx * (sf - sr) / L
        vy = vx * sr + p.lr * r
        if abs(r) <= 1.2 and _outside_band(p, vx):
            return np.array([vx, vy, r])


def _scaled_rel_err(a, b, length):
    """Relative error of a state in m/s units (yaw rate scaled by the wheelbase)."""
    sa = np.array([a[0], a[1], a[2] * length])
    sb = np.array([b[0], b[1], b[2] * length])
    return np.linalg.norm(sa - sb) / np.linalg.norm(sb)


@settings(max_examples=150, derandomize=True, deadline=None)
@given(
    k=st.integers(0, len(PARAM_SETS) - 1),
    vx=st.floats(0.3, 70.0),
    vy=st.floats(-5.0, 5.0),
    r=st.floats(-1.5, 1.5),
)
def test_round_trip_state_flat_state(k, vx, vy, r):
    """state -> (y1, y2, y2') -> A -> state, 1e-9 relative in the state's norm (vx, vy and
    L r in m/s). Outside the refused band the normalized determinant is >= 0.049, so rounding
    (1e-16) is amplified at most ~1e3 by the cancellation in y2 and D: 1e-9 has margin."""
    p = PARAM_SETS[k]
    assume(_outside_band(p, vx))
    y = flat_outputs(p, [vx, vy, r])
    x = state_from_flat(p, *y)
    assert _scaled_rel_err(x, [vx, vy, r], p.lf + p.lr) <= 1e-9


def test_flat_outputs_and_decoupling_match_sympy(derivation):
    """At 30 random (seeded) states per parameter set, with random wheel accelerations:
    (y1, y2, y2'), Delta and Phi at A(y) match the sympy derivation to 1e-10 relative per
    entry (entries combine up to ~10 terms; float64 rounding with that cancellation stays
    below 1e-13 except near zero-crossings, hence atol = 1e-12 x the row's largest entry),
    and det(Delta) equals the paper's closed form (det_delta_kernel) to 1e-10."""
    S = Sym
    args = [S.vx, S.vy, S.r, S.wf, S.wr]
    rng = np.random.default_rng(11)
    for p in PARAM_SETS:
        pv = _pvals(p)
        y2_num = sp.lambdify(args, derivation["y2"].subs(pv), "math")
        y2d_num = sp.lambdify(args, derivation["y2dot"].subs(pv), "math")
        dm_num = sp.lambdify(args, derivation["delta"].subs(pv), "numpy")
        phi_num = sp.lambdify(args, derivation["phi"].subs(pv), "numpy")
        for _ in range(30):
            x = _random_state(rng, p)
            wf, wr = rng.uniform(-300, 300, size=2)
            y = flat_outputs(p, x)
            assert y[0] == x[0]
            assert y[1] == pytest.approx(y2_num(*x, wf, wr), rel=1e-12, abs=1e-9)
            assert y[2] == pytest.approx(y2d_num(*x, wf, wr), rel=1e-10, abs=1e-9)
            dm, phi = decoupling_matrices(p, *y, wdot_f=wf, wdot_r=wr)
            dm_ref = np.array(dm_num(*x, wf, wr), dtype=float)
            phi_ref = np.array(phi_num(*x, wf, wr), dtype=float).ravel()
            for i in range(2):
                scale = max(np.max(np.abs(dm_ref[i])), 1e-300)
                np.testing.assert_allclose(dm[i], dm_ref[i], rtol=1e-10, atol=1e-12 * scale)
            np.testing.assert_allclose(phi, phi_ref, rtol=1e-10,
                                       atol=1e-12 * np.max(np.abs(phi_ref)))
            det_code = dm[0, 0] * dm[1, 1] - dm[0, 1] * dm[1, 0]
            assert det_code == pytest.approx(det_delta(p, x[0], wdot_f=wf), rel=1e-10)


def test_b_inverts_the_model(derivation):
    """u = B(y1, y1', y2, y2', y2'') applied to the 3DoF vector field (and to the sympy
    y2'' of the derivation) yields the commanded y1' and y2''. 40 random (seeded) commands
    per parameter set: y1' in [-6, 4] m/s^2, y2'' random of the size of Phi2. Tolerance
    1e-9 relative to the size of the terms summed in Delta u + Phi (|Delta| |u| + |Phi| per
    row: the natural scale of rounding in that sum; near vx* the inputs are large and cancel).
    Measured worst case over 9000 such samples (3 parameter sets): 6e-11, so 1e-9 keeps a
    ~15x margin while a wrong term (relative error O(1)) fails by orders of magnitude."""
    S = Sym
    rng = np.random.default_rng(5)
    for p in PARAM_SETS:
        pv = _pvals(p)
        y2dd_sym = sp.lambdify([S.vx, S.vy, S.r, S.tw, S.d, S.wf, S.wr],
                               derivation["y2ddot"].subs(pv), "math")
        for _ in range(40):
            x = _random_state(rng, p)
            wf, wr = rng.uniform(-300, 300, size=2)
            y1, y2, y2d = flat_outputs(p, x)
            dm, phi = decoupling_matrices(p, y1, y2, y2d, wdot_f=wf, wdot_r=wr)
            cmd = np.array([rng.uniform(-6, 4), phi[1] * rng.uniform(-2, 2)])
            u = input_from_flat(p, y1, cmd[0], y2, y2d, cmd[1], wdot_f=wf, wdot_r=wr)
            scale = np.abs(dm) @ np.abs(u) + np.abs(phi)
            got = flat_output_rates(p, x, u, wdot_f=wf, wdot_r=wr)  # chain rule on the model
            assert np.all(np.abs(got - cmd) <= 1e-9 * scale), (got, cmd)
            xdot = vector_field(p, x, u, wdot_f=wf, wdot_r=wr)
            assert abs(xdot[0] - cmd[0]) <= 1e-9 * scale[0]
            got_sym = y2dd_sym(*x, *u, wf, wr)
            assert abs(got_sym - cmd[1]) <= 1e-9 * scale[1]


def test_b_recovers_the_input():
    """input -> (y1', y2'') along the model -> B -> the same input (1e-9 relative per
    component, delta compared in absolute 1e-12 rad when it is tiny)."""
    rng = np.random.default_rng(9)
    for p in PARAM_SETS:
        for _ in range(30):
            x = _random_state(rng, p)
            u = np.array([rng.uniform(-5000, 3000), rng.uniform(-0.3, 0.3)])
            rates = flat_output_rates(p, x, u)
            y = flat_outputs(p, x)
            u2 = input_from_flat(p, y[0], rates[0], y[1], y[2], rates[1])
            assert u2[0] == pytest.approx(u[0], rel=1e-9, abs=1e-9)
            assert u2[1] == pytest.approx(u[1], rel=1e-9, abs=1e-12)


def test_b_inverts_the_rolling_closure_model():
    """With the model's rolling closure (w_dot = vx_dot / R), B with wdot_f = wdot_r = y1'/R
    gives an input whose rolling-closure vector field yields the commanded y1', y2''
    (the closure's wheel accelerations equal y1'/R exactly when vx_dot = y1'). 1e-9.
    y2'' is computed from x_dot by the chain rule with the gradient of y2' (NOTES.md); the
    tolerance scale is that of test_b_inverts_the_model."""
    rng = np.random.default_rng(21)
    for p in (P406, DALLARA):
        L = p.lf + p.lr
        for _ in range(20):
            x = _random_state(rng, p, vmin=17.0, vmax=50.0)
            y1, y2, y2d = flat_outputs(p, x)
            cmd = np.array([rng.uniform(-6, 4), rng.uniform(-2e4, 2e4)])
            w = cmd[0] / p.wheel_radius
            u = input_from_flat(p, y1, cmd[0], y2, y2d, cmd[1], wdot_f=w, wdot_r=w)
            xd = vector_field(p, x, u, rolling=True)
            vx, vy, r = x
            grad = np.array([-p.lf * p.m * r + p.cr * L * (vy - p.lr * r) / vx**2,
                             -p.cr * L / vx,
                             -p.lf * p.m * vx + p.cr * L * p.lr / vx])
            got = np.array([xd[0], grad @ xd])
            dm, phi = decoupling_matrices(p, y1, y2, y2d, wdot_f=w, wdot_r=w)
            scale = np.abs(dm) @ np.abs(u) + np.abs(phi)
            assert np.all(np.abs(got - cmd) <= 1e-9 * scale), (got, cmd)


# --------------------------------------------------------------------------------------------
# The singular speed
# --------------------------------------------------------------------------------------------
def test_singular_speed_values_and_det_vanishes_there():
    """vx* = sqrt(Cr L (lf lr m - Iz)) / (lf m) (NOTES.md). det(Delta) (paper's closed form)
    is 0 there to rounding (|det(vx*)| <= 1e-12 x |det(2 vx*)|: D = a + b with a = -b cancels
    to ~1e-16 relative) and changes sign across it."""
    for p in (P406, DALLARA):
        vs = singular_speed(p)
        L = p.lf + p.lr
        assert vs == pytest.approx(
            math.sqrt(p.cr * L * (p.lf * p.lr * p.m - p.iz)) / (p.lf * p.m), rel=1e-15)
        far = abs(det_delta(p, 2 * vs))
        assert abs(det_delta(p, vs)) <= 1e-12 * far
        assert det_delta(p, vs * (1 - 1e-6)) * det_delta(p, vs * (1 + 1e-6)) < 0
        assert singularity_ratio(p, vs) == pytest.approx(0.0, abs=1e-12)
        assert singularity_ratio(p, 1e3 * vs) == pytest.approx(1.0, abs=1e-5)
        assert singularity_ratio(p, 0.5 * vs) < 0
    assert singular_speed(DALLARA) == pytest.approx(10.70, abs=0.01)  # hand computation
    assert singular_speed(HIGH_IZ) is None
    assert safe_speed(HIGH_IZ) == 0.0
    assert singular_band(HIGH_IZ) is None
    np.testing.assert_allclose(singularity_ratio(HIGH_IZ, np.array([0.1, 1.0, 30.0])), 1.0)
    assert safe_speed(DALLARA) == pytest.approx((1 + SAFE_MARGIN) * singular_speed(DALLARA))
    assert safe_speed(DALLARA, 0.2) == pytest.approx(1.2 * singular_speed(DALLARA))


def test_maps_refuse_near_the_singular_speed():
    """Inside the band the Python maps raise ValueError naming vx* and the safe speed; the
    kernels return FlatStatus.singular_speed and zeros (never a division by ~0, never NaN).
    Just outside the band B still inverts the model (1e-9)."""
    p = DALLARA
    vs = singular_speed(p)
    x = np.array([vs, 0.5, 0.2])
    y1, y2, y2d = flat_outputs(p, x)  # the outputs themselves exist at vx*
    with pytest.raises(ValueError, match="singular speed"):
        state_from_flat(p, y1, y2, y2d)
    with pytest.raises(ValueError, match="safe_speed"):
        input_from_flat(p, y1, 0.0, y2, y2d, 0.0)
    with pytest.raises(ValueError, match="singular speed"):
        decoupling_matrices(p, vs * 1.04, y2, y2d)
    pa = p.to_array()
    for v in (vs, vs * 1.0000001, vs / 1.04, vs * 1.04):
        tw, delta, status = input_from_flat_kernel(v, 0.0, y2, y2d, 0.0, pa, 0.0, 0.0,
                                                   MAP_MARGIN)
        assert status == FlatStatus.singular_speed and tw == 0.0 and delta == 0.0
        *xs, status = state_from_flat_kernel(v, y2, y2d, pa, MAP_MARGIN)
        assert status == FlatStatus.singular_speed and xs == [0.0, 0.0, 0.0]
    # just outside the band: computed, finite, and B inverts
    v = vs * (1 + MAP_MARGIN) * 1.001
    x = np.array([v, 0.5, 0.2])
    y1, y2, y2d = flat_outputs(p, x)
    u = np.array([800.0, 0.05])
    rates = flat_output_rates(p, x, u)
    np.testing.assert_allclose(input_from_flat(p, y1, rates[0], y2, y2d, rates[1]), u,
                               rtol=1e-9)


def test_speed_sweep_through_singularity_never_nan():
    """B from 0.05 to 30 m/s through vx* = 10.8 m/s: every output is finite; the status is
    singular exactly inside the band and ok elsewhere."""
    p = DALLARA
    pa = p.to_array()
    lo, hi = singular_band(p)
    for v in np.linspace(0.05, 30.0, 2001):
        tw, delta, status = input_from_flat_kernel(v, 0.5, 300.0, -2000.0, 100.0, pa, 0.0,
                                                   0.0, MAP_MARGIN)
        assert math.isfinite(tw) and math.isfinite(delta)
        assert status == (FlatStatus.singular_speed if lo < v < hi else FlatStatus.ok)


def test_other_refusals():
    """y1 <= 0 and an absurd front wheel acceleration (J_f w_dot_f near Cf R: the other det
    factor) are refused with ValueError / a status; the det formula itself vanishes there."""
    p = P406
    pa = p.to_array()
    with pytest.raises(ValueError, match="y1 = vx = 0.0 m/s"):
        input_from_flat(p, 0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="vx = -2.0 m/s"):
        flat_outputs(p, [-2.0, 0.0, 0.0])
    w_sing = p.cf * p.wheel_radius / p.wheel_inertia_front
    assert abs(det_delta_kernel(20.0, pa, w_sing)) <= 1e-12 * abs(det_delta_kernel(20.0, pa, 0.0))
    with pytest.raises(ValueError, match="wdot_f"):
        input_from_flat(p, 20.0, 0.0, 0.0, 0.0, 0.0, wdot_f=w_sing)
    *_, status = input_from_flat_kernel(20.0, 0.0, 0.0, 0.0, 0.0, pa, w_sing, 0.0, MAP_MARGIN)
    assert status == FlatStatus.wheel_accel
    *_, status = input_from_flat_kernel(math.nan, 0.0, 0.0, 0.0, 0.0, pa, 0.0, 0.0, MAP_MARGIN)
    assert status == FlatStatus.bad_speed
    with pytest.raises(ValueError, match="margin"):
        state_from_flat(p, 20.0, 0.0, 0.0, margin=0.0)


def test_check_reference_speeds():
    """A reference entering the band or crossing vx* is refused; one above safe_speed passes;
    one entirely below the band passes (no crossing); a car without vx* accepts anything > 0."""
    p = DALLARA
    vs = singular_speed(p)
    check_reference_speeds(p, np.linspace(safe_speed(p) * 1.01, 60.0, 50))
    with pytest.raises(ValueError, match="singular"):
        check_reference_speeds(p, np.linspace(5.0, 30.0, 50))
    with pytest.raises(ValueError, match="crosses"):
        check_reference_speeds(p, [0.5 * vs, 2 * vs])  # jumps over the band: still crosses
    check_reference_speeds(p, np.linspace(0.5, vs / (1 + SAFE_MARGIN) * 0.99, 20))
    with pytest.raises(ValueError, match="> 0"):
        check_reference_speeds(p, [20.0, 0.0])
    check_reference_speeds(HIGH_IZ, np.linspace(0.1, 60.0, 10))


@pytest.mark.parametrize(("call", "msg"), [
    (lambda: flat_outputs(P406, "1.0"), "x = '1.0': expected real numbers, got dtype <U3"),
    (lambda: flat_output_rates(P406, [20.0, 0.0, 0.0], [True, False]),
     "u = [True, False]: expected real numbers, got dtype bool"),
    (lambda: singularity_ratio(P406, [10.0, None]),
     "vx = [10.0, None]: expected real numbers, got dtype object"),
    (lambda: check_reference_speeds(P406, "20"),
     "vx_ref = '20': expected real numbers, got dtype <U2"),
])
def test_arrays_that_are_not_real_numbers_are_refused_by_name(call, msg):
    # float64 reads "1.0" and True as numbers and a None as a silent NaN: refused, by name
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        call()
