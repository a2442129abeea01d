"""The paper's three vehicle controllers (Sections 2.3, 3.3 and 3.4) for the compiled loop.

``flatness`` (flatness-based control, Section 2.3)
    :func:`flatfree.controllers.flatness_control.flatness_step` on the measured (vx, vy, r),
    tracking y1 = Vx and y2 = lf m Vy - Iz r with a design model whose Cf, Cr may be scaled
    (the paper's Figure 2 mismatch: ``cf_scale = cr_scale = 0.3``).

The two model-free designs are two decoupled single-input single-output loops each (paper
Section 3.3-3.4, NOTES.md):

``mfc-flat`` (model-free control on flat outputs, Section 3.3)
    y1 = Vx (input: wheel torque T_w) and y2 = lf m Vy - Iz r (input: steer delta), both with an
    iPI on the ultra-local model y' = F + alpha u (nu = 1). Uses m, Iz, lf to form y2 and
    nothing else of the vehicle.
``mfc-natural`` (model-free control on natural outputs, Section 3.4)
    y1 = Vx with an iP (nu = 1) on the wheel torque, and y2 = the lateral deviation e_y from
    the reference path with an iPD (nu = 2) on the steer. No vehicle parameter at all. Added
    here (each documented in :class:`MfcNaturalSettings`, off-switchable): a parameter-free yaw
    damper on the steer, the paper's causal denoiser on the measurements, the estimators
    fed with the inputs actually applied, a speed schedule of the lateral gains, a bound on
    the iPD's proportional correction (``correction_max``: a car off its path comes back at a
    bounded speed), the steer held at a standstill (``steer_min_speed``), and
    (``estimator_lat = "imu"``, beyond the paper) the lateral F, e_y and e_y' from an
    inertial unit's measured e_y'' instead of the algebraic estimator.

Outer path-following correction (``flatness`` and ``mfc-flat``; ``path_correction``, default
on; off reproduces the paper's designs exactly). Both designs track velocities only
(y1 = Vx, y2 = lf m Vy - Iz r): nothing in them feeds back the position or the heading, so any
yaw-rate error integrates into the heading and the lateral deviation and the car drifts off
the track within a lap (benchmarks/README.md "Closed loop"). A kinematic outer loop corrects
the yaw rate the inner loop is asked for, from the measured lateral deviation e_y and course
error chi = e_psi + atan(Vy / Vx) (direction of the CoG velocity minus the path heading):

    Delta r = -beta_ref' - (3 w_o chi + 3 w_o^2 e_y / Vx + w_o^3 integral(e_y / Vx) dt)

Kinematics (V ~ Vx, small angles): e_y' = Vx chi and chi' = r + beta' - Vx kappa, so with the
inner loop delivering r = Vx kappa + Delta r, chi' = beta' - beta_ref' - (feedback); where the
car's sideslip rate equals the reference's, the deviation obeys
e_y''' + 3 w_o e_y'' + 3 w_o^2 e_y' + w_o^3 e_y = 0 (triple pole -w_o). The integral removes the
steady error of the y2-to-r conversion below (``outer_integral = False``: the PD
-(2 zeta_o w_o chi + w_o^2 e_y / Vx)); ``-beta_ref'`` (``sideslip_feedforward``) turns the
reference's yaw rate Vx kappa into the kinematically consistent V kappa - beta'. The inner
loops keep tracking y2,
whose reference is shifted by ``Delta y2 = (d y2 / d r) Delta r`` with the design model's
steady-cornering ratio (:func:`y2_per_r`; column ``CREF.Y2_PER_R``): in the linear 3DoF model,
holding y2 and y2' = 0 pins r = y2 / (d y2 / d r) algebraically (the steer cancels in y2', the
rear force then fixes Vy - lr r). Gain rule (the same on every track): the outer triple pole
well below the inner loop, at half the flatness controller's slowest inner pole
(:data:`OUTER_WN` = 2 rad/s) and at a third of the mfc-flat iPI's pole
(:data:`MFC_FLAT_OUTER_WN` = 1 rad/s; half was unstable). Default on for both designs.

The intelligent controllers are :mod:`flatfree.controllers.intelligent` (estimator of F fed with
the applied input, saturation and rate limits mirrored from the actuators, anti-windup). The
references are scheduled by the car's measured arc length by default (``schedule``). Each
loop's reference and its derivatives come from the reference trajectory (columns :class:`CREF`);
the measurement vector has the layout :class:`MEAS`.

Sign conventions: e = y - y_ref inside the intelligent controllers (NOTES.md); a positive steer
turns left and increases e_y'' (alpha_lat > 0); a positive torque accelerates (alpha_lon > 0).

A caveat of the paper's flat-output design: the steer cancels in y2' (NOTES.md), i.e. y2 has
relative degree 2 with respect to the steer, and d(y2'')/d(delta) = Delta_22 ~ -C_f lf^2 m Vx / Iz
(for Iz ~ lf lr m) is negative. The first-order ultra-local model y2' = F + alpha delta of the
paper therefore stands for the effect of the steer on y2' accumulated over the estimator window,
and alpha_lat must be negative (:class:`MfcFlatSettings`). The paper reports this design as
clearly worse than the natural-output one (lateral errors above 10 cm). In general
Delta_22 = C_f C_r L G(Vx) / (m Iz Vx) with G the steady ratio d y2 / d r (:func:`y2_per_r`): it
vanishes at the speed :func:`flatfree.controllers.flatness.singular_speed` of a car whose yaw
index Iz / (m lf lr) is below 1, where both flat-output designs lose the steer (the dallara_av21 at
10.8 m/s; ``simulation.prepare`` warns when a reference passes it).

References
----------
.. [P] paper 000_81cd509a47ab99bc, Sections 2.3, 3.2-3.4; corrections in NOTES.md.
.. [FJ13] M. Fliess, C. Join, "Model-free control", Int. J. Control 86 (2013) 2228-2252.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np
from numba import njit

from flatfree._validate import (
    as_real,
    boolean,
    finite,
    in_range,
    nonnegative,
    positive,
    positive_or_inf,
    real,
    whole,
)
from flatfree._vecmath import no_refcount
from flatfree._warn import warn
from flatfree.actuators import ActuatorParams, actuate_step, actuator_state
from flatfree.controllers._shell import independent_copy, nonfinite_command
from flatfree.controllers.flatness_control import (
    FlatnessControlParams,
    flatness_step,
    gains_from_poles,
)
from flatfree.controllers.flatness_control import make_state as flat_make_state
from flatfree.controllers.intelligent import (
    IPAR,
    IST,
    IntelligentParams,
    IntelligentStatus,
    gap_weight,
    intelligent_law_ran,
    intelligent_override,
    intelligent_predict,
    intelligent_set_applied,
    intelligent_status,
    intelligent_step,
    intelligent_step_external,
    make_state,
)
from flatfree.estimators import denoising_weights, fir_new, fir_reset, fir_update
from flatfree.estimators._fir import fir_add
from flatfree.models.bicycle3dof import Bicycle3DoFParams

__all__ = [
    "MEAS",
    "CREF",
    "KIND",
    "MfcFlatSettings",
    "MfcNaturalSettings",
    "NaturalOutputController",
    "NaturalOutputStatus",
    "FlatnessSettings",
    "SCHEDULES",
    "ESTIMATORS_LAT",
    "wants_ey_ddot",
    "unread_channels",
    "VehicleControllerArrays",
    "settings_from_mapping",
    "build_mfc",
    "warn_if_untuned_period",
    "build_flatness",
    "flatness_params",
    "vehicle_step",
    "path_correction",
    "y2_per_r",
    "OUTER_WN",
    "OUTER_ZETA",
    "MFC_FLAT_OUTER_WN",
    "TUNED_PERIOD_S",
    "sample_counts",
    "rescale_sample_counts",
]


class MEAS(enum.IntEnum):
    """Measurement vector handed to a vehicle controller (SI)."""

    X = 0  # [m]
    Y = 1  # [m]
    PSI = 2  # [rad]
    VX = 3  # [m/s]
    VY = 4  # [m/s]
    R = 5  # [rad/s]
    E_Y = 6  # lateral deviation from the reference path, from the measured pose [m]
    E_PSI = 7  # heading error from the measured pose [rad]
    AX = 8  # measured longitudinal acceleration of the CoG, body axes, road plane [m/s^2]
    AY = 9  # measured lateral acceleration of the CoG, body axes, road plane [m/s^2]
    EY_DDOT = 10  # e_y'' from the measured accelerations, velocities and pose (kinematics,
    #               flatfree.tracks.lateral_deviation_acceleration) [m/s^2]


class CREF(enum.IntEnum):
    """Controller reference vector at the current time (SI)."""

    VX = 0  # [m/s]
    AX = 1  # d Vx / dt [m/s^2]
    Y2 = 2  # lf m Vy - Iz r of the 3DoF reference states [kg m^2/s]
    Y2_DOT = 3
    Y2_DDOT = 4
    EY = 5  # lateral deviation reference [m]
    EY_DOT = 6
    EY_DDOT = 7
    KAPPA = 8  # path curvature at the reference point [1/m]
    Y2_PER_R = 9  # d y2 / d r of the design model in steady cornering at the reference
    #               speed [kg m^2/s / (rad/s)] (the path correction's conversion, y2_per_r)
    R_KIN = 10  # yaw-rate feedforward of the path correction: minus the reference sideslip
    #             rate, -beta_ref' [rad/s] (kinematic consistency, module docstring)


# plain-int copies of the slots NaturalOutputController.step writes (an IntEnum member costs
# an attribute lookup and a conversion per use in Python; the names stay)
_M_VX, _M_R, _M_EY, _M_EYDD = int(MEAS.VX), int(MEAS.R), int(MEAS.E_Y), int(MEAS.EY_DDOT)
_C_VX, _C_AX, _C_KAPPA = int(CREF.VX), int(CREF.AX), int(CREF.KAPPA)
_C_EY, _C_EYD, _C_EYDD = int(CREF.EY), int(CREF.EY_DOT), int(CREF.EY_DDOT)

#: How the reference is scheduled: ``"path"`` samples it at the time the reference reaches the
#: car's *measured* arc length (path following), ``"time"`` at the clock time (trajectory
#: tracking). See :class:`MfcNaturalSettings`.
SCHEDULES = ("path", "time")
#: Sources of the lateral F estimate of ``mfc-natural`` (:class:`MfcNaturalSettings`).
ESTIMATORS_LAT = ("algebraic", "imu")


def _check_schedule(value: str) -> None:
    if value not in SCHEDULES:
        raise ValueError(f"schedule = {value!r}: must be one of {', '.join(SCHEDULES)}")


def _least_samples(settings, k: str) -> int:
    """The smallest count the sample-count field ``k`` of ``settings`` accepts: the estimator
    windows' ``_LEAST_WINDOW`` (the natural-output iPD's nu = 2 fit takes 3), 2 for a
    denoiser."""
    return settings._LEAST_WINDOW if k.startswith("window") else 2


def _check_sample_counts(settings) -> None:
    """Each sample count of ``settings`` (:func:`sample_counts`) stored as an int (a TOML 100.0
    too), at least :func:`_least_samples`; a denoiser may be 0 (off)."""
    for k, v in sample_counts(settings).items():
        if k.startswith("denoise") and as_real(v) == 0.0:
            object.__setattr__(settings, k, 0)
            continue
        unit = "samples (0: off)" if k.startswith("denoise") else "samples"
        object.__setattr__(settings, k, whole(k, v, _least_samples(settings, k), unit))


#: The control period [s] at which the model-free settings' sample counts (estimator windows,
#: denoisers) were chosen: the defaults' and the named scenarios' are counts at 1 kHz.
TUNED_PERIOD_S = 0.001

# the settings' fields that count samples (those a settings class has)
_SAMPLE_COUNTS = ("window_lon", "window_lat", "denoise_lon", "denoise_lat", "denoise_yaw")


def sample_counts(settings) -> dict[str, int]:
    """The fields of a controller's settings that count samples (estimator windows,
    denoisers), with their values; empty for :class:`FlatnessSettings`."""
    return {k: getattr(settings, k) for k in _SAMPLE_COUNTS if hasattr(settings, k)}


def rescale_sample_counts(settings, dt: float, *, from_dt: float = TUNED_PERIOD_S):
    """``settings`` with every sample count moved from control period ``from_dt`` [s] to
    ``dt`` [s] so that each window and denoiser keeps its duration.

    A count ``n`` becomes the nearest whole number to ``n from_dt / dt``, at least the smallest
    the settings accept (:func:`_least_samples`: 3 for the natural-output windows, 2 for the
    others); 0 (a denoiser off) stays 0. Settings without sample counts
    (:class:`FlatnessSettings`) come back unchanged. The gains, time constants and rates of the
    settings are in seconds already and stay. What the durations are worth at another rate
    was measured on the 10DoF with noise (benchmarks/README.md "Control period").
    """
    dt = positive("dt", dt, "s")
    ratio = positive("from_dt", from_dt, "s") / dt
    changes = {k: 0 if n == 0 else max(_least_samples(settings, k), round(n * ratio))
               for k, n in sample_counts(settings).items()}
    return dataclasses.replace(settings, **changes) if changes else settings


# a window whose duration is off the tuned one by more than this factor is warned about
_PERIOD_WARN_RATIO = 1.5


def warn_if_untuned_period(controller: str, settings, dt: float) -> None:
    """Warn when a model-free controller runs at a period other than :data:`TUNED_PERIOD_S`
    with its estimator windows left at the counts tuned at 1 kHz (the defaults) and their
    durations more than 1.5x off the tuned ones: at 100 Hz the natural-output controller's
    default windows span 1 s instead of 0.1 s, and the car leaves Norisring at 4.7 s
    (benchmarks/README.md "Control period"). Counts a user chose are the user's (a chosen
    count that equals the default is taken as left at it); the denoisers are not checked
    (their tuned lengths differ between the named scenarios: ``denoise_yaw`` 50 or 20)."""
    ratio = dt / TUNED_PERIOD_S  # a window left at its count spans ratio x its tuned time
    if 1.0 / _PERIOD_WARN_RATIO <= ratio <= _PERIOD_WARN_RATIO:
        return
    tuned = type(settings)()
    off = [f"{k} = {n} samples spans {n * dt:g} s (tuned: {n * TUNED_PERIOD_S:g} s)"
           for k in ("window_lon", "window_lat")
           if (n := getattr(settings, k)) == getattr(tuned, k)]
    if off:
        warn(f"{controller} at a control period of {dt:g} s: its sample counts were tuned at "
             f"{TUNED_PERIOD_S:g} s; {'; '.join(off)}. It is not the tuned controller and may "
             f"leave the track: scale them with settings.for_period({dt:g}) "
             "(Scenario.with_control_period, flatfree run --control-period)", RuntimeWarning)


def _denoiser(n: int) -> np.ndarray:
    """Kernel state of the paper's causal denoiser over ``n`` samples (1-element dummy: off)."""
    if n == 0:
        return np.zeros(1)
    # NOTES.md "Denoising": kernel (2T - 3d), exact on ramps; start-up: prefill (at rest)
    return fir_new(denoising_weights(int(n)), startup="prefill", nonfinite="hold")


