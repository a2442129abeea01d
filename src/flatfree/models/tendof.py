"""The 10DoF validation model: the "truth" plant of flatfree's closed-loop tests.

A two-track (four-wheel) car with a sprung body that heaves, rolls and pitches on springs,
dampers and anti-roll bars, four spinning wheels, per-wheel vertical loads and per-wheel
combined-slip Magic Formula tyres (:mod:`flatfree.tires`), aerodynamic drag and lift, and
rolling resistance. Equations: ``docs/VEHICLE_MODEL.md`` ([VM]) sections 1.1-1.9;
the numbered choices below are this module's, and each says why.

Frame, reference point and signs
--------------------------------
ISO 8855: body axes x forward, y left, z up at the CoG; ground frame X, Y, Z up; yaw ``psi``
counter-clockwise positive. Roll ``phi > 0`` raises the left side; pitch ``theta > 0`` lowers
the nose; heave ``z > 0`` raises the body. Wheels ``fl, fr, rl, rr`` sit at ``x_f = +l_f``,
``x_r = -l_r``, ``y_l = +T/2``, ``y_r = -T/2``. Slip ratio ``kappa > 0`` when driving (then
``F_x > 0``); slip angle ``alpha > 0`` gives ``F_y < 0`` ([VM] section 0).

State (:class:`TenDoFState`, 22 entries)
----------------------------------------
==================  ========  =========================================================
name                unit      meaning
==================  ========  =========================================================
x, y                m         CoG position in the ground frame
psi                 rad       yaw angle
vx, vy              m/s       CoG velocity in body axes
r                   rad/s     yaw rate
heave, heave_rate   m, m/s    sprung-body heave from static equilibrium (up +)
roll, roll_rate     rad, -/s  sprung-body roll angle phi and its rate
pitch, pitch_rate   rad, -/s  sprung-body pitch angle theta and its rate
omega_fl .. rr      rad/s     wheel spin speeds (forward rolling > 0)
kappa_fl .. rr      -         transient (relaxed) longitudinal slips kappa'
ax_filt, ay_filt    m/s^2     low-passed body accelerations (quasi-static load transfer)
==================  ========  =========================================================

"10DoF" counts the six body DoF x, y, yaw, heave, roll, pitch and the four wheel spins; the
four relaxed slips and the two filtered accelerations are first-order auxiliary states.

Inputs (:class:`TenDoFInput`, 8 entries)
-----------------------------------------
``tw`` [N m] total wheel torque: ``>= 0`` drives, split equally on the driven axle
(``VehicleParams.drive``; an open differential, [VM] 1.7); ``< 0`` brakes, ``|tw|`` split
``brake_balance_front`` / rest on the front / rear axle and equally left / right, applied
against the wheel's spin with a smooth sign. ``delta`` [rad] road-wheel steer angle of the
front axle (parallel steer, or Ackermann with :attr:`TenDoFOptions.ackermann`).
``mu_fl .. mu_rr`` [-] road friction scale under each wheel, ``mu_road / mu_ref`` (1 = the
road of the tyre data): it scales the Magic Formula peaks and may vary in time or along the
road (a wet patch). ``bank`` [rad] the road's bank (cross-slope) angle under the car, as a
roll of the road surface about the car's x axis (``> 0`` raises the left side, like ``phi``;
a left-hand turn banked for speed has ``bank < 0``); 0: a flat road (Model, item 7).
``e_psi_road`` [rad] the car's heading relative to the road's tangent there (``psi`` minus
the road's heading; the closed loop passes its Frenet heading error): it turns the bank's
slope, which falls across the road, into body axes (0: across the body). An input of 6
entries (without the last two) is a flat road. Input limits are *not* in the model (the
actuators clip them).

Model
-----
1. Planar motion, reduced Newton-Euler form ([VM] 1.3)::

       m (vx' - r vy) = sum F_X - F_D,   m (vy' + r vx) = sum F_Y,
       I_z r' = sum (x_i F_Y,ij - y_j F_X,ij)

   with body-axis tyre forces ``F_X = F_x cos d - F_y sin d``, ``F_Y = F_x sin d + F_y cos d``
   ([VM] 1.2) and drag ``F_D = 1/2 rho C_d A vx |vx|`` ([VM] 1.9). The sprung-mass offset
   terms ``m_s h' phi''`` and products of inertia are neglected, as is road grade.
2. Sprung body (mass ``m_s``, CoG height ``h_s`` from ``m h = m_s h_s + m_u R_e``, the
   unsprung mass ``m_u = m - m_s`` split equally between the axles at wheel-centre height)
   heaving, rolling about the roll axis (height ``h_rc`` at the CoG, interpolated between the
   axles' roll centres; arm ``h' = h_s - h_rc``) and pitching about a ground-level axis
   (arm ``h'' = h_s``), small angles ([VM] 1.4)::

       m_s z''                  = sum dF_s + sum F_L
       (I_xs + m_s h'^2) phi''  =  m_s h' (a_y + g sin phi) + sum y_j (dF_s + dF_arb)
       (I_ys + m_s h''^2) th''  = -m_s h'' a_x - F_D h_a + m_s g h'' sin th
                                  - sum x_i dF_s - l_f F_L,f + l_r F_L,r

   with corner deflection ``s_ij = -z + x_i th - y_j phi``, ``dF_s = k_i s + c_i s'``,
   ``dF_arb = -(2 y_j / T_i^2) K_arb,i phi`` and the aerodynamic vertical force on the body
   ``F_L,i = 1/2 rho C_L,i A vx^2`` per axle (up +; ``C_L < 0`` is downforce; [VM] 1.9 writes
   the wheel-load increase, which is ``-F_L,i``). The inertia is taken about the rotation axis
   (``I_xs`` about the sprung CoG plus ``m_s h'^2``). Heave makes the suspension forces sum to
   the lift only, so the wheel loads sum to ``m g - sum F_L`` in every steady state; without
   heave a pitch angle would load both axles whenever ``k_f l_f != k_r l_r``.
3. Wheel loads ([VM] 1.5): ``F_z,ij = F_z0,ij + dF_s + dF_arb + dF_geo + dF_u``, clamped at 0,
   with the static ``F_z0 = m g l_r / (2L)`` (front), ``m g l_f / (2L)`` (rear). The transfer
   that does not pass through the springs (roll-centre links ``dF_geo = -/+ m_s (share_i)
   a_y h_rc,i / T_i``, unsprung masses ``-/+ m_u,i a_y R_e / T_i`` and ``-/+ m_u a_x R_e / (2L)``)
   uses the low-passed accelerations ``ax_filt, ay_filt`` (time constant
   :attr:`TenDoFOptions.accel_filter_time`): the same-step accelerations would make an
   algebraic loop ([VM] 1.5 recommends 10-50 ms). In steady state the total lateral
   transfer is ``m h a_y + m_s h' g sin phi`` and the longitudinal ``m h a_x + F_D h_a``
   (as [VM] 5.2-5.3).
4. Contact points and slips ([VM] 1.6): ``v_x,ij = vx - r y_j``, ``v_y,ij = vy + r x_i``,
   rotated into wheel axes. The slip angle is the tyre module's ``slip_angle``,
   ``atan(v_yw / s(v_xw))``, with the floor speed :attr:`TenDoFOptions.v_min_lat` of the
   smooth denominator ``s`` (remedy 1 of [VM] section 3, lateral only).
5. Longitudinal slip: relaxation length with carcass damping (remedy 2 of [VM] section 3,
   [P12] section 7.2)::

       sigma_x kappa'' = (Omega R_e - v_xw) - |v_xw| kappa'       (kappa'' := d kappa'/dt)
       kappa_eff       = kappa' + tau_d d(kappa')/dt

   ``kappa_eff`` enters the combined-slip Magic Formula ``mf_combined(kappa_eff, alpha, F_z,
   mu)``. In steady state ``kappa' = (Omega R_e - v_xw)/|v_xw|``, the plain slip ratio, so
   steady-state behaviour is the textbook model's. *Why*: with the plain slip the wheel-spin
   mode has the eigenvalue ``-R_e^2 C_kappa / (I_w |v|)``, unbounded at standstill; for the
   peugeot406 front wheel (light wheel, stiff load-sensitive tyre) RK4 at 1 ms is unstable
   below 3.7 m/s at static load and below about 8 m/s at 1.75 x static load, so a floor speed
   in the slip denominator would have to be larger than that ([VM] section 3 table). With the
   relaxed slip the wheel and tyre form a second-order system ``s^2 + (|v|/sigma_x +
   omega_n^2 tau_d) s + omega_n^2``, ``omega_n^2 = R_e^2 C_kappa / (I_w sigma_x)``, whose
   frequency does not depend on speed (228 rad/s for the 406 front at static load:
   ``omega_n dt = 0.23`` at 1 ms). The Kelvin-Voigt carcass damping ``tau_d =
   2 zeta_0 / omega_n`` (at static load, :attr:`TenDoFOptions.carcass_damping_ratio`) damps
   that mode at standstill, where the relaxation alone leaves it undamped, and changes no
   steady state because ``d(kappa')/dt = 0`` there. The relaxation lengths are the tyre's
   ``relaxation_length_x``.
6. Wheel spin ([VM] 1.7)::

       I_w Omega' = T_d - T_b sgn_e(Omega) - R_e F_x - f_r F_z R_e sgn_0(Omega)

   ``sgn_e(w) = w / sqrt(w^2 + e^2)``. Rolling resistance uses ``e_0 =``
   :attr:`TenDoFOptions.sign_speed`; the brake uses ``e_b = max(e_0, T_b tau_b / I_w)``, so
   the viscous slope of the brake near ``Omega = 0`` never exceeds ``I_w / tau_b``
   (``tau_b =`` :attr:`TenDoFOptions.brake_time_constant`), whatever the brake torque:
   the sheet's condition ``e >= T_b dt / (2.785 I_w)`` then holds for ``dt <= 2.785 tau_b``.
   Wheels may spin backwards (no clamp), so the model can reverse.
7. Road bank ``b`` (inputs ``bank`` and ``e_psi_road``; [Raj] Ch. 2, the bank-angle term of
   the lateral model): the road surface is locally a plane rolled by ``b`` about the road's
   tangent, and the car moves in it (paths and curvatures are taken in that plane: a
   horizontal circle of radius R on a bank has the in-plane curvature cos b / R, so the
   neutral speed of v^2 kappa = g sin b is the classical v^2 / R = g tan b). Gravity has the
   in-plane part ``g sin b`` across the road towards its low side, in body axes
   ``(-g sin b sin e, -g sin b cos e)`` with ``e = e_psi_road``, added to ``vx'`` and
   ``vy'`` (the tyre forces hold the car against it; the accelerations that load the body,
   ``a_x``, ``a_y`` and their filtered values, are the tyre forces over the mass, which is
   what the springs feel), and the normal part ``g cos b``, which replaces ``g`` in the
   static wheel loads (``F_z0 cos b``) and the body's gravity moments of roll and pitch.
   The springs keep their static deflection (the body's heave to the lighter normal load,
   ``1 - cos b`` = 6 % of the static deflection at 20 deg, is neglected); the road's twist
   where the bank changes is not modelled. ``b = 0`` gives the flat-road model bit for bit.

Low speed and stable step
-------------------------
Starts from standstill and stops to 0 are regular: every right-hand side term is finite at
``vx = 0, Omega = 0``; at standstill the tyres act as a longitudinal spring-damper
(``C_kappa / sigma_x``, ``C_kappa tau_d / sigma_x``) and a lateral damper
(``C_alpha / s(0)``, ``s(0) = 3 v_min_lat / 8``). :func:`stable_step` computes the largest
stable RK4 step of the model linearised at a state and input; over standstill to 60 m/s,
coasting, braking with 70 % of the maximum brake torque and steering, its minimum is
2.0 ms (peugeot406), 2.3 ms (bmw320i, dallara_av21), reached at standstill under braking;
it is 4-7 ms at 0.5 m/s, 10-20 ms from 2 to 40 m/s and ~7 ms at 60 m/s (table in
``benchmarks/README.md``). The default ``dt = 1 ms`` is inside with a factor >= 2. With plain
slips RK4 at 1 ms is unstable below 1.7 m/s (bmw320i) and 3.7 m/s (peugeot406) ([VM] 3).
The right-hand side has kinks only at ``vx = 0`` (``|v_xw|``), ``|v_xw| = v_min_lat`` (C2
there) and ``F_z = 0`` (lift-off); inputs switch the drive/brake branch at ``tw = 0``.

Speed: about 0.68-0.72 us per peugeot406 RK4 step (~1400-1450x real time at 1 ms) on the
project's machine, about two thirds of it in the four 4-tyre Magic Formula evaluations of a
step (the step took 0.24 us with a linear tyre in their place); 2.5 us (~400x) before the
tyres were evaluated in SIMD lanes, 0.82 us before the rounding-level changes below
(``benchmarks/README.md``).

Implementation
--------------
One implementation of the dynamics, :func:`rhs_kernel` (``numba.njit(cache=True)``), used by
the compiled RK4 step :func:`rk4_step_kernel`, the compiled loop :func:`simulate_kernel`
(writing into preallocated arrays), the Python-callable ``rhs(t, x)`` for
``scipy.integrate.solve_ivp`` (:meth:`TenDoF.ivp_rhs`) and the per-wheel diagnostics
(:meth:`TenDoF.diagnostics`). Parameters enter the kernels as flat arrays: ``MP`` (derived
vehicle and model constants, built by :meth:`TenDoF.__init__`) and the two tyres'
``TireParams.to_array()``.

:func:`rhs_kernel` makes three passes over the wheels: (1) suspension, loads, contact-point
velocities and the relaxed-slip dynamics, wheel by wheel; (2) the tyre forces of the four
wheels at once; (3) body forces, moments and wheel spin, wheel by wheel. The per-wheel values
travel from pass 1 as 4-tuples (registers) and from pass 2 to pass 3 in a 3 x 4 scratch array
in the function's stack frame (``flatfree._vecmath.stack_array``), so that the lanes' loop
neither gathers its inputs from scalar stores just made nor scatters its results at a stride
for pass 3 to wait on; pass 3 writes ``diag`` (its columns are :func:`flatfree.tires.
mf_combined4`'s lane layout; the inner RK4 stages leave the friction scales in the
``kappa_plain`` column, the last writes the slip ratio there). Pass 2 is, by default
(:attr:`TenDoFOptions.tire_lanes`), one loop over four SIMD lanes: the slip angle's ``atan``
and the whole combined-slip Magic Formula, branch-free, with the polynomial ``atan``, ``sin``,
``cos``, ``exp`` of ``flatfree._vecmath``; LLVM evaluates the four wheels in 4-wide vector
registers. It gives the forces of the scalar kernels to
round-off (1-2 ulp elementary functions) and the trajectories of the scalar path to ~1e-14 of
each state's range (``tests/test_tendof_fastpath.py``). With ``tire_lanes=False`` pass 2 calls
``math.atan`` and :func:`flatfree.tires.mf_combined` wheel by wheel, and the body's cos and
sin are libm's: the reference path (the lanes' path uses ``flatfree._vecmath`` for those too;
the steer angle's cos and sin, once per step, are ``flatfree._vecmath``'s in both paths). Both
paths share passes 1 and 3, which multiply by reciprocals of the constant divisors (``MP.inv_*``,
``arb_t_*``, ``q_lat_*``, ``q_long``); the lanes use fused multiply-adds (``flatfree.tires``)
and, for tyres whose combined-slip curvature factors ``r_Ex1, r_Ex2, r_Ey1, r_Ey2`` vanish (the
peugeot406's), skip the weighting curves' second arc tangent, which then equals the first
(``MP.lane_variant``, decided once per model). The model before these changes (2026-11-22) is
reproduced to rounding, not bit for bit (60 s open-loop step-steer and braking runs of the three
presets: max difference 2.9e-13 of each state's largest magnitude). The hot kernels
(:func:`rhs_kernel`, :func:`rk4_step_kernel` and the loop of :func:`simulate_kernel`) are
compiled without numba's reference counting (they allocate nothing): its per-call atomic
increments and decrements of every array argument cost ~40 % of the run time. One RK4 step
evaluates the steer angles' cos and sin once for its four stages (the input is held) and the
diagnostic plain slip ratios only in its last stage (the one it leaves in ``diag``). Pass 3 and
the body read their constants before their first store to ``dx`` (which, for all the compiler
knows, may overlap ``p`` and ``x``), so that nothing is loaded again between the stores.

References
----------
[VM] docs/VEHICLE_MODEL.md, sections 0, 1.1-1.9, 3 and 5.
[P12] H. B. Pacejka, Tire and Vehicle Dynamics, 3rd ed., 2012, section 4.3.2 (Magic Formula)
      and section 7.2 (single-contact-point transient tyre model, relaxation length).
[Raj] R. Rajamani, Vehicle Dynamics and Control, 2nd ed., 2012, Ch. 2 and Ch. 4.
[K&N] U. Kiencke, L. Nielsen, Automotive Control Systems, 2nd ed., 2005 (two-track model).
[HW] E. Hairer, G. Wanner, Solving ODEs II, section IV.2 (RK4 stability region).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from flatfree import _vecmath as vm
from flatfree._validate import boolean, finite, positive, real_array, whole
from flatfree.tires import _lanes_g_plain as _mf_lanes_g_plain
from flatfree.tires import _lanes_general as _mf_lanes_general
from flatfree.tires import _mf_combined_lane, mf_combined, slip_speed, slip_stiffness
from flatfree.units import G
from flatfree.vehicles.params import TP, VehicleParams

__all__ = [
    "MP",
    "TenDoF",
    "TenDoFInput",
    "TenDoFOptions",
    "TenDoFState",
    "Wheel",
    "drive_speed",
    "rhs_kernel",
    "lane_table",
    "rk4_step_kernel",
    "rk4_step_table",
    "simulate_kernel",
    "stable_step",
]


# --------------------------------------------------------------------------------------------
# Layouts
# --------------------------------------------------------------------------------------------
class TenDoFState(enum.IntEnum):
    """State layout of the 10DoF model (units in the module docstring)."""

    x = 0
    y = 1
    psi = 2
    vx = 3
    vy = 4
    r = 5
    heave = 6
    heave_rate = 7
    roll = 8
    roll_rate = 9
    pitch = 10
    pitch_rate = 11
    omega_fl = 12
    omega_fr = 13
    omega_rl = 14
    omega_rr = 15
    kappa_fl = 16
    kappa_fr = 17
    kappa_rl = 18
    kappa_rr = 19
    ax_filt = 20
    ay_filt = 21


class TenDoFInput(enum.IntEnum):
    """Input layout: tw [N m], delta [rad], mu_fl, mu_fr, mu_rl, mu_rr [-] (module docstring)."""

    tw = 0
    delta = 1
    mu_fl = 2
    mu_fr = 3
    mu_rl = 4
    mu_rr = 5
    bank = 6
    e_psi_road = 7


class Wheel(enum.IntEnum):
    """Wheel order of every per-wheel array: front left, front right, rear left, rear right."""

    fl = 0
    fr = 1
    rl = 2
    rr = 3


class MP(enum.IntEnum):
    """Index enum of the kernels' model-parameter array (built by :class:`TenDoF`)."""

    m = 0  # total mass [kg]
    m_s = 1  # sprung mass [kg]
    m_u_axle = 2  # unsprung mass per axle [kg]
    lf = 3  # [m]
    lr = 4  # [m]
    wheelbase = 5  # [m]
    track_f = 6  # [m]
    track_r = 7  # [m]
    h_s = 8  # sprung CoG height [m]
    h_roll = 9  # roll arm h' [m]
    h_rc_f = 10  # front roll-centre height [m]
    h_rc_r = 11  # rear roll-centre height [m]
    iz = 12  # [kg m^2]
    i_roll = 13  # roll inertia about the roll axis [kg m^2]
    i_pitch = 14  # pitch inertia about the pitch axis [kg m^2]
    k_f = 15  # spring per corner [N/m]
    k_r = 16
    c_f = 17  # damper per corner [N s/m]
    c_r = 18
    arb_f = 19  # anti-roll bar axle stiffness [N m/rad]
    arb_r = 20
    r_e = 21  # effective rolling radius [m]
    iw_f = 22  # wheel spin inertia [kg m^2]
    iw_r = 23
    drive_front = 24  # 1 if the front axle is driven, else 0
    brake_front = 25  # brake share of the front axle [-]
    f_roll = 26  # rolling resistance coefficient [-]
    drag = 27  # 1/2 rho C_d A [kg/m]
    lift_f = 28  # 1/2 rho C_L,f A [kg/m]
    lift_r = 29
    h_drag = 30  # [m]
    fz0_f = 31  # static load per front wheel [N]
    fz0_r = 32  # static load per rear wheel [N]
    g = 33  # [m/s^2]
    sigma_f = 34  # longitudinal relaxation length [m]
    sigma_r = 35
    tau_d_f = 36  # carcass damping time [s]
    tau_d_r = 37
    v_min_lat = 38  # floor speed of the slip-angle denominator [m/s]
    tau_brake = 39  # brake stiction time constant [s]
    sign_speed = 40  # smooth-sign width for rolling resistance [rad/s]
    tau_acc = 41  # acceleration filter time constant [s]
    ackermann = 42  # 1 for Ackermann steering, 0 for parallel
    h_u = 43  # unsprung CoG height = R_e [m]
    tire_lanes = 44  # 1: tyres in SIMD lanes (mf_combined4), 0: scalar mf_combined
    # reciprocals and per-axle combinations of the constants above: the right-hand side
    # multiplies instead of dividing (a division has ~4x the latency of a multiplication)
    inv_m = 45  # 1 / m [1/kg]
    inv_ms = 46  # 1 / m_s [1/kg]
    inv_iz = 47  # 1 / I_z [1/(kg m^2)]
    inv_i_roll = 48  # [1/(kg m^2)]
    inv_i_pitch = 49  # [1/(kg m^2)]
    inv_tau_acc = 50  # [1/s]
    inv_sigma_f = 51  # [1/m]
    inv_sigma_r = 52
    inv_iw_f = 53  # [1/(kg m^2)]
    inv_iw_r = 54
    arb_t_f = 55  # K_arb,f / T_f [N/rad]: the anti-roll bar's load change per unit roll
    arb_t_r = 56
    q_lat_f = 57  # (m_s share_f h_rc,f + m_u,f h_u) / T_f [kg]: transfer outside the springs
    q_lat_r = 58
    q_long = 59  # m_u,i h_u / L [kg]
    lane_variant = 60  # the tyre lanes' variant: 0 plain, 1 E = 0 weighting curves, 2 general


