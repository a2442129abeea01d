"""Scenario: validation, TOML round trip, and errors that name the line and the field."""

from __future__ import annotations

import dataclasses
import math
import tomllib
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np
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
    scenario_with_settings,
)
from flatfree.sensors import SensorChannel, SensorSuite


def _rich() -> Scenario:
    return Scenario(
        name="wet-norisring",
        description="a patch of wet road",
        vehicle="dallara_av21",
        vehicle_overrides={"mass": 800.0},
        controller="mfc-flat",
        controller_settings={"alpha_lat": 2.5, "window_lat": 20},
        reference=ReferenceSpec(track="Norisring", line="raceline", laps=2, a_lat_max=5.0,
                                drive_limit=True),
        timing=Timing(plant_dt_s=0.001, control_dt_s=0.002, log_dt_s=0.01, duration_s=30.0),
        sensors=SensorSuite({"vx": SensorChannel(noise_std=0.05, markov_std=0.02,
                                                 markov_tau_s=2.0),
                             "x": SensorChannel(markov_std=0.01, markov_tau_s=60.0,
                                                markov_order=2),
                             "psi": SensorChannel(noise_std=0.01, rate_hz=100.0,
                                                  delay_s=0.01)}),
        noise=False,
        road=RoadSpec(mu=1.0, patches=(FrictionPatch(s_start_m=100.0, s_end_m=200.0, mu=0.5),),
                      bank_deg=((0.0, 0.0), (80.0, -9.2), (400.0, -9.2))),
        faults=(Fault(kind="nan_measurement", channel="psi", t_start_s=5.0, duration_s=0.05),
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
    eff = sc.effective_sensors.channels["psi"]
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
        # an unknown kind is named before the keys it would need (not a TypeError's text)
        ('[[fault]]\nkind = "meteor"\n', ["line 2", "fault.kind = 'meteor'",
                                           "nan_measurement, steer_limit"]),
        ('[[fault]]\nkind = "steer_limit"\nvalue = 0.1\n',
         ["line 1", "field fault", "missing keys t_start_s, duration_s"]),
        ('[[road.patch]]\ns_start_m = 10.0\ns_end_m = 20.0\n',
         ["line 1", "field road.patch", "missing key mu"]),
        # an error in a second table of an array is reported at that table (it was the first's)
        (('[[fault]]\nkind = "steer_limit"\nt_start_s = 1.0\nduration_s = 1.0\nvalue = 0.1\n'
          '\n[[fault]]\nkind = "steer_limit"\nt_start_s = 2.0\nduration_s = -1.0\nvalue = 0.1\n'),
         ["line 10", "field fault.duration_s ([[fault]] table 2)", "-1.0"]),
        (('[[fault]]\nkind = "steer_limit"\nt_start_s = 1.0\nduration_s = 1.0\nvalue = 0.1\n'
          '[[fault]]\nkind = "meteor"\n'), ["line 7", "fault.kind ([[fault]] table 2)"]),
        (('[[road.patch]]\ns_start_m = 10.0\ns_end_m = 20.0\nmu = 0.5\n'
          '[[road.patch]]\ns_start_m = 30.0\ns_end_m = 40.0\n'),
         ["line 5", "field road.patch ([[road.patch]] table 2)", "missing key mu"]),
        ('seed = -3\n', ["line 1", "field seed", "-3"]),
        ('seed = 2.5\n', ["line 1", "field seed", "seed = 2.5: must be an integer >= 0"]),
        # a channel the loop does not measure (a table or a fault the run would never use)
        ('[sensors.x]\nnoise_std = 0.1\n[sensors.e_y]\nnoise_std = 0.1\n',
         ["line 3", ("field sensors.e_y: 'e_y' is not a measured channel; channels: x, y, "
                     "psi, vx, vy, r, ax, ay")]),
        (('[[fault]]\nkind = "nan_measurement"\nchannel = "e_y"\nt_start_s = 1.0\n'
          'duration_s = 0.1\n'),
         ["line 3", ("field fault.channel: fault.channel: 'e_y' is not a measured channel; "
                     "channels: x, y, psi, vx, vy, r, ax, ay")]),
        ('name = "paper-noise-free"\nnoise = true\n',
         ["line 2", ("field noise: noise = true: the scenario's name 'paper-noise-free' says "
                     "noise-free; run 'paper' for the noisy variant, or rename it "
                     "(name = ...)")]),
        ('[reference]\ndrive_limit = "yes"\n', ["line 2", "reference.drive_limit", "'yes'"]),
        ('wheels = 4\n', ["line 1", "field wheels", "unknown key"]),
        # text and booleans are not numbers (float() would take "6" and true)
        ('[reference]\na_lat_max = "6"\n', ["line 2", "reference.a_lat_max", "'6'",
                                             "expected a real number"]),
        ('[reference]\nj_lat_max = "inf"\n', ["line 2", "reference.j_lat_max", "'inf'"]),
        ('[sensors.y]\nnoise_std = true\n', ["line 2", "sensors.y.noise_std", "True"]),
        ('[road]\nbank_deg = [[0.0, true]]\n', ["road.bank_deg", "True"]),
        # a bare number (a user's "constant bank") is named with the form to write instead
        ('[road]\nbank_deg = 5\n', ["line 2", "road.bank_deg = 5", "[[0.0, 5.0]]"]),
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
        ({"name": 3}, r"^name = 3: expected a text$"),
        ({"description": None}, r"^description = None: expected a text$"),
        ({"vehicle": 406}, r"^vehicle = 406: expected a preset name or a file path$"),
        ({"seed": 3.5}, r"^seed = 3.5: must be an integer >= 0$"),
        ({"seed": "3"}, r"^seed = '3': must be an integer >= 0$"),
        ({"seed": math.nan}, r"^seed = nan: must be an integer >= 0$"),
        ({"sensors": SensorSuite({"e_y": SensorChannel()})},
         (r"^sensors.e_y: 'e_y' is not a measured channel; channels: x, y, psi, vx, vy, r, "
          r"ax, ay$")),
        # its name says noise-free (noise is on by default)
        ({"name": "recorded-imu-noise-free"},
         (r"^noise = true: the scenario's name 'recorded-imu-noise-free' says noise-free; "
          r"run 'recorded-imu' for the noisy variant, or rename it \(name = \.\.\.\)$")),
    ],
)
def test_invalid_scenarios(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Scenario(**kwargs)


def test_reference_names_and_laps_are_checked():
    with pytest.raises(ValueError, match=r"^reference.track = 7: expected a name or a file path$"):
        ReferenceSpec(track=7)
    with pytest.raises(ValueError, match=r"^reference.recording = \[1\]: expected a name"):
        ReferenceSpec(track=None, recording=[1])
    for laps in (math.inf, math.nan, True, 1.5, 0, "2"):
        with pytest.raises(ValueError, match=r"^reference.laps = .*: must be an integer >= 1$"):
            ReferenceSpec(laps=laps)
    assert ReferenceSpec(laps=2.0).laps == 2.0


@pytest.mark.parametrize(
    ("bank", "match"),
    [
        (((0.0, 1.0), (0.0, 2.0)), r"road.bank_deg\[1\] = \(0.0, 2.0\): s must increase"),
        (((0.0, 95.0),), r"road.bank_deg\[0\] = \(0.0, 95.0\): .*within \(-90, 90\)"),
        (((1.0,),), r"road.bank_deg\[0\] = \(1.0,\): expected a pair"),
        (5.0, r"road.bank_deg = 5.0: expected a list of \(s \[m\], bank \[deg\]\) points"),
    ],
)
def test_bad_bank_profiles_are_refused(bank, match):
    with pytest.raises(ValueError, match=match):
        RoadSpec(bank_deg=bank)


def test_bad_patches_container_is_refused():
    with pytest.raises(ValueError, match=r"road.patches = 3: expected a sequence"):
        RoadSpec(patches=3)


def test_a_tracks_shape_and_smoothing_are_reference_settings(tmp_path):
    """reference.closed and reference.smoothing_length_m reach load_track: an out-and-back road
    digitised every 10 m ends 2.4 spacings from its start, which the detection closes with a
    warning (tests/test_tracks_io.py); closed = false keeps the run's path open, silently. Checked
    and refused by name; a recording has neither (its path is the one driven)."""
    from flatfree.simulation import prepare, reference_of
    from flatfree.tracks import load_track

    out = np.arange(0.0, 301.0, 10.0)
    a = np.linspace(0.0, np.pi, 5)[1:-1]
    xy = np.concatenate([np.column_stack([out, 0.0 * out]),
                         np.column_stack([300 + 12 * np.sin(a), 12 - 12 * np.cos(a)]),
                         np.column_stack([out[::-1], 0.0 * out + 24.0])])
    f = tmp_path / "road.csv"
    f.write_text("x,y\n" + "".join(f"{p:.6f},{q:.6f}\n" for p, q in xy))
    base = Scenario(reference=ReferenceSpec(track=str(f), a_lat_max=3.0))
    with pytest.warns(UserWarning, match=r"closed into a loop .*reference\.closed"):
        assert prepare(base).reference.path.closed
    sc = base.with_settings(["reference.closed=false"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = prepare(sc).reference.path
    assert not path.closed
    assert path.length == pytest.approx(load_track(f, closed=False).length, rel=1e-12)
    assert scenario_from_toml(sc.to_toml()) == sc
    smooth = reference_of(Scenario(reference=ReferenceSpec(track="Norisring",
                                                           smoothing_length_m=60.0)))
    want = load_track("Norisring", smoothing_length=60.0)
    assert smooth.path.length == want.length != load_track("Norisring").length
    assert ReferenceSpec(smoothing_length_m=0).smoothing_length_m == 0  # the points as given
    # another track or a recording drops the old file's settings, unless set with it
    rec = sc.with_settings(["reference.recording=LVMS_23_01_04_B"])
    assert (rec.reference.closed, rec.reference.smoothing_length_m) == (None, None)
    other = sc.with_settings(["reference.smoothing_length_m=30", "reference.track=Monza"])
    assert (other.reference.closed, other.reference.smoothing_length_m) == (None, 30.0)
    for bad, msg in ((dict(closed="yes"), r"^reference.closed = 'yes': must be true or false$"),
                     (dict(closed=1), r"^reference.closed = 1: must be true or false$"),
                     (dict(smoothing_length_m=-1.0),
                      r"^reference.smoothing_length_m = -1.0 m: must be >= 0$"),
                     (dict(smoothing_length_m=math.nan),
                      r"^reference.smoothing_length_m = nan m: must be finite$"),
                     (dict(track=None, recording="LVMS_23_01_04_B", closed=False),
                      (r"^reference.closed = False: a track's setting; the reference is the "
                       r"recording 'LVMS_23_01_04_B' \(its path as driven\)$"))):
        with pytest.raises(ValueError, match=msg):
            ReferenceSpec(**bad)


def test_a_duration_shorter_than_one_plant_step_is_refused():
    """A run of 0.0005 s at a 1 ms plant step took no step and reported completed with an
    empty log."""
    for kw in ({"duration_s": 0.0005}, {"duration_s": 0.004, "plant_dt_s": 0.01,
                                        "control_dt_s": 0.01, "log_dt_s": 0.01}):
        with pytest.raises(ValueError, match=r"timing.duration_s = .* s: shorter than one "
                                             r"plant step \(plant_dt_s = "):
            Timing(**kw)
    assert Timing(duration_s=0.001).duration_s == 0.001  # one step
    with pytest.raises(ValueError, match="setting timing.duration_s=0.0001: .*plant_dt_s"):
        Scenario().with_settings(["timing.duration_s=0.0001"])


def test_reference_needs_exactly_one_source():
    with pytest.raises(ValueError, match="exactly one of track"):
        ReferenceSpec(track=None)
    with pytest.raises(ValueError, match="exactly one of track"):
        ReferenceSpec(track="Monza", recording="LVMS")


def test_seed_is_a_whole_number_as_the_other_counts():
    """seed as reference.laps (_validate.whole): a whole float (a TOML 3.0) is the integer."""
    import numpy as np

    for seed in (3, 3.0, np.int64(3)):
        sc = Scenario(seed=seed)
        assert sc.seed == 3 and type(sc.seed) is int
    assert scenario_from_toml("seed = 3.0\n") == Scenario(seed=3)
    big = 2**53 + 1  # not a float: kept exactly
    assert Scenario(seed=big).seed == big
    assert scenario_from_toml(Scenario(seed=2**63 - 1).to_toml()).seed == 2**63 - 1


def test_noise_free_names_refuse_the_noise_on_every_path():
    from flatfree.scenarios import named_scenario

    msg = (r"noise = true: the scenario's name 'paper-noise-free' says noise-free; run 'paper' "
           r"for the noisy variant, or rename it \(name = \.\.\.\)$")
    sc = named_scenario("paper-noise-free")
    with pytest.raises(ValueError, match=rf"^{msg}"):
        sc.with_(noise=True)
    with pytest.raises(ValueError, match=rf"^setting noise=true: field noise: {msg}"):
        sc.with_settings(["noise=true"])
    # renamed in the same step, or without the noise, it is a scenario like any other
    assert sc.with_(noise=True, name="mine").noise
    assert sc.with_settings(["noise=true", "name=mine"]).name == "mine"
    assert Scenario(name="x-noise-free", noise=False).name == "x-noise-free"


def test_bundled_names_are_held_in_their_own_spelling(tmp_path, monkeypatch):
    """As the loaders match them (case-insensitive, a track's .csv optional): one spelling, so
    that what compares names (natural_settings, the CLI's output) sees the car it runs."""
    monkeypatch.chdir(tmp_path)
    sc = Scenario(vehicle="Dallara_AV21", reference=ReferenceSpec(track=" monza.CSV"))
    assert (sc.vehicle, sc.reference.track) == ("dallara_av21", "Monza")
    assert sc.with_(vehicle="BMW320I").vehicle == "bmw320i"
    assert ReferenceSpec(track=None, recording="lvms_23_01_04_b").recording == "LVMS_23_01_04_B"
    assert ReferenceSpec(track="lvms_23_01_04_b").track == "LVMS_23_01_04_B"  # its driven path
    assert scenario_from_toml('vehicle = "PEUGEOT406"\n').vehicle == "peugeot406"
    assert scenario_with_settings(Scenario(), ["reference.track=spa"]).reference.track == "Spa"
    # not a bundled name: as given (the loader's error names it), a Path as a Path
    assert ReferenceSpec(track="Monza2").track == "Monza2"
    assert Scenario(vehicle="PEUGEOT406.toml").vehicle == "PEUGEOT406.toml"
    assert Scenario(vehicle=Path("my car.toml")).vehicle == "my car.toml"  # its text
    # a file of that name in the current directory is what a loader reads: kept
    (tmp_path / "monza").write_text("")
    (tmp_path / "Dallara_AV21").write_text("")
    sc = Scenario(vehicle="Dallara_AV21", reference=ReferenceSpec(track="monza"))
    assert (sc.vehicle, sc.reference.track) == ("Dallara_AV21", "monza")


def test_setting_path_is_the_path_scenario_with_settings_reads():
    from flatfree.scenario import setting_path

    assert setting_path(" reference . track = Monza") == "reference.track"
    assert setting_path("sensors.y.markov_order=2") == "sensors.y.markov_order"
    with pytest.raises(ValueError, match=r"^setting seed: expected FIELD=VALUE"):
        setting_path("seed")
    with pytest.raises(ValueError, match=r"^setting reference\.\.mu=1: the path "
                                         r"'reference\.\.mu' has an empty part"):
        setting_path("reference..mu=1")


def test_fault_needs_its_fields():
    with pytest.raises(ValueError, match="needs the channel"):
        Fault(kind="nan_measurement", t_start_s=0.0, duration_s=1.0)
    with pytest.raises(ValueError, match=r"^fault.channel: 'e_y' is not a measured channel; "
                                         r"channels: x, y, psi, vx, vy, r, ax, ay$"):
        Fault(kind="nan_measurement", channel="e_y", t_start_s=0.0, duration_s=1.0)
    with pytest.raises(ValueError, match="needs the limit"):
        Fault(kind="steer_limit", t_start_s=0.0, duration_s=1.0)


def test_a_scenarios_faults_must_be_faults():
    # a string or a mapping in faults was accepted and failed in simulate with an
    # AttributeError (a user's audit); a bare Fault was a TypeError
    sc = Scenario()
    gap = Fault(kind="nan_measurement", channel="y", t_start_s=0.1, duration_s=0.1)
    with pytest.raises(ValueError, match=r"^faults\[0\] = 'x': expected a Fault"):
        sc.with_(faults=("x",))
    with pytest.raises(ValueError, match=r"^faults\[1\] = \{'kind': 'steer_limit'\}: expected"):
        sc.with_(faults=(gap, {"kind": "steer_limit"}))
    with pytest.raises(ValueError, match=r"^faults = Fault\(.*\): expected a sequence of Fault"):
        sc.with_(faults=gap)
    with pytest.raises(ValueError, match=r"^faults = 3: expected a sequence of Fault"):
        sc.with_(faults=3)
    assert sc.with_(faults=[gap]).faults == (gap,)
    assert sc.with_(faults=(f for f in [gap])).faults == (gap,)  # an iterator, read once


def test_a_fault_refuses_a_key_of_the_other_kind(tmp_path):
    """``value = 3`` on a nan_measurement fault ran and was ignored: a key that does not
    apply to the fault's kind is refused, naming the key and the kind (in a file, the line)."""
    with pytest.raises(ValueError, match=r"fault.value = 3: a nan_measurement fault takes no "
                                         r"value .*its keys: kind, channel, t_start_s"):
        Fault(kind="nan_measurement", channel="x", t_start_s=0.0, duration_s=1.0, value=3)
    with pytest.raises(ValueError, match=r"fault.channel = 'x': a steer_limit fault takes no "
                                         r"channel .*its keys: kind, t_start_s, duration_s, "
                                         r"value"):
        Fault(kind="steer_limit", channel="x", t_start_s=0.0, duration_s=1.0, value=0.01)
    f = tmp_path / "f.toml"
    f.write_text('[[fault]]\nkind = "nan_measurement"\nchannel = "x"\nt_start_s = 1.0\n'
                 'duration_s = 0.05\nvalue = 3\n')
    with pytest.raises(ValueError) as info:
        load_scenario(f)
    msg = str(info.value)
    for w in (str(f), "line 6", "field fault.value", "nan_measurement fault takes no value"):
        assert w in msg, (w, msg)


def test_missing_file():
    with pytest.raises(ValueError, match="scenario file not found"):
        load_scenario("/nonexistent/x.toml")


def test_a_file_that_cannot_be_read_is_a_value_error_naming_it(tmp_path):
    """A folder, or bytes that are not UTF-8, as a scenario file or a vehicle file: a
    ValueError naming the file (not an OSError, nor a UnicodeDecodeError without the file)."""
    folder = tmp_path / "dir.toml"
    folder.mkdir()
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00bad")
    for f, reason in ((folder, "Is a directory"), (binary, "not a UTF-8 text file")):
        with pytest.raises(ValueError, match=reason) as info:
            load_scenario(f)
        assert str(f) in str(info.value)
        with pytest.raises(ValueError, match=reason) as info:
            Scenario(vehicle=str(f)).load_vehicle()
        assert str(f) in str(info.value)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('name = "my-scenario"\n\n[controller_settings]\nalpha_lat = "48.9"\n',
         ["line 4", "field controller_settings.alpha_lat", "controller mfc-natural",
          "alpha_lat = '48.9'", "real number"]),
        ('name = "my-scenario"\n[vehicle_overrides]\nmass = "1600 kg"\n',
         ["line 3", "field vehicle_overrides.mass", "vehicle peugeot406",
          "mass = '1600 kg'", "real number"]),
        ('controller = "flatness"\n\n[controller_settings]\ncf_scale = 0.3\nalpha_lat = 30\n',
         ["line 5", "field controller_settings.alpha_lat", "unknown for flatness"]),
        ('[vehicle_overrides]\nwheels = 4\n',
         ["line 2", "field vehicle_overrides.wheels", "not parameters of a vehicle"]),
    ],
)
def test_a_files_controller_settings_and_overrides_name_the_file_line_and_field(
        tmp_path, text, words):
    """The controller's settings and the vehicle overrides were checked only by the run, whose
    error named neither the file nor the line (and blamed the controller for the car's
    mass): load_scenario checks them as a setting of them is checked, and so does
    scenario_from_toml for a text without a file (it let them through to the run)."""
    f = tmp_path / "mine.toml"
    f.write_text(text)
    with pytest.raises(ValueError) as info:
        load_scenario(f)
    msg = str(info.value)
    assert msg.startswith(f"{f}, "), msg
    for w in words:
        assert w in msg, (w, msg)
    with pytest.raises(ValueError) as info:
        scenario_from_toml(text)
    assert str(info.value) == msg.replace(str(f), "<scenario>", 1)


# ------------------------------------------------------------------------------------------
# file paths: relative to the scenario file's folder; saved absolute
# ------------------------------------------------------------------------------------------
def _files(root):
    """A scenario folder with a car and a track of its own, and another current directory."""
    (root / "rw" / "sub").mkdir(parents=True)
    (root / "rw" / "sub" / "mycar.toml").write_text("# a car\n")
    (root / "rw" / "tracks").mkdir()
    (root / "rw" / "tracks" / "circle.csv").write_text("# a track\n")
    (root / "elsewhere").mkdir()
    return root / "rw"


def test_relative_paths_in_a_file_are_relative_to_its_folder(tmp_path, monkeypatch):
    rw = _files(tmp_path)
    (rw / "scenario.toml").write_text('vehicle = "sub/mycar.toml"\n[reference]\n'
                                      'track = "tracks/circle.csv"\n')
    monkeypatch.chdir(tmp_path / "elsewhere")
    for path in (rw / "scenario.toml", "../rw/scenario.toml"):  # absolute, and relative
        sc = load_scenario(path)
        assert sc.vehicle == str(rw / "sub" / "mycar.toml")
        assert sc.reference.track == str(rw / "tracks" / "circle.csv")
    # a recording file too; a missing file is looked for in the folder too (so its error
    # names where), "../" included
    (rw / "scenario.toml").write_text('vehicle = "../elsewhere/none.toml"\n[reference]\n'
                                      'recording = "tracks/circle.csv"\n')
    sc = load_scenario(rw / "scenario.toml")
    assert sc.vehicle == str(tmp_path / "elsewhere" / "none.toml")
    assert sc.reference.recording == str(rw / "tracks" / "circle.csv")
    # bundled names are names, in any spelling the loaders take, held in their own
    (rw / "scenario.toml").write_text('vehicle = "PEUGEOT406"\n[reference]\n'
                                      'track = "monza.csv"\n')
    sc = load_scenario(rw / "scenario.toml")
    assert (sc.vehicle, sc.reference.track) == ("peugeot406", "Monza")
    (rw / "scenario.toml").write_text(f'vehicle = "{rw / "sub" / "mycar.toml"}"\n'
                                      '[reference]\nrecording = "LVMS_23_01_04_B"\n')
    sc = load_scenario(rw / "scenario.toml")  # an absolute path is kept
    assert sc.vehicle == str(rw / "sub" / "mycar.toml")
    assert sc.reference.recording == "LVMS_23_01_04_B"
    # as a loader reads an existing file before a bundled name, so does the folder
    (rw / "Monza").write_text("# a file named like a bundled track\n")
    (rw / "scenario.toml").write_text('[reference]\ntrack = "Monza"\n')
    assert load_scenario(rw / "scenario.toml").reference.track == str(rw / "Monza")
    # in another spelling too: the folder's file, not the bundled track in its own spelling
    (rw / "monza").write_text("# a file named like a bundled track\n")
    (rw / "scenario.toml").write_text('[reference]\ntrack = "monza"\n')
    assert load_scenario(rw / "scenario.toml").reference.track == str(rw / "monza")
    # text without a folder keeps the values as written
    assert scenario_from_toml('vehicle = "sub/mycar.toml"\n').vehicle == "sub/mycar.toml"


def test_save_writes_file_paths_absolute_so_the_file_works_anywhere(tmp_path, monkeypatch):
    rw = _files(tmp_path)
    monkeypatch.chdir(rw)
    sc = Scenario(vehicle="sub/mycar.toml",
                  reference=ReferenceSpec(track="tracks/circle.csv"))
    out = tmp_path / "elsewhere" / "saved.toml"
    sc.save(out)
    assert sc.vehicle == "sub/mycar.toml"  # the scenario itself is unchanged
    doc = tomllib.loads(out.read_text())
    assert doc["vehicle"] == str(rw / "sub" / "mycar.toml")
    assert doc["reference"]["track"] == str(rw / "tracks" / "circle.csv")
    monkeypatch.chdir(tmp_path)
    back = load_scenario(out)
    assert back == sc.with_(vehicle=str(rw / "sub" / "mycar.toml"), reference=ReferenceSpec(
        track=str(rw / "tracks" / "circle.csv")))
    # and that file saved again is the same file; bundled names stay names
    assert load_scenario(back.save(tmp_path / "again.toml")) == back
    rec = Scenario(reference=ReferenceSpec(track=None, recording="lvms_23_01_04_b"))
    assert load_scenario(rec.save(tmp_path / "rec.toml")) == rec
    # a path given as a Path is held and written as its text: the scenario equals itself read
    # back (it held the PosixPath, which never equals the file's text)
    assert scenario_from_toml(Scenario(vehicle=Path("a.toml")).to_toml()).vehicle == "a.toml"
    by_path = Scenario(vehicle=rw / "sub" / "mycar.toml",
                       reference=ReferenceSpec(track=rw / "tracks" / "circle.csv"))
    assert type(by_path.vehicle) is str and type(by_path.reference.track) is str
    assert load_scenario(by_path.save(tmp_path / "by_path.toml")) == by_path
    assert scenario_from_toml(by_path.to_toml()) == by_path


# ------------------------------------------------------------------------------------------
# settings "path=value" (scenario_with_settings, Scenario.with_settings, flatfree run --set)
# ------------------------------------------------------------------------------------------
def _base() -> Scenario:
    """The rich scenario with controller settings its controller (mfc-flat) takes."""
    return _rich().with_(controller_settings={"alpha_lat": 2.5, "window_lat": 20})


def _value_at(sc: Scenario, path: str):
    node = sc
    for part in path.split("."):
        if isinstance(node, SensorSuite):
            node = node.channels
        node = node[part] if isinstance(node, Mapping) else getattr(node, part)
    return node


def _flat(sc: Scenario) -> dict:
    """The scenario's TOML document as {dotted path: value}."""
    out = {}

    def walk(d, prefix):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, (*prefix, k))
            else:
                out[".".join((*prefix, k))] = v

    walk(tomllib.loads(sc.to_toml()), ())
    return out