#: Default natural frequency of the outer path-following loop [rad/s] (module docstring).
#: Rule: the outer triple pole at half the flatness controller's slowest inner pole (4 rad/s),
#: the same on every track. Measured (Norisring / Budapest, realistic sensors, flatness):
#: wn 1, 1.5, 2, 3 rad/s gave max lateral 50/57, 24/23, 14/13, 6.6/8.8 cm (benchmarks/README.md).
OUTER_WN = 2.0
#: Outer loop of ``mfc-flat`` [rad/s]: a third of the iPI's designed pole (kp_lat = 3 /s). Half
#: of it (1.5 rad/s), the flatness rule, left Norisring: with y2 of relative degree 2 the iPI
#: does not achieve its designed first-order response (measured, :class:`MfcFlatSettings`).
MFC_FLAT_OUTER_WN = 1.0
#: Default damping of the outer path-following loop [-]: critically damped.
OUTER_ZETA = 1.0
#: Floor on the speed dividing e_y in the outer loop and the lateral speed schedule [m/s]
#: (standstill guard).
_OUTER_V_MIN = 5.0


def _check_outer(settings) -> None:
    for k in ("path_correction", "sideslip_feedforward", "outer_integral"):
        boolean(k, getattr(settings, k))
    positive("outer_wn", settings.outer_wn, "rad/s")
    positive("outer_zeta", settings.outer_zeta, "-")


def y2_per_r(model: Bicycle3DoFParams, vx: np.ndarray | float) -> np.ndarray:
    """Steady-cornering ratio d y2 / d r of the linear 3DoF model at speed ``vx``.

    With y2 = lf m Vy - Iz r held (y2' = 0): y2' = L Fyr - lf m Vx r (NOTES.md: the steer
    cancels) gives Fyr = lf m Vx r / L, and Fyr = -Cr (Vy - lr r) / Vx gives
    Vy = (lr - lf m Vx^2 / (Cr L)) r, hence y2 = G r with

        G = lf m lr - Iz - (lf m Vx)^2 / (Cr L)      [kg m^2/s per rad/s]

    (checked with sympy in tests/test_paper_scenarios.py).
    """
    big_l = model.lf + model.lr
    vx = np.asarray(vx, dtype=float)
    return model.lf * model.m * model.lr - model.iz - (model.lf * model.m * vx) ** 2 / (
        model.cr * big_l)


@njit(cache=True)
def path_correction(vx, vy, e_y, e_psi, wn, zeta, integral):
    """Yaw-rate correction of the outer path-following loop [rad/s] (module docstring).

    ``integral`` is the time integral of ``e_y / max(vx, 5 m/s)`` [s]; with ``zeta <= 0`` the
    loop is the PID with the triple pole ``-wn``:
    ``-(3 wn chi + 3 wn^2 e_y / v + wn^3 integral)``; else the PD
    ``-(2 zeta wn chi + wn^2 e_y / v)``; ``chi = e_psi + atan2(vy, vx)`` is the course error.
    """
    v = max(vx, _OUTER_V_MIN)
    chi = e_psi + math.atan2(vy, v)  # course = psi + beta (ISO 8855)
    if zeta <= 0.0:  # (s + wn)^3 = s^3 + 3 wn s^2 + 3 wn^2 s + wn^3
        return -(3.0 * wn * chi + 3.0 * wn * wn * e_y / v + wn * wn * wn * integral)
    return -(2.0 * zeta * wn * chi + wn * wn * e_y / v)


class KIND(enum.IntEnum):
    """Controller codes of the compiled loop."""

    FLATNESS = 0
    MFC_FLAT = 1
    MFC_NATURAL = 2
    PYTHON = 3  # a user's Python controller (flatfree.simulation.simulate(controller=...))


class _SampleCountSettings:
    """Settings whose estimator windows and denoisers are counts of control samples."""

    __slots__ = ()
    # the smallest estimator window [samples] (the nu = 1 fit; a subclass may ask more)
    _LEAST_WINDOW: ClassVar[int] = 2

    def for_period(self, dt: float, *, from_dt: float = TUNED_PERIOD_S) -> Self:
        """These settings at control period ``dt`` [s]: every window and denoiser keeps its
        duration (:func:`rescale_sample_counts`; the counts given are at ``from_dt``, the
        defaults' 1 ms). ``MfcNaturalSettings().for_period(0.01)`` for a 100 Hz loop."""
        return rescale_sample_counts(self, dt, from_dt=from_dt)


