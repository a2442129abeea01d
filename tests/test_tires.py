"""Tests of flatfree.tires: slip definitions, Magic Formula pure and combined slip, stiffnesses.

Reference values come from the peer library (CommonRoad's ``vehiclemodels.utils.tire_model``),
from closed forms of the tyre coefficients (the Pacejka 205/60R15 table of VEHICLE_MODEL.md
section 2.6 is checked as their printed rounding), and from exact properties of the formulas
(oddness, bounds, similarity under mu_scale, C2 blend). One bound is a measured regression
value, not a reference: the 205/60R15 friction-ellipse exceedance (P06_ELLIPSE_SUP).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flatfree.tires import (
    combined,
    cornering_stiffness,
    friction_coefficients,
    fx0,
    fy0,
    linear_fy,
    mf_combined,
    mf_fx0,
    mf_fy0,
    slip_angle,
    slip_ratio,
    slip_speed,
    slip_stiffness,
    slips,
)
from flatfree.vehicles import load_tire

BUNDLED = ["commonroad", "pacejka2006_205_60R15"]
HSET = settings(max_examples=60, deadline=None, derandomize=True)  # seeded (derandomized)

# Pacejka's book values of the terms the bundled 205/60R15 file sets to 0 (its TOML header and
# VEHICLE_MODEL.md section 2.6): used to test the shift paths of the code.
P06_SHIFTS = dict(
    phx1=-0.002, phx2=0.002, phy1=0.003, phy2=-0.001, pvy1=0.045, pvy2=-0.024,
    rhx1=0.007, rhy1=0.009, rvy1=0.053, rvy2=-0.073,
)


# The bundled sets are symmetrised: besides the shift terms, p_Ey3 (205/60R15: E_y depends on
# sgn(alpha_y), [P12] 4.E24, F_y0 not odd by up to 34 N at 4 kN) and r_By3 ([P12] 4.E62: centres
# B_ykappa at alpha = r_By3, combined F_y not odd when kappa != 0, up to 247 N at 4 kN and
# kappa = 0.1 for the CommonRoad set) are set to 0 in their TOML files. The oddness tests below
# check the files as shipped.


loads = st.floats(300.0, 9000.0)
kappas = st.floats(-1.0, 1.0)
alphas = st.floats(-0.8, 0.8)
mus = st.floats(0.05, 1.5)


# ============================================================================================
# Peer cross-check: CommonRoad's tire_model.py on the UN-symmetrised CommonRoad coefficients
# ============================================================================================
def _cr_modules():
    tm = pytest.importorskip("vehiclemodels.utils.tire_model")
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2

    return tm, parameters_vehicle2().tire


#: (flatfree field, CommonRoad field, sign) of the coefficients both models have; the sign
#: flips r_Hy1 and r_Vy1 (CommonRoad's MB slip s = -kappa, see _flatfree_like_commonroad)
_CR_NAMES = tuple(
    (f"{a[0]}{a[2:]}", a, -1.0 if a in ("r_hy1", "r_vy1") else 1.0) for a in (
        "p_cx1", "p_dx1", "p_ex1", "p_kx1", "p_hx1", "p_vx1",
        "p_cy1", "p_dy1", "p_ey1", "p_ky1", "p_hy1", "p_vy1",
        "r_bx1", "r_bx2", "r_cx1", "r_ex1", "r_hx1",
        "r_by1", "r_by2", "r_by3", "r_cy1", "r_ey1", "r_hy1", "r_vy1", "r_vy4", "r_vy5", "r_vy6"))


def _flatfree_like_commonroad(p, *, pvx1: float):
    """flatfree TireParams with CommonRoad's raw coefficients, mapped where the models differ.

    * CommonRoad multiplies S_Hy and S_Vy by sgn(gamma): at gamma = 0 they are 0, so
      phy1 = pvy1 = 0 here (VEHICLE_MODEL.md section 2.4, point 3).
    * CommonRoad's MB passes s = -kappa (its slip 1 - R Omega / u) to the combined functions,
      while formula_longitudinal negates it back. In the lateral combined function this flips the
      sign of kappa_S = s + r_hy1 and of S_Vykappa ~ sin(r_vy5 atan(r_vy6 s)); G is even in
      kappa_S, so flatfree with r_hy1 -> -r_hy1 and r_vy1 -> -r_vy1 is CommonRoad's tyre.
    * S_Vx: CommonRoad adds it inside the sine; compared separately (pvx1 argument).
    """
    values = {ours: sign * getattr(p, theirs) for ours, theirs, sign in _CR_NAMES}
    values.update(pvx1=pvx1, phy1=0.0, pvy1=0.0)
    return dataclasses.replace(load_tire("commonroad"), **values)


def test_matches_commonroad_tire_model_on_a_grid():
    """flatfree's MF equals CommonRoad's functions to 1e-9 of the peak force D = mu F_z.

    Both evaluate the same double-precision expressions (S_Vx aside, see the next test). The only
    deliberate difference is flatfree's guard B = K / (C D + 1e-9 N), which changes B by
    < 1e-12 relative at these loads, so 1e-9 D leaves a factor ~1000 of margin for rounding
    (the error is measured about 1e-13 D) while any formula difference would show at >= 1e-4 D.
    """
    tm, p = _cr_modules()
    p0 = dataclasses.replace(p, p_vx1=0.0)  # S_Vx = 0 in both: the formulas coincide
    tire = _flatfree_like_commonroad(p, pvx1=0.0)
    tp = tire.to_array()
    worst = 0.0
    for fz in (800.0, 2404.2, 2958.4, 4000.0, 7000.0):  # includes set 2's static wheel loads
        d = p.p_dx1 * fz
        for kappa in np.linspace(-0.6, 0.6, 25):
            s = -kappa  # CommonRoad MB's slip variable (VEHICLE_MODEL.md 1.6)
            fx0_cr = tm.formula_longitudinal(s, 0.0, fz, p0)
            for alpha in np.linspace(-0.5, 0.5, 21):
                fy0_cr, mu_y = tm.formula_lateral(alpha, 0.0, fz, p0)
                fx_cr = tm.formula_longitudinal_comb(s, alpha, fx0_cr, p0)
                fy_cr = tm.formula_lateral_comb(s, alpha, 0.0, mu_y, fz, fy0_cr, p0)
                fx, fy = mf_combined(kappa, alpha, fz, 1.0, tp)
                errs = (
                    mf_fx0(kappa, fz, 1.0, tp) - fx0_cr,
                    mf_fy0(alpha, fz, 1.0, tp) - fy0_cr,
                    fx - fx_cr,
                    fy - fy_cr,
                )
                worst = max(worst, max(abs(e) for e in errs) / d)
    assert worst <= 1e-9, worst


def _fx0_at_zero_slip(p, fz: float, *, svx_inside_the_sine: bool) -> float:
    """F_x0 at kappa = 0 written out from the CommonRoad coefficients (not from either code).

    kappa_x = S_Hx = p_Hx1, B = p_Kx1 / (p_Cx1 p_Dx1), D = p_Dx1 F_z, S_Vx = p_Vx1 F_z; the
    textbook ([P12] 4.E9) adds S_Vx to D sin(theta), CommonRoad adds it to theta (VEHICLE_MODEL.md
    section 2.4, point 2).
    """
    bx = p.p_kx1 / (p.p_cx1 * p.p_dx1) * p.p_hx1
    theta = p.p_cx1 * math.atan(bx - p.p_ex1 * (bx - math.atan(bx)))
    svx = fz * p.p_vx1
    if svx_inside_the_sine:
        return p.p_dx1 * fz * math.sin(theta + svx)
    return p.p_dx1 * fz * math.sin(theta) + svx


def test_svx_is_added_outside_the_sine_as_in_the_textbook():
    """With CommonRoad's p_vx1 != 0, flatfree = CommonRoad(p_vx1 = 0) + F_z p_vx1 ([P12] 4.E9).

    The free-rolling force F_x0(kappa = 0) equals the textbook closed form written out in
    ``_fx0_at_zero_slip`` (measured difference 1.4e-11 N, the 1e-9 N guard in B; tolerance
    1e-9 F_z as in the loop), and CommonRoad's own function equals the same closed form with S_Vx
    inside the sine (measured 1e-14 N), which is the difference the cross-check maps. The
    sheet's figures (VEHICLE_MODEL.md section 2.4: textbook +81.1 N at 2958 N, CommonRoad -9.4 N
    and -55.8 N at 2958 N and 4000 N) are the closed forms printed to 0.1 N: checked as text.
    (The sheet's +109.7 N at 4000 N is a rounding slip: the closed form gives 109.648 N.)
    """
    tm, p = _cr_modules()
    p0 = dataclasses.replace(p, p_vx1=0.0)
    tp = _flatfree_like_commonroad(p, pvx1=p.p_vx1).to_array()
    for fz in (1000.0, 2958.4, 6000.0):
        for kappa in np.linspace(-0.5, 0.5, 11):
            ref = tm.formula_longitudinal(-kappa, 0.0, fz, p0) + fz * p.p_vx1
            assert mf_fx0(kappa, fz, 1.0, tp) == pytest.approx(ref, rel=0, abs=1e-9 * fz)
    for fz in (2958.4, 4000.0):
        textbook = _fx0_at_zero_slip(p, fz, svx_inside_the_sine=False)
        inside = _fx0_at_zero_slip(p, fz, svx_inside_the_sine=True)
        assert mf_fx0(0.0, fz, 1.0, tp) == pytest.approx(textbook, rel=0, abs=1e-9 * fz)
        cr = tm.formula_longitudinal(0.0, 0.0, fz, p)
        assert cr == pytest.approx(inside, rel=0, abs=1e-9 * fz)
        assert textbook - inside > 90.0  # the quirk moves the free-rolling force by 90-165 N
    assert f"{_fx0_at_zero_slip(p, 2958.4, svx_inside_the_sine=False):.1f}" == "81.1"
    assert f"{_fx0_at_zero_slip(p, 2958.4, svx_inside_the_sine=True):.1f}" == "-9.4"
    assert f"{_fx0_at_zero_slip(p, 4000.0, svx_inside_the_sine=True):.1f}" == "-55.8"


# ============================================================================================
# Pacejka 205/60R15 evaluated table (VEHICLE_MODEL.md section 2.6)
# ============================================================================================
@pytest.mark.parametrize(
    "fz, c_alpha, c_alpha_per_fz, k_x, mu_y, mu_x",
    [
        (2000.0, "26609", "13.30", "38204", "1.062", "1.228"),
        (3000.0, "37467", "12.49", "60811", "1.026", "1.219"),
        (4000.0, "46009", "11.50", "86040", "0.990", "1.210"),
        (5000.0, "52208", "10.44", "114127", "0.954", "1.201"),
        (6000.0, "56303", "9.38", "145326", "0.917", "1.192"),
    ],
)
def test_pacejka_205_60r15_table(fz, c_alpha, c_alpha_per_fz, k_x, mu_y, mu_x):
    """Stiffnesses and peak friction equal their closed forms from the TOML coefficients.

    With df_z = (F_z - F_z0)/F_z0 and gamma = 0 ([P12] 4.E13, 4.E15, 4.E23, 4.E25):
    C_alpha = |p_Ky1 F_z0 sin(p_Ky4 atan(F_z / (p_Ky2 F_z0)))| lambda_Ky,
    K_x = F_z (p_Kx1 + p_Kx2 df_z) exp(p_Kx3 df_z) lambda_Kx, mu_y = |p_Dy1 + p_Dy2 df_z|,
    mu_x = |p_Dx1 + p_Dx2 df_z|. Tolerance rel 1e-11: the stiffnesses are B C D with
    B = K / (C D + 1e-9 N), relative deviation 1e-9 N / (C D) (measured <= 4e-13); mu is exact.
    Second check: the closed forms printed to the sheet's digits (VEHICLE_MODEL.md section 2.6)
    are the sheet's text (Python's round-half-even: mu_y at 2000 N is exactly 1.0625 -> 1.062).
    """
    tire = load_tire("pacejka2006_205_60R15")
    dfz = (fz - tire.fz0) / tire.fz0
    z = fz / (tire.pky2 * tire.fz0)
    ca_ref = abs(tire.pky1 * tire.fz0 * math.sin(tire.pky4 * math.atan(z))) * tire.lambda_ky
    kx_ref = fz * (tire.pkx1 + tire.pkx2 * dfz) * math.exp(tire.pkx3 * dfz) * tire.lambda_kx
    muy_ref = abs(tire.pdy1 + tire.pdy2 * dfz)
    mux_ref = abs(tire.pdx1 + tire.pdx2 * dfz)
    assert cornering_stiffness(tire, fz) == pytest.approx(ca_ref, rel=1e-11)
    assert slip_stiffness(tire, fz) == pytest.approx(kx_ref, rel=1e-11)
    mx, my = friction_coefficients(tire, fz)
    assert my == pytest.approx(muy_ref, rel=1e-11)
    assert mx == pytest.approx(mux_ref, rel=1e-11)
    printed = (f"{ca_ref:.0f}", f"{ca_ref / fz:.2f}", f"{kx_ref:.0f}", f"{muy_ref:.3f}",
               f"{mux_ref:.3f}")
    assert printed == (c_alpha, c_alpha_per_fz, k_x, mu_y, mu_x)


def test_commonroad_stiffness_is_proportional_to_load():
    """CommonRoad set: C_alpha = 21.92 F_z and K_x = 22.303 F_z exactly (VEHICLE_MODEL.md 2.4).

    rel 1e-11: the only deviation is the 1e-9 N guard in B (relative 1e-12 at 1 kN).
    """
    tire = load_tire("commonroad")
    for fz in (1000.0, 2958.4, 7000.0):
        assert cornering_stiffness(tire, fz) == pytest.approx(21.92 * fz, rel=1e-11)
        assert slip_stiffness(tire, fz) == pytest.approx(22.303 * fz, rel=1e-11)


# ============================================================================================
# Properties of the bundled sets (hypothesis, derandomized)
# ============================================================================================
@pytest.mark.parametrize("name", BUNDLED)
@HSET
@given(kappa=kappas, alpha=alphas, fz=loads, mu=mus)
def test_curves_are_odd(name, kappa, alpha, fz, mu):
    """F_x0, F_y0 odd; combined F_x odd in kappa and even in alpha, F_y the other way round.

    Tolerance 1e-12 mu F_z: the code computes the same operations on negated arguments (atan,
    sin odd; cos and 1/sqrt(1+t^2) even), so only last-bit differences of libm are allowed.
    """
    tp = load_tire(name).to_array()
    tol = 1e-12 * 1.3 * mu * fz
    assert mf_fx0(-kappa, fz, mu, tp) == pytest.approx(-mf_fx0(kappa, fz, mu, tp), abs=tol)
    assert mf_fy0(-alpha, fz, mu, tp) == pytest.approx(-mf_fy0(alpha, fz, mu, tp), abs=tol)
    fx, fy = mf_combined(kappa, alpha, fz, mu, tp)
    for sk, sa in ((-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)):
        gx, gy = mf_combined(sk * kappa, sa * alpha, fz, mu, tp)
        assert gx == pytest.approx(sk * fx, abs=tol)
        assert gy == pytest.approx(sa * fy, abs=tol)


def test_commonroad_bundled_pure_curves_are_odd_as_shipped():
    """The CommonRoad file has no p_Ey3, p_Ex4: its pure-slip curves are odd without _odd()."""
    tire = load_tire("commonroad")
    a = np.linspace(0.0, 0.8, 33)
    assert np.array_equal(fy0(-a, 3000.0, tire), -fy0(a, 3000.0, tire))
    assert np.array_equal(fx0(-a, 3000.0, tire), -fx0(a, 3000.0, tire))


@pytest.mark.parametrize("name", BUNDLED)
@HSET
@given(kappa=st.floats(-50.0, 50.0), alpha=st.floats(-1.5, 1.5), fz=loads, mu=mus)
def test_pure_slip_bounded_by_mu_fz(name, kappa, alpha, fz, mu):
    """|F_x0| <= mu_x F_z and |F_y0| <= mu_y F_z (|sin| <= 1, S_V = 0 in the bundled sets).

    mu_x, mu_y include mu_scale. Tolerance 1e-12 relative: rounding only.
    """
    tire = load_tire(name)
    tp = tire.to_array()
    mx, my = friction_coefficients(tire, fz, mu_scale=mu)
    assert abs(mf_fx0(kappa, fz, mu, tp)) <= mx * fz * (1 + 1e-12)
    assert abs(mf_fy0(alpha, fz, mu, tp)) <= my * fz * (1 + 1e-12)


@pytest.mark.parametrize("name", BUNDLED)
@HSET
@given(fz=loads, mu=mus)
def test_slope_at_zero_slip_equals_stiffness(name, fz, mu):
    """Central difference of F_y0 and F_x0 at 0 equals cornering_stiffness and slip_stiffness.

    h = 1e-6: truncation error ~ (B h)^2 / 6 < 1e-9 relative for B <= 30 / mu_scale
    (B_y = 15.5, B_x = 11.6 for the CommonRoad set at mu_scale 1); the rounding error is
    ~ 1e-16 F(h) / h ~ 1e-16 K. Tolerance 1e-7 relative. The MF stiffness does not depend on
    mu_scale (B = K / (C D)), so the reference is evaluated at mu_scale = 1.
    """
    tire = load_tire(name)
    tp = tire.to_array()
    h = 1e-6
    dfy = (mf_fy0(h, fz, mu, tp) - mf_fy0(-h, fz, mu, tp)) / (2 * h)
    dfx = (mf_fx0(h, fz, mu, tp) - mf_fx0(-h, fz, mu, tp)) / (2 * h)
    assert -dfy == pytest.approx(cornering_stiffness(tire, fz), rel=1e-7)
    assert dfx == pytest.approx(slip_stiffness(tire, fz), rel=1e-7)
    # and stiffness does not change with mu_scale (guard eps only: 1e-12 relative)
    assert cornering_stiffness(tire, fz, mu_scale=mu) == pytest.approx(
        cornering_stiffness(tire, fz), rel=1e-10
    )


def test_stiffness_is_the_exact_slope_with_shift_terms():
    """With the book's shift terms (S_Hy, S_Hx != 0) the stiffness is the slope at slip 0.

    Same central difference and tolerance as above; the MF parameter K differs from that slope by
    about 0.1 % here, so the test distinguishes the two.
    """
    tire = dataclasses.replace(load_tire("pacejka2006_205_60R15"), **P06_SHIFTS)
    tp = tire.to_array()
    h = 1e-6
    for fz in (2000.0, 4000.0, 6500.0):
        dfy = (mf_fy0(h, fz, 1.0, tp) - mf_fy0(-h, fz, 1.0, tp)) / (2 * h)
        dfx = (mf_fx0(h, fz, 1.0, tp) - mf_fx0(-h, fz, 1.0, tp)) / (2 * h)
        assert abs(dfy) == pytest.approx(cornering_stiffness(tire, fz), rel=1e-7)
        assert dfx == pytest.approx(slip_stiffness(tire, fz), rel=1e-7)
    sym = load_tire("pacejka2006_205_60R15")
    assert cornering_stiffness(tire, 4000.0) != pytest.approx(
        cornering_stiffness(sym, 4000.0), rel=1e-4
    )


# ============================================================================================
# Friction-ellipse exceedance of the MF combined-slip formulation
# ============================================================================================
# e = (F_x/(mu_x F_z))^2 + (F_y/(mu_y F_z))^2. The weighting functions G_xalpha, G_ykappa reduce
# each force from its pure-slip value, but near the longitudinal peak with a small slip angle
# not enough to keep the resultant inside the friction ellipse: e exceeds 1 (without the
# weighting, G = 1, it would reach 2). The tests below bound that exceedance; they do not claim
# that the forces stay inside the ellipse.
#
# CommonRoad set: the bound is the supremum of e computed with the PEER's functions on the
# bundled coefficients (_commonroad_peer_ellipse). 205/60R15 set: the peer cannot represent it
# (load-dependent p_Dx2, p_Kx2, p_Kx3, p_Dy2, p_Ey2 and the degressive K_y law of [P12] 4.E25),
# so its bound is a measured value (regression guard, P06_ELLIPSE_SUP).

#: Fields of the bundled CommonRoad set that differ from CommonRoad's raw coefficients: the shift
#: and asymmetry terms, all 0 in the bundled (symmetrised) file.
_SYMMETRISED = {"p_hx1", "p_vx1", "p_hy1", "p_vy1", "r_hx1", "r_by3", "r_hy1", "r_vy1"}


def _commonroad_peer_tire(tm, p):
    """CommonRoad TireParameters carrying the bundled (symmetrised) ``commonroad`` coefficients.

    The inverse of ``_flatfree_like_commonroad``: r_hy1, r_vy1 change sign (both 0 here). The
    peer has no load dependence besides proportionality, and neither has the bundled set: the
    terms the peer lacks are asserted to be 0 (1 for the lambdas), so the peer object is the
    bundled tyre exactly. The gamma terms (p_dx3, p_hy3, ...) stay raw: they vanish at gamma = 0.
    """
    t = load_tire("commonroad")
    assert t.cornering_law == "proportional" and t.lambda_kx == t.lambda_ky == 1.0
    absent = ("pdx2", "pex2", "pex3", "pex4", "pkx2", "pkx3", "phx2", "pvx2", "pdy2", "pey2",
              "pey3", "phy2", "pvy2", "rex2", "rey2", "rhy2", "rvy2")
    assert all(getattr(t, f) == 0.0 for f in absent)
    q = dataclasses.replace(p, **{theirs: sign * getattr(t, ours)
                                  for ours, theirs, sign in _CR_NAMES})
    changed = {f.name for f in dataclasses.fields(p) if getattr(p, f.name) != getattr(q, f.name)}
    assert changed == _SYMMETRISED and all(getattr(q, f) == 0.0 for f in changed)
    return q


def _peer_ellipse_ratio(tm, q, kappa: float, alpha: float, fz: float) -> float:
    """e evaluated with CommonRoad's functions, as its MB calls them (s = -kappa)."""
    s = -kappa
    fx_0 = tm.formula_longitudinal(s, 0.0, fz, q)
    fy_0, mu_y = tm.formula_lateral(alpha, 0.0, fz, q)
    fx = tm.formula_longitudinal_comb(s, alpha, fx_0, q)
    fy = tm.formula_lateral_comb(s, alpha, 0.0, mu_y, fz, fy_0, q)
    return (fx / (q.p_dx1 * fz)) ** 2 + (fy / (mu_y * fz)) ** 2