@pytest.mark.parametrize(
    ("setting", "path", "expected"),
    [
        ("reference.j_lat_max=15", "reference.j_lat_max", 15.0),
        ("reference.j_lat_max=1.5e-3", "reference.j_lat_max", 1.5e-3),
        ("timing.plant_dt_s=5e-4", "timing.plant_dt_s", 5e-4),
        ("reference.drive_limit=false", "reference.drive_limit", False),
        ("reference.closed=false", "reference.closed", False),
        ("reference.smoothing_length_m=60", "reference.smoothing_length_m", 60.0),
        ("noise=true", "noise", True),
        ('reference.track="Monza"', "reference.track", "Monza"),
        ("reference.track=Monza", "reference.track", "Monza"),  # a bare string
        ("reference.track=data/my track.csv", "reference.track", "data/my track.csv"),
        ("name=2024", "name", "2024"),  # a string field takes the text as written
        ("description=a wet road", "description", "a wet road"),
        ("plant=3dof", "plant", "3dof"),
        ("seed=7", "seed", 7),
        ("reference.laps=3", "reference.laps", 3),
        (" road.mu = 0.8 ", "road.mu", 0.8),
        ("road.bank_deg=[[0, 0], [80, -9.2]]", "road.bank_deg", ((0.0, 0.0), (80.0, -9.2))),
        ("actuators.steer_tau_s=0.05", "actuators.steer_tau_s", 0.05),
        ("timing.duration_s=5", "timing.duration_s", 5.0),
        ("sensors.y.markov_order=2", "sensors.y.markov_order", 2),
        ("sensors.psi.noise_std=0.03", "sensors.psi.noise_std", 0.03),
        ("sensors.ay.rate_hz=100", "sensors.ay.rate_hz", 100.0),
        ("controller_settings.alpha_lat=40", "controller_settings.alpha_lat", 40),
        ("controller_settings.window_lat=30", "controller_settings.window_lat", 30),
        ("vehicle_overrides.mass=900.5", "vehicle_overrides.mass", 900.5),
        ("vehicle_overrides.iz=1000", "vehicle_overrides.iz", 1000),
    ],
)
def test_a_setting_changes_its_field_and_nothing_else(setting, path, expected):
    base = _base()
    sc = scenario_with_settings(base, [setting])
    got = _value_at(sc, path)
    assert got == expected and type(got) is type(expected), (got, expected)
    # every other field as before (a new sensor channel comes with its defaults)
    before, after = _flat(base), _flat(sc)
    changed = {k for k in before.keys() | after.keys() if before.get(k) != after.get(k)}
    parts = path.split(".")
    if parts[0] == "sensors" and parts[1] not in base.sensors.channels:
        assert path in changed and all(k.startswith(f"sensors.{parts[1]}.") for k in changed)
    else:
        assert changed == {path}
    # a round trip through TOML gives the same scenario back
    assert scenario_from_toml(sc.to_toml()) == sc
    assert _base() == base  # the base is left alone