@dataclass(frozen=True, slots=True, kw_only=True)
class MfcNaturalSettings(_SampleCountSettings):
    """Settings of the model-free controller on natural outputs (iP on Vx, iPD on e_y).

    The defaults are the base of every named tuning (flatfree.scenarios), the same on every
    track, at a 1 kHz control rate: ``paper-imu`` uses them with its inertial estimator
    (:data:`flatfree.scenarios.IMU_SETTINGS`), the dallara_av21 (``recorded``) with
    ``alpha_lat`` 60 (:data:`flatfree.scenarios.DALLARA_NATURAL_SETTINGS`: alpha follows the
    car's steer gain; 30 puts the iPD below its stable range on that car, measured), and the
    peugeot406's ``paper`` (the paper's algebraic estimator) with ``curvature_term`` on and
    the lateral loop retuned around it (:data:`flatfree.scenarios.NATURAL_SETTINGS`, a joint
    search in session 23: every lap of the 7 bundled tracks over 100 seeds within 2.11 cm;
    with the defaults Spa keeps 62 laps of 100). The
    defaults were chosen by sweeps on the 10DoF plant with the realistic sensors over Norisring,
    Monza, Spa and Budapest, several seeds (worst max lateral error, completion, steer rate);
    the record is benchmarks/README.md "Closed loop"; the figures below are theirs.
    ``yaw_damping = 0``, ``wn_lat = 4``,
    ``wn_lat_speed = 0``, ``correction_max = inf`` and ``steer_min_speed = 0`` are the
    paper's design unchanged (it completes Norisring noise-free at 2.1 cm but leaves the
    track on fast tracks and with noise: see ``yaw_damping``; with these defaults the last two
    never act on the named scenarios' runs).

    Parameters
    ----------
    alpha_lon : float
        Input gain of the longitudinal ultra-local model Vx' = F + alpha u [(m/s^2) / (N m)].
        Of the order of 1 / (m R_e) (a car of 1,000-1,500 kg on 0.3 m wheels: 0.002-0.003);
        the iP is stable for alpha / b from about 0.24 to 50 (intelligent.py), so one value
        serves every preset.
    kp_lon : float
        Gain of the speed error [1/s] (closed-loop time constant 1 / kp_lon).
    window_lon : int
        Samples of the F estimator window (speed loop). 100 (0.1 s at 1 kHz, as the lateral
        window): the speed loop's F is a first derivative of the measured Vx, so the window
        sets the torque's chatter (wheel-speed noise 0.05 m/s at 1 kHz; the derivative's noise
        falls as window^-1.5, down to the proportional term's kp sigma_v / alpha_lon = 50 N m),
        and its lag (half the window) the speed error where F changes. With 50 (before
        2026-11-22) the recorded drive's torque was mostly noise (RMS 509 N m, noise-free 296;
        324 with 100) and the laps' torque-rate RMS was 18-25 kN m/s (8-11 with 100); the
        price is the dallara_av21's speed-error RMS on LVMS, 0.025 -> 0.041 m/s (150: 0.060 for
        a further 20 % less torque rate). Lateral errors and completion rates do not move
        beyond the seeds' spread (100 seeds on Spa / Catalunya / LVMS: 56 / 97 / 93 completed
        with 100, 58 / 92 / 92 with 50, both with the body-speed power cap of that day;
        benchmarks/README.md "Speed-loop window").
    alpha_lat : float
        Input gain of the lateral ultra-local model e_y'' = F + alpha delta [(m/s^2) / rad];
        of the order of C_f / m (the direct effect of the front lateral force).
    wn_lat, zeta_lat : float
        Natural frequency [rad/s] and damping [-] of the designed lateral error dynamics
        e'' + 2 zeta wn e' + wn^2 e = 0 (kp = wn^2, kd = 2 zeta wn), at and above
        ``wn_lat_speed``.
    wn_lat_speed : float
        Speed [m/s] below which the lateral error dynamics are made faster in inverse
        proportion to the measured speed, ``wn = wn_lat min(wn_lat_speed / Vx, wn_lat_ratio)``
        (kp and kd follow, zeta kept); 0: off (``wn = wn_lat`` always). Why: the largest errors
        with a constant ``wn`` are at the entries of slow corners (Norisring's hairpin, braking
        at 6 m/s^2 from 20 m/s: 2.6 cm noise-free at ``wn`` 8, 1.2 cm at 12), where the F
        estimator's lag meets the fastest change of the lateral demand; but a constant
        ``wn`` of 10-12 loses the fast tracks (Spa, LVMS: measured). The yaw mode left as zero
        dynamics (``yaw_damping``) is damped in proportion to ``1 / Vx``, so the loop can be
        faster where the car is slow. No vehicle parameter enters; the same rule serves every
        track (benchmarks/README.md "Closed loop"; reproduce the constant-wn figures with
        ``benchmarks/sweep_seeds.py --set wn_lat_speed=0 --set wn_lat=12``).
    wn_lat_ratio : float
        Largest ratio ``wn / wn_lat`` of the schedule (>= 1). 1.5 (wn <= 12 rad/s, reached
        at 20 m/s): with 2 (wn up to 16 rad/s at hairpin exits near 10 m/s) the steer swung
        up to 0.5 rad while the unloaded inner front wheel of the open differential spun up
        under full drive torque and 3 of 60 noisy Norisring laps left the track at its
        hairpin exit (49-54 s); with 1.5, 60 of 60 completed, max 1.34-2.65 cm (2: 1.41-2.59);
        Spa 20/30 vs 18/30, Catalunya 27/30 both (benchmarks/README.md "Closed loop"; measured
        with ``window_lon`` 50).
    correction_max : float
        Bound [m/s^2] on the iPD's proportional correction ``|kp e|`` (the e_y'' it asks for
        to close the error, beyond ``-F + e_y_ref''`` and the damping ``kd e'``;
        :class:`~flatfree.controllers.intelligent.IntelligentParams` ``correction_max``, a
        nested saturation): a large error closes at a speed of at most
        ``correction_max / kd`` (0.17-0.25 m/s at 4) instead of through a steer step that the
        steer-rate limit turns into a growing swing. Why 4 (beyond the paper): the gains
        tuned for the tracks (``wn_lat`` 8-12 rad/s; the paper's 4 holds a wider region but
        not the tracks' centimetres) leave, unbounded (inf), a region of attraction of
        centimetres: a car started 0.1 m off a straight path leaves it at 10 and 40 m/s, 5 cm
        suffice at 20 m/s; with 4 the peugeot406 and the bmw320i (at 5-40
        m/s) and the dallara_av21 (its alpha_lat 60, at 10-60 m/s) come back from 3 m, within
        1 cm after 4.2-6.3 s from 1 m and 12.2-18.3 s from 3 m, noise-free
        (``benchmarks/initial_offset.py [--vehicle V]``). On the
        tracks ``|kp e|`` stays below it with these defaults: 100 seeds on each bundled track
        gave the figures of the unbounded law, and the named scenarios' seed-1 laps were the
        same bit for bit; so are ``paper``'s (:data:`flatfree.scenarios.NATURAL_SETTINGS`:
        wn 5.7 rad/s, kp e reaches 4 m/s^2 at 12 cm), whose starts off the path come back
        from the whole grid too. (Session 21's tuning, with wn up to 19 rad/s below 16 m/s,
        reached it briefly: benchmarks/README.md "A search for a more robust `paper`
        tuning".) With the defaults, 3
        already moves Spa and Catalunya (65 and 98 of 100 laps, up to 4.50 cm, against 62 and
        97); 6 loses the 5 cm start at 20 m/s (benchmarks/README.md "The bound on the
        proportional correction").
    steer_min_speed : float
        Measured speed [m/s] below which the lateral loop holds the steer applied last
        (0: never). At a standstill the steer does not move e_y: the iPD's F absorbs the
        missing response and the law, an integrator in disguise there, turns the wheels to
        their lock within seconds (peugeot406, a 5 cm offset, 1 s standing: 0.42 rad, and
        pulling away from it swings the car 0.28 m off its path). Held, the estimators keep
        running on the held steer and the law takes over when the car moves: pulling away from
        0.05-1 m off, the error never exceeds the start's (``benchmarks/pull_away.py``). 1 m/s
        is below every speed of the named scenarios (the recording's stop ends at 1.9 m/s),
        so their runs are unchanged. Beyond the paper.
    window_lat : int
        Samples of the F estimator window (lateral loop).
    derivative_lat : str
        Source of e_y' (``"model"``: the F estimator's least-squares fit, no lag;
        ``"algebraic"``: the paper's derivative, lag T/2).
    denoise_lon, denoise_lat : int
        Samples of the paper's causal denoiser (eq. (filtering), corrected in NOTES.md:
        :func:`flatfree.estimators.denoising_weights`, the least-squares line over the window
        at the newest sample, exact on ramps) applied to the measured Vx and e_y before the
        iP / iPD; 0 (default): none. With 1 mm white position noise at 1 kHz the iPD's steer
        jitter exceeds the steer-rate limit (0.4 rad/s for the peugeot406) whatever the
        setting short of windows of 0.3 s (measured); a denoiser of 100 samples with a
        300-sample F window gives smooth steering at about 4x the lateral error.
    yaw_damping : float
        Gain ``k_r`` [s] of a parameter-free yaw damper added to the iPD's steer:
        ``delta = delta_iPD - k_r (r - Vx kappa(s))`` with the measured yaw rate and speed and
        the path curvature at the measured position; 0: off (the paper's design). Why: the
        lateral deviation of the CoG as output leaves the yaw motion as zero dynamics,
        ``s^2 + L Cr lr / (Iz Vx) s + L Cr / Iz`` for the linear bicycle (derivation in
        benchmarks/README.md "Closed loop"), 8.7 rad/s with damping 0.14 at 50 m/s for the
        peugeot406: perfect e_y tracking leaves a weave that noise excites and the steer-rate
        limit then destabilises. ``r - Vx kappa`` is minus the sideslip rate when the car is on
        the path, zero in steady cornering, so the damper adds no steady error.
    denoise_yaw : int
        Samples of the paper's causal denoiser applied to the yaw damper's input
        ``r - Vx kappa`` (0: none); the gyro's white noise would otherwise reach the steer
        directly (``k_r sigma_r`` per sample).
    estimator_lat : str
        Source of the lateral loop's F and of e_y, e_y'. ``"algebraic"`` (default, the
        paper's): the algebraic estimator on the window of measured e_y and applied steer.
        ``"imu"``: from the measured lateral acceleration of the deviation, ``e_y''`` (column
        ``MEAS.EY_DDOT``, formed from an inertial unit's accelerations, the measured velocities
        and the path: :func:`flatfree.tracks.lateral_deviation_acceleration`), the
        ultra-local model read directly at the acceleration level,
        ``F = lp(e_y'') - alpha lp(delta_applied)``, with the same first-order filter ``lp``
        (``imu_filter_s``) on both so that the input's effect cancels in step; and e_y, e_y'
        from a complementary observer that integrates e_y'' twice and is corrected by the
        measured e_y (``observer_wn``). Still model-free and parameter-free (kinematics only);
        no estimator lag, and the 1 mm position noise no longer reaches the steer through a
        second derivative (benchmarks/README.md "Closed loop", "Acceleration-aided F"). Where
        e_y'' or e_y is not finite (a sensor fault) the step falls back to the algebraic
        estimate, which keeps running, and the observer restarts from the next finite sample.
        With it the yaw damper's term, added after the iPD, is a lateral disturbance
        ``alpha k_r (r - Vx kappa)`` that the lag-free loop does not compensate (it enters F
        through the applied steer one step late): the lateral error grows with ``yaw_damping``
        (0.1 cm at 0, 1.0-1.5 cm at the algebraic design's 0.4 s), while some damping is
        needed where the yaw mode loses its own, braking hard at speed:
        :data:`flatfree.scenarios.IMU_SETTINGS` uses 0.2 s on a 20-sample denoiser
        (``denoise_yaw``; measured trade-off there).
    imu_filter_s : float
        Time constant [s] of the first-order filter on e_y'' and on the applied steer
        (``estimator_lat = "imu"``). Insensitive below 5 ms (without the yaw damper, where the
        estimator's own error shows: Norisring, Spa, LVMS, realistic sensors, seeds 0-2, max
        lateral error 0.08-0.13 cm at 1 and 2 ms, 0.09-0.13 at 5); slower filters lag:
        0.10-0.18 cm at 10 ms, 0.14-0.24 at 20, 0.27-0.48 at 50 (``benchmarks/sweep_seeds.py
        --scenario paper-imu --seeds 3 --tracks Norisring,Spa,LVMS --set yaw_damping=0 --set
        denoise_yaw=50 --set imu_filter_s=T``). With the scenarios' damper 1 to 20 ms all give
        0.64-0.67 cm on Norisring (``benchmarks/imu_sensitivity.py``).
    observer_wn : float
        Bandwidth [rad/s] of the complementary observer of (e_y, e_y') (double pole,
        ``estimator_lat = "imu"``): below it the estimate follows the measured e_y, above it
        the integrated acceleration (``benchmarks/imu_sensitivity.py``, with ``--set
        yaw_damping=0 --set denoise_yaw=50`` for the damper-less figures). Without the yaw
        damper 20 is the best measured with 1 mm of position noise (Norisring and Spa, seeds 0-1,
        max lateral error 0.09-0.13 cm; 5: 0.21-0.26, 40: 0.12-0.19 with a steer-rate RMS of 0.21
        rad/s), and with 1 cm of white position noise 20 leaves the track where 5-10 hold 0.3-0.9
        cm: lower it for a noisier position. With the scenarios' damper (k_r 0.2 s) 5 to 40 all
        hold, 1 cm noise too (benchmarks/README.md "Acceleration-aided F").
    observer_bias_wn : float
        Pole [rad/s] of a third observer state, the accelerometers' constant bias in e_y''
        (``estimator_lat = "imu"``; the poles are then -observer_wn twice and
        -observer_bias_wn); 0 (default): no bias state. Without it a bias b leaves the steady
        offset (b + kp b / wo^2 + kd 2 b / wo) / kp. A trade (``paper-imu``, Norisring and Spa,
        seeds 0-2, max lateral error [cm]; ``benchmarks/imu_sensitivity.py --only bias``): with
        an uncalibrated MEMS unit's 0.5 m/s^2 (50 mg) the bias state at 0 / 0.5 / 1 / 2 / 5
        rad/s gives 2.5-3.2 / 1.6-1.9 / 1.3-1.4 / 0.9-1.3 / 0.6-1.3; but it also reads position
        noise as bias: with 1 cm of white position noise 1 and 2 rad/s lose 2 of 6 runs and 5
        loses 3 (0 and 0.5: none), and with every channel at 100 Hz 2 and 5 rad/s lose 1 of 6. Off
        by default (an INS's calibrated bias, 0.01 m/s^2, costs nothing); 0.5 for a raw
        accelerometer.
    curvature_term : bool
        Take the path's curvature out of the lateral loop's F: the ultra-local model becomes
        ``e_y'' = F + alpha (delta - Vx^2 kappa(s) / alpha)``, so F is estimated without
        ``-Vx^2 kappa`` and the law adds it back at once, ``delta = delta_iPD + Vx^2 kappa /
        alpha`` (default False: the paper's F, which holds the whole path term). Why: in the
        Frenet frame ``e_y'' = a_n cos(e_chi) - V^2 kappa cos^2(e_chi) / (1 - kappa e_y) +
        V' sin(e_chi)``, with ``a_n`` the acceleration normal to the velocity (what the tyres
        and the steer make) and ``e_chi`` the course error: where the curvature changes, the
        term ``-V^2 kappa`` changes at once, and an F estimated over a window of past samples
        follows it late (the window's lag: half of it, 50 ms at 100 samples, for the F of a
        line fitted to it), which the loop pays in lateral error at every change of curvature.
        The term is kinematic: the measured speed and the path's curvature at the measured
        position (the inputs of the yaw damper), no vehicle parameter, so the design stays
        model-free; beyond the paper, whose F holds it. Where the speed or the curvature is not
        finite the last finite term is kept. A step that holds the iPD's output (a non-finite
        e_y) keeps the term current, the path turning on while the position is lost; while the
        window fills the start's steer is held as it is. The estimators are fed
        ``delta_applied - Vx^2 kappa / alpha`` of each period, so it needs ``feed_applied``
        (benchmarks/README.md "The path's curvature out of F").
    feed_applied : bool
        Feed the estimators the inputs the actuators actually applied (rate limits, the power
        cap, faults, the yaw damper) instead of the controllers' own outputs (default True;
        intelligent.py: F must be estimated from the applied input).
    schedule : str
        ``"path"`` (default): the speed and lateral references are read at the reference time
        of the car's measured arc length; ``"time"``: at the clock time. Why path: the
        speed profile (a friction ellipse, :mod:`flatfree.tracks.speed`) ignores the engine's
        power, so on long straights the car falls behind the clock (peugeot406 on Norisring:
        ~0.8 s after the first straight); with clock scheduling it then brakes and accelerates
        at the wrong places (at an apex, where the open differential lets the unloaded inner
        front wheel spin up: the run leaves the track at 26.5 s). The loop ends the lap when the
        car reaches the end of the reference path.
    """

    alpha_lon: float = 0.002
    kp_lon: float = 2.0
    window_lon: int = 100
    alpha_lat: float = 30.0
    wn_lat: float = 8.0
    zeta_lat: float = 1.0
    wn_lat_speed: float = 30.0
    wn_lat_ratio: float = 1.5
    correction_max: float = 4.0
    steer_min_speed: float = 1.0
    window_lat: int = 100
    derivative_lat: str = "model"
    denoise_lon: int = 0
    denoise_lat: int = 0
    yaw_damping: float = 0.4
    denoise_yaw: int = 50
    estimator_lat: str = "algebraic"
    imu_filter_s: float = 0.005
    observer_wn: float = 20.0
    observer_bias_wn: float = 0.0
    curvature_term: bool = False
    feed_applied: bool = True
    schedule: str = "path"

    # the smallest estimator window (the iPD's nu = 2 fit) [samples]
    _LEAST_WINDOW: ClassVar[int] = 3

    def __post_init__(self) -> None:
        _check_schedule(self.schedule)
        _check_sample_counts(self)
        if finite("yaw_damping", self.yaw_damping, "s") < 0.0:
            raise ValueError(f"yaw_damping = {self.yaw_damping!r} s: must be >= 0")
        if self.estimator_lat not in ESTIMATORS_LAT:
            raise ValueError(f"estimator_lat = {self.estimator_lat!r}: must be one of "
                             f"{', '.join(ESTIMATORS_LAT)}")
        positive("imu_filter_s", self.imu_filter_s, "s")
        positive("observer_wn", self.observer_wn, "rad/s")
        if finite("observer_bias_wn", self.observer_bias_wn, "rad/s") < 0.0:
            raise ValueError(f"observer_bias_wn = {self.observer_bias_wn!r} rad/s: must be >= 0")
        boolean("feed_applied", self.feed_applied)
        boolean("curvature_term", self.curvature_term)
        if self.curvature_term and not self.feed_applied:
            raise ValueError("curvature_term = True needs feed_applied = True (the estimators "
                             "are fed the applied steer less the curvature term)")
        positive("alpha_lon", self.alpha_lon, "(m/s^2)/(N m)")
        positive("kp_lon", self.kp_lon, "1/s")
        positive("alpha_lat", self.alpha_lat, "(m/s^2)/rad")
        positive("wn_lat", self.wn_lat, "rad/s")
        positive_or_inf("correction_max", self.correction_max, "m/s^2")
        nonnegative("steer_min_speed", self.steer_min_speed, "m/s")
        if finite("wn_lat_speed", self.wn_lat_speed, "m/s") < 0.0:
            raise ValueError(f"wn_lat_speed = {self.wn_lat_speed!r} m/s: must be >= 0 "
                             "(0: no schedule)")
        if finite("wn_lat_ratio", self.wn_lat_ratio, "-") < 1.0:
            raise ValueError(f"wn_lat_ratio = {self.wn_lat_ratio!r}: must be >= 1")
        positive("zeta_lat", self.zeta_lat, "-")
        if self.derivative_lat not in ("model", "algebraic"):
            raise ValueError(
                f"derivative_lat = {self.derivative_lat!r}: must be 'model' or 'algebraic'")