NX = len(TenDoFState)
NU = len(TenDoFInput)
#: Columns of the per-wheel diagnostics array written by :func:`rhs_kernel`.
DIAG_FIELDS = ("fz", "fx", "fy", "alpha", "kappa", "kappa_plain")
NDIAG = len(DIAG_FIELDS)

# integer constants for the kernels (numba freezes module-level ints at compile time).
# NOTE: numba's on-disk cache does not notice a change of these layouts; clear it after editing.
_X, _Y, _PSI, _VX, _VY, _R = 0, 1, 2, 3, 4, 5
_Z, _ZD, _PHI, _PHID, _TH, _THD = 6, 7, 8, 9, 10, 11
_OM, _KA, _AXF, _AYF = 12, 16, 20, 21
_TW, _DELTA, _MU, _BANK, _EPSI_ROAD = 0, 1, 2, 6, 7
_M = int(MP.m)
_MS = int(MP.m_s)
_MUA = int(MP.m_u_axle)
_LF = int(MP.lf)
_LR = int(MP.lr)
_L = int(MP.wheelbase)
_TF = int(MP.track_f)
_TR = int(MP.track_r)
_HS = int(MP.h_s)
_HROLL = int(MP.h_roll)
_HRCF = int(MP.h_rc_f)
_HRCR = int(MP.h_rc_r)
_IZ = int(MP.iz)
_IROLL = int(MP.i_roll)
_IPITCH = int(MP.i_pitch)
_KF = int(MP.k_f)
_KR = int(MP.k_r)
_CF = int(MP.c_f)
_CR = int(MP.c_r)
_ARBF = int(MP.arb_f)
_ARBR = int(MP.arb_r)
_RE = int(MP.r_e)
_IWF = int(MP.iw_f)
_IWR = int(MP.iw_r)
_DRVF = int(MP.drive_front)
_BRKF = int(MP.brake_front)
_FR = int(MP.f_roll)
_DRAG = int(MP.drag)
_LIFTF = int(MP.lift_f)
_LIFTR = int(MP.lift_r)
_HD = int(MP.h_drag)
_FZ0F = int(MP.fz0_f)
_FZ0R = int(MP.fz0_r)
_G = int(MP.g)
_SIGF = int(MP.sigma_f)
_SIGR = int(MP.sigma_r)
_TDF = int(MP.tau_d_f)
_TDR = int(MP.tau_d_r)
_VMIN = int(MP.v_min_lat)
_TAUB = int(MP.tau_brake)
_SGN0 = int(MP.sign_speed)
_TAUA = int(MP.tau_acc)
_ACK = int(MP.ackermann)
_HU = int(MP.h_u)
_LANES = int(MP.tire_lanes)
_INVM = int(MP.inv_m)
_INVMS = int(MP.inv_ms)
_INVIZ = int(MP.inv_iz)
_INVIROLL = int(MP.inv_i_roll)
_INVIPITCH = int(MP.inv_i_pitch)
_INVTAUA = int(MP.inv_tau_acc)
_INVSIGF = int(MP.inv_sigma_f)
_INVSIGR = int(MP.inv_sigma_r)
_INVIWF = int(MP.inv_iw_f)
_INVIWR = int(MP.inv_iw_r)
_ARBTF = int(MP.arb_t_f)
_ARBTR = int(MP.arb_t_r)
_QLATF = int(MP.q_lat_f)
_QLATR = int(MP.q_lat_r)
_QLONG = int(MP.q_long)
_LVAR = int(MP.lane_variant)
_NTP = len(TP)

