"""Vehicle and tyre parameter types: presets load, values are validated, data files cite sources."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from flatfree.units import G
from flatfree.vehicles import (
    TP,
    VP,
    TireParams,
    load_tire,
    load_vehicle,
    tire_names,
    vehicle_names,
)


def test_bundled_names():
    assert vehicle_names() == ["bmw320i", "dallara_av21", "peugeot406"]
    assert tire_names() == ["commonroad", "pacejka2006_205_60R15"]


@pytest.mark.parametrize("name", ["bmw320i", "dallara_av21", "peugeot406"])
def test_presets_load_and_static_loads_sum_to_weight(name):
    v = load_vehicle(name)
    assert v.name == name
    front, rear = v.static_axle_loads
    assert front + rear == pytest.approx(v.mass * G, rel=1e-12)
    # moment balance about the CoG: front * lf == rear * lr
    assert front * v.lf == pytest.approx(rear * v.lr, rel=1e-12)


def test_names_are_case_insensitive():
    assert load_vehicle("PEUGEOT406") == load_vehicle("peugeot406")
    assert load_tire("Pacejka2006_205_60r15") == load_tire("pacejka2006_205_60R15")


def test_unknown_name_lists_valid_ones():
    with pytest.raises(ValueError, match="valid names: bmw320i, dallara_av21, peugeot406"):
        load_vehicle("trabant")
    with pytest.raises(ValueError, match=r"^unknown tire set 'michelin'; valid names: "
                                         r"commonroad, pacejka2006_205_60R15$"):
        load_tire("michelin")


def test_bundled_name_is_the_loaders_lookup(tmp_path, monkeypatch):
    """One name lookup (case-insensitive, surrounding blanks ignored, as the tracks') that the
    loaders use and the scenario spells its car with; a file of that name (or a .toml path) is
    read first."""
    from flatfree.vehicles.params import bundled_name

    assert bundled_name("Dallara_AV21") == "dallara_av21"
    assert bundled_name("PACEJKA2006_205_60r15", "tire") == "pacejka2006_205_60R15"
    assert bundled_name("peugeot406", "tire") is None
    for other in ("trabant", "peugeot406.toml", " peugeot406.toml", 406, None, ""):
        assert bundled_name(other) is None, other
    with pytest.raises(ValueError, match=r"^kind = 'car': must be one of vehicle, tire$"):
        bundled_name("peugeot406", "car")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "PEUGEOT406").write_text("not = [toml")
    with pytest.raises(ValueError, match="malformed TOML"):
        load_vehicle("PEUGEOT406")
    # a folder is no vehicle file: the bundled preset
    (tmp_path / "bmw320i").mkdir()
    assert load_vehicle("bmw320i") == load_vehicle("BMW320I")


def test_bmw320i_is_commonroad_set_2():
    """The peer's own numbers (parameters_vehicle2) must be what the preset holds."""
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2

    cr = parameters_vehicle2()
    v = load_vehicle("bmw320i")
    assert v.mass == cr.m
    assert v.sprung_mass == cr.m_s
    assert v.lf == cr.a and v.lr == cr.b
    assert v.iz == cr.I_z and v.ix_s == cr.I_Phi_s and v.iy_s == cr.I_y_s
    assert v.track_front == cr.T_f and v.track_rear == cr.T_r
    assert v.cog_height == pytest.approx(cr.h_cg, rel=1e-12)  # CR stores 0.5748689544000001
    assert v.spring_front == cr.K_sf and v.spring_rear == cr.K_sr
    assert v.damper_front == cr.K_sdf and v.damper_rear == cr.K_sdr
    assert v.arb_front == -cr.K_tsf and v.arb_rear == -cr.K_tsr
    assert v.wheel_radius == cr.R_w and v.wheel_inertia_front == cr.I_y_w
    assert v.brake_balance_front == cr.T_sb
    assert v.max_steer == cr.steering.max and v.max_steer_rate == cr.steering.v_max
    assert v.drive == "rear" and cr.T_se == 0
    assert v.max_drive_torque == pytest.approx(cr.m * cr.R_w * cr.longitudinal.a_max, rel=1e-4)
    assert v.max_power == pytest.approx(
        cr.m * cr.longitudinal.a_max * cr.longitudinal.v_switch, rel=1e-4
    )


def test_commonroad_tire_set_matches_peer_except_documented_shifts():
    """Every coefficient equals CommonRoad's, except the shifts zeroed to symmetrise the tyre."""
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2

    cr = parameters_vehicle2().tire
    t = load_tire("commonroad")
    zeroed = {"phx1", "pvx1", "phy1", "pvy1", "rhx1", "rhy1", "rvy1", "rby3"}
    compared = 0
    for ours in _TIRE_COEFFS:
        theirs = getattr(cr, f"{ours[0]}_{ours[1:]}", None)
        if theirs is None:
            continue
        compared += 1
        if ours in zeroed:
            assert getattr(t, ours) == 0.0, ours
            assert theirs != 0.0, ours
        else:
            assert getattr(t, ours) == theirs, ours
    assert compared >= 25
    assert t.cornering_law == "proportional"


_TIRE_COEFFS = [
    f.name
    for f in dataclasses.fields(TireParams)
    if f.name[:1] in ("p", "r") and f.name[1:2] in ("c", "d", "e", "k", "h", "v", "b")
]


def test_peugeot406_estimates_match_the_reference_sheet():
    """VEHICLE_MODEL.md 4.2: K_phi front/rear 38,600 / 25,700 N m/rad, yaw index 1.0, 60% front.

    The sheet rounds K_phi to 100 N m/rad, so the exact value lies within half of that: abs=50
    (as test_bicycle3dof does for C_f / C_r); rel=5e-3 allowed ~190 N m/rad. The data give
    38,563 / 25,668 N m/rad (37 / 32 off the sheet)."""
    v = load_vehicle("peugeot406")
    k_phi_f = v.spring_front * v.track_front**2 / 2 + v.arb_front
    k_phi_r = v.spring_rear * v.track_rear**2 / 2 + v.arb_rear
    assert k_phi_f == pytest.approx(38_600, abs=50.0)
    assert k_phi_r == pytest.approx(25_700, abs=50.0)
    assert v.yaw_index == pytest.approx(1.0, abs=0.01)
    assert v.static_axle_loads[0] / (v.mass * G) == pytest.approx(0.60, abs=1e-9)
    assert v.wheelbase == 2.70 and v.drive == "front"


def test_dallara_lf_lr_follow_the_corner_weights_not_the_swapped_upstream():
    """Corner weights give 40.5% on the front axle (sheet 4.3); upstream lf/lr (58% front) look
    swapped."""
    v = load_vehicle("dallara_av21")
    front_share = v.static_axle_loads[0] / (v.mass * G)
    assert 0.40 <= front_share <= 0.44
    assert v.lf > v.lr
    assert v.drive == "rear"
    assert v.iz == 1000.0 and v.mass == 790.0
    # Iz < lf lr m: the flatness controller has a singular speed for this car (NOTES.md)
    assert v.yaw_index < 1.0


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("mass", -1.0, ["mass", "-1.0", "kg", "> 0"]),
        ("mass", 0.0, ["mass", "0.0", "kg"]),
        ("mass", math.nan, ["mass", "nan", "kg", "finite"]),
        ("iz", math.inf, ["iz", "inf", "kg m^2"]),
        ("wheel_radius", -0.3, ["wheel_radius", "m"]),
        ("brake_balance_front", 1.5, ["brake_balance_front", "1.5"]),
        ("rolling_resistance", -0.01, ["rolling_resistance", "-0.01"]),
        ("max_steer_rate", 0.0, ["max_steer_rate", "rad/s"]),
        ("drive", "all", ["drive", "'all'"]),
        ("mass", "heavy", ["mass", "'heavy'", "real number"]),
    ],
)
def test_bad_values_raise_naming_field_value_and_unit(field, value, words):
    v = load_vehicle("peugeot406")
    with pytest.raises(ValueError) as info:
        dataclasses.replace(v, **{field: value})
    for w in words:
        assert w in str(info.value)


