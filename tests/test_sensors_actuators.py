"""Sensors (noise, bias, rate, delay, seeding) and actuators (dead time, lag, rate and range
limits)."""

from __future__ import annotations

import dataclasses
import math
import re
import warnings

import numpy as np
import pytest

from flatfree.actuators import V_POWER_MIN, ActuatorParams, actuate_step, actuator_state
from flatfree.sensors import SensorChannel, SensorSuite, sense_step
from flatfree.vehicles import load_vehicle


def _measure(cs, truth):
    """Run compiled sensors over the rows of ``truth`` (controller steps 0, 1, ...)."""
    out = np.empty(truth.shape)
    row = np.empty(truth.shape[1])
    for k in range(truth.shape[0]):
        sense_step(k, truth[k], cs.table, cs.noise, k - cs.first_step, cs.history, cs.held, row)
        out[k] = row
    return out


def _run_sensors(suite, truth, names, dt=1e-3, seed=0):
    return _measure(suite.compile(names, dt, truth.shape[0], seed), truth)


def test_delay_shifts_by_whole_periods_and_rate_holds():
    n = 50
    ramp = np.arange(n, dtype=float)
    truth = np.column_stack([ramp, ramp])
    suite = SensorSuite({"a": SensorChannel(delay_s=0.003), "b": SensorChannel(rate_hz=250.0)})
    out = _run_sensors(suite, truth, ("a", "b"))
    # channel a: value of 3 steps earlier; the first value before that
    np.testing.assert_array_equal(out[3:, 0], ramp[:-3])
    np.testing.assert_array_equal(out[:3, 0], 0.0)
    # channel b: sampled every 4 ms, held in between
    np.testing.assert_array_equal(out[:, 1], (np.arange(n) // 4) * 4.0)


def test_noise_statistics_bias_and_seeding():
    n = 200_000
    truth = np.zeros((n, 1))
    suite = SensorSuite({"y": SensorChannel(noise_std=0.05, bias=0.2)})
    out = _run_sensors(suite, truth, ("y",), seed=7)[:, 0]
    # std of the sample std ~ sigma / sqrt(2 n) = 0.16 %: 1 % is > 6 sigma
    assert np.std(out) == pytest.approx(0.05, rel=0.01)
    # std of the sample mean ~ sigma / sqrt(n) = 1.1e-4: 1e-3 is > 8 sigma
    assert np.mean(out) == pytest.approx(0.2, abs=1e-3)
    again = _run_sensors(suite, truth[:1000], ("y",), seed=7)[:, 0]
    np.testing.assert_array_equal(again, out[:1000])
    other = _run_sensors(suite, truth[:1000], ("y",), seed=8)[:, 0]
    assert not np.array_equal(other, out[:1000])
    clean = _run_sensors(suite.noise_free(), truth[:10], ("y",))[:, 0]
    np.testing.assert_array_equal(clean, 0.0)


def test_unknown_sensor_channel_and_bad_values():
    """Each bad value raises a ValueError naming the field and the value as given."""
    msg = "sensor channel(s) ['yaw'] are not measured signals; valid: psi, r"
    with pytest.raises(ValueError, match=re.escape(msg)):
        SensorSuite({"yaw": SensorChannel()}).compile(("psi", "r"), 1e-3, 10, 0)
    with pytest.raises(ValueError, match=r"^noise_std = -1\.0: must be >= 0$"):
        SensorChannel(noise_std=-1.0)
    with pytest.raises(ValueError, match=r"^rate_hz = 0\.0 Hz: must be > 0$"):
        SensorChannel(rate_hz=0.0)
    with pytest.raises(ValueError, match=r"^delay_s = -0\.001 s: must be >= 0$"):
        SensorChannel(delay_s=-0.001)
    with pytest.raises(ValueError, match=r"^bias = nan: must be finite$"):
        SensorChannel(bias=math.nan)


def test_non_finite_truth_propagates_to_its_measurement():
    """sense_step docstring: a non-finite true value propagates to its measurement. A NaN true
    value at step 5 is NaN at step 5 through noise and bias, NaN at step 8 (only) on a channel
    delayed 3 steps; a held channel (sampled at steps 0, 4, 8, ...) keeps its step-4 sample at
    step 5, measures a NaN (or infinite) true value at its sample instant 8 as such, and does
    not hold it: it samples again at step 9, then holds that sample to its next instant 12."""
    n = 14
    truth = np.tile(np.arange(n, dtype=float)[:, None], (1, 4))
    truth[5] = math.nan
    truth[8, 2] = math.nan
    truth[8, 3] = math.inf
    suite = SensorSuite({
        "a": SensorChannel(noise_std=0.1, bias=0.2),
        "b": SensorChannel(delay_s=0.003),
        "c": SensorChannel(rate_hz=250.0),
        "d": SensorChannel(rate_hz=250.0),
    })
    out = _run_sensors(suite, truth, ("a", "b", "c", "d"), seed=1)
    np.testing.assert_array_equal(np.flatnonzero(np.isnan(out[:, 0])), [5])
    np.testing.assert_array_equal(np.flatnonzero(np.isnan(out[:, 1])), [8])
    assert out[4, 2] == out[5, 2] == 4.0
    assert math.isnan(out[8, 2]) and out[8, 3] == math.inf
    for c in (2, 3):
        np.testing.assert_array_equal(out[9:, c], [9.0, 9.0, 9.0, 12.0, 12.0])


def test_noise_free_keeps_rates_and_delays_and_zeroes_every_error():
    """SensorSuite.noise_free: no white noise, bias or drift left, the same rates and delays.
    On a ramp, a channel delayed 3 steps and sampled every 4 measures exactly
    ramp[max(4 (k // 4) - 3, 0)], one delayed 2 steps exactly ramp[max(k - 2, 0)]."""
    suite = SensorSuite({
        "a": SensorChannel(noise_std=0.1, bias=0.5, rate_hz=250.0, delay_s=0.003,
                           markov_std=0.01, markov_tau_s=1.0, markov_order=2),
        "b": SensorChannel(noise_std=0.2, bias=-1.0, delay_s=0.002, markov_std=0.01,
                           markov_tau_s=0.5),
    })
    clean = suite.noise_free()
    assert dict(clean.channels) == {"a": SensorChannel(rate_hz=250.0, delay_s=0.003),
                                    "b": SensorChannel(delay_s=0.002)}
    n = 40
    cs = clean.compile(("a", "b"), 1e-3, n, seed=5)
    assert np.all(cs.noise == 0.0) and np.all(cs.table[:, 1] == 0.0)
    k = np.arange(n)
    out = _measure(cs, np.column_stack([k, k]).astype(float))
    np.testing.assert_array_equal(out[:, 0], np.maximum(4 * (k // 4) - 3, 0))
    np.testing.assert_array_equal(out[:, 1], np.maximum(k - 2, 0))


def test_delay_and_rate_are_rounded_to_the_nearest_whole_period():
    """SensorChannel docstring: the delay is rounded to whole controller periods, the sample
    period rounded and at least 1. At 1 ms: 2.4 ms -> 2 steps, 2.6 ms -> 3, 0.4 ms -> 0;
    300 Hz (3.33 steps) -> 3, 220 Hz (4.55) -> 5, 1500 Hz (0.67) -> 1, 3000 Hz (0.33, which
    rounds to 0) -> 1, 400 Hz (2.5, an exact half: to the even number, as documented) -> 2."""
    delays = {"d24": (0.0024, 2), "d26": (0.0026, 3), "d04": (0.0004, 0)}
    rates = {"r300": (300.0, 3), "r220": (220.0, 5), "r1500": (1500.0, 1), "r3000": (3000.0, 1),
             "r400": (400.0, 2)}  # 2.5 steps exactly: the half to the even number
    chans = {**{k: SensorChannel(delay_s=d) for k, (d, _) in delays.items()},
             **{k: SensorChannel(rate_hz=f) for k, (f, _) in rates.items()}}
    names = tuple(chans)
    n = 30
    with pytest.warns(UserWarning, match="rounded to whole control periods"):  # each said
        cs = SensorSuite(chans).compile(names, 1e-3, n, seed=0)
    k = np.arange(n)
    out = _measure(cs, np.tile(k[:, None], (1, len(names))).astype(float))
    for i, name in enumerate(names):
        if name in delays:
            steps = delays[name][1]
            assert cs.table[i, 3] == steps and cs.table[i, 2] == 1
            np.testing.assert_array_equal(out[:, i], np.maximum(k - steps, 0), err_msg=name)
        else:
            steps = rates[name][1]
            assert cs.table[i, 2] == steps and cs.table[i, 3] == 0
            np.testing.assert_array_equal(out[:, i], steps * (k // steps), err_msg=name)


def test_reset_clears_the_state_and_a_rerun_is_bit_identical():
    """CompiledSensors.reset docstring: history and held values cleared (all NaN, as compiled);
    the same compiled sensors then run a second time give the first run's measurements bit for
    bit (noise, bias, drift, delay and hold included)."""
    suite = SensorSuite({
        "a": SensorChannel(noise_std=0.1, bias=0.2, delay_s=0.004, rate_hz=200.0),
        "b": SensorChannel(noise_std=0.05, markov_std=0.01, markov_tau_s=0.1),
    })
    n = 60
    truth = np.column_stack([np.sin(0.1 * np.arange(n)), np.cos(0.07 * np.arange(n))])
    cs = suite.compile(("a", "b"), 1e-3, n, seed=9)
    first = _measure(cs, truth)
    assert np.all(np.isfinite(cs.history)) and np.all(np.isfinite(cs.held))  # a used state
    cs.reset()
    assert np.all(np.isnan(cs.history)) and np.all(np.isnan(cs.held))
    np.testing.assert_array_equal(_measure(cs, truth), first)


def _act(params, cmds, vx=10.0, dt=1e-3):
    p = params.to_array(dt)
    st = actuator_state(params, dt)
    out = np.empty((len(cmds), 2))
    for k, (tq, s) in enumerate(cmds):
        out[k] = actuate_step(tq, s, vx, p, st)
    return out


BASE = dict(max_steer=0.5, max_steer_rate=0.4, max_drive_torque=2000.0, max_power=50_000.0,
            max_brake_torque=5000.0, wheel_radius=0.3)


def test_steer_rate_and_range_limits():
    out = _act(ActuatorParams(**BASE), [(0.0, 1.0)] * 2000)
    # ramps at 0.4 rad/s (0.4 mrad a step), then clips at 0.5 rad
    np.testing.assert_allclose(out[:1000, 1], 0.4e-3 * np.arange(1, 1001), rtol=1e-12)
    assert out[-1, 1] == 0.5 and np.all(out[:, 1] <= 0.5)


def test_first_order_lag_is_exact_for_a_held_command():
    params = ActuatorParams(**{**BASE, "max_steer_rate": 100.0}, torque_tau=0.05, steer_tau=0.02)
    out = _act(params, [(1000.0, 0.1)] * 200)
    k = np.arange(1, 201)
    np.testing.assert_allclose(out[:, 0], 1000.0 * (1 - np.exp(-k * 1e-3 / 0.05)), rtol=1e-12)
    np.testing.assert_allclose(out[:, 1], 0.1 * (1 - np.exp(-k * 1e-3 / 0.02)), rtol=1e-12)


def test_dead_time_and_power_cap():
    params = ActuatorParams(**BASE, torque_delay=0.005, steer_delay=0.002)
    cmds = [(100.0 * k, 1e-4 * k) for k in range(20)]
    out = _act(params, cmds)
    np.testing.assert_allclose(out[5:, 0], [100.0 * k for k in range(15)])
    np.testing.assert_allclose(out[2:, 1], [1e-4 * k for k in range(18)], rtol=1e-12)
    # at 50 m/s the drive torque is capped by P R / v = 50 kW * 0.3 / 50 = 300 N m
    capped = _act(ActuatorParams(**BASE), [(2000.0, 0.0)] * 3, vx=50.0)
    assert capped[-1, 0] == pytest.approx(300.0)
    braking = _act(ActuatorParams(**BASE), [(-9000.0, 0.0)] * 3, vx=50.0)
    assert braking[-1, 0] == -5000.0


def test_a_dead_time_off_the_plant_step_is_rounded_and_said():
    """Module docstring, item 1: at a 1 ms step a 2.4 ms steer delay acts as 2 steps and a
    2.6 ms torque delay as 3, and a warning names each moved setting (as the sensors do); delays
    of whole steps pass without one."""
    params = ActuatorParams(**BASE, steer_delay=0.0024, torque_delay=0.0026)
    with pytest.warns(UserWarning, match=re.escape(
            "steer_delay = 0.0024 s -> 0.002 s; torque_delay = 0.0026 s -> 0.003 s "
            "(rounded to whole steps)")):
        out = _act(params, [(100.0 * k, 1e-4 * k) for k in range(10)])
    np.testing.assert_allclose(out[3:, 0], [100.0 * k for k in range(7)])
    np.testing.assert_allclose(out[2:, 1], [1e-4 * k for k in range(8)], rtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ActuatorParams(**BASE, steer_delay=0.002, torque_delay=0.005).to_array(1e-3)


def test_power_cap_below_v_power_min_and_for_a_negative_drive_speed():
    """Module docstring, item 4: drive torque <= P R_e / max(|v_drive|, V_POWER_MIN), with
    V_POWER_MIN = 1 m/s. With P = 1 kW, R_e = 0.3 m: 300 N m for |v| <= 1 m/s (v = 0 included:
    no division by zero), 150 N m at v = +-2 m/s, 15 N m at -20 m/s (the speed's magnitude);
    a command under the cap passes; braking is limited by max_brake_torque only."""
    assert V_POWER_MIN == 1.0
    low = ActuatorParams(**{**BASE, "max_power": 1000.0})
    for v, cap in [(0.0, 300.0), (0.5, 300.0), (-0.5, 300.0), (1.0, 300.0), (-1.0, 300.0),
                   (2.0, 150.0), (-2.0, 150.0), (-20.0, 15.0)]:
        assert _act(low, [(2000.0, 0.0)], vx=v)[0, 0] == pytest.approx(cap, rel=1e-15), v
    assert _act(low, [(250.0, 0.0)], vx=0.5)[0, 0] == 250.0
    assert _act(low, [(-4000.0, 0.0)], vx=0.0)[0, 0] == -4000.0
    assert _act(low, [(-9000.0, 0.0)], vx=-20.0)[0, 0] == -5000.0


def test_non_finite_command_repeats_the_previous_one():
    fast = ActuatorParams(**{**BASE, "max_steer_rate": 100.0})
    out = _act(fast, [(500.0, 0.01), (math.nan, math.nan), (math.inf, 0.01)])
    assert np.all(np.isfinite(out))
    assert out[1, 0] == 500.0 and out[2, 0] == 500.0
    assert out[0, 1] == out[1, 1] == pytest.approx(0.01)


def test_from_vehicle_takes_the_preset_limits():
    """Every field of ActuatorParams.from_vehicle: each limit is the preset's field of the same
    name (the six preset values differ from each other, so a swapped or dropped one fails),
    lags and delays are 0 unless given; an override replaces only its own field and is
    validated like any other value."""
    v = load_vehicle("dallara_av21")
    limits = {name: getattr(v, name) for name in (
        "max_steer", "max_steer_rate", "max_drive_torque", "max_power", "max_brake_torque",
        "wheel_radius")}
    assert len(set(limits.values())) == len(limits)  # all distinct: a mix-up is visible
    a = ActuatorParams.from_vehicle(v, steer_delay=0.04)
    got = {f.name: getattr(a, f.name) for f in dataclasses.fields(a)}
    assert got == {**limits, "steer_tau": 0.0, "steer_delay": 0.04, "torque_tau": 0.0,
                   "torque_delay": 0.0}
    b = ActuatorParams.from_vehicle(v, max_power=1000.0)
    assert dataclasses.replace(a, steer_delay=0.0, max_power=1000.0) == b
    with pytest.raises(ValueError, match=r"^torque_tau = -0\.1 s: must be >= 0$"):
        ActuatorParams.from_vehicle(v, torque_tau=-0.1)
    # a road-wheel angle in radians: 40 (degrees given as radians) is refused by name
    with pytest.raises(ValueError, match=r"^max_steer = 40\.0 rad: must lie in \(0\.0, 1\.57"):
        ActuatorParams.from_vehicle(v, max_steer=40.0)
    # 0 is refused, and the interval the message writes says so (it wrote [0.0, ...])
    for bad in (0.0, -0.1):
        with pytest.raises(ValueError, match=rf"^max_steer = {bad!r} rad: must lie in "
                                             r"\(0\.0, 1\.5707963267948966\]$"):
            ActuatorParams.from_vehicle(v, max_steer=bad)


def test_gauss_markov_drift_has_its_std_and_correlation_time():
    """Stationary std markov_std and autocorrelation exp(-lag / tau) (first-order Gauss-Markov).

    400 000 samples at 1 ms with tau = 0.2 s: about 1000 correlation times, so the sample std
    has a relative spread ~ sqrt(1 / 1000) ~ 3 %: checked within 10 %; the lag-tau
    autocorrelation within 0.05 of exp(-1).
    """
    n, dt, tau = 400_000, 1e-3, 0.2
    suite = SensorSuite({"y": SensorChannel(markov_std=0.01, markov_tau_s=tau)})
    out = _run_sensors(suite, np.zeros((n, 1)), ("y",), dt=dt, seed=3)[:, 0]
    assert np.std(out) == pytest.approx(0.01, rel=0.1)
    lag = int(tau / dt)
    rho = np.corrcoef(out[:-lag], out[lag:])[0, 1]
    assert rho == pytest.approx(math.exp(-1.0), abs=0.05)
    # white noise alone is unchanged by the drift option's existence (same seed, same draws)
    white = SensorSuite({"y": SensorChannel(noise_std=0.05)})
    both = SensorSuite({"y": SensorChannel(noise_std=0.05, markov_std=0.01, markov_tau_s=tau)})
    w = _run_sensors(white, np.zeros((100, 1)), ("y",), seed=3)[:, 0]
    b = _run_sensors(both, np.zeros((100, 1)), ("y",), seed=3)[:, 0]
    assert not np.array_equal(w, b)
    assert np.std(b - w) < 0.02  # the difference is the slow drift, ~0.01
    assert SensorSuite({"y": both.channels["y"]}).noise_free().channels["y"].markov_std == 0.0


def test_second_order_drift_is_stationary_with_its_exact_autocorrelation():
    """markov_order = 2 (sensors module docstring): over 20 000 independent short sequences
    (phi = 0.3, where the discrete autocorrelation phi^m (1 + m tanh(dt / tau)) at lags 1, 2
    differs from its continuous limit by 0.11, 0.066), the variance is markov_std^2 at the
    first sample and at the last (started stationary: the state before the first sample is
    drawn too), and
    the lag-m correlations are the closed form: standard errors ~ 1 % of the variance and
    0.007 in a correlation, checked within 5 % / 0.03."""
    from flatfree.sensors import _NoiseDraw

    std, phi, n_seq, n = 0.02, 0.3, 20_000, 6
    rng = np.random.default_rng(11)
    ch = SensorChannel(markov_std=std, markov_tau_s=1.0, markov_order=2)
    seqs = np.zeros((n_seq, n))
    for row in seqs:  # the drift's first n samples, from its stationary start
        _NoiseDraw._drift(ch, rng, phi, None, n, row)
    var = seqs.var(axis=0)
    assert var[0] == pytest.approx(std**2, rel=0.05)
    assert var[-1] == pytest.approx(std**2, rel=0.05)
    th = math.tanh(-math.log(phi))  # tanh(dt / tau), phi = exp(-dt / tau)
    x = -math.log(phi)  # dt / tau
    for m in (1, 2):
        rho = np.corrcoef(seqs[:, 0], seqs[:, m])[0, 1]
        exact = phi**m * (1.0 + m * th)
        assert rho == pytest.approx(exact, abs=0.03)
        assert abs(exact - math.exp(-m * x) * (1.0 + m * x)) > 0.06  # the check discriminates


def test_second_order_drift_is_smooth_where_the_first_order_one_walks():
    """At 1 kHz with tau = 10 s and 1 cm: the same stationary std, but the sample-to-sample
    increments' std is the closed form sqrt(2 (1 - phi (1 + tanh(dt / tau)))) markov_std, about
    (dt / tau) markov_std = 1e-4 of it for order 2 (order dt^2 in the variance), against
    sqrt(2 (1 - phi)) = 1.4e-2 of it for order 1; one long run of 2e6 samples (200 correlation
    times)."""
    n, dt, tau, std = 2_000_000, 1e-3, 10.0, 0.01
    phi = math.exp(-dt / tau)
    out = {}
    for order in (1, 2):
        suite = SensorSuite({"y": SensorChannel(markov_std=std, markov_tau_s=tau,
                                                markov_order=order)})
        out[order] = suite.compile(("y",), dt, n, seed=4).noise[0]
    d1 = np.std(np.diff(out[1]))
    d2 = np.std(np.diff(out[2]))
    assert d1 == pytest.approx(math.sqrt(2.0 * (1.0 - phi)) * std, rel=0.02)
    assert d2 == pytest.approx(math.sqrt(2.0 * (1.0 - phi * (1.0 + math.tanh(dt / tau)))) * std,
                               rel=0.1)
    assert d2 < 1e-2 * d1
    for order in (1, 2):
        assert np.std(out[order]) == pytest.approx(std, rel=0.25)  # 200 tau: ~10 % spread


def test_drift_order_is_one_or_two():
    """markov_order other than 1 or 2 (also True and NumPy's True, which equal 1) raises,
    naming it; a file's 2.0 is stored as the int 2."""
    for bad in (3, True, np.True_, "2"):
        msg = rf"^markov_order = {re.escape(repr(bad))}: must be 1 or 2$"
        with pytest.raises(ValueError, match=msg):
            SensorChannel(markov_std=0.01, markov_tau_s=1.0, markov_order=bad)
    ch = SensorChannel(markov_std=0.01, markov_tau_s=1.0, markov_order=2.0)
    assert ch.markov_order == 2 and type(ch.markov_order) is int


def test_drift_needs_its_correlation_time():
    """A drift without markov_tau_s, or with markov_tau_s <= 0, raises naming the value."""
    msg = "markov_std = 0.01: a drift needs its correlation time markov_tau_s [s]"
    with pytest.raises(ValueError, match=re.escape(msg)):
        SensorChannel(markov_std=0.01)
    with pytest.raises(ValueError, match=r"^markov_tau_s = 0\.0 s: must be > 0$"):
        SensorChannel(markov_std=0.01, markov_tau_s=0.0)


def test_a_channels_noise_is_its_own_and_drawn_in_time_order():
    """Each channel draws from its own streams (sensors module docstring): for a given seed
    its error sequence (white, first- and second-order drift) does not depend on the run's
    length, the order of the names, the other channels' settings or its own other component;
    it is the documented draw of :func:`channel_streams`."""
    from flatfree.sensors import channel_streams

    names = ("x", "y", "psi", "vx", "vy", "r", "ax", "ay")
    chans = {
        "x": SensorChannel(noise_std=0.001, markov_std=0.01, markov_tau_s=1.0, markov_order=2),
        "psi": SensorChannel(noise_std=0.002, markov_std=0.01, markov_tau_s=1.0),
        "r": SensorChannel(noise_std=0.003),
    }
    suite = SensorSuite(chans)
    short = suite.compile(names, 0.001, 500, seed=7).noise.T  # (steps, channels)
    long = suite.compile(names, 0.001, 1200, seed=7).noise.T
    np.testing.assert_array_equal(long[:500], short)  # a shorter run: the start of a longer
    assert np.all(short[:, [1, 3, 4, 6, 7]] == 0.0)  # no channel: measured exactly
    # another channel added, the names reordered: each channel keeps its sequence
    more = SensorSuite({**chans, "ay": SensorChannel(noise_std=0.05)})
    order = names[::-1]
    rev = more.compile(order, 0.001, 500, seed=7).noise.T
    for i, name in enumerate(names):
        if name != "ay":
            np.testing.assert_array_equal(rev[:, order.index(name)], short[:, i])
    assert np.std(rev[:, order.index("ay")]) == pytest.approx(0.05, rel=0.15)
    # the white noise is channel_streams' white standard normals times noise_std; twice the
    # noise_std, twice the same sequence; the drift alone is the same drift
    white, _ = channel_streams(7, "r")
    np.testing.assert_array_equal(short[:, 5], white.standard_normal(500) * 0.003)
    double = SensorSuite({"r": SensorChannel(noise_std=0.006)}).compile(names, 0.001, 500, 7)
    np.testing.assert_array_equal(double.noise[5], 2.0 * short[:, 5])
    drift_only = SensorSuite({"psi": SensorChannel(markov_std=0.01, markov_tau_s=1.0)})
    white_psi, _ = channel_streams(7, "psi")
    np.testing.assert_array_equal(  # (IEEE addition commutes: exact)
        drift_only.compile(names, 0.001, 500, 7).noise[2] + white_psi.standard_normal(500)
        * 0.002, short[:, 2])
    # channels with the same settings get different, uncorrelated noise; another seed differs
    same = SensorSuite({k: SensorChannel(noise_std=1.0) for k in names})
    z = same.compile(names, 0.001, 20_000, seed=3).noise
    corr = np.corrcoef(z)[np.triu_indices(len(names), 1)]
    assert np.max(np.abs(corr)) < 0.04  # 20 000 samples: std of a correlation ~0.007
    other = same.compile(names, 0.001, 20_000, seed=4).noise
    assert np.max(np.abs(np.corrcoef(z[0], other[0])[0, 1])) < 0.04


def test_a_delay_or_rate_the_control_clock_cannot_keep_is_said():
    """Delays and sample periods are whole control periods (module docstring): a setting that
    rounds to another value is said (a reviewer's 4 ms and 5 ms delays at 100 Hz both gave
    the no-delay run silently); one that is a whole number of periods is not."""
    import warnings

    from flatfree.sensors import SENSOR_CHANNELS, SensorChannel, SensorSuite

    suite = SensorSuite({"y": SensorChannel(delay_s=0.004), "vx": SensorChannel(rate_hz=400.0)})
    with pytest.warns(UserWarning, match=r"^sensors at a control period of 0.01 s: y.delay_s = "
                                         r"0.004 s -> 0 s; vx.rate_hz = 400 Hz -> 100 Hz"):
        suite.compile(SENSOR_CHANNELS, 0.01, 10, 0)
    whole = SensorSuite({"y": SensorChannel(delay_s=0.004), "vx": SensorChannel(rate_hz=250.0)})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        whole.compile(SENSOR_CHANNELS, 0.002, 10, 0)  # 2 periods each


def _blocks(suite, names, n, seed, block):
    """The error sequences of ``n`` steps drawn ``block`` at a time (next_block), joined."""
    cs = suite.compile(names, 0.001, n, seed, block=block)
    parts, first = [cs.noise.copy()], [cs.first_step]
    while sum(p.shape[1] for p in parts) < n:
        first.append(cs.next_block())
        parts.append(cs.noise.copy())
    assert first == [i * min(block, n) for i in range(len(parts))]
    return np.concatenate(parts, axis=1)[:, :n]


@pytest.mark.parametrize("block", [1, 7, 500, 4096, 10_000])
def test_noise_drawn_in_blocks_is_the_noise_drawn_whole(block):
    """SensorSuite.compile(block=...) and CompiledSensors.next_block: each channel's white
    noise and first- and second-order drift go on from block to block (the streams and the
    drifts' filter states carried), the sequences of compile() without a block bit for bit;
    a block longer than the run holds the whole run."""
    names = ("x", "y", "psi", "vx", "vy", "r", "ax", "ay")
    suite = SensorSuite({
        "x": SensorChannel(noise_std=0.001, markov_std=0.01, markov_tau_s=1.0, markov_order=2),
        "y": SensorChannel(markov_std=0.02, markov_tau_s=0.05, markov_order=2),
        "psi": SensorChannel(noise_std=0.002, markov_std=0.01, markov_tau_s=0.3),
        "vx": SensorChannel(markov_std=0.1, markov_tau_s=2.0),
        "r": SensorChannel(noise_std=0.003, bias=0.1, delay_s=0.002, rate_hz=250.0),
    })
    n = 9_000
    whole = suite.compile(names, 0.001, n, seed=11)
    assert whole.first_step == 0
    np.testing.assert_array_equal(_blocks(suite, names, n, 11, block), whole.noise)
    # measured through sense_step, delays and holds across the blocks' ends included; reset
    # starts the streams again: a second run measures the same
    truth = np.random.default_rng(2).standard_normal((n, len(names)))
    cs = suite.compile(names, 0.001, n, seed=11, block=block)

    def measure():
        out = np.empty(truth.shape)
        for k in range(n):
            if k - cs.first_step == cs.noise.shape[1]:
                cs.next_block()
            sense_step(k, truth[k], cs.table, cs.noise, k - cs.first_step, cs.history,
                       cs.held, out[k])
        return out

    np.testing.assert_array_equal(measure(), _measure(whole, truth))
    cs.reset()
    assert cs.first_step == 0
    np.testing.assert_array_equal(measure(), _measure(whole, truth))


@pytest.mark.parametrize("block", [None, 7, 4096])
def test_unread_channels_draw_nothing_and_measure_nan(block):
    """compile(unread=...): those channels measure NaN at every step (no noise drawn, through
    the blocks too) and every other channel's errors are those of a compile without it."""
    names = ("x", "y", "psi", "vx", "vy", "r", "ax", "ay")
    suite = SensorSuite({k: SensorChannel(noise_std=0.01, markov_std=0.02, markov_tau_s=0.5)
                         for k in names})
    n = 9_000
    full = suite.compile(names, 0.001, n, seed=3)
    lean = suite.compile(names, 0.001, n, seed=3, block=block, unread=("vy", "ay"))
    noise = lean.noise if block is None else _blocks_of(lean, n)
    skip = [names.index("vy"), names.index("ay")]
    keep = [i for i in range(len(names)) if i not in skip]
    assert np.all(np.isnan(noise[skip]))
    np.testing.assert_array_equal(noise[keep], full.noise[keep])
    truth = np.ones(len(names))
    out = np.empty(len(names))
    sense_step(0, truth, lean.table, lean.noise, 0, lean.history, lean.held, out)
    assert np.all(np.isnan(out[skip])) and np.all(np.isfinite(out[keep]))
    with pytest.raises(ValueError, match=r"unread = \['vz'\]: not among"):
        suite.compile(names, 0.001, n, seed=3, unread=("vz",))


def _blocks_of(cs, n):
    parts = [cs.noise.copy()]
    while sum(p.shape[1] for p in parts) < n:
        cs.next_block()
        parts.append(cs.noise.copy())
    return np.concatenate(parts, axis=1)[:, :n]


def test_a_block_is_a_whole_number_of_steps_and_whole_sensors_have_no_next_block():
    suite = SensorSuite({"x": SensorChannel(noise_std=0.1)})
    for bad in (0, -3, 2.5, True, "8"):
        with pytest.raises(ValueError, match=rf"^block = {re.escape(repr(bad))}: expected a "
                                             r"whole number of control steps >= 1"):
            suite.compile(("x",), 0.001, 10, 0, block=bad)
    with pytest.raises(ValueError, match="compiled whole"):
        suite.compile(("x",), 0.001, 10, 0).next_block()


@pytest.mark.parametrize("order", [1, 2])
def test_the_drift_recursions_are_scipys_lfilter_bit_for_bit(order):
    """The drifts' compiled recursions (sensors._drift1, _drift2) give the numbers of
    scipy.signal.lfilter on the documented draw (the module's "drift": the stationary start,
    then the driving noise; order 2 two first-order stages from their stationary state), bit
    for bit, over a long run and for a fast and a slow correlation time."""
    from scipy.signal import lfilter

    from flatfree.sensors import channel_streams

    n, dt, std = 50_000, 0.001, 0.02
    for tau in (0.004, 30.0):
        phi = math.exp(-dt / tau)
        suite = SensorSuite({"y": SensorChannel(markov_std=std, markov_tau_s=tau,
                                                markov_order=order)})
        got = suite.compile(("y",), dt, n, seed=9).noise[0]
        _, rng = channel_streams(9, "y")
        if order == 1:
            w = rng.standard_normal(n)
            w[0] *= std
            w[1:] *= std * math.sqrt(1.0 - phi * phi)
            want = lfilter([1.0], [1.0, -phi], w)
        else:
            q = 1.0 - phi * phi
            var_s, cov_ys, var_y = 1.0 / q, 1.0 / (q * q), (1.0 + phi * phi) / (q * q * q)
            z = rng.standard_normal(n + 2)
            s_m = z[0] * math.sqrt(var_s)
            y_m = (cov_ys / var_s) * s_m + z[1] * math.sqrt(var_y - cov_ys * cov_ys / var_s)
            scale = std / math.sqrt(var_y)
            s1, _ = lfilter([1.0], [1.0, -phi], z[2:] * scale, zi=[phi * s_m * scale])
            want, _ = lfilter([1.0], [1.0, -phi], s1, zi=[phi * y_m * scale])
        np.testing.assert_array_equal(got, want)