_JIT = dict(cache=True, nogil=True, error_model="numpy")
# The hot kernels allocate nothing and only index the arrays they are given (owned by the
# caller for the whole call), so they need no reference counting. With it, numba increfs and
# decrefs every array argument and view on every call (lock-prefixed atomic operations); its
# pruning pass cannot remove them across calls that are not inlined (mf_combined, rhs_kernel),
# and they took ~37 % of the run time (perf, benchmarks/README.md). ``_nrt=False`` compiles a
# function without numba's runtime (flatfree._vecmath.no_refcount: left out, with the same
# results, should a numba release drop the option).
_JIT_NO_REFCOUNT = vm.no_refcount(_JIT)


# --------------------------------------------------------------------------------------------
# Options
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class TenDoFOptions:
    """Modelling choices and low-speed regularisation of the 10DoF model.

    Attributes
    ----------
    ackermann : bool
        Ackermann steering geometry ([VM] 1.8) instead of parallel steer (default, as
        CommonRoad's MB model).
    v_min_lat : float
        Floor speed of the slip-angle denominator [m/s], > 0 ([VM] section 3, remedy 1; the
        tyre module's smooth ``slip_speed``). Default 1.0 m/s [estimate]: keeps the lateral and
        yaw modes at standstill (``|lambda| ~ sum C_alpha / (m 3 v_min / 8)``) well inside the
        RK4 region at 1 ms for the three presets; above ``v_min_lat`` the slip angle is exact.
    carcass_damping_ratio : float
        Damping ratio zeta_0 [-] of the wheel-spin / tyre-deflection mode at standstill and static
        load, >= 0 (module docstring, item 5). Default 0.5 [estimate].
    brake_time_constant : float
        tau_b [s], > 0: the brake's smooth sign is never steeper than ``I_w / tau_b``
        (module docstring, item 6). Default 1 ms [estimate], i.e. stable RK4 steps up to
        about 2.8 ms from this term.
    sign_speed : float
        Width e_0 [rad/s], > 0, of the smooth sign of the rolling resistance (and the lower
        bound of the brake's). Default 0.1 rad/s [estimate] (3 cm/s of tread speed).
    accel_filter_time : float
        Time constant [s], > 0, of the low-pass filter on the accelerations that drive the
        quasi-static load transfer (module docstring, item 3). Default 10 ms, the low end of
        [VM] 1.5's 10-50 ms.
    tire_lanes : bool
        Evaluate the four tyres together in SIMD lanes (:func:`flatfree.tires.mf_combined4`
        and :func:`flatfree._vecmath.atan` for the slip angles; default) instead of one
        :func:`flatfree.tires.mf_combined` call and one ``math.atan`` per wheel. Both give the
        same forces to round-off (the elementary functions differ by 1-2 ulp) and the same
        trajectories to ~1e-14 of each state's range (``tests/test_tendof_fastpath.py``); the
        lanes make the whole model about 2.3x faster. ``False`` is the scalar reference path
        (libm and ``mf_combined``; module docstring, Implementation).
    """

    ackermann: bool = field(default=False, metadata={"unit": ""})
    v_min_lat: float = field(default=1.0, metadata={"unit": "m/s"})
    carcass_damping_ratio: float = field(default=0.5, metadata={"unit": "-"})
    brake_time_constant: float = field(default=1e-3, metadata={"unit": "s"})
    sign_speed: float = field(default=0.1, metadata={"unit": "rad/s"})
    accel_filter_time: float = field(default=0.01, metadata={"unit": "s"})
    tire_lanes: bool = field(default=True, metadata={"unit": ""})

    def __post_init__(self) -> None:
        boolean("ackermann", self.ackermann)
        positive("v_min_lat", self.v_min_lat, "m/s")
        v = finite("carcass_damping_ratio", self.carcass_damping_ratio, "-")
        if v < 0.0:
            raise ValueError(f"carcass_damping_ratio = {v!r}: must be >= 0")
        positive("brake_time_constant", self.brake_time_constant, "s")
        positive("sign_speed", self.sign_speed, "rad/s")
        positive("accel_filter_time", self.accel_filter_time, "s")
        boolean("tire_lanes", self.tire_lanes)


