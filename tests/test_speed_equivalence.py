"""The closed loop's speed work changed no result: each optimised kernel against the plain code.

The kernels of the compiled loop were restructured for speed (issue 7's benchmark target,
benchmarks/README.md "Closed loop"): reference counting off, contiguous views instead of offset
indexing, ring indices without integer divisions, a walking search instead of a binary one, the
steer angle's trigonometry once per RK4 step, the control and log clocks as counters. None of
these may change a single bit. Each test below runs the optimised kernel and a plain transcription
of the formula it replaced (the code before the change, in Python or numba) on the same inputs
and asserts exact equality (``assert_array_equal``: no tolerance, because none is needed; a
difference of one ulp is a defect here).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flatfree.actuators import ActuatorParams, actuate_step, actuator_state
from flatfree.controllers.flatness_control import sample_flat_reference
from flatfree.controllers.intelligent import IST, IntelligentParams, intelligent_step, make_state
from flatfree.estimators._fir import _W, _dot
from flatfree.models.tendof import TenDoF, TenDoFOptions, rhs_kernel, rk4_step_kernel
from flatfree.scenario import ReferenceSpec, Scenario, Timing
from flatfree.scenarios import REALISTIC_SENSORS
from flatfree.sensors import SensorChannel, SensorSuite, sense_step
from flatfree.simulation import _time_at, simulate
from flatfree.vehicles import load_vehicle


# ---- reference search: _time_at vs sample_flat_reference (binary search) --------------------
def test_walking_search_equals_the_binary_search_bit_for_bit():
    rng = np.random.default_rng(7)
    s = np.cumsum(rng.uniform(0.01, 2.0, 400))  # strictly increasing, uneven grid
    table = np.ascontiguousarray(np.column_stack((s, rng.standard_normal(400))))
    # a run's queries: mostly forward by less than a row, some jumps both ways, the ends
    q = np.concatenate((np.cumsum(rng.uniform(0.0, 0.3, 2000)) + s[0] - 1.0,
                        rng.uniform(s[0] - 5.0, s[-1] + 5.0, 500), s[:50], [s[0], s[-1]]))
    out = np.empty(2)
    row = 0
    for t in q:
        sample_flat_reference(table, t, out)
        v, row = _time_at(table, t, row)
        assert v == out[1] or (math.isnan(v) and math.isnan(out[1])), t
        assert 0 <= row <= len(s) - 2
    v, row = _time_at(table, math.nan, 3)
    assert math.isnan(v)


# ---- actuators: ring indices without integer divisions ---------------------------------------
def _actuate_plain(torque_cmd, steer_cmd, vx, p, st):
    """actuate_step before the change (Python's modulo on every ring index)."""
    depth = (st.shape[0] - 3) // 2
    w = int(st[2])
    if not math.isfinite(steer_cmd):
        steer_cmd = st[3 + (w - 1) % depth]
    if not math.isfinite(torque_cmd):
        torque_cmd = st[3 + depth + (w - 1) % depth]
    st[3 + w] = steer_cmd
    st[3 + depth + w] = torque_cmd
    steer_in = st[3 + (w - int(p[3])) % depth]
    torque_in = st[3 + depth + (w - int(p[8])) % depth]
    st[2] = (w + 1) % depth
    target = st[0] + p[2] * (steer_in - st[0])
    step = min(max(target - st[0], -p[1]), p[1])
    s = min(max(st[0] + step, -p[0]), p[0])
    st[0] = s
    tq = st[1] + p[7] * (torque_in - st[1])
    tq = min(max(tq, -p[6]), min(p[4], p[5] / max(abs(vx), 1.0)))
    st[1] = tq
    return tq, s


@pytest.mark.parametrize("steer_delay, torque_delay", [(0.0, 0.0), (0.003, 0.0), (0.0, 0.002),
                                                       (0.004, 0.001)])
def test_actuators_equal_the_modulo_form(steer_delay, torque_delay):
    dt = 1e-3
    prm = ActuatorParams.from_vehicle(load_vehicle("peugeot406"), steer_tau=0.02,
                                      torque_tau=0.05, steer_delay=steer_delay,
                                      torque_delay=torque_delay)
    p = prm.to_array(dt)
    st_a = actuator_state(prm, dt, steer0=0.01, torque0=100.0)
    st_b = st_a.copy()
    rng = np.random.default_rng(3)
    for k in range(300):
        tq = rng.uniform(-3000.0, 3000.0) if k % 17 else math.nan  # some non-finite commands
        de = rng.uniform(-0.3, 0.3) if k % 23 else math.inf
        vx = rng.uniform(0.0, 60.0)
        a = actuate_step(tq, de, vx, p, st_a)
        b = _actuate_plain(tq, de, vx, p, st_b)
        assert a == b, k
        np.testing.assert_array_equal(st_a, st_b)


# ---- sensors: no division for undelayed channels sampled every step --------------------------
def _sense_plain(k, truth, table, noise, history, held, out):
    """sense_step before the change."""
    depth = history.shape[1]
    for i in range(truth.shape[0]):
        history[i, k % depth] = truth[i]
        delay = int(table[i, 3])
        delayed = history[i, (k - delay) % depth] if k >= delay else history[i, 0]
        if k % int(table[i, 2]) == 0 or math.isnan(held[i]):
            held[i] = delayed + table[i, 1] + table[i, 0] * noise[k, i]
        out[i] = held[i]


@pytest.mark.parametrize("delays", [False, True])
def test_sensors_equal_the_modulo_form(delays):
    chans = {"a": SensorChannel(noise_std=0.1, bias=0.2),
             "b": SensorChannel(noise_std=0.05, delay_s=0.003 if delays else 0.0),
             "c": SensorChannel(noise_std=0.0, rate_hz=250.0 if delays else None)}
    comp = SensorSuite(channels=chans).compile(("a", "b", "c"), 1e-3, 200, 5)
    hist_b, held_b = comp.history.copy(), comp.held.copy()
    rng = np.random.default_rng(11)
    out_a, out_b = np.empty(3), np.empty(3)
    for k in range(200):
        truth = rng.standard_normal(3)
        sense_step(k, truth, comp.table, comp.noise, comp.history, comp.held, out_a)
        _sense_plain(k, truth, comp.table, comp.noise, hist_b, held_b, out_b)
        np.testing.assert_array_equal(out_a, out_b)


# ---- 10DoF: the steer's trigonometry once per RK4 step ---------------------------------------
@pytest.mark.parametrize("ackermann", [False, True])
def test_rk4_step_equals_four_right_hand_sides(ackermann):
    """rk4_step_kernel is classical RK4 over the public rhs_kernel, bit for bit, and leaves the
    last stage's diagnostics in diag."""
    model = TenDoF(load_vehicle("peugeot406"), TenDoFOptions(ackermann=ackermann))
    veh = model.vehicle
    tpf, tpr = veh.tire_front.to_array(), veh.tire_rear.to_array()
    x = model.initial_state(25.0, vy=0.3, r=0.2)
    x[12:16] += np.array([0.5, -0.3, 1.0, 0.2])  # some wheel slip
    dt = 1e-3
    n = x.size
    work, diag, out = np.empty((5, n)), np.empty((4, 6)), np.empty(n)
    diag_ref = np.empty((4, 6))
    for u in (np.array([400.0, 0.05, 1.0, 1.0, 0.9, 0.9]),
              np.array([-900.0, -0.12, 0.6, 0.6, 0.6, 0.6]), np.zeros(6) + [0, 0, 1, 1, 1, 1]):
        rk4_step_kernel(x, u, dt, model.params, tpf, tpr, out, work, diag)
        k1, k2, k3, k4 = (np.empty(n) for _ in range(4))
        rhs_kernel(x, u, model.params, tpf, tpr, k1, diag_ref)
        rhs_kernel(x + 0.5 * dt * k1, u, model.params, tpf, tpr, k2, diag_ref)
        rhs_kernel(x + 0.5 * dt * k2, u, model.params, tpf, tpr, k3, diag_ref)
        rhs_kernel(x + dt * k3, u, model.params, tpf, tpr, k4, diag_ref)
        ref = x + dt / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
        np.testing.assert_array_equal(out, ref)
        np.testing.assert_array_equal(diag, diag_ref)


# ---- the estimators' sums: views instead of offset indexing ----------------------------------
def test_fir_dot_equals_four_accumulators_in_order():
    rng = np.random.default_rng(2)
    a = rng.standard_normal(_W + 61)
    for m in (1, 3, 4, 50, 51):
        ia, ib = _W, 7
        s = [0.0, 0.0, 0.0, 0.0]
        for j in range(m - m % 4):
            s[j % 4] += a[ia + j] * a[ib + j]
        for j in range(m - m % 4, m):
            s[0] += a[ia + j] * a[ib + j]
        assert _dot(a, ia, a, ib, m) == (s[0] + s[1]) + (s[2] + s[3])


@pytest.mark.parametrize("nu", [1, 2])
def test_intelligent_sums_equal_the_fused_loop(nu):
    """F_hat (and y'_hat) after each step equal the sums in the original loop's order."""
    kw = {"nu": nu, "alpha": 30.0, "dt": 1e-3, "window": 40, "kp": 4.0, "u_min": -0.5,
          "u_max": 0.5}
    if nu == 2:
        kw.update(kd=4.0, derivative="model", derivative_window=40)
    prm = IntelligentParams(**kw)
    p = prm.to_array()
    s = make_state(p)
    L = int(p[11])
    hp, hs = 12, len(IST)
    wy, wu = p[hp:hp + L], p[hp + L:hp + 2 * L]
    wdy, wdu = p[hp + 2 * L:hp + 3 * L], p[hp + 3 * L:hp + 4 * L]
    rng = np.random.default_rng(5)
    for k in range(150):
        intelligent_step(p, s, 0.01 * math.sin(0.05 * k) + 1e-3 * rng.standard_normal(),
                         0.0, 0.0, 0.0)
        if k + 1 < L:
            continue
        head = int(s[IST.HEAD])
        y = s[hs + head:hs + head + L]
        # the u ring holds this step's output at head: the estimate used u[k-1-i] = head+1+i
        u = s[hs + 2 * L + head + 1:hs + 2 * L + head + L]
        ay = wy[L - 1] * y[L - 1]
        au = 0.0
        dy = wdy[L - 1] * y[L - 1]
        du = 0.0
        for i in range(L - 1):
            ay += wy[i] * y[i]
            au += wu[i] * u[i]
            dy += wdy[i] * y[i]
            du += wdu[i] * u[i]
        assert s[IST.F_HAT] == ay + p[1] * au
        if nu == 2:
            assert s[IST.YDOT] == dy + p[1] * du


# ---- the loop: clocks as counters, projection reuse, pause and resume ------------------------
class _Replay:
    """A Python controller returning the built-in run's commands (to test the pausing door with
    control and log clocks that are not multiples of each other)."""

    def __init__(self, commands):
        self.commands = commands
        self.i = 0

    def step(self, t, measurement, reference, applied):
        tw, de = self.commands[self.i]
        self.i += 1
        return tw, de


def test_slow_control_clock_and_odd_log_clock_through_both_doors():
    """Control every 3 plant steps, log every 7: a Python controller replaying the built-in
    run's commands gives its logged trajectory bit for bit (the clock counters keep their
    phase across the pauses of the Python door), and the rows fall every 7 ms."""
    timing = {"duration_s": 0.6, "plant_dt_s": 1e-3, "control_dt_s": 3e-3}
    sc = Scenario(plant="10dof", controller="mfc-natural",
                  reference=ReferenceSpec(track="Norisring", a_lat_max=3.0),
                  timing=Timing(log_dt_s=7e-3, **timing), sensors=REALISTIC_SENSORS, seed=4,
                  controller_settings={"window_lat": 20, "window_lon": 10, "denoise_yaw": 5})
    a = simulate(sc)
    assert len(a) == 86
    np.testing.assert_allclose(np.diff(a.time), 7e-3, rtol=0, atol=1e-12)
    # the commands at every control step: the same run logged at the plant rate (the log's
    # rate does not touch the dynamics), taken every 3 rows
    fine = simulate(sc.with_(timing=Timing(log_dt_s=1e-3, **timing)))
    np.testing.assert_array_equal(fine["x"][::7], a["x"])
    replay = _Replay(np.column_stack((fine["torque_cmd"][::3], fine["steer_cmd"][::3])))
    b = simulate(sc, controller=replay)
    assert replay.i == 200
    for k in a:
        if k in ("f_lon", "f_lat"):  # controller internals: only the built-in door logs them
            continue
        np.testing.assert_array_equal(b[k], a[k], err_msg=k)
