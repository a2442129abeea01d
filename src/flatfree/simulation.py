"""The sampled-data closed loop: plant, sensors, controller, actuators, in one compiled function.

:func:`simulate` runs a :class:`~flatfree.scenario.Scenario` and returns a
:class:`~flatfree.trajectory.Trajectory`. When every part is built in (the bundled plants and
controllers), the whole loop runs inside :func:`_closed_loop` (``numba.njit``): per plant step

1. the true pose is projected on the reference path (compiled Frenet projection, local search);
   the run stops with status ``left_track`` when |e_y| exceeds the track half-width there (or
   :data:`DEFAULT_HALF_WIDTH_M` where the width is unknown), with ``non_finite`` when a
   state becomes NaN or infinite, and with ``completed`` when the car reaches the end of the
   reference path (or the duration ends). On a road without friction patches and bank, the
   projection waits for the next logged row while the car cannot have reached the road's
   edge or the path's end since the last one (:func:`_closed_loop`, "Projections"): the same
   trajectory and status, at the same step (the logged path coordinates to round-off);
2. every ``control_every`` plant steps the sensors sample the true signals (noise, bias, rate,
   delay; seeded) and the faults are applied; the lateral deviation, heading error and arc
   length are computed from the *measured* pose; the references are read at the reference
   time of that measured arc length (``schedule = "path"``, the default of every controller's
   settings) or at the clock (``"time"``); the controller (:func:`flatfree.controllers.vehicle.
   vehicle_step`: flatness, mfc-flat or mfc-natural) computes torque and steer, held (ZOH)
   until its next step;
3. the actuators (dead time, lag, rate and range limits, power cap) produce the applied inputs;
   the road friction under each axle comes from the friction patches at the axle's arc length;
4. the plant advances one fixed RK4 step; signals are logged every ``log_every`` plant steps.

Measured channels (sensor names): ``x``, ``y``, ``psi``, ``vx``, ``vy``, ``r``, ``ax``, ``ay``.
``ax``, ``ay`` are the CoG's acceleration in the body axes in the road plane (an inertial
unit's gravity-compensated output), the mean over the last plant step
(``(v_k - v_{k-1}) / dt`` with the rotation term ``-/+ r v`` at mid-step). From the measured
channels the loop forms the lateral deviation, heading error and, from the accelerations,
velocities and the path's curvature at the measured foot point, the deviation's second
derivative (:func:`flatfree.tracks.lateral_deviation_acceleration`).

After the loop, the lateral error and the yaw error are formed against the reference by arc
length (:mod:`flatfree.metrics` states the definitions): ``lateral_error = e_y - e_y_ref(s)``
and ``yaw_error = psi - (psi_ref(s) - beta_ref(s))`` with the reference sideslip
``beta_ref = atan(vy_ref / vx_ref)`` of the 3DoF model whose CoG follows the path
(:func:`flatfree.tracks.reference_states_3dof`, ``method="path"``; ISO 8855: the velocity's
course is ``psi + beta``, so the heading that keeps the CoG velocity tangent to the path is
``psi_ref - beta_ref``; for a recorded reference the gap between the path's course and the
recorded yaw, so that the reference yaw is the recorded one).

The car starts on the reference at ``s = 0`` (position, heading, sideslip angle, path
curvature), at the speed it can have there: on a closed track the power-limited speed of a
flying lap (:func:`flying_lap_speed`), at most the reference's. The speed profiles know the
friction ellipse, not the engine; starting at an unreachable reference speed put the
peugeot406 at 49.1 m/s (it arrives at 44.8 m/s) into a 6 m/s^2 braking through the LVMS
seam's S-bend, where the braking car is yaw-unstable: it spun within 4.4 s (the S-bend, an
artefact of the bound files, is now bridged: tracks.loaders.LVMS_SEAM_M; the profile asks
49.7 m/s there, the car arrives at 44.7).

The reference tables are sampled every :data:`REFERENCE_DT_S` and interpolated linearly.
A user's own Python controller (:class:`PythonController`, ``simulate(sc, controller=obj)``)
runs on the same compiled engine: the loop pauses at every control step, hands the
measurement and reference to the object and resumes with its commands (slower: one Python call
per control step).
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import math
import time
import warnings
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np
from numba import njit

from flatfree._validate import as_real, whole
from flatfree._vecmath import all_finite, no_refcount, stack_array
from flatfree._warn import warn
from flatfree.actuators import ActuatorParams, actuate_step, actuator_state
from flatfree.controllers.flatness import singular_speed
from flatfree.controllers.intelligent import IST
from flatfree.controllers.vehicle import (
    CREF,
    KIND,
    MEAS,
    SCHEDULES,
    VehicleControllerArrays,
    build_flatness,
    build_mfc,
    lateral_f_hat,
    settings_from_mapping,
    unread_channels,
    vehicle_step,
    wants_ey_ddot,
    warn_if_untuned_period,
    y2_per_r,
)
from flatfree.metrics import wrap_angle
from flatfree.models.bicycle3dof import Bicycle3DoFParams, rk4_step_into
from flatfree.models.tendof import (
    LANE_TABLE_SHAPE,
    NU,
    TenDoF,
    TenDoFState,
    drive_speed,
    lane_table,
    rk4_step_table,
)
from flatfree.scenario import Scenario
from flatfree.scenarios import SCENARIO_NAMES, named_scenario, warn_if_untuned
from flatfree.sensors import SENSOR_CHANNELS, sense_step
from flatfree.tracks import (
    GC,
    RS,
    Reference,
    SpeedLimits,
    frenet_init,
    frenet_project,
    lateral_deviation_acceleration_kernel,
    load_track,
    make_reference,
    progress,
    reference_states_3dof,
    sample_reference,
)
from flatfree.tracks.speed import _drive_array, _power_cap
from flatfree.trajectory import Status, Trajectory, _adopting
from flatfree.units import G
from flatfree.vehicles import VehicleParams

__all__ = ["LOG", "SENSOR_CHANNELS", "DEFAULT_HALF_WIDTH_M", "REFERENCE_DT_S", "ROUGH_JERK",
           "Prepared",
           "flying_lap_speed",
           "PythonController", "RunTooLongError", "prepare", "reference_of", "simulate",
           "simulate_prepared"]

#: Half-width of the road used for the left-the-track check where the track gives no width [m].
DEFAULT_HALF_WIDTH_M = 7.5
#: Time step of the reference tables [s]; the loop interpolates them linearly at every plant
#: step. 10 ms: a 10-minute run then holds 60 000 reference rows instead of 600 000 (the
#: 1 ms tables took ~300 MB). Measured against 1 ms tables (Norisring, Spa; checked in
#: tests/test_simulation.py): position 7.5e-5 m, heading 1.3e-5 rad, curvature 4e-6 1/m,
#: vx 0.019 m/s at the corners of the profile (4e-4 of its range; RMS 6e-6 of its range); the
#: piecewise-constant ax is smeared over 10 ms at its jumps (RMS 1 % of its range).
#: Engineering choice.
REFERENCE_DT_S = 0.01
_N_SENS = len(SENSOR_CHANNELS)

_STATUS = {0: Status.COMPLETED, 1: Status.LEFT_TRACK, 2: Status.NON_FINITE}
_PYTHON = int(KIND.PYTHON)
# plain ints for the compiled loop (numba folds module-level ints into constants)
_W_LEFT, _W_RIGHT = int(GC.W_LEFT), int(GC.W_RIGHT)
_KAPPA, _DKAPPA = int(GC.KAPPA), int(GC.DKAPPA)
_ROLL, _PITCH = int(TenDoFState.roll), int(TenDoFState.pitch)
_OMEGA_FL = int(TenDoFState.omega_fl)
_F_HAT = int(IST.F_HAT)


class LOG(enum.IntEnum):
    """Columns of the compiled loop's log (SI)."""

    T = 0
    X = 1
    Y = 2
    PSI = 3
    VX = 4
    VY = 5
    R = 6
    ROLL = 7
    PITCH = 8
    S = 9  # unwrapped arc length along the path [m]
    E_Y = 10  # true lateral deviation from the path [m]
    E_PSI = 11  # true heading error from the path [rad]
    VX_REF = 12
    TORQUE_CMD = 13
    STEER_CMD = 14
    TORQUE = 15  # applied
    STEER = 16  # applied
    MEAS_VX = 17
    MEAS_E_Y = 18
    F_LON = 19  # estimated F of the speed loop
    F_LAT = 20  # estimated F of the lateral loop
    MU_FRONT = 21
    OMEGA_FL = 22  # wheel spin speeds (10DoF plant; NaN on the 3DoF) [rad/s]
    OMEGA_FR = 23
    OMEGA_RL = 24
    OMEGA_RR = 25
    T_REF = 26  # reference time the controller used (path schedule: of the measured arc length)


_UNITS = {
    "x": "m", "y": "m", "psi": "rad", "vx": "m/s", "vy": "m/s", "r": "rad/s", "roll": "rad",
    "pitch": "rad", "s": "m", "e_y": "m", "e_psi": "rad", "vx_ref": "m/s", "torque_cmd": "N m",
    "steer_cmd": "rad", "torque": "N m", "steer": "rad", "meas_vx": "m/s", "meas_e_y": "m",
    "f_lon": "m/s^2", "f_lat": "-", "mu_front": "-",
    "omega_fl": "rad/s", "omega_fr": "rad/s", "omega_rl": "rad/s", "omega_rr": "rad/s",
    "t_ref": "s",
}