# --------------------------------------------------------------------------------------------
# Compiled kernels
# --------------------------------------------------------------------------------------------
@njit(**_JIT)
def _smooth_sign(w: float, eps: float) -> float:
    """``w / sqrt(w^2 + eps^2)``: odd, slope ``1/eps`` at 0, -> sgn(w) for ``|w| >> eps``."""
    return w / math.sqrt(w * w + eps * eps)


@njit(**_JIT_NO_REFCOUNT)
def _steer_trig(u, p):
    """cos and sin of the left and right road-wheel steer angles ([VM] 1.8): (cl, sl, cr, sr).

    A function of the input alone, so one RK4 step evaluates it once for its four stages.
    """
    delta = u[_DELTA]
    if p[_ACK] != 0.0 and delta != 0.0:
        wb = p[_L]
        tf = p[_TF]
        td = math.tan(delta)
        d_l = math.atan(wb * td / (wb - 0.5 * tf * td))  # [VM] 1.8 Ackermann, inner = left
        d_r = math.atan(wb * td / (wb + 0.5 * tf * td))
        return math.cos(d_l), math.sin(d_l), math.cos(d_r), math.sin(d_r)
    # flatfree._vecmath's cos and sin (<= 2 ulp, inlined: no libm call) in both paths: passes 1
    # and 3, which use them, are shared by the lanes and the scalar reference path
    cl = vm.cos(delta)
    sl = vm.sin(delta)
    return cl, sl, cl, sl


@njit(**_JIT_NO_REFCOUNT)
def _bank_trig(u):
    """The road bank's ``(cos b, sin b sin e, sin b cos e)`` (Model, item 7; ``e`` the heading
    to the road): exactly (1, 0, 0) on a flat road, whose results are then those of the model
    without the bank, bit for bit."""
    bank = u[_BANK]
    if bank == 0.0:
        return 1.0, 0.0, 0.0
    sb = math.sin(bank)
    e = u[_EPSI_ROAD]
    return math.cos(bank), sb * math.sin(e), sb * math.cos(e)


@njit(**dict(_JIT, forceinline=True))
def _of_wheel(t, w):
    """``t[w]`` for a 4-tuple ``t`` and a wheel (lane) index ``w``, by selects: a lane loop
    evaluates them in vector registers, and an unrolled wheel loop folds them away."""
    return (t[0] if w == 0 else t[1]) if w < 2 else (t[2] if w == 2 else t[3])


@njit(**dict(_JIT_NO_REFCOUNT, forceinline=True))
def _check_lane_table(lt):
    """ValueError unless ``lt`` is a C-contiguous float64[len(TP), 4] (the lanes then know its
    strides as constants)."""
    if lt.shape[0] != _NTP or lt.shape[1] != 4 or lt.strides[0] != 32 or lt.strides[1] != 8:
        raise ValueError("the tyre lane table must be a C-contiguous (len(TP), 4) array")


#: Shape of the tyre lanes' coefficient table (:func:`lane_table`).
LANE_TABLE_SHAPE = (_NTP, 4)


@njit(**dict(_JIT_NO_REFCOUNT, forceinline=True))
def lane_table(lt, tpf, tpr):
    """Fill ``lt`` (float64[len(TP), 4], C-contiguous) with the tyre lanes' coefficients:
    column w holds wheel w's tyre (``tpf`` for the front wheels 0, 1, ``tpr`` for the rear
    ones), so that a coefficient of the four lanes is one vector load. Before, the lanes took
    both tyres as tuples: ~100 values loaded, spilled to the stack and paired by shuffles at
    every right-hand side (benchmarks/README.md "The tyre lanes' coefficients as a table")."""
    _check_lane_table(lt)
    for k in range(_NTP):
        a = tpf[k]
        b = tpr[k]
        lt[k, 0] = a
        lt[k, 1] = a
        lt[k, 2] = b
        lt[k, 3] = b


@njit(**_JIT_NO_REFCOUNT)
def rhs_kernel(x, u, p, tpf, tpr, dx, diag):
    """Time derivative of the 10DoF state (module docstring), written into ``dx``.

    Parameters
    ----------
    x : float64[22]
        State, :class:`TenDoFState` layout.
    u : float64[8]
        Input, :class:`TenDoFInput` layout (not clipped, not checked).
    p : float64[len(MP)]
        Model parameters, :class:`MP` layout.
    tpf, tpr : float64[len(TP)]
        Front and rear ``TireParams.to_array()``.
    dx : float64[22]
        Output.
    diag : float64[4, 6]
        Output: per wheel (:class:`Wheel` order) the columns ``DIAG_FIELDS`` = vertical load
        [N], tyre forces ``F_x``, ``F_y`` in wheel axes [N], slip angle [rad], the slip
        ``kappa_eff`` seen by the tyre [-] and the plain slip ratio
        ``(Omega R_e - v_xw)/max(|v_xw|, v_min_lat)`` [-]. Written by pass 3, not read (module
        docstring, Implementation); another row length raises ValueError.

    References
    ----------
    [VM] sections 1.2-1.9; [P12] 4.3.2 and 7.2.
    """
    cl, sl, cr_, sr_ = _steer_trig(u, p)
    cb, sbx, sby = _bank_trig(u)
    lt = vm.stack_array(_NTP, 4)
    lane_table(lt, tpf, tpr)
    _rhs_steered(x, u, p, lt, dx, diag, cl, sl, cr_, sr_, cb, sbx, sby, True)


@njit(**dict(_JIT_NO_REFCOUNT, forceinline=True))
def _wheel_pass1(w, x, p, dx, body, sums):
    """Pass 1 of :func:`_rhs_steered` for wheel ``w`` (a constant at each call): suspension,
    load, contact-point velocity and the relaxed slip, whose derivative it writes into ``dx``.

    ``body`` holds the body's states and the car's and steer's constants that pass 1 reads,
    ``sums`` the suspension's heave force, roll moment and pitch moment over the wheels before
    this one. Returns the load ``F_z``, ``tan`` of the slip angle, the slip ``kappa_eff`` seen
    by the tyre and ``sums`` with this wheel's terms added.
    """
    (vx, vy, r, z, zd, phi, phid, th, thd, axf, ayf, lf, lr, tf, tr, re, cl, sl, cr_, sr_,
     cb) = body
    front = w < 2
    left = (w % 2) == 0
    if front:
        xi = lf
        tt = tf
        k = p[_KF]
        c = p[_CF]
        karb_t = p[_ARBTF]
        fz0 = p[_FZ0F]
        q_lat = p[_QLATF]
        inv_sig = p[_INVSIGF]
        taud = p[_TDF]
        dlong = -1.0  # front gains load when braking (a_x < 0)
        if left:
            cd = cl
            sd = sl
        else:
            cd = cr_
            sd = sr_
    else:
        xi = -lr
        tt = tr
        k = p[_KR]
        c = p[_CR]
        karb_t = p[_ARBTR]
        fz0 = p[_FZ0R]
        q_lat = p[_QLATR]
        inv_sig = p[_INVSIGR]
        taud = p[_TDR]
        dlong = 1.0
        cd = 1.0
        sd = 0.0
    yj = 0.5 * tt if left else -0.5 * tt
    side = 1.0 if left else -1.0

    # ---- suspension and loads ([VM] 1.4-1.5) ----
    s = -z + xi * th - yj * phi  # corner compression
    sd_ = -zd + xi * thd - yj * phid
    dfs = k * s + c * sd_
    dfarb = -side * karb_t * phi  # -(2 y_j / T_i^2) K_arb,i phi, 2 y_j / T_i = side
    # transfer outside the springs: roll-centre links and unsprung masses (filtered a)
    # per wheel: lateral m_s share_i a_y h_rc,i / T_i + m_u,i a_y h_u / T_i, longitudinal
    # (m_u h_u a_x) / (2 L) with m_u = 2 m_u,i ([VM] 1.5 moment balance); the constant
    # factors q_lat, q_long are precomputed (_build_params)
    dfq = -side * q_lat * ayf + dlong * p[_QLONG] * axf
    fz = fz0 * cb + dfs + dfarb + dfq
    if fz < 0.0:
        fz = 0.0  # lift-off

    # ---- contact point and slips ([VM] 1.6) ----
    vxc = vx - r * yj
    vyc = vy + r * xi
    vxw = vxc * cd + vyc * sd
    vyw = -vxc * sd + vyc * cd
    om = x[_OM + w]
    kap = x[_KA + w]
    vslip = om * re - vxw  # slip speed, > 0 when driving
    kdot = (vslip - abs(vxw) * kap) * inv_sig  # [P12] 7.2 relaxation, sigma_x
    dx[_KA + w] = kdot
    keff = kap + taud * kdot  # Kelvin-Voigt carcass damping (module docstring, item 5)
    # tan(alpha): the slip angle is atan(v_yw / s(v_xw)), tyre module's slip_angle ([VM] 1.6)
    tan_a = vyw / slip_speed(vxw, p[_VMIN])
    return fz, tan_a, keff, (sums[0] + dfs, sums[1] + yj * (dfs + dfarb), sums[2] + xi * dfs)