@dataclass(frozen=True, slots=True, kw_only=True)
class MfcFlatSettings(_SampleCountSettings):
    """Settings of the model-free controller on flat outputs (two iPIs, nu = 1).

    Parameters
    ----------
    alpha_lon, kp_lon, ki_lon, window_lon
        Speed loop (as :class:`MfcNaturalSettings`, plus the integral gain [1/s^2]). The window
        stays 50 samples here (the natural-output design's is 100 since 2026-11-22, against
        the torque's chatter): this design's laps are chaotic at the 1 m level, and its
        completion moved both ways with a longer window (benchmarks/README.md "Speed-loop
        window"), so no change could be judged from them.
    alpha_lat : float
        Input gain of y2' = F + alpha delta [(kg m^2/s^2) / rad]. Negative (module docstring):
        left steer raises the yaw rate and lowers y2 = lf m Vy - Iz r. Of the order of
        -Iz (lf C_f / Iz) = -lf C_f over the window (the yaw-rate response to the steer).
    kp_lat, ki_lat, window_lat
        Lateral loop gains [1/s], [1/s^2] and window [samples].
    denoise_lon, denoise_lat : int
        As :class:`MfcNaturalSettings` (applied to Vx and to y2).
    schedule : str
        As :class:`MfcNaturalSettings`.
    path_correction : bool
        The outer path-following correction of the y2 reference (module docstring); default
        True; False is the paper's design exactly (velocities only: it drifts off the track).
    outer_wn : float
        Natural frequency of the outer loop [rad/s] (:data:`MFC_FLAT_OUTER_WN`).
    outer_zeta, sideslip_feedforward, outer_integral
        As :class:`FlatnessSettings`.
    steer_min_speed : float
        Below this measured speed [m/s] the steer applied last is held (default 1): at a
        standstill the steer does not move y2, and the iPI wound the wheels to their lock
        (0.6 rad after 60 s at 0 m/s with a 0.5 m lateral deviation; below the singular speed,
        0.58 m/s for the peugeot406, the correction's d y2 / d r also changes sign). 0: no
        hold.

    Tuning of the lateral loop (the paper gives no values; benchmarks/README.md "Closed
    loop" has the sweeps). Sign: negative (module docstring); a positive alpha_lat left
    Budapest within 1.7 s for every window and gain tried, noise-free. Size: of the order of
    the steer's effect on y2' accumulated over the estimator window,
    d(y2'')/d(delta) T ~ -C_f lf^2 m Vx / Iz T (about -2e6 /s x 0.05 s = -1e5 at 30 m/s for
    the peugeot406). Gains: with the former kp 10, window 20 the steer limit-cycles at its
    rate limit (+-80 mrad, noise-free, Budapest 2-3 s, without the correction); kp 3
    (alpha -3e5, window 20) leaves a 0.4 mrad ripple there. Swept with the correction on
    and the realistic sensors (alpha -5e4 to -1e6, windows 20-200, kp 1-8, ki 0/3, denoiser
    0/30/100, outer wn 0.5-2): no setting with kp >= 5, a window >= 80 or outer wn >= 1.5
    completed both Norisring and Budapest;
    alpha -1e5, window 50, kp 3, wn 1 completes both for seeds 0-3 (max lateral error
    0.99-1.03 m on Norisring, 0.71 m on Budapest); -5e4 was better for seed 0 but 1.4 m for
    seed 1. The steer still moves close to its rate limit of 0.4 rad/s (steer-rate RMS
    0.31 rad/s, 0.21 noise-free): the nu = 1 iPI on a relative-degree-2 output is the limit
    of this design. On a car with a yaw index Iz / (m lf lr) below 1 the steer's effect on y2
    vanishes at :func:`flatfree.controllers.flatness.singular_speed` and reverses below it:
    the dallara_av21 (10.8 m/s) follows its recording within 10.75 cm until the recorded car
    brakes through that speed at the end, then leaves the path (1.1 m in the last 1.5 s,
    noise-free too).
    """

    alpha_lon: float = 0.002
    kp_lon: float = 2.0
    ki_lon: float = 0.0
    window_lon: int = 50
    alpha_lat: float = -1.0e5
    kp_lat: float = 3.0
    ki_lat: float = 0.0
    window_lat: int = 50
    denoise_lon: int = 0
    denoise_lat: int = 0
    schedule: str = "path"
    path_correction: bool = True
    outer_wn: float = MFC_FLAT_OUTER_WN
    outer_zeta: float = OUTER_ZETA
    sideslip_feedforward: bool = True
    outer_integral: bool = True
    steer_min_speed: float = 1.0

    def __post_init__(self) -> None:
        _check_schedule(self.schedule)
        _check_sample_counts(self)
        _check_outer(self)
        nonnegative("steer_min_speed", self.steer_min_speed, "m/s")
        positive("alpha_lon", self.alpha_lon, "(m/s^2)/(N m)")
        finite("alpha_lat", self.alpha_lat, "(kg m^2/s^2)/rad")
        if self.alpha_lat == 0.0:
            raise ValueError("alpha_lat = 0.0 (kg m^2/s^2)/rad: must be nonzero")
        for k in ("kp_lon", "kp_lat"):
            positive(k, getattr(self, k), "1/s")
        for k in ("ki_lon", "ki_lat"):
            if finite(k, getattr(self, k), "1/s^2") < 0.0:
                raise ValueError(f"{k} = {getattr(self, k)!r} 1/s^2: must be >= 0")


@dataclass(frozen=True, slots=True, kw_only=True)
class FlatnessSettings:
    """Settings of the flatness-based controller in the closed loop.

    Parameters
    ----------
    speed_poles : tuple of 2 floats
        Closed-loop poles of the speed error (PI) [1/s] (:func:`gains_from_poles`).
    lateral_poles : tuple of 3 floats
        Closed-loop poles of the y2 error (PID) [1/s].
    cf_scale, cr_scale : float
        Factors on the design model's cornering stiffnesses [-] (paper Figure 2: 0.3, 0.3).
        The controller's own y2 reference is computed with the scaled model too: the
        controller plans and tracks with the model it believes in.
    derivative : str
        Source of the measured y2' (``"model"`` or ``"algebraic"``; flatness_control.py).
    wheel_accel : str
        ``"zero"`` or ``"rolling"`` (flatness_control.py).
    schedule : str
        As :class:`MfcNaturalSettings`.
    path_correction : bool
        The outer path-following correction of the y2 reference (module docstring); default
        True; False is the paper's design exactly (velocities only: it drifts off the track).
        The y2 correction uses the controller's own (possibly scaled) design model for
        d y2 / d r.
    outer_wn : float
        Natural frequency of the outer loop [rad/s] (:data:`OUTER_WN`, chosen by a rule).
    outer_zeta : float
        Damping of the outer PD [-] (used when ``outer_integral`` is False).
    sideslip_feedforward : bool
        Add ``-beta_ref'`` (column ``CREF.R_KIN``) to the yaw-rate correction: the reference's
        r = Vx kappa is then the kinematically consistent r = V kappa - beta'. Measured
        (flatness, wn 2): max 13.9 / 13.1 cm on Norisring / Budapest with it, 16.0 / 19.4
        without (for 0.3 Cf, Cr it is slightly worse: 28 vs 26 cm).
    outer_integral : bool
        Integral action on e_y / V (the PID with the triple pole -wn, module docstring);
        it removes the steady error of d y2 / d r, which the linear model gets wrong when the
        10DoF's tyres are nonlinear. Measured (flatness, wn 2): 14 / 13 cm with it, 42 / 41 cm
        without (PD, zeta 1).
    """

    speed_poles: tuple[float, ...] = (-2.0, -3.0)
    lateral_poles: tuple[float, ...] = (-4.0, -5.0, -6.0)
    cf_scale: float = 1.0
    cr_scale: float = 1.0
    derivative: str = "model"
    wheel_accel: str = "rolling"
    schedule: str = "path"
    path_correction: bool = True
    outer_wn: float = OUTER_WN
    outer_zeta: float = OUTER_ZETA
    sideslip_feedforward: bool = True
    outer_integral: bool = True

    def __post_init__(self) -> None:
        _check_schedule(self.schedule)
        _check_outer(self)
        object.__setattr__(self, "speed_poles", tuple(float(v) for v in self.speed_poles))
        object.__setattr__(self, "lateral_poles", tuple(float(v) for v in self.lateral_poles))
        gains_from_poles(self.speed_poles, self.lateral_poles)  # validates
        positive("cf_scale", self.cf_scale, "-")
        positive("cr_scale", self.cr_scale, "-")

    def for_period(self, dt: float, *, from_dt: float = TUNED_PERIOD_S) -> Self:
        """These settings at control period ``dt``: the same (the flatness law counts no
        samples: its poles are in 1/s), as the model-free settings' ``for_period`` is called
        in code that serves every design."""
        positive("dt", dt, "s")
        positive("from_dt", from_dt, "s")
        return self


_SETTINGS = {"mfc-natural": MfcNaturalSettings, "mfc-flat": MfcFlatSettings,
             "flatness": FlatnessSettings}
_CONTROLLER_OF = {cls: name for name, cls in _SETTINGS.items()}