# compiled-loop helpers and the loop allocate nothing (the caller passes every buffer), so they
# are compiled without numba's reference counting (flatfree._vecmath.no_refcount): with it, every
# array argument, row view and call of the loop cost lock-prefixed increfs and decrefs.
_JIT_LOOP = no_refcount({"cache": True})


@njit(**_JIT_LOOP)
def _mu_at(s, base, patches, length, closed):
    """Road friction at arc length ``s``: the last patch containing it, else ``base``."""
    if patches.shape[0] == 0:
        return base
    if closed and length > 0.0:
        s = s - length * math.floor(s / length)
    mu = base
    for i in range(patches.shape[0]):
        if patches[i, 0] <= s < patches[i, 1]:
            mu = patches[i, 2]
    return mu


@njit(**_JIT_LOOP)
def _time_at(table, s, i):
    """Column 1 of ``table`` interpolated linearly at ``table[:, 0] = s``; returns (value, row).

    The row is searched from ``i`` (the previous call's row) by walking: O(1) per call along a
    run, where the arc length moves by less than a row per control step. The bracket
    ``table[row, 0] <= s < table[row + 1, 0]`` is unique on a strictly increasing grid, so the
    result is bit for bit :func:`flatfree.controllers.flatness_control.sample_flat_reference`'s
    (binary search, same formula); ends held.
    """
    n = table.shape[0]
    if s <= table[0, 0]:
        return table[0, 1], 0
    if s >= table[n - 1, 0]:
        return table[n - 1, 1], max(n - 2, 0)
    if math.isnan(s):
        return math.nan, i
    i = min(max(i, 0), n - 2)
    while table[i, 0] > s:
        i -= 1
    while table[i + 1, 0] <= s:
        i += 1
    w = (s - table[i, 0]) / (table[i + 1, 0] - table[i, 0])
    return (1.0 - w) * table[i, 1] + w * table[i + 1, 1], i


# loop state kept between calls of _closed_loop (a Python controller pauses the loop)
(_LS_INIT, _LS_SEG, _LS_SEG_M, _LS_S_PREV, _LS_S_UNW, _LS_S_PREV_M, _LS_S_UNW_M, _LS_T_REF,
 _LS_T_CTRL, _LS_TW_APP, _LS_DE_APP, _LS_TW_CMD, _LS_DE_CMD, _LS_ME_Y, _LS_N_LOG,
 _LS_RESUME, _LS_ST_ROW, _LS_VX_P, _LS_VY_P, _LS_R_P, _LS_BANK_ROW,
 _LS_NF_TW, _LS_NF_DE, _LS_NF_FIRST, _LS_X_PROJ, _LS_Y_PROJ, _LS_SAFE, _LS_W_MIN, _LS_K_MAX,
 _LS_LAPS) = range(30)
_LS_N = 30

# The true pose's projection between two logged rows (_closed_loop, "Projections"): the most the
# car may move before the next projection [m] (a few of the path's 1 m segments, so that the
# local search walks as few), the margin kept from the road's edge [m], the distance from the
# path's end within which every step projects [m], and the bound on kappa e_y along the way
# (then |ds| <= |dq| / (1 - 1/2), at most 4 m for a 2 m move: within the 5 m).
_SKIP_MOVE_M = 2.0
_SKIP_EDGE_M = 0.25
_SKIP_END_M = 5.0
_SKIP_KAPPA_EY = 0.5
_PAUSE = 3  # status code: a Python controller must give the commands for step k
# Control steps of sensor noise drawn at a time (sensors.SensorSuite.compile, block): 8 s at
# 1 kHz, 0.5 MB for the 8 channels; the whole run's noise was 38 MB for 10 minutes
# (benchmarks/README.md "The sensor noise a block at a time"). The loop stops at a block's end
# and goes on from the same step: the trajectory is the same bit for bit.
_NOISE_BLOCK = 8192


@njit(**_JIT_LOOP)
def _count_nonfinite(ls, k, tw_cmd, delta_cmd):
    """Count a control step whose command is not finite, per channel, in the loop state ``ls``
    (and the plant step ``k`` of the first one); the actuators hold the previous command."""
    if not math.isfinite(tw_cmd):
        ls[_LS_NF_TW] += 1.0
    if not math.isfinite(delta_cmd):
        ls[_LS_NF_DE] += 1.0
    if ls[_LS_NF_FIRST] < 0.0:
        ls[_LS_NF_FIRST] = k


@njit(**_JIT_LOOP)
def _path_bounds(g, half_width):
    """The narrowest half-width of the road the left-the-track check uses anywhere on the path
    (the nodes' widths, ``half_width`` where they are unknown) [m], and a bound on the path's
    curvature [1/m] (the nodes' largest, plus the most the Hermite interpolation between
    them can add: ``h max |dkappa/ds|``)."""
    w_min = math.inf
    k_abs = 0.0
    dk_abs = 0.0
    for i in range(g.shape[0]):
        for c in (_W_LEFT, _W_RIGHT):
            w = g[i, c]
            w_min = min(w_min, w if math.isfinite(w) else half_width)
        k_abs = max(k_abs, abs(g[i, _KAPPA]))
        dk_abs = max(dk_abs, abs(g[i, _DKAPPA]))
    h = g[1, 0] - g[0, 0] if g.shape[0] > 1 else 0.0
    return w_min, k_abs + h * dk_abs


@njit(**_JIT_LOOP)
def _safe_move(e_y, s_unw, s_end, w_min, k_max):
    """How far [m] the car may move from a pose projected at ``e_y`` [m], ``s_unw`` [m]
    before its projection could decide anything: leave the road or reach the path's end
    (:func:`_closed_loop`, "Projections"); 0 where it must be projected at every step."""
    ae = abs(e_y)
    if not (k_max * (ae + _SKIP_MOVE_M) <= _SKIP_KAPPA_EY and s_end - s_unw > _SKIP_END_M):
        return 0.0
    return max(min(w_min - ae - _SKIP_EDGE_M, _SKIP_MOVE_M), 0.0)


def _loop_scratch(n: int) -> tuple:
    """Work arrays of :func:`_closed_loop` for a plant of ``n`` states (allocated by the caller:
    the loop itself allocates nothing)."""
    return (np.empty(n), np.empty((5, n)), np.empty((4, 6)), np.zeros(NU), np.empty(_N_SENS),
            np.empty(_N_SENS))