#: Slip grid of the peer's ellipse search (kappa and alpha alike): 301 points, 3.1e-3 apart
#: near 0 (the maximum sits at |kappa| = 0.118, |alpha| = 0.082 rad), out to |slip| = 27.8,
#: which covers kappa / mu_scale and alpha / mu_scale of the similarity test (<= 20 and 16).
#: Beyond, e stays below 0.88 (a one-off measurement with flatfree out to |slip| = 1000).
_ELLIPSE_GRID = 0.3 * np.tan(np.linspace(-1.56, 1.56, 301))
_PEER_FZ = 4000.0


@functools.cache
def _commonroad_peer_ellipse():
    """(supremum of e, e on _ELLIPSE_GRID) of the bundled CommonRoad set, from the PEER's code.

    Grid, then Nelder-Mead (scipy) from the grid's best point to xatol 1e-10, fatol 1e-15: at a
    smooth maximum the value error is ~ H dx^2, far below 1e-12. The CommonRoad law makes every
    force proportional to F_z, so e does not depend on the load (measured: equal to 2e-16 at
    300-9000 N); the peer is evaluated at 4000 N. Measured: sup e = 1.2061304 at
    |kappa| = 0.1176, |alpha| = 0.0819 rad; the grid maximum is 1.2060741. Cost ~0.3 s, once.
    """
    from scipy.optimize import minimize

    tm, p = _cr_modules()
    q = _commonroad_peer_tire(tm, p)
    grid = np.array([[_peer_ellipse_ratio(tm, q, k, a, _PEER_FZ) for k in _ELLIPSE_GRID]
                     for a in _ELLIPSE_GRID])
    i, j = np.unravel_index(np.argmax(grid), grid.shape)
    res = minimize(lambda z: -_peer_ellipse_ratio(tm, q, z[0], z[1], _PEER_FZ),
                   [_ELLIPSE_GRID[j], _ELLIPSE_GRID[i]], method="Nelder-Mead",
                   options=dict(xatol=1e-10, fatol=1e-15, maxiter=4000))
    assert res.success
    sup = -float(res.fun)
    assert sup >= grid.max()
    return sup, grid


