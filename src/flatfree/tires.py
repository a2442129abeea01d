"""Tyre force laws: slip definitions, the linear tyre, the Magic Formula (pure and combined slip).

Conventions
-----------
ISO 8855 wheel axes (x along the wheel heading, y to its left, z up), SI units. For a wheel whose
contact point moves with ``(v_xw, v_yw)`` in wheel axes and whose circumferential speed is
``Omega * R_e``:

* slip ratio  ``kappa = (Omega R_e - v_xw) / |v_xw|``: positive when driving, and then ``F_x > 0``;
* slip angle  ``alpha = atan(v_yw / |v_xw|)``: positive ``alpha`` gives ``F_y < 0``
  (``F_y ~ -C_alpha alpha``), the sign of the ``.tir`` coefficients (``p_Ky1 < 0``) and of
  CommonRoad (VEHICLE_MODEL.md section 0). The paper's ``alpha`` is ``-alpha`` here and its
  ``C_f``, ``C_r`` are positive per-axle stiffnesses.

Forces are returned in wheel axes; rotating them into body axes is the vehicle model's job.

Low-speed regularisation
------------------------
Both slips divide by ``|v_xw|``. At standstill the slip gain ``d kappa / d Omega = R_e / |v_xw|``
is unbounded, and the wheel-spin mode of ``I_w dOmega/dt = -R_e F_x`` has the eigenvalue
``-R_e^2 C_kappa / (I_w |v_xw|)``, which leaves the stability region of any explicit
fixed-step integrator below a speed ``v*`` (about 1.7 m/s for the CommonRoad set at 1 ms with
RK4; VEHICLE_MODEL.md section 3). The slip definitions here therefore divide by a smooth
maximum of ``|v_xw|`` and a floor speed ``v_min`` > 0 (remedy 1 of VEHICLE_MODEL.md section 3):

    s(v) = |v|                                               for |v| >= v_min
    s(v) = 3 v_min / 8 + 3 v^2 / (4 v_min) - v^4 / (8 v_min^3)    for |v| <  v_min

``s`` is even, increasing in ``|v|``, at least ``3 v_min / 8`` and twice continuously
differentiable (value, slope 1 and curvature 0 match at ``|v| = v_min``), so an RK4 step sees a
C2 right-hand side. Above ``v_min`` the slips equal the plain definitions exactly. Below it the
tyre acts as a viscous damper: ``F_x ~ C_kappa (Omega R_e - v_xw) / s(v_xw)`` is a force
proportional to the slip *speed*, with damping coefficient ``C_kappa / s`` between
``C_kappa / v_min`` and ``8 C_kappa / (3 v_min)``; the wheel-spin time constant no longer goes
to zero but stays at least ``I_w s(0) / (R_e^2 C_kappa)`` (so choose ``3 v_min / 8 >= v*``
for RK4 to be stable at standstill). ``kappa`` and ``alpha`` stay finite at ``v_xw = 0``, and
``alpha`` is within ``(-pi/2, pi/2)`` for every finite ``v_yw``.

Magic Formula
-------------
MF 5.2 / 6.x equations of [P12] section 4.3.2 at camber 0, without turn slip and pressure
terms, all scaling factors 1 except ``lambda_mu`` (the road, ``mu_scale``) and ``lambda_Kx``,
``lambda_Ky`` (``TireParams.lambda_kx``, ``lambda_ky``). ``mu_scale = mu_road / mu_ref``
multiplies the friction coefficients ``mu_x``, ``mu_y`` (4.E13, 4.E23) and, as in MF 5.2, the
vertical shifts ``S_Vx``, ``S_Vy`` (4.E18, 4.E29); because ``B = K / (C D)`` the slip and
cornering stiffnesses do not change with ``mu_scale`` (VEHICLE_MODEL.md section 1.9). A vertical
load ``F_z <= 0`` (lift-off) gives zero force. The cornering stiffness follows
``TireParams.cornering_law``: ``"mf52"`` is 4.E25 (degressive in load), ``"proportional"`` is
CommonRoad's ``K_y = p_Ky1 F_z``.

Differences from CommonRoad's ``vehiclemodels.utils.tire_model`` (VEHICLE_MODEL.md section 2.4):
flatfree adds ``S_Vx`` outside the sine as in the textbook (CommonRoad adds it inside), and it
uses the ISO ``kappa`` in the combined lateral force (CommonRoad passes ``-kappa`` there, which
flips the sign of its ``r_Hy1`` and ``r_Vy1`` terms). At camber 0 both are otherwise the same
formulas; ``tests/test_tires.py`` checks them against each other to 1e-9. (CommonRoad also
multiplies ``S_Hy``, ``S_Vy`` by ``sgn(gamma)``, so at camber 0 they vanish there; flatfree uses
``p_Hy1``, ``p_Vy1`` as given.)

Limits of the MF combined-slip formulation (measured, see ``tests/test_tires.py``): the weighting
functions ``G`` reduce each force from its pure-slip value but do not keep the resultant inside
the friction ellipse. At ``mu_scale = 1``, ``(F_x/(mu_x F_z))^2 + (F_y/(mu_y F_z))^2`` reaches
1.2061 for the CommonRoad set (the supremum, from CommonRoad's own functions) and 1.0461 for the
205/60R15 set (near the longitudinal peak with a small slip angle); the hard bound is 2
(``|G| <= 1``). On a road of lower friction the excess is the same: :func:`mf_combined`
evaluates ``G`` at slip / ``mu_scale``, so the forces are a similarity in ``mu_scale``
(``tests/test_tires.py``, ``test_combined_is_a_similarity_in_mu``; the plain MF 5.2 weighting
would reach 1.51 at ``mu_scale = 0.5`` and 1.93 at 0.1: benchmarks/README.md "Friction-ellipse
exceedance on low-friction roads").

Compiled kernels (``numba.njit``, scalars in, scalars out, no allocation): :func:`slip_speed`,
:func:`slip_ratio`, :func:`slip_angle`, :func:`mf_fx0`, :func:`mf_fy0`, :func:`mf_combined`,
:func:`linear_fy`. They take the tyre as the array ``TireParams.to_array()`` (indexed by ``TP``)
and do not validate their input. The numpy wrappers :func:`fx0`, :func:`fy0`, :func:`combined`,
:func:`slips` and the stiffness functions validate and loop over the same kernels.
:func:`mf_combined4` evaluates :func:`mf_combined` for four tyres at once in SIMD lanes (the
10DoF model's fast path): the same formulas without branches and with the polynomial
elementary functions of ``flatfree._vecmath``, equal to :func:`mf_combined` to round-off;
:func:`mf_combined` stays the reference kernel.

References
----------
[P12] H. B. Pacejka, Tire and Vehicle Dynamics, 3rd ed., Butterworth-Heinemann, 2012,
      section 4.3.2, eqs. (4.E1)-(4.E67).
[CR-tm] commonroad-vehicle-models 3.0.2, ``vehiclemodels/utils/tire_model.py``.
[VM] docs/VEHICLE_MODEL.md, sections 0, 1.6, 1.9, 2 and 3.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from flatfree import _vecmath as vm
from flatfree._validate import positive, real_array
from flatfree.vehicles.params import TP, TireParams

__all__ = [
    "slip_speed",
    "slip_ratio",
    "slip_angle",
    "mf_fx0",
    "mf_fy0",
    "mf_combined",
    "mf_combined4",
    "MF4_COLUMNS",
    "linear_fy",
    "cornering_stiffness",
    "slip_stiffness",
    "friction_coefficients",
    "fx0",
    "fy0",
    "combined",
    "slips",
]

#: Guard in B = K / (C D + eps) [N] ([P12] 4.E16, 4.E26 epsilon_x, epsilon_y); small enough to
#: change B by < 1e-12 relative at loads above 1 kN, large enough to keep B finite at D = 0.
EPS_CD_N = 1e-9

# Array indices, frozen as compile-time constants in the kernels. NOTE: numba's on-disk cache
# does not notice a change of the TP layout in params.py; clear the cache after editing it.
_FZ0 = int(TP.fz0)
_LAW = int(TP.cornering_law)
_PCX1, _PDX1, _PDX2 = int(TP.pcx1), int(TP.pdx1), int(TP.pdx2)
_PEX1, _PEX2, _PEX3, _PEX4 = int(TP.pex1), int(TP.pex2), int(TP.pex3), int(TP.pex4)
_PKX1, _PKX2, _PKX3 = int(TP.pkx1), int(TP.pkx2), int(TP.pkx3)
_PHX1, _PHX2, _PVX1, _PVX2 = int(TP.phx1), int(TP.phx2), int(TP.pvx1), int(TP.pvx2)
_PCY1, _PDY1, _PDY2 = int(TP.pcy1), int(TP.pdy1), int(TP.pdy2)
_PEY1, _PEY2, _PEY3 = int(TP.pey1), int(TP.pey2), int(TP.pey3)
_PKY1, _PKY2, _PKY4 = int(TP.pky1), int(TP.pky2), int(TP.pky4)
_PHY1, _PHY2, _PVY1, _PVY2 = int(TP.phy1), int(TP.phy2), int(TP.pvy1), int(TP.pvy2)
_RBX1, _RBX2, _RCX1, _REX1, _REX2, _RHX1 = (
    int(TP.rbx1), int(TP.rbx2), int(TP.rcx1), int(TP.rex1), int(TP.rex2), int(TP.rhx1)
)
_RBY1, _RBY2, _RBY3, _RCY1, _REY1, _REY2 = (
    int(TP.rby1), int(TP.rby2), int(TP.rby3), int(TP.rcy1), int(TP.rey1), int(TP.rey2)
)
_RHY1, _RHY2, _RVY1, _RVY2, _RVY4, _RVY5, _RVY6 = (
    int(TP.rhy1), int(TP.rhy2), int(TP.rvy1), int(TP.rvy2), int(TP.rvy4), int(TP.rvy5),
    int(TP.rvy6),
)
_LKX, _LKY = int(TP.lambda_kx), int(TP.lambda_ky)

_JIT = dict(cache=True, nogil=True, error_model="numpy")


# ============================================================================================
# Slip definitions
# ============================================================================================
@njit(**_JIT)
def slip_speed(vxw: float, v_min: float) -> float:
    """Smooth maximum of ``|vxw|`` and ``v_min`` [m/s]: the slip denominator (module docstring).

    Equals ``|vxw|`` for ``|vxw| >= v_min``; below, the even quartic
    ``3 v_min/8 + 3 v^2/(4 v_min) - v^4/(8 v_min^3)``, C2 at ``|vxw| = v_min``.
    ``v_min <= 0`` gives the plain ``|vxw|``.
    """
    a = abs(vxw)
    if a >= v_min:
        return a
    r2 = (a / v_min) ** 2
    # [VM] section 3 remedy 1, smoothed [derived]: value v_min, slope 1, curvature 0 at v_min
    return v_min * (0.375 + r2 * (0.75 - 0.125 * r2))


@njit(**_JIT)
def slip_ratio(omega_re: float, vxw: float, v_min: float) -> float:
    """Longitudinal slip ``kappa = (Omega R_e - v_xw) / s(v_xw)`` [-], positive when driving.

    Parameters
    ----------
    omega_re : wheel spin times effective rolling radius, ``Omega * R_e`` [m/s].
    vxw : contact-point speed along the wheel heading [m/s].
    v_min : floor speed of the smooth slip denominator ``s`` [m/s] (module docstring).

    References
    ----------
    [VM] sections 0 and 1.6 (ISO sign).
    """
    return (omega_re - vxw) / slip_speed(vxw, v_min)  # [VM] 1.6


@njit(**_JIT)
def slip_angle(vxw: float, vyw: float, v_min: float) -> float:
    """Slip angle ``alpha = atan(v_yw / s(v_xw))`` [rad]; positive alpha gives ``F_y < 0``.

    Parameters
    ----------
    vxw, vyw : contact-point velocity in wheel axes [m/s].
    v_min : floor speed of the smooth slip denominator ``s`` [m/s] (module docstring).

    References
    ----------
    [VM] sections 0 and 1.6.
    """
    return math.atan(vyw / slip_speed(vxw, v_min))  # [VM] 1.6, ISO sign


@njit(**_JIT)
def linear_fy(alpha: float, c_alpha: float) -> float:
    """Linear tyre: ``F_y = -C_alpha alpha`` [N] (ISO sign, ``C_alpha > 0`` [N/rad]).

    References
    ----------
    [VM] section 0; the paper's ``F_y = C alpha_paper`` with ``alpha_paper = -alpha``.
    """
    return -c_alpha * alpha


# ============================================================================================
# Magic Formula building blocks
# ============================================================================================
@njit(**_JIT)
def _sgn(x: float) -> float:
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@njit(**_JIT)
def _mf_phi(bx: float, e: float) -> float:
    """The MF inner argument ``B x - E (B x - atan(B x))`` ([P12] 4.E9)."""
    return bx - e * (bx - math.atan(bx))


@njit(**_JIT)
def _dfz(fz: float, tp: np.ndarray) -> float:
    """Normalised load change ``df_z = (F_z - F_z0) / F_z0`` ([P12] 4.E2a, lambda_Fz0 = 1)."""
    fz0 = tp[_FZ0]
    return (fz - fz0) / fz0


@njit(**_JIT)
def _long_coeffs(fz: float, dfz: float, mu_scale: float, tp: np.ndarray):
    """Pure longitudinal slip coefficients at load ``fz`` > 0: (B, C, D, E0, S_H, S_V, mu_x).

    E0 is E_x without its sgn(kappa_x) factor. [P12] 4.E11-4.E18.
    """
    c = tp[_PCX1]  # 4.E11
    mu = (tp[_PDX1] + tp[_PDX2] * dfz) * mu_scale  # 4.E13, lambda_mux = mu_scale
    d = mu * fz  # 4.E12
    k = fz * (tp[_PKX1] + tp[_PKX2] * dfz) * tp[_LKX]  # 4.E15
    if tp[_PKX3] != 0.0:
        k *= math.exp(tp[_PKX3] * dfz)  # 4.E15
    cd = c * d
    b = k / (cd + math.copysign(EPS_CD_N, cd))  # 4.E16
    e0 = tp[_PEX1] + (tp[_PEX2] + tp[_PEX3] * dfz) * dfz  # 4.E14
    sh = tp[_PHX1] + tp[_PHX2] * dfz  # 4.E17
    sv = fz * (tp[_PVX1] + tp[_PVX2] * dfz) * mu_scale  # 4.E18 (MF 5.2: times lambda_mux)
    return b, c, d, e0, sh, sv, mu


@njit(**_JIT)
def _lat_coeffs(fz: float, dfz: float, mu_scale: float, tp: np.ndarray):
    """Pure lateral slip coefficients at load ``fz`` > 0: (B, C, D, E0, S_H, S_V, mu_y).

    E0 is E_y without its sgn(alpha_y) factor. [P12] 4.E21-4.E30 with gamma = 0.
    """
    fz0 = tp[_FZ0]
    c = tp[_PCY1]  # 4.E21
    mu = (tp[_PDY1] + tp[_PDY2] * dfz) * mu_scale  # 4.E23, lambda_muy = mu_scale
    d = mu * fz  # 4.E22
    if tp[_LAW] == 0.0:
        # 4.E25 (MF 6.x with p_Ky4; MF 5.2 has p_Ky4 = 2), degressive in load
        z = fz / (tp[_PKY2] * fz0)
        if tp[_PKY4] == 2.0:
            k = tp[_PKY1] * fz0 * 2.0 * z / (1.0 + z * z)  # sin(2 atan z) = 2 z / (1 + z^2)
        else:
            k = tp[_PKY1] * fz0 * math.sin(tp[_PKY4] * math.atan(z))
    else:
        k = tp[_PKY1] * fz  # [CR-tm] formula_lateral: K_y = p_ky1 F_z
    k *= tp[_LKY]
    cd = c * d
    b = k / (cd + math.copysign(EPS_CD_N, cd))  # 4.E26
    e0 = tp[_PEY1] + tp[_PEY2] * dfz  # 4.E24
    sh = tp[_PHY1] + tp[_PHY2] * dfz  # 4.E27 (gamma = 0)
    sv = fz * (tp[_PVY1] + tp[_PVY2] * dfz) * mu_scale  # 4.E29 (MF 5.2: times lambda_muy)
    return b, c, d, e0, sh, sv, mu


@njit(**_JIT)
def _fx0_core(kappa: float, fz: float, dfz: float, mu_scale: float, tp: np.ndarray):
    """(F_x0, mu_x) for ``fz`` > 0."""
    b, c, d, e0, sh, sv, mu = _long_coeffs(fz, dfz, mu_scale, tp)
    kx = kappa + sh  # 4.E10
    e = min(e0 * (1.0 - tp[_PEX4] * _sgn(kx)), 1.0)  # 4.E14, E_x <= 1
    return d * math.sin(c * math.atan(_mf_phi(b * kx, e))) + sv, mu  # 4.E9


@njit(**_JIT)
def _fy0_core(alpha: float, fz: float, dfz: float, mu_scale: float, tp: np.ndarray):
    """(F_y0, mu_y) for ``fz`` > 0."""
    b, c, d, e0, sh, sv, mu = _lat_coeffs(fz, dfz, mu_scale, tp)
    ay = alpha + sh  # 4.E20
    e = min(e0 * (1.0 - tp[_PEY3] * _sgn(ay)), 1.0)  # 4.E24, E_y <= 1
    return d * math.sin(c * math.atan(_mf_phi(b * ay, e))) + sv, mu  # 4.E19


# ============================================================================================
# Magic Formula kernels
# ============================================================================================
@njit(**_JIT)
def mf_fx0(kappa: float, fz: float, mu_scale: float, tp: np.ndarray) -> float:
    """Magic Formula longitudinal force in pure slip ``F_x0`` [N], wheel axes.

    Parameters
    ----------
    kappa : slip ratio [-] (ISO: positive when driving).
    fz : vertical load [N]; ``fz <= 0`` gives 0.
    mu_scale : road friction over reference friction, ``lambda_mux`` [-], > 0 (not checked).
    tp : ``TireParams.to_array()``.

    References
    ----------
    [P12] eqs. (4.E9)-(4.E18).
    """
    if not fz > 0.0:
        return 0.0
    return _fx0_core(kappa, fz, _dfz(fz, tp), mu_scale, tp)[0]


@njit(**_JIT)
def mf_fy0(alpha: float, fz: float, mu_scale: float, tp: np.ndarray) -> float:
    """Magic Formula lateral force in pure slip ``F_y0`` [N], wheel axes, camber 0.

    Parameters
    ----------
    alpha : slip angle [rad] (ISO: positive alpha gives negative force).
    fz : vertical load [N]; ``fz <= 0`` gives 0.
    mu_scale : road friction over reference friction, ``lambda_muy`` [-], > 0 (not checked).
    tp : ``TireParams.to_array()``.

    References
    ----------
    [P12] eqs. (4.E19)-(4.E30) with gamma = 0.
    """
    if not fz > 0.0:
        return 0.0
    return _fy0_core(alpha, fz, _dfz(fz, tp), mu_scale, tp)[0]


@njit(**_JIT)
def _weight(bx: float, c: float, e: float) -> float:
    """``cos(C atan(B x - E (B x - atan(B x))))``: numerator/denominator of G ([P12] 4.E51)."""
    return math.cos(c * math.atan(_mf_phi(bx, e)))


@njit(**_JIT)
def mf_combined(kappa: float, alpha: float, fz: float, mu_scale: float, tp: np.ndarray):
    """Magic Formula forces in combined slip ``(F_x, F_y)`` [N], wheel axes, camber 0.

    ``F_x = G_xalpha F_x0`` and ``F_y = G_ykappa F_y0 + S_Vykappa`` with the cosine weighting
    functions of [P12]. ``G = 1`` when the other slip is zero (and ``S_Vykappa = 0`` at
    ``kappa = 0``), so the combined forces reduce to the pure-slip forces exactly.

    Road friction (deviation from MF 5.2, where lambda_mu does not enter G): the weighting
    functions are evaluated at the slips divided by ``mu_scale``. Since the pure-slip curves obey
    ``F_0(s; mu) = mu F_0(s / mu; 1)`` (B = K / (C D)), the combined forces then obey the same
    similarity, ``F(kappa, alpha; mu) = mu F(kappa / mu, alpha / mu; 1)``: a low-friction road
    keeps the shape of the combined-slip envelope and its friction-ellipse exceedance. With the
    plain MF 5.2 weighting the exceedance (sup of the ellipse sum) grows from 1.21 at
    mu_scale = 1 to 1.51 at 0.5 and 1.93 at 0.1 for the bundled CommonRoad set (1.04, 1.39,
    1.91 for the 205/60R15 set; benchmarks/bench_tires.py, ``ellipse_exceedance``), i.e. a wet
    road would grip far outside its ellipse. At ``mu_scale = 1`` both are identical (and
    identical to CommonRoad's, see the tests).

    Parameters
    ----------
    kappa : slip ratio [-].
    alpha : slip angle [rad].
    fz : vertical load [N]; ``fz <= 0`` gives (0, 0).
    mu_scale : road friction over reference friction [-], > 0 (not checked).
    tp : ``TireParams.to_array()``.

    References
    ----------
    [P12] eqs. (4.E50)-(4.E57) (longitudinal) and (4.E58)-(4.E67) (lateral), gamma = 0.
    """
    if not fz > 0.0:
        return 0.0, 0.0
    dfz = _dfz(fz, tp)  # 4.E2a
    fx_0, _mux = _fx0_core(kappa, fz, dfz, mu_scale, tp)
    fy_0, muy = _fy0_core(alpha, fz, dfz, mu_scale, tp)

    # similarity under road friction (docstring): weighting functions at slip / mu_scale
    inv_mu = 1.0 / mu_scale
    kappa_m = kappa * inv_mu
    alpha_m = alpha * inv_mu

    # longitudinal: 4.E50-4.E57
    shxa = tp[_RHX1]  # 4.E57
    t = tp[_RBX2] * kappa_m
    bxa = tp[_RBX1] / math.sqrt(1.0 + t * t)  # 4.E54: cos(atan(t)) = 1/sqrt(1+t^2)
    cxa = tp[_RCX1]  # 4.E55
    exa = min(tp[_REX1] + tp[_REX2] * dfz, 1.0)  # 4.E56
    gxa = _weight(bxa * (alpha_m + shxa), cxa, exa)  # 4.E51, alpha_S = alpha + S_Hxalpha (4.E53)
    if shxa != 0.0:
        gxa /= _weight(bxa * shxa, cxa, exa)  # 4.E52 (= 1 when S_Hxalpha = 0)
    fx = gxa * fx_0  # 4.E50

    # lateral: 4.E58-4.E67
    shyk = tp[_RHY1] + tp[_RHY2] * dfz  # 4.E65
    t = tp[_RBY2] * (alpha_m - tp[_RBY3])
    byk = tp[_RBY1] / math.sqrt(1.0 + t * t)  # 4.E62
    cyk = tp[_RCY1]  # 4.E63
    eyk = min(tp[_REY1] + tp[_REY2] * dfz, 1.0)  # 4.E64
    gyk = _weight(byk * (kappa_m + shyk), cyk, eyk)  # 4.E59, kappa_S = kappa + S_Hykappa (4.E61)
    if shyk != 0.0:
        gyk /= _weight(byk * shyk, cyk, eyk)  # 4.E60
    fy = gyk * fy_0  # 4.E58
    dv = tp[_RVY1] + tp[_RVY2] * dfz
    if dv != 0.0:
        t = tp[_RVY4] * alpha_m
        dvyk = muy * fz * dv / math.sqrt(1.0 + t * t)  # 4.E67
        fy += dvyk * math.sin(tp[_RVY5] * math.atan(tp[_RVY6] * kappa_m))  # 4.E66, 4.E58
    return fx, fy


# ============================================================================================
# Four tyres at once: the same Magic Formula, branch-free, in SIMD lanes
# ============================================================================================
# The 10DoF model evaluates mf_combined for its four wheels at every right-hand side call.
# mf_combined4 evaluates the four together: one loop over 4 lanes whose body is straight-line
# arithmetic (selects instead of branches, the elementary functions of flatfree._vecmath
# instead of libm calls), which LLVM vectorises into 4-wide AVX registers. The formulas, their
# order of operations and their special cases are mf_combined's, line by line; only atan, sin,
# cos and exp differ from libm, by less than 2 ulp (flatfree._vecmath), so the forces agree to
# round-off (tests/test_tendof_fastpath.py: |difference| < 1e-12 mu F_z, measured 7e-16).
# forceinline: a call inside the lane loop would stop its vectorisation.
# fastmath "contract": fused multiply-adds in the lanes (rounding-level differences from
# mf_combined, which stays without them; the force tolerance of tests/test_tendof_fastpath.py).
_JIT_LANE = dict(cache=True, nogil=True, error_model="numpy", forceinline=True,
                 fastmath={"contract"})


@njit(**_JIT_LANE)
def _weight_v(bx: float, c: float, e: float) -> float:
    """:func:`_weight` with the vectorisable elementary functions."""
    return vm.cos(c * vm.atan(bx - e * (bx - vm.atan(bx))))


@njit(**_JIT_LANE)
def _mf_combined_lane(kappa, alpha, fz_in, mu_scale, ta, tb, use_a, general, g_plain=False):
    """One lane of :func:`mf_combined4`: :func:`mf_combined` without branches.

    ``ta``, ``tb`` are the two tyres' coefficient arrays as tuples (``_vecmath.as_tuple``) and
    ``use_a`` picks the lane's one; the 10DoF model passes its lane's column of a coefficient
    table twice instead (``models.tendof.lane_table``: one vector load per coefficient).
    ``general=False`` leaves out the terms that vanish
    identically for both tyres (checked by the caller with :func:`_lanes_general`):
    ``S_Hxalpha``, ``S_Hykappa``, ``S_Vykappa`` and the ``sin(p_Ky4 atan z)`` form of 4.E25;
    ``general=True`` evaluates them and selects per lane, as ``mf_combined`` branches. The four
    Magic Formula curves (F_x0, F_y0, G_xalpha, G_ykappa) are evaluated step by step side by
    side, so that the processor overlaps their four dependency chains.

    ``g_plain=True`` (with ``general=False``; checked by the caller with :func:`_lanes_g_plain`)
    is for tyres whose weighting curvature factors ``r_Ex1, r_Ex2, r_Ey1, r_Ey2`` are all 0:
    then ``E_xalpha = E_ykappa = 0`` exactly, the second arc tangent of each weighting curve,
    ``atan(B x - 0 (B x - atan(B x)))``, is the first one, and it is not evaluated again (the
    same forces bit for bit, two arc tangents fewer per lane).

    A loop over 4 lanes that calls this (``forceinline``) vectorises when it touches no memory
    but one array at a known stride (:func:`_mf_lanes_loop`): with other arrays LLVM would need
    run-time alias checks, which it does not allow in a loop of 4 iterations.
    """
    tp = ta if use_a else tb  # the lane's tyre (a select per coefficient after inlining)
    fz_ok = fz_in > 0.0  # mf_combined: fz <= 0 (or NaN) gives (0, 0)
    fz0 = tp[_FZ0]
    fz = fz_in if fz_ok else fz0  # a harmless load for the lanes whose result is discarded
    dfz = (fz - fz0) / fz0  # 4.E2a

    # ---- pure longitudinal slip coefficients: _long_coeffs ----
    c_x = tp[_PCX1]  # 4.E11
    mu_x = (tp[_PDX1] + tp[_PDX2] * dfz) * mu_scale  # 4.E13
    d_x = mu_x * fz  # 4.E12
    k = fz * (tp[_PKX1] + tp[_PKX2] * dfz) * tp[_LKX]  # 4.E15
    pkx3 = tp[_PKX3]
    k_e = k * vm.exp(pkx3 * dfz)
    k = k_e if pkx3 != 0.0 else k  # 4.E15
    cd = c_x * d_x
    b_x = k / (cd + math.copysign(EPS_CD_N, cd))  # 4.E16
    e0 = tp[_PEX1] + (tp[_PEX2] + tp[_PEX3] * dfz) * dfz  # 4.E14
    sh = tp[_PHX1] + tp[_PHX2] * dfz  # 4.E17
    sv_x = fz * (tp[_PVX1] + tp[_PVX2] * dfz) * mu_scale
    kx = kappa + sh  # 4.E10
    sgn = 1.0 if kx > 0.0 else (-1.0 if kx < 0.0 else 0.0)  # _sgn
    e_x = min(e0 * (1.0 - tp[_PEX4] * sgn), 1.0)  # 4.E14, E_x <= 1

    # ---- pure lateral slip coefficients: _lat_coeffs ----
    c_y = tp[_PCY1]  # 4.E21
    mu_y = (tp[_PDY1] + tp[_PDY2] * dfz) * mu_scale  # 4.E23
    d_y = mu_y * fz  # 4.E22
    pky1 = tp[_PKY1]
    z = fz / (tp[_PKY2] * fz0)
    k_mf = pky1 * fz0 * 2.0 * z / (1.0 + z * z)  # 4.E25, p_Ky4 = 2: sin(2 atan z)
    if general:
        pky4 = tp[_PKY4]
        k_gen = pky1 * fz0 * vm.sin(pky4 * vm.atan(z))  # 4.E25
        k_mf = k_mf if pky4 == 2.0 else k_gen
    k_pr = pky1 * fz  # [CR-tm] K_y = p_ky1 F_z
    k = k_mf if tp[_LAW] == 0.0 else k_pr
    k *= tp[_LKY]
    cd = c_y * d_y
    b_y = k / (cd + math.copysign(EPS_CD_N, cd))  # 4.E26
    e0 = tp[_PEY1] + tp[_PEY2] * dfz  # 4.E24
    sh = tp[_PHY1] + tp[_PHY2] * dfz  # 4.E27
    sv_y = fz * (tp[_PVY1] + tp[_PVY2] * dfz) * mu_scale
    ay = alpha + sh  # 4.E20
    sgn = 1.0 if ay > 0.0 else (-1.0 if ay < 0.0 else 0.0)  # _sgn
    e_y = min(e0 * (1.0 - tp[_PEY3] * sgn), 1.0)  # 4.E24, E_y <= 1

    # ---- combined-slip weighting coefficients: mf_combined ----
    inv_mu = 1.0 / mu_scale
    kappa_m = kappa * inv_mu
    alpha_m = alpha * inv_mu
    shxa = tp[_RHX1]  # 4.E57
    t = tp[_RBX2] * kappa_m
    bxa = tp[_RBX1] / math.sqrt(1.0 + t * t)  # 4.E54
    cxa = tp[_RCX1]  # 4.E55
    exa = min(tp[_REX1] + tp[_REX2] * dfz, 1.0)  # 4.E56
    shyk = tp[_RHY1] + tp[_RHY2] * dfz  # 4.E65
    t = tp[_RBY2] * (alpha_m - tp[_RBY3])
    byk = tp[_RBY1] / math.sqrt(1.0 + t * t)  # 4.E62
    cyk = tp[_RCY1]  # 4.E63
    eyk = min(tp[_REY1] + tp[_REY2] * dfz, 1.0)  # 4.E64

    # ---- the four curves side by side: y = trig(C atan(B x - E (B x - atan(B x)))) ----
    s_x = b_x * kx  # 4.E9
    s_y = b_y * ay  # 4.E19
    s_gx = bxa * (alpha_m + shxa)  # 4.E51, alpha_S = alpha + S_Hxalpha (4.E53)
    s_gy = byk * (kappa_m + shyk)  # 4.E59, kappa_S = kappa + S_Hykappa (4.E61)
    a_x = vm.atan(s_x)
    a_y = vm.atan(s_y)
    a_gx = vm.atan(s_gx)
    a_gy = vm.atan(s_gy)
    a_x = vm.atan(s_x - e_x * (s_x - a_x))  # _mf_phi
    a_y = vm.atan(s_y - e_y * (s_y - a_y))
    if not g_plain:
        a_gx = vm.atan(s_gx - exa * (s_gx - a_gx))
        a_gy = vm.atan(s_gy - eyk * (s_gy - a_gy))
    fx_0 = d_x * vm.sin(c_x * a_x) + sv_x  # 4.E9
    fy_0 = d_y * vm.sin(c_y * a_y) + sv_y  # 4.E19
    gxa = vm.cos(cxa * a_gx)  # 4.E51
    gyk = vm.cos(cyk * a_gy)  # 4.E59

    if general:
        gxa_s = gxa / _weight_v(bxa * shxa, cxa, exa)  # 4.E52
        gxa = gxa_s if shxa != 0.0 else gxa
        gyk_s = gyk / _weight_v(byk * shyk, cyk, eyk)  # 4.E60
        gyk = gyk_s if shyk != 0.0 else gyk
    fx = gxa * fx_0  # 4.E50
    fy = gyk * fy_0  # 4.E58
    if general:
        dv = tp[_RVY1] + tp[_RVY2] * dfz
        t = tp[_RVY4] * alpha_m
        dvyk = mu_y * fz * dv / math.sqrt(1.0 + t * t)  # 4.E67
        fy_v = fy + dvyk * vm.sin(tp[_RVY5] * vm.atan(tp[_RVY6] * kappa_m))  # 4.E66, 4.E58
        fy = fy_v if dv != 0.0 else fy
    return (fx if fz_ok else 0.0), (fy if fz_ok else 0.0)


@njit(**_JIT_LANE)
def _lanes_general(ta, tb) -> bool:
    """False when the terms that :func:`_mf_combined_lane` skips with ``general=False`` vanish
    identically for both tyres (the bundled sets): zero ``r_Hx1``, ``r_Hy1``, ``r_Hy2``,
    ``r_Vy1``, ``r_Vy2``, and ``p_Ky4 = 2`` unless the proportional law is used."""
    ga = (ta[_RHX1] != 0.0 or ta[_RHY1] != 0.0 or ta[_RHY2] != 0.0 or ta[_RVY1] != 0.0
          or ta[_RVY2] != 0.0 or (ta[_LAW] == 0.0 and ta[_PKY4] != 2.0))
    gb = (tb[_RHX1] != 0.0 or tb[_RHY1] != 0.0 or tb[_RHY2] != 0.0 or tb[_RVY1] != 0.0
          or tb[_RVY2] != 0.0 or (tb[_LAW] == 0.0 and tb[_PKY4] != 2.0))
    return ga or gb


@njit(**_JIT_LANE)
def _lanes_g_plain(ta, tb) -> bool:
    """True when both tyres have ``r_Ex1 = r_Ex2 = r_Ey1 = r_Ey2 = 0`` (the 205/60R15 set of
    the peugeot406): the weighting curves' ``E`` vanish (:func:`_mf_combined_lane`)."""
    return (ta[_REX1] == 0.0 and ta[_REX2] == 0.0 and ta[_REY1] == 0.0 and ta[_REY2] == 0.0
            and tb[_REX1] == 0.0 and tb[_REX2] == 0.0 and tb[_REY1] == 0.0
            and tb[_REY2] == 0.0)


@njit(**_JIT_LANE)
def _mf_lanes_loop(lanes, ta, tb) -> None:
    """The loop of :func:`mf_combined4` over ``lanes`` (float64[4, 6]).

    The row length is checked here so that LLVM knows the stride (6) of the lane loads and
    stores.
    """
    if lanes.shape[1] != 6:
        raise ValueError("mf_combined4: lanes must have 6 columns")
    if _lanes_general(ta, tb):
        for i in range(4):
            fx, fy = _mf_combined_lane(lanes[i, 4], lanes[i, 3], lanes[i, 0], lanes[i, 5], ta,
                                       tb, i < 2, True)
            lanes[i, 1] = fx
            lanes[i, 2] = fy
    elif _lanes_g_plain(ta, tb):
        for i in range(4):
            fx, fy = _mf_combined_lane(lanes[i, 4], lanes[i, 3], lanes[i, 0], lanes[i, 5], ta,
                                       tb, i < 2, False, True)
            lanes[i, 1] = fx
            lanes[i, 2] = fy
    else:
        for i in range(4):
            fx, fy = _mf_combined_lane(lanes[i, 4], lanes[i, 3], lanes[i, 0], lanes[i, 5], ta,
                                       tb, i < 2, False)
            lanes[i, 1] = fx
            lanes[i, 2] = fy


#: Columns of the ``lanes`` array of :func:`mf_combined4` (one row per tyre); the first five
#: are those of the 10DoF model's per-wheel diagnostics, which it evaluates its tyres in.
MF4_COLUMNS = ("fz", "fx", "fy", "alpha", "kappa", "mu_scale")
_NTP = len(TP)


@njit(**_JIT)
def mf_combined4(lanes, tp_front, tp_rear) -> None:
    """:func:`mf_combined` for four tyres at once (SIMD lanes), in place.

    The same forces as four calls of :func:`mf_combined` to round-off: the formulas and their
    order of operations are the same; ``atan``, ``sin``, ``cos``, ``exp`` are those of
    :mod:`flatfree._vecmath` (within 2 ulp of libm's). About 4x faster than the four calls
    (``benchmarks/bench_tires.py``: ~150 ns against ~600 ns) because LLVM evaluates the four
    tyres in one set of 4-wide vector instructions.

    Parameters
    ----------
    lanes : float64[4, 6] (C-contiguous is fastest)
        One row per tyre, columns :data:`MF4_COLUMNS`: vertical load ``F_z`` [N] (``<= 0``
        gives zero forces), ``F_x`` and ``F_y`` [N] (outputs, wheel axes), slip angle
        ``alpha`` [rad], slip ratio ``kappa`` [-], road friction scale ``mu_scale`` [-]
        (> 0, not checked).
    tp_front, tp_rear : float64[len(TP)]
        ``TireParams.to_array()`` of rows 0, 1 and of rows 2, 3 (the wheel order fl, fr, rl, rr
        of the 10DoF model).

    References
    ----------
    [P12] eqs. (4.E9)-(4.E30) and (4.E50)-(4.E67), gamma = 0 (as :func:`mf_combined`).
    """
    if lanes.shape[0] != 4:
        raise ValueError("mf_combined4: lanes must have shape (4, 6)")
    _mf_lanes_loop(lanes, vm.as_tuple(tp_front, _NTP), vm.as_tuple(tp_rear, _NTP))


# ============================================================================================
# Python layer: stiffnesses, friction, numpy wrappers (thin over the kernels above)
# ============================================================================================
def _check_tire(tire) -> None:
    if not isinstance(tire, TireParams):
        raise ValueError(f"tire = {tire!r}: expected a TireParams (see flatfree.load_tire)")


def _check_mu(mu_scale) -> np.ndarray:
    m = real_array("mu_scale", mu_scale)
    if not np.all(np.isfinite(m) & (m > 0.0)):
        raise ValueError(
            f"mu_scale = {mu_scale!r} (-): must be finite and > 0 (mu_road / mu_ref)"
        )
    return m


def _as_float_array(name: str, value, unit: str) -> np.ndarray:
    a = real_array(name, value, unit)
    if np.any(np.isnan(a)):
        raise ValueError(f"{name} = {value!r} {unit}: contains NaN")
    return a


def _mf_slope(b: float, c: float, d: float, e: float, x: float) -> float:
    """d/dx of ``D sin(C atan(phi(B x)))`` ([P12] 4.E9/4.E19 differentiated)."""
    bx = b * x
    phi = bx - e * (bx - math.atan(bx))
    dphi = b * (1.0 - e) + e * b / (1.0 + bx * bx)
    return d * c * math.cos(c * math.atan(phi)) * dphi / (1.0 + phi * phi)


def cornering_stiffness(tire: TireParams, fz: float, *, mu_scale: float = 1.0) -> float:
    """Cornering stiffness of one tyre ``|dF_y0/dalpha|`` at ``alpha = 0`` [N/rad], > 0.

    Equal to ``|K_yalpha|`` ([P12] 4.E25, or ``|p_Ky1| F_z`` for the proportional law, times
    ``lambda_ky``) when the horizontal shift ``S_Hy`` is 0, as in the bundled sets; otherwise the
    exact slope of the curve at ``alpha = 0``. Independent of ``mu_scale`` when ``S_Hy = 0``.
    For the 3DoF model's per-axle ``C_f``, ``C_r`` add the two tyres of the axle.

    Parameters
    ----------
    tire : the tyre coefficients.
    fz : vertical load on this tyre [N], > 0.
    mu_scale : road friction over reference friction [-], > 0.

    References
    ----------
    [P12] eqs. (4.E19)-(4.E26); [VM] sections 2.5 and 2.6.
    """
    _check_tire(tire)
    fz = positive("fz", fz, "N")
    mu = positive("mu_scale", mu_scale)
    tp = tire.to_array()
    b, c, d, e0, sh, _sv, _mu = _lat_coeffs(fz, _dfz(fz, tp), mu, tp)
    e = min(e0 * (1.0 - tire.pey3 * float(np.sign(sh))), 1.0)  # 4.E24 at alpha_y = S_Hy
    return abs(_mf_slope(b, c, d, e, sh))


def slip_stiffness(tire: TireParams, fz: float, *, mu_scale: float = 1.0) -> float:
    """Longitudinal slip stiffness of one tyre ``dF_x0/dkappa`` at ``kappa = 0`` [N], > 0.

    Equal to ``K_xkappa`` ([P12] 4.E15, times ``lambda_kx``) when ``S_Hx = 0``, otherwise the
    exact slope of the curve at ``kappa = 0``.

    Parameters
    ----------
    tire : the tyre coefficients.
    fz : vertical load on this tyre [N], > 0.
    mu_scale : road friction over reference friction [-], > 0.

    References
    ----------
    [P12] eqs. (4.E9)-(4.E16); [VM] sections 2.4 and 2.6.
    """
    _check_tire(tire)
    fz = positive("fz", fz, "N")
    mu = positive("mu_scale", mu_scale)
    tp = tire.to_array()
    b, c, d, e0, sh, _sv, _mu = _long_coeffs(fz, _dfz(fz, tp), mu, tp)
    e = min(e0 * (1.0 - tire.pex4 * float(np.sign(sh))), 1.0)  # 4.E14 at kappa_x = S_Hx
    return _mf_slope(b, c, d, e, sh)


def friction_coefficients(
    tire: TireParams, fz: float, *, mu_scale: float = 1.0
) -> tuple[float, float]:
    """Peak friction coefficients ``(|mu_x|, |mu_y|)`` [-] at load ``fz`` (``D / F_z``).

    References
    ----------
    [P12] eqs. (4.E13) and (4.E23).
    """
    _check_tire(tire)
    fz = positive("fz", fz, "N")
    mu = positive("mu_scale", mu_scale)
    tp = tire.to_array()
    dfz = _dfz(fz, tp)
    return abs(_long_coeffs(fz, dfz, mu, tp)[6]), abs(_lat_coeffs(fz, dfz, mu, tp)[6])


@njit(cache=True)
def _fx0_many(s, fz, mu, tp, out):
    for i in range(out.size):
        out[i] = mf_fx0(s[i], fz[i], mu[i], tp)


@njit(cache=True)
def _fy0_many(s, fz, mu, tp, out):
    for i in range(out.size):
        out[i] = mf_fy0(s[i], fz[i], mu[i], tp)


@njit(cache=True)
def _combined_many(kappa, alpha, fz, mu, tp, outx, outy):
    for i in range(outx.size):
        outx[i], outy[i] = mf_combined(kappa[i], alpha[i], fz[i], mu[i], tp)


@njit(cache=True)
def _slips_many(omega_re, vxw, vyw, v_min, out_k, out_a):
    for i in range(out_k.size):
        out_k[i] = slip_ratio(omega_re[i], vxw[i], v_min[i])
        out_a[i] = slip_angle(vxw[i], vyw[i], v_min[i])


def _flat(*arrays: np.ndarray):
    b = np.broadcast_arrays(*arrays)
    shape = b[0].shape
    return shape, [np.ascontiguousarray(x, dtype=np.float64).ravel() for x in b]


def _out(a: np.ndarray, shape):
    a = a.reshape(shape)
    return float(a) if a.ndim == 0 else a


def fx0(kappa, fz, tire: TireParams, mu_scale=1.0):
    """Pure-slip longitudinal force ``F_x0`` [N] over arrays (broadcast), via :func:`mf_fx0`.

    Parameters
    ----------
    kappa : slip ratio [-], array-like.
    fz : vertical load [N], array-like; values <= 0 give 0.
    tire : the tyre coefficients.
    mu_scale : road friction over reference friction [-], > 0, array-like.

    Returns
    -------
    float or ndarray of the broadcast shape.

    References
    ----------
    [P12] eqs. (4.E9)-(4.E18).
    """
    _check_tire(tire)
    shape, (k, f, m) = _flat(
        _as_float_array("kappa", kappa, "-"), _as_float_array("fz", fz, "N"), _check_mu(mu_scale)
    )
    out = np.empty(k.size)
    _fx0_many(k, f, m, tire.to_array(), out)
    return _out(out, shape)


def fy0(alpha, fz, tire: TireParams, mu_scale=1.0):
    """Pure-slip lateral force ``F_y0`` [N] over arrays (broadcast), via :func:`mf_fy0`.

    Parameters
    ----------
    alpha : slip angle [rad], array-like.
    fz : vertical load [N], array-like; values <= 0 give 0.
    tire : the tyre coefficients.
    mu_scale : road friction over reference friction [-], > 0, array-like.

    Returns
    -------
    float or ndarray of the broadcast shape.

    References
    ----------
    [P12] eqs. (4.E19)-(4.E30).
    """
    _check_tire(tire)
    shape, (a, f, m) = _flat(
        _as_float_array("alpha", alpha, "rad"), _as_float_array("fz", fz, "N"), _check_mu(mu_scale)
    )
    out = np.empty(a.size)
    _fy0_many(a, f, m, tire.to_array(), out)
    return _out(out, shape)


def combined(kappa, alpha, fz, tire: TireParams, mu_scale=1.0):
    """Combined-slip forces ``(F_x, F_y)`` [N] over arrays (broadcast), via :func:`mf_combined`.

    Parameters
    ----------
    kappa : slip ratio [-], array-like.
    alpha : slip angle [rad], array-like.
    fz : vertical load [N], array-like; values <= 0 give 0.
    tire : the tyre coefficients.
    mu_scale : road friction over reference friction [-], > 0, array-like.

    Returns
    -------
    (fx, fy): floats or ndarrays of the broadcast shape.

    References
    ----------
    [P12] eqs. (4.E50)-(4.E67).
    """
    _check_tire(tire)
    shape, (k, a, f, m) = _flat(
        _as_float_array("kappa", kappa, "-"),
        _as_float_array("alpha", alpha, "rad"),
        _as_float_array("fz", fz, "N"),
        _check_mu(mu_scale),
    )
    outx = np.empty(k.size)
    outy = np.empty(k.size)
    _combined_many(k, a, f, m, tire.to_array(), outx, outy)
    return _out(outx, shape), _out(outy, shape)


def slips(omega_re, vxw, vyw, v_min):
    """Slip ratio and slip angle ``(kappa, alpha)`` over arrays, via the compiled kernels.

    Parameters
    ----------
    omega_re : ``Omega * R_e`` [m/s], array-like.
    vxw, vyw : contact-point velocity in wheel axes [m/s], array-like.
    v_min : floor speed of the slip denominator [m/s], > 0.

    References
    ----------
    [VM] sections 0, 1.6 and 3 (module docstring: low-speed regularisation).
    """
    vm = _as_float_array("v_min", v_min, "m/s")
    if not np.all(np.isfinite(vm) & (vm > 0.0)):
        raise ValueError(f"v_min = {v_min!r} m/s: must be finite and > 0")
    shape, (w, vx, vy, m) = _flat(
        _as_float_array("omega_re", omega_re, "m/s"),
        _as_float_array("vxw", vxw, "m/s"),
        _as_float_array("vyw", vyw, "m/s"),
        vm,
    )
    ok = np.empty(w.size)
    oa = np.empty(w.size)
    _slips_many(w, vx, vy, m, ok, oa)
    return _out(ok, shape), _out(oa, shape)