@njit(**_JIT_LOOP)
def _closed_loop(plant, x, mp, tpf, tpr, bp, lf, lr, dt, n_steps, ctrl_every,
                 kind, p_lon, s_lon, p_lat, s_lat, coef, f_lon, f_lat, f_yaw,
                 cref_table, g, closed, sched_path, st_table, s_end,
                 sens_table, noise, noise_k0, hist, held, act_p, act_s,
                 mu_base, patches, bank_table, nan_faults, steer_faults,
                 log, log_every, half_width, k0, ls, meas, crow, scratch):
    """The whole closed loop (module docstring). Returns (status code, step, rows logged).

    ``ls`` (length ``_LS_N``) carries the loop's own state between calls, ``meas`` (8) and
    ``crow`` (1 + len(CREF)) the last measurement and controller reference, ``scratch`` the
    work arrays (:func:`_loop_scratch`). With ``kind`` = ``KIND.PYTHON`` the loop returns
    ``_PAUSE`` at every control step with ``meas`` and ``crow`` filled; the caller writes the
    commands into ``ls``, sets ``ls[_LS_RESUME]`` and calls again with ``k0`` = the returned
    step. The loop runs the plant steps ``k0`` to ``n_steps - 1``; ``noise`` holds the sensor
    noise of the control steps from ``noise_k0`` on (one block, :data:`_NOISE_BLOCK`), and the
    caller stops the loop where the block ends (``n_steps``; status 0, step ``n_steps``),
    draws the next block and calls again with ``k0`` = that step: a loop started at any step
    goes on as if it had not stopped (its state is in ``ls`` and the arrays).

    Projections. The true pose's Frenet coordinates serve the logged row, the two checks that
    end a run (the road's edge, the path's end), and the friction patches and bank, looked up
    at its arc length. Without patches and bank the loop projects it at the logged rows only,
    and in between wherever a check could decide. From a pose projected at ``e_y``, a pose at
    the distance ``d`` has ``|e_y'| <= |e_y| + d`` (the distance to a curve changes no faster
    than the point moves) and an arc length within ``d / (1 - kappa |e_y|)`` along the way;
    so it cannot be off the road while ``d < w_min - |e_y|`` (``w_min`` the narrowest
    half-width anywhere on the path), nor at the path's end while ``d`` is short of the
    remaining length over that factor. A step projects when ``|dx| + |dy|`` (at least ``d``)
    from the last projected position reaches :func:`_safe_move`: that edge distance less
    0.25 m, at most 2 m, and nothing within 5 m of the end or where ``kappa_max (|e_y| +
    2 m)`` exceeds 1/2 (``kappa_max`` the path's; then the arc length moves at most 4 m).
    The unwrapped arc length is ``s`` plus the laps, which does not depend on the poses
    projected before. The controller sees the measured pose's projection, made at every
    control step as before. So the trajectory is the same bit for bit. A projection from an
    older segment finds the same foot point, to round-off where the local search ends on the
    neighbouring segment (the flat-output MFC's laps, metres off the path: e_y and s within
    2.3e-13 m in up to 9 logged rows; every other named scenario and track, bit for bit), so
    the run ends at the same step unless its arc length lands within that round-off of the
    end (tests/test_projection_skip.py).
    The skip is the common case near the path (``paper`` on Norisring, whose tightest bend
    gives ``kappa_max`` 0.11 1/m: |e_y| up to 2.5 m); a car far off it projects every step.
    It saves one projection per plant step of two (the measured pose is noisy): ~50 ns of
    ~1000 (benchmarks/README.md "The true pose projected at the logged rows").
    """
    xn, work, diag, u, truth, meas_s = scratch
    n = x.shape[0]
    # the 10DoF tyre lanes' coefficient table, filled once for the run (not at every step)
    lt = stack_array(LANE_TABLE_SHAPE[0], LANE_TABLE_SHAPE[1])
    if plant == 0:
        lane_table(lt, tpf, tpr)
    length = g[g.shape[0] - 1, 0]
    off = 3  # index of vx in both plant layouts (X, Y, psi, vx, vy, r, ...)
    if ls[_LS_INIT] == 0.0:
        seg = frenet_init(g, closed, x[0], x[1], x[2])
        s0, _, _, _, seg = frenet_project(g, closed, x[0], x[1], x[2], seg)
        ls[_LS_INIT] = 1.0
        ls[_LS_SEG] = seg
        ls[_LS_SEG_M] = seg
        ls[_LS_S_PREV] = s0
        ls[_LS_S_UNW] = s0
        ls[_LS_S_PREV_M] = s0
        ls[_LS_S_UNW_M] = s0
        ls[_LS_T_REF] = 0.0
        ls[_LS_T_CTRL] = 0.0
        ls[_LS_TW_APP] = math.nan
        ls[_LS_DE_APP] = math.nan
        ls[_LS_TW_CMD] = 0.0
        ls[_LS_DE_CMD] = 0.0
        ls[_LS_ME_Y] = math.nan
        ls[_LS_N_LOG] = 0.0
        ls[_LS_RESUME] = 0.0
        ls[_LS_ST_ROW] = 0.0
        ls[_LS_VX_P] = math.nan  # no previous velocity: the first acceleration is unknown
        ls[_LS_VY_P] = math.nan
        ls[_LS_R_P] = math.nan
        ls[_LS_BANK_ROW] = 0.0
        ls[_LS_NF_TW] = 0.0  # control steps with a non-finite torque command
        ls[_LS_NF_DE] = 0.0  # ... steer command
        ls[_LS_NF_FIRST] = -1.0  # plant step of the first one (-1: none)
        ls[_LS_X_PROJ] = x[0]  # the true pose's position at its last projection
        ls[_LS_Y_PROJ] = x[1]
        ls[_LS_SAFE] = 0.0  # how far from there the checks stay undecided (0: every step)
        ls[_LS_W_MIN], ls[_LS_K_MAX] = _path_bounds(g, half_width)
        ls[_LS_LAPS] = 0.0  # times the true pose crossed the closed path's start, net
    seg = int(ls[_LS_SEG])
    seg_m = int(ls[_LS_SEG_M])
    s_prev = ls[_LS_S_PREV]
    s_unw = ls[_LS_S_UNW]
    s_prev_m = ls[_LS_S_PREV_M]
    s_unw_m = ls[_LS_S_UNW_M]
    t_ref = ls[_LS_T_REF]
    t_ctrl_last = ls[_LS_T_CTRL]
    tw_app = ls[_LS_TW_APP]
    delta_app = ls[_LS_DE_APP]
    tw_cmd = ls[_LS_TW_CMD]
    delta_cmd = ls[_LS_DE_CMD]
    me_y = ls[_LS_ME_Y]
    n_log = int(ls[_LS_N_LOG])
    st_row = int(ls[_LS_ST_ROW])
    vx_p = ls[_LS_VX_P]
    vy_p = ls[_LS_VY_P]
    r_p = ls[_LS_R_P]
    bank_row = int(ls[_LS_BANK_ROW])
    x_proj = ls[_LS_X_PROJ]
    y_proj = ls[_LS_Y_PROJ]
    safe = ls[_LS_SAFE]
    laps = ls[_LS_LAPS]
    w_min = ls[_LS_W_MIN]
    k_max = ls[_LS_K_MAX]
    # the true pose's projection may wait for the next logged row where nothing else needs it:
    # no friction patches and no bank, which are looked up at its arc length ("Projections")
    lazy = patches.shape[0] == 0 and bank_table.shape[0] == 0
    s = s_prev
    e_y = 0.0
    e_psi = 0.0
    kap = 0.0
    inv_dt = 1.0 / dt
    form_ey_ddot = wants_ey_ddot(kind, coef)
    resume = ls[_LS_RESUME] == 1.0
    ls[_LS_RESUME] = 0.0
    status = 0
    # phases of the control and log clocks (k % ctrl_every, k % log_every) kept as counters:
    # an integer division per step and clock is not free at this rate
    c_ctrl = k0 % ctrl_every
    c_log = k0 % log_every
    k = k0
    for k in range(k0, n_steps):
        t = k * dt
        for i in range(6):
            truth[i] = x[i] if i < 3 else x[off + i - 3]
        if not all_finite(x):
            status = 2
            break
        # the distance from the last projected position (|dx| + |dy| >= its length)
        project = not (lazy and c_log != 0
                       and abs(truth[0] - x_proj) + abs(truth[1] - y_proj) < safe)
        seg_old = -1  # the true pose's projection of this step, if any, started from seg_old
        if project:
            seg_old = seg
            s, e_y, e_psi, kap, seg = frenet_project(g, closed, truth[0], truth[1], truth[2],
                                                     seg)
            # the unwrapped arc length from s and the laps: the same at a pose whether or not
            # the poses before it were projected (a running sum of the steps' progress would
            # round by the steps it summed)
            if closed:
                laps -= math.floor((s - s_prev) / length + 0.5)  # a crossing of the start
            s_unw = s + laps * length
            s_prev = s
            w = g[seg, _W_LEFT] if e_y > 0.0 else g[seg, _W_RIGHT]
            if not math.isfinite(w):
                w = half_width
            if abs(e_y) > w:
                status = 1
                break
            if s_unw >= s_end:
                break  # the end of the reference path is reached: completed
            if lazy:
                x_proj = truth[0]
                y_proj = truth[1]
                safe = _safe_move(e_y, s_unw, s_end, w_min, k_max)
        if c_ctrl == 0 and not (resume and k == k0):
            kc = k if ctrl_every == 1 else k // ctrl_every
            # the CoG's acceleration in body axes over the last plant step (module docstring)
            r_m = 0.5 * (truth[5] + r_p)
            truth[6] = (truth[3] - vx_p) * inv_dt - r_m * 0.5 * (truth[4] + vy_p)
            truth[7] = (truth[4] - vy_p) * inv_dt + r_m * 0.5 * (truth[3] + vx_p)
            sense_step(kc, truth, sens_table, noise, kc - noise_k0, hist, held, meas_s)
            for f in range(nan_faults.shape[0]):
                if nan_faults[f, 1] <= t < nan_faults[f, 2]:
                    meas_s[int(nan_faults[f, 0])] = math.nan
            for i in range(6):
                meas[i] = meas_s[i]
            meas[8] = meas_s[6]
            meas[9] = meas_s[7]
            if math.isfinite(meas[0]) and math.isfinite(meas[1]) and math.isfinite(meas[2]):
                if (meas[0] == truth[0] and meas[1] == truth[1] and meas[2] == truth[2]
                        and seg_m == seg_old):
                    # the measured pose is the true one (noise-free, no delay) and the search
                    # starts from the same segment: the projection above, reused (the same
                    # computation on the same inputs)
                    s_m = s
                    me_y = e_y
                    me_psi = e_psi
                    me_kap = kap
                    seg_m = seg
                else:
                    s_m, me_y, me_psi, me_kap, seg_m = frenet_project(g, closed, meas[0],
                                                                      meas[1], meas[2], seg_m)
                s_unw_m += progress(s_m, s_prev_m, length, closed)
                s_prev_m = s_m
                if sched_path:
                    # reference time at the measured arc length (path schedule)
                    t_ref, st_row = _time_at(st_table, s_unw_m, st_row)
                else:
                    t_ref = t
            else:
                me_y = math.nan
                me_psi = math.nan
                me_kap = math.nan
                t_ref += t - t_ctrl_last  # no pose: the schedule runs on with the clock
            t_ctrl_last = t
            meas[6] = me_y
            meas[7] = me_psi
            if form_ey_ddot:
                # NaN at the path's centre of curvature (no foot point moves with the car)
                meas[10] = lateral_deviation_acceleration_kernel(meas[8], meas[9], meas[3],
                                                                 meas[4], me_y, me_psi, me_kap)
            sample_reference(cref_table, t_ref, crow)
            if kind == _PYTHON:
                status = _PAUSE  # hand the measurement to the Python controller
                break
            tw_cmd, delta_cmd = vehicle_step(kind, p_lon, s_lon, p_lat, s_lat, coef, f_lon,
                                             f_lat, f_yaw, meas, crow[1:], tw_app, delta_app)
            if not (math.isfinite(tw_cmd) and math.isfinite(delta_cmd)):
                _count_nonfinite(ls, k, tw_cmd, delta_cmd)  # held by the actuators
        vx_p = truth[3]
        vy_p = truth[4]
        r_p = truth[5]
        c_ctrl += 1
        if c_ctrl == ctrl_every:
            c_ctrl = 0
        # the power cap at the driveline's speed (a spinning driven wheel takes power too);
        # the 3DoF plant has no wheel spins: its body speed
        v_drive = drive_speed(x, mp) if plant == 0 else truth[3]
        delta_prev = act_s[0]
        tw, delta = actuate_step(tw_cmd, delta_cmd, v_drive, act_p, act_s)
        for f in range(steer_faults.shape[0]):
            if steer_faults[f, 0] <= t < steer_faults[f, 1]:
                # the range shrinks to the limit no faster than the steer's rate limit: a
                # steer beyond it when the fault starts is driven in by the actuator (a
                # clamp at once moved them within a plant step: 70.8 rad/s from 0.07 rad,
                # tests/test_simulation.py, counted in the rate metrics)
                lim = max(steer_faults[f, 2], abs(delta_prev) - act_p[1])
                delta = min(max(delta, -lim), lim)
                act_s[0] = delta
        tw_app = tw
        delta_app = delta
        mu_f = _mu_at(s + lf, mu_base, patches, length, closed)
        mu_r = _mu_at(s - lr, mu_base, patches, length, closed)
        u[0] = tw
        u[1] = delta
        u[2] = mu_f
        u[3] = mu_f
        u[4] = mu_r
        u[5] = mu_r
        if bank_table.shape[0] > 0:  # the road's bank at the CoG (else u[6] stays 0: flat)
            u[6], bank_row = _time_at(bank_table, s, bank_row)
            u[7] = e_psi  # the heading to the road's tangent orients the bank's slope
        if c_log == 0 and n_log < log.shape[1]:
            log[0, n_log] = t
            for i in range(6):
                log[1 + i, n_log] = truth[i]
            log[7, n_log] = x[_ROLL] if plant == 0 else 0.0
            log[8, n_log] = x[_PITCH] if plant == 0 else 0.0
            log[9, n_log] = s_unw
            log[10, n_log] = e_y
            log[11, n_log] = e_psi
            log[12, n_log] = crow[1]  # the speed reference the controller used
            log[13, n_log] = tw_cmd
            log[14, n_log] = delta_cmd
            log[15, n_log] = tw
            log[16, n_log] = delta
            log[17, n_log] = meas[3]
            log[18, n_log] = me_y
            log[19, n_log] = s_lon[_F_HAT] if kind == 1 or kind == 2 else math.nan
            log[20, n_log] = lateral_f_hat(kind, p_lat, s_lat, coef)
            log[21, n_log] = mu_f
            for i in range(4):
                log[22 + i, n_log] = x[_OMEGA_FL + i] if plant == 0 else math.nan
            log[26, n_log] = t_ref
            n_log += 1
        c_log += 1
        if c_log == log_every:
            c_log = 0
        if plant == 0:
            rk4_step_table(x, u, dt, mp, tpf, tpr, lt, x, work, diag)  # in place (allowed)
        else:
            rk4_step_into(x, u, dt, bp, 0.0, 0.0, False, xn)
            for i in range(n):
                x[i] = xn[i]
    else:
        k = n_steps
        if not all_finite(x):  # the last plant step's result, which no step above looked at
            status = 2
    ls[_LS_SEG] = seg
    ls[_LS_SEG_M] = seg_m
    ls[_LS_S_PREV] = s_prev
    ls[_LS_S_UNW] = s_unw
    ls[_LS_S_PREV_M] = s_prev_m
    ls[_LS_S_UNW_M] = s_unw_m
    ls[_LS_T_REF] = t_ref
    ls[_LS_T_CTRL] = t_ctrl_last
    ls[_LS_TW_APP] = tw_app
    ls[_LS_DE_APP] = delta_app
    ls[_LS_TW_CMD] = tw_cmd
    ls[_LS_DE_CMD] = delta_cmd
    ls[_LS_ME_Y] = me_y
    ls[_LS_N_LOG] = n_log
    ls[_LS_ST_ROW] = st_row
    ls[_LS_VX_P] = vx_p
    ls[_LS_VY_P] = vy_p
    ls[_LS_R_P] = r_p
    ls[_LS_BANK_ROW] = bank_row
    ls[_LS_X_PROJ] = x_proj
    ls[_LS_Y_PROJ] = y_proj
    ls[_LS_SAFE] = safe
    ls[_LS_LAPS] = laps
    return status, k, n_log


