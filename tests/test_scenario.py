"""Scenario: validation, TOML round trip, and errors that name the line and the field."""

from __future__ import annotations

import dataclasses

import pytest

from flatfree.scenario import (
    Fault,
    FrictionPatch,
    ReferenceSpec,
    RoadSpec,
    Scenario,
    Timing,
    load_scenario,
    scenario_from_toml,
)
from flatfree.sensors import SensorChannel, SensorSuite


def _rich() -> Scenario:
    return Scenario(
        name="wet-norisring",
        description="a patch of wet road",
        vehicle="dallara_av21",
        vehicle_overrides={"mass": 800.0},
        controller="mfc-flat",
        controller_settings={"alpha_lat": 2.5, "window": 20},
        reference=ReferenceSpec(track="Norisring", line="raceline", laps=2, a_lat_max=5.0,
                                drive_limit=True),
        timing=Timing(plant_dt_s=0.001, control_dt_s=0.002, log_dt_s=0.01, duration_s=30.0),
        sensors=SensorSuite({"vx": SensorChannel(noise_std=0.05, markov_std=0.02,
                                                 markov_tau_s=2.0),
                             "x": SensorChannel(markov_std=0.01, markov_tau_s=60.0,
                                                markov_order=2),
                             "e_y": SensorChannel(noise_std=0.01, rate_hz=100.0,
                                                  delay_s=0.01)}),
        noise=False,
        road=RoadSpec(mu=1.0, patches=(FrictionPatch(s_start_m=100.0, s_end_m=200.0, mu=0.5),),
                      bank_deg=((0.0, 0.0), (80.0, -9.2), (400.0, -9.2))),
        faults=(Fault(kind="nan_measurement", channel="e_y", t_start_s=5.0, duration_s=0.05),
                Fault(kind="steer_limit", t_start_s=8.0, duration_s=1.0, value=0.01)),
        seed=42,
    )


def test_toml_round_trip_is_exact(tmp_path):
    sc = _rich()
    assert scenario_from_toml(sc.to_toml()) == sc
    assert load_scenario(sc.save(tmp_path / "s.toml")) == sc
    default = Scenario()
    assert scenario_from_toml(default.to_toml()) == default


def test_defaults_and_recording_reference():
    sc = scenario_from_toml('controller = "flatness"\n[reference]\nrecording = "LVMS"\n')
    assert sc.reference.track is None and sc.reference.recording == "LVMS"
    assert sc.controller == "flatness" and sc.plant == "10dof" and sc.noise is True
    assert sc.timing.control_every == 1 and sc.timing.log_every == 10


def test_noise_switch_keeps_rates_and_delays():
    sc = _rich()
    eff = sc.effective_sensors.channels["e_y"]
    assert eff.noise_std == 0.0 and eff.rate_hz == 100.0 and eff.delay_s == 0.01
    assert dataclasses.replace(sc, noise=True).effective_sensors is sc.sensors


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('name = "x"\ncontroller = "pid"\n', ["line 2", "field controller", "'pid'",
                                             "flatness, mfc-flat, mfc-natural"]),
        ('name = "x"\n\n[timing]\nplant_dt_s = -0.001\n',
         ["line 4", "field timing.plant_dt_s", "-0.001"]),
        ('[timing]\nplant_dt_s = 0.001\ncontrol_dt_s = 0.0015\n',
         ["line 3", "timing.control_dt_s", "whole multiple"]),
        ('[reference]\ntrack = "Monza"\nlanes = 3\n', ["line 3", "reference.lanes",
                                                      "unknown key"]),
        ('[sensors.vx]\nnoise_std = -1.0\n', ["line 2", "sensors.vx.noise_std", "-1.0"]),
        ('[[road.patch]]\ns_start_m = 10.0\ns_end_m = 5.0\nmu = 0.5\n',
         ["line 3", "road.patch.s_end_m", "must exceed"]),
        ('[[fault]]\nkind = "meteor"\nt_start_s = 1.0\nduration_s = 1.0\n',
         ["line 2", "fault.kind", "'meteor'"]),
        ('seed = -3\n', ["line 1", "field seed", "-3"]),
        ('[reference]\ndrive_limit = "yes"\n', ["line 2", "reference.drive_limit", "'yes'"]),
        ('wheels = 4\n', ["line 1", "field wheels", "unknown key"]),
        ('name = \n', ["malformed TOML", "line 1"]),
    ],
)
def test_malformed_files_name_the_line_and_the_field(text, words):
    with pytest.raises(ValueError) as info:
        scenario_from_toml(text, source="my.toml")
    msg = str(info.value)
    assert msg.startswith("my.toml")
    for w in words:
        assert w in msg, (w, msg)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"plant": "14dof"}, "plant = '14dof'"),
        ({"noise": "yes"}, "noise = 'yes'"),
        ({"vehicle_overrides": {"mass": [1]}}, "vehicle_overrides.mass"),
    ],
)
def test_invalid_scenarios(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Scenario(**kwargs)


@pytest.mark.parametrize(
    ("bank", "match"),
    [
        (((0.0, 1.0), (0.0, 2.0)), r"road.bank_deg\[1\] = \(0.0, 2.0\): s must increase"),
        (((0.0, 95.0),), r"road.bank_deg\[0\] = \(0.0, 95.0\): .*within \(-90, 90\)"),
        (((1.0,),), r"road.bank_deg\[0\] = \(1.0,\): expected a pair"),
    ],
)
def test_bad_bank_profiles_are_refused(bank, match):
    with pytest.raises(ValueError, match=match):
        RoadSpec(bank_deg=bank)


def test_reference_needs_exactly_one_source():
    with pytest.raises(ValueError, match="exactly one of track"):
        ReferenceSpec(track=None)
    with pytest.raises(ValueError, match="exactly one of track"):
        ReferenceSpec(track="Monza", recording="LVMS")


def test_fault_needs_its_fields():
    with pytest.raises(ValueError, match="needs the channel"):
        Fault(kind="nan_measurement", t_start_s=0.0, duration_s=1.0)
    with pytest.raises(ValueError, match="needs the limit"):
        Fault(kind="steer_limit", t_start_s=0.0, duration_s=1.0)


def test_missing_file():
    with pytest.raises(ValueError, match="scenario file not found"):
        load_scenario("/nonexistent/x.toml")