#: 205/60R15 set, mu_scale = 1: sup e = 1.04611 (measured with flatfree: Nelder-Mead over kappa,
#: alpha and F_z in [300, 9000] N from the best point of an 801 x 801 grid at eight loads,
#: 2026-11-22, after r_By3 and p_Ey3 were set to 0; re-measured 1.0461072 at |kappa| = 0.151,
#: |alpha| = 0.073 rad, F_z = 2243 N). Not a peer value: the bound is a regression guard of the
#: formulation that the CommonRoad tests verify against the peer.
P06_ELLIPSE_SUP = 1.04611


def _ellipse_bound(name: str) -> float:
    """Upper bound of e: the peer's supremum + 1e-9 (rounding; flatfree equals the peer to
    ~1e-13 in e, see test_commonroad_ellipse_exceedance_equals_the_peers_on_a_grid), or the
    205/60R15 regression value + 1e-3 (the margin it was recorded with)."""
    if name == "commonroad":
        return _commonroad_peer_ellipse()[0] + 1e-9
    return P06_ELLIPSE_SUP + 1e-3


@pytest.mark.parametrize("name", BUNDLED)
@settings(max_examples=150, deadline=None, derandomize=True)
@given(kappa=kappas, alpha=alphas, fz=loads)
def test_friction_ellipse_exceedance_is_bounded(name, kappa, alpha, fz):
    """e at mu_scale = 1 never exceeds the bound of _ellipse_bound (1.2061 CommonRoad set, from
    the peer's code; 1.0461 205/60R15 set, a regression guard of a measured value)."""
    tire = load_tire(name)
    mx, my = friction_coefficients(tire, fz)
    fx, fy = mf_combined(kappa, alpha, fz, 1.0, tire.to_array())
    assert (fx / (mx * fz)) ** 2 + (fy / (my * fz)) ** 2 <= _ellipse_bound(name)


