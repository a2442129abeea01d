"""The model-free controllers at another control period: the settings' sample counts rescaled
(rescale_sample_counts, for_period, Scenario.with_control_period, --control-period) and the
warning when a period change leaves the 1 kHz counts in place."""

from __future__ import annotations

import dataclasses
import tomllib
import warnings

import pytest
from click.testing import CliRunner

from flatfree.actuators import ActuatorParams
from flatfree.cli import main
from flatfree.controllers.vehicle import (
    TUNED_PERIOD_S,
    FlatnessSettings,
    MfcFlatSettings,
    MfcNaturalSettings,
    NaturalOutputController,
    rescale_sample_counts,
    sample_counts,
)
from flatfree.scenarios import named_scenario, natural_settings
from flatfree.simulation import simulate
from flatfree.vehicles import load_vehicle

ACT = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))


def test_counts_keep_their_durations_nearest_whole_at_least_the_minimum_zero_stays_off():
    s = MfcNaturalSettings(window_lat=100, window_lon=50, denoise_lat=30, denoise_yaw=3)
    at100 = s.for_period(0.01)
    assert sample_counts(at100) == {"window_lon": 5, "window_lat": 10, "denoise_lon": 0,
                                    "denoise_lat": 3, "denoise_yaw": 2}
    # the nearest whole number: 100 samples of 1 ms at 3 ms is 33.3 -> 33, 50 -> 16.7 -> 17
    assert sample_counts(s.for_period(0.003))["window_lat"] == 33
    assert sample_counts(s.for_period(0.003))["window_lon"] == 17
    # faster than the tuning: more samples; from another period than 1 ms
    assert sample_counts(s.for_period(0.0005))["window_lat"] == 200
    assert sample_counts(at100.for_period(0.002, from_dt=0.01))["window_lat"] == 50
    # only the counts change
    assert dataclasses.replace(at100, **sample_counts(s)) == s
    assert s.for_period(TUNED_PERIOD_S) == s
    assert MfcFlatSettings().for_period(0.002).window_lat == 25
    # at least the smallest window each class accepts (the natural-output iPD's is 3 samples):
    # at 20 Hz 100 x 1 ms is 2 samples, which MfcNaturalSettings refused, naming a value the
    # user never wrote
    assert sample_counts(MfcNaturalSettings().for_period(0.05))["window_lat"] == 3
    assert MfcFlatSettings().for_period(0.1).window_lat == 2
    assert rescale_sample_counts(FlatnessSettings(), 0.01) == FlatnessSettings()  # no counts


@pytest.mark.parametrize(("kw", "field"), [({"dt": 0.0}, "dt"), ({"dt": float("nan")}, "dt"),
                                           ({"dt": 0.01, "from_dt": -1.0}, "from_dt")])
def test_a_bad_period_is_refused_by_name(kw, field):
    with pytest.raises(ValueError, match=f"^{field} = "):
        MfcNaturalSettings().for_period(**kw)


def _warnings(fn) -> list[str]:
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        fn()
    return [str(w.message) for w in got if issubclass(w.category, RuntimeWarning)]


def test_the_1_khz_windows_at_100_hz_are_warned_about_naming_the_windows_and_the_fix():
    def build_and_reset():
        c = NaturalOutputController(dt=0.01, actuators=ACT)
        c.reset()
        c.reset()

    got = _warnings(build_and_reset)
    assert len(got) == 1  # said when built, not again at every reset (review find)
    assert "window_lat = 100 samples spans 1 s (tuned: 0.1 s)" in got[0]
    assert "window_lon = 100 samples spans 1 s" in got[0]
    assert "settings.for_period(0.01)" in got[0]