def test_settings_inf_and_defaults_and_order():
    sc = scenario_with_settings(Scenario(), ["reference.j_lat_max=15"])
    assert sc.reference.j_lat_max == 15.0
    assert math.isinf(sc.with_settings(["reference.j_lat_max=inf"]).reference.j_lat_max)
    # applied in order: the later setting of a path wins
    assert Scenario().with_settings(["seed=1", "seed=2"]).seed == 2
    # a mapping takes values as they are; None: the field's default
    sc = Scenario().with_settings({"timing.duration_s": 3, "reference.track": "Spa"})
    assert sc.timing.duration_s == 3.0 and isinstance(sc.timing.duration_s, float)
    assert sc.reference.track == "Spa"
    assert sc.with_settings({"timing.duration_s": None}).timing.duration_s is None
    # a string with nothing after the "=" (a command line's only way to None) likewise
    shaped = sc.with_settings(["reference.closed=false", "reference.smoothing_length_m=40"])
    assert (shaped.reference.closed, shaped.reference.smoothing_length_m) == (False, 40.0)
    back = shaped.with_settings(["reference.closed=", " reference.smoothing_length_m = "])
    assert (back.reference.closed, back.reference.smoothing_length_m) == (None, None)
    assert back == sc
    assert sc.with_settings(["timing.duration_s="]).timing.duration_s is None
    assert Scenario().with_settings(["seed=3", "seed="]).seed == Scenario().seed
    # string fields too (an empty text is name="")
    moved = Scenario().with_settings(["reference.track=Monza", "name=x", "vehicle=bmw320i"])
    assert moved.with_settings(["reference.track=", "name=", "vehicle="]) == Scenario()
    assert Scenario().with_settings(['description=""']).description == ""
    # no settings: the scenario itself
    base = _rich()
    assert scenario_with_settings(base, []) is base