def test_commonroad_ellipse_exceedance_equals_the_peers_on_a_grid():
    """flatfree's e on _ELLIPSE_GRID equals the peer's, pointwise to 1e-9 and in its maximum.

    Measured: max |e_flatfree - e_peer| = 1.6e-13 (the 1e-9 N guard in B and rounding); a 1 %
    change of any of r_Bx1, r_Bx2, r_Cx1, r_Ex1, r_By1, r_By2, r_Cy1, r_Ey1 moves e by 3.4e-4
    (r_Ey1) to 1.4e-2 (r_Cx1) somewhere on the grid, and replacing cos(atan(r_Bx2 kappa)) by
    its square in the code fails this test. flatfree at 300, 2958.4 and
    9000 N is compared with the peer at 4000 N: e is load-independent for this set (see
    _commonroad_peer_ellipse). The grid maximum is within the peer's supremum, and that
    supremum really exceeds the ellipse (> 1.2): the naming above is not a formality.
    """
    sup, peer = _commonroad_peer_ellipse()
    tire = load_tire("commonroad")
    k, a = np.meshgrid(_ELLIPSE_GRID, _ELLIPSE_GRID)
    for fz in (300.0, 2958.4, 9000.0):
        mx, my = friction_coefficients(tire, fz)
        fx, fy = combined(k, a, fz, tire)
        e = (fx / (mx * fz)) ** 2 + (fy / (my * fz)) ** 2
        assert np.max(np.abs(e - peer)) <= 1e-9
        assert e.max() == pytest.approx(peer.max(), rel=0, abs=1e-9)
        assert e.max() <= sup + 1e-9
    assert 1.2 < sup < 2.0


