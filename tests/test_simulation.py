"""The closed-loop engine: determinism, seeding, faults and statuses (never an exception), the
path schedule, the Python-controller door, the flatness wiring and the yaw damper's law.

Whole-lap tracking figures of the paper's controllers are in tests/test_paper_scenarios.py;
these tests check the engine's contracts on short runs.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

from flatfree.metrics import compute_metrics
from flatfree.scenario import Fault, FrictionPatch, ReferenceSpec, RoadSpec, Scenario, Timing
from flatfree.scenarios import REALISTIC_SENSORS
from flatfree.simulation import simulate
from flatfree.trajectory import Status, Trajectory

# the paper scenarios' sensors (flatfree.scenarios documents each sigma; the first version here
# had 1 cm of white position noise at 1 kHz, far noisier than an RTK-INS's sample jitter)
NOISY = REALISTIC_SENSORS


def _scenario(**kw) -> Scenario:
    base = dict(plant="10dof", controller="mfc-natural",
                reference=ReferenceSpec(track="Norisring", a_lat_max=3.0),
                timing=Timing(duration_s=4.0, log_dt_s=0.01), sensors=NOISY, seed=1)
    base.update(kw)
    return Scenario(**base)


def _finite(tr) -> bool:
    return all(np.all(np.isfinite(tr[k])) for k in ("x", "y", "vx", "e_y", "steer", "torque"))


def test_same_seed_bit_identical_other_seed_different():
    a = simulate(_scenario())
    b = simulate(_scenario())
    assert a.status is Status.COMPLETED and len(a) == 400
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    c = simulate(_scenario(seed=2))
    assert not np.array_equal(a["meas_vx"], c["meas_vx"])
    # the noise is what differs: the measured speed error's spread is the sensor's sigma
    dv = a["meas_vx"][1:] - a["vx"][1:]
    sigma = NOISY.channels["vx"].noise_std
    assert np.std(dv) == pytest.approx(sigma, rel=0.2)  # 400 samples: sampling spread ~4 %


def test_a_shorter_run_is_the_start_of_a_longer_one():
    """The noise is drawn per channel in time order (sensors module docstring): the same
    scenario and seed run for 2 s gives the first 2 s of the 4 s run bit for bit (the noise used
    to be drawn over the run's allotted length, so a run's length changed its noise)."""
    from flatfree.scenarios import IMU_SETTINGS  # the lateral F from the accelerometer

    imu = {"controller_settings": IMU_SETTINGS}
    a = simulate(_scenario(**imu))
    b = simulate(_scenario(**imu, timing=Timing(duration_s=2.0, log_dt_s=0.01)))
    assert len(b) == 200 and b.status is Status.COMPLETED
    for k in a:
        np.testing.assert_array_equal(a[k][:200], b[k], err_msg=k)


def test_a_rough_reference_is_warned_about():
    """Norisring's race line has a kink at 106 m that the default profile takes at 50 m/s
    (steady lateral jerk 34.7 m/s^3, above simulation.ROUGH_JERK = 25): the natural-output
    design spins off, noise-free (`paper`'s settings: at 9.28 s, 5 m off the line from ~5 s;
    session 21's and the controller's defaults at 4.45-4.47 s, `paper-imu` at 4.48 s), and the
    run warns first, naming the jerk, where,
    and reference.j_lat_max; capped at 15 m/s^3 it neither warns nor leaves; with a Python
    controller the warning is not given. No bundled reference of the default profile warns
    (their largest: 20.9 m/s^3)."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import ROUGH_JERK, prepare

    assert ROUGH_JERK == 25.0
    sc = named_scenario("paper-noise-free", duration_s=12.0).with_settings(
        ["reference.line=raceline"])
    with pytest.warns(UserWarning, match=r"^the path may be too rough for the natural-output "
                                         r"controller: .* steady lateral jerk v\^3 \|dkappa/ds\| "
                                         r"of 34\.7 m/s\^3 at s = 106 m \(50\.0 m/s\), above 25 "
                                         r"m/s\^3, .*--set reference\.j_lat_max=15\) caps it$"):
        tr = simulate(sc)
    assert tr.status is Status.LEFT_TRACK and 4.0 < tr.status_time < 12.0
    with warnings.catch_warnings():  # a Python controller: nothing said about the built-in one
        warnings.simplefilter("error")
        prepare(sc, python_controller=object())
    capped = sc.with_settings(["reference.j_lat_max=15"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tr = simulate(capped)
    assert tr.status is Status.COMPLETED
    from flatfree.tracks import raceline_names, track_names

    for track in track_names():
        for line in ("centerline", "raceline") if track in raceline_names() else ("centerline",):
            with warnings.catch_warnings(record=True) as got:
                warnings.simplefilter("always")
                prepare(named_scenario("paper", track=track).with_settings(
                    [f"reference.line={line}"]))
            jerk = [str(w.message) for w in got if "lateral jerk" in str(w.message)]
            assert bool(jerk) == (track == "Norisring" and line == "raceline"), (track, line)


def test_noise_switch_gives_exact_measurements():
    tr = simulate(_scenario(noise=False))
    np.testing.assert_array_equal(tr["meas_vx"], tr["vx"])


def test_metrics_of_a_short_gentle_run():
    """A gentle profile (3 m/s^2 lateral) on the 10DoF plant with noise: the loop tracks.

    Measured with the default settings (2026-11-22): max lateral error 5.3 / 6.1 / 6.7 mm for
    seeds 1 / 2 / 3 (the start: hard braking from 37.6 m/s into the first corner). The bound,
    2 cm, is the issue's target; the whole-lap figures are in tests/paper_scenario_bounds.json.
    """
    m = compute_metrics(simulate(_scenario()))
    assert m.status == "completed"
    assert m.lateral_error_max_m < 0.02
    assert math.isfinite(m.real_time_factor) and m.real_time_factor > 0


def test_the_real_time_factor_leaves_out_the_compiler(tmp_path):
    """A cold numba cache (a fresh clone) compiles the loop for seconds on its first run: that
    happens before the clock starts, and the timed run compiles nothing (a fresh interpreter
    with an empty cache directory, so the compilation really happens there): the first call
    adds exactly the one signature it compiles before timing, the second none, and the timed
    run takes a small part of the compile time (with the compiler inside the clock it would take
    all of it: measured 0.6 ms against 12.7 s of compiling, cold)."""
    code = ("import json\n"
            "from flatfree import simulation\n"
            "from flatfree.scenarios import named_scenario\n"
            "out = []\n"
            "for _ in range(2):\n"
            "    n0 = len(simulation._closed_loop.signatures)\n"
            "    m = simulation.simulate(named_scenario('paper-noise-free', duration_s=0.2)).meta\n"
            "    out.append([len(simulation._closed_loop.signatures) - n0, m['compile_time_s'],"
            " m['real_time_factor'], m['wall_time_s']])\n"
            "print(json.dumps(out))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True)
    first, second = json.loads(out.stdout.strip().splitlines()[-1])
    assert first[0] == 1 and second[0] == 0
    assert first[1] > 0.0 and first[2] > 0.0
    assert first[3] < 0.1 * first[1], first  # the compiling is outside wall_time_s


def test_a_run_too_long_for_the_memory_is_a_value_error():
    """The clock schedule keeps any duration: one that cannot be allocated is refused by name
    (numpy's MemoryError before), as a RunTooLongError (a ValueError) the CLI recognises."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import RunTooLongError

    assert issubclass(RunTooLongError, ValueError)
    sc = named_scenario("paper-noise-free")
    sc = sc.with_(controller_settings={**sc.controller_settings, "schedule": "time"},
                  timing=Timing(duration_s=1e9))
    with pytest.raises(RunTooLongError, match=r"^timing\.duration_s = 1e\+09 s: the run's "
                                              r"log, allocated for the whole duration, does "
                                              r"not fit in memory \(.+\)$"):
        simulate(sc)


@pytest.mark.parametrize("channel", ["x", "vx"])
def test_a_measurement_that_goes_nan_for_50_ms_is_survived(channel):
    """The measured channel is NaN exactly in its window (the logged measurement says so), the
    run before it is the fault-free run bit for bit, the loop completes with the healthy run's
    accuracy (the gentle run's 2 cm), and without a pose the schedule runs on with the clock."""
    t0, t1 = 2.0, 2.05
    fault = Fault(kind="nan_measurement", channel=channel, t_start_s=t0, duration_s=t1 - t0)
    timing = Timing(duration_s=4.0, log_dt_s=0.001)
    ok = simulate(_scenario(timing=timing))
    tr = simulate(_scenario(timing=timing, faults=(fault,)))
    assert tr.status is Status.COMPLETED and _finite(tr)
    assert compute_metrics(tr).lateral_error_max_m < 0.02
    inside = (tr.time >= t0 - 1e-9) & (tr.time < t1 - 1e-9)
    assert inside.sum() == 50
    signal = "meas_e_y" if channel == "x" else "meas_vx"
    assert np.all(np.isnan(tr[signal][inside]))
    assert np.all(np.isfinite(tr[signal][~inside]))
    before = tr.time < t0 - 1e-9
    for k in tr:
        np.testing.assert_array_equal(tr[k][before], ok[k][before], err_msg=k)
    if channel == "x":  # no measured pose: the reference time advances with the clock
        np.testing.assert_allclose(np.diff(tr["t_ref"][inside]), 0.001, rtol=0, atol=1e-12)
    else:  # the pose is still measured
        assert np.all(np.isfinite(tr["meas_e_y"]))


@pytest.mark.parametrize(("name", "bound_m"), [("paper", 0.02), ("paper-imu", 0.01)])
def test_a_0_1_s_gap_in_the_position_costs_centimetres_not_the_car(name, bound_m):
    """Norisring's paper scenario, the position NaN for 0.1 s from 12 s, in a corner: the run
    completes within the lateral target, seed 0 run here: 1.30 cm and 0.67 cm (seeds 0-9 with
    session 26's gap handling: 1.30-2.56 cm, 2 of 10 above 2 cm, and 0.64-0.68 cm; at 1ed7df4
    1.28-3.65 cm and 0.65-0.76 cm, when this bound was 3 cm). It left the track at ~15 s
    (seed 0; both designs) while the held steer integrated the yaw damper's term (session 14,
    vehicle_step)."""
    from flatfree.scenarios import named_scenario

    sc = named_scenario(name, duration_s=16.0)
    gap = Fault(kind="nan_measurement", channel="y", t_start_s=12.0, duration_s=0.1)
    tr = simulate(sc.with_(faults=(gap,)))
    assert tr.status is Status.COMPLETED and _finite(tr)
    assert compute_metrics(tr).lateral_error_max_m < bound_m


def test_a_steer_limit_that_binds_for_1_s_is_survived():
    """A 0.005 rad steer limit for 1 s from t = 1.5 s, through the braking into the first corner:
    the applied steer is within it (and at it: the limit binds), the run completes."""
    lock = Fault(kind="steer_limit", t_start_s=1.5, duration_s=1.0, value=0.005)
    tr = simulate(_scenario(faults=(lock,)))
    assert tr.status is Status.COMPLETED and _finite(tr)
    window = (tr.time >= 1.5) & (tr.time < 2.5)
    assert np.max(np.abs(tr["steer"][window])) == pytest.approx(0.005, abs=1e-12)
    assert np.max(np.abs(tr["steer"][~window])) > 0.005


def test_a_steer_limit_is_reached_at_the_steering_rate_limit():
    """A limit of 0 rad from the moment of the largest steer of `paper`'s first 6 s (about
    0.07 rad): the wheels are driven in at the actuator's rate limit (0.4 rad/s), not clamped
    at once (which moved them at ~70 rad/s in one plant step), then held at the limit until the
    fault ends."""
    from flatfree.actuators import ActuatorParams
    from flatfree.scenarios import named_scenario
    from flatfree.vehicles import load_vehicle

    sc = named_scenario("paper", duration_s=6.0).with_(
        timing=Timing(duration_s=6.0, log_dt_s=0.001))
    free = simulate(sc)
    w = (free.time >= 2.0) & (free.time < 5.0)
    k = int(np.flatnonzero(w)[np.argmax(np.abs(free["steer"][w]))])
    t0, d0 = float(free.time[k]), float(free["steer"][k])
    assert abs(d0) > 0.03
    tr = simulate(sc.with_(faults=(Fault(kind="steer_limit", t_start_s=t0, duration_s=0.5,
                                         value=0.0),)))
    rate = ActuatorParams.from_vehicle(load_vehicle("peugeot406")).max_steer_rate
    steer, t = tr["steer"], tr.time
    assert np.max(np.abs(np.diff(steer)) / np.diff(t)) <= rate * (1.0 + 1e-9)
    reach = t0 + abs(d0) / rate + 0.002  # the ramp in, within two plant steps
    held = (t >= reach) & (t < t0 + 0.5)
    assert held.sum() > 200 and np.all(steer[held] == 0.0)
    ramp = (t >= t0) & (t < reach - 0.004)
    assert np.all(np.abs(steer[ramp]) > 0.0)  # not at the limit at once


def test_low_friction_patch_reaches_the_plant_and_the_run_ends_with_its_status():
    """mu 0.5 on the first 80 m, into which the mu = 1 profile brakes at 6 m/s^2 (more than
    0.5 g): the car slides off the track (left_track after the patch starts, finite numbers),
    where the same run without the patch completes. The front axle's friction is logged; the
    rear's is shown by a patch that only the rear wheels stand on at the start (the CoG at
    s = 0, the rear axle lr behind it on the closed track): the run differs from the first
    step while the front friction stays 1."""
    from flatfree.tracks import load_track
    from flatfree.vehicles import load_vehicle

    ten = Timing(duration_s=10.0, log_dt_s=0.01)
    clean = simulate(_scenario(timing=ten))
    assert clean.status is Status.COMPLETED
    patch = FrictionPatch(s_start_m=0.0, s_end_m=80.0, mu=0.5)
    tr = simulate(_scenario(timing=ten, road=RoadSpec(mu=1.0, patches=(patch,))))
    assert tr.status is Status.LEFT_TRACK and _finite(tr)
    assert 1.0 < tr.status_time < 10.0
    on = tr["s"] + load_vehicle("peugeot406").lf < 80.0  # the front axle on the patch
    assert on.any() and (~on).any()
    np.testing.assert_array_equal(tr["mu_front"], np.where(on, 0.5, 1.0))
    length = load_track("Norisring").length
    rear = FrictionPatch(s_start_m=length - 3.0, s_end_m=length, mu=0.2)
    short = Timing(duration_s=0.5, log_dt_s=0.001)
    a = simulate(_scenario(timing=short, noise=False))
    b = simulate(_scenario(timing=short, noise=False, road=RoadSpec(mu=1.0, patches=(rear,))))
    assert a["s"][0] == 0.0 and np.all(b["mu_front"] == 1.0)
    assert a["vx"][1] != b["vx"][1]


def test_leaving_the_track_is_a_status_not_an_exception():
    """The steering locked straight (a steer_limit fault of 0 rad) through the first corners: the
    car must leave the track; the run ends with that status and its time, without raising, when
    |e_y| passes the width on its own side of the path: the last logged sample (1 ms) is within
    one step's travel of it."""
    from flatfree.tracks import load_track

    lock = Fault(kind="steer_limit", t_start_s=0.0, duration_s=20.0, value=0.0)
    sc = _scenario(faults=(lock,), timing=Timing(duration_s=20.0, log_dt_s=0.001))
    tr = simulate(sc)
    assert tr.status is Status.LEFT_TRACK
    assert tr.status_time is not None and tr.status_time < 20.0
    assert tr.status_time == pytest.approx(tr.time[-1] + 0.001, abs=1e-9)
    assert compute_metrics(tr).status == tr.status.value
    assert _finite(tr)
    e_y = tr["e_y"]
    side = "w_left" if e_y[-1] > 0 else "w_right"
    width = float(load_track("Norisring").at(tr["s"][-1])[side][0])
    step = abs(e_y[-1] - e_y[-2])
    assert 0.0 <= width - abs(e_y[-1]) <= 1.5 * step


def test_a_path_without_widths_is_left_at_the_default_half_width():
    """The recording's path has no widths: the run leaves at DEFAULT_HALF_WIDTH_M."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import DEFAULT_HALF_WIDTH_M

    sc = named_scenario("recorded-noise-free", duration_s=30.0)
    lock = Fault(kind="steer_limit", t_start_s=0.0, duration_s=30.0, value=0.0)
    tr = simulate(sc.with_(faults=(lock,), timing=Timing(duration_s=30.0, log_dt_s=0.001)))
    assert tr.status is Status.LEFT_TRACK
    step = abs(tr["e_y"][-1] - tr["e_y"][-2])
    assert 0.0 <= DEFAULT_HALF_WIDTH_M - abs(tr["e_y"][-1]) <= 1.5 * step


def test_a_state_that_goes_non_finite_ends_the_run_with_that_status():
    """A suspension spring of 1e100 N/m makes the first RK4 step overflow: the run stops with
    non_finite at that step's time, the rows logged before it finite, and metrics of no sample.
    It does so also when that step is the run's last (the loop checks the final state too)."""
    from flatfree.scenarios import named_scenario

    stiff = named_scenario("paper-noise-free").with_(vehicle_overrides={"spring_front": 1e100})
    for duration in (0.05, 0.001):
        sc = stiff.with_(timing=Timing(duration_s=duration, log_dt_s=0.001))
        tr = simulate(sc)
        assert tr.status is Status.NON_FINITE, duration
        assert tr.status_time == pytest.approx(0.001, abs=1e-12)
        assert len(tr) == 1 and _finite(tr)
        with pytest.warns(RuntimeWarning, match="one sample only"):  # (no rate of one sample)
            m = compute_metrics(tr, startup_s=0.0)
        assert m.status == "non_finite"


@pytest.mark.parametrize("name", ["paper", "recorded"])
def test_reference_of_is_the_reference_prepare_builds(name):
    """reference_of(sc) (the reference alone, read after a run) is prepare(sc).reference, bit for
    bit, with the vehicle's overrides (a drive limit that depends on them)."""
    from flatfree.scenario import scenario_with_settings
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare, reference_of

    sc = named_scenario(name, duration_s=5.0)
    if name == "paper":
        sc = scenario_with_settings(sc, {"reference.drive_limit": True,
                                         "vehicle_overrides.max_power": 60e3})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = prepare(sc).reference
    b = reference_of(sc)
    for k in ("t", "s_path", "x", "y", "vx", "kappa"):
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    if name == "paper":  # the override acts: the 60 kW car's reference is slower
        assert reference_of(named_scenario(name))["vx"].max() > b["vx"].max() + 1.0


def test_simulate_prepared_is_simulate_and_leaves_prep_as_built():
    """simulate_prepared(prepare(sc)) is simulate(sc) bit for bit (noise, faults' NaN too), and
    runs on copies of prep's controller arrays: a second run of the same prep is the same
    trajectory; a Python controller must be the one prepare() was given."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare, simulate_prepared

    sc = named_scenario("paper", duration_s=3.0)
    ref = simulate(sc).to_columns()
    prep = prepare(sc)
    state = [a.copy() for a in (prep.controller.s_lon, prep.controller.s_lat)]
    for _ in range(2):
        got = simulate_prepared(prep).to_columns()
        assert got.keys() == ref.keys()
        for k in ref:
            np.testing.assert_array_equal(got[k], ref[k], err_msg=k)
    np.testing.assert_array_equal(prep.controller.s_lon, state[0])
    np.testing.assert_array_equal(prep.controller.s_lat, state[1])

    class Hold:
        def step(self, t, measurement, reference, applied):
            return 0.0, 0.0

    with pytest.raises(ValueError, match="same Python controller"):
        simulate_prepared(prep, Hold())
    with pytest.raises(ValueError, match="same Python controller"):
        simulate_prepared(prepare(sc, python_controller=Hold()))
    with pytest.raises(ValueError, match=r"prep = 'paper': expected a Prepared"):
        simulate_prepared("paper")


def test_path_schedule_reads_the_reference_at_the_measured_arc_length():
    """With exact sensors the controller's reference time is the reference's time at the car's
    own arc length (the loop's compiled interpolation vs np.interp: rounding only)."""
    from flatfree.simulation import prepare

    sc = _scenario(noise=False, timing=Timing(duration_s=6.0, log_dt_s=0.01))
    tr = simulate(sc)
    ref = prepare(sc).reference
    expected = np.interp(tr["s"], ref["s_path"], ref["t"])
    np.testing.assert_allclose(tr["t_ref"], expected, rtol=0, atol=1e-9)
    # and vx_ref is the profile at that time, not at the clock
    np.testing.assert_allclose(tr["vx_ref"], np.interp(expected, ref["t"], ref["vx"]),
                               rtol=0, atol=1e-9)
    clock = _scenario(noise=False, timing=Timing(duration_s=6.0, log_dt_s=0.01),
                      controller_settings={"schedule": "time"})
    np.testing.assert_allclose(simulate(clock)["t_ref"], tr.time, rtol=0, atol=1e-12)


def test_yaw_damper_term_is_minus_k_r_times_r_minus_vx_kappa():
    """With the iPD's law running (its window full), the steer of a damped controller minus an
    undamped one's, both fed the same measurements and applied steer, is the damper's term
    -k_r (r - vx kappa), to rounding; while the window fills (the iPD holds its start value,
    0) the damper adds nothing (vehicle_step: a held steer holds the last damper term)."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import CREF, MEAS, MfcNaturalSettings, build_mfc, vehicle_step
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    damped, plain = (build_mfc("mfc-natural", MfcNaturalSettings(yaw_damping=k, denoise_yaw=0),
                               dt=0.001, actuators=act) for k in (0.3, 0.0))
    meas = np.zeros(len(MEAS))
    meas[MEAS.VX], meas[MEAS.R], meas[MEAS.E_Y] = 20.0, 0.25, 0.01
    cref = np.zeros(len(CREF))
    cref[CREF.VX], cref[CREF.KAPPA] = 20.0, 0.01
    window = MfcNaturalSettings().window_lat
    for k in range(window + 5):
        steers = [vehicle_step(c.kind, c.p_lon, c.s_lon, c.p_lat, c.s_lat, c.coef, c.f_lon,
                               c.f_lat, c.f_yaw, meas, cref, 0.0, 0.0)[1] for c in (damped, plain)]
        if k < window - 1:
            assert steers == [0.0, 0.0]
        else:
            assert steers[0] - steers[1] == pytest.approx(-0.3 * (0.25 - 20.0 * 0.01), rel=1e-12)


def _natural_step(c, vx: float) -> float:
    from flatfree.controllers.vehicle import CREF, MEAS, vehicle_step

    meas = np.zeros(len(MEAS))
    meas[MEAS.VX] = vx
    cref = np.zeros(len(CREF))
    cref[CREF.VX] = vx
    _, delta = vehicle_step(c.kind, c.p_lon, c.s_lon, c.p_lat, c.s_lat, c.coef, c.f_lon, c.f_lat,
                            c.f_yaw, meas, cref, math.nan, math.nan)
    return delta


def test_lateral_gains_follow_the_speed_schedule():
    """kp = wn^2, kd = 2 zeta wn with wn = wn_lat min(max(v_s / Vx, 1), ratio) at the measured
    speed (MfcNaturalSettings.wn_lat_speed); 0 switches the schedule off."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.intelligent import IPAR
    from flatfree.controllers.vehicle import MfcNaturalSettings, build_mfc
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    st = MfcNaturalSettings(wn_lat=8.0, zeta_lat=0.8, wn_lat_speed=30.0, wn_lat_ratio=2.0)
    c = build_mfc("mfc-natural", st, dt=0.001, actuators=act)
    for vx, wn in ((45.0, 8.0), (30.0, 8.0), (20.0, 12.0), (15.0, 16.0), (6.0, 16.0)):
        _natural_step(c, vx)
        assert c.p_lat[IPAR.KP] == pytest.approx(wn * wn, rel=1e-14), vx
        assert c.p_lat[IPAR.KD] == pytest.approx(2.0 * 0.8 * wn, rel=1e-14), vx
    off = build_mfc("mfc-natural", MfcNaturalSettings(wn_lat=8.0, wn_lat_speed=0.0), dt=0.001,
                    actuators=act)
    _natural_step(off, 10.0)
    assert off.p_lat[IPAR.KP] == 64.0 and off.p_lat[IPAR.KD] == 16.0
    with pytest.raises(ValueError, match="wn_lat_speed"):
        MfcNaturalSettings(wn_lat_speed=-1.0)
    with pytest.raises(ValueError, match="wn_lat_ratio"):
        MfcNaturalSettings(wn_lat_ratio=0.5)


def test_controller_holds_and_run_starts_at_the_reference_steer(tmp_path):
    """The model-free controller holds ``steer0`` until its window is full, and a run starts
    with the actuator there: on a circle of radius 150 m the start is in the curve (steer0 of
    the order of wheelbase / radius, 18 mrad; the check asks for more than 10 mrad)."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import MfcNaturalSettings, build_mfc
    from flatfree.models.bicycle3dof import Bicycle3DoFParams
    from flatfree.simulation import prepare
    from flatfree.tracks import reference_states_3dof
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    c = build_mfc("mfc-natural", MfcNaturalSettings(yaw_damping=0.0), dt=0.001, actuators=act,
                  steer0=0.03)
    assert [_natural_step(c, 20.0) for _ in range(5)] == [0.03] * 5
    from flatfree.tracks import circle_track

    circle = circle_track(150.0).to_csv(tmp_path / "circle.csv")
    sc = _scenario(reference=ReferenceSpec(track=str(circle)), noise=False,
                   timing=Timing(duration_s=0.2, log_dt_s=0.001))
    prep = prepare(sc)
    bic = Bicycle3DoFParams.from_vehicle(prep.vehicle)
    lat = reference_states_3dof(prep.reference, cf=bic.cf, cr=bic.cr, mass=bic.m, iz=bic.iz,
                                lf=bic.lf, lr=bic.lr)
    assert prep.steer0 == float(lat.delta[0]) and abs(prep.steer0) > 1e-2
    tr = simulate(sc)
    assert tr["steer"][0] == prep.steer0


def test_flatness_runs_in_the_loop_and_plans_with_its_own_model():
    from flatfree.controllers.vehicle import CREF
    from flatfree.simulation import prepare

    exact = _scenario(controller="flatness", noise=False)
    mism = _scenario(controller="flatness", noise=False,
                     controller_settings={"cf_scale": 0.3, "cr_scale": 0.3})
    # the y2 reference (lf m vy_ref - Iz r_ref) comes from the controller's model (measured:
    # the two differ by 1.7x the exact one's range; 0.1 only asks that they differ materially)
    y2e = prepare(exact).cref[:, 1 + CREF.Y2]
    y2m = prepare(mism).cref[:, 1 + CREF.Y2]
    assert np.max(np.abs(y2e - y2m)) > 0.1 * np.max(np.abs(y2e))
    tr = simulate(exact)
    assert tr.status is Status.COMPLETED and _finite(tr)
    # exact model on a gentle profile: the speed loop (PI, poles -2, -3) tracks; measured
    # 0.0099 m/s RMS after 1 s while the reference brakes at up to 6 m/s^2 (an open speed loop
    # would be metres per second off): bound 2x that
    assert np.sqrt(np.mean((tr["vx"] - tr["vx_ref"])[100:] ** 2)) < 0.02


class _NaturalDoor:
    """The engine's built-in natural-output controller through its Python class
    (:class:`flatfree.controllers.vehicle.NaturalOutputController`, same compiled kernel)."""

    schedule = "path"

    def __init__(self, sc):
        from flatfree.actuators import ActuatorParams
        from flatfree.controllers.vehicle import NaturalOutputController, settings_from_mapping
        from flatfree.simulation import prepare
        from flatfree.vehicles import load_vehicle

        self.steer0 = prepare(sc).steer0
        self.calls = 0
        self.c = NaturalOutputController(
            dt=sc.timing.control_dt_s,
            actuators=ActuatorParams.from_vehicle(load_vehicle(sc.vehicle)),
            settings=settings_from_mapping("mfc-natural", sc.controller_settings))

    def reset(self):
        self.c.reset(steer0=self.steer0)

    def step(self, t, measurement, reference, applied):
        from flatfree.controllers.vehicle import CREF, MEAS

        self.calls += 1
        m, r = measurement, reference
        return self.c.step(vx=m[MEAS.VX], r=m[MEAS.R], e_y=m[MEAS.E_Y], kappa=r[CREF.KAPPA],
                           vx_ref=r[CREF.VX], ax_ref=r[CREF.AX], e_y_ref=r[CREF.EY],
                           e_y_ref_dot=r[CREF.EY_DOT], e_y_ref_ddot=r[CREF.EY_DDOT],
                           applied_torque=applied[0], applied_steer=applied[1],
                           e_y_ddot=m[MEAS.EY_DDOT])


@pytest.mark.parametrize("settings", [{}, {"estimator_lat": "imu", "yaw_damping": 0.2}],
                         ids=["algebraic", "imu"])
def test_python_controller_door_gives_the_compiled_result_bit_for_bit(settings):
    """The same kernel called from Python through the pausing loop, by the user-facing
    NaturalOutputController: identical trajectories (the engine, sensors, actuators and logging
    are shared; only the door differs). With the imu estimator this also checks that the
    measured e_y'' handed to Python (and the loop's velocity memory across the pauses) is the
    one the compiled controller sees."""
    sc = _scenario(timing=Timing(duration_s=1.5, log_dt_s=0.01), controller_settings=settings)
    ref_run = simulate(sc)
    wrapped = _NaturalDoor(sc)
    py_run = simulate(sc, controller=wrapped)
    assert wrapped.calls == 1500
    assert py_run.meta["controller"] == "python:_NaturalDoor"
    for k in ref_run:
        if k in ("f_lon", "f_lat"):  # controller internals: only the built-in door logs them
            continue
        np.testing.assert_array_equal(py_run[k], ref_run[k], err_msg=k)
    if settings:  # the imu estimator acted (it is not the algebraic controller's fallback)
        alg = simulate(_scenario(timing=Timing(duration_s=1.5, log_dt_s=0.01)))
        assert not np.array_equal(alg["steer"], ref_run["steer"])
    with pytest.raises(ValueError, match="step"):
        simulate(sc, controller=object())


def test_flying_lap_speed_matches_the_power_law_closed_form():
    """Drag, rolling resistance and the torque limit removed, the drive force is P / v, so
    v dv/ds = P / (m v) and v(s)^3 = v0^3 + 3 P s / m exactly. Heun's method in v^2 is second
    order: halving the 1 m step divides the error by ~4 (checked: 3 to 5); measured worst
    relative error 3.6e-5 on 1 m steps (at the first steps, 6.7 m/s^2 at 10 m/s), bound 2e-4
    (5x headroom); 4e-8 after the cap (30 m/s, gentler). The result never exceeds the
    reference, and a reference the car can hold comes back unchanged on a closed lap."""
    import dataclasses

    from flatfree.simulation import flying_lap_speed
    from flatfree.vehicles import load_vehicle

    veh = dataclasses.replace(load_vehicle("peugeot406"), drag_area=0.0,
                              rolling_resistance=0.0, max_drive_torque=1e9)
    s = np.arange(0.0, 2001.0, 1.0)
    v_ref = np.full_like(s, 200.0)
    v_ref[0] = 10.0
    v = flying_lap_speed(s, v_ref, veh, closed=False)
    exact = np.cbrt(10.0**3 + 3.0 * veh.max_power * s / veh.mass)
    np.testing.assert_allclose(v, exact, rtol=2e-4)
    err1 = np.max(np.abs(v / exact - 1.0))
    s_half = np.arange(0.0, 2000.5, 0.5)
    v_half_ref = np.full_like(s_half, 200.0)
    v_half_ref[0] = 10.0
    v_half = flying_lap_speed(s_half, v_half_ref, veh, closed=False)
    err_half = np.max(np.abs(v_half / np.cbrt(10.0**3 + 3.0 * veh.max_power * s_half
                                                / veh.mass) - 1.0))
    assert 3.0 < err1 / err_half < 5.0  # second order
    # a cap on the way: never above the reference, and power-limited again after it
    v_ref[1000:1100] = 30.0
    v2 = flying_lap_speed(s, v_ref, veh, closed=False)
    assert np.all(v2 <= v_ref)
    np.testing.assert_allclose(v2[1100:], np.cbrt(30.0**3 + 3.0 * veh.max_power
                                                  * (s[1100:] - s[1099]) / veh.mass), rtol=1e-6)
    # closed lap at a speed the real car holds (20 m/s: drag + rolling << 100 kW / 20 m/s)
    real = load_vehicle("peugeot406")
    np.testing.assert_array_equal(
        flying_lap_speed(s, np.full_like(s, 20.0), real, closed=True), 20.0)
    # the compiled integration reads both arrays point by point: mismatched or empty refused
    for bad_s, bad_v in ((s, v_ref[:-1]), (s[:0], v_ref[:0]), (s[None, :], v_ref[None, :])):
        with pytest.raises(ValueError, match="^s, v_ref: shapes"):
            flying_lap_speed(bad_s, bad_v, real, closed=True)


def test_lvms_oval_start_is_reachable_and_the_car_does_not_spin():
    """Regression (LVMS oval, peugeot406): the friction-only speed profile asks for 49.7 m/s at
    s = 0 (49.1 before the loop-closure artefact was bridged), where the 100 kW car arrives at
    44.7 m/s on a flying lap (measured: the end of a lap), at the start of a 6 m/s^2 braking
    into turn 1. Started at the profile's speed the car spun and left the track at 4.4 s
    (lateral error 7.5 m, yaw error 72 deg). The start speed is now the flying-lap speed (45.5
    m/s with drag and rolling resistance, no cornering drag: an upper estimate, hence the 1 m/s
    margin above the measured 44.7), and the first 15 s (through turn 1) complete with the
    default lap's accuracy: 1.2 cm max after the 1 s start-up (3.0-3.2 cm with the artefact's
    S-bend at the start line); bound 4 cm (the issue's 2x of the paper's 2 cm on every bundled
    track)."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import flying_lap_speed, prepare

    sc = named_scenario("paper-noise-free", track="LVMS", duration_s=15.0)
    prep = prepare(sc)
    assert prep.reference["vx"][0] == pytest.approx(49.66, abs=0.05)
    assert 44.0 < prep.x0[3] < 44.7 + 1.0
    # the flying lap closes on itself: the speed at the lap's end is the start speed
    v = flying_lap_speed(prep.reference["s_path"], prep.reference["vx"], prep.vehicle,
                         closed=True)
    assert v[-1] == pytest.approx(v[0], abs=1e-9 * v[0]) and v[0] == prep.x0[3]
    tr = simulate(sc)
    assert tr.status is Status.COMPLETED
    after = tr.time >= sc.timing.startup_s
    assert np.max(np.abs(tr["lateral_error"][after])) < 0.04
    assert np.max(np.abs(tr["vy"])) < 5.0  # the spin reached 23 m/s


@pytest.mark.parametrize("track", ["Norisring", "Spa"])
def test_reference_tables_at_10_ms_interpolate_like_1_ms_tables(track):
    """REFERENCE_DT_S (10 ms) tables, linearly interpolated as the loop does, against 1 ms tables
    over their common span, within the bounds of linear interpolation on a step h: h^2/8
    max|f''| for a smooth signal (position, heading, curvature; f'' from the 1 ms table's second
    differences, 1 % for that estimate), h/4 osc(f') on each interval for a signal with kinks
    (vx, whose slope ax jumps where the profile switches), and for ax itself, which jumps, the
    smaller of h^2/8 max|f''| and its oscillation on each interval. Measured (2026-11-22):
    position 7.5e-5 m, heading 1.3e-5 rad, curvature 2.0e-6 / 3.7e-6 1/m, each within 0.5 % of
    its bound; vx 0.016-0.019 m/s (bound 0.020-0.021); ax RMS 0.09 m/s^2 (bound 0.22)."""
    from flatfree.simulation import REFERENCE_DT_S
    from flatfree.tracks import load_track, make_reference

    tr = load_track(track)
    d, h = 0.001, REFERENCE_DT_S
    k = round(h / d)
    fine = make_reference(tr, dt=d)
    coarse = make_reference(tr, dt=h)
    m = fine["t"] <= coarse["t"][-1]
    t = fine["t"][m]
    n_int = (t.size - 1) // k
    row = np.minimum(np.arange(t.size) // k, n_int - 1)  # the coarse interval of each sample

    def err(q):
        return np.abs(np.interp(t, coarse["t"], coarse[q]) - fine[q][m])

    def f2max(*q):  # max |f''| (Euclidean over the components) from second differences
        return np.sqrt(sum((np.diff(fine[c][m], 2) / d**2) ** 2 for c in q)).max()

    def per_interval(q):  # (k + 1) fine samples of each coarse interval, ends included
        return np.lib.stride_tricks.sliding_window_view(fine[q][m], k + 1)[::k][:n_int]

    c2 = 1.01 * h * h / 8.0
    assert np.hypot(err("x"), err("y")).max() <= c2 * f2max("x", "y")
    assert err("psi").max() <= c2 * f2max("psi")
    assert err("kappa").max() <= c2 * f2max("kappa")
    ax = per_interval("ax")
    assert np.all(err("vx") <= 1.01 * h / 4.0 * np.ptp(ax, axis=1)[row] + 1e-12)
    bound = np.minimum(np.ptp(ax, axis=1),
                       c2 * np.abs(np.diff(ax, 2, axis=1)).max(axis=1) / d**2)[row]
    e_ax = err("ax")
    assert np.all(e_ax <= bound + 1e-12)  # and so its RMS within the bound's RMS


def test_drive_limit_plans_the_reference_the_car_can_drive():
    """reference.drive_limit: the run's reference is the power-aware profile of the scenario's
    car (tracks.speed_profile(vehicle=...)); off (default): the friction-only profile."""
    import dataclasses

    from flatfree.simulation import prepare
    from flatfree.tracks import load_track, speed_profile

    sc = _scenario(timing=Timing(duration_s=1.0, log_dt_s=0.01))
    on = sc.with_(reference=dataclasses.replace(sc.reference, drive_limit=True))
    v_on = prepare(on).reference["vx"]
    v_off = prepare(sc).reference["vx"]
    trk = load_track("Norisring")
    lim = dataclasses.replace(speed_profile(trk).limits, a_lat_max=3.0)  # _scenario's profile
    top_on = speed_profile(trk, lim, vehicle=prepare(on).vehicle).v.max()
    top_off = speed_profile(trk, lim).v.max()
    # the 10 ms time grid samples the profile: its maximum is at most the profile's top speed
    # and misses it by less than one sample at the largest deceleration (6 m/s^2 x 10 ms)
    for v, top in ((v_on, top_on), (v_off, top_off)):
        assert top - 0.06 < v.max() <= top + 1e-9
    assert top_on < top_off - 5.0  # the peugeot406 cannot reach the friction profile's


def test_natural_output_controller_holds_limits_and_refuses_bad_input():
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import MfcNaturalSettings, NaturalOutputController
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    c = NaturalOutputController(dt=0.001, actuators=act,
                                settings=MfcNaturalSettings(yaw_damping=0.0))
    c.reset(steer0=0.02, torque0=100.0)
    # before the windows are full the held inputs come back (the actuators' positions): the
    # first window - 1 = 99 steps (step's docstring), then the laws act
    held = [c.step(vx=20.0 + 0.01 * k, r=0.0, e_y=0.01, kappa=0.0, vx_ref=21.0)
            for k in range(100)]
    assert held[:99] == [(100.0, 0.02)] * 99
    assert held[99][0] != 100.0 and held[99][1] != 0.02
    # a 10 m step of lateral deviation: once the window is full the paper's law (no bound on
    # its correction) asks for more steer than the car has; the command reaches the
    # actuators' range and stays within it
    c = NaturalOutputController(dt=0.001, actuators=act, settings=MfcNaturalSettings(
        yaw_damping=0.0, correction_max=math.inf))
    c.reset(steer0=0.02, torque0=100.0)
    steers = [c.step(vx=20.0, r=0.0, e_y=10.0, kappa=0.0, vx_ref=20.0)[1] for _ in range(300)]
    assert max(abs(v) for v in steers) == act.max_steer
    with pytest.raises(ValueError, match="actuators = None"):
        NaturalOutputController(dt=0.001, actuators=None)
    with pytest.raises(ValueError, match=r"dt = 0\.0"):
        NaturalOutputController(dt=0.0, actuators=act)
    with pytest.raises(ValueError, match="steer0 = nan"):
        c.reset(steer0=math.nan)
    # the actuators' range: degrees given as radians, a torque beyond the brakes
    with pytest.raises(ValueError, match=r"steer0 = 5\.0 rad: must lie in \[-0\.6"):
        c.reset(steer0=5.0)
    with pytest.raises(ValueError, match=r"torque0 = -1000000\.0 N m: must lie in"):
        c.reset(torque0=-1e6)


def test_natural_output_controller_status_tells_a_held_steer_and_the_whole_f():
    """status.steer_held: the window's filling, a NaN e_y, the standstill hold; law steps not.
    f_lat is the lateral F of e_y'' = F + alpha delta: the iPD's own F without the curvature
    term, that F less vx^2 kappa (the term alpha * vx^2 kappa / alpha) with it."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import MfcNaturalSettings, NaturalOutputController
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    for curv in (False, True):
        settings = MfcNaturalSettings(curvature_term=curv, feed_applied=True)
        c = NaturalOutputController(dt=0.001, actuators=act, settings=settings)
        assert c.status.steer_held and c.status.lateral.samples == 0
        held = []
        for k in range(150):
            c.step(vx=20.0, r=0.1, e_y=0.01 + 1e-5 * k, kappa=0.005, vx_ref=20.0)
            held.append(c.status.steer_held)
        assert held == [True] * 99 + [False] * 51  # window_lat 100: the law from the 100th
        st = c.status
        term = 20.0**2 * 0.005 if curv else 0.0
        assert st.f_lat == pytest.approx(st.lateral.f_hat - term, rel=0, abs=1e-12)
        assert st.lateral.window_full and st.speed.window_full
        c.step(vx=20.0, r=0.1, e_y=math.nan, kappa=0.005, vx_ref=20.0)
        assert c.status.steer_held and c.status.lateral.nonfinite
        c.step(vx=0.5, r=0.0, e_y=0.01, kappa=0.005, vx_ref=20.0)  # below steer_min_speed
        assert c.status.steer_held and not c.status.lateral.nonfinite
        c.step(vx=20.0, r=0.1, e_y=0.01, kappa=0.005, vx_ref=20.0)
        assert not c.status.steer_held


def test_natural_output_controller_takes_a_nan_applied_value_as_unknown():
    """A lost feedback frame (NaN applied_steer / applied_torque) is the default's model of
    the actuators, bit for bit: not a third behaviour."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import NaturalOutputController
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))

    def run(applied):
        c = NaturalOutputController(dt=0.001, actuators=act)
        return [c.step(vx=20.0, r=0.01 * math.sin(0.01 * k), e_y=0.05 * math.cos(0.003 * k),
                       kappa=0.002, vx_ref=21.0, applied_steer=applied,
                       applied_torque=applied) for k in range(400)]

    none = run(None)
    assert run(math.nan) == none
    assert run(0.0) != none  # the applied values are used: the comparison can fail


def test_a_curve_beyond_the_steer_lock_is_warned_about():
    """The dallara_av21 (lock 0.279 rad, wheelbase 2.97 m) on Norisring, whose hairpin has a
    9.9 m radius (kinematic steer 0.30 rad): warned; the peugeot406 (0.6 rad) there and the
    dallara on LVMS (161 m): not."""
    import warnings

    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    with pytest.warns(UserWarning, match=r"radius 9\.9 m.*dallara_av21's max_steer = 0\.279"):
        prepare(named_scenario("paper", vehicle="dallara_av21"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prepare(named_scenario("paper"))
        prepare(named_scenario("paper", track="LVMS", vehicle="dallara_av21"))


def test_the_power_cap_counts_a_spinning_driven_wheel():
    """The engine's power goes to the driven wheels at their own speed: with the front wheels
    of the peugeot406 spinning on ice-like road (mu 0.3 over 30 m where the car leaves a corner
    under full power) the applied drive torque times the driveline's speed R_e (Omega_fl +
    Omega_fr) / 2 never exceeds P R_e. Capping at the body speed, as before 2026-11-22 (session
    5), let the front wheels spin up to 10x the road speed on average and take 10x the
    engine's power here (measured; now 2.5x the road speed, and the cap binds at 0.40 of the
    body-speed cap)."""
    from flatfree.actuators import V_POWER_MIN
    from flatfree.vehicles import load_vehicle

    veh = load_vehicle("peugeot406")
    ice = FrictionPatch(s_start_m=170.0, s_end_m=200.0, mu=0.3)
    tr = simulate(_scenario(road=RoadSpec(mu=1.0, patches=(ice,)), noise=False,
                            timing=Timing(duration_s=12.0, log_dt_s=0.001)))
    assert tr.status is Status.COMPLETED
    v_drive = veh.wheel_radius * 0.5 * (tr["omega_fl"] + tr["omega_fr"])
    p_re = veh.max_power * veh.wheel_radius
    drive = tr["torque"] > 0.0
    assert np.all(tr["torque"][drive] * np.maximum(v_drive[drive], V_POWER_MIN)
                  <= p_re * (1.0 + 1e-12))
    # the patch really spins the front wheels, and the cap then binds well below P R_e / vx
    spin = v_drive > 1.5 * tr["vx"]
    assert spin.any()
    capped = drive & (np.abs(tr["torque"] * v_drive - p_re) <= 1e-9 * p_re)
    assert np.min(tr["torque"][capped] * tr["vx"][capped] / p_re) < 0.5


def test_a_banked_road_reaches_the_plant_and_the_model_free_loop_holds_it():
    """road.bank_deg: the loop gives the 10DoF plant the bank at the car's arc length and its
    heading to the road. With the road's left side raised by 5 deg, gravity pulls the car across
    the road with m g sin(5 deg) = 1.28 kN; the model-free controller (which knows nothing of
    it) keeps the CoG on the path, so the car crabs: it yaws up the slope by the rear slip
    angle that holds the rear axle's share, (lf / L) m g sin b / C_r = 0.40 deg by the bicycle
    model at static loads (measured 0.57: the first corner's load transfer and the driven front
    tyres), its sideslip the same the other way (the course does not move). Mirrored for
    -5 deg. A profile flat until s = 1e6 m gives the flat road's run bit for bit (the bank is
    read along the path); the 3DoF plant has no bank input."""
    from flatfree.tires import cornering_stiffness
    from flatfree.units import G
    from flatfree.vehicles import load_vehicle

    vp = load_vehicle("peugeot406")
    flat = simulate(_scenario(noise=False))
    later = simulate(_scenario(noise=False, road=RoadSpec(bank_deg=((1e6, 0.0), (2e6, 5.0)))))
    for k in flat:
        np.testing.assert_array_equal(flat[k], later[k], err_msg=k)
    after = flat.time >= 1.0
    b = math.radians(5.0)
    c_r = 2.0 * cornering_stiffness(vp.tire_rear, 0.5 * vp.mass * G * vp.lf / vp.wheelbase
                                    * math.cos(b))
    crab = vp.lf / vp.wheelbase * vp.mass * G * math.sin(b) / c_r
    for sign in (1.0, -1.0):
        tilted = simulate(_scenario(noise=False, road=RoadSpec(bank_deg=((0.0, 5.0 * sign),))))
        assert tilted.status is Status.COMPLETED
        d_psi = np.mean(tilted["e_psi"][after] - flat["e_psi"][after])
        d_beta = np.mean(np.arctan2(tilted["vy"], tilted["vx"])[after]
                         - np.arctan2(flat["vy"], flat["vx"])[after])
        assert 0.5 * crab < sign * d_psi < 2.0 * crab
        assert abs(d_psi + d_beta) < 0.05 * abs(d_psi)
        assert np.max(np.abs(tilted["lateral_error"][after])) < 0.02
    f3 = simulate(_scenario(noise=False, plant="3dof"))
    t3 = simulate(_scenario(noise=False, plant="3dof", road=RoadSpec(bank_deg=((0.0, 5.0),))))
    np.testing.assert_array_equal(f3["steer"], t3["steer"])


def test_yaw_error_reference_is_the_path_following_3dof_and_the_run_starts_on_it():
    """The yaw error's reference sideslip is the 3DoF model's with its CoG on the path
    (reference_states_3dof, method "path"; metrics.py), and the car starts with that sideslip:
    zero yaw and course error at t = 0 (noise-free, LVMS's curved start line)."""
    from flatfree.models.bicycle3dof import Bicycle3DoFParams
    from flatfree.simulation import prepare
    from flatfree.tracks import reference_states_3dof

    sc = _scenario(reference=ReferenceSpec(track="LVMS"), noise=False,
                   timing=Timing(duration_s=0.05, log_dt_s=0.001))
    prep = prepare(sc)
    bic = Bicycle3DoFParams.from_vehicle(prep.vehicle)
    kw = dict(cf=bic.cf, cr=bic.cr, mass=bic.m, iz=bic.iz, lf=bic.lf, lr=bic.lr)
    path = reference_states_3dof(prep.reference, method="path", **kw)
    np.testing.assert_array_equal(prep.beta_ref, np.arctan2(path.vy, path.vx))
    dyn = reference_states_3dof(prep.reference, **kw)
    # the two models differ materially along a lap (measured 1.9 deg on LVMS)
    assert np.max(np.abs(prep.beta_ref - np.arctan2(dyn.vy, dyn.vx))) > np.radians(0.5)
    tr = simulate(sc)
    assert abs(prep.beta_ref[0]) > 1e-3  # a material sideslip at the start
    assert abs(tr["yaw_error"][0]) < 1e-12 and abs(tr["course_error"][0]) < 1e-12


def test_a_recording_starts_with_its_recorded_yaw_and_its_sideslip():
    """For a recording the reference sideslip is the path's course minus the recorded yaw
    (wrapped), and the car starts on it: heading = the recorded yaw, vy = vx tan(beta_0); zero
    yaw and course error at t = 0 (recorded-noise-free; beta_0 measured -0.62 deg)."""
    from flatfree.metrics import wrap_angle
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    sc = named_scenario("recorded-noise-free", duration_s=0.05)
    prep = prepare(sc)
    ref = prep.reference
    np.testing.assert_array_equal(prep.beta_ref,
                                  wrap_angle(ref["psi"] - ref.extras["psi_recorded"]))
    assert np.radians(0.5) < abs(prep.beta_ref[0]) < np.radians(1.0)
    assert abs(prep.x0[2] - ref.extras["psi_recorded"][0]) < 1e-12
    assert prep.x0[4] == pytest.approx(prep.x0[3] * math.tan(prep.beta_ref[0]), rel=1e-15)
    tr = simulate(sc.with_(timing=Timing(duration_s=0.05, log_dt_s=0.001)))
    assert abs(tr["yaw_error"][0]) < 1e-12 and abs(tr["course_error"][0]) < 1e-12


@pytest.mark.parametrize("offset, outcome", [(0.0, "quiet"), (0.3, "warns"), (1.4, "refused"),
                                             (math.pi / 2, "refused")])
def test_a_recorded_yaw_far_from_the_course_is_warned_about_or_refused(tmp_path, offset,
                                                                      outcome):
    """A recording's phi is the car's yaw, rad, counter-clockwise from +x: one that differs
    from the course of its positions by 5 deg or more is warned about (a sideslip the run takes
    and starts with), by 30 deg or more refused (another convention: pi/2, a heading from north,
    made the start's vy infinite and the run end at t = 0 as completed, every metric NaN). A
    straight line at 15 m/s with a constant phi."""
    from flatfree.simulation import prepare

    t = np.arange(0.0, 10.0, 0.04)
    rows = "\n".join(f"{ti:g},{15.0 * ti:g},0,15,0,{offset!r},0" for ti in t)
    path = tmp_path / "line.csv"
    path.write_text("time,x,y,vx,vy,phi,delta\n" + rows + "\n")
    sc = Scenario(vehicle="dallara_av21", controller="mfc-natural",
                  controller_settings={"alpha_lat": 60.0}, noise=False,
                  reference=ReferenceSpec(track=None, recording=str(path)))
    if outcome == "refused":
        with pytest.raises(ValueError, match=r"line\.csv: its yaw phi differs from the course "
                                             r"of its positions by -\d+\.\d deg at t = 0\.00 s: "
                                             r"phi must be the car's yaw in rad"):
            prepare(sc)
        return
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        prep = prepare(sc)
    said = [str(w.message) for w in got if "yaw phi" in str(w.message)]
    if outcome == "quiet":
        assert not said and np.max(np.abs(prep.beta_ref)) < 1e-9
    else:
        assert len(said) == 1 and "by -17.2 deg" in said[0], said
        assert prep.beta_ref[0] == pytest.approx(-0.3, abs=1e-9)

def test_simulate_takes_a_named_scenarios_name_and_refuses_anything_else():
    """``simulate("paper")`` used to fail with AttributeError: a name is the named scenario
    with its defaults (flatfree.scenarios.named_scenario); anything else is a ValueError that
    says what to pass."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    assert prepare("paper-noise-free").scenario == named_scenario("paper-noise-free")
    tr = simulate("paper")
    assert tr.meta["scenario"] == "paper" and tr.status is Status.COMPLETED
    for bad in ("no-such-scenario", 42, None, {"name": "paper"}):
        with pytest.raises(ValueError, match=r"sc = .*: expected a Scenario \(flatfree\."
                                             r"load_scenario\(path\).* paper, "):
            simulate(bad)


class _Failing:
    """A Python controller that drives like the built-in one until ``t_bad``, then returns
    ``bad`` (per channel: NaN where the tuple says so) from then on."""

    schedule = "path"

    def __init__(self, sc, t_bad, bad):
        self.door = _NaturalDoor(sc)
        self.t_bad = t_bad
        self.bad = bad

    def reset(self):
        self.door.reset()

    def step(self, t, measurement, reference, applied):
        out = self.door.step(t, measurement, reference, applied)
        if t >= self.t_bad - 1e-9:
            return self.bad(out)
        return out


def test_a_python_controllers_nonfinite_commands_are_counted_and_warned_about():
    """A Python controller returning (nan, nan) from t = 0.5 s: the actuators hold the last
    command (the run still completes, 1.5 s), the trajectory's meta counts the steps per channel
    with the first one's time, and one RuntimeWarning names them."""
    import warnings

    sc = _scenario(timing=Timing(duration_s=1.5, log_dt_s=0.001))
    ctrl = _Failing(sc, 0.5, lambda out: (math.nan, math.nan))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tr = simulate(sc, controller=ctrl)
    mine = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(mine) == 1
    assert str(mine[0].message).startswith(
        "controller _Failing: step returned a non-finite command at 1000 (torque) and 1000 "
        "(steer) of its 1500 calls, the first at t = 0.5 s (control step 500); the actuators "
        "held the previous command")
    assert mine[0].filename == __file__  # attributed to the caller of simulate
    assert tr.status is Status.COMPLETED
    assert tr.meta["n_nonfinite_torque_cmd"] == 1000 and tr.meta["n_nonfinite_steer_cmd"] == 1000
    assert tr.meta["first_nonfinite_cmd_t_s"] == pytest.approx(0.5, abs=1e-12)
    bad = tr.time >= 0.5 - 1e-9
    assert np.all(np.isnan(tr["steer_cmd"][bad])) and np.all(np.isfinite(tr["steer_cmd"][~bad]))
    # the actuators hold the last finite command: the applied steer settles on it
    held = tr["steer_cmd"][~bad][-1]
    np.testing.assert_allclose(tr["steer"][tr.time >= 1.0], held, rtol=0, atol=1e-9)
    # one channel only: counted per channel
    steer_only = _Failing(sc, 1.0, lambda out: (out[0], math.inf))
    with pytest.warns(RuntimeWarning, match=r"at 0 \(torque\) and 500 \(steer\) of its 1500 "
                                            r"calls, the first at t = 1 s"):
        tr = simulate(sc, controller=steer_only)
    assert (tr.meta["n_nonfinite_torque_cmd"], tr.meta["n_nonfinite_steer_cmd"]) == (0, 500)


def test_finite_commands_count_zero_and_warn_nothing():
    import warnings

    sc = _scenario(timing=Timing(duration_s=0.2, log_dt_s=0.01))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for tr in (simulate(sc), simulate(sc, controller=_NaturalDoor(sc))):
            assert tr.meta["n_nonfinite_torque_cmd"] == 0
            assert tr.meta["n_nonfinite_steer_cmd"] == 0
            assert tr.meta["first_nonfinite_cmd_t_s"] is None


@pytest.mark.parametrize("bad", ["0.1", None, (0.0,), (0.0, "a"), (True, 0.0),
                                 (np.zeros(2), 0.0)])
def test_a_python_controllers_command_that_is_not_two_real_numbers_is_refused(bad):
    sc = _scenario(timing=Timing(duration_s=0.2, log_dt_s=0.01))
    ctrl = _Failing(sc, 0.1, lambda out: bad)
    with pytest.raises(ValueError, match=r"controller\.step\(t = 0\.1 s, \.\.\.\) = .* "
                                         r"\(_Failing\): expected \(torque \[N m\], steer"):
        simulate(sc, controller=ctrl)


def test_a_builtin_controllers_nonfinite_commands_are_counted_and_warned_about():
    """The compiled loop counts them too: a speed sensor biased by 1e307 m/s overflows the
    natural-output controller's speed loop (its torque command is NaN from when its window is
    full, 0.1 s); the actuators hold the torque and the run goes on, "completed". A built-in
    controller holds through non-finite measurements, so a NaN command is an overflow: warned
    about once, as a Python controller's (its shells raise on it)."""
    import warnings

    from flatfree.sensors import SensorChannel, SensorSuite

    sc = _scenario(plant="3dof", sensors=SensorSuite({"vx": SensorChannel(bias=1e307)}),
                   timing=Timing(duration_s=0.5, log_dt_s=0.001))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tr = simulate(sc)
    mine = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(mine) == 1
    assert str(mine[0].message).startswith(
        f"controller mfc-natural: a non-finite command at {tr.meta['n_nonfinite_torque_cmd']} "
        "(torque) and 0 (steer) control steps, the first at t = ")
    assert mine[0].filename == __file__  # attributed to the caller of simulate
    nan_cmd = np.isnan(tr["torque_cmd"])
    assert nan_cmd.sum() > 300 and not np.isnan(tr["steer_cmd"]).any()
    assert tr.meta["n_nonfinite_torque_cmd"] == nan_cmd.sum()  # logged at every control step
    assert tr.meta["n_nonfinite_steer_cmd"] == 0
    assert tr.meta["first_nonfinite_cmd_t_s"] == tr.time[np.argmax(nan_cmd)]


def test_natural_output_controller_step_refuses_what_is_not_a_real_number():
    """``step(vx="20")`` (or None, an array) used to give a numba TypingError: a ValueError
    naming the argument, its value and its unit, before anything is stepped."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import NaturalOutputController
    from flatfree.vehicles import load_vehicle

    c = NaturalOutputController(dt=0.001,
                                actuators=ActuatorParams.from_vehicle(load_vehicle("peugeot406")))
    base = dict(vx=20.0, r=0.0, e_y=0.01, kappa=0.0, vx_ref=20.0)
    names = {"vx": "m/s", "r": "rad/s", "e_y": "m", "kappa": "1/m", "vx_ref": "m/s",
             "ax_ref": "m/s^2", "e_y_ref": "m", "e_y_ref_dot": "m/s", "e_y_ref_ddot": "m/s^2",
             "applied_torque": "N m", "applied_steer": "rad", "e_y_ddot": "m/s^2"}
    for name, unit in names.items():
        for bad in ("20", None, np.array([1.0, 2.0]), False):
            if bad is None and name.startswith("applied_"):
                continue  # None: the actuators' model (documented)
            with pytest.raises(ValueError, match=rf"^{name} = {re.escape(repr(bad))} "
                                                 rf"{re.escape(unit)}: expected a real number"):
                c.step(**{**base, name: bad})
    assert c._prev.tolist() == [0.0, 0.0]  # nothing was stepped
    # ints and NumPy scalars are the numbers they are
    fresh = NaturalOutputController(
        dt=0.001, actuators=ActuatorParams.from_vehicle(load_vehicle("peugeot406")))
    for _ in range(150):
        assert c.step(vx=20, r=np.float32(0.0), e_y=np.float64(0.01), kappa=0, vx_ref=20.0) \
            == fresh.step(**base)


def test_a_held_steer_does_not_integrate_the_yaw_damper_and_stays_in_range():
    """The yaw damper (k_r (r - vx kappa)) acts with the iPD's law only: while the lateral
    deviation is missing, or before the window is full, the steer applied last is held (it
    integrated the damper's term at every held step: 0.4 s x 0.1 rad/s per ms, a 0.1 s gap
    in the position left the track); the damper's sum is clipped to the steer range."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import NaturalOutputController
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    c = NaturalOutputController(dt=0.001, actuators=act)  # yaw_damping 0.4 s
    c.reset(steer0=0.01)
    turn = dict(vx=20.0, r=0.1, kappa=0.0, vx_ref=20.0)  # r - vx kappa = 0.1 rad/s
    warm = [c.step(e_y=0.0, **turn)[1] for _ in range(99)]
    assert warm == [0.01] * 99  # held, damper included
    law = [c.step(e_y=0.0, **turn)[1] for _ in range(200)]
    held = [c.step(e_y=math.nan, **turn)[1] for _ in range(100)]  # 0.1 s without e_y
    # the steer applied last (the actuators' model: rate-limited behind the last command),
    # not walking
    assert held == [held[0]] * 100
    assert min(law) <= held[0] <= max(law)
    # far beyond the range: the iPD at its limit and the damper on top stay within it
    c.reset(steer0=0.05)
    for _ in range(3000):
        steer = c.step(vx=15.0, r=0.35, e_y=0.0, kappa=0.02, vx_ref=15.0)[1]
        assert abs(steer) <= act.max_steer
    assert steer == -act.max_steer


def test_natural_output_controller_overflow_raises_and_nan_measurements_do_not():
    """Finite inputs that overflow the law raise, naming the inputs and the command, and reset
    the controller at its last finite commands: two speeds of 1e308 m/s in the speed loop's
    window make its F estimate inf - inf (one is clipped: the torque limit). A NaN or infinite
    measurement is the documented hold (finite outputs, no error)."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.vehicle import NaturalOutputController
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    c = NaturalOutputController(dt=0.001, actuators=act)
    base = dict(vx=20.0, r=0.0, e_y=0.01, kappa=0.0, vx_ref=20.0)
    for _ in range(150):
        last = c.step(**base)
    for name in ("vx", "r", "e_y", "kappa", "vx_ref", "e_y_ref", "e_y_ddot"):
        for bad in (math.nan, math.inf, -math.inf):
            tw, delta = c.step(**{**base, name: bad})
            assert math.isfinite(tw) and math.isfinite(delta), (name, bad)
    last = c.step(**{**base, "vx": 1e308})
    assert last[0] == -act.max_brake_torque  # -inf from F_hat = +inf, clipped at the limit
    with pytest.raises(ValueError, match=r"NaturalOutputController\.step\(vx = 1e\+308, r = 0\.0"
                                         r".*: the command torque = nan is not finite.*"
                                         r"controller was reset \(reset\(steer0="):
        c.step(**{**base, "vx": 1e308})
    fresh = NaturalOutputController(
        dt=0.001, actuators=ActuatorParams.from_vehicle(load_vehicle("peugeot406")))
    fresh.reset(torque0=last[0], steer0=last[1])
    for _ in range(150):
        assert c.step(**base) == fresh.step(**base)


def test_a_track_run_longer_than_its_path_is_capped_near_the_path_end():
    """The loop allocates its log for the whole duration: a track run, which
    ends where its path ends, is capped at twice its default horizon (1.5 x the reference's
    duration + 5 s); a shorter request is kept, and any on the clock schedule."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    sc = named_scenario("paper-noise-free")
    default = prepare(sc)
    horizon = 1.5 * default.reference.duration + 5.0
    dt = sc.timing.plant_dt_s
    assert default.n_steps == int(round(horizon / dt))
    long = prepare(sc.with_(timing=Timing(duration_s=3600.0)))
    assert long.n_steps == int(round(2.0 * horizon / dt))
    assert prepare(sc.with_(timing=Timing(duration_s=20.0))).n_steps == int(round(20.0 / dt))
    # the clock schedule keeps what is asked
    clock = sc.with_(controller_settings={**sc.controller_settings, "schedule": "time"})
    assert prepare(clock).n_steps == int(round(default.reference.duration / dt))
    assert prepare(clock.with_(timing=Timing(duration_s=3600.0))).n_steps == 3_600_000


def test_a_patch_beyond_the_path_is_refused_a_late_fault_and_a_3dof_road_are_said():
    """Friction patches are placed by the path's arc length, modulo the lap on a closed path:
    one starting at or beyond the lap's length never applied, silently (a reviewer's patch
    meant for lap 2). A fault after the run's end never happens; the 3DoF plant's linear
    tyres ignore the road's friction (it logged mu as given)."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    sc = named_scenario("paper-noise-free", duration_s=2.0)
    lap = prepare(sc).reference.path.length
    ok = FrictionPatch(s_start_m=lap - 10.0, s_end_m=lap + 50.0, mu=0.5)  # across the line
    prepare(sc.with_(road=RoadSpec(patches=(ok,))))
    late = FrictionPatch(s_start_m=lap + 300.0, s_end_m=lap + 600.0, mu=0.5)
    with pytest.raises(ValueError, match=r"^road.patch\[1\].s_start_m = .* at or beyond the "
                                         r"lap's length, .* never applies"):
        prepare(sc.with_(road=RoadSpec(patches=(ok, late))))
    gap = Fault(kind="nan_measurement", channel="y", t_start_s=5.0, duration_s=0.1)
    with pytest.warns(UserWarning, match=r"fault\[0\] \(nan_measurement\) at t_start_s = 5 s"):
        prepare(sc.with_(faults=(gap,)))
    with pytest.warns(UserWarning, match="do not act on the 3dof plant"):
        prepare(sc.with_(plant="3dof", road=RoadSpec(mu=0.5)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prepare(sc.with_(plant="3dof"))


def test_a_road_below_what_the_reference_asks_is_said():
    """simulation._check_road: on the 10DoF plant a base road.mu whose mu g is below the
    reference's largest |(a_x, V_x^2 kappa)| is warned about with the figures and the remedy
    (the default profile asks about 6 m/s^2: road.mu 0.5 gives 4.90, 0.7 gives 6.86); a
    profile planned for that road (reference.mu = 0.5) is not, unless the path's own curvature
    asks more (LVMS unsmoothed); a recording's reference says it is the recording's (the LVMS
    recording asks more than 0.1 g)."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    sc = named_scenario("paper-noise-free", duration_s=0.5)
    ref = prepare(sc).reference
    demand = np.hypot(ref["ax"], ref["vx"] ** 2 * ref["kappa"]).max()
    assert demand == pytest.approx(6.0, abs=0.01)  # the ellipse's 6, sampled (6.007)
    with pytest.warns(UserWarning, match=rf"road.mu = 0.5: the reference asks for up to "
                                         rf"{demand:.2f} m/s\^2 \(at s = \d+ m\).*\(road.mu g = "
                                         r"4.90 m/s\^2; .*set reference.mu = 0.5"):
        prepare(sc.with_(road=RoadSpec(mu=0.5)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prepare(sc.with_(road=RoadSpec(mu=0.7)))
        planned = prepare(sc.with_(road=RoadSpec(mu=0.5),
                                   reference=dataclasses.replace(sc.reference, mu=0.5)))
    # the margin's reason: a profile planned for the road asks 0.12 % more than mu g
    r = planned.reference
    over = np.hypot(r["ax"], r["vx"] ** 2 * r["kappa"]).max() / (0.5 * 9.80665)
    assert 1.0 < over < 1.002
    # planned for the road, but an unsmoothed path's curvature asks more (LVMS: 1.2x)
    raw = sc.with_(road=RoadSpec(mu=0.5), reference=dataclasses.replace(
        sc.reference, track="LVMS", mu=0.5, smoothing_length_m=0.0))
    # (its jerk gives the rough-path warning too: not this test's, left out)
    with pytest.warns(UserWarning, match=r"plans for this road's friction, but the path's "
                                         r"curvature .*reference.smoothing_length_m"), \
            warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="the path may be too rough")
        prepare(raw)
    rec = named_scenario("recorded-noise-free", duration_s=0.5)
    with pytest.warns(UserWarning, match=r"road.mu = 0.1: .*the recording's speeds"):
        prepare(rec.with_(road=RoadSpec(mu=0.1)))


@pytest.mark.parametrize("name", ["paper-flatness-noise-free", "paper-mfc-flat-noise-free"])
def test_the_flat_output_designs_follow_an_offset_line(name):
    """reference.lateral_offset_m: the outer path correction of the flat-output designs acted
    on the deviation from the path itself, so they drove the centreline 0.5 m off the line
    asked for (a researcher's study; mean lateral error -0.50 m). Monza's first 20 s,
    noise-free, after the start-up: the mean error from the offset line was measured -0.008 /
    -0.66 cm with the correction on the line's deviation (max |error| 0.25 / 13.7 cm); bound
    2 cm."""
    import dataclasses

    from flatfree.scenarios import named_scenario

    sc = named_scenario(name, track="Monza", duration_s=20.0)
    sc = sc.with_(reference=dataclasses.replace(sc.reference, lateral_offset_m=0.5))
    tr = simulate(sc)
    assert tr.status is Status.COMPLETED
    after = tr.time >= sc.timing.startup_s
    assert abs(np.mean(tr["lateral_error"][after])) < 0.02
    assert abs(np.mean(tr["e_y"][after]) - 0.5) < 0.02  # the path is 0.5 m to the right


@pytest.mark.parametrize("block, plant_dt", [(997, 0.001), (4096, 0.001), (1500, 0.0005)])
def test_the_noise_drawn_a_block_at_a_time_gives_the_run_of_the_noise_drawn_whole(
        monkeypatch, block, plant_dt):
    """simulation._NOISE_BLOCK: the loop stops where a block of sensor noise ends and goes on
    from the same step with the next block; the trajectory is the one of the whole run's
    noise drawn at once, bit for bit (every signal and the status), through the compiled door
    and through a Python controller's pauses (a block's end between two of them), with
    sensors that drift and are delayed and held, and with the plant twice as fast as the
    controller (a block's end in control steps, not plant steps)."""
    from flatfree import simulation
    from flatfree.sensors import SensorChannel, SensorSuite

    sc = _scenario(timing=Timing(duration_s=6.0, log_dt_s=0.01, plant_dt_s=plant_dt))
    sensors = SensorSuite({**sc.sensors.channels,
                           "x": SensorChannel(noise_std=0.002, markov_std=0.01,
                                              markov_tau_s=1.0, markov_order=2),
                           "r": SensorChannel(noise_std=0.0017, delay_s=0.003, rate_hz=250.0)})
    sc = sc.with_(sensors=sensors)
    monkeypatch.setattr(simulation, "_NOISE_BLOCK", 10**9)
    whole = simulate(sc)
    short = sc.with_(timing=dataclasses.replace(sc.timing, duration_s=1.5))
    whole_py = simulate(short, controller=_NaturalDoor(short))
    monkeypatch.setattr(simulation, "_NOISE_BLOCK", block)
    blocks = simulate(sc)
    assert whole.status is blocks.status and whole.duration == blocks.duration > 5.9
    for k in whole:
        np.testing.assert_array_equal(blocks[k], whole[k], err_msg=k)
    py = simulate(short, controller=_NaturalDoor(short))
    for k in whole_py:
        np.testing.assert_array_equal(py[k], whole_py[k], err_msg=k)


@pytest.mark.parametrize("block", [1, 2, 3])
def test_a_state_that_goes_non_finite_at_a_noise_blocks_end_ends_the_run_the_same(
        monkeypatch, block):
    """The loop checks the state a block's last step left (its for-else), as the next step
    would: the overflowing stiff spring stops the run with the same status, time and rows
    whatever the block (a block's end at the overflowing step or just before or after it)."""
    from flatfree import simulation
    from flatfree.scenarios import named_scenario

    stiff = named_scenario("paper").with_(vehicle_overrides={"spring_front": 1e100},
                                          timing=Timing(duration_s=0.05, log_dt_s=0.001))
    monkeypatch.setattr(simulation, "_NOISE_BLOCK", 10**9)
    whole = simulate(stiff)
    assert whole.status is Status.NON_FINITE
    monkeypatch.setattr(simulation, "_NOISE_BLOCK", block)
    tr = simulate(stiff)
    assert tr.status is whole.status and tr.status_time == whole.status_time
    for k in whole:
        np.testing.assert_array_equal(tr[k], whole[k], err_msg=k)


def test_a_runs_signals_are_contiguous_read_only_and_its_own():
    """simulate hands its log's columns to the Trajectory without a copy
    (trajectory._adopting): each signal is a contiguous float64 array that cannot be written;
    two runs share nothing; a Trajectory made by a user still copies what it is given."""
    sc = _scenario(timing=Timing(duration_s=0.5, log_dt_s=0.01))
    a, b = simulate(sc), simulate(sc)
    for k in ("time", *a):
        assert a[k].flags.c_contiguous and a[k].dtype == np.float64, k
        assert not a[k].flags.writeable, k
        assert not np.shares_memory(a[k], b[k]), k
        with pytest.raises(ValueError, match="read-only"):
            a[k][0] = 1.0
        assert a[k].base is None or not a[k].base.flags.writeable, k
    given = np.arange(3.0)
    tr = Trajectory(time=given, signals={"v": given}, units={"v": "m"})
    given[0] = 9.0
    assert tr.time[0] == 0.0 and tr["v"][0] == 0.0
    # a run that ends early keeps only its rows: the log shrunk to them
    lock = Fault(kind="steer_limit", t_start_s=0.0, duration_s=20.0, value=0.0)
    left = simulate(_scenario(faults=(lock,), timing=Timing(duration_s=20.0, log_dt_s=0.01)))
    assert left.status is Status.LEFT_TRACK and len(left) < 2001  # of the rows allotted
    base = left["x"].base
    assert base.shape == (27, len(left)) and base.nbytes == 27 * 8 * len(left)
    assert all(np.shares_memory(left[k], base) for k in ("time", "x", "steer", "t_ref"))


@pytest.mark.parametrize("controller, settings", [
    ("mfc-natural", {}), ("mfc-natural", {"estimator_lat": "imu"}), ("mfc-flat", {}),
    ("flatness", {})], ids=["natural", "natural-imu", "mfc-flat", "flatness"])
def test_channels_no_controller_reads_are_not_drawn_and_change_nothing(
        monkeypatch, controller, settings):
    """The loop draws no noise for the channels its controller never reads (unread_channels:
    vy, ax, ay for the natural-output design; they measure NaN): the trajectory is the one of
    a run that measures every channel, bit for bit. A controller that read one of them would
    see NaN and hold, and differ here."""
    import flatfree.simulation as sim

    sc = _scenario(controller=controller, controller_settings=settings,
                   timing=Timing(duration_s=1.5, log_dt_s=0.01))
    skipped = sim.unread_channels(sim.prepare(sc).controller)
    assert skipped == {"mfc-natural": () if settings else ("vy", "ax", "ay")}.get(
        controller, ("ax", "ay"))
    lean = simulate(sc)
    monkeypatch.setattr(sim, "unread_channels", lambda ctrl: ())
    full = simulate(sc)
    assert lean.status is Status.COMPLETED
    for k in full:
        np.testing.assert_array_equal(lean[k], full[k], err_msg=k)


@pytest.mark.parametrize("name, old_m, bound_m", [("paper-flatness", 0.0082, 0.004),
                                                  ("paper-mfc-flat", 0.0511, 0.005)])
def test_a_lost_position_holds_the_flat_output_designs_path_correction(name, old_m, bound_m):
    """50 ms without the position (x NaN): the flat-output designs' path correction holds its
    last shift of the y2 reference. Left out, as before, the y2 reference jumped back to the
    uncorrected one for the gap: the lateral path moved by up to old_m against the same run
    without the fault (measured, seed 0, 6 s of Norisring); held, 1.4 and 0.6 mm."""
    from flatfree.scenario import Fault
    from flatfree.scenarios import named_scenario

    sc = named_scenario(name).with_(timing=Timing(duration_s=6.0, log_dt_s=0.001))
    base = simulate(sc)
    lost = simulate(sc.with_(faults=(Fault(kind="nan_measurement", channel="x", t_start_s=3.0,
                                           duration_s=0.05),)))
    assert lost.status is Status.COMPLETED
    assert np.max(np.abs(lost["e_y"] - base["e_y"])) < bound_m < old_m


def test_a_yaw_inertia_too_small_for_the_reference_sideslip_is_named_not_a_hang():
    """vehicle_overrides iz = 1e-6 kg m^2 hung prepare (the 3DoF sideslip dynamics along the
    reference asked ~3e12 RK4 sub-steps): a ValueError naming iz; 1 kg m^2 (3.3e6 sub-steps)
    still prepares."""
    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare

    sc = named_scenario("paper", duration_s=0.01)
    with pytest.raises(ValueError, match=r"^iz = 1e-06 kg m\^2: .* RK4 sub-steps"):
        prepare(sc.with_(vehicle_overrides={"iz": 1e-6}))
    assert prepare(sc.with_(vehicle_overrides={"iz": 1.0})).n_steps == 10


def test_the_meta_says_how_the_run_was_sampled():
    """The metrics' rates depend on the log's period: the trajectory's meta records the
    plant, control and log periods and the scenario's start-up interval, so that results
    compared later can be checked for like with like."""
    sc = _scenario(timing=Timing(duration_s=0.5, log_dt_s=0.02, startup_s=0.25))
    meta = simulate(sc).meta
    assert (meta["plant_dt_s"], meta["control_dt_s"], meta["log_dt_s"], meta["startup_s"]) == (
        0.001, 0.001, 0.02, 0.25)