@njit(**_JIT_NO_REFCOUNT)
def _rhs_steered(x, u, p, lt, dx, diag, cl, sl, cr_, sr_, cb, sbx, sby, plain_slip):
    """:func:`rhs_kernel` with the steer angles' cos and sin given (:func:`_steer_trig`), the
    road bank's (:func:`_bank_trig`) and the tyres as the table ``lt`` (:func:`lane_table`; the
    scalar path too: two array arguments fewer, which numba passes as 7 words each).

    ``plain_slip = False`` skips the diagnostic plain slip ratio (``diag[:, 5]`` then holds the
    friction scales): the inner RK4 stages, whose diagnostics the next stage overwrites.
    """
    vx = x[_VX]
    vy = x[_VY]
    r = x[_R]
    z = x[_Z]
    zd = x[_ZD]
    phi = x[_PHI]
    phid = x[_PHID]
    th = x[_TH]
    thd = x[_THD]
    axf = x[_AXF]
    ayf = x[_AYF]
    tw = u[_TW]

    ms = p[_MS]
    lf = p[_LF]
    lr = p[_LR]
    tf = p[_TF]
    tr = p[_TR]
    re = p[_RE]
    g = p[_G] * cb  # gravity normal to the (banked) road; its in-plane part enters vy'

    # ---- aerodynamics ([VM] 1.9) ----
    fd = p[_DRAG] * vx * abs(vx)  # F_D = 1/2 rho C_d A vx |vx|
    v2 = vx * vx
    # aerodynamic vertical force on the body, up + (C_L < 0: downforce); [VM] 1.9 writes the
    # wheel-load increase -1/2 rho C_L A vx^2, i.e. minus this force
    lift_f = p[_LIFTF] * v2
    lift_r = p[_LIFTR] * v2

    # ---- steering ([VM] 1.8): cl, sl, cr_, sr_ from _steer_trig ----

    # ---- torques ([VM] 1.7) ----
    if tw >= 0.0:
        drv_f = 0.5 * tw * p[_DRVF]  # open differential: half per wheel of the driven axle
        drv_r = 0.5 * tw * (1.0 - p[_DRVF])
        brk_f = 0.0
        brk_r = 0.0
    else:
        drv_f = 0.0
        drv_r = 0.0
        brk_f = -0.5 * tw * p[_BRKF]  # brake balance, half per wheel
        brk_r = -0.5 * tw * (1.0 - p[_BRKF])

    sum_fx = 0.0
    sum_fy = 0.0
    mz = 0.0

    # Three passes over the wheels: (1) loads, slips and the relaxed-slip dynamics; (2) the
    # tyre forces of all four wheels at once; (3) body forces and wheel spin. Per-wheel values
    # pass from (1) to (2) and (3) as 4-tuples (registers) and from (2) to (3) in ``res``, a
    # scratch array in this function's stack frame; pass 3 writes ``diag``, which nothing here
    # reads back: with ``diag`` as the passes' scratch, the lanes' loop gathered its inputs
    # from pass 1's scalar stores just before and scattered its results at diag's stride, and
    # pass 3's loads waited for the scatters (benchmarks/README.md "The tyre lanes' stores").
    if diag.shape[0] < 4 or diag.shape[1] != NDIAG:
        raise ValueError("rhs_kernel: diag must have shape (4, 6)")
    body = (vx, vy, r, z, zd, phi, phid, th, thd, axf, ayf, lf, lr, tf, tr, re, cl, sl, cr_, sr_,
            cb)
    # sum dF_s (heave), sum y_j (dF_s + dF_arb) (roll), sum x_i dF_s (pitch), wheel after wheel
    sums = (0.0, 0.0, 0.0)
    fz_0, tan_0, ke_0, sums = _wheel_pass1(0, x, p, dx, body, sums)
    fz_1, tan_1, ke_1, sums = _wheel_pass1(1, x, p, dx, body, sums)
    fz_2, tan_2, ke_2, sums = _wheel_pass1(2, x, p, dx, body, sums)
    fz_3, tan_3, ke_3, sums = _wheel_pass1(3, x, p, dx, body, sums)
    f_heave, m_roll_susp, m_pitch_susp = sums
    fz4 = (fz_0, fz_1, fz_2, fz_3)
    tan4 = (tan_0, tan_1, tan_2, tan_3)  # tan of the slip angles
    ke4 = (ke_0, ke_1, ke_2, ke_3)
    mu4 = (u[_MU], u[_MU + 1], u[_MU + 2], u[_MU + 3])
    res = vm.stack_array(3, 4)  # rows: slip angle, F_x, F_y; a column per wheel

    # ---- tyre forces, wheel axes ([P12] 4.3.2; flatfree.tires) ----
    if p[_LANES] != 0.0:
        # the four wheels in SIMD lanes: the loop of flatfree.tires.mf_combined4 with the slip
        # angle's atan in it. Its per-wheel inputs are values (tuples), its outputs contiguous
        # rows of res, which no argument can alias: LLVM vectorises it with plain vector
        # stores. The coefficients come from lt (lane_table): lt[:, w] is wheel w's tyre, so a
        # coefficient of the four lanes is one vector load (the strides checked: constants)
        _check_lane_table(lt)
        # the variant, decided once per model (_build_params: flatfree.tires._lanes_general,
        # _lanes_g_plain on the two tyres), not at every call
        variant = p[_LVAR]
        if variant == 2.0:
            for w in range(4):
                alpha = vm.atan(_of_wheel(tan4, w))
                res[0, w] = alpha
                res[1, w], res[2, w] = _mf_combined_lane(_of_wheel(ke4, w), alpha,
                                                         _of_wheel(fz4, w), _of_wheel(mu4, w),
                                                         lt[:, w], lt[:, w], True, True)
        elif variant == 1.0:
            # weighting curves with E = 0 (flatfree.tires._mf_combined_lane, g_plain)
            for w in range(4):
                alpha = vm.atan(_of_wheel(tan4, w))
                res[0, w] = alpha
                res[1, w], res[2, w] = _mf_combined_lane(_of_wheel(ke4, w), alpha,
                                                         _of_wheel(fz4, w), _of_wheel(mu4, w),
                                                         lt[:, w], lt[:, w], True, False, True)
        else:
            for w in range(4):
                alpha = vm.atan(_of_wheel(tan4, w))
                res[0, w] = alpha
                res[1, w], res[2, w] = _mf_combined_lane(_of_wheel(ke4, w), alpha,
                                                         _of_wheel(fz4, w), _of_wheel(mu4, w),
                                                         lt[:, w], lt[:, w], True, False)
    else:
        # scalar reference: slip_angle's atan and mf_combined, wheel by wheel
        for w in range(4):
            alpha = math.atan(_of_wheel(tan4, w))
            res[0, w] = alpha
            # the tyre's coefficients as lt's column of the wheel (lane_table: tpf, tpr)
            res[1, w], res[2, w] = mf_combined(_of_wheel(ke4, w), alpha, _of_wheel(fz4, w),
                                               _of_wheel(mu4, w), lt[:, w])

    # Everything pass 3 and the body read from p and x is read here, before their first store
    # to dx: the compiler must assume that dx may overlap p and x and would load again after
    # each store whatever is read after it, on the way to the derivatives that the next RK4
    # stage waits for (read after the tyres, not before them, where they would only add to
    # the registers that the tyre lanes' loop needs).
    psi = x[_PSI]
    lanes = p[_LANES] != 0.0
    sgn_e0 = p[_SGN0]
    f_roll = p[_FR]
    tau_b = p[_TAUB]
    v_min = p[_VMIN]
    inv_iw_f = p[_INVIWF]
    inv_iw_r = p[_INVIWR]
    inv_m = p[_INVM]
    g0 = p[_G]
    inv_iz = p[_INVIZ]
    inv_ms = p[_INVMS]
    inv_iroll = p[_INVIROLL]
    inv_ipitch = p[_INVIPITCH]
    inv_tau = p[_INVTAUA]
    hroll = p[_HROLL]
    hs = p[_HS]
    h_drag = p[_HD]
    for w in range(4):
        front = w < 2
        left = (w % 2) == 0
        if front:
            xi = lf
            tt = tf
            inv_iw = inv_iw_f
            tdrive = drv_f
            tbrake = brk_f
            if left:
                cd = cl
                sd = sl
            else:
                cd = cr_
                sd = sr_
        else:
            xi = -lr
            tt = tr
            inv_iw = inv_iw_r
            tdrive = drv_r
            tbrake = brk_r
            cd = 1.0
            sd = 0.0
        yj = 0.5 * tt if left else -0.5 * tt
        fz = _of_wheel(fz4, w)
        fx = res[1, w]
        fy = res[2, w]

        # ---- body forces ([VM] 1.2-1.3) ----
        fxb = fx * cd - fy * sd
        fyb = fx * sd + fy * cd
        sum_fx += fxb
        sum_fy += fyb
        mz += xi * fyb - yj * fxb

        # ---- wheel spin ([VM] 1.7) ----
        om = x[_OM + w]
        sgn0 = _smooth_sign(om, sgn_e0)
        tq = tdrive - re * fx - f_roll * fz * re * sgn0
        if tbrake > 0.0:
            eps_b = max(sgn_e0, tbrake * tau_b * inv_iw)
            tq -= tbrake * _smooth_sign(om, eps_b)
        dx[_OM + w] = tq * inv_iw

        diag[w, 0] = fz
        diag[w, 1] = fx
        diag[w, 2] = fy
        diag[w, 3] = res[0, w]
        diag[w, 4] = _of_wheel(ke4, w)
        if plain_slip:
            # plain slip ratio (diagnostics): the contact-point speed of pass 1, recomputed
            vxw = (vx - r * yj) * cd + (vy + r * xi) * sd
            diag[w, 5] = (om * re - vxw) / max(abs(vxw), v_min)
        else:
            diag[w, 5] = _of_wheel(mu4, w)

    # ---- planar motion ([VM] 1.3) ----
    ax = (sum_fx - fd) * inv_m  # body-frame CoG acceleration
    ay = sum_fy * inv_m
    if lanes:
        # the fast path's elementary functions (flatfree._vecmath, <= 2 ulp; inlined
        # polynomials instead of four libm calls per right-hand side)
        cpsi = vm.cos(psi)
        spsi = vm.sin(psi)
        sphi = vm.sin(phi)
        sth = vm.sin(th)
    else:
        cpsi = math.cos(psi)
        spsi = math.sin(psi)
        sphi = math.sin(phi)
        sth = math.sin(th)
    dx[_X] = vx * cpsi - vy * spsi  # [VM] 1.1
    dx[_Y] = vx * spsi + vy * cpsi
    dx[_PSI] = r
    dx[_VX] = ax + r * vy
    dx[_VY] = ay - r * vx
    # gravity down the bank's slope (Model, item 7); exactly nothing on a flat road, where
    # _bank_trig gives sbx = sby = 0 (x - 0.0 is x)
    dx[_VX] -= g0 * sbx
    dx[_VY] -= g0 * sby
    dx[_R] = mz * inv_iz

    # ---- sprung body ([VM] 1.4, module docstring item 2) ----
    dx[_Z] = zd
    dx[_ZD] = (f_heave + lift_f + lift_r) * inv_ms
    dx[_PHI] = phid
    dx[_PHID] = (ms * hroll * (ay + g * sphi) + m_roll_susp) * inv_iroll
    dx[_TH] = thd
    dx[_THD] = (
        -ms * hs * ax - fd * h_drag + ms * g * hs * sth - m_pitch_susp
        - lf * lift_f + lr * lift_r
    ) * inv_ipitch

    # ---- acceleration filter ([VM] 1.5) ----
    dx[_AXF] = (ax - axf) * inv_tau
    dx[_AYF] = (ay - ayf) * inv_tau