def test_wheelbase_inconsistent_with_lf_lr():
    v = load_vehicle("peugeot406")
    with pytest.raises(ValueError, match=r"lf \+ lr = 2\.8.* wheelbase = 2\.7 m"):
        dataclasses.replace(v, lf=1.18)
    # within 1 mm passes
    dataclasses.replace(v, lf=1.0805)


def test_sprung_mass_above_total_mass():
    v = load_vehicle("peugeot406")
    with pytest.raises(ValueError, match="sprung_mass = 1600.0 kg"):
        dataclasses.replace(v, sprung_mass=1600.0)


def test_overrides_are_validated():
    assert load_vehicle("peugeot406", mass=1360.0).mass == 1360.0
    with pytest.raises(ValueError, match=r"^mass = -5\.0 kg: must be > 0$"):
        load_vehicle("peugeot406", mass=-5.0)
    with pytest.raises(ValueError, match=r"^mass = True kg: expected a real number$"):
        load_vehicle("peugeot406", mass=True)
    with pytest.raises(ValueError, match=r"^vehicle overrides \['masss'\]: not parameters of "
                                         r"a vehicle; valid: .*\bmass\b"):
        load_vehicle("peugeot406", masss=1.0)


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("fz0", 0.0, ["fz0", "N", "> 0"]),
        ("pky1", 5.0, ["pky1", "< 0"]),
        ("pdy1", 0.0, ["pdy1"]),
        ("pcx1", math.nan, ["pcx1", "nan"]),
        ("cornering_law", "linear", ["cornering_law", "'linear'"]),
        ("relaxation_length_y", -0.1, ["relaxation_length_y", "m"]),
    ],
)
def test_bad_tire_values(field, value, words):
    t = load_tire("pacejka2006_205_60R15")
    with pytest.raises(ValueError) as info:
        dataclasses.replace(t, **{field: value})
    for w in words:
        assert w in str(info.value)