def flying_lap_speed(s: np.ndarray, v_ref: np.ndarray, vehicle: VehicleParams, *,
                     closed: bool, max_laps: int = 10) -> np.ndarray:
    """Speed a car following ``v_ref`` can actually have along the path (power-limited).

    The speed profiles of :mod:`flatfree.tracks` know the friction ellipse, not the engine: on
    a fast stretch the reference may ask for more speed than the car can reach. The car holds
    ``v <= v_ref`` (it brakes where the reference brakes) and below it accelerates at most with
    the drive force ``min(max_drive_torque / R_e, max_power / v)`` (the actuators' power cap)
    against the drag ``1/2 rho C_d A v^2`` and the rolling resistance ``f_r m g`` ([VM] 1.9,
    the 10DoF plant's resistances):

        d(v^2)/ds = 2 a(v),   a(v) = (F_drive(v) - 1/2 rho C_d A v^2 - f_r m g) / m,

    integrated with Heun's method in ``v^2`` between the given points, then capped by
    ``v_ref``. On a closed path the integration wraps around the lap until the speed at
    ``s[0]`` repeats (the car arrives at the line on a flying lap); an open path starts from
    ``v_ref[0]``.

    Parameters
    ----------
    s : ndarray
        Arc length, non-decreasing [m]; a closed path's last point is the lap's end (= ``s[0]``
        plus one lap, where ``v_ref[-1]`` equals ``v_ref[0]``).
    v_ref : ndarray
        Reference speed at ``s`` [m/s].
    vehicle : VehicleParams
        Mass, wheel radius, drive torque and power limits, drag area, air density, rolling
        resistance.
    closed : bool
        Wrap the integration around the lap.
    max_laps : int
        Laps integrated at most on a closed path (the speed at ``s[0]`` only decreases from lap
        to lap and is fixed once the car meets ``v_ref`` anywhere on the lap).

    Returns
    -------
    ndarray
        The reachable speed at ``s`` [m/s], ``<= v_ref``.

    Notes
    -----
    The drive model is :func:`flatfree.tracks.drive_acceleration`'s. Unlike
    ``tracks.speed_profile(..., vehicle=...)`` this does not apply the friction ellipse while the
    car accelerates below ``v_ref`` (measured: up to 0.14 m/s above that profile on Spa, 0.015
    m/s at its top speed on LVMS); on a profile planned with the drive limit
    (``reference.drive_limit``) it returns the profile itself (to ~1e-13 m/s).

    References
    ----------
    .. [VM] shared/reference/VEHICLE_MODEL.md 1.9 (drag, rolling resistance); the power cap:
       :class:`flatfree.actuators.ActuatorParams`.
    """
    s = np.ascontiguousarray(s, dtype=float)
    v_ref = np.ascontiguousarray(v_ref, dtype=float)
    if s.ndim != 1 or s.shape != v_ref.shape or s.size == 0:
        raise ValueError(f"s, v_ref: shapes {s.shape}, {v_ref.shape}: expected the same 1-d "
                         "shape with at least one point")
    max_laps = whole("max_laps", max_laps, 1, "laps")
    drv = _drive_array(vehicle)  # the drive model of tracks.speed.drive_acceleration
    v = np.empty_like(v_ref)
    _flying_lap_kernel(s, v_ref, drv, closed, max_laps, v)
    return v


@njit(cache=True)
def _flying_lap_kernel(s, v_ref, drv, closed, max_laps, v):
    """:func:`flying_lap_speed`'s integration, written into ``v`` (compiled: a lap has 6 000-25 000
    points: in Python it took 16 ms of a Norisring run's 28 ms preparation; compiled 0.4 ms,
    benchmarks/profile_closed_loop.py)."""
    v0 = v_ref[0]
    for _ in range(max_laps if closed else 1):
        v[0] = v0
        for i in range(s.shape[0] - 1):  # the speed profile's drive step, no friction limit
            w1 = _power_cap(v[i] * v[i], s[i + 1] - s[i], math.inf, drv)
            v[i + 1] = min(v_ref[i + 1], math.sqrt(w1))
        if not closed:
            break
        v0_next = min(v_ref[0], v[v.shape[0] - 1])  # s[-1] is s[0] one lap on
        if abs(v0_next - v0) <= 1e-9 * max(v0, 1.0):
            break
        v0 = v0_next


@dataclass(frozen=True, slots=True, eq=False)
class Prepared:
    """A scenario turned into the arrays of the compiled loop (inspectable; one run each)."""

    scenario: Scenario
    vehicle: VehicleParams
    reference: Reference
    # reference sideslip on the reference grid [rad]: the path's course minus the reference
    # yaw (the 3DoF model's on a track, the recorded one for a recording; module docstring)
    beta_ref: np.ndarray
    controller: VehicleControllerArrays
    actuators: ActuatorParams
    cref: np.ndarray  # controller references: time, then the CREF columns
    x0: np.ndarray
    n_steps: int
    path_schedule: bool  # references read at the measured arc length (else at the clock)
    steer0: float = 0.0  # initial road-wheel steer of the actuator and the controller [rad]


def _ref_dt(sc: Scenario) -> float:
    """Time step of the reference tables: :data:`REFERENCE_DT_S`, or the plant step if coarser."""
    return max(REFERENCE_DT_S, sc.timing.plant_dt_s)