@njit(**_JIT_NO_REFCOUNT)
def drive_speed(x, p):
    """Speed of the driveline in road units [m/s]: the speed at which the drive torque works.

    A drive torque ``tw >= 0`` reaches the wheels in fixed shares ``s_i`` (``drive_front / 2``
    on each front wheel, ``(1 - drive_front) / 2`` on each rear one: the open differentials of
    :func:`rhs_kernel`), so the power it delivers is ``tw sum_i s_i Omega_i`` and an engine of
    power P can give at most ``tw = P R_e / v_drive`` with

        v_drive = R_e sum_i s_i Omega_i,

    the speed to use in the actuators' power cap (:func:`flatfree.actuators.actuate_step`).
    With the wheels rolling it is the body speed within the driven wheels' slip; with an
    unloaded driven wheel spinning up (an open differential's inner wheel out of a corner) it
    grows with that wheel's spin, and the power it may take falls, as it does on the car.
    """
    f = p[_DRVF]
    return p[_RE] * (0.5 * f * (x[_OM] + x[_OM + 1])
                     + 0.5 * (1.0 - f) * (x[_OM + 2] + x[_OM + 3]))


@njit(**_JIT_NO_REFCOUNT)
def rk4_step_kernel(x, u, dt, p, tpf, tpr, out, work, diag):
    """One classical RK4 step of :func:`rhs_kernel`, input held: writes ``x(t + dt)`` into ``out``.

    ``x`` and ``out`` have 22 entries (NX), ``work`` is a float64[5, 22] scratch array and
    ``diag`` a float64[4, 6] one (left holding the diagnostics of the last stage); other
    lengths raise ValueError. ``out`` may be ``x`` itself.
    """
    lt = vm.stack_array(_NTP, 4)
    lane_table(lt, tpf, tpr)
    rk4_step_table(x, u, dt, p, tpf, tpr, lt, out, work, diag)


@njit(**_JIT_NO_REFCOUNT)
def rk4_step_table(x, u, dt, p, tpf, tpr, lt, out, work, diag):
    """:func:`rk4_step_kernel` with the tyre lanes' coefficient table ``lt`` given
    (:func:`lane_table` of ``tpf``, ``tpr``): a loop of many steps fills it once, not at every
    step (208 stores, ~30 ns a step)."""
    if x.shape[0] != NX or out.shape[0] != NX or work.shape[0] < 5 or work.shape[1] != NX:
        raise ValueError("rk4_step_kernel: x and out must have 22 entries, work shape (5, 22)")
    _check_lane_table(lt)
    # the state's length as a constant: LLVM unrolls the stage updates below into scalar code.
    # With a run-time length it vectorised them, and their 4-wide loads of k1 .. k4 waited for
    # the right-hand side's scalar stores just before (a vector load cannot take its data from
    # several stores in flight: benchmarks/README.md "The tyre lanes' stores")
    n = NX
    k1 = work[0]
    k2 = work[1]
    k3 = work[2]
    k4 = work[3]
    xt = work[4]
    # the input is held over the step: the steer's cos and sin once, not once per stage; the
    # diagnostic plain slip ratios only in the last stage (the one left in diag)
    cl, sl, cr_, sr_ = _steer_trig(u, p)
    cb, sbx, sby = _bank_trig(u)
    # the stages' flag as a run-time bool (bool() of a constant is typed ``boolean``, not
    # ``Literal[bool]``): one compiled right-hand side for the four stages. Passed as the
    # literals False and True, numba compiled two ~32 KB copies, both hot, and inside the
    # closed loop they ran ~70-190 ns a step slower than alone (the code's size, likely; no
    # counters to tell: benchmarks/README.md "One right-hand side for the four RK4 stages")
    inner = bool(False)  # noqa: UP018 (not a literal: the point)
    last = bool(True)  # noqa: UP018
    _rhs_steered(x, u, p, lt, k1, diag, cl, sl, cr_, sr_, cb, sbx, sby, inner)
    h2 = 0.5 * dt
    for i in range(n):
        xt[i] = x[i] + h2 * k1[i]
    _rhs_steered(xt, u, p, lt, k2, diag, cl, sl, cr_, sr_, cb, sbx, sby, inner)
    for i in range(n):
        xt[i] = x[i] + h2 * k2[i]
    _rhs_steered(xt, u, p, lt, k3, diag, cl, sl, cr_, sr_, cb, sbx, sby, inner)
    for i in range(n):
        xt[i] = x[i] + dt * k3[i]
    # the weighted sum's first terms, in its order of operations, before the last stage (so
    # off its path; k2 is free again): the update after it is short enough to be unrolled too
    for i in range(n):
        k2[i] = k1[i] + 2.0 * (k2[i] + k3[i])
    _rhs_steered(xt, u, p, lt, k4, diag, cl, sl, cr_, sr_, cb, sbx, sby, last)
    h6 = dt / 6.0
    for i in range(n):
        out[i] = x[i] + h6 * (k2[i] + k4[i])  # = x + h6 (k1 + 2 (k2 + k3) + k4), bit for bit


@njit(**_JIT)
def simulate_kernel(x0, us, dt, p, tpf, tpr, xs):
    """Fixed-step RK4 over the input sequence ``us`` (n, 8), writing states into ``xs`` (n+1, 22).

    ``xs[0] = x0``; the input ``us[k]`` is held over step k. Returns the number of steps done:
    ``n`` on success, fewer if a state became non-finite (that step's row is written, the
    remaining rows are left untouched).
    """
    nx = x0.shape[0]
    work = np.empty((5, nx))
    diag = np.empty((4, NDIAG))
    return _simulate_steps(x0, us, dt, p, tpf, tpr, xs, work, diag)


@njit(**_JIT_NO_REFCOUNT)
def _simulate_steps(x0, us, dt, p, tpf, tpr, xs, work, diag):
    """The loop of :func:`simulate_kernel` (scratch arrays allocated by the caller)."""
    n = us.shape[0]
    nx = x0.shape[0]
    for i in range(nx):
        xs[0, i] = x0[i]
    lt = vm.stack_array(_NTP, 4)
    lane_table(lt, tpf, tpr)
    for k in range(n):
        rk4_step_table(xs[k], us[k], dt, p, tpf, tpr, lt, xs[k + 1], work, diag)
        if not vm.all_finite(xs[k + 1]):
            return k
    return n


@njit(**_JIT)
def _diag_many(xs, us, p, tpf, tpr, out):
    dx = np.empty(xs.shape[1])
    for k in range(xs.shape[0]):
        rhs_kernel(xs[k], us[k], p, tpf, tpr, dx, out[k])


@njit(**_JIT)
def _rhs_many(xs, us, p, tpf, tpr, out):
    diag = np.empty((4, NDIAG))
    for k in range(xs.shape[0]):
        rhs_kernel(xs[k], us[k], p, tpf, tpr, out[k], diag)


# --------------------------------------------------------------------------------------------
# Python layer
# --------------------------------------------------------------------------------------------
def _as_state(x, name: str = "x") -> np.ndarray:
    a = real_array(name, x)
    if a.shape != (NX,):
        raise ValueError(f"{name} has shape {a.shape}: expected ({NX},) (TenDoFState layout)")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} = {a.tolist()}: must be finite")
    return np.ascontiguousarray(a)


def _complete_inputs(a: np.ndarray) -> np.ndarray:
    """Inputs of 6 entries (a flat road) completed with zeros to the :class:`TenDoFInput`
    layout; any other length is returned as it is."""
    if a.ndim >= 1 and a.shape[-1] == NU - 2:
        a = np.concatenate((a, np.zeros((*a.shape[:-1], NU - a.shape[-1]))), axis=-1)
    return a


def _check_inputs(u, shape_what: str) -> np.ndarray:
    a = _complete_inputs(np.ascontiguousarray(real_array(shape_what, u)))
    if a.shape[-1:] != (NU,):
        raise ValueError(
            f"{shape_what} has shape {a.shape}: expected last axis {NU} = "
            "[tw (N m), delta (rad), mu_fl, mu_fr, mu_rl, mu_rr (-), bank (rad), "
            f"e_psi_road (rad)] (TenDoFInput; {NU - 2} entries: a flat road; build it with "
            "TenDoF.inputs)"
        )
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{shape_what}: all inputs must be finite [N m, rad, -]")
    mu = a[..., _MU:_MU + 4]
    if np.any(mu <= 0.0):
        bad = float(mu[mu <= 0.0].ravel()[0])
        raise ValueError(f"{shape_what}: road friction scale mu = {bad!r} (-): must be > 0")
    bank = a[..., _BANK]
    if np.any(np.abs(bank) >= 0.5 * math.pi):
        bad = float(bank[np.abs(bank) >= 0.5 * math.pi].ravel()[0])
        raise ValueError(f"{shape_what}: road bank angle bank = {bad!r} rad: must be within "
                         "(-pi/2, pi/2)")
    return a