def test_205_60r15_ellipse_exceedance_grid_is_bounded():
    """A deterministic grid near the worst region (where hypothesis may not look), 205/60R15.

    Regression guard of P06_ELLIPSE_SUP (a value measured with flatfree, not from the peer).
    """
    tire = load_tire("pacejka2006_205_60R15")
    k, a = np.meshgrid(np.linspace(-0.3, 0.3, 121), np.linspace(-0.2, 0.2, 81))
    for fz in (1000.0, 2243.0, 4000.0, 8000.0):
        mx, my = friction_coefficients(tire, fz)
        fx, fy = combined(k, a, fz, tire)
        r = (fx / (mx * fz)) ** 2 + (fy / (my * fz)) ** 2
        assert r.max() <= _ellipse_bound("pacejka2006_205_60R15")


@pytest.mark.parametrize("name", BUNDLED)
@HSET
@given(kappa=kappas, alpha=alphas, fz=loads, mu=st.floats(0.05, 1.0))
def test_combined_is_a_similarity_in_mu(name, kappa, alpha, fz, mu):
    """F(kappa, alpha; mu) = mu F(kappa/mu, alpha/mu; 1) (weighting at slip / mu_scale).

    Hence the friction-ellipse exceedance e at any mu_scale is bounded by its supremum at
    mu_scale = 1 (checked below against _ellipse_bound). Tolerance 1e-12 x 1.3 F_z: rounding
    only.
    """
    tire = load_tire(name)
    tp = tire.to_array()
    fx, fy = mf_combined(kappa, alpha, fz, mu, tp)
    fx1, fy1 = mf_combined(kappa / mu, alpha / mu, fz, 1.0, tp)
    tol = 1e-12 * 1.3 * fz
    assert fx == pytest.approx(mu * fx1, abs=tol)
    assert fy == pytest.approx(mu * fy1, abs=tol)
    mx, my = friction_coefficients(tire, fz, mu_scale=mu)
    assert (fx / (mx * fz)) ** 2 + (fy / (my * fz)) ** 2 <= _ellipse_bound(name)