def _reference(sc: Scenario, vehicle: VehicleParams) -> Reference:
    spec = sc.reference
    if spec.recording is not None:
        from flatfree.tracks import load_recording

        rec = load_recording(spec.recording).on_track()
        return rec.reference(dt=_ref_dt(sc))
    track = load_track(spec.track, raceline=spec.line == "raceline", closed=spec.closed,
                       smoothing_length=spec.smoothing_length_m)
    limits = SpeedLimits(a_lat_max=spec.a_lat_max, a_drive_max=spec.a_drive_max,
                         a_brake_max=spec.a_brake_max, v_max=spec.v_max, mu=spec.mu,
                         j_lat_max=spec.j_lat_max)
    # drive_limit: the profile also within the car's drive limit (tracks.speed_profile)
    return make_reference(track, limits, dt=_ref_dt(sc),
                          lateral_offset=spec.lateral_offset_m, laps=spec.laps,
                          vehicle=vehicle if spec.drive_limit else None)


def _warn_if_beyond_steer_lock(ref: Reference, vehicle: VehicleParams) -> None:
    """Warn when the path's tightest curve needs more road-wheel steer than the car has.

    The kinematic steer L kappa is a lower bound of the steer a curve needs (the tyres' slip
    angles add to it in an understeering car): above the car's lock no controller can follow
    the path there (the dallara_av21, 0.279 rad, on the 9.5-10 m hairpins of Monza, Spa and
    Norisring). A warning, not an error: the run is still a valid experiment.
    """
    kappa = np.abs(np.asarray(ref["kappa"], dtype=float))
    if kappa.size == 0 or not np.isfinite(kappa).any():
        return
    k_max = float(np.nanmax(kappa))
    need = vehicle.wheelbase * k_max
    if need > vehicle.max_steer:
        warn(
            f"the reference's tightest curve (radius {1.0 / k_max:.1f} m) needs a road-wheel "
            f"steer of at least {need:.3f} rad (wheelbase x curvature), beyond "
            f"{vehicle.name}'s max_steer = {vehicle.max_steer:.3f} rad: the car cannot follow "
            "the path there", UserWarning)


#: Steady lateral jerk v^3 |dkappa/ds| [m/s^3] of a track reference above which a run of the
#: natural-output controller warns (:func:`_warn_if_rough`). The bundled references of the
#: default profile reach 20.9 (Norisring's centerline). The three measured above it made both
#: natural-output designs leave on the peugeot406, noise-free, and completed with
#: ``reference.j_lat_max`` = 15: Norisring's race line (34.7 at 106 m, at 50 m/s: they spin
#: off at 4.4-4.5 s), and the LVMS centerline smoothed at 20 m before session 13 bridged its
#: start (28.7 at 869 m: 5.0-5.2 s; tests/test_speed_jerk.py) and after (29.5 at 1071 m:
#: both leave at 30.2 s); benchmarks/jerk_limit.py part 7 prints these. A threshold between
#: what was seen to work and to fail (benchmarks/README.md "The noise drawn per channel"),
#: not a property of every car.
ROUGH_JERK = 25.0


def _steady_jerk_peak(ref: Reference) -> tuple[float, int] | None:
    """The largest steady lateral jerk v^3 |dkappa/ds| [m/s^3] a reference asks and its row
    (None if none is finite): what :func:`_warn_if_rough` compares with :data:`ROUGH_JERK`."""
    jerk = np.abs(np.asarray(ref["vx"]) ** 3 * np.asarray(ref["dkappa_ds"]))
    if not np.isfinite(jerk).any():
        return None
    i = int(np.nanargmax(jerk))
    return float(jerk[i]), i


def _warn_if_rough(ref: Reference, sc: Scenario) -> None:
    """Warn when a track reference asks the natural-output controller for more steady lateral
    jerk than :data:`ROUGH_JERK` (a rough path: a kink in the data, or a light smoothing)."""
    if sc.reference.recording is not None or sc.controller != "mfc-natural":
        return
    peak = _steady_jerk_peak(ref)
    if peak is None or peak[0] <= ROUGH_JERK:
        return
    jerk, i = peak
    warn(f"the path may be too rough for the natural-output controller: its reference asks "
         f"for a steady lateral jerk v^3 |dkappa/ds| of {jerk:.1f} m/s^3 at s = "
         f"{float(ref['s'][i]):.0f} m ({float(ref['vx'][i]):.1f} m/s), above {ROUGH_JERK:g} "
         "m/s^3, and the car left the track on every such reference tested; a speed profile "
         "with reference.j_lat_max = 15 (--set reference.j_lat_max=15) caps it", UserWarning)


#: Largest |course - yaw| [rad] of a recording taken as the car's sideslip (30 deg): beyond it
#: the recorded yaw is refused (another convention: degrees, clockwise, from north); beyond
#: :data:`_RECORDED_BETA_WARN` (5 deg, more than a race car's sideslip at the limit) a warning.
_RECORDED_BETA_MAX = math.radians(30.0)
_RECORDED_BETA_WARN = math.radians(5.0)


def _recorded_sideslip(ref: Reference, name) -> np.ndarray:
    """The sideslip of a recorded reference [rad]: its path's course minus its recorded yaw,
    wrapped; a ``ValueError`` when it reaches :data:`_RECORDED_BETA_MAX` (the yaw is not the
    car's yaw as flatfree takes it), a warning beyond :data:`_RECORDED_BETA_WARN`."""
    beta = wrap_angle(ref["psi"] - ref.extras["psi_recorded"])
    i = int(np.nanargmax(np.abs(beta))) if np.isfinite(beta).any() else 0
    worst = abs(float(beta[i]))
    if worst >= _RECORDED_BETA_WARN:
        what = (f"recording {name}: its yaw phi differs from the course of its positions by "
                f"{math.degrees(float(beta[i])):.1f} deg at t = {float(ref['t'][i]):.2f} s")
        if worst >= _RECORDED_BETA_MAX:
            raise ValueError(f"{what}: phi must be the car's yaw in rad, counter-clockwise from "
                             f"+x (a sideslip beyond {math.degrees(_RECORDED_BETA_MAX):g} deg "
                             "is taken for another convention)")
        warn(f"{what}, the sideslip the run takes as its reference there (and starts with at "
             f"t = 0: {math.degrees(float(beta[0])):.1f} deg); phi is the car's yaw in rad, "
             "counter-clockwise from +x")
    return beta


def _warn_if_flat_output_singular(ref: Reference, model: Bicycle3DoFParams,
                                  controller: str, vehicle: VehicleParams) -> None:
    """Warn when a flat-output design's reference passes the speed where the steer loses its
    authority over y2 (:func:`flatfree.controllers.flatness.singular_speed`)."""
    if controller not in ("flatness", "mfc-flat"):
        return
    v_star = singular_speed(model)
    vx = np.asarray(ref["vx"], dtype=float)
    vx = vx[np.isfinite(vx)]
    if v_star is None or vx.size == 0 or not vx.min() <= v_star <= vx.max():
        return
    warn(
        f"{controller} on {vehicle.name}: the reference's speed ({vx.min():.1f}-{vx.max():.1f} "
        f"m/s) passes {v_star:.1f} m/s, where the steer has no effect on the flat output "
        f"y2 = lf m Vy - Iz r (yaw index Iz / (m lf lr) = "
        f"{model.iz / (model.m * model.lf * model.lr):.2f} < 1): the lateral loop fails near "
        "that speed", UserWarning)


#: A reference asking more than this times ``road.mu g`` is warned about (:func:`_check_road`):
#: a profile planned for the road exceeds its friction ellipse by ~0.1 % where the table's
#: samples meet (4.909 against 4.903 m/s^2 at mu 0.5 on Norisring, tests/test_simulation.py).
_GRIP_MARGIN = 1.01


def _check_road(sc: Scenario, ref: Reference) -> None:
    """Refuse a friction patch the car can never reach, and say when the plant ignores the
    road's friction.

    A patch is found by the path's own arc length (on a closed path taken modulo the lap:
    :func:`_mu_at`; the patch then acts on every lap), so one that starts at or beyond the
    path's length (the lap's, on a closed path) never applies: ``ValueError`` naming it. The
    3DoF plant's linear tyres have no friction limit: ``road.mu`` and the patches do not act
    on it (a warning; the trajectory logs them as given). On the 10DoF plant a base
    ``road.mu`` whose ``mu g`` is below the reference's largest acceleration ``|(a_x,
    V_x^2 kappa)|`` (by more than :data:`_GRIP_MARGIN`) is warned about: the speed profile
    plans with ``reference.mu``, not with the road's (a patch below it is a local fault,
    meant, and not warned about).
    """
    length = ref.path.length
    what = "the lap's length" if ref.path.closed else "the path's length"
    for i, p in enumerate(sc.road.patches):
        if p.s_start_m >= length:
            raise ValueError(
                f"road.patch[{i}].s_start_m = {p.s_start_m!r} m: at or beyond {what}, "
                f"{length:.1f} m, so the patch never applies (patches are placed by the arc "
                "length along the path" + (", modulo the lap, and act on every lap)"
                                           if ref.path.closed else ")"))
    if sc.plant == "3dof":
        if sc.road.mu != 1.0 or sc.road.patches:
            warn(f"road.mu = {sc.road.mu!r} and {len(sc.road.patches)} friction patch(es) do "
                 "not act on the 3dof plant (linear tyres, no friction limit): use plant = "
                 "'10dof' for the road's friction")
        return
    # a road below what the reference asks everywhere (a patch is a local fault, meant)
    acc = np.hypot(ref["ax"], ref["vx"] ** 2 * ref["kappa"])
    k = int(np.argmax(acc))
    grip = sc.road.mu * G
    if acc[k] > _GRIP_MARGIN * grip:
        if sc.reference.recording is not None:
            why = "the recording's speeds on its path"
        elif sc.reference.mu > sc.road.mu:
            why = (f"the speed profile plans with reference.mu = {sc.reference.mu!r}, not with "
                   f"the road's: set reference.mu = {sc.road.mu!r} to plan for this road")
        else:  # planned for this road: the path's own curvature asks it (its smoothing)
            why = ("the speed profile plans for this road's friction, but the path's curvature "
                   "varies faster than the profile follows (its smoothing: "
                   "reference.smoothing_length_m)")
        warn(f"road.mu = {sc.road.mu!r}: the reference asks for up to {acc[k]:.2f} m/s^2 "
             f"(at s = {ref['s'][k]:.0f} m), more than the road's friction gives anywhere "
             f"(road.mu g = {grip:.2f} m/s^2; {why})")