class TenDoF:
    """The 10DoF validation model of a car (module docstring): a thin shell over the kernels.

    Parameters
    ----------
    vehicle : VehicleParams
        The car, e.g. ``flatfree.vehicles.load_vehicle("peugeot406")``. Both tyres need a
        ``relaxation_length_x > 0``.
    options : TenDoFOptions, optional
        Modelling choices and low-speed regularisation (defaults documented there).

    Attributes
    ----------
    vehicle, options : the inputs.
    params : ndarray
        The :class:`MP` array of the kernels.
    tire_front, tire_rear : ndarray
        ``TireParams.to_array()`` of the front and rear tyres.

    Examples
    --------
    >>> from flatfree.vehicles import load_vehicle
    >>> model = TenDoF(load_vehicle("peugeot406"))
    >>> x0 = model.initial_state(vx=20.0)
    >>> u = model.inputs(tw=0.0, delta=0.02, n=2000)          # 2 s at 1 ms
    >>> xs = model.simulate(x0, u, dt=1e-3)                   # shape (2001, 22)

    References
    ----------
    [VM] docs/VEHICLE_MODEL.md sections 1, 3, 5.
    """

    State = TenDoFState
    Input = TenDoFInput

    def __init__(self, vehicle: VehicleParams, options: TenDoFOptions | None = None) -> None:
        if not isinstance(vehicle, VehicleParams):
            raise ValueError(f"vehicle = {vehicle!r}: expected a VehicleParams (load_vehicle)")
        opts = TenDoFOptions() if options is None else options
        if not isinstance(opts, TenDoFOptions):
            raise ValueError(f"options = {opts!r}: expected a TenDoFOptions")
        for side in ("tire_front", "tire_rear"):
            sig = getattr(vehicle, side).relaxation_length_x
            if not sig > 0.0:
                raise ValueError(
                    f"{side}.relaxation_length_x = {sig!r} m: the 10DoF model's relaxed "
                    "longitudinal slip needs a relaxation length > 0"
                )
        self.vehicle = vehicle
        self.options = opts
        self.params = _build_params(vehicle, opts)
        self.tire_front = vehicle.tire_front.to_array()
        self.tire_rear = vehicle.tire_rear.to_array()

    # ----- helpers -----
    def __repr__(self) -> str:
        return f"TenDoF({self.vehicle.name!r}, {self.options!r})"

    def initial_state(
        self, vx: float = 0.0, *, vy: float = 0.0, r: float = 0.0, x: float = 0.0,
        y: float = 0.0, psi: float = 0.0,
    ) -> np.ndarray:
        """A state at rest in the suspension, wheels free-rolling (``Omega R_e = v_x,ij``).

        Heave, roll, pitch and their rates, the relaxed slips and the filtered accelerations
        are 0 (static equilibrium of the suspension at zero acceleration).
        """
        s = np.zeros(NX)
        s[_X] = finite("x", x, "m")
        s[_Y] = finite("y", y, "m")
        s[_PSI] = finite("psi", psi, "rad")
        s[_VX] = finite("vx", vx, "m/s")
        s[_VY] = finite("vy", vy, "m/s")
        s[_R] = finite("r", r, "rad/s")
        p = self.params
        for w in Wheel:
            yj = (0.5 if w % 2 == 0 else -0.5) * (p[_TF] if w < 2 else p[_TR])
            s[_OM + w] = (s[_VX] - s[_R] * yj) / p[_RE]
        return s

    @staticmethod
    def inputs(tw, delta, mu=1.0, *, mu_wheels=None, bank=0.0, e_psi_road=0.0,
               n: int | None = None) -> np.ndarray:
        """Build an input array in the :class:`TenDoFInput` layout.

        Parameters
        ----------
        tw : float or array_like (n,)
            Total wheel torque [N m] (> 0 drive, < 0 brake).
        delta : float or array_like (n,)
            Front road-wheel steer angle [rad].
        mu : float or array_like (n,)
            Road friction scale [-] under all four wheels (ignored when ``mu_wheels`` is
            given).
        mu_wheels : array_like (4,) or (n, 4), optional
            Road friction scale [-] per wheel, :class:`Wheel` order (a split-mu road, a wet
            patch under one side).
        bank : float or array_like (n,)
            Road bank angle [rad] (module docstring, Inputs; 0: flat road).
        e_psi_road : float or array_like (n,)
            The car's heading relative to the road's tangent [rad] (orients the bank's slope).
        n : int, optional
            Number of steps. If None it is taken from the array arguments, and a single
            input of shape (8,) is returned when all of them are scalars (or ``mu_wheels``
            has shape (4,)).

        Returns
        -------
        ndarray, shape (8,) or (n, 8)

        Raises
        ------
        ValueError
            Inconsistent lengths, a non-finite value, a friction scale <= 0 or a bank angle
            of 90 deg or more.
        """
        tw_a = real_array("tw", tw)
        de_a = real_array("delta", delta)
        if mu_wheels is None:
            mu_a = real_array("mu", mu)
            if mu_a.ndim > 1:
                raise ValueError(f"mu has shape {mu_a.shape}: expected a scalar or (n,); "
                                 "use mu_wheels for one value per wheel")
            mu_a = mu_a[..., None] * np.ones(4)
        else:
            mu_a = real_array("mu_wheels", mu_wheels)
            if mu_a.ndim not in (1, 2) or mu_a.shape[-1] != 4:
                raise ValueError(f"mu_wheels has shape {mu_a.shape}: expected (4,) or (n, 4)")
        bank_a = real_array("bank", bank)
        ep_a = real_array("e_psi_road", e_psi_road)
        scalars = (("tw", tw_a), ("delta", de_a), ("bank", bank_a), ("e_psi_road", ep_a))
        for name, a in scalars:
            if a.ndim > 1:
                raise ValueError(f"{name} has shape {a.shape}: expected a scalar or (n,)")
        lengths = {a.shape[0] for _, a in scalars if a.ndim == 1}
        if mu_a.ndim == 2:
            lengths.add(mu_a.shape[0])
        if n is not None:
            lengths.add(whole("n", n, 1))
        if len(lengths) > 1:
            raise ValueError(f"inputs: inconsistent lengths {sorted(lengths)}")
        shape = (NU,) if not lengths else (lengths.pop(), NU)
        out = np.empty(shape)
        out[..., _TW] = tw_a
        out[..., _DELTA] = de_a
        out[..., _MU:_MU + 4] = mu_a
        out[..., _BANK] = bank_a
        out[..., _EPSI_ROAD] = ep_a
        return _check_inputs(out, "u")

    # ----- dynamics -----
    def rhs(self, x, u) -> np.ndarray:
        """Time derivative of the state ``x`` (22,) under the input ``u`` (8,)."""
        xa = _as_state(x)
        ua = _check_inputs(u, "u")
        if ua.shape != (NU,):
            raise ValueError(f"u has shape {ua.shape}: expected ({NU},)")
        dx = np.empty(NX)
        rhs_kernel(xa, ua, self.params, self.tire_front, self.tire_rear, dx,
                   np.empty((4, NDIAG)))
        return dx

    def ivp_rhs(self, u) -> Callable[[float, np.ndarray], np.ndarray]:
        """A ``fun(t, x)`` for ``scipy.integrate.solve_ivp`` over the compiled right-hand side.

        Parameters
        ----------
        u : array_like (8,) or callable
            A constant input, or ``u(t) -> array (8,)`` (e.g. a zero-order hold of a sampled
            sequence). The input is not validated (though completed to 8 entries) at every call
            when callable.

        Returns
        -------
        callable ``fun(t, x) -> dx`` (new arrays; ``x`` of shape (22,)).
        """
        p, tpf, tpr = self.params, self.tire_front, self.tire_rear
        diag = np.empty((4, NDIAG))
        if callable(u):
            def fun(t: float, x: np.ndarray) -> np.ndarray:
                dx = np.empty(NX)
                # without the bank entries: the kernel reads them
                ut = _complete_inputs(np.ascontiguousarray(u(t), dtype=np.float64))
                rhs_kernel(np.ascontiguousarray(x, dtype=np.float64), ut, p, tpf, tpr, dx, diag)
                return dx
        else:
            uc = _check_inputs(u, "u")
            if uc.shape != (NU,):
                raise ValueError(f"u has shape {uc.shape}: expected ({NU},) or a callable")

            def fun(t: float, x: np.ndarray) -> np.ndarray:
                dx = np.empty(NX)
                rhs_kernel(np.ascontiguousarray(x, dtype=np.float64), uc, p, tpf, tpr, dx, diag)
                return dx
        return fun

    def step(self, x, u, dt: float = 1e-3) -> np.ndarray:
        """One RK4 step of length ``dt`` [s] with the input ``u`` (8,) held: the new state."""
        xa = _as_state(x)
        ua = _check_inputs(u, "u")
        if ua.shape != (NU,):
            raise ValueError(f"u has shape {ua.shape}: expected ({NU},)")
        h = positive("dt", dt, "s")
        out = np.empty(NX)
        rk4_step_kernel(xa, ua, h, self.params, self.tire_front, self.tire_rear, out,
                        np.empty((5, NX)), np.empty((4, NDIAG)))
        return out

    def simulate(self, x0, u, dt: float = 1e-3, *, out: np.ndarray | None = None) -> np.ndarray:
        """Integrate with the compiled fixed-step RK4, input ``u[k]`` held over step k.

        Parameters
        ----------
        x0 : array_like (22,)
            Initial state (:meth:`initial_state`).
        u : array_like (n, 8)
            Inputs per step (:meth:`inputs`; (n, 6): a flat road).
        dt : float
            Step [s], > 0 (default 1 ms; see the module docstring for stable steps).
        out : ndarray (n + 1, 22), optional
            Preallocated C-contiguous float64 output (reused between runs).

        Returns
        -------
        ndarray (n + 1, 22): the states at ``t = k dt``.

        Raises
        ------
        ValueError
            Bad arguments, or a state became non-finite (the message gives the time).
        """
        xa = _as_state(x0, "x0")
        ua = _check_inputs(u, "u")
        if ua.ndim != 2:
            raise ValueError(f"u has shape {ua.shape}: expected (n, {NU})")
        h = positive("dt", dt, "s")
        n = ua.shape[0]
        if out is None:
            xs = np.empty((n + 1, NX))
        else:
            xs = out
            if (xs.shape != (n + 1, NX) or xs.dtype != np.float64
                    or not xs.flags.c_contiguous):
                raise ValueError(
                    f"out has shape {xs.shape} and dtype {xs.dtype}: expected a C-contiguous "
                    f"float64 array of shape {(n + 1, NX)}"
                )
        n_ok = simulate_kernel(xa, ua, h, self.params, self.tire_front, self.tire_rear, xs)
        if n_ok < n:
            raise ValueError(
                f"the state became non-finite at t = {(n_ok + 1) * h!r} s (step {n_ok + 1} "
                f"of {n}); dt = {h!r} s may be outside the stable range (stable_step)"
            )
        return xs

    def diagnostics(self, x, u) -> dict[str, np.ndarray]:
        """Per-wheel loads, forces and slips for a state and input, or for trajectories.

        Parameters
        ----------
        x : array_like (22,) or (n, 22)
        u : array_like (8,) or (n, 8) (6 entries: a flat road)

        Returns
        -------
        dict of arrays of shape (4,) or (n, 4), :class:`Wheel` order, with keys
        ``fz`` [N] vertical load, ``fx``, ``fy`` [N] tyre forces in wheel axes, ``alpha``
        [rad] slip angle, ``kappa`` [-] the slip seen by the tyre (relaxed, with carcass
        damping), ``kappa_plain`` [-] the instantaneous slip ratio; and ``ax``, ``ay``
        [m/s^2] (shape () or (n,)) the body-frame CoG accelerations. The effective
        cornering stiffness of an axle (the paper's Figure 3) is
        ``-(fy[fl] + fy[fr]) / mean(alpha[fl], alpha[fr])`` (ISO sign).
        """
        xa = np.ascontiguousarray(real_array("x", x))
        ua = _check_inputs(u, "u")
        single = xa.ndim == 1
        xs = xa[None, :] if single else xa
        us = ua[None, :] if ua.ndim == 1 else ua
        if xs.ndim != 2 or xs.shape[1] != NX or us.shape[0] != xs.shape[0]:
            raise ValueError(
                f"x has shape {xa.shape} and u {ua.shape}: expected (22,) and (8,), or "
                "(n, 22) and (n, 8)"
            )
        if not np.all(np.isfinite(xs)):
            raise ValueError("x: states must be finite")
        d = np.empty((xs.shape[0], 4, NDIAG))
        _diag_many(xs, us, self.params, self.tire_front, self.tire_rear, d)
        dxs = np.empty_like(xs)
        _rhs_many(xs, us, self.params, self.tire_front, self.tire_rear, dxs)
        res = {name: d[:, :, i] for i, name in enumerate(DIAG_FIELDS)}
        res["ax"] = dxs[:, _VX] - xs[:, _R] * xs[:, _VY]
        res["ay"] = dxs[:, _VY] + xs[:, _R] * xs[:, _VX]
        if single:
            res = {k: v[0] for k, v in res.items()}
        return res

    def jacobian(self, x, u, *, rel_step: float = 1e-6) -> np.ndarray:
        """Central finite-difference Jacobian d(rhs)/dx (22, 22) at ``(x, u)``."""
        xa = _as_state(x)
        ua = _check_inputs(u, "u")
        jac = np.empty((NX, NX))
        fp = np.empty(NX)
        fm = np.empty(NX)
        diag = np.empty((4, NDIAG))
        for i in range(NX):
            h = rel_step * max(1.0, abs(xa[i]))
            xp = xa.copy()
            xp[i] += h
            xm = xa.copy()
            xm[i] -= h
            rhs_kernel(xp, ua, self.params, self.tire_front, self.tire_rear, fp, diag)
            rhs_kernel(xm, ua, self.params, self.tire_front, self.tire_rear, fm, diag)
            jac[:, i] = (fp - fm) / (2.0 * h)
        return jac