@pytest.mark.parametrize("shifted", [False, True])
@pytest.mark.parametrize("name", BUNDLED)
@HSET
@given(kappa=kappas, alpha=alphas, fz=loads, mu=mus)
def test_combined_reduces_to_pure_slip(name, shifted, kappa, alpha, fz, mu):
    """F_x(kappa, 0) = F_x0(kappa) and F_y(0, alpha) = F_y0(alpha), exactly.

    At zero other slip G = cos(x)/cos(x) of identical arguments (= 1.0 in IEEE arithmetic) and
    S_Vykappa = 0 at kappa = 0, also with the book's shift terms (shifted=True).
    """
    tire = load_tire(name)
    if shifted:
        tire = dataclasses.replace(tire, **P06_SHIFTS)
    tp = tire.to_array()
    assert mf_combined(kappa, 0.0, fz, mu, tp)[0] == mf_fx0(kappa, fz, mu, tp)
    assert mf_combined(0.0, alpha, fz, mu, tp)[1] == mf_fy0(alpha, fz, mu, tp)


@pytest.mark.parametrize("name", BUNDLED)
@HSET
@given(kappa=kappas, alpha=alphas, fz=loads, mu=mus)
def test_mu_scale_is_a_similarity(name, kappa, alpha, fz, mu):
    """F_0(s; mu) = mu F_0(s / mu; 1): mu_scale scales the peak by mu and keeps the stiffness.

    Exact for the MF with lambda_mu in D and S_V = S_H = 0: D ~ mu, B ~ 1/mu, C and E do not
    depend on mu. Tolerance 1e-12 mu F_z: B s computed as (B/mu) s vs B (s/mu), rounding only.
    """
    tp = load_tire(name).to_array()
    tol = 1e-12 * 1.3 * fz
    assert mf_fx0(kappa, fz, mu, tp) == pytest.approx(mu * mf_fx0(kappa / mu, fz, 1.0, tp), abs=tol)
    assert mf_fy0(alpha, fz, mu, tp) == pytest.approx(mu * mf_fy0(alpha / mu, fz, 1.0, tp), abs=tol)