def test_arrays_follow_their_index_enums():
    v = load_vehicle("dallara_av21")
    a = v.to_array()
    assert a.dtype == np.float64 and a.shape == (len(VP),)
    assert a[VP.mass] == 790.0 and a[VP.lf] == v.lf and a[VP.drive] == 1.0
    assert a[VP.lift_area_rear] == -1.18
    t = v.tire_front.to_array()
    assert t.shape == (len(TP),)
    assert t[TP.pky1] == -21.92 and t[TP.lambda_ky] == 1.05 and t[TP.cornering_law] == 1.0


def _write(tmp_path, text):
    p = tmp_path / "car.toml"
    p.write_text(text, encoding="utf-8")
    return p


def _preset_text(name="peugeot406"):
    from importlib import resources

    return (resources.files("flatfree.vehicles") / "data" / f"{name}.toml").read_text("utf-8")


def test_user_file_loads_like_a_preset(tmp_path):
    p = _write(tmp_path, _preset_text())
    assert load_vehicle(p) == load_vehicle("peugeot406")
    assert load_vehicle(str(p)).mass == 1500.0


def test_file_with_wrong_unit_is_refused(tmp_path):
    text = _preset_text().replace('value = 1500.0, unit = "kg"', 'value = 1500.0, unit = "lb"')
    with pytest.raises(ValueError, match="'mass' is given in 'lb', expected 'kg'"):
        load_vehicle(_write(tmp_path, text))


def test_file_without_source_is_refused(tmp_path):
    lines = [
        line if not line.startswith("mass ") else
        'mass = { value = 1500.0, unit = "kg", source = "" }'
        for line in _preset_text().splitlines()
    ]
    with pytest.raises(ValueError, match="'mass' cites no source"):
        load_vehicle(_write(tmp_path, "\n".join(lines)))


def test_file_with_unknown_or_missing_parameter(tmp_path):
    text = _preset_text() + '\nwings = { value = 2.0, unit = "-", source = "x" }\n'
    with pytest.raises(ValueError, match="unknown parameter 'wings'"):
        load_vehicle(_write(tmp_path, text))
    text = "\n".join(ln for ln in _preset_text().splitlines() if not ln.startswith("iz "))
    with pytest.raises(ValueError, match=r"missing parameter\(s\) iz"):
        load_vehicle(_write(tmp_path, text))


def test_malformed_toml_names_the_file(tmp_path):
    p = _write(tmp_path, "name = \n")
    with pytest.raises(ValueError, match="malformed TOML"):
        load_vehicle(p)


def test_vehicle_and_tire_names_ignore_surrounding_blanks():
    """The vehicle lookup is the tracks' (flatfree._names): ``" peugeot406"`` used to be an
    "unknown vehicle"; a ``.toml`` suffix stays a path (read as a file, not a name)."""
    from flatfree.vehicles.params import bundled_name

    assert bundled_name(" peugeot406") == "peugeot406"
    assert bundled_name("\tDallara_AV21 \n") == "dallara_av21"
    assert bundled_name(" Pacejka2006_205_60r15 ", "tire") == "pacejka2006_205_60R15"
    assert load_vehicle(" peugeot406") == load_vehicle("peugeot406")
    assert load_tire(" commonroad ") == load_tire("commonroad")
    with pytest.raises(ValueError, match=r"^tire  peugeot406\.toml: file not found: "):
        load_tire(" peugeot406.toml")