def settings_from_mapping(controller: str, values: Mapping[str, Any]):
    """The settings object of ``controller`` from a mapping (a scenario's controller_settings).

    Unknown keys raise ``ValueError`` listing the valid ones; missing keys take the documented
    defaults of the settings class.
    """
    try:
        cls = _SETTINGS[controller]
    except KeyError:
        raise ValueError(
            f"controller {controller!r} has no model-free settings; valid: {sorted(_SETTINGS)}"
        ) from None
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise ValueError(f"controller_settings {unknown} unknown for {controller}; valid keys: "
                         f"{', '.join(sorted(known))}")
    return cls(**dict(values))


@dataclass(frozen=True, slots=True)
class VehicleControllerArrays:
    """Everything the compiled loop needs for one vehicle controller."""

    kind: int
    p_lon: np.ndarray
    s_lon: np.ndarray
    p_lat: np.ndarray
    s_lat: np.ndarray
    coef: np.ndarray  # [denoise_lon on, denoise_lat on, a, b, yaw damping k_r, feed applied,
    #                   denoise_yaw on, path correction on, outer_wn, outer_zeta,
    #                   sideslip feedforward on, integral on, dt, integrator of e_y / v,
    #                   then mfc-natural only: zeta_lat, wn_lat, wn_lat_speed, wn_lat_ratio,
    #                   imu estimator on, filter pole, observer gains l1, l2, then the imu
    #                   estimator's state: filtered e_y'', filtered steer, e_y and e_y'
    #                   estimates, started flag, then the bias gain l3 and the bias estimate
    #                   (_IMU_* indices), steer_min_speed, the curvature term on, and
    #                   the term of the period running (_CURV_*)];
    #                   mfc-flat a, b = lf m, Iz; flatness a = dt; both then, after the
    #                   outer correction's 7, its held y2 shift and held flag and mfc-flat's
    #                   steer_min_speed (_OUTER_SHIFT, _OUTER_HELD, _FLAT_STEER_MIN_V)
    f_lon: np.ndarray  # denoiser kernel state of the speed loop's measurement (or a dummy)
    f_lat: np.ndarray  # denoiser kernel state of the lateral loop's measurement (or a dummy)
    f_yaw: np.ndarray  # denoiser kernel state of the yaw damper's input (or a dummy)

    def reset(self) -> None:
        """Fresh controller states."""
        if self.coef.shape[0] > 13:
            self.coef[13] = 0.0  # the path correction's integrator
        if self.kind == KIND.MFC_NATURAL and self.coef.shape[0] > _CMD_LAST:
            # no damper term, speed, curvature or command yet
            self.coef[_DAMP_DR: _CMD_LAST + 1] = math.nan
        if self.kind in (KIND.FLATNESS, KIND.MFC_FLAT):
            self.coef[_OUTER_SHIFT] = 0.0  # no correction held
            self.coef[_OUTER_HELD] = 0.0
        if self.coef.shape[0] > _IMU_STARTED:
            self.coef[_IMU_STARTED] = 0.0  # the imu estimator restarts from the next sample
        if self.coef.shape[0] > _IMU_B:
            self.coef[_IMU_B] = 0.0  # and forgets the bias of the previous run
        if self.coef.shape[0] > _CURV_FF:
            self.coef[_CURV_FF] = 0.0  # no curvature term in the steer held at the start
        for on, ks in ((self.coef[0], self.f_lon), (self.coef[1], self.f_lat),
                       (self.coef[6], self.f_yaw)):
            if on:
                fir_reset(ks)
        if self.kind == KIND.FLATNESS:
            self.s_lon[:] = flat_make_state(self.p_lon)
            return
        self.s_lon[:] = make_state(self.p_lon)
        self.s_lat[:] = make_state(self.p_lat)


def build_flatness(settings: FlatnessSettings, *, dt: float,
                   model: Bicycle3DoFParams) -> VehicleControllerArrays:
    """Arrays of the flatness-based controller at control period ``dt`` [s].

    ``model`` is the *nominal* design model (normally ``Bicycle3DoFParams.from_vehicle``); the
    settings' ``cf_scale``, ``cr_scale`` are applied by :class:`FlatnessControlParams`. The
    parameter and state arrays go in the ``p_lon``/``s_lon`` slots (``p_lat``, ``s_lat`` unused).
    """
    dt = positive("dt", dt, "s")
    fp = flatness_params(settings, dt=dt, model=model)
    p = fp.to_array()
    return VehicleControllerArrays(int(KIND.FLATNESS), p, flat_make_state(p), np.zeros(1),
                                   np.zeros(1), np.array([0.0, 0.0, dt, 0.0, 0.0, 0.0, 0.0,
                                                          *_outer_coef(settings, dt),
                                                          0.0, 0.0, 0.0]),
                                   np.zeros(1), np.zeros(1), np.zeros(1))


def _outer_coef(settings, dt: float) -> list[float]:
    """``[on, wn, zeta, feedforward on, integral on, dt, integrator]`` (coef[7:14])."""
    if not getattr(settings, "path_correction", False):
        return [0.0] * 7
    return [1.0, float(settings.outer_wn), float(settings.outer_zeta),
            float(settings.sideslip_feedforward), float(settings.outer_integral), dt, 0.0]


def flatness_params(settings: FlatnessSettings, *, dt: float,
                    model: Bicycle3DoFParams) -> FlatnessControlParams:
    """The :class:`FlatnessControlParams` of ``settings`` (design model scaled as set)."""
    return FlatnessControlParams(
        model=model, gains=gains_from_poles(settings.speed_poles, settings.lateral_poles),
        dt=dt, cf_scale=settings.cf_scale, cr_scale=settings.cr_scale,
        derivative=settings.derivative, wheel_accel=settings.wheel_accel)


def build_mfc(controller: str, settings, *, dt: float, actuators: ActuatorParams,
              mass: float = math.nan, iz: float = math.nan, lf: float = math.nan,
              torque0: float = 0.0, steer0: float = 0.0) -> VehicleControllerArrays:
    """Arrays of a model-free vehicle controller at control period ``dt`` [s].

    ``torque0`` [N m] and ``steer0`` [rad] are the inputs the controllers hold until their
    estimator windows are full (the actuators' positions when the controller is switched on).

    The intelligent controllers' limits mirror the actuators' (so that the F estimators see the
    input actually applied): steer range and rate, torque between -max_brake_torque and
    max_drive_torque (the speed-dependent power cap is the actuator's own; the estimator then
    sees the difference as part of F).
    """
    dt = positive("dt", dt, "s")
    # with feed_applied the actuator alone rate-limits the steer and the estimator is told what
    # it applied; a second rate limit inside the iPD would integrate the yaw damper's term
    feed = bool(getattr(settings, "feed_applied", False))
    steer_lim = dict(u_min=-actuators.max_steer, u_max=actuators.max_steer,
                     rate_max=math.inf if feed else actuators.max_steer_rate, u0=steer0)
    torque_lim = dict(u_min=-actuators.max_brake_torque, u_max=actuators.max_drive_torque,
                      u0=torque0)
    if controller == "mfc-natural":
        s: MfcNaturalSettings = settings
        lon = IntelligentParams(nu=1, alpha=s.alpha_lon, dt=dt, window=s.window_lon,
                                kp=s.kp_lon, **torque_lim)
        lat = IntelligentParams(nu=2, alpha=s.alpha_lat, dt=dt, window=s.window_lat,
                                kp=s.wn_lat**2, kd=2.0 * s.zeta_lat * s.wn_lat,
                                derivative=s.derivative_lat,
                                derivative_window=s.window_lat,
                                correction_max=s.correction_max, **steer_lim)
        kind = KIND.MFC_NATURAL
        # the imu estimator's observer, discrete (predict with e_y'', correct with e_y): the
        # gains of the poles -observer_wn (double) and -observer_bias_wn (the bias state), to
        # first order in w dt: (s + wo)^2 (s + wb) = s^3 + l1 s^2 + l2 s + l3
        w_o = s.observer_wn
        w_b = s.observer_bias_wn
        coef = np.array([float(s.denoise_lon > 0), float(s.denoise_lat > 0), 0.0, 0.0,
                         s.yaw_damping, float(s.feed_applied), float(s.denoise_yaw > 0),
                         *([0.0] * 7), s.zeta_lat, s.wn_lat, s.wn_lat_speed,
                         s.wn_lat_ratio, float(s.estimator_lat == "imu"),
                         math.exp(-dt / s.imu_filter_s), (2.0 * w_o + w_b) * dt,
                         (w_o * w_o + 2.0 * w_o * w_b) * dt,
                         0.0, 0.0, 0.0, 0.0, 0.0, w_o * w_o * w_b * dt, 0.0,
                         s.steer_min_speed, float(s.curvature_term), 0.0, math.nan,
                         math.nan, math.nan, math.nan])
    elif controller == "mfc-flat":
        s2: MfcFlatSettings = settings
        positive("mass", mass, "kg")
        positive("iz", iz, "kg m^2")
        positive("lf", lf, "m")
        lon = IntelligentParams(nu=1, alpha=s2.alpha_lon, dt=dt, window=s2.window_lon,
                                kp=s2.kp_lon, ki=s2.ki_lon, **torque_lim)
        lat = IntelligentParams(nu=1, alpha=s2.alpha_lat, dt=dt, window=s2.window_lat,
                                kp=s2.kp_lat, ki=s2.ki_lat, **steer_lim)
        kind = KIND.MFC_FLAT
        coef = np.array([float(s2.denoise_lon > 0), float(s2.denoise_lat > 0), lf * mass, iz,
                         0.0, 0.0, 0.0, *_outer_coef(s2, dt), 0.0, 0.0, s2.steer_min_speed])
    else:
        raise ValueError(f"controller = {controller!r}: expected 'mfc-flat' or 'mfc-natural'")
    p_lon = lon.to_array()
    p_lat = lat.to_array()
    return VehicleControllerArrays(int(kind), p_lon, make_state(p_lon), p_lat,
                                   make_state(p_lat), coef, _denoiser(settings.denoise_lon),
                                   _denoiser(settings.denoise_lat),
                                   _denoiser(getattr(settings, "denoise_yaw", 0)))


# coef slots of the imu estimator (mfc-natural; MfcNaturalSettings.estimator_lat)
_IMU_ON, _IMU_PHI, _IMU_L1, _IMU_L2 = 18, 19, 20, 21
_IMU_A, _IMU_U, _IMU_E, _IMU_ED, _IMU_STARTED = 22, 23, 24, 25, 26
_IMU_L3, _IMU_B = 27, 28  # bias gain, bias estimate (kept across restarts: the bias persists)
_STEER_MIN_V = 29  # MfcNaturalSettings.steer_min_speed [m/s]
# the flat-output designs (flatness, mfc-flat), after the outer correction's coef[7:14]: the
# correction's last y2 shift [kg m^2/s] and whether the last step held it (a non-finite
# input), then MfcFlatSettings.steer_min_speed [m/s] (mfc-flat)
_OUTER_SHIFT, _OUTER_HELD, _FLAT_STEER_MIN_V = 14, 15, 16
# MfcNaturalSettings.curvature_term: on; the term Vx^2 kappa / alpha [rad] of the period running
_CURV_ON, _CURV_FF = 30, 31
# mfc-natural: the yaw damper's input r - Vx kappa at its last term [rad/s]; the last finite
# measured speed [m/s] and path curvature [1/m]; the last steer command [rad] (NaN: none yet)
_DAMP_DR, _VX_LAST, _KAP_LAST, _CMD_LAST = 32, 33, 34, 35
_ALPHA, _DT_I, _L_I = int(IPAR.ALPHA), int(IPAR.DT), int(IPAR.L)
_UMIN_I, _UMAX_I = int(IPAR.U_MIN), int(IPAR.U_MAX)
_F_HAT_I = int(IST.F_HAT)
_K_I, _U_I, _YD_I = int(IST.K), int(IST.U), int(IST.YDOT)
_GAP_I, _YL_I, _NU_I = int(IST.GAP), int(IST.Y_LAST), int(IPAR.NU)


# The step kernels allocate nothing and only index the arrays they are given: compiled without
# numba's reference counting (flatfree._vecmath.no_refcount). Left to numba, the option came
# from the first caller that compiled them (and was then cached): compiled first from a loop
# with reference counting (a user's own @njit loop, profile_closed_loop.py's replay), every call
# there paid for it (measured: 206-243 instead of 130-139 ns a call); the engine's closed loop
# was not affected (measured, a process that stepped NaturalOutputController first).
_JIT_STEP = no_refcount({"cache": True})


