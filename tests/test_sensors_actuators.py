"""Sensors (noise, bias, rate, delay, seeding) and actuators (dead time, lag, rate and range
limits)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flatfree.actuators import ActuatorParams, actuate_step, actuator_state
from flatfree.sensors import SensorChannel, SensorSuite, sense_step
from flatfree.vehicles import load_vehicle


def _run_sensors(suite, truth, names, dt=1e-3, seed=0):
    n = truth.shape[0]
    cs = suite.compile(names, dt, n, seed)
    out = np.empty((n, len(names)))
    row = np.empty(len(names))
    for k in range(n):
        sense_step(k, truth[k], cs.table, cs.noise, cs.history, cs.held, row)
        out[k] = row
    return out


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
    with pytest.raises(ValueError, match=r"\['yaw'\] are not measured signals; valid: psi, r"):
        SensorSuite({"yaw": SensorChannel()}).compile(("psi", "r"), 1e-3, 10, 0)
    with pytest.raises(ValueError, match="noise_std = -1"):
        SensorChannel(noise_std=-1.0)
    with pytest.raises(ValueError, match="rate_hz = 0.0 Hz"):
        SensorChannel(rate_hz=0.0)


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


def test_non_finite_command_repeats_the_previous_one():
    fast = ActuatorParams(**{**BASE, "max_steer_rate": 100.0})
    out = _act(fast, [(500.0, 0.01), (math.nan, math.nan), (math.inf, 0.01)])
    assert np.all(np.isfinite(out))
    assert out[1, 0] == 500.0 and out[2, 0] == 500.0
    assert out[0, 1] == out[1, 1] == pytest.approx(0.01)


def test_from_vehicle_takes_the_preset_limits():
    v = load_vehicle("dallara_av21")
    a = ActuatorParams.from_vehicle(v, steer_delay=0.04)
    assert a.max_steer == v.max_steer and a.max_power == v.max_power and a.steer_delay == 0.04
    with pytest.raises(ValueError, match="torque_tau = -0.1 s"):
        ActuatorParams.from_vehicle(v, torque_tau=-0.1)


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
    from flatfree.sensors import _gauss_markov2

    std, phi, n_seq, n = 0.02, 0.3, 20_000, 6
    rng = np.random.default_rng(11)
    seqs = np.array([_gauss_markov2(rng, n, std, phi) for _ in range(n_seq)])
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
        out[order] = suite.compile(("y",), dt, n, seed=4).noise[:, 0]
    d1 = np.std(np.diff(out[1]))
    d2 = np.std(np.diff(out[2]))
    assert d1 == pytest.approx(math.sqrt(2.0 * (1.0 - phi)) * std, rel=0.02)
    assert d2 == pytest.approx(math.sqrt(2.0 * (1.0 - phi * (1.0 + math.tanh(dt / tau)))) * std,
                               rel=0.1)
    assert d2 < 1e-2 * d1
    for order in (1, 2):
        assert np.std(out[order]) == pytest.approx(std, rel=0.25)  # 200 tau: ~10 % spread


def test_drift_order_is_one_or_two():
    with pytest.raises(ValueError, match="markov_order = 3"):
        SensorChannel(markov_std=0.01, markov_tau_s=1.0, markov_order=3)
    with pytest.raises(ValueError, match="markov_order = True"):
        SensorChannel(markov_std=0.01, markov_tau_s=1.0, markov_order=True)


def test_drift_needs_its_correlation_time():
    with pytest.raises(ValueError, match="markov_tau_s"):
        SensorChannel(markov_std=0.01)
    with pytest.raises(ValueError, match="markov_tau_s = 0.0 s"):
        SensorChannel(markov_std=0.01, markov_tau_s=0.0)


def test_channels_appended_in_a_new_block_keep_the_earlier_noise():
    """SensorSuite.compile ``blocks``: the engine's accelerometers (``ax``, ``ay``) came after
    the first six channels; drawn as a second block they leave the first six channels' noise
    (white and drift) exactly as it was for the same seed, and they get noise of their own."""
    first = ("x", "y", "psi", "vx", "vy", "r")
    six = {
        "x": SensorChannel(noise_std=0.001),
        "psi": SensorChannel(noise_std=0.002, markov_std=0.01, markov_tau_s=1.0),
        "r": SensorChannel(noise_std=0.003),
    }
    old = SensorSuite(six).compile(first, 0.001, 500, seed=7)
    suite = SensorSuite({**six, "ay": SensorChannel(noise_std=0.05)})
    new = suite.compile((*first, "ax", "ay"), 0.001, 500, seed=7, blocks=(6, 2))
    np.testing.assert_array_equal(new.noise[:, :6], old.noise)
    assert np.all(new.noise[:, 6] == 0.0)  # ax has no channel: measured exactly
    assert np.std(new.noise[:, 7]) == pytest.approx(0.05, rel=0.15)
    # the white noise is the seed's generator's standard normals, row-major, block by block
    # (drawn in chunks of rows: the same sequence as one draw), then each drift
    n = 100_000  # more rows than one chunk
    got = SensorSuite({"x": SensorChannel(noise_std=0.5), "r": SensorChannel(noise_std=2.0)}
                      ).compile(first, 0.001, n, seed=3).noise
    want = np.random.default_rng(3).standard_normal((n, 6)) * [0.5, 0, 0, 0, 0, 2.0]
    np.testing.assert_array_equal(got, want)
    one_block = suite.compile((*first, "ax", "ay"), 0.001, 500, seed=7)
    assert not np.array_equal(one_block.noise[:, :6], old.noise)
    with pytest.raises(ValueError, match="blocks"):
        suite.compile((*first, "ax", "ay"), 0.001, 500, seed=7, blocks=(6, 1))