def test_a_mapping_setting_is_held_as_a_toml_file_holds_it():
    """A value from a mapping is stored as TOML reads it (a numpy number as a float), as if the
    setting had been read from a file."""
    sc = Scenario(controller="mfc-natural").with_settings(
        {"controller_settings.alpha_lat": np.float64(40.0)})
    got = sc.controller_settings["alpha_lat"]
    assert got == 40.0 and type(got) is float
    assert scenario_from_toml(sc.to_toml()) == sc


def test_settings_reach_channels_and_free_tables():
    base = Scenario(controller="mfc-natural")
    sc = base.with_settings(["sensors.y.markov_std=0.01", "sensors.y.markov_tau_s=60",
                             "sensors.y.markov_order=2", "controller_settings.alpha_lat=40",
                             "controller_settings.estimator_lat=imu",
                             "vehicle_overrides.mass=1500"])
    y = sc.sensors.channels["y"]
    assert (y.markov_std, y.markov_tau_s, y.markov_order, y.noise_std) == (0.01, 60.0, 2, 0.0)
    assert set(sc.sensors.channels) == {"y"}  # a new channel; the others stay absent (exact)
    assert dict(sc.controller_settings) == {"alpha_lat": 40, "estimator_lat": "imu"}
    assert dict(sc.vehicle_overrides) == {"mass": 1500}
    other = base.with_settings(["vehicle=bmw320i", "vehicle_overrides.mass=1500"])
    assert other.vehicle == "bmw320i" and dict(other.vehicle_overrides) == {"mass": 1500}
    # an inline table merges into a channel; {} empties the controller settings
    rich = _rich().with_settings(["sensors.vx={noise_std = 0.1}", "controller_settings={}"])
    assert rich.sensors.channels["vx"] == dataclasses.replace(_rich().sensors.channels["vx"],
                                                              noise_std=0.1)
    assert rich.sensors.channels["x"] == _rich().sensors.channels["x"]
    assert dict(rich.controller_settings) == {}
    assert scenario_from_toml(rich.to_toml()) == rich