@njit(cache=True)
def _imu_on(kind, coef) -> bool:
    """The natural-output controller with ``estimator_lat = "imu"``."""
    return kind == 2 and coef.shape[0] > _IMU_STARTED and coef[_IMU_ON] != 0.0


@njit(cache=True)
def wants_ey_ddot(kind, coef) -> bool:
    """Whether a controller reads the measured e_y'' (``MEAS.EY_DDOT``): a Python controller
    (it gets every column) or the natural-output one with ``estimator_lat = "imu"``. The loop
    forms the column only then (it costs a cosine, a sine and a division per control step)."""
    return kind == 3 or _imu_on(kind, coef)  # 3: KIND.PYTHON


def unread_channels(ctrl: VehicleControllerArrays) -> tuple[str, ...]:
    """The sensor channels (flatfree.sensors.SENSOR_CHANNELS) the closed loop's controller
    ``ctrl`` never reads, by what :func:`vehicle_step` reads of :class:`MEAS`: the loop draws
    no noise for them (:meth:`flatfree.sensors.SensorSuite.compile`, ``unread``; 3 of the
    8 channels for the natural-output controller). Every design reads the pose (the path's
    schedule, e_y, e_psi), vx (logged as ``meas_vx``) and r; the flat-output designs vy; only
    a controller that forms e_y'' (the imu estimator; a Python controller gets every column)
    reads vy, ax and ay. The trajectory is the same bit for bit (each channel draws from its
    own streams; tests/test_simulation.py)."""
    if wants_ey_ddot(ctrl.kind, ctrl.coef):
        return ()
    if ctrl.kind == KIND.MFC_NATURAL:
        return ("vy", "ax", "ay")
    return ("ax", "ay")



@njit(**_JIT_STEP)
def _imu_lateral(p, s, coef, y_alg, y, a, yr, yrd, yrdd, u_prev):
    """The iPD's steer with F, e_y and e_y' from the measured e_y'' (``estimator_lat = "imu"``).

    ``y`` is the measured e_y, ``a`` the measured e_y'', ``u_prev`` the steer applied over
    the last period, ``y_alg`` the sample for the algebraic estimator's window (``y``, denoised
    when the settings say so). The observer's estimates drive the iPD's law
    (:func:`~flatfree.controllers.intelligent.intelligent_step_external`); the algebraic
    estimator only keeps its window current. Where an input is not finite or the window is not
    full yet, the algebraic controller's step is returned and the observer restarts; at the
    sample it restarts on, it starts from the algebraic estimate of e_y'.
    """
    ok = (math.isfinite(a) and math.isfinite(y) and math.isfinite(u_prev)
          and math.isfinite(yr) and math.isfinite(yrd) and math.isfinite(yrdd))
    if not ok or coef[_IMU_STARTED] == 0.0 or s[_K_I] < p[_L_I]:
        u_alg = intelligent_step(p, s, y_alg, yr, yrd, yrdd)
        if not ok or s[_K_I] < p[_L_I]:
            coef[_IMU_STARTED] = 0.0
            return u_alg
        coef[_IMU_A] = a
        coef[_IMU_U] = u_prev
        coef[_IMU_E] = y
        coef[_IMU_ED] = s[_YD_I]  # the algebraic estimate of e_y' (its window is full)
        coef[_IMU_STARTED] = 1.0
        starting = True
    else:
        starting = False
        phi = coef[_IMU_PHI]
        coef[_IMU_A] = phi * coef[_IMU_A] + (1.0 - phi) * a
        coef[_IMU_U] = phi * coef[_IMU_U] + (1.0 - phi) * u_prev
        dt = p[_DT_I]
        # a is the mean e_y'' over the last period (less the bias estimate): predict, then
        # correct with e_y
        acc = a - coef[_IMU_B]
        coef[_IMU_E] += dt * coef[_IMU_ED] + 0.5 * dt * dt * acc
        coef[_IMU_ED] += dt * acc
        inn = y - coef[_IMU_E]
        coef[_IMU_E] += coef[_IMU_L1] * inn
        coef[_IMU_ED] += coef[_IMU_L2] * inn
        coef[_IMU_B] -= coef[_IMU_L3] * inn
    # the ultra-local model at the filtered instant, the bias removed
    f_hat = coef[_IMU_A] - coef[_IMU_B] - p[_ALPHA] * coef[_IMU_U]
    if starting:  # the window's step was just taken: replace its output
        return intelligent_override(p, s, y_alg, yr, yrd, yrdd, f_hat, coef[_IMU_E],
                                    coef[_IMU_ED])
    return intelligent_step_external(p, s, y_alg, yr, yrd, yrdd, f_hat, coef[_IMU_E],
                                     coef[_IMU_ED])


@njit(**dict(_JIT_STEP, forceinline=True))
def _denoised(p, s, f, y):
    """``y`` through a loop's denoiser ``f`` (NOTES.md denoiser (2T - 3d)); a non-finite ``y``
    bypasses it (the intelligent controller's own policy applies). At the first finite ``y``
    after a gap of its loop (``IST.GAP``) the denoiser's samples of the gap (the model's, see
    :func:`_bridge_denoiser`) are first moved toward ``y`` as the controller's window's are
    (:func:`~flatfree.controllers.intelligent.gap_weight`, at the raw sample's prediction
    error), so that neither meets a step."""
    if not math.isfinite(y):
        return y
    m = int(s[_GAP_I])
    if m > 0:
        d = y - intelligent_predict(p, s)
        if math.isfinite(d):
            nu = int(p[_NU_I])
            for j in range(m):
                if not fir_add(f, j, d * gap_weight(m - j, m, nu)):
                    break
    return fir_update(f, y)


@njit(**dict(_JIT_STEP, forceinline=True))
def _bridge_denoiser(s, f):
    """After a step that took its sample from the model (a non-finite ``y``: ``IST.GAP`` > 0),
    the denoiser ``f`` takes the same sample, so that its window keeps its time base through
    the gap (it would otherwise join the samples before the gap to the one after it)."""
    if s[_GAP_I] > 0.0:
        fir_update(f, s[_YL_I])


@njit(**_JIT_STEP)
def vehicle_step(kind, p_lon, s_lon, p_lat, s_lat, coef, f_lon, f_lat, f_yaw, meas, cref,
                 tw_applied, delta_applied):
    """One control step of a vehicle controller: returns (torque [N m], steer [rad]).

    ``meas`` has the layout :class:`MEAS`, ``cref`` the layout :class:`CREF`; ``f_lon``,
    ``f_lat`` are the denoisers' kernel states (used when ``coef[0]``, ``coef[1]`` are set; a
    non-finite sample bypasses them so that the intelligent controller's own policy applies);
    ``tw_applied``, ``delta_applied`` are the inputs applied over the previous plant step
    (anti-windup of the flatness controller; NaN: unknown). The model-free loops feed their
    own limited outputs to their estimators (intelligent.py).
    """
    y2r = cref[2]
    if coef.shape[0] > 10 and coef[7] != 0.0:
        # outer path-following correction of the y2 reference (module docstring), on the
        # deviation from the reference line (the path offset by its e_y reference, e.g.
        # reference.lateral_offset_m; it was the path's own, so the flat-output designs drove
        # the path instead of the offset line)
        e_line = meas[6] - cref[5]
        v_out = max(meas[3], _OUTER_V_MIN)
        # ... and its heading: the line turns from the path's tangent by e_y_ref' / v
        e_psi_line = meas[7] - cref[6] / v_out
        zeta = coef[9]
        if coef[11] != 0.0:  # integral action: integrate e_y / v, triple pole (zeta unused)
            zeta = 0.0
            if math.isfinite(e_line) and math.isfinite(meas[3]):
                coef[13] += coef[12] * e_line / v_out
        dr = path_correction(meas[3], meas[4], e_line, e_psi_line, coef[8], zeta, coef[13])
        if coef[10] != 0.0:
            dr += cref[10]
        shift = cref[9] * dr
        if math.isfinite(shift) and math.isfinite(meas[3]):
            coef[_OUTER_SHIFT] = shift
            coef[_OUTER_HELD] = 0.0
        else:
            # a lost pose, speed or reference sample: the last shift held (left out, the
            # y2 reference jumped back to the uncorrected one for that period: a steer spike)
            coef[_OUTER_HELD] = 1.0
        y2r += coef[_OUTER_SHIFT]
    if kind == 0:  # flatness-based (paper Section 2.3), arrays in the lon slots
        return flatness_step(p_lon, s_lon, meas[3], meas[4], meas[5], cref[0], cref[1],
                             y2r, cref[3], cref[4], coef[2], tw_applied, delta_applied)
    # MfcNaturalSettings.curvature_term: the lateral loop's input is delta - ff, ff = Vx^2
    # kappa / alpha; ff_run is the term of the period that just ended
    curv = kind == 2 and coef.shape[0] > _CURV_FF and coef[_CURV_ON] != 0.0
    ff_run = coef[_CURV_FF] if curv else 0.0
    if coef[5] != 0.0:  # the estimators see what the actuators applied (intelligent.py)
        intelligent_set_applied(p_lon, s_lon, tw_applied)
        intelligent_set_applied(p_lat, s_lat, delta_applied - ff_run)
    vx = meas[3]
    if coef[0] != 0.0:
        vx = _denoised(p_lon, s_lon, f_lon, vx)  # NOTES.md denoiser (2T - 3d)
    tw = intelligent_step(p_lon, s_lon, vx, cref[0], cref[1], 0.0)  # iP / iPI on Vx
    if coef[0] != 0.0:
        _bridge_denoiser(s_lon, f_lon)
    if kind == 2:  # natural outputs: iPD on e_y (paper Section 3.4)
        y = meas[6]
        yr, yrd, yrdd = cref[5], cref[6], cref[7]
    else:  # flat outputs: iPI on y2 = lf m Vy - Iz r (paper Section 3.3)
        y = coef[2] * meas[4] - coef[3] * meas[5]
        yr, yrd, yrdd = y2r, cref[3], 0.0
    if coef[1] != 0.0:
        y = _denoised(p_lat, s_lat, f_lat, y)  # NOTES.md denoiser (2T - 3d)
    if kind == 2 and coef.shape[0] > 17 and coef[16] > 0.0 and math.isfinite(meas[3]):
        # speed schedule of the lateral error dynamics (MfcNaturalSettings.wn_lat_speed)
        wn = coef[15] * min(max(coef[16] / max(meas[3], _OUTER_V_MIN), 1.0), coef[17])
        p_lat[IPAR.KP] = wn * wn
        p_lat[IPAR.KD] = 2.0 * coef[14] * wn
    ff = ff_run
    u_min = p_lat[_UMIN_I]
    u_max = p_lat[_UMAX_I]
    vx_lat = meas[3]  # the speed and curvature of the curvature term and the yaw damper
    kap = cref[8]
    nat = kind == 2 and coef.shape[0] > _CMD_LAST
    if nat:
        # a non-finite speed sample: the last finite one, with the path's current curvature
        # (holding the term itself left it behind a corner's entry: 9.5 cm after 0.5 s at
        # 10.8 s on Norisring, benchmarks/README.md "A gap in the speed"); a non-finite
        # curvature (an own loop's projection of a lost pose): the last finite one
        if math.isfinite(vx_lat):
            coef[_VX_LAST] = vx_lat
        else:
            vx_lat = coef[_VX_LAST]
        if math.isfinite(kap):
            coef[_KAP_LAST] = kap
        else:
            kap = coef[_KAP_LAST]
    if curv:
        ff_now = vx_lat * vx_lat * kap / p_lat[_ALPHA]
        if math.isfinite(ff_now):
            ff = ff_now  # else the last finite term
        # the iPD's steer range, in its own input delta - ff (put back as it was, below)
        p_lat[_UMIN_I] = u_min - ff
        p_lat[_UMAX_I] = u_max - ff
    # the lateral loop's input over the last period (feed_applied) or as commanded
    u_prev = s_lat[_U_I]
    if _imu_on(kind, coef):
        delta = _imu_lateral(p_lat, s_lat, coef, y, meas[6], meas[10], yr, yrd, yrdd, u_prev)
    else:
        delta = intelligent_step(p_lat, s_lat, y, yr, yrd, yrdd)
    if coef[1] != 0.0:
        _bridge_denoiser(s_lat, f_lat)
    if curv:
        p_lat[_UMIN_I] = u_min
        p_lat[_UMAX_I] = u_max
        # while the window fills the start's steer is held (the input held is the steer less
        # the last period's term); a step that holds on a non-finite input keeps the term
        # current: the path's curvature goes on while the position is lost
        delta += ff_run if s_lat[_K_I] < p_lat[_L_I] else ff
        if delta < u_min:  # (x - ff) + ff may round past the range; a hold may move past it
            delta = u_min
        elif delta > u_max:
            delta = u_max
        # the term of the period that starts; none before a first finite e_y (the estimator
        # has stored no input yet, its held output is the start's steer itself)
        coef[_CURV_FF] = ff if s_lat[_K_I] > 0.0 else 0.0
        u_prev += ff_run  # the steer applied over the last period
    d_damp = 0.0  # the damper's change on a held step
    if coef[4] != 0.0:
        # parameter-free yaw damper (MfcNaturalSettings.yaw_damping): r - Vx kappa(s)
        dr = meas[5] - vx_lat * kap
        have = math.isfinite(dr)
        if have and coef[6] != 0.0:
            dr = fir_update(f_yaw, dr)  # NOTES.md denoiser (2T - 3d)
        elif not have and nat and math.isfinite(coef[_DAMP_DR]):
            # a non-finite yaw rate: the damper's last input kept (its term fell out of the
            # steer at once, ~2 deg, and came back after the gap); its denoiser takes it too
            dr = coef[_DAMP_DR]
            have = True
            if coef[6] != 0.0:
                fir_update(f_yaw, dr)
        if have:
            # on the iPD's law only, when it is fed the applied steer: a step that holds
            # (window not full, a non-finite input) then returns the steer applied last, the
            # last damper term in it; adding the term again at every held step integrated it
            # (a 0.1 s gap in the position left the track)
            if coef[5] == 0.0 or intelligent_law_ran(p_lat, s_lat):
                # within the steer range (the iPD's limits, the actuators'), as the iPD's own
                delta -= coef[4] * dr
                if delta < p_lat[_UMIN_I]:
                    delta = p_lat[_UMIN_I]
                elif delta > p_lat[_UMAX_I]:
                    delta = p_lat[_UMAX_I]
                if nat:
                    coef[_DAMP_DR] = dr
            elif nat and math.isfinite(coef[_DAMP_DR]):
                # a step held on a non-finite input (a gap in the position): the damper stays
                # live on the change of its input since its last term, which the held steer
                # holds; the yaw rate is still measured, and without it the car drifted off
                # the line on a corner's entry (benchmarks/README.md "The yaw damper through
                # a gap in the position")
                # (the held step's steer is formed below, from the last command)
                d_damp = -coef[4] * (dr - coef[_DAMP_DR])
                coef[_DAMP_DR] = dr
    if (nat and coef[5] != 0.0 and s_lat[_K_I] >= p_lat[_L_I]
            and not intelligent_law_ran(p_lat, s_lat) and math.isfinite(coef[_CMD_LAST])):
        # a step held on a non-finite input (a gap in the position): the steer held is the
        # last command, not the steer applied last, with the changes of the curvature term
        # and of the damper's term since (above): where the actuators lag the command (dead
        # time, a lag, the rate limit) the applied steer dropped most of those changes
        delta = min(max(coef[_CMD_LAST] + d_damp + (ff - ff_run if curv else 0.0),
                        p_lat[_UMIN_I]), p_lat[_UMAX_I])
    if kind == 2 and coef.shape[0] > _STEER_MIN_V and vx_lat < coef[_STEER_MIN_V]:
        # too slow for the steer to move e_y (MfcNaturalSettings.steer_min_speed): hold the
        # steer applied last; the estimators are told so (their window keeps its time base);
        # a non-finite speed sample: the last finite one decides
        delta = u_prev
        intelligent_set_applied(p_lat, s_lat, delta - ff)
    elif kind == 1 and meas[3] < coef[_FLAT_STEER_MIN_V]:
        # MfcFlatSettings.steer_min_speed: at a standstill the steer does not move y2 (and the
        # correction's d y2 / d r changes sign below the singular speed): hold it
        delta = u_prev
        intelligent_set_applied(p_lat, s_lat, delta)
    if nat:
        coef[_CMD_LAST] = min(max(delta, p_lat[_UMIN_I]), p_lat[_UMAX_I])
    return tw, delta


