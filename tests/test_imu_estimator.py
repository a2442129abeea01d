"""The acceleration-aided lateral estimator of the natural-output controller (``estimator_lat =
"imu"``) and the measured e_y'' it uses (flatfree.tracks.lateral_deviation_acceleration).

Reference values: exact kinematics of a point on a circle and on a line (closed forms), the
second difference of a simulated 10DoF lateral deviation, exactness of the observer and the
ultra-local model on a parabola, and the algebraic controller itself (the fallback).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from flatfree.actuators import ActuatorParams
from flatfree.controllers.vehicle import MEAS, MfcNaturalSettings, NaturalOutputController
from flatfree.metrics import compute_metrics
from flatfree.scenario import Fault, ReferenceSpec, Scenario, Timing
from flatfree.scenarios import named_scenario
from flatfree.simulation import prepare, simulate
from flatfree.tracks import (
    frenet_init,
    frenet_project,
    lateral_deviation_acceleration,
    lateral_deviation_acceleration_kernel,
)
from flatfree.trajectory import Status
from flatfree.vehicles import load_vehicle

_ACT = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))


def test_lateral_deviation_acceleration_exact_on_a_circle_and_a_line():
    # a point on a circle of radius r0 inside a concentric path of radius R (left turn): the
    # deviation e_y = R - r0 is constant, so e_y'' = 0 although a . n = v^2 / r0 and the path
    # term is kappa v^2 / (1 - kappa e_y) = v^2 / r0 (the factor is needed: v^2 / R without it)
    for v, big_r, r0 in ((20.0, 50.0, 49.0), (35.0, 120.0, 122.5), (5.0, 10.0, 9.2)):
        got = lateral_deviation_acceleration(0.0, v * v / r0, v, 0.0, big_r - r0, 0.0,
                                             1.0 / big_r)
        assert abs(got) <= 1e-12 * v * v / r0, got
    # a point accelerating at a along a line at angle theta to a straight path:
    # e_y = (v0 t + a t^2 / 2) sin(theta), e_y'' = a sin(theta); body axes along the velocity
    for a, theta in ((3.0, 0.2), (-6.0, -0.05), (1.5, 1.0)):
        got = lateral_deviation_acceleration(a, 0.0, 12.0, 0.0, 0.7, theta, 0.0)
        assert got == pytest.approx(a * math.sin(theta), rel=1e-14, abs=1e-15)
    assert math.isnan(lateral_deviation_acceleration(math.nan, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0))
    # NumPy scalars and integers are numbers; the compiled twin gives the same value
    args = (np.float64(0.3), 2, 20.0, np.float32(0.5), 0.1, -0.02, 0.004)
    assert lateral_deviation_acceleration(*args) == lateral_deviation_acceleration_kernel(
        *(float(a) for a in args))


@pytest.mark.parametrize(("args", "message"), [
    (("a", 0.0, 20.0, 0.0, 0.0, 0.0, 0.0), "ax = 'a' m/s^2: expected a real number"),
    ((0.0, 0.0, None, 0.0, 0.0, 0.0, 0.0), "vx = None m/s: expected a real number"),
    ((0.0, 0.0, 20.0, 0.0, np.zeros(2), 0.0, 0.0),
     "e_y = array([0., 0.]) m: expected a real number"),
    ((0.0, 0.0, 20.0, 0.0, 0.0, 0.0, True), "kappa = True 1/m: expected a real number"),
    ((0.0, 0.0, 20.0, 0.0, 10.0, 0.0, 0.1), ("e_y = 10.0 m, kappa = 0.1 1/m: the point is at "
     "the path's centre of curvature (kappa e_y = 1), where e_y'' is not defined")),
])
def test_lateral_deviation_acceleration_refuses_bad_arguments_by_name(args, message):
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        lateral_deviation_acceleration(*args)


def test_the_compiled_twin_gives_nan_at_the_centre_of_curvature():
    # a compiled loop must not raise: NaN there, which the imu estimator treats as a lost sample
    assert math.isnan(lateral_deviation_acceleration_kernel(0.0, 0.0, 20.0, 0.0, 10.0, 0.0, 0.1))


class _Recorder:
    """The built-in natural-output controller through the Python door, keeping every
    measurement vector the engine hands it."""

    def __init__(self, sc):
        self.c = NaturalOutputController(dt=sc.timing.control_dt_s, actuators=_ACT)
        self.steer0 = prepare(sc).steer0
        self.meas = []

    def reset(self):
        self.c.reset(steer0=self.steer0)

    def step(self, t, m, ref, applied):
        self.meas.append(m.copy())
        return self.c.step(vx=m[MEAS.VX], r=m[MEAS.R], e_y=m[MEAS.E_Y], kappa=ref[8],
                           vx_ref=ref[0], ax_ref=ref[1], applied_torque=applied[0],
                           applied_steer=applied[1])


def test_engine_measures_the_second_derivative_of_the_simulated_deviation():
    """On a 10DoF run (Norisring's first corner, noise-free, logged at every plant step), the
    kinematic e_y'' from central differences of the logged velocities matches the second
    difference of the logged e_y to 0.01 m/s^2 (measured; bound 0.03) while a . n and the path
    term each reach 6 m/s^2; the engine's measured column (accelerations over the last plant
    step) matches it to 0.017 m/s^2 (bound 0.05)."""
    sc = Scenario(plant="10dof", controller="mfc-natural",
                  reference=ReferenceSpec(track="Norisring"),
                  timing=Timing(duration_s=6.0, log_dt_s=0.001), noise=False)
    rec = _Recorder(sc)
    tr = simulate(sc, controller=rec)
    assert tr.status is Status.COMPLETED
    meas = np.array(rec.meas)
    dt = sc.timing.plant_dt_s
    x, y, psi, vx, vy, r, ey, epsi = (tr[k] for k in ("x", "y", "psi", "vx", "vy", "r", "e_y",
                                                        "e_psi"))
    n = x.size
    assert meas.shape == (n, len(MEAS))
    g = prepare(sc).reference.path.geometry
    seg = frenet_init(g, True, x[0], y[0], psi[0])
    kappa = np.empty(n)
    for i in range(n):
        _, _, _, kappa[i], seg = frenet_project(g, True, x[i], y[i], psi[i], seg)
    k = np.arange(1, n - 1)
    ax = (vx[k + 1] - vx[k - 1]) / (2 * dt) - vy[k] * r[k]
    ay = (vy[k + 1] - vy[k - 1]) / (2 * dt) + vx[k] * r[k]
    assert np.max(np.abs(ay)) > 5.0
    kin = np.array([lateral_deviation_acceleration(ax[i], ay[i], vx[j], vy[j], ey[j], epsi[j],
                                                   kappa[j]) for i, j in enumerate(k)])
    fd = (ey[k + 1] - 2.0 * ey[k] + ey[k - 1]) / dt**2
    assert np.max(np.abs(kin - fd)) < 0.03
    engine = meas[1:n - 1, MEAS.EY_DDOT]
    assert np.all(np.isfinite(engine))
    assert np.max(np.abs(engine - fd)) < 0.05
    assert math.isnan(meas[0, MEAS.EY_DDOT])  # no previous velocity at the first step


def _imu(**kw) -> MfcNaturalSettings:
    return MfcNaturalSettings(estimator_lat="imu", yaw_damping=0.0, wn_lat_speed=0.0, **kw)


def test_imu_law_is_exact_on_a_parabola():
    """e_y = c t^2 measured exactly with e_y'' = 2c and a constant applied steer u0: the
    observer's predictions are exact on quadratics (no correction), the filtered e_y'' and
    steer are constants, so the steer is the iPD law with the true F = 2c - alpha u0, e and e'
    to rounding: u = -(F + kp e + kd e') / alpha."""
    s = _imu()
    c = NaturalOutputController(dt=0.001, actuators=_ACT, settings=s)
    c.reset(steer0=0.01)
    cc, u0, dt = 0.01, 0.01, 0.001
    kp, kd = s.wn_lat**2, 2.0 * s.zeta_lat * s.wn_lat
    got, want = [], []
    for i in range(400):
        t = i * dt
        out = c.step(vx=20.0, r=0.0, e_y=cc * t * t, kappa=0.0, vx_ref=20.0,
                     applied_steer=u0, e_y_ddot=2.0 * cc)[1]
        if i >= s.window_lat:  # the window is full: the law acts
            got.append(out)
            want.append(-(2.0 * cc - s.alpha_lat * u0 + kp * cc * t * t + kd * 2.0 * cc * t)
                        / s.alpha_lat)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_imu_without_acceleration_is_the_algebraic_controller():
    """With no e_y'' (NaN: a sensor fault, or no inertial unit) the imu controller returns
    the algebraic controller's steer bit for bit; given e_y'', it acts on it."""
    alg = NaturalOutputController(dt=0.001, actuators=_ACT, settings=MfcNaturalSettings(
        yaw_damping=0.0, wn_lat_speed=0.0))
    imu = NaturalOutputController(dt=0.001, actuators=_ACT, settings=_imu())
    alg.reset(steer0=0.02)
    imu.reset(steer0=0.02)
    same, differ = [], []
    for i in range(600):
        t = i * 0.001
        e_y = 0.05 * math.sin(3.0 * t)
        kw = {"vx": 20.0, "r": 0.0, "e_y": e_y, "kappa": 0.0, "vx_ref": 20.0}
        a = alg.step(**kw)
        if i < 300:
            same.append((a, imu.step(**kw)))
        else:
            differ.append((a[1], imu.step(**kw, e_y_ddot=-0.45 * math.sin(3.0 * t))[1]))
    assert all(a == b for a, b in same)
    assert max(abs(a - b) for a, b in differ) > 1e-3


@pytest.mark.parametrize("channel", ["ay", "y"])
def test_imu_survives_a_blanked_channel(channel):
    """A measurement that goes NaN for 50 ms in the middle of a corner (the hairpin, 4.5 s):
    the step falls back to the algebraic estimate, the observer restarts after it; the run
    completes with finite numbers, identical to the clean run before the fault and within
    1 cm of it after, half the lateral target (measured: 3.7 mm with ay blanked, 5.0 mm with
    y blanked; during the blank the algebraic fallback predicts e_y with the observer's e_y',
    which the iPD's window state holds since intelligent_step_external. The y case read
    1.4 mm before the gap's end was bridged (2.8 mm after it) and the yaw damper kept live
    through the hold (5.0 mm): in `paper`'s trace there the clean run takes 1 deg of steer off
    within the 50 ms, which a held steer cannot; over 29 gaps of 50 ms along Norisring the
    same code deviates from the clean run by 0.9 mm at the median, 3.6 mm at most,
    benchmarks/README.md "A user's audit of the gap handling")."""
    clean = simulate(named_scenario("paper-imu", duration_s=8.0))
    sc = named_scenario("paper-imu", duration_s=8.0).with_(
        faults=(Fault(kind="nan_measurement", channel=channel, t_start_s=4.5,
                      duration_s=0.05),))
    tr = simulate(sc)
    m = compute_metrics(tr)
    assert m.status == "completed"
    assert all(np.all(np.isfinite(tr[k])) for k in ("x", "y", "vx", "steer", "torque"))
    before = tr.time < 4.5
    np.testing.assert_array_equal(tr["lateral_error"][before], clean["lateral_error"][before])
    gap = np.max(np.abs(tr["lateral_error"] - clean["lateral_error"]))
    assert 0.0 < gap < 0.01


def test_imu_settings_refuse_bad_values():
    with pytest.raises(ValueError, match="estimator_lat"):
        MfcNaturalSettings(estimator_lat="kalman")
    with pytest.raises(ValueError, match="imu_filter_s"):
        MfcNaturalSettings(imu_filter_s=0.0)
    with pytest.raises(ValueError, match="observer_wn"):
        MfcNaturalSettings(observer_wn=-1.0)


def test_own_loop_example_runs_and_tracks():
    """examples/own_loop.py, the documented reset()/step() use in a user's own loop (the
    10DoF model stepped from Python, flatfree's actuator model as the car's actuators): both
    estimators hold the first 3 s of Norisring (measured: 1.03 cm algebraic, 0.029 cm imu). The
    imu bound, 0.1 cm, is 3.4x its measured figure (it was 0.5 cm, 17x); the algebraic one is
    the issue's 2 cm."""
    from conftest import load_script

    mod = load_script("examples/own_loop.py")
    alg = mod.run(MfcNaturalSettings(), 3.0)
    imu = mod.run(_imu(), 3.0)
    assert alg["max_lateral_m"] < 0.02 and imu["max_lateral_m"] < 0.001
    assert imu["max_lateral_m"] < alg["max_lateral_m"]


@pytest.mark.parametrize("fault", [
    Fault(kind="nan_measurement", channel="ax", t_start_s=2.0, duration_s=0.05),
    Fault(kind="steer_limit", t_start_s=1.5, duration_s=1.0, value=0.005),
    None,  # mu 0.5 on the first 80 m
])
def test_imu_faults_end_with_a_status_and_finite_numbers(fault):
    """The issue's faults on the gentler test scenario of tests/test_simulation.py (3 m/s^2
    lateral, 4 s) with the imu estimator: a status, finite numbers, the steer limit held."""
    from flatfree.scenario import FrictionPatch, RoadSpec
    from flatfree.scenarios import IMU_SETTINGS, REALISTIC_SENSORS

    sc = Scenario(plant="10dof", controller="mfc-natural", controller_settings=IMU_SETTINGS,
                  reference=ReferenceSpec(track="Norisring", a_lat_max=3.0),
                  timing=Timing(duration_s=4.0), sensors=REALISTIC_SENSORS, seed=1)
    if fault is None:
        sc = sc.with_(road=RoadSpec(mu=1.0, patches=(FrictionPatch(s_start_m=0.0, s_end_m=80.0,
                                                                     mu=0.5),)))
    else:
        sc = sc.with_(faults=(fault,))
    tr = simulate(sc)
    assert isinstance(tr.status, Status)
    assert all(np.all(np.isfinite(tr[k])) for k in ("x", "y", "vx", "e_y", "steer", "torque"))
    if fault is not None and fault.kind == "steer_limit":
        window = (tr.time >= 1.5) & (tr.time < 2.5)
        assert np.all(np.abs(tr["steer"][window]) <= 0.005 + 1e-12)


@pytest.mark.parametrize("bias_wn", [0.0, 5.0])
def test_accelerometer_bias_offset_and_its_observer_state(bias_wn):
    """e_y = c t^2 measured exactly, e_y'' with a constant bias b. Without a bias state the
    discrete observer settles at e-error (1 - 2 wo dt) b / wo^2 and e'-error 2 b / wo - b dt / 2
    (derived from its predict / correct steps) and F at +b, so the steer is off by
    -(b + kp (1 - 2 wo dt) b / wo^2 + kd (2 b / wo - b dt / 2)) / alpha; with the bias state
    (``observer_bias_wn`` > 0) the offset vanishes (integral action on the innovation).

    Measured residual against the closed form after 5 s: 5.0e-16 without the bias state
    (rounding: tolerance 1e-14), 1.06e-12 with it (the bias state's transient, still decaying:
    tolerance 1e-11, ~10x)."""
    s = _imu(observer_bias_wn=bias_wn)
    c = NaturalOutputController(dt=0.001, actuators=_ACT, settings=s)
    c.reset(steer0=0.01)
    cc, u0, dt, b = 0.001, 0.01, 0.001, 0.3  # e_y 2.5 cm at 5 s: the steer stays in range
    kp, kd, wo = s.wn_lat**2, 2.0 * s.zeta_lat * s.wn_lat, s.observer_wn
    for i in range(5000):
        t = i * dt
        out = c.step(vx=20.0, r=0.0, e_y=cc * t * t, kappa=0.0, vx_ref=20.0,
                     applied_steer=u0, e_y_ddot=2.0 * cc + b)[1]
    exact = -(2.0 * cc - s.alpha_lat * u0 + kp * cc * t * t + kd * 2.0 * cc * t) / s.alpha_lat
    offset = 0.0 if bias_wn > 0.0 else -(b + kp * (1.0 - 2.0 * wo * dt) * b / wo**2
                                         + kd * (2.0 * b / wo - 0.5 * b * dt)) / s.alpha_lat
    assert abs(offset) > 0.01 or bias_wn > 0.0  # the effect is not small
    assert out - exact == pytest.approx(offset, abs=1e-11 if bias_wn > 0.0 else 1e-14)


def test_imu_holds_a_lap_at_a_100_hz_control_rate():
    """A typical ROS 2 loop rate: the controller at 100 Hz (sensors sampled there, windows and
    denoisers rescaled to their 1 kHz durations: Scenario.with_control_period), plant at
    1 kHz: a whole noisy Norisring lap within the issue's 2 cm (measured 0.77 cm, the worst
    of seeds 0-2, benchmarks/control_period.py, session 16; the algebraic estimator leaves the
    track at this rate)."""
    m = compute_metrics(simulate(named_scenario("paper-imu").with_control_period(0.01)))
    assert m.status == "completed"
    assert m.lateral_error_max_m < 0.02


def test_the_loop_forms_ey_ddot_only_for_controllers_that_read_it():
    from flatfree.controllers.vehicle import (
        KIND,
        FlatnessSettings,
        build_flatness,
        build_mfc,
        wants_ey_ddot,
    )
    from flatfree.models.bicycle3dof import Bicycle3DoFParams

    def arrays(settings):
        return build_mfc("mfc-natural", settings, dt=0.001, actuators=_ACT)

    alg = arrays(MfcNaturalSettings())
    imu = arrays(_imu())
    flat = build_flatness(FlatnessSettings(), dt=0.001, model=Bicycle3DoFParams.from_vehicle(
        load_vehicle("peugeot406")))
    assert wants_ey_ddot(imu.kind, imu.coef)
    assert not wants_ey_ddot(alg.kind, alg.coef)
    assert not wants_ey_ddot(flat.kind, flat.coef)
    assert wants_ey_ddot(int(KIND.PYTHON), np.zeros(14))