def test_an_inline_table_merges_its_keys_into_the_table():
    """``reference={j_lat_max=15}`` replaced the whole reference (the track went back to
    Norisring, the other fields to their defaults): an inline table now sets each of its keys
    as ``reference.KEY=VALUE`` would, and keeps the table's other fields."""
    from flatfree.scenarios import named_scenario

    base = _rich()  # raceline, 2 laps, a_lat_max 5 and drive_limit on, not the defaults
    sc = base.with_settings(["reference={j_lat_max = 15, v_max = 40}"])
    assert sc.reference == dataclasses.replace(base.reference, j_lat_max=15.0, v_max=40.0)
    assert sc == base.with_settings(["reference.j_lat_max=15", "reference.v_max=40"])
    assert type(sc.reference.j_lat_max) is float  # as reference.j_lat_max=15 stores it
    # a free table (the controller's settings) and nested tables too
    imu = named_scenario("paper-imu")
    tuned = imu.with_settings(["controller_settings={alpha_lat = 30}"])
    assert dict(tuned.controller_settings) == {**imu.controller_settings, "alpha_lat": 30}
    assert tuned.controller_settings["estimator_lat"] == "imu"
    deep = base.with_settings(["sensors={vx = {noise_std = 0.1}, y = {bias = 0.5}}"])
    assert deep.sensors.channels["vx"] == dataclasses.replace(base.sensors.channels["vx"],
                                                              noise_std=0.1)
    assert deep.sensors.channels["y"] == SensorChannel(bias=0.5)  # a new channel: exact
    assert deep.sensors.channels["x"] == base.sensors.channels["x"]
    # a mapping's dict likewise
    assert base.with_settings({"reference": {"j_lat_max": 15}}).reference == \
        dataclasses.replace(base.reference, j_lat_max=15.0)
    # a track in it replaces the recording, as reference.track does
    rec = Scenario(reference=ReferenceSpec(track=None, recording="LVMS_23_01_04_B"))
    moved = rec.with_settings(['reference={track = "Monza", laps = 2}'])
    assert (moved.reference.track, moved.reference.recording, moved.reference.laps) == \
        ("Monza", None, 2)
    # each key is checked and named as its own setting would be
    for setting, words in (
            ("reference={j_lat_max = -1}", ["setting reference={j_lat_max = -1}:",
                                            "reference.j_lat_max = -1.0", "> 0"]),
            ("reference={wheels = 4}", ["field reference.wheels", "unknown key"]),
            ("road={patch = [1]}", ["road.patch", "replaces all of it"]),
            ('reference={track = "Spa", recording = "LVMS_23_01_04_B"}', ["not both"]),
            ("controller_settings={alpha_lat = 0}", ["alpha_lat = 0", "> 0"])):
        with pytest.raises(ValueError) as info:
            imu.with_settings([setting])
        msg = str(info.value)
        assert msg.count(setting) == 1, msg  # named once, however many keys it has
        for w in words:
            assert w in msg, (w, msg)