@njit(**_JIT_STEP)
def lateral_f_hat(kind, p_lat, s_lat, coef) -> float:
    """The lateral loop's last F estimate, of ``e_y'' = F + alpha delta`` for the natural-output
    design whatever ``curvature_term`` (with it, its estimator's F less the term ``alpha ff``,
    ``Vx^2 kappa``, that the law took out of it), of ``y2' = F + alpha delta`` for the flat
    outputs; NaN for the flatness controller."""
    if kind != 1 and kind != 2:
        return math.nan
    f = s_lat[_F_HAT_I]
    if (kind == 2 and coef.shape[0] > _CURV_FF and coef[_CURV_ON] != 0.0
            and s_lat[_K_I] >= p_lat[_L_I]):  # (0 until the window is full, as without it)
        f -= p_lat[_ALPHA] * coef[_CURV_FF]
    return f


def f_hat_index() -> int:
    """Index of the last F estimate in an intelligent controller's state array (with
    ``curvature_term``, the natural-output loop's F without the path's term: the whole F of
    ``e_y'' = F + alpha delta`` is :func:`lateral_f_hat`)."""
    return int(IST.F_HAT)


class _OwnLoopShell:
    """What the own-loop shells of the vehicle designs share (:class:`NaturalOutputController`,
    :class:`flatfree.controllers.flat_output.FlatOutputController`): the actuators' model
    that stands for an unknown applied input, the reset at the actuators' positions, the
    steer clipped to the range and the reset on an overflowed command. A subclass sets
    ``_SETTINGS`` (the settings classes it takes) and builds its kernel's arrays in
    :meth:`_build`."""

    __slots__ = ("_arrays", "_act", "_act_p", "_act_s", "_dt", "_settings", "_meas", "_ref",
                 "_prev", "_vx_prev")

    __copy__ = independent_copy

    _SETTINGS: ClassVar[tuple[type, ...]]  # the settings classes taken; the first the default

    def __init__(self, *, dt: float, actuators: ActuatorParams, settings) -> None:
        if not isinstance(actuators, ActuatorParams):
            # {!r:.60}: a VehicleParams' repr runs to hundreds of characters
            raise ValueError(f"actuators = {actuators!r:.60}: expected flatfree.actuators."
                             "ActuatorParams (e.g. ActuatorParams.from_vehicle(vehicle))")
        if settings is None:
            settings = self._SETTINGS[0]()
        if not isinstance(settings, self._SETTINGS):
            raise ValueError(f"settings = {settings!r}: expected "
                             f"{' or '.join(c.__name__ for c in self._SETTINGS)}")
        self._dt = positive("dt", dt, "s")
        self._act = actuators
        self._settings = settings
        self._meas = np.full(len(MEAS), np.nan)
        self._ref = np.zeros(len(CREF))
        self._act_p = actuators.to_array(self._dt)
        self._prev = np.zeros(2)  # previous commands (torque, steer)
        if isinstance(settings, _SampleCountSettings):  # once, not at every reset
            warn_if_untuned_period(_CONTROLLER_OF[type(settings)], settings, self._dt)
        self.reset()

    @property
    def settings(self):
        """The controller's settings."""
        return self._settings

    def _build(self, steer0: float, torque0: float) -> VehicleControllerArrays:
        raise NotImplementedError

    def reset(self, *, steer0: float = 0.0, torque0: float = 0.0) -> None:
        """Fresh estimators; ``steer0`` [rad] and ``torque0`` [N m] are the actuators' positions,
        held until the estimator windows are full (``window_lon`` / ``window_lat`` samples).
        Each within the actuators' range (``ValueError`` otherwise: ``|steer0| <= max_steer``,
        ``-max_brake_torque <= torque0 <= max_drive_torque``)."""
        a = self._act
        steer0 = in_range("steer0", steer0, -a.max_steer, a.max_steer, "rad")
        torque0 = in_range("torque0", torque0, -a.max_brake_torque, a.max_drive_torque, "N m")
        self._arrays = self._build(steer0, torque0)
        self._act_s = actuator_state(self._act, self._dt, steer0=steer0, torque0=torque0)
        self._prev[:] = (torque0, steer0)
        self._vx_prev = math.nan

    def _applied(self, vx: float, applied_torque, applied_steer) -> tuple[float, float]:
        """The inputs applied over the last period: the caller's where given and finite, else
        the previous commands through the actuators' model (at the speed measured then)."""
        applied_torque = _optional_real("applied_torque", applied_torque, "N m")
        applied_steer = _optional_real("applied_steer", applied_steer, "rad")
        prev = self._prev
        vx_then = vx if math.isnan(self._vx_prev) else self._vx_prev
        model_tw, model_delta = actuate_step(prev[0], prev[1], vx_then, self._act_p,
                                             self._act_s)
        # a non-finite applied value (a lost feedback frame) counts as unknown: the model's
        a_tw = (model_tw if applied_torque is None or not math.isfinite(applied_torque)
                else applied_torque)
        a_delta = (model_delta if applied_steer is None or not math.isfinite(applied_steer)
                   else applied_steer)
        return a_tw, a_delta

    def _step_kernel(self, vx: float, a_tw: float, a_delta: float, inputs) -> tuple[float, float]:
        """:func:`vehicle_step` on the measurement and reference arrays filled by the caller;
        a non-finite command resets and raises (``inputs()`` gives the step's arguments for
        the message); the steer and the torque clipped to the actuators' ranges."""
        z = self._arrays
        tw, delta = vehicle_step(z.kind, z.p_lon, z.s_lon, z.p_lat, z.s_lat, z.coef, z.f_lon,
                                 z.f_lat, z.f_yaw, self._meas, self._ref, a_tw, a_delta)
        # a held step (a standstill, a NaN input) returns the steer applied last, which the
        # caller may report beyond the range (applied_steer); in the engine, and for the
        # model-free laws' own outputs, it is within the range already. The flatness law knows
        # no limits (its anti-windup sees what was applied): its torque reached -47.7 kN m
        # against a 6 kN m brake
        if not (math.isfinite(tw) and math.isfinite(delta)):  # overflowed (Raises)
            self._overflowed(tw, delta, inputs())
        a = self._act
        lim = a.max_steer
        if delta > lim:
            delta = lim
        elif delta < -lim:
            delta = -lim
        if tw > a.max_drive_torque:
            tw = a.max_drive_torque
        elif tw < -a.max_brake_torque:
            tw = -a.max_brake_torque
        prev = self._prev
        prev[0] = tw
        prev[1] = delta
        self._vx_prev = vx
        return tw, delta

    def _overflowed(self, tw: float, delta: float, inputs: dict) -> None:
        """Reset at the last finite commands and raise (``step``, Raises)."""
        a = self._act  # (within the ranges reset checks: the commands are, to round-off)
        torque0 = min(max(float(self._prev[0]), -a.max_brake_torque), a.max_drive_torque)
        steer0 = min(max(float(self._prev[1]), -a.max_steer), a.max_steer)
        self.reset(steer0=steer0, torque0=torque0)
        raise nonfinite_command(
            type(self).__name__, {"torque": tw, "steer": delta}, inputs,
            f"the controller was reset (reset(steer0={steer0!r}, torque0={torque0!r}), the "
            "last finite commands: its windows held the overflowed values)")


def _optional_real(name: str, value, unit: str) -> float | None:
    """``None`` or one real number (``ValueError`` naming ``name`` otherwise)."""
    if value is None or isinstance(value, float):
        return value
    return real(name, value, unit)


@dataclass(frozen=True, slots=True)
class NaturalOutputStatus:
    """Snapshot of a :class:`NaturalOutputController` after its last step.

    Attributes
    ----------
    speed : IntelligentStatus
        The iP on the speed (y = vx [m/s], u = wheel torque [N m]).
    lateral : IntelligentStatus
        The iPD on the lateral deviation (y = e_y [m], u = steer [rad]). With
        ``curvature_term`` its input is the steer less the path's term ``vx^2 kappa / alpha``
        and its ``f_hat`` the F without the term; ``f_lat`` below is the whole F.
    f_lat : float
        The F of ``e_y'' = F + alpha delta`` [m/s^2] (0 until the window is full).
    steer_held : bool
        The last steer is not the law's: the window still filling (the start's steer held), a
        non-finite ``e_y`` or lateral reference (the last command held, moved by the
        changes of the curvature term and of the yaw damper's term since), or a speed below
        ``steer_min_speed`` (the standstill hold; a NaN speed: the last finite one).
    """

    speed: IntelligentStatus
    lateral: IntelligentStatus
    f_lat: float
    steer_held: bool