@pytest.mark.parametrize("name", BUNDLED)
def test_mu_scale_scales_the_peak(name):
    """Peak |F_y0| over a fine alpha grid equals mu_scale mu_y F_z (grid error < 1e-6 relative).

    The grid step 1e-4 rad near a smooth maximum costs ~ (B dalpha)^2 < 1e-5 relative; 1e-5 tol.
    """
    tire = load_tire(name)
    a = np.linspace(0.0, 0.6, 6001)
    for mu in (0.3, 1.0):
        for fz in (2000.0, 5000.0):
            my = friction_coefficients(tire, fz)[1]
            assert np.max(np.abs(fy0(a, fz, tire, mu))) == pytest.approx(mu * my * fz, rel=1e-5)


@HSET
@given(
    kappa=st.floats(-1e6, 1e6), alpha=st.floats(-1.57, 1.57), fz=st.floats(-1e4, 1e6),
    mu=st.floats(1e-3, 10.0),
)
def test_never_nan_and_zero_at_lift_off(kappa, alpha, fz, mu):
    """Forces are finite for any finite input, and exactly 0 for F_z <= 0 (lift-off)."""
    for name in BUNDLED:
        tp = _shifted(name).to_array()
        fx, fy = mf_combined(kappa, alpha, fz, mu, tp)
        f1, f2 = mf_fx0(kappa, fz, mu, tp), mf_fy0(alpha, fz, mu, tp)
        assert all(math.isfinite(v) for v in (fx, fy, f1, f2))
        if fz <= 0.0:
            assert (fx, fy, f1, f2) == (0.0, 0.0, 0.0, 0.0)


def _shifted(name):
    return dataclasses.replace(load_tire(name), **P06_SHIFTS)


def test_tiny_load_is_finite():
    """B = K / (C D + eps) stays finite as F_z -> 0+ (K and D both ~ F_z)."""
    for name in BUNDLED:
        tp = load_tire(name).to_array()
        for fz in (1e-300, 1e-12, 1e-3):
            fx, fy = mf_combined(0.1, 0.1, fz, 1.0, tp)
            assert math.isfinite(fx) and math.isfinite(fy)
            assert abs(fx) <= 2 * fz and abs(fy) <= 2 * fz


# ============================================================================================
# Linear tyre and signs
# ============================================================================================
def test_linear_tyre_sign_and_agreement_with_mf_at_small_slip():
    """ISO sign: positive alpha gives negative force; MF ~ linear tyre at 1e-4 rad.

    Relative difference ~ (B alpha)^2 ~ 2.4e-6 for B_y = 15.5; tolerance 1e-5.
    """
    assert linear_fy(0.01, 1e5) == -1000.0
    tire = load_tire("commonroad")
    c = cornering_stiffness(tire, 3000.0)
    assert fy0(1e-4, 3000.0, tire) == pytest.approx(linear_fy(1e-4, c), rel=1e-5)
    assert fx0(1e-4, 3000.0, tire) > 0.0  # driving slip gives traction


# ============================================================================================
# Slip definitions and their low-speed regularisation
# ============================================================================================
V_MIN = 2.0


@settings(max_examples=100, deadline=None, derandomize=True)
@given(v=st.floats(-50.0, 50.0), w=st.floats(-60.0, 60.0), vy=st.floats(-10.0, 10.0))
def test_slips_equal_plain_definitions_above_v_min(v, w, vy):
    """For |v_xw| >= v_min the slips are exactly (w - v)/|v| and atan(v_y/|v|)."""
    if abs(v) < V_MIN:
        v = math.copysign(V_MIN + abs(v), v)
    assert slip_ratio(w, v, V_MIN) == (w - v) / abs(v)
    assert slip_angle(v, vy, V_MIN) == math.atan(vy / abs(v))


@settings(max_examples=100, deadline=None, derandomize=True)
@given(v=st.floats(-5.0, 5.0), w=st.floats(-60.0, 60.0), vy=st.floats(-1e6, 1e6))
def test_slips_finite_and_bounded_at_low_speed(v, w, vy):
    """Finite everywhere; the denominator is >= 3 v_min / 8, alpha in (-pi/2, pi/2)."""
    k = slip_ratio(w, v, V_MIN)
    a = slip_angle(v, vy, V_MIN)
    assert math.isfinite(k) and abs(k) <= abs(w - v) / (0.375 * V_MIN) * (1 + 1e-15)
    assert -math.pi / 2 <= a <= math.pi / 2


def test_slip_speed_is_c2_and_monotone():
    """s(v) is even, increasing, s(0) = 3 v_min / 8, and C2 at |v| = v_min.

    C2 check: for the quartic, s(v_min - h) - (v_min - h) = h^3 / (2 v_min^2) - h^4 / (8 v_min^3)
    exactly (Taylor at v_min: s = v_min, s' = 1, s'' = 0, s''' = -3/v_min^2, s'''' = -3/v_min^3),
    about 5e-7 v_min at h = 0.01 v_min; a merely C1 blend would leave ~ h^2 / (2 v_min) =
    5e-5 v_min. Tolerance 1e-14 absolute (rounding of values ~ 3).
    """
    vm = 3.0
    assert slip_speed(0.0, vm) == 0.375 * vm
    v = np.linspace(0.0, 2 * vm, 2001)
    s = np.array([slip_speed(x, vm) for x in v])
    assert np.all(np.diff(s) > 0.0)
    assert np.array_equal(s, [slip_speed(-x, vm) for x in v])
    assert np.all(s >= v - 1e-15)  # a max: never below |v|
    for h in (0.03, 0.003):
        ref = h**3 / (2 * vm**2) - h**4 / (8 * vm**3)
        assert slip_speed(vm - h, vm) - (vm - h) == pytest.approx(ref, abs=1e-14)
    assert slip_speed(vm, vm) == vm