def _build_params(vp: VehicleParams, opts: TenDoFOptions) -> np.ndarray:
    """The :class:`MP` array of derived constants (module docstring, items 2-6)."""
    p = np.zeros(len(MP))
    m = vp.mass
    m_s = vp.sprung_mass
    m_u = m - m_s
    wb = vp.wheelbase
    h_u = vp.wheel_radius  # unsprung CoG at the wheel centre [estimate]
    h_s = (m * vp.cog_height - m_u * h_u) / m_s  # m h = m_s h_s + m_u h_u
    if not h_s > 0.0:
        raise ValueError(
            f"sprung CoG height h_s = {h_s!r} m (from m h = m_s h_s + m_u R_e): must be > 0"
        )
    h_rc = (vp.roll_center_height_front * vp.lr + vp.roll_center_height_rear * vp.lf) / wb
    h_roll = h_s - h_rc
    rho = vp.air_density
    fz0_f = 0.5 * m * G * vp.lr / wb  # [VM] 1.5 static load per wheel
    fz0_r = 0.5 * m * G * vp.lf / wb
    p[_M] = m
    p[_MS] = m_s
    p[_MUA] = 0.5 * m_u  # [assumption] unsprung mass split equally between the axles
    p[_LF] = vp.lf
    p[_LR] = vp.lr
    p[_L] = wb
    p[_TF] = vp.track_front
    p[_TR] = vp.track_rear
    p[_HS] = h_s
    p[_HROLL] = h_roll
    p[_HRCF] = vp.roll_center_height_front
    p[_HRCR] = vp.roll_center_height_rear
    p[_IZ] = vp.iz
    p[_IROLL] = vp.ix_s + m_s * h_roll * h_roll  # about the roll axis
    p[_IPITCH] = vp.iy_s + m_s * h_s * h_s  # about the ground-level pitch axis
    p[_KF] = vp.spring_front
    p[_KR] = vp.spring_rear
    p[_CF] = vp.damper_front
    p[_CR] = vp.damper_rear
    p[_ARBF] = vp.arb_front
    p[_ARBR] = vp.arb_rear
    p[_RE] = vp.wheel_radius
    p[_IWF] = vp.wheel_inertia_front
    p[_IWR] = vp.wheel_inertia_rear
    p[_DRVF] = 1.0 if vp.drive == "front" else 0.0
    p[_BRKF] = vp.brake_balance_front
    p[_FR] = vp.rolling_resistance
    p[_DRAG] = 0.5 * rho * vp.drag_area
    p[_LIFTF] = 0.5 * rho * vp.lift_area_front
    p[_LIFTR] = 0.5 * rho * vp.lift_area_rear
    p[_HD] = vp.drag_height
    p[_FZ0F] = fz0_f
    p[_FZ0R] = fz0_r
    p[_G] = G
    p[_SIGF] = vp.tire_front.relaxation_length_x
    p[_SIGR] = vp.tire_rear.relaxation_length_x
    for tire, fz0, iw, sig, idx in (
        (vp.tire_front, fz0_f, vp.wheel_inertia_front, p[_SIGF], _TDF),
        (vp.tire_rear, fz0_r, vp.wheel_inertia_rear, p[_SIGR], _TDR),
    ):
        c_kappa = slip_stiffness(tire, fz0)
        omega_n = math.sqrt(vp.wheel_radius**2 * c_kappa / (iw * sig))  # module doc, item 5
        p[idx] = 2.0 * opts.carcass_damping_ratio / omega_n
    p[_VMIN] = opts.v_min_lat
    p[_TAUB] = opts.brake_time_constant
    p[_SGN0] = opts.sign_speed
    p[_TAUA] = opts.accel_filter_time
    p[_ACK] = 1.0 if opts.ackermann else 0.0
    p[_HU] = h_u
    p[_LANES] = 1.0 if opts.tire_lanes else 0.0
    for inv, val in ((_INVM, m), (_INVMS, m_s), (_INVIZ, p[_IZ]), (_INVIROLL, p[_IROLL]),
                     (_INVIPITCH, p[_IPITCH]), (_INVTAUA, p[_TAUA]), (_INVSIGF, p[_SIGF]),
                     (_INVSIGR, p[_SIGR]), (_INVIWF, p[_IWF]), (_INVIWR, p[_IWR])):
        p[inv] = 1.0 / val
    p[_ARBTF] = p[_ARBF] / p[_TF]
    p[_ARBTR] = p[_ARBR] / p[_TR]
    # module docstring item 3: m_s share_i h_rc,i / T_i + m_u,i h_u / T_i, m_u,i h_u / L
    p[_QLATF] = (m_s * (vp.lr / wb) * p[_HRCF] + p[_MUA] * h_u) / p[_TF]
    p[_QLATR] = (m_s * (vp.lf / wb) * p[_HRCR] + p[_MUA] * h_u) / p[_TR]
    p[_QLONG] = p[_MUA] * h_u / wb
    ta, tb = vp.tire_front.to_array(), vp.tire_rear.to_array()
    p[_LVAR] = 2.0 if _lanes_general_py(ta, tb) else (1.0 if _lanes_g_plain_py(ta, tb) else 0.0)
    return p


@njit(cache=True)
def _lanes_general_py(tpf, tpr) -> bool:
    return _mf_lanes_general(vm.as_tuple(tpf, _NTP), vm.as_tuple(tpr, _NTP))


@njit(cache=True)
def _lanes_g_plain_py(tpf, tpr) -> bool:
    return _mf_lanes_g_plain(vm.as_tuple(tpf, _NTP), vm.as_tuple(tpr, _NTP))


def stable_step(model: TenDoF, x, u) -> tuple[float, float]:
    """Largest RK4 step for the model linearised at ``(x, u)``, and the spectral radius.

    Every eigenvalue ``lambda`` of the finite-difference Jacobian must satisfy
    ``|R(lambda dt)| <= 1`` with the RK4 stability polynomial ``R(z) = 1 + z + z^2/2 + z^3/6 +
    z^4/24`` ([HW] IV.2); the step is found by bisection on that condition. Eigenvalues with
    positive real part (a physically unstable mode, e.g. roll-over) are skipped.

    Returns
    -------
    (dt_max [s], max |lambda| [1/s])
    """
    lam = np.linalg.eigvals(model.jacobian(x, u))
    lam = lam[(np.abs(lam) > 1e-9) & (lam.real <= 1e-9)]
    if lam.size == 0:
        return math.inf, 0.0

    def ok(dt: float) -> bool:
        z = lam * dt
        r = 1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0
        return bool(np.all(np.abs(r) <= 1.0 + 1e-12))

    lo, hi = 0.0, 3.0 / float(np.max(np.abs(lam)))
    while ok(hi):
        lo, hi = hi, 2.0 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo, float(np.max(np.abs(lam)))