class NaturalOutputController(_OwnLoopShell):
    """The paper's model-free controller on natural outputs for a user's own loop.

    ``reset()`` / ``step()`` over the same compiled kernel as the closed-loop engine
    (:func:`vehicle_step` with :class:`MfcNaturalSettings`): an iP on the speed (wheel torque)
    and an iPD on the lateral deviation (steer), plus the settings' yaw damper and speed
    schedule. Call :meth:`step` once per control period ``dt``; hold its outputs until the next
    call (zero-order hold: the estimators assume it). One controller per loop: its state is
    updated in place (not safe to step from two threads at once); ``copy.copy`` gives an
    independent controller in the same state.

    Parameters
    ----------
    dt : float
        Control period [s]. The settings' windows and denoisers count samples, tuned at 1 ms:
        at another period pass ``settings.for_period(dt)``, which keeps their durations (the
        controller warns when their durations are far from the tuned ones: at 100 Hz the
        default windows would span 1 s and the car leaves the track). Measured on the 10DoF
        with noise, rescaled (``benchmarks/control_period.py``, benchmarks/README.md "Control
        period"; seeds 0-2, session 16): with :data:`flatfree.scenarios.IMU_SETTINGS`
        100 Hz holds Norisring to 0.77 cm and Spa to 1.21 cm; the algebraic estimator holds
        Norisring (1.69 / 2.63 cm at 500 / 200 Hz) and leaves the track at 100 Hz.
    actuators : ActuatorParams
        Steer and torque limits (``ActuatorParams.from_vehicle(load_vehicle(...))`` or your
        own). The controller clips to them and, unless told what was applied, assumes that
        these actuators (:func:`flatfree.actuators.actuate_step`: dead time, lag, rate limit,
        range, power cap) applied its previous command.
    settings : MfcNaturalSettings, optional
        Default: ``MfcNaturalSettings()``, the base tuning at 1 kHz (the peugeot406's
        ``paper`` runs ``MfcNaturalSettings(**natural_settings("peugeot406"))``, with the
        curvature term and more accurate with the algebraic estimator:
        :data:`flatfree.scenarios.NATURAL_SETTINGS`); use
        ``alpha_lat`` of the order of your car's steer gain
        (``natural_settings("dallara_av21")``), and :meth:`MfcNaturalSettings.for_period` at
        another control period.

    Examples
    --------
    >>> from flatfree.actuators import ActuatorParams
    >>> from flatfree.vehicles import load_vehicle
    >>> ctrl = NaturalOutputController(
    ...     dt=0.001, actuators=ActuatorParams.from_vehicle(load_vehicle("peugeot406")))
    >>> ctrl.reset()
    >>> torque, steer = ctrl.step(vx=20.0, r=0.0, e_y=0.01, kappa=0.0, vx_ref=20.0)

    At 100 Hz (a typical ROS 2 loop), the inertial-unit variant with its windows rescaled:

    >>> from flatfree.scenarios import natural_settings
    >>> imu = MfcNaturalSettings(**natural_settings("peugeot406", imu=True))
    >>> slow = NaturalOutputController(
    ...     dt=0.01, actuators=ActuatorParams.from_vehicle(load_vehicle("peugeot406")),
    ...     settings=imu.for_period(0.01))
    """

    __slots__ = ()

    _SETTINGS = (MfcNaturalSettings,)

    def __init__(self, *, dt: float, actuators: ActuatorParams,
                 settings: MfcNaturalSettings | None = None) -> None:
        super().__init__(dt=dt, actuators=actuators, settings=settings)

    @property
    def settings(self) -> MfcNaturalSettings:
        """The controller's settings."""
        return self._settings

    def reset(self, *, steer0: float = 0.0, torque0: float = 0.0) -> None:
        """Fresh estimators; ``steer0`` [rad] and ``torque0`` [N m] are the actuators' positions,
        held until the estimator windows are full (``window_lon`` / ``window_lat`` samples,
        100 each by default). Each within the actuators' range (``ValueError`` otherwise:
        ``|steer0| <= max_steer``, ``-max_brake_torque <= torque0 <= max_drive_torque``)."""
        super().reset(steer0=steer0, torque0=torque0)

    def _build(self, steer0: float, torque0: float) -> VehicleControllerArrays:
        return build_mfc("mfc-natural", self._settings, dt=self._dt, actuators=self._act,
                         steer0=steer0, torque0=torque0)

    def step(self, *, vx: float, r: float, e_y: float, kappa: float, vx_ref: float,
             ax_ref: float = 0.0, e_y_ref: float = 0.0, e_y_ref_dot: float = 0.0,
             e_y_ref_ddot: float = 0.0, applied_torque: float | None = None,
             applied_steer: float | None = None,
             e_y_ddot: float = math.nan) -> tuple[float, float]:
        """One control step: returns (wheel torque [N m], road-wheel steer [rad]).

        A bumpless start: until its estimator's window is full (the first ``window_lon - 1``
        and ``window_lat - 1`` steps, 0.1 s at the default settings) each loop gives its
        start value, the :meth:`reset`'s ``torque0`` and ``steer0``. A step whose ``e_y`` (or
        lateral reference) is not finite holds the last steer command, the yaw damper's term
        in it (the damper acts with the iPD's law; once the window is full, a held step
        follows the change of the damper's term since its last one, the yaw rate being still
        measured; with ``feed_applied = False`` the iPD holds its own output and the damper is
        added at every step, the warm-up's included; with ``curvature_term`` the held steer
        follows the change of the term ``vx^2 kappa / alpha`` since; a NaN ``kappa`` is the
        last finite one); the steer returned is within ``actuators.max_steer``. The iPD's
        window and denoiser bridge the gap with the ultra-local model's predictions
        (:mod:`flatfree.controllers.intelligent`).

        Conventions (ISO 8855, as the whole library): body axes at the CoG, x forward, y
        left, z up; the yaw rate, the steer and the curvature are positive to the left
        (counter-clockwise seen from above). The torque is the sum at the wheels, > 0
        driving, < 0 braking. Below :attr:`MfcNaturalSettings.steer_min_speed` (1 m/s) the
        steer applied last is held: at a standstill the steer does not move ``e_y`` and the
        iPD would wind the wheels to their lock (with the hold off, ``reset`` at the
        actuators' positions when the car pulls away; a NaN ``vx`` does not hold: the
        lateral law does not need the speed, and the curvature term and the yaw damper take
        the last finite one). A car
        started off its reference comes back at a bounded speed
        (:attr:`MfcNaturalSettings.correction_max`: from 3 m on the bundled presets at
        5-60 m/s, measured; unbounded, ``correction_max = inf``, the default gains leave the
        path from 0.1 m). For a smooth
        engagement start the reference at the car and merge it into the path (``e_y_ref``
        and its derivatives, over ~3 s; ``benchmarks/initial_offset.py``).

        Parameters
        ----------
        vx : float
            Measured longitudinal speed of the CoG in body axes [m/s].
        r : float
            Measured yaw rate [rad/s], left positive (the yaw damper).
        e_y : float
            Measured lateral deviation of the CoG from the path [m], left positive
            (``Track.projector()`` of :mod:`flatfree.tracks` gives it from a pose).
        kappa : float
            Path curvature at the car's position [1/m], > 0 in a left turn (the yaw damper's
            r - vx kappa, and the term vx^2 kappa of ``curvature_term``).
        vx_ref, ax_ref : float
            Speed reference [m/s] and its time derivative [m/s^2], read at the car's arc
            length. Give ``ax_ref``: it is the iP's feedforward; without it the speed lags the
            profile by ``ax_ref / kp_lon`` (3 m/s at a 6 m/s^2 braking) and the car enters
            corners too fast (examples/own_loop.py).
        e_y_ref, e_y_ref_dot, e_y_ref_ddot : float
            Lateral-deviation reference and its derivatives (0: follow the path).
        applied_torque, applied_steer : float, optional
            What the actuators applied over the last period, if known (the estimators must see
            the applied input); ``None`` (default) or a non-finite value (a lost feedback
            frame): the previous command through the model of ``actuators`` over one period
            (at the speed measured then). A NaN measurement is handled as in the engine (the
            last output is held, the window keeps its time base).
        e_y_ddot : float, optional
            Measured second derivative of the lateral deviation [m/s^2], from an inertial
            unit (:func:`flatfree.tracks.lateral_deviation_acceleration`); used with
            ``estimator_lat = "imu"`` (NaN, the default: the algebraic estimate).

        Raises
        ------
        ValueError
            An argument that is not one real number (text, ``None``, an array), naming it.
            And, instead of returning NaN, a step whose torque or steer comes out non-finite
            (the arithmetic overflowed: finite values of the order of 1e300 among the inputs
            or still in the estimators' windows). The controller is then reset
            (:meth:`reset`) at its last finite commands: its windows hold the overflowed
            values, which would make every later output NaN. Non-finite measurements are not
            an error (held, above): the outputs stay finite.
        """
        # the common path (floats) costs one type test per argument (_shell docstring)
        vx = vx if isinstance(vx, float) else real("vx", vx, "m/s")
        r = r if isinstance(r, float) else real("r", r, "rad/s")
        e_y = e_y if isinstance(e_y, float) else real("e_y", e_y, "m")
        kappa = kappa if isinstance(kappa, float) else real("kappa", kappa, "1/m")
        vx_ref = vx_ref if isinstance(vx_ref, float) else real("vx_ref", vx_ref, "m/s")
        ax_ref = ax_ref if isinstance(ax_ref, float) else real("ax_ref", ax_ref, "m/s^2")
        if not isinstance(e_y_ref, float):
            e_y_ref = real("e_y_ref", e_y_ref, "m")
        if not isinstance(e_y_ref_dot, float):
            e_y_ref_dot = real("e_y_ref_dot", e_y_ref_dot, "m/s")
        if not isinstance(e_y_ref_ddot, float):
            e_y_ref_ddot = real("e_y_ref_ddot", e_y_ref_ddot, "m/s^2")
        if not isinstance(e_y_ddot, float):
            e_y_ddot = real("e_y_ddot", e_y_ddot, "m/s^2")
        a_tw, a_delta = self._applied(vx, applied_torque, applied_steer)
        m = self._meas
        m[_M_VX] = vx
        m[_M_R] = r
        m[_M_EY] = e_y
        m[_M_EYDD] = e_y_ddot
        c = self._ref
        c[_C_VX] = vx_ref
        c[_C_AX] = ax_ref
        c[_C_KAPPA] = kappa
        c[_C_EY] = e_y_ref
        c[_C_EYD] = e_y_ref_dot
        c[_C_EYDD] = e_y_ref_ddot
        return self._step_kernel(vx, a_tw, a_delta, lambda: dict(
            vx=vx, r=r, e_y=e_y, kappa=kappa, vx_ref=vx_ref, ax_ref=ax_ref, e_y_ref=e_y_ref,
            e_y_ref_dot=e_y_ref_dot, e_y_ref_ddot=e_y_ref_ddot,
            applied_torque=applied_torque, applied_steer=applied_steer, e_y_ddot=e_y_ddot))

    @property
    def status(self) -> NaturalOutputStatus:
        """The loops' counters, flags and estimates after the last step
        (:class:`NaturalOutputStatus`)."""
        z = self._arrays
        # the speed the standstill hold went by: the last finite one (False before: NaN)
        vx = self._vx_prev if math.isfinite(self._vx_prev) else float(z.coef[_VX_LAST])
        below = vx < self._settings.steer_min_speed
        return NaturalOutputStatus(
            speed=intelligent_status(z.p_lon, z.s_lon),
            lateral=intelligent_status(z.p_lat, z.s_lat),
            f_lat=float(lateral_f_hat(z.kind, z.p_lat, z.s_lat, z.coef)),
            steer_held=below or not intelligent_law_ran(z.p_lat, z.s_lat))