def test_a_table_setting_with_nothing_after_the_equals_is_its_defaults():
    """``timing=`` was refused ("timing is a table") though the help says FIELD= puts a field
    back to its default: a table's setting with nothing after the = (or {}) puts the whole
    table back to its defaults."""
    base = _rich()
    assert base.with_settings(["timing="]).timing == Timing()
    assert base.with_settings(["timing={}"]).timing == Timing()
    assert base.with_settings(["reference="]).reference == ReferenceSpec()
    assert base.with_settings(["actuators="]).actuators == Scenario().actuators
    assert base.with_settings(["road="]).road == RoadSpec()  # its patches and bank too
    assert base.with_settings({"road": None}).road == RoadSpec()
    assert base.with_settings(["sensors.vx="]).sensors.channels.keys() == {"x", "psi"}
    assert base.with_settings(["sensors="]).sensors == SensorSuite()  # every channel exact
    assert dict(base.with_settings(["controller_settings="]).controller_settings) == {}
    assert dict(base.with_settings(["vehicle_overrides="]).vehicle_overrides) == {}
    # then a field of it, in order
    sc = base.with_settings(["timing=", "timing.duration_s=4"])
    assert sc.timing == Timing(duration_s=4.0)
    # anything else than a table or nothing is refused, saying what a table takes
    with pytest.raises(ValueError, match=r"timing is a table: .*nothing after the = for its "
                                         r"defaults"):
        base.with_settings(["timing=3"])


def test_setting_a_recording_replaces_the_track_and_back():
    track = Scenario()
    rec = track.with_settings(["reference.recording=LVMS_23_01_04_B"])
    assert rec.reference.recording == "LVMS_23_01_04_B" and rec.reference.track is None
    assert rec.reference.line == track.reference.line  # the rest of the reference kept
    back = rec.with_settings(["reference.track=Monza"])
    assert back.reference.track == "Monza" and back.reference.recording is None
    with pytest.raises(ValueError) as info:
        track.with_settings(["reference.track=Spa", "reference.recording=LVMS"])
    msg = str(info.value)
    assert "reference.track=Spa" in msg and "reference.recording=LVMS" in msg
    assert "not both" in msg