def reference_of(sc: Scenario | str) -> Reference:
    """The reference a run of ``sc`` follows (``prepare(sc).reference``), without building the
    controllers and their 3DoF references; the warnings a run gives about it are not repeated
    (for reading a run's reference after the run: the recorded steer, figures, notes)."""
    sc = _as_scenario(sc)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _reference(sc, sc.load_vehicle())


def prepare(sc: Scenario | str, *, python_controller: object | None = None) -> Prepared:
    """Build the vehicle, reference, controller and initial state of a scenario (or of the
    named scenario of that name, as :func:`simulate`).

    With ``python_controller`` the built-in controller is replaced by a :data:`KIND.PYTHON`
    placeholder and the schedule is the object's ``schedule`` attribute (default ``"path"``).
    """
    sc = _as_scenario(sc)
    vehicle = sc.load_vehicle()
    ref = _reference(sc, vehicle)
    _warn_if_beyond_steer_lock(ref, vehicle)
    _check_road(sc, ref)
    bic = Bicycle3DoFParams.from_vehicle(vehicle)
    if python_controller is None:  # said about the built-in controller only
        _warn_if_rough(ref, sc)
        warn_if_untuned(sc.vehicle, sc.controller, sc.controller_settings,
                        steer_gain=bic.cf / bic.m)
        _warn_if_flat_output_singular(ref, bic, sc.controller, vehicle)
    # the controllers' lateral references: the 3DoF model with the yaw rate V kappa of the path
    # ("dynamic"; each design's documented reference)
    lat = reference_states_3dof(ref, cf=bic.cf, cr=bic.cr, mass=bic.m, iz=bic.iz,
                                lf=bic.lf, lr=bic.lr)
    recorded = sc.reference.recording is not None
    # the yaw error's reference sideslip (metrics.py) and the start's. On a track the 3DoF
    # model with its CoG on the path ("path"). Planning the flat-output designs' y2 from it
    # instead made them leave Spa, the mismatched one Norisring too (noise-free, seed 0: its y2
    # carries the model's weakly damped yaw mode, which the 10DoF car then rings with;
    # benchmarks/README.md "The yaw error's reference: the 3DoF model on the path")
    if recorded:
        # the recorded yaw is the reference yaw: the gap to the path's course (the smoothed
        # positions' tangent; -0.62 deg at the LVMS recording's start, 0.62 at most) is the
        # sideslip the car starts with and the yaw error's reference
        beta = _recorded_sideslip(ref, sc.reference.recording)
    else:
        lat_p = reference_states_3dof(ref, cf=bic.cf, cr=bic.cr, mass=bic.m, iz=bic.iz,
                                      lf=bic.lf, lr=bic.lr, method="path")
        beta = np.arctan2(lat_p.vy, np.maximum(lat_p.vx, 1e-6))
        del lat_p  # its other states are not needed (a long run's peak is in this function)
    act = ActuatorParams.from_vehicle(
        vehicle, steer_tau=sc.actuators.steer_tau_s, steer_delay=sc.actuators.steer_delay_s,
        torque_tau=sc.actuators.torque_tau_s, torque_delay=sc.actuators.torque_delay_s)
    settings = settings_from_mapping(sc.controller, sc.controller_settings)
    schedule = settings.schedule
    lat_c = lat
    if python_controller is not None:
        schedule = getattr(python_controller, "schedule", "path")
        if schedule not in SCHEDULES:
            raise ValueError(f"controller.schedule = {schedule!r}: must be one of "
                             f"{', '.join(SCHEDULES)}")
        z = np.zeros(1)
        ctrl = VehicleControllerArrays(int(KIND.PYTHON), z, z.copy(), z.copy(), z.copy(),
                                       np.zeros(14), z.copy(), z.copy(), z.copy())
    elif sc.controller == "flatness":
        ctrl = build_flatness(settings, dt=sc.timing.control_dt_s, model=bic)
        if settings.cf_scale != 1.0 or settings.cr_scale != 1.0:
            # the controller plans its y2 reference with the model it believes in
            lat_c = reference_states_3dof(ref, cf=settings.cf_scale * bic.cf,
                                          cr=settings.cr_scale * bic.cr, mass=bic.m,
                                          iz=bic.iz, lf=bic.lf, lr=bic.lr)
    else:
        warn_if_untuned_period(sc.controller, settings, sc.timing.control_dt_s)
        ctrl = build_mfc(sc.controller, settings, dt=sc.timing.control_dt_s, actuators=act,
                         mass=vehicle.mass, iz=vehicle.iz, lf=vehicle.lf,
                         steer0=float(lat.delta[0]))
    if schedule == "path":
        # the run ends at the end of the path: by default leave time for a car slower than the
        # profile; a longer requested duration is capped at twice that horizon, far beyond any
        # car that follows the profile (the loop's log, len(LOG) = 27 floats a logged sample,
        # is allocated for the whole duration: 78 MB for an hour logged at 100 Hz, 3.6e5 x 27
        # doubles; the reference and the controller's table grow with the duration too)
        horizon = 1.5 * ref.duration + 5.0
        duration = horizon if sc.timing.duration_s is None else min(sc.timing.duration_s,
                                                                     2.0 * horizon)
    elif sc.timing.duration_s is not None:
        duration = sc.timing.duration_s
    else:
        duration = ref.duration
    n_steps = int(round(duration / sc.timing.plant_dt_s))
    late = [f"fault[{i}] ({f.kind}) at t_start_s = {f.t_start_s:g} s"
            for i, f in enumerate(sc.faults) if f.t_start_s >= duration]
    if late:
        warn(f"{', '.join(late)}: at or after the run's end ({duration:g} s at most), never "
             "happens")
    # start on the reference, with its sideslip and path curvature, at the speed the car can
    # have there: on a closed track the car arrives at the line on a flying lap, and the
    # friction-only profile may ask for more than the engine gives (LVMS: 49.7 m/s at s = 0,
    # where the peugeot406 arrives at 44.7 m/s, at the start of a 6 m/s^2 braking;
    # flying_lap_speed). A recording's speed was driven: kept.
    row = ref.table[0]
    vx_ref0 = float(row[RS.VX])
    vx0 = vx_ref0
    if not recorded and ref.path.closed:
        vx0 = float(flying_lap_speed(ref["s_path"], ref["vx"], vehicle, closed=True)[0])
    scale = vx0 / vx_ref0 if vx_ref0 > 0.0 else 1.0
    vy0 = vx0 * math.tan(float(beta[0]))  # the reference's sideslip
    r0 = scale * float(row[RS.R])  # Vx kappa at the car's speed
    psi0 = float(row[RS.PSI]) - float(beta[0])  # heading = course - sideslip (ISO 8855)
    if sc.plant == "10dof":
        x0 = TenDoF(vehicle).initial_state(vx0, vy=vy0, r=r0, x=float(row[RS.X]),
                                           y=float(row[RS.Y]), psi=psi0)
    else:
        x0 = np.array([row[RS.X], row[RS.Y], psi0, vx0, vy0, r0], dtype=float)
    # controller references: t, then the CREF columns
    cref = np.empty((ref.table.shape[0], 1 + len(CREF)))
    cref[:, 0] = ref["t"]
    cref[:, 1 + CREF.VX] = ref["vx"]
    cref[:, 1 + CREF.AX] = ref["ax"]
    cref[:, 1 + CREF.Y2] = lat_c.y2
    cref[:, 1 + CREF.Y2_DOT] = lat_c.y2_dot
    cref[:, 1 + CREF.Y2_DDOT] = lat_c.y2_ddot
    cref[:, 1 + CREF.EY] = ref["e_y_ref"]
    cref[:, 1 + CREF.EY_DOT] = ref["e_y_ref_dot"]
    cref[:, 1 + CREF.EY_DDOT] = ref["e_y_ref_ddot"]
    cref[:, 1 + CREF.KAPPA] = ref["kappa"]
    # d y2 / d r of the controller's design model (path correction; vehicle.py), at the
    # reference speed: the scaled model for a mismatched flatness controller
    design = bic
    if sc.controller == "flatness" and python_controller is None:
        design = dataclasses.replace(bic, cf=settings.cf_scale * bic.cf,
                                     cr=settings.cr_scale * bic.cr)
    cref[:, 1 + CREF.Y2_PER_R] = y2_per_r(design, ref["vx"])
    # -beta_ref' of the controller's reference (vx_ref, vy_ref): a car whose CoG follows the
    # path turns at r = V kappa - beta' (course = psi + beta), the reference has r = Vx kappa
    beta_c = np.arctan2(lat_c.vy, np.maximum(ref["vx"], 1e-6))
    cref[:, 1 + CREF.R_KIN] = -np.gradient(beta_c, ref["t"]) if len(beta_c) > 1 else 0.0
    # the car starts in the reference's cornering state, so its steer starts at the design
    # model's steer there (the actuator's position, known to any controller switched on while
    # the car is driven; a model-free controller holds it until its window is full). With a
    # zero initial steer the car started un-trimmed in a curve: the peugeot406 at 45 m/s on
    # LVMS's curved start line (the bound files' seam, since bridged) left the track within 3 s
    # (seed 4; noise-free with wn_lat 10).
    steer0 = float(np.clip(lat.delta[0], -act.max_steer, act.max_steer))
    return Prepared(sc, vehicle, ref, beta, ctrl, act, cref, x0, n_steps, schedule == "path",
                    steer0)