@pytest.mark.parametrize("value", ["car.v2", "cars/mine", "cars\\mine"])
def test_a_value_that_looks_like_a_path_is_a_missing_file_for_every_loader(value):
    """One rule (flatfree._names.looks_like_path) for the vehicle, tyre, track and recording
    loaders and a scenario file's values: a folder separator or a suffix makes a path, so a
    missing one is "file not found", not an unknown name."""
    from flatfree.tracks import load_recording, load_track

    for load in (load_vehicle, load_tire, load_track, load_recording):
        with pytest.raises(ValueError, match="file not found"):
            load(value)


_PJ = "pacejka2006_205_60R15"


def _tire_text(name=_PJ):
    from importlib import resources

    folder = resources.files("flatfree.vehicles") / "data" / "tires"
    return (folder / f"{name}.toml").read_text("utf-8")


def _with_tires(front, rear=f'"{_PJ}"'):
    """The peugeot406 preset's text with its tyre lines replaced."""
    text = _preset_text()
    old = f'tire_front = "{_PJ}"\ntire_rear = "{_PJ}"\n'
    assert old in text
    return text.replace(old, f"tire_front = {front}\ntire_rear = {rear}\n")


def test_a_tyre_path_in_a_vehicle_file_is_relative_to_its_folder(tmp_path, monkeypatch):
    """As a scenario file's paths: read from another directory, a vehicle file's relative tyre
    path is the file next to it (not one in the current directory); a missing one's error names
    the vehicle file and where the tyre was looked for; bundled names and absolute paths stay."""
    cars, elsewhere = tmp_path / "cars", tmp_path / "elsewhere"
    (cars / "sub").mkdir(parents=True)
    elsewhere.mkdir()
    (cars / "mytire.toml").write_text(_tire_text().replace(f'name = "{_PJ}"', 'name = "mine"'))
    (cars / "sub" / "rear.toml").write_text(_tire_text("commonroad"))
    (elsewhere / "mytire.toml").write_text("not = [toml")  # the current directory's: not read
    monkeypatch.chdir(elsewhere)
    car = _write(cars, _with_tires('"mytire.toml"', '"sub/rear.toml"'))
    v = load_vehicle(car)
    assert v.tire_front == dataclasses.replace(load_tire(_PJ), name="mine")
    assert v.tire_rear == load_tire("commonroad")
    same = load_vehicle(_write(cars, _with_tires(f'"{cars / "mytire.toml"}"', f'"{_PJ}"')))
    assert same.tire_front == v.tire_front and same.tire_rear == load_tire(_PJ)
    car = _write(cars, _with_tires('"none.toml"'))
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: tire_front: "
                                         rf"tire none\.toml: file not found: "
                                         rf"{re.escape(str(cars / 'none.toml'))}$"):
        load_vehicle(car)


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (lambda text: "steering_ratio = 15.5\n" + text, "steering_ratio"),
        (lambda text: text.replace("[params]", "[param]"), "param"),
        (lambda text: text + '\n[param]\nmass = { value = 1.0, unit = "kg", source = "x" }\n',
         "param"),
    ],
    ids=["key", "misspelt-params", "extra-table"],
)
def test_a_vehicle_file_with_an_unknown_key_or_table_is_refused(tmp_path, change, key):
    """A top-level key or table the loader does not read (a misspelt ``[params]``, a parameter
    outside it) was ignored: the car loaded without it."""
    car = _write(tmp_path, change(_preset_text()))
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: unknown "
                                         rf"key\(s\) '{key}'; valid: name, drive, tire_front, "
                                         r"tire_rear, params$"):
        load_vehicle(car)


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (lambda text: text.replace("cornering_law =", "corneringlaw ="), "corneringlaw"),
        (lambda text: text.replace("[coefficients]", "[coeficients]"), "coeficients"),
        (lambda text: text + '\n[coefficient]\npdy1 = { value = 1.0, source = "x" }\n',
         "coefficient"),
    ],
    ids=["key", "misspelt-table", "extra-table"],
)
def test_a_tyre_file_with_an_unknown_key_or_table_is_refused(tmp_path, change, key):
    """As a vehicle file: a top-level key the loader does not read was ignored (a misspelt
    cornering_law gave the default "mf52" law silently); refused, naming the file and the key."""
    f = tmp_path / "tyre.toml"
    f.write_text(change(_tire_text("commonroad")), encoding="utf-8")
    with pytest.raises(ValueError, match=rf"^tire file {re.escape(str(f))}: unknown "
                                         rf"key\(s\) '{key}'; valid: name, cornering_law, "
                                         r"coefficients$"):
        load_tire(f)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        (f'{{ set = "{_PJ}", lambda_ky = 0.9, lamda_kx = 1.1, source = "x" }}',
         (r"unknown key\(s\) 'lamda_kx'; valid: set, source, name, .*, lambda_kx, "
          r"relaxation_length_x, relaxation_length_y$")),
        (f'{{ set = "{_PJ}", lambda_ky = 0.9, unit = "-", source = "x" }}',
         r"unknown key\(s\) 'unit'; valid: set, source, "),
        ('{ sett = "commonroad" }', r"unknown key\(s\) 'sett'; valid: set, "),
        ("{ set = 5 }", r"tire entry \{'set': 5\} is neither a set name or path nor a table "),
        ("5", r"tire entry 5 is neither a set name or path nor a table "),
    ],
    ids=["misspelt-key", "unit", "misspelt-set", "set-not-a-name", "not-a-name"],
)
def test_a_bad_tyre_entry_names_the_file_the_side_and_the_key(tmp_path, entry, message):
    """An unknown key in a tyre table (or a set that is no name) was a raw TypeError."""
    car = _write(tmp_path, _with_tires(f'"{_PJ}"', entry))
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: tire_rear: "
                                         + message):
        load_vehicle(car)