@pytest.mark.parametrize(
    ("settings", "words"),
    [
        (["seed"], ["setting seed:", "FIELD=VALUE"]),
        (["=3"], ["setting =3", "empty part"]),
        (["reference..mu=1"], ["setting reference..mu=1", "empty part"]),
        (["seed.x=1"], ["setting seed.x=1", "seed = 42 is not a table"]),
        (["reference.track.x=1"], ["reference.track = 'Norisring' is not a table"]),
        (["fault.kind=steer_limit"], ["setting fault.kind=steer_limit", "[[fault]]",
                                      "replaces all of it", "one entry's field"]),
        (["road.patch.mu=0.5"], ["setting road.patch.mu=0.5", "[[road.patch]]",
                                 "one entry's field"]),
        (["road.patch=3"], ["setting road.patch=3", "replaces all of it"]),
        (["fault=[1, 2]"], ["setting fault=[1, 2]", "replaces all of it"]),
        (['fault=[{kind = "nan_measurement", channel = "x"}]'],
         ["field fault", "missing key"]),
        (["wheels=4"], ["setting wheels=4", "field wheels", "unknown key"]),
        (["wheels.front=4"], ["setting wheels.front=4", "wheels is not a table"]),
        (["timing.x.y=1"], ["setting timing.x.y=1", "timing has no table 'x'"]),
        (["timing.control_dt=0.002"], ["setting timing.control_dt=0.002",
                                       "field timing.control_dt", "unknown key",
                                       "control_dt_s"]),
        (["reference=3"], ["setting reference=3", "reference is a table"]),
        (["sensors.vx=0.1"], ["setting sensors.vx=0.1", "sensors.vx is a table"]),
        (["sensors.vxx.noise_std=0.1"], ["setting sensors.vxx.noise_std=0.1",
                                         "not a measured channel", "vx"]),
        (["reference.j_lat_max=nan"], ["setting reference.j_lat_max=nan",
                                       "field reference.j_lat_max", "= nan", "must be > 0"]),
        (["reference.j_lat_max=-1"], ["reference.j_lat_max = -1.0", "must be > 0"]),
        (["reference.laps=inf"], ["setting reference.laps=inf", "reference.laps = inf",
                                  "integer >= 1"]),
        (["reference.laps=nan"], ["reference.laps = nan", "integer >= 1"]),
        (["reference.laps=1.5"], ["reference.laps = 1.5", "integer >= 1"]),
        (["reference.line=middle"], ["setting reference.line=middle", "'middle'",
                                     "centerline, raceline"]),
        (["reference.a_lat_max=\"6\""], ["setting reference.a_lat_max=\"6\"",
                                         "reference.a_lat_max = '6' m/s^2",
                                         "expected a real number"]),
        (["reference.a_lat_max=fast"], ["reference.a_lat_max = 'fast' m/s^2",
                                        "expected a real number"]),
        (["seed=true"], ["setting seed=true", "seed = True", "must be an integer >= 0"]),
        (["seed=-1"], ["setting seed=-1", "seed = -1", "integer >= 0"]),
        (["noise=yes"], ["setting noise=yes", "noise = 'yes'", "true or false"]),
        (["sensors.y.markov_order=3"], ["setting sensors.y.markov_order=3",
                                        "field sensors.y.markov_order", "markov_order = 3"]),
        (["sensors.y.noise_std=nan"], ["sensors.y.noise_std", "noise_std = nan", "finite"]),
        (["road.mu=0"], ["setting road.mu=0", "road.mu = 0.0", "> 0"]),
        (["road.bank_deg=[[0, 0], [0, 1]]"], ["road.bank_deg[1] = [0, 1]", "increase"]),
        (["road.bank_deg=5"], ["setting road.bank_deg=5", "road.bank_deg = 5", "points"]),
        (["actuators.steer_delay_s=-0.1"], ["actuators.steer_delay_s = -0.1", ">= 0"]),
        # the error names the setting that broke a rule about another field
        (["seed=3", "timing.plant_dt_s=0.003"],
         ["setting timing.plant_dt_s=0.003", "timing.control_dt_s", "whole multiple"]),
        (["controller_settings.alpha_lon=-1"], ["setting controller_settings.alpha_lon=-1",
                                                "alpha_lon = -1", "> 0"]),
        (["controller_settings.alpha_lat=0"], ["setting controller_settings.alpha_lat=0",
                                               "alpha_lat = 0", "nonzero"]),
        (["controller_settings.alpha_lat=nan"], ["alpha_lat = nan", "finite"]),
        (["controller_settings.lanes=2"], ["setting controller_settings.lanes=2", "'lanes'",
                                           "unknown for mfc-flat"]),
        (["controller=flatness"], ["setting controller=flatness", "unknown for flatness",
                                   "controller_settings= (nothing after the =)"]),
        (["vehicle=trabant"], ["setting vehicle=trabant", "unknown vehicle 'trabant'"]),
        (["vehicle_overrides.mass=nan"], ["setting vehicle_overrides.mass=nan",
                                          "mass = nan kg", "finite"]),
    ],
)
def test_bad_settings_name_the_setting_and_the_value(settings, words):
    with pytest.raises(ValueError) as info:
        scenario_with_settings(_base(), settings)
    msg = str(info.value)
    for w in words:
        assert w in msg, (w, msg)


def test_every_number_of_a_scenario_refuses_nan():
    """No silent NaN: a setting ``nan`` of any numeric field (and of a controller setting) is
    refused, naming the field."""
    sc = _base()
    paths = [k for k, v in _flat(sc).items()
             if isinstance(v, (int, float)) and not isinstance(v, bool)]
    paths += ["timing.duration_s", "sensors.x.rate_hz", "sensors.x.markov_tau_s"]
    assert len(paths) > 30
    for path in paths:
        with pytest.raises(ValueError) as info:
            sc.with_settings([f"{path}=nan"])
        msg = str(info.value)
        assert msg.startswith(f"setting {path}=nan: "), msg
        # the field named again by the validator (but int() of a controller's window says
        # only "cannot convert float NaN to integer")
        if path != "controller_settings.window_lat":
            assert path.rsplit(".", 1)[-1] in msg.split(":", 1)[1], msg
            assert "nan" in msg.split(":", 1)[1], msg