class PythonController(Protocol):
    """A user's controller for :func:`simulate` (the slower, Python door).

    ``step`` is called at every control instant (``timing.control_dt_s``) with

    - ``t``: the clock time [s];
    - ``measurement``: a float array in the layout :class:`flatfree.controllers.vehicle.MEAS`
      (measured x, y, psi, vx, vy, r, then the lateral deviation and heading error of the
      measured pose from the path, the measured accelerations ax, ay and the deviation's
      second derivative formed from them
      (:func:`flatfree.tracks.lateral_deviation_acceleration`); NaN where
      a sensor fault blanks a channel, and e_y'' where the measured pose is at the path's
      centre of curvature);
    - ``reference``: a float array in the layout :class:`flatfree.controllers.vehicle.CREF`
      (speed, acceleration, flat-output and lateral-deviation references, path curvature,
      the path correction's d y2 / d r and -beta_ref'),
      read at the scheduled reference time (``schedule``);

    - ``applied``: ``[torque, steer]`` the actuators applied over the previous plant step (NaN
      before the first), for controllers that estimate from the applied input;

    and returns ``(torque [N m], steer [rad])``, held until the next call and passed through
    the actuators. ``reset()``, if present, is called before the run. An optional attribute
    ``schedule`` (``"path"`` or ``"time"``, default ``"path"``) chooses the reference schedule.
    The arrays are the loop's own buffers: copy them to keep them.

    A command that is not a real number (text, ``None``, an array) raises ``ValueError``
    naming the call. A non-finite command (NaN, inf) is not an error: the actuators hold the
    previous command in its place (:func:`flatfree.actuators.actuate_step`), so a controller
    that keeps returning NaN leaves the car on its last command. :func:`simulate` counts such
    steps per channel in the trajectory's ``meta`` and warns once (``RuntimeWarning``) after
    the run, naming the first one.
    """

    def step(self, t: float, measurement: np.ndarray, reference: np.ndarray,
             applied: np.ndarray) -> tuple[float, float]: ...


def _as_scenario(sc) -> Scenario:
    """``sc``, or the named scenario of that name (:func:`flatfree.scenarios.named_scenario`);
    ``ValueError`` saying what to pass for anything else."""
    if isinstance(sc, Scenario):
        return sc
    if isinstance(sc, str) and sc in SCENARIO_NAMES:
        return named_scenario(sc)
    raise ValueError(f"sc = {sc!r}: expected a Scenario (flatfree.load_scenario(path) for a "
                     "scenario file, flatfree.named_scenario(name, ...) for a named one with "
                     f"options) or a named scenario's name: {', '.join(SCENARIO_NAMES)}")


def _python_command(controller, t: float, out) -> tuple[float, float]:
    """A Python controller's return value as (torque, steer) floats; ``ValueError`` naming the
    call for anything but two real numbers (non-finite ones pass: :class:`PythonController`)."""
    if type(out) is tuple and len(out) == 2 and isinstance(out[0], float) and isinstance(
            out[1], float):
        return out  # the common case: two floats (Python or NumPy)
    try:
        tw, delta = out
    except (TypeError, ValueError):
        tw = delta = None
    tw_f = as_real(tw)
    delta_f = as_real(delta)
    if tw_f is None or delta_f is None:
        raise ValueError(f"controller.step(t = {t!r} s, ...) = {out!r} "
                         f"({type(controller).__name__}): expected (torque [N m], steer [rad]), "
                         "two real numbers")
    return tw_f, delta_f


class RunTooLongError(ValueError):
    """A run whose log, allocated for its whole duration, does not fit in memory
    (:func:`simulate`; the message names ``timing.duration_s``)."""


def simulate(sc: Scenario | str, controller: PythonController | None = None) -> Trajectory:
    """Run a scenario in the compiled closed loop; never raises on a failed run (see status).

    Parameters
    ----------
    sc : Scenario or str
        The run (vehicle, plant, reference, controller and its settings, timing, sensors,
        actuators, road, faults, seed), or a named scenario's name (``"paper"``:
        :func:`flatfree.scenarios.named_scenario` with its defaults). Anything else raises
        ``ValueError``.
    controller : PythonController, optional
        A user's controller (Python object with ``step``) replacing ``sc.controller``. The same
        compiled engine runs, pausing at every control step to call it: a few microseconds of
        Python per call (benchmarks/README.md "Closed loop": 266-288x real time with a
        controller returning constants at 1 kHz on the 10DoF, against about 1000x for the
        built-in controllers). Its commands must be real numbers
        (``ValueError`` otherwise); non-finite ones are counted and warned about (below).

    Returns
    -------
    Trajectory
        Named signals (:class:`LOG` columns in lower case, plus ``lateral_error``,
        ``yaw_error`` and ``course_error``, the direction of the CoG velocity minus the path
        heading), status and its time, and ``meta``: ``real_time_factor`` (simulated over wall
        time of the loop) and ``wall_time_s``, which leave out compiling the loop or loading
        it from numba's cache (``compile_time_s``) and drawing the sensor noise
        (``noise_time_s``: the first block before the loop, the next ones where the loop
        stops for them).
        ``n_nonfinite_torque_cmd`` and ``n_nonfinite_steer_cmd`` count the control steps
        whose torque / steer command was not finite, and ``first_nonfinite_cmd_t_s`` is the
        time of the first such step (None: none). The actuators hold the previous command in
        place of a non-finite one (:func:`flatfree.actuators.actuate_step`), so such a run
        can end "completed" with the car on stale commands; ``simulate`` then also warns once
        (``RuntimeWarning``: the first step's time and the counts). A built-in controller
        holds its output through non-finite measurements (its documented policy), so its
        command is not finite only when its law overflowed (e.g. finite measurements of the
        order of 1e307).

    Raises
    ------
    ValueError
        A bad scenario or controller (above); :class:`RunTooLongError` (a ValueError) when the
        run's log, allocated for its whole duration, does not fit in memory.
    """
    sc = _as_scenario(sc)
    if controller is not None and not callable(getattr(controller, "step", None)):
        raise ValueError(f"controller = {controller!r}: expected an object with a step(t, "
                         "measurement, reference, applied) method")
    return _simulate_prepared(prepare(sc, python_controller=controller), controller)


def simulate_prepared(prep: Prepared, controller: PythonController | None = None) -> Trajectory:
    """:func:`simulate` of a scenario already prepared (:func:`prepare`, with the same
    ``controller`` as its ``python_controller``): for a caller that also needs what the run was
    built from (``prep.reference``, the vehicle) without building it twice. The run works on
    copies of ``prep``'s controller arrays, so ``prep`` is left as it was (running it again
    gives the same trajectory)."""
    if not isinstance(prep, Prepared):
        raise ValueError(f"prep = {prep!r}: expected a Prepared (simulation.prepare)")
    if (controller is not None) != (prep.controller.kind == KIND.PYTHON):
        raise ValueError("controller: give the same Python controller (or none) as the "
                         "prepare(..., python_controller=...) that built prep")
    return _simulate_prepared(prep, controller)