@pytest.mark.parametrize("make", [
    lambda: NaturalOutputController(dt=0.01, actuators=ACT,
                                    settings=MfcNaturalSettings().for_period(0.01)),
    # the inertial variant's own denoiser length (20, not the default 50) is not a mismatch
    lambda: NaturalOutputController(dt=0.01, actuators=ACT, settings=MfcNaturalSettings(
        **natural_settings("peugeot406", imu=True)).for_period(0.01)),
    # at the tuned period any window is the user's choice
    lambda: NaturalOutputController(dt=0.001, actuators=ACT,
                                    settings=MfcNaturalSettings(window_lat=300)),
    # within 1.5x of the tuned durations (a 1.2 ms period keeps 100 samples: 0.12 s)
    lambda: NaturalOutputController(dt=0.0012, actuators=ACT),
    # counts the user chose for this period (not the defaults): the user's
    lambda: NaturalOutputController(dt=0.002, actuators=ACT, settings=MfcNaturalSettings(
        window_lat=150, window_lon=150)),
])
def test_rescaled_or_tuned_settings_are_not_warned_about(make):
    assert _warnings(make) == []


def test_with_control_period_rescales_from_the_scenario_s_own_period():
    sc = named_scenario("paper-imu")
    at100 = sc.with_control_period(0.01)
    assert at100.timing.control_dt_s == 0.01
    cs = dict(at100.controller_settings)
    assert (cs["window_lat"], cs["window_lon"], cs["denoise_yaw"]) == (10, 10, 2)
    assert cs["estimator_lat"] == "imu" and cs["yaw_damping"] == 0.2  # the rest kept
    back = at100.with_control_period(0.001)
    assert {k: back.controller_settings[k] for k in ("window_lat", "denoise_yaw")} == {
        "window_lat": 100, "denoise_yaw": 20}
    # the flatness controller has no counts; its settings stay as they were
    flat = named_scenario("paper-mismatch").with_control_period(0.002)
    assert flat.timing.control_dt_s == 0.002
    assert dict(flat.controller_settings) == dict(named_scenario("paper-mismatch")
                                                  .controller_settings)
    with pytest.raises(ValueError, match="timing.control_dt_s = 0.0015 s: must be a whole "):
        sc.with_control_period(0.0015)


def test_a_run_whose_period_changed_alone_says_so():
    """paper-imu with timing.control_dt_s 0.01 and the 1 kHz counts (1 s windows) left the
    track at 4.7 s without a word (benchmarks/README.md "Control period"); the run now warns.
    The rescaled lap: tests/test_imu_estimator.py."""
    sc = named_scenario("paper-imu", duration_s=2.0)
    kept = sc.with_(timing=dataclasses.replace(sc.timing, control_dt_s=0.01))
    got = _warnings(lambda: simulate(kept))
    assert any("window_lat = 100 samples spans 1 s" in g for g in got)
    assert _warnings(lambda: simulate(sc.with_control_period(0.01))) == []


def test_cli_control_period_option_runs_the_rescaled_controller(tmp_path):
    def run(*extra):
        res = CliRunner().invoke(main, ["run", "paper-imu", "--control-period", "0.01",
                                        "--duration", "3", "--out", str(tmp_path), *extra])
        assert res.exit_code == 0, res.output
        assert "control period" not in res.output  # no warning: the counts were rescaled
        return tomllib.loads((tmp_path / "scenario.toml").read_text())

    doc = run()
    assert doc["timing"]["control_dt_s"] == 0.01
    assert doc["controller_settings"]["window_lat"] == 10
    # a --set after it wins, as over every option
    assert run("--set", "controller_settings.window_lat=12")["controller_settings"][
        "window_lat"] == 12


def test_a_wrong_controller_is_refused_before_any_period_check():
    """build_mfc names a controller it does not build, at any period (at 10 ms the period
    check ran first and raised AttributeError on the flatness settings)."""
    from flatfree.controllers.vehicle import build_mfc

    for dt in (0.001, 0.01):
        with pytest.raises(ValueError, match="^controller = 'flatness': expected"):
            build_mfc("flatness", FlatnessSettings(), dt=dt, actuators=ACT)