def test_errors_building_a_vehicle_from_a_file_name_the_file(tmp_path):
    """A value the file holds that VehicleParams or TireParams refuses: the error names the file
    (and the tyre's side); built in Python, the same errors are unchanged."""
    car = _write(tmp_path, _preset_text().replace("value = 1.08,", "value = 1.5,"))
    lf = r"lf \+ lr = 3\.12 m is inconsistent with wheelbase = 2\.7 m"
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: {lf}"):
        load_vehicle(car)
    with pytest.raises(ValueError, match=rf"^{lf}"):
        dataclasses.replace(load_vehicle("peugeot406"), lf=1.5)
    car = _write(tmp_path, _preset_text().replace("value = 1500.0,", 'value = "1500",'))
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: "
                                         r"mass = '1500' kg: expected a real number$"):
        load_vehicle(car)
    car = _write(tmp_path, _with_tires(f'{{ set = "{_PJ}", lambda_ky = -0.9, source = "x" }}'))
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: tire_front: "
                                         r"lambda_ky = -0\.9: must be > 0$"):
        load_vehicle(car)
    tire = tmp_path / "bad.toml"
    tire.write_text(_tire_text().replace("pkx1 = { value = 21.51", "pkx1 = { value = -21.51"))
    bad = r"pkx1 = -21\.51: the slip stiffness factor must be > 0$"
    with pytest.raises(ValueError, match=rf"^tire file {re.escape(str(tire))}: {bad}"):
        load_tire(tire)
    car = _write(tmp_path, _with_tires('"bad.toml"'))
    with pytest.raises(ValueError, match=rf"^vehicle file {re.escape(str(car))}: tire_front: "
                                         rf"tire file {re.escape(str(tire))}: {bad}"):
        load_vehicle(car)
    with pytest.raises(ValueError, match=rf"^{bad}"):
        dataclasses.replace(load_tire(_PJ), pkx1=-21.51)


def test_a_preset_is_read_once_and_overrides_leave_it_alone(tmp_path):
    """A bundled preset is read once per process (vehicles.params._preset) and shared: the same
    object in any spelling; overrides make a new one and leave the shared preset as it was; a
    file is read on every call (a changed file is seen)."""
    a = load_vehicle("peugeot406")
    assert load_vehicle(" PEUGEOT406 ") is a
    heavier = load_vehicle("peugeot406", mass=a.mass + 100.0)
    assert heavier.mass == a.mass + 100.0 and load_vehicle("peugeot406").mass == a.mass
    car = _write(tmp_path, _preset_text())
    assert load_vehicle(car) == a and load_vehicle(car) is not a
    car.write_text(_preset_text().replace("value = 1500.0", "value = 1510.0", 1))
    assert load_vehicle(car).mass == 1510.0