def _simulate_prepared(prep: Prepared, controller: PythonController | None) -> Trajectory:
    """The run of :func:`simulate` and :func:`simulate_prepared`."""
    sc = prep.scenario
    cref = prep.cref
    vehicle = prep.vehicle
    ref = prep.reference
    timing = sc.timing
    plant = 0 if sc.plant == "10dof" else 1
    if plant == 0:
        model = TenDoF(vehicle)
        mp = model.params
    else:
        mp = np.zeros(1)
    bp = Bicycle3DoFParams.from_vehicle(vehicle).to_array()
    tpf = vehicle.tire_front.to_array()
    tpr = vehicle.tire_rear.to_array()
    n_ctrl = prep.n_steps // timing.control_every + 1
    n_log = prep.n_steps // timing.log_every + 1
    # the sensor noise a block at a time (the loop stops at a block's end for the next one)
    t_draw = time.perf_counter()
    sens = sc.effective_sensors.compile(SENSOR_CHANNELS, timing.control_dt_s, n_ctrl, sc.seed,
                                        block=_NOISE_BLOCK,
                                        unread=unread_channels(prep.controller))
    noise0_s = time.perf_counter() - t_draw
    try:  # the log of the whole duration
        # a row per signal (len(LOG), n_log): each signal contiguous, and the trajectory
        # takes them without a copy (trajectory._adopting)
        log = np.full((len(LOG), n_log), np.nan)
    except MemoryError as exc:
        d = timing.duration_s
        d = "the run" if d is None else f"timing.duration_s = {d:g} s"
        raise RunTooLongError(f"{d}: the run's log, allocated for the whole duration, does "
                              f"not fit in memory ({exc})") from None
    act_p = prep.actuators.to_array(timing.plant_dt_s)
    act_s = actuator_state(prep.actuators, timing.plant_dt_s, steer0=prep.steer0)
    patches = np.array([[p.s_start_m, p.s_end_m, p.mu] for p in sc.road.patches],
                       dtype=float).reshape(-1, 3)
    # the road's bank (s [m], bank [rad]) for the 10DoF plant (the 3DoF plant has no input for it)
    bank_table = np.array(sc.road.bank_deg if plant == 0 else (), dtype=float).reshape(-1, 2)
    bank_table[:, 1] = np.radians(bank_table[:, 1])
    nan_f = np.array([[SENSOR_CHANNELS.index(f.channel), f.t_start_s,
                       f.t_start_s + f.duration_s] for f in sc.faults
                      if f.kind == "nan_measurement"], dtype=float).reshape(-1, 3)
    steer_f = np.array([[f.t_start_s, f.t_start_s + f.duration_s, f.value] for f in sc.faults
                        if f.kind == "steer_limit"], dtype=float).reshape(-1, 3)
    # the controller's state lives in its arrays: the run's own copies (prep stays as built)
    ctrl = copy.deepcopy(prep.controller)
    x = prep.x0.copy()
    ls = np.zeros(_LS_N)
    scratch = _loop_scratch(x.shape[0])
    meas = np.full(len(MEAS), np.nan)
    crow = np.empty(cref.shape[1])
    applied = np.empty(2)
    # arc length -> reference time (path schedule); strictly increasing arc length required
    s_path = ref["s_path"]
    keep = np.concatenate(([True], np.diff(s_path) > 1e-9))
    st_table = np.ascontiguousarray(np.column_stack((s_path[keep], ref["t"][keep])))
    s_end = float(s_path[-1]) - 0.1  # 10 cm short of the end: the projection saturates there
    if controller is not None and callable(getattr(controller, "reset", None)):
        controller.reset()

    def loop_args(k0: int, k_end: int) -> tuple:
        return (plant, x, mp, tpf, tpr, bp, vehicle.lf, vehicle.lr, timing.plant_dt_s,
                k_end, timing.control_every, ctrl.kind, ctrl.p_lon, ctrl.s_lon,
                ctrl.p_lat, ctrl.s_lat, ctrl.coef, ctrl.f_lon, ctrl.f_lat, ctrl.f_yaw, cref,
                ref.path.geometry, ref.path.closed, prep.path_schedule, st_table, s_end,
                sens.table, sens.noise, sens.first_step, sens.history, sens.held, act_p, act_s,
                sc.road.mu, patches, bank_table, nan_f, steer_f, log, timing.log_every,
                DEFAULT_HALF_WIDTH_M, k0, ls, meas, crow, scratch)

    # compile the loop (or load it from numba's cache) before the clock starts: the real-time
    # factor is the loop's, not the compiler's (a fresh clone's first run compiles for seconds)
    t_compile = time.perf_counter()
    _closed_loop.compile(tuple(numba.typeof(a) for a in loop_args(0, prep.n_steps)))
    compile_s = time.perf_counter() - t_compile
    t0 = time.perf_counter()
    noise_s = 0.0  # drawing the sensor noise's blocks after the first (out of the loop's time)
    k0 = 0
    n_calls = 0
    ce = timing.control_every
    while True:
        # the plant steps whose control steps have their noise drawn (the whole run's end at
        # the last block)
        k_end = min(prep.n_steps, (sens.first_step + sens.noise.shape[1]) * ce)
        code, k_stop, rows = _closed_loop(*loop_args(k0, k_end))
        if code == 0 and k_stop == k_end < prep.n_steps:
            t_draw = time.perf_counter()
            sens.next_block()  # the block's end: the run goes on from step k_stop
            noise_s += time.perf_counter() - t_draw
            k0 = k_stop
            continue
        if code != _PAUSE:
            break
        applied[0] = ls[_LS_TW_APP]
        applied[1] = ls[_LS_DE_APP]
        t_call = k_stop * timing.plant_dt_s
        out = controller.step(t_call, meas, crow[1:], applied)
        n_calls += 1
        tw, delta = _python_command(controller, t_call, out)
        if not (math.isfinite(tw) and math.isfinite(delta)):
            _count_nonfinite(ls, k_stop, tw, delta)
        ls[_LS_TW_CMD] = tw
        ls[_LS_DE_CMD] = delta
        ls[_LS_RESUME] = 1.0
        k0 = k_stop
    wall = time.perf_counter() - t0 - noise_s
    if rows < log.shape[1]:
        # the rows logged, moved to the front signal by signal (numpy copies overlapping
        # ranges safely), and the buffer shrunk to them: the trajectory's signals are then
        # its only contents, without a second copy at the run's peak
        flat = log.reshape(-1)
        for m in range(1, len(LOG)):
            flat[m * rows:(m + 1) * rows] = log[m, :rows]
        del flat
        log.resize((len(LOG), rows), refcheck=False)
    log.flags.writeable = False
    status = _STATUS[int(code)]
    sim_time = k_stop * timing.plant_dt_s
    signals = {m.name.lower(): log[m] for m in LOG if m is not LOG.T}
    # errors against the reference by arc length (metrics.py definitions)
    s_ref = ref["s_path"]
    # heading = path course - sideslip (ISO 8855): for a recording the recorded yaw (issue 7's
    # definition; prepare). The LVMS recording's phi follows its course, atan2(dy, dx), signed
    # median difference -0.03 deg (its PROVENANCE.md): its car's sideslip is not in it
    psi_full = ref["psi"] - prep.beta_ref
    s_log = np.clip(log[LOG.S], s_ref[0], s_ref[-1])
    signals["lateral_error"] = log[LOG.E_Y] - np.interp(s_log, s_ref, ref["e_y_ref"])
    signals["yaw_error"] = wrap_angle(log[LOG.PSI] - np.interp(s_log, s_ref, psi_full))
    # direction of the CoG velocity against the path heading (no sideslip model involved): what
    # a steering law can hold when the CoG is on the path (benchmarks/README.md "Closed loop")
    course = log[LOG.PSI] + np.arctan2(log[LOG.VY], log[LOG.VX])
    signals["course_error"] = wrap_angle(course - np.interp(s_log, s_ref, ref["psi"]))
    units = dict(_UNITS, lateral_error="m", yaw_error="rad", course_error="rad")
    units["f_lat"] = "m/s^2" if sc.controller == "mfc-natural" else "kg m^2/s^2"
    units["f_lon"] = "m/s^2"
    name = sc.controller if controller is None else f"python:{type(controller).__name__}"
    meta = {
        "scenario": sc.name, "controller": name, "vehicle": vehicle.name,
        "plant": sc.plant, "seed": sc.seed, "noise": sc.noise,
        "track": sc.reference.track or sc.reference.recording,
        # how it was sampled (the metrics' rates depend on the log's period; metrics.py)
        "plant_dt_s": timing.plant_dt_s, "control_dt_s": timing.control_dt_s,
        "log_dt_s": timing.log_dt_s, "startup_s": timing.startup_s,
        "real_time_factor": sim_time / wall if wall > 0 else math.nan,
        "wall_time_s": wall,
        # time to compile the loop or load it from the cache, outside wall_time_s
        "compile_time_s": compile_s,
        # drawing the sensor noise, the first block included (outside wall_time_s)
        "noise_time_s": noise_s + noise0_s,
        # control steps whose command was not finite (the actuators held the previous one)
        "n_nonfinite_torque_cmd": int(ls[_LS_NF_TW]),
        "n_nonfinite_steer_cmd": int(ls[_LS_NF_DE]),
        "first_nonfinite_cmd_t_s": (None if ls[_LS_NF_FIRST] < 0.0
                                    else float(ls[_LS_NF_FIRST]) * timing.plant_dt_s),
    }
    if ls[_LS_NF_FIRST] >= 0.0:
        # a built-in controller's command is not finite only when its law overflowed (a
        # non-finite measurement is held, not passed on): said as a Python controller's is
        counts = (f"{meta['n_nonfinite_torque_cmd']} (torque) and "
                  f"{meta['n_nonfinite_steer_cmd']} (steer)")
        if controller is not None:
            head = (f"controller {type(controller).__name__}: step returned a non-finite "
                    f"command at {counts} of its {n_calls} calls")
        else:
            head = f"controller {sc.controller}: a non-finite command at {counts} control steps"
        warn(
            f"{head}, the first at t = {meta['first_nonfinite_cmd_t_s']:.6g} s (control step "
            f"{int(ls[_LS_NF_FIRST]) // timing.control_every}); the actuators held the previous "
            "command there (flatfree.actuators.actuate_step). Counts in the trajectory's meta "
            "(n_nonfinite_torque_cmd, n_nonfinite_steer_cmd)", RuntimeWarning)
    with _adopting():  # the log's columns, which nothing else holds
        return Trajectory(time=log[LOG.T], signals=signals, units=units, status=status,
                          status_time=None if status is Status.COMPLETED else sim_time,
                          meta=meta)


# keep the TenDoFState import meaningful for readers of the loop's indices
assert TenDoFState.roll == 8 and TenDoFState.pitch == 10 and TenDoFState.vx == 3
assert TenDoFState.omega_fl == 12 and LOG.T_REF == 26 and len(LOG) == 27
assert IST.F_HAT == 6 and KIND.MFC_NATURAL == 2 and KIND.PYTHON == _PYTHON == 3
assert MEAS.E_Y == 6 and MEAS.E_PSI == 7 and CREF.VX == 0 and CREF.KAPPA == 8
assert MEAS.AX == 8 and MEAS.AY == 9 and MEAS.EY_DDOT == 10 and _N_SENS == 8