def test_slips_continuous_through_standstill():
    """kappa, alpha continuous at v_xw = 0 (difference across +-1e-9 m/s below 1e-8)."""
    for w in (-1.0, 0.0, 0.5):
        assert abs(slip_ratio(w, 1e-9, V_MIN) - slip_ratio(w, -1e-9, V_MIN)) < 1e-8
        assert math.isfinite(slip_ratio(w, 0.0, V_MIN))
    assert abs(slip_angle(1e-9, 0.3, V_MIN) - slip_angle(-1e-9, 0.3, V_MIN)) < 1e-8
    k, a = slips([0.5, 0.0], [0.0, 0.0], [0.0, 0.2], V_MIN)
    assert k[0] == 0.5 / (0.375 * V_MIN) and a[1] == math.atan(0.2 / (0.375 * V_MIN))


# ============================================================================================
# numpy wrappers and validation
# ============================================================================================
def test_wrappers_equal_kernels_and_broadcast():
    tire = load_tire("pacejka2006_205_60R15")
    tp = tire.to_array()
    k = np.linspace(-0.4, 0.4, 7)
    a = np.linspace(-0.2, 0.2, 5)[:, None]
    fz = np.array([1500.0, 3000.0, 0.0, 4500.0, -1.0])[:, None]
    fx, fy = combined(k, a, fz, tire, mu_scale=0.8)
    assert fx.shape == fy.shape == (5, 7)
    for i in range(5):
        for j in range(7):
            assert (fx[i, j], fy[i, j]) == mf_combined(k[j], a[i, 0], fz[i, 0], 0.8, tp)
    assert isinstance(fx0(0.1, 3000.0, tire), float)
    assert fy0(a, 3000.0, tire).shape == (5, 1)


@pytest.mark.parametrize("bad", [0.0, -0.5, float("nan"), float("inf"), [1.0, 0.0]])
def test_bad_mu_scale_raises(bad):
    tire = load_tire("commonroad")
    for call in (
        lambda: fx0(0.1, 3000.0, tire, bad),
        lambda: fy0(0.1, 3000.0, tire, bad),
        lambda: combined(0.1, 0.1, 3000.0, tire, bad),
        lambda: cornering_stiffness(tire, 3000.0, mu_scale=bad),
    ):
        with pytest.raises(ValueError, match="mu_scale"):
            call()


def test_other_bad_inputs_raise():
    tire = load_tire("commonroad")
    for fz in (0.0, -1.0, float("nan"), "x"):
        with pytest.raises(ValueError, match="fz"):
            cornering_stiffness(tire, fz)
        with pytest.raises(ValueError, match="fz"):
            slip_stiffness(tire, fz)
    with pytest.raises(ValueError, match="tire"):
        fx0(0.1, 3000.0, tire.to_array())
    with pytest.raises(ValueError, match="kappa"):
        fx0([0.1, float("nan")], 3000.0, tire)
    with pytest.raises(ValueError, match="v_min"):
        slips(1.0, 1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="v_min"):
        slips(1.0, 1.0, 0.0, -1.0)


@pytest.mark.parametrize(("call", "msg"), [
    (lambda tire: fx0("1.0", 3000.0, tire), "kappa = '1.0': expected real numbers, got dtype <U3"),
    (lambda tire: fy0([True, False], 3000.0, tire),
     "alpha = [True, False] rad: expected real numbers, got dtype bool"),
    (lambda tire: combined(0.1, 0.1, [3000.0, None], tire),
     "fz = [3000.0, None] N: expected real numbers, got dtype object"),
    (lambda tire: slips(1.0, "1.0", 0.0, 1.0),
     "vxw = '1.0' m/s: expected real numbers, got dtype <U3"),
    (lambda tire: slips(1.0, 1.0, 0.0, True),
     "v_min = True m/s: expected real numbers, got dtype bool"),
    (lambda tire: fx0(0.1, 3000.0, tire, "1.0"),
     "mu_scale = '1.0': expected real numbers, got dtype <U3"),
    # the one-tyre functions take one load and one friction scale: not text, not a list
    (lambda tire: cornering_stiffness(tire, 3000.0, mu_scale=True),
     "mu_scale = True: expected a real number"),
    (lambda tire: friction_coefficients(tire, 3000.0, mu_scale=[None]),
     "mu_scale = [None]: expected a real number"),
    (lambda tire: slip_stiffness(tire, 3000.0, mu_scale=np.array([1.0, 0.8])),
     "mu_scale = array([1. , 0.8]): expected a real number"),
    (lambda tire: cornering_stiffness(tire, "3000"), "fz = '3000' N: expected a real number"),
    (lambda tire: friction_coefficients(tire, [3000.0]),
     "fz = [3000.0] N: expected a real number"),
])
def test_arrays_that_are_not_real_numbers_are_refused_by_name(call, msg):
    # float64 reads "1.0" and True as numbers and a None as a silent NaN: refused, by name
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        call(load_tire("commonroad"))