def test_settings_must_be_a_sequence_or_a_mapping():
    with pytest.raises(TypeError, match="expected a sequence"):
        scenario_with_settings(Scenario(), "seed=3")
    with pytest.raises(TypeError, match="expected a string"):
        scenario_with_settings(Scenario(), [("seed", 3)])


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("reference = 3\n", ["field reference", "expected a table"]),
        ("[road]\npatch = 3\n", ["road.patch", "array of tables"]),
        ("fault = [1]\n", ["field fault", "array of tables"]),
        ("[road]\npatches = []\n", ["line 2", "road.patches", "unknown key"]),
        ("[reference]\nlaps = inf\n", ["line 2", "reference.laps = inf", "integer >= 1"]),
        ("[reference]\nlaps = true\n", ["reference.laps = True", "integer >= 1"]),
    ],
)
def test_malformed_tables_in_a_file_are_value_errors(text, words):
    with pytest.raises(ValueError) as info:
        scenario_from_toml(text, source="f.toml")
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_a_car_the_model_free_settings_were_not_tuned_on_is_warned_about(tmp_path):
    """A car file, whatever it holds (here the dallara_av21's own file renamed), or a bundled
    preset without a tuning runs the peugeot406's alpha_lat, and so does a tuned car whose
    scenario's settings leave alpha_lat at that default: every run says so (prepare), however
    the scenario was built. Not for the tuned cars on their tuning, for the flatness
    controller (its model is the car's), or when controller_settings set alpha_lat."""
    import shutil

    from flatfree.scenarios import named_scenario
    from flatfree.simulation import prepare
    from flatfree.vehicles.params import vehicle_file

    copy = tmp_path / "my_formula.toml"
    shutil.copy(vehicle_file("dallara_av21"), copy)
    for name, car in (("paper", "bmw320i"), ("paper", str(copy)), ("paper-imu", "bmw320i"),
                      ("paper-mfc-flat", "dallara_av21")):
        sc = named_scenario(name, vehicle=car, duration_s=1.0)
        with pytest.warns(UserWarning, match="alpha_lat") as got:
            prepare(sc)
        assert any(str(w.message).startswith(f"vehicle {car!r}: the ") for w in got)
    # a tuned car whose scenario's settings are not its tuning: the tuned value is named
    # (the flat-output scenario's {} kept by a bare change of the controller, or the car
    # changed under the peugeot406's settings)
    for sc in (named_scenario("paper-flatness", vehicle="dallara_av21",
                              duration_s=1.0).with_settings(["controller=mfc-natural"]),
               named_scenario("paper", duration_s=1.0).with_(vehicle="dallara_av21"),
               # and its estimator changed on the way: 48.9 is still the peugeot406's
               named_scenario("paper", duration_s=1.0).with_(vehicle="dallara_av21")
               .with_settings(["controller_settings.estimator_lat=imu"])):
        with pytest.warns(UserWarning, match=r"alpha_lat at (its default 30 \(the "
                                             r"peugeot406's tuning with estimator_lat = 'imu', "
                                             r"not with the 'algebraic' one in use\)|"
                                             r"48.9 \(peugeot406's\))") as got:
            prepare(sc)
        assert any("set controller_settings.alpha_lat = 60" in str(w.message) for w in got)
    # the default 30 is the peugeot406's inertial-unit tuning, not its algebraic one (48.9):
    # the warning said "its default 30 (the peugeot406's)" with either estimator
    car = str(copy)
    for extra, note in (([], ("the peugeot406's tuning with estimator_lat = 'imu', not with "
                              "the 'algebraic' one in use")),
                        (["controller_settings.estimator_lat=imu"],
                         "the peugeot406's tuning with estimator_lat = 'imu')")):
        sc = named_scenario("paper", vehicle=car, duration_s=1.0).with_settings(
            ["controller_settings=", "controller_settings.wn_lat=6", *extra])
        with pytest.warns(UserWarning, match="alpha_lat") as got:
            prepare(sc)
        msg = next(str(w.message) for w in got if "alpha_lat" in str(w.message))
        assert f"alpha_lat at its default 30 ({note}" in msg, msg
    # an untuned car's message quotes its steer gain beside the tuned cars' (the algebraic
    # estimator's: the peugeot406's 48.9; with the inertial one its 30, the defaults')
    with pytest.warns(UserWarning, match=r"this car's 119; peugeot406: 65, tuned 30; "
                                         r"dallara_av21: 95, tuned 60"):
        prepare(named_scenario("paper-imu", vehicle="bmw320i", duration_s=1.0))
    with pytest.warns(UserWarning, match=r"this car's 119; peugeot406: 65, tuned 48.9; "
                                         r"dallara_av21: 95, tuned 60"):
        prepare(named_scenario("paper", vehicle="bmw320i", duration_s=1.0))
    retuned = named_scenario("paper", vehicle="bmw320i", duration_s=1.0).with_settings(
        ["controller_settings.alpha_lat=35"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the dallara's steer lock on Norisring's hairpin
        warnings.filterwarnings("error", message="vehicle .* alpha_lat")
        for sc in (named_scenario("paper", vehicle="Peugeot406", duration_s=1.0),
                   named_scenario("paper", vehicle="dallara_av21", duration_s=1.0),
                   named_scenario("paper-imu", vehicle="dallara_av21", duration_s=1.0),
                   named_scenario("paper-flatness", vehicle="bmw320i", duration_s=1.0),
                   named_scenario("paper-mismatch", vehicle=str(copy), duration_s=1.0),
                   retuned):
            prepare(sc)


def test_the_arrays_of_tables_are_set_whole_and_cleared():
    """``fault=[{...}, ...]`` and ``road.patch=[{...}]`` replace the arrays of tables (each
    entry checked as a [[fault]] table is), ``fault=`` and ``[]`` clear them: the faults of a
    scenario could not be removed from the command line."""
    from flatfree.scenario import Fault, FrictionPatch

    base = Scenario()
    one = base.with_settings([('fault=[{kind = "nan_measurement", channel = "x", '
                              't_start_s = 2.0, duration_s = 0.05}]')])
    assert one.faults == (Fault(kind="nan_measurement", channel="x", t_start_s=2.0,
                                duration_s=0.05),)
    two = one.with_settings([('fault=[{kind = "steer_limit", t_start_s = 1, duration_s = 1, '
                             'value = 0.01}, {kind = "nan_measurement", channel = "y", '
                             't_start_s = 3, duration_s = 0.1}]')])
    assert [f.kind for f in two.faults] == ["steer_limit", "nan_measurement"]
    for clear in ("fault=", "fault=[]"):
        assert two.with_settings([clear]).faults == ()
    assert two.with_settings({"fault": None}).faults == ()
    patched = base.with_settings(["road.patch=[{s_start_m = 0, s_end_m = 80, mu = 0.5}]"])
    assert patched.road.patches == (FrictionPatch(s_start_m=0.0, s_end_m=80.0, mu=0.5),)
    assert patched.road.mu == base.road.mu
    assert patched.with_settings(["road={patch = []}"]).road.patches == ()
    # a round trip through the file keeps them
    assert scenario_from_toml(two.to_toml()) == two
