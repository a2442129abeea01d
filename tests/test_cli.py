"""The ``flatfree`` command line (issue 8), through click's CliRunner.

Every error path of the issue is exercised: unknown names list the valid ones, a malformed TOML
file names the line and the field, exit codes are 0 (completed), 1 (status not completed) and 2
(bad usage or input). Runs are kept short (``--duration``) so that the file stays fast; the
closed-loop numbers themselves are the engine's business (tests/test_simulation.py): here only
the plumbing is checked against independent computations.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from flatfree.cli import (
    CORNER_MERGE_GAP_M,
    CORNER_MIN_LENGTH_M,
    CORNER_RADIUS_M,
    JSON_KEYS,
    SCENARIO_TEMPLATE,
    count_corners,
    main,
)
from flatfree.scenario import (
    CONTROLLERS,
    Fault,
    Scenario,
    Timing,
    load_scenario,
    scenario_from_toml,
)
from flatfree.tracks import track_names
from flatfree.trajectory import Trajectory
from flatfree.vehicles import vehicle_names

SHORT = ["--duration", "3"]


@pytest.fixture
def runner():
    return CliRunner()


def _invoke(runner, args, **kw):
    return runner.invoke(main, args, catch_exceptions=False, **kw)


# ------------------------------------------------------------------------------------------
# help, tracks, vehicles
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", [[], ["run"], ["demo"], ["tracks"], ["vehicles"],
                                 ["scenario"], ["scenario", "new"], ["scenario", "list"],
                                 ["bench"]])
def test_help_everywhere_with_examples(runner, cmd):
    res = _invoke(runner, [*cmd, "--help"])
    assert res.exit_code == 0
    assert "Usage:" in res.stdout
    assert "Examples:" in res.stdout


def test_unknown_command_is_usage_error(runner):
    res = _invoke(runner, ["fly"])
    assert res.exit_code == 2
    assert "No such command" in res.stderr


def test_tracks_json_lists_every_bundled_track_and_the_recording(runner):
    res = _invoke(runner, ["tracks", "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    assert [t["name"] for t in doc["tracks"]] == track_names()
    for t in doc["tracks"]:
        assert t["length_m"] > 1000.0 and t["corners"] >= 2 and t["closed"]
        assert ("GPL-3.0" if t["name"] == "LVMS" else "LGPL-3.0") in t["license"]
    ims = next(t for t in doc["tracks"] if t["name"] == "IMS")
    assert ims["corners"] == 4  # the Indianapolis oval: four turns
    assert doc["recordings"][0]["name"] == "LVMS_23_01_04_B"
    assert "GPL-3.0" in doc["recordings"][0]["license"]
    text = _invoke(runner, ["tracks"]).stdout
    assert all(n in text for n in track_names())


def test_vehicles(runner):
    res = _invoke(runner, ["vehicles", "--json"])
    doc = json.loads(res.stdout)
    assert [v["name"] for v in doc["vehicles"]] == vehicle_names()
    assert {"peugeot406", "bmw320i", "dallara_av21"} <= set(vehicle_names())
    assert "peugeot406" in _invoke(runner, ["vehicles"]).stdout


# ------------------------------------------------------------------------------------------
# corners (closed form on synthetic curvature)
# ------------------------------------------------------------------------------------------
def test_count_corners_on_known_curvature():
    ds = 1.0
    k = 1.0 / (0.5 * CORNER_RADIUS_M)  # well inside a corner
    straight = np.zeros(200)
    left = np.full(100, k)
    right = np.full(100, -k)
    # two corners, opposite ways, separated by a straight
    assert count_corners(np.concatenate([straight, left, straight, right, straight]), ds,
                         False) == 2
    # an S-bend with no gap: two corners
    assert count_corners(np.concatenate([straight, left, right, straight]), ds, False) == 2
    # one corner whose radius wobbles above the threshold for less than the merge gap
    gap = np.zeros(int(CORNER_MERGE_GAP_M / ds) - 5)
    assert count_corners(np.concatenate([straight, left, gap, left, straight]), ds,
                         False) == 1
    # a kink shorter than the minimum length is no corner
    kink = np.full(int(CORNER_MIN_LENGTH_M / ds) - 2, k)
    assert count_corners(np.concatenate([straight, kink, straight]), ds, False) == 0
    # a corner across the start of a closed path counts once, twice on an open path
    wrap = np.concatenate([left[:50], straight, left[:50]])
    assert count_corners(wrap, ds, True) == 1
    assert count_corners(wrap, ds, False) == 2
    # a circle
    assert count_corners(np.full(500, k), ds, True) == 1
    with pytest.raises(ValueError):
        count_corners(np.zeros((2, 2)), ds, True)


# ------------------------------------------------------------------------------------------
# scenario new
# ------------------------------------------------------------------------------------------
def test_scenario_new_writes_a_valid_commented_template(runner, tmp_path):
    f = tmp_path / "s.toml"
    res = _invoke(runner, ["scenario", "new", str(f)])
    assert res.exit_code == 0 and f.read_text() == SCENARIO_TEMPLATE
    sc = load_scenario(f)
    assert sc.controller == "mfc-natural" and sc.vehicle == "peugeot406"
    assert sc.reference.track == "Norisring" and sc.plant == "10dof"
    assert set(sc.sensors.channels) == {"x", "y", "psi", "vx", "vy", "r", "ax", "ay"}
    assert SCENARIO_TEMPLATE.count("#") > 30  # commented
    # refuses to overwrite; --force does
    res = _invoke(runner, ["scenario", "new", str(f)])
    assert res.exit_code == 2 and "--force" in res.stderr
    f.write_text("x")
    assert _invoke(runner, ["scenario", "new", str(f), "--force"]).exit_code == 0
    assert f.read_text() == SCENARIO_TEMPLATE
    res = _invoke(runner, ["scenario", "new", str(tmp_path / "nope" / "s.toml")])
    assert res.exit_code == 2 and "does not exist" in res.stderr


def test_scenario_new_a_file_it_cannot_write_is_one_error_line(runner, tmp_path):
    """An OSError of the write (a folder that is a file, a full device) is an Error: line
    naming the file and the reason, exit 2, not a traceback."""
    (tmp_path / "f").write_text("")
    target = tmp_path / "f" / "s.toml"  # the folder is a file
    res = _invoke(runner, ["scenario", "new", str(target)])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("Error: ") and str(target) in res.stderr
    assert "Not a directory" in res.stderr and len(res.stderr.splitlines()) == 1
    if Path("/dev/full").exists():  # Linux: every write fails with ENOSPC
        res = _invoke(runner, ["scenario", "new", "/dev/full", "--force"])
        assert res.exit_code == 2, res.output
        assert "/dev/full" in res.stderr and "No space left" in res.stderr


def test_run_a_file_it_cannot_read_names_the_file(runner, tmp_path):
    """A folder or a non-UTF-8 file given as the scenario or the --vehicle: one Error: line
    naming the file and the reason, exit 2."""
    (tmp_path / "dir.toml").mkdir()
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe\x00bad")
    for name, reason in (("dir.toml", "Is a directory"), ("bin.toml", "not a UTF-8")):
        f = str(tmp_path / name)
        for args in ([f], ["--vehicle", f, "--duration", "0.01"]):
            res = _invoke(runner, ["run", *args])
            assert res.exit_code == 2, res.output
            assert res.stderr.startswith("Error: ") and len(res.stderr.splitlines()) == 1
            assert f in res.stderr and reason in res.stderr, res.stderr


def test_template_is_the_paper_scenario_as_it_says():
    """The template says its values are those of `paper`: loaded, only its name and
    description differ (a template with 2 mm of position noise read like the paper scenario
    and ran another)."""
    from flatfree.scenarios import named_scenario

    sc = scenario_from_toml(SCENARIO_TEMPLATE)
    paper = named_scenario("paper")
    assert sc.with_(name=paper.name, description=paper.description) == paper
    assert 'named scenario "paper"' in SCENARIO_TEMPLATE


def test_scenario_new_from_a_named_scenario_and_the_list(runner, tmp_path):
    from flatfree.scenarios import SCENARIO_NAMES, named_scenario

    f = tmp_path / "imu.toml"
    res = _invoke(runner, ["scenario", "new", str(f), "--from", "paper-imu"])
    assert res.exit_code == 0
    assert load_scenario(f) == named_scenario("paper-imu")
    assert f.read_text().startswith("# The named scenario 'paper-imu'")
    res = _invoke(runner, ["scenario", "new", str(tmp_path / "x.toml"), "--from", "meteor"])
    assert res.exit_code == 2 and "'meteor'" in res.stderr and "recorded-imu" in res.stderr
    assert not (tmp_path / "x.toml").exists()
    doc = json.loads(_invoke(runner, ["scenario", "list", "--json"]).stdout)
    assert [r["name"] for r in doc["scenarios"]] == list(SCENARIO_NAMES)
    imu = next(r for r in doc["scenarios"] if r["name"] == "recorded-imu-noise-free")
    assert (imu["vehicle"], imu["reference"], imu["noise"]) == ("dallara_av21",
                                                                "LVMS_23_01_04_B", False)
    text = _invoke(runner, ["scenario", "list"]).stdout.split()
    assert all(n in text for n in SCENARIO_NAMES)


def test_template_commented_options_are_valid_when_uncommented():
    """The commented [[road.patch]] and [[fault]] examples parse once uncommented."""
    text = SCENARIO_TEMPLATE
    for block in ("# [[road.patch]]", "# [[fault]]"):
        i = text.index(block)
        lines = text[i:].split("\n")
        out = []
        for ln in lines:
            if not ln.startswith("# "):
                break
            out.append(ln[2:])
        text = text[:i] + "\n".join(out) + text[i + len("\n".join(lines[:len(out)])):]
    sc = scenario_from_toml(text)
    assert sc.road.patches[0].mu == 0.5
    assert sc.faults[0].kind == "nan_measurement"


# ------------------------------------------------------------------------------------------
# run: error paths (exit code 2)
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--controller", "nope"], ["nope", *CONTROLLERS]),
        (["--track", "Nurburgring"], ["unknown track", "Norisring", "Monza", "Spa"]),
        (["--track", "missing/file.csv"], ["not found"]),
        (["--vehicle", "trabant"], ["unknown vehicle", "peugeot406", "dallara_av21"]),
        (["--recording", "nope"], ["unknown recording", "LVMS_23_01_04_B"]),
        (["--track", "Monza", "--recording", "LVMS_23_01_04_B"], ["not both"]),
        (["--cf-scale", "-1"], ["--cf-scale", "> 0"]),
        (["--cr-scale", "nan"], ["--cr-scale"]),
        (["--seed", "-1"], ["--seed"]),
        (["--duration", "0"], ["--duration"]),
        (["--duration", "0.0005", "--set", "timing.startup_s=0"],
         ["timing.duration_s = 0.0005 s", "shorter than one plant step", "plant_dt_s = 0.001"]),
        # the natural-output controller does not take the flatness model's stiffness scale
        (["--controller", "mfc-natural", "--cf-scale", "0.3", *SHORT], ["cf_scale"]),
        (["no-such-scenario"], ["unknown scenario", "paper", "recorded"]),
        (["missing.toml"], ["not found", "missing.toml"]),
    ],
)
def test_run_bad_input_exits_2_and_names_the_valid_choices(runner, args, needles):
    res = _invoke(runner, ["run", *args])
    assert res.exit_code == 2, res.output
    for n in needles:
        assert n in res.stderr, (n, res.stderr)
    assert res.stdout == ""


def test_run_malformed_toml_names_line_and_field(runner, tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('name = "x"\n\n[timing]\nplant_dt_s = 0.001\ncontrol_dt_s = -0.5\n')
    res = _invoke(runner, ["run", str(f)])
    assert res.exit_code == 2
    assert "line 5" in res.stderr and "timing.control_dt_s" in res.stderr
    f.write_text('name = "x"\n[reference]\ntrack = "Monza"\nlaps = 1.5\n')
    res = _invoke(runner, ["run", str(f), "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    assert "line 4" in res.stderr and "reference.laps" in res.stderr
    f.write_text('name = "x"\ncontroller = \n')  # not TOML at all
    res = _invoke(runner, ["run", str(f)])
    assert res.exit_code == 2 and "line 2" in res.stderr


def test_run_a_files_controller_setting_error_names_the_file_and_line(runner, tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('name = "my-scenario"\n\n[controller_settings]\nalpha_lat = "48.9"\n')
    res = _invoke(runner, ["run", str(f), *SHORT])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith(f"Error: {f}, line 4: field controller_settings.alpha_lat: ")
    # a --vehicle that cannot be read is the option's error, not the controller's
    (tmp_path / "car.toml").mkdir()
    res = _invoke(runner, ["run", "--vehicle", str(tmp_path / "car.toml"), *SHORT])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("Error: --vehicle: ") and "controller mfc" not in res.stderr


# ------------------------------------------------------------------------------------------
# run: results
# ------------------------------------------------------------------------------------------
def test_run_json_is_one_object_with_the_keys(runner):
    res = _invoke(runner, ["run", "--controller", "mfc-natural", "--track", "norisring",
                           "--no-noise", *SHORT, "--json"])
    doc = json.loads(res.stdout)  # exactly one JSON document, nothing else on stdout
    assert isinstance(doc, dict)
    for k in JSON_KEYS:
        assert k in doc, k
    # the bundled track's own spelling, not the option's
    assert doc["controller"] == "mfc-natural" and doc["track"] == "Norisring"
    assert doc["noise"] is False
    # a deterministic run that completes: exit 0, the whole requested duration
    assert doc["status"] == "completed" and res.exit_code == 0, res.output
    assert doc["duration_s"] == pytest.approx(3.0, abs=0.02)


def test_run_prints_times_rounded_and_writes_them_exact(runner, tmp_path):
    """The log's last time is 1999 * 0.01 s = 19.990000000000002 s in binary: printed 19.99;
    metrics.json keeps the number the trajectory has."""
    res = _invoke(runner, ["run", "--no-noise", "--duration", "20", "--json",
                           "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert '"duration_s": 19.99,' in res.stdout
    tr = Trajectory.from_parquet(tmp_path / "o" / "trajectory.parquet")
    assert tr.duration != 19.99  # else this test checks nothing
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["duration_s"] == \
        tr.duration


def test_run_says_why_every_metric_is_null(runner, tmp_path):
    res = _invoke(runner, ["run", "--no-noise", "--duration", "1", "--json",
                           "--out", str(tmp_path / "o")])
    doc = json.loads(res.stdout)
    assert doc["status"] == "completed" and doc["lateral_error_max_m"] is None
    assert "note: every metric is null" in res.stderr
    assert "0.99 s" in res.stderr and "timing.startup_s = 1 s" in res.stderr
    # the JSON carries it too (a pipe keeps stdout only)
    (note,) = doc["notes"]
    assert note.startswith("every metric is null: its log ends at 0.99 s")
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["notes"] == [note]
    assert "note: every metric is null" in (tmp_path / "o" / "report.html").read_text()
    res = _invoke(runner, ["run", "--no-noise", "--duration", "1.5", "--json"])
    assert "every metric is null" not in res.stderr
    assert "notes" not in json.loads(res.stdout)


def test_run_says_when_the_path_ends_before_the_duration(runner):
    """Norisring's one lap ends near 98.8 s: a longer --duration cannot be run, and the note
    says so, naming both and the setting that makes the run longer."""
    res = _invoke(runner, ["run", "--no-noise", "--duration", "200", "--json"])
    assert res.exit_code == 0, res.output
    end = json.loads(res.stdout)["duration_s"]
    assert 90.0 < end < 110.0
    note = " ".join(res.stderr.split())
    assert f"note: the run ended at {end:.2f} s, not at the requested duration of 200 s" in note
    assert "1 lap of Norisring" in note and "--set reference.laps=N" in note
    assert json.loads(res.stdout)["notes"][0].startswith(f"the run ended at {end:.2f} s")
    res = _invoke(runner, ["run", "--no-noise", *SHORT, "--json"])
    assert "note" not in res.stderr


def test_run_too_long_for_the_memory_is_a_clean_error(runner):
    # on the clock schedule a run lasts what is asked (on the path schedule it is capped near
    # the path's end: simulation.prepare)
    res = _invoke(runner, ["run", "--duration", "1e9", "--set",
                           "controller_settings.schedule=time", "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    msg = " ".join(res.stderr.split())
    assert "timing.duration_s = 1e+09 s" in msg and "does not fit in memory" in msg
    assert "1 lap of Norisring" in msg and "reference.laps" in msg
    assert "Traceback" not in res.output


def test_run_out_is_checked_before_the_run(runner, tmp_path, monkeypatch):
    import flatfree.simulation

    def never(*a, **k):
        raise AssertionError("the run started before --out was checked")

    monkeypatch.setattr(flatfree.simulation, "prepare", never)  # a run starts with prepare()
    blocker = tmp_path / "a_file"  # a folder cannot be made inside a file (root or not)
    blocker.write_text("")
    out = blocker / "run1"
    res = _invoke(runner, ["run", *SHORT, "--out", str(out)])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert f"--out {out}: cannot create or write this folder" in res.stderr
    res = _invoke(runner, ["demo", "--duration", "2", "--out", str(out)])  # demo too
    assert res.exit_code == 2 and f"--out {out}: cannot create" in res.stderr
    # a folder that can be made passes; made and left empty by a failed run, it is removed
    with pytest.raises(AssertionError, match="before --out"):
        _invoke(runner, ["run", *SHORT, "--out", str(tmp_path / "new" / "deeper" / "run1")])
    assert not (tmp_path / "new").exists()
    # demo too
    import flatfree.cli

    def fails(*a, **k):
        raise AssertionError("a demo run failed")

    monkeypatch.setattr(flatfree.cli, "_try_run", fails)
    with pytest.raises(AssertionError, match="a demo run failed"):
        _invoke(runner, ["demo", "--duration", "2", "--no-recorded", "--out",
                         str(tmp_path / "new" / "demo")])
    assert not (tmp_path / "new").exists()


def test_run_exit_code_1_when_the_run_does_not_complete(runner, tmp_path):
    """The steering locked straight (a steer_limit fault of 0 rad) from t = 1 s: the car cannot
    take Norisring's first corner and leaves the track, status left_track, exit code 1."""
    f = tmp_path / "locked.toml"
    f.write_text('controller = "mfc-natural"\nnoise = false\n[reference]\ntrack = "Norisring"\n'
                 '[timing]\nduration_s = 30.0\n[[fault]]\nkind = "steer_limit"\n'
                 't_start_s = 1.0\nduration_s = 60.0\nvalue = 0.0\n')
    res = _invoke(runner, ["run", str(f), "--json"])
    doc = json.loads(res.stdout)
    assert doc["status"] in ("left_track", "non_finite")
    assert res.exit_code == 1
    assert doc["status_time_s"] is not None and doc["status_time_s"] < 30.0


def test_run_out_writes_files_and_round_trips_the_scenario(runner, tmp_path):
    out = tmp_path / "run1"
    res = _invoke(runner, ["run", "--controller", "mfc-flat", "--seed", "3", *SHORT,
                           "--out", str(out), "--csv"])
    assert res.exit_code == 0, res.output  # seed 3 completes its 3 s
    sc = load_scenario(out / "scenario.toml")
    assert sc.controller == "mfc-flat" and sc.seed == 3 and sc.timing.duration_s == 3.0
    tr = Trajectory.from_parquet(out / "trajectory.parquet")
    # --csv: the same trajectory as CSV, every number exact
    tc = Trajectory.from_csv(out / "trajectory.csv")
    assert tc.status == tr.status and tc.names == tr.names
    for k, v in tr.to_columns().items():
        np.testing.assert_array_equal(tc.to_columns()[k], v)
    m = json.loads((out / "metrics.json").read_text())
    # the metrics file is the metrics of the written trajectory
    e = np.abs(tr["lateral_error"][tr.time >= tr.time[0] + sc.timing.startup_s])
    assert m["lateral_error_max_m"] == pytest.approx(float(e.max()), rel=1e-12)
    html = (out / "report.html").read_text()
    assert 'data-controller="mfc-flat"' in html
    for stem in ("fig4_paths", "fig5_errors", "fig6_inputs", "f_estimates", "track_map"):
        assert (out / "figures" / f"{stem}.png").is_file()
        assert (out / "figures" / f"{stem}.svg").is_file()
    # the closing line names every file it wrote, each of which exists
    line = res.stdout.strip().splitlines()[-1]
    assert line.startswith(f"wrote {out}/: ")
    for name in ("report.html", "scenario.toml", "metrics.json", "trajectory.parquet",
                 "trajectory.csv", "figures/"):
        assert name in line and (out / name.rstrip("/")).exists(), name


def test_run_csv_needs_out(runner):
    res = _invoke(runner, ["run", *SHORT, "--csv"])
    assert res.exit_code == 2 and "--csv" in res.stderr and "--out" in res.stderr


def test_run_recording_reports_steer_rms_against_the_recording(runner, tmp_path):
    out = tmp_path / "rec"
    res = _invoke(runner, ["run", "--recording", "lvms_23_01_04_b", "--no-noise", *SHORT,
                           "--json", "--out", str(out)])
    doc = json.loads(res.stdout)
    assert doc["track"] == "LVMS_23_01_04_B" and doc["vehicle"] == "dallara_av21"
    v = doc["steer_rms_vs_recorded_deg"]
    assert v is not None and math.isfinite(v) and v >= 0.0
    # independent check: RMS over t >= startup of (applied steer - recorded steer), the
    # recording read at the reference time of each logged sample
    from flatfree.scenarios import recorded_steer

    sc = load_scenario(out / "scenario.toml")
    tr = Trajectory.from_parquet(out / "trajectory.parquet")
    clock = tr["t_ref"] if "t_ref" in tr else tr.time  # noqa: SIM401 (Trajectory has no .get)
    keep = tr.time >= sc.timing.startup_s
    d = tr["steer"][keep] - recorded_steer(clock, sc)[keep]
    assert v == pytest.approx(math.degrees(math.sqrt(np.mean(d * d))), rel=1e-9)


def test_named_scenario_and_option_override(runner):
    res = _invoke(runner, ["run", "paper-noise-free", "--controller", "mfc-flat", *SHORT,
                           "--json"])
    doc = json.loads(res.stdout)
    # the named scenario it then is (paper-noise-free is mfc-natural's)
    assert doc["scenario"] == "paper-mfc-flat-noise-free" and doc["controller"] == "mfc-flat"
    assert doc["noise"] is False and doc["vehicle"] == "peugeot406"


def test_controller_option_names_and_describes_the_controller_run(runner, tmp_path):
    """--controller flatness on the default base wrote name "paper" and the description
    "paper Section 4: mfc-natural on the 10DoF peugeot406" into the run's scenario.toml and
    report: a named base becomes the named scenario it then is, any other base's description
    says which controller replaced which."""
    from flatfree.cli import build_scenario
    from flatfree.scenarios import named_scenario

    sc = build_scenario(controller="flatness", track="Monza", duration_s=2.0)
    ref = named_scenario("paper-flatness", track="Monza", duration_s=2.0)
    assert (sc.name, sc.description) == (ref.name, ref.description) and sc == ref
    assert "mfc-natural" not in sc.description
    mism = build_scenario(controller="flatness", cf_scale=0.3, cr_scale=0.3)
    assert mism == named_scenario("paper-mismatch")
    # no named scenario runs it: the base's name, its description amended
    rec = build_scenario("recorded", controller="mfc-flat")
    assert rec.name == "recorded"
    assert rec.description.endswith("the mfc-flat controller in place of mfc-natural "
                                    "(--controller)")
    f = tmp_path / "mine.toml"
    f.write_text('name = "mine"\ndescription = "mfc-natural on Spa"\n')
    mine = build_scenario(str(f), controller="mfc-flat")
    assert mine.name == "mine"
    assert mine.description == ("mfc-natural on Spa; the mfc-flat controller in place of "
                                "mfc-natural (--controller)")
    res = _invoke(runner, ["run", "--controller", "flatness", "--track", "Monza",
                           "--duration", "1", "--json"])
    assert json.loads(res.stdout)["scenario"] == "paper-flatness"
    # the stiffness options alone, on the controller the base has: paper-flatness with 0.3 Cf
    # and 0.3 Cr is paper-mismatch (it kept its name); another scale, described
    assert build_scenario("paper-flatness", cf_scale=0.3, cr_scale=0.3) == named_scenario(
        "paper-mismatch")
    half = build_scenario("paper-flatness", cf_scale=0.5)
    assert half.name == "paper-flatness"
    assert half.description == (named_scenario("paper-flatness").description
                                + "; its model's cf_scale 0.5 (--cf-scale)")
    # scales of 1 are the nominal model: the mismatch undone is paper-flatness (it kept the
    # name paper-mismatch)
    undone = build_scenario("paper-mismatch", cf_scale=1.0, cr_scale=1.0)
    assert (undone.name, undone.description) == ("paper-flatness", named_scenario(
        "paper-flatness").description)


def test_vehicle_option_takes_the_cars_natural_settings():
    """--vehicle swaps the base scenario's car tuning (alpha_lat) for the new car's, unless the
    settings were changed; other controllers' settings are left alone."""
    from flatfree.cli import build_scenario
    from flatfree.scenarios import DALLARA_NATURAL_SETTINGS, NATURAL_SETTINGS

    assert build_scenario(track="LVMS", vehicle="dallara_av21").controller_settings == \
        DALLARA_NATURAL_SETTINGS
    assert build_scenario(recording="LVMS_23_01_04_B",
                          vehicle="peugeot406").controller_settings == NATURAL_SETTINGS
    assert build_scenario(recording="LVMS_23_01_04_B").controller_settings == \
        DALLARA_NATURAL_SETTINGS
    flat = build_scenario("paper-flatness", vehicle="dallara_av21", cf_scale=0.5)
    assert flat.controller_settings == {"cf_scale": 0.5}
    # the inertial-unit variant keeps its estimator with the new car's alpha
    from flatfree.scenarios import natural_settings

    imu = build_scenario("paper-imu", track="LVMS", vehicle="dallara_av21")
    assert imu.controller_settings == natural_settings("dallara_av21", imu=True)
    assert imu.controller_settings["estimator_lat"] == "imu"
    assert imu.controller_settings["alpha_lat"] == 60.0
    # the car in any spelling the loader takes is that car, with its tuning and its name
    sc = build_scenario(track="LVMS", vehicle="Dallara_AV21")
    assert sc.vehicle == "dallara_av21" and sc.controller_settings == DALLARA_NATURAL_SETTINGS
    # a named track scenario with --vehicle is named_scenario(vehicle=...), its description
    # naming the car (it named the peugeot406)
    from flatfree.scenarios import named_scenario

    for name in ("paper", "paper-imu", "paper-mismatch-noise-free"):
        sc = build_scenario(name, vehicle="dallara_av21")
        assert sc == named_scenario(name, vehicle="dallara_av21")
        assert "dallara_av21" in sc.description and "peugeot406" not in sc.description


# ------------------------------------------------------------------------------------------
# demo
# ------------------------------------------------------------------------------------------
def test_demo_on_a_short_run_writes_report_and_figures(runner, tmp_path):
    out = tmp_path / "tmp"
    res = _invoke(runner, ["demo", "--out", str(out), "--duration", "3",
                           "--recording-duration", "3", "--no-progress"])
    html = (out / "report.html").read_text()
    rows = [r for r in ("flatness", "mfc-flat", "mfc-natural")
            if f'<tr class="run" data-controller="{r}">' in html]
    assert rows == ["flatness", "mfc-flat", "mfc-natural"]
    assert res.exit_code == 0, res.output  # every paper run made
    assert "not every paper run could be made" not in res.stderr
    for ctrl in ("flatness", "mfc-flat", "mfc-natural"):
        assert ctrl in res.stdout
    figs = out / "figures"
    for stem in ("fig3_cornering_stiffness", "fig4_paths", "fig5_errors", "f_estimates",
                 "track_map", "fig6_inputs"):
        assert (figs / f"{stem}.png").is_file(), stem
        assert (figs / f"{stem}.svg").is_file(), stem
    assert (figs / "fig2_mismatch.png").is_file()
    n_png = len(list(figs.glob("*.png")))
    assert html.count('src="data:image/png;base64,') == n_png
    # the library's warnings reach stderr once each and the report's notes (the recording's
    # reference passes the dallara_av21's flat-output singular speed, 10.8 m/s)
    w = "warning: recorded, mfc-flat: mfc-flat on dallara_av21"
    assert res.stderr.count(w) == 1 and w in html
    summary = json.loads((out / "metrics.json").read_text())
    from flatfree.cli import IMU_LABEL

    assert [r["label"] for r in summary["paper"]] == ["flatness", "mfc-flat", "mfc-natural",
                                                      IMU_LABEL]
    assert [r["scenario"] for r in summary["paper"]][-1] == "paper-imu"
    assert [r["label"] for r in summary["recorded"]] == ["mfc-flat", "mfc-natural", IMU_LABEL]
    assert [r["controller"] for r in summary["recorded"]] == ["mfc-flat", "mfc-natural",
                                                              "mfc-natural"]
    assert all("steer_rms_vs_recorded_deg" in r for r in summary["recorded"])


def test_vehicle_option_retunes_a_file_with_the_defaults(tmp_path):
    """A peugeot406 scenario file whose controller settings are empty (the defaults: the
    peugeot406's tuning until session 21, as files of the earlier template hold them) or
    session 21's tuning (the template until session 23) is retuned for the new car by
    --vehicle, as a file with the peugeot406's present tuning is; a file whose settings are
    the user's own keeps them."""
    from flatfree.cli import _PEUGEOT_SESSION21, build_scenario
    from flatfree.scenarios import DALLARA_NATURAL_SETTINGS, NATURAL_SETTINGS, named_scenario

    base = named_scenario("paper")
    assert _PEUGEOT_SESSION21 != NATURAL_SETTINGS
    for settings in ({}, _PEUGEOT_SESSION21, NATURAL_SETTINGS):
        f = tmp_path / "base.toml"
        base.with_(controller_settings=settings).save(f)
        assert build_scenario(str(f), vehicle="dallara_av21").controller_settings == \
            DALLARA_NATURAL_SETTINGS
    base.with_(controller_settings={"wn_lat": 9.0}).save(f)
    assert build_scenario(str(f), vehicle="dallara_av21").controller_settings == {"wn_lat": 9.0}


def _strict_json(text: str):
    """JSON as the standard has it: NaN and Infinity refused (json.loads takes them)."""
    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_a_nan_metric_is_null_in_the_json_and_n_a_in_the_text(runner, tmp_path):
    """Recorded runs shorter than the start-up interval have no steer RMS (NaN): demo's and
    run's metrics.json hold null (valid JSON), their text lines n/a."""
    out = tmp_path / "d"
    res = _invoke(runner, ["demo", "--out", str(out), "--duration", "0.5",
                           "--recording-duration", "0.5", "--no-progress"])
    assert res.exit_code == 0, res.output
    summary = _strict_json((out / "metrics.json").read_text())
    assert [r["steer_rms_vs_recorded_deg"] for r in summary["recorded"]] == [None] * 3
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("recorded, ")]
    assert len(lines) == 3 and all("nan" not in ln for ln in lines), lines
    assert all("steer RMS vs recorded n/a deg" in ln for ln in lines), lines
    res = _invoke(runner, ["run", "--recording", "LVMS_23_01_04_B", "--duration", "0.5",
                           "--out", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output
    assert "steer_rms_vs_recorded_deg: n/a" in res.stdout
    doc = _strict_json((tmp_path / "r" / "metrics.json").read_text())
    assert doc["steer_rms_vs_recorded_deg"] is None


def test_demo_bad_track_exits_2(runner, tmp_path):
    res = _invoke(runner, ["demo", "--out", str(tmp_path / "o"), "--track", "Atlantis"])
    assert res.exit_code == 2 and "Atlantis" in res.stderr and "Norisring" in res.stderr
    assert not (tmp_path / "o" / "report.html").exists()


def test_bench_quick_json(runner):
    res = _invoke(runner, ["bench", "--quick", "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    for k in ("open_loop_10dof_real_time_factor", "open_loop_3dof_real_time_factor",
              "controller_step_ns", "closed_loop_mfc-natural_real_time_factor"):
        assert doc[k] > 0.0, k  # None: a run failed (a note says which)
    assert "notes" not in doc, doc["notes"]
    assert doc["machine"]["cores"]


def test_module_entry_point():
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "flatfree.cli", "--version"],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0 and "flatfree" in r.stdout


def test_noise_flag_without_noisy_sensors_says_so(runner, tmp_path):
    f = tmp_path / "quiet.toml"
    f.write_text('name = "quiet"\n[timing]\nduration_s = 2.0\n')  # no [sensors.*] table
    res = _invoke(runner, ["run", str(f), "--noise", "--json"])
    assert "--noise has no effect" in res.stderr
    assert json.loads(res.stdout)["noise"] is True
    # a seed changes nothing either: said, and the header does not claim a seeded noise
    res = _invoke(runner, ["run", str(f), "--seed", "2"])
    assert "--seed has no effect" in res.stderr
    assert "noise on but no sensor has random noise" in res.stdout
    assert "seed" not in res.stdout.splitlines()[0]
    res = _invoke(runner, ["run", str(f), "--noise", "--seed", "2", "--json"])
    assert "--noise and --seed have no effect" in res.stderr
    # a drift alone is random noise: no note, and the header names the seed
    f.write_text(f.read_text() + "[sensors.y]\nmarkov_std = 0.01\nmarkov_tau_s = 60.0\n")
    res = _invoke(runner, ["run", str(f), "--noise", "--seed", "2"])
    assert "no effect" not in res.stderr
    assert res.stdout.splitlines()[0].endswith("noise on, seed 2")
    # with the noise off a seed changes nothing either (it was not said)
    res = _invoke(runner, ["run", str(f), "--no-noise", "--seed", "2"])
    assert "note: --seed has no effect: the run's sensor noise is off" in res.stderr


def test_sensor_suite_knows_whether_it_draws_random_numbers():
    from flatfree.sensors import SensorChannel, SensorSuite

    assert not SensorSuite({"y": SensorChannel(bias=0.1, delay_s=0.01)}).random
    assert SensorSuite({"y": SensorChannel(noise_std=1e-3)}).random
    assert SensorSuite({"y": SensorChannel(markov_std=1e-3, markov_tau_s=10.0)}).random
    assert not SensorSuite({"y": SensorChannel(noise_std=1e-3)}).noise_free().random


def test_run_on_a_users_track_csv(runner, tmp_path):
    """A circle of radius 100 m in the TUMFTM format (x_m, y_m, w_tr_right_m, w_tr_left_m)."""
    th = np.linspace(0.0, 2.0 * np.pi, 301)[:-1]
    f = tmp_path / "circle.csv"
    f.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + "".join(
        f"{100 * np.cos(t):.4f},{100 * np.sin(t):.4f},5.0,5.0\n" for t in th))
    res = _invoke(runner, ["run", "--track", str(f), "--no-noise", *SHORT, "--json"])
    doc = json.loads(res.stdout)
    assert doc["track"] == str(f)
    assert doc["status"] == "completed" and res.exit_code == 0, res.output
    bad = tmp_path / "bad.csv"
    bad.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n0,0,5,5\n1,0,5,5\n2,oops,5,5\n")
    res = _invoke(runner, ["run", "--track", str(bad), *SHORT])
    assert res.exit_code == 2 and "line" in res.stderr and "bad.csv" in res.stderr


def test_run_help_names_every_named_scenario(runner):
    from flatfree.scenarios import SCENARIO_NAMES

    res = _invoke(runner, ["run", "--help"])
    text = " ".join(res.stdout.split())
    listed = text[text.index("Named scenarios"):text.index("Exit codes")]
    assert "each also as NAME-noise-free" in listed
    for name in SCENARIO_NAMES:
        assert re.search(rf"[:,] {re.escape(name.removesuffix('-noise-free'))}[,;]", listed), \
            (name, listed)


def test_noise_on_a_noise_free_scenario_is_refused(runner):
    from flatfree.cli import InputError, build_scenario

    res = _invoke(runner, ["run", "paper-noise-free", "--noise", *SHORT, "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    assert "'paper-noise-free'" in res.stderr and "run 'paper'" in res.stderr
    # the scenario's own check (flatfree.scenario), --noise applied as the setting noise=true
    # and named as the option the user gave (it said "setting noise=true", "noise = True")
    assert res.stderr == ("Error: --noise: field noise: noise = true: the "
                          "scenario's name 'paper-noise-free' says noise-free; run 'paper' for "
                          "the noisy variant, or rename it (name = ...)\n")
    res = _invoke(runner, ["run", "paper", "--no-noise", "--set", "noise=x"])
    assert res.exit_code == 2
    assert res.stderr.startswith("Error: --no-noise, setting noise=x: field noise: ")
    with pytest.raises(InputError, match=r"^setting noise=true: field noise: noise = true: the "
                                         r"scenario's name 'recorded-imu-noise-free' says "
                                         r"noise-free; run 'recorded-imu' for the noisy variant, "
                                         r"or rename it \(name = \.\.\.\)$"):
        build_scenario("recorded-imu-noise-free", settings=["noise=true"])
    sc = build_scenario("paper-noise-free", noise=True, settings=["name=mine"])
    assert sc.noise and sc.name == "mine"
    # demo --set too, before any run
    from flatfree.cli import _demo_tasks

    with pytest.raises(InputError, match=r"^paper, flatness: setting noise=true: field noise: "
                                         r"noise = true: the scenario's name "
                                         r"'paper-flatness-noise-free' says noise-free"):
        _demo_tasks(track=None, seed=0, duration_s=2.0, rec_duration_s=2.0, no_recorded=True,
                    noise=False, settings=["noise=true"])


def test_bundled_references_come_out_in_their_own_spelling(tmp_path, monkeypatch):
    from flatfree.cli import build_scenario

    assert build_scenario(track="monza").reference.track == "Monza"
    assert build_scenario(settings=["reference.track=spa.csv"]).reference.track == "Spa"
    assert build_scenario(recording="lvms_23_01_04_b").reference.recording == "LVMS_23_01_04_B"
    monkeypatch.chdir(tmp_path)  # a file wins over a bundled name, as the loaders read it
    (tmp_path / "monza").write_text("")
    assert build_scenario(track="monza").reference.track == "monza"


def test_run_a_scenario_file_from_another_folder_and_its_saved_copy(runner, tmp_path,
                                                                   monkeypatch):
    """`cd / && flatfree run /tmp/rw/r4/scenario.toml` with vehicle = "sub/mycar.toml": the
    car is read beside the file; the run's saved scenario.toml works from anywhere."""
    from flatfree.vehicles import load_vehicle

    folder = tmp_path / "rw" / "r4"
    (folder / "sub").mkdir(parents=True)
    car = folder / "sub" / "mycar.toml"
    shutil.copy(resources.files("flatfree.vehicles") / "data" / "peugeot406.toml", car)
    (folder / "scenario.toml").write_text('name = "r4"\nvehicle = "sub/mycar.toml"\n'
                                          'noise = false\n')
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    res = _invoke(runner, ["run", str(folder / "scenario.toml"), "--duration", "0.5",
                           "--json", "--out", "out"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["vehicle"] == str(car)
    saved = tmp_path / "elsewhere" / "out" / "scenario.toml"
    assert load_scenario(saved).vehicle == str(car)
    assert load_vehicle(str(car)).mass == load_vehicle("peugeot406").mass
    monkeypatch.chdir(tmp_path)
    res = _invoke(runner, ["run", str(saved), "--duration", "0.5", "--json"])
    assert res.exit_code == 0, res.output


def test_run_prints_the_steer_lock_warning_as_one_line(runner):
    res = _invoke(runner, ["run", "--vehicle", "dallara_av21", "--duration", "0.5", "--json"])
    assert "warning: the reference's tightest curve (radius 9.9 m)" in res.stderr
    assert "UserWarning" not in res.stderr
    json.loads(res.stdout)  # stdout stays machine-readable


def test_run_out_prints_the_steer_lock_warning_once(runner, tmp_path):
    """--out draws the desired path from the run's reference, built again without its
    warnings (it printed the warning a second time, raw with its source line; pytest records
    a raw warning instead of printing it, so it is caught here)."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = _invoke(runner, ["run", "--vehicle", "dallara_av21", "--track", "Monza",
                               "--duration", "3", "--out", str(tmp_path / "o"), "--json"])
    assert res.exit_code == 0, res.output
    assert res.stderr.count("the reference's tightest curve") == 1, res.stderr
    assert res.stderr.startswith("warning: the reference's tightest curve (radius")
    assert [str(w.message) for w in caught] == []
    # and it goes with the run's numbers: the JSON, metrics.json and the report's notes
    # (stderr is not kept; a user's review found it nowhere in the run's folder)
    out = json.loads(res.stdout)
    assert out["warnings"][0].startswith("the reference's tightest curve (radius 9.")
    saved = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert saved["warnings"] == out["warnings"]
    html = (tmp_path / "o" / "report.html").read_text()
    assert "warning: the reference&#x27;s tightest curve (radius 9." in html  # escaped
    quiet = json.loads(_invoke(runner, ["run", "--duration", "0.5", "--json"]).stdout)
    assert "warnings" not in quiet  # only when there are some


def test_run_builds_the_reference_once(runner, tmp_path, monkeypatch):
    """The note on a run shorter than --duration, the recorded steer and --out's figures share
    the reference the run was prepared with: one prepare(), one reference build (there were
    four builds, each a whole prepare(), then two)."""
    import flatfree.simulation

    calls: dict[str, int] = {"prepare": 0, "_reference": 0}

    def counting(name):
        real = getattr(flatfree.simulation, name)

        def counted(*args, **kwargs):
            calls[name] += 1
            return real(*args, **kwargs)
        return counted

    for name in calls:
        monkeypatch.setattr(flatfree.simulation, name, counting(name))
    # 20 s of the bundled recording, at speed (a short user recording)
    lines = (resources.files("flatfree") / "data" / "recordings" /
             "LVMS_23_01_04_B.csv").read_text().splitlines()
    rec = tmp_path / "short.csv"
    rec.write_text("\n".join([lines[0], *lines[3000:3500]]) + "\n")
    res = _invoke(runner, ["run", "--recording", str(rec), "--no-noise", "--duration", "60",
                           "--out", str(tmp_path / "o"), "--json"])
    assert res.exit_code == 0, res.output
    assert "note: the run ended at" in res.stderr  # the three users of the reference ran
    assert json.loads(res.stdout)["steer_rms_vs_recorded_deg"] is not None
    assert (tmp_path / "o" / "figures" / "fig4_paths.png").is_file()
    assert calls == {"prepare": 1, "_reference": 1}


# ------------------------------------------------------------------------------------------
# --set FIELD=VALUE
# ------------------------------------------------------------------------------------------
def test_set_wins_over_the_options_and_reaches_any_field():
    from flatfree.cli import build_scenario

    sc = build_scenario("paper-imu", seed=1, track="Monza", duration_s=3.0, noise=False,
                        settings=["seed=2", "reference.track=Spa", "timing.duration_s=2",
                                  "noise=true", "reference.j_lat_max=15",
                                  "sensors.y.markov_order=2", "timing.control_dt_s=0.002",
                                  "actuators.steer_tau_s=0.05", "road.mu=0.9"])
    assert (sc.seed, sc.reference.track, sc.timing.duration_s, sc.noise) == (2, "Spa", 2.0, True)
    assert sc.reference.j_lat_max == 15.0 and sc.sensors.channels["y"].markov_order == 2
    assert sc.timing.control_dt_s == 0.002 and sc.actuators.steer_tau_s == 0.05
    assert sc.road.mu == 0.9
    assert sc.controller_settings["estimator_lat"] == "imu"  # the rest of the base kept
    # the options still apply where --set does not touch them
    sc = build_scenario("paper", seed=4, settings=["reference.a_lat_max=5"])
    assert sc.seed == 4 and sc.reference.a_lat_max == 5.0
    # --controller drops the other controller's settings first; --set then adds to them
    sc = build_scenario("paper", controller="flatness", cf_scale=0.3,
                        settings=["controller_settings.cr_scale=0.5"])
    assert sc.controller == "flatness"
    assert dict(sc.controller_settings) == {"cf_scale": 0.3, "cr_scale": 0.5}
    # a recording replaces the track (the scenario's car and settings are kept)
    sc = build_scenario("paper", settings=["reference.recording=LVMS_23_01_04_B"])
    assert sc.reference.recording == "LVMS_23_01_04_B" and sc.reference.track is None
    assert sc.vehicle == "peugeot406"


@pytest.mark.parametrize(
    ("settings", "needles"),
    [
        # one case of each way a setting fails (every case of the library's messages:
        # tests/test_scenario.py): a field's validation, a malformed setting, the controller's
        # settings, two settings together
        (["reference.j_lat_max=nan"], ["reference.j_lat_max=nan", "must be > 0"]),
        (["seed"], ["setting seed", "FIELD=VALUE"]),
        (["controller_settings.alpha_lat=nan"], ["controller_settings.alpha_lat=nan",
                                                 "alpha_lat = nan"]),
        (["reference.track=Monza", "reference.recording=LVMS_23_01_04_B"], ["not both"]),
    ],
)
def test_run_bad_set_exits_2_naming_the_setting(runner, settings, needles):
    args = [a for s in settings for a in ("--set", s)]
    res = _invoke(runner, ["run", *args, *SHORT, "--json"])
    assert res.exit_code == 2, res.output
    assert res.stdout == ""
    for n in needles:
        assert n in res.stderr, (n, res.stderr)


def test_run_with_set_runs_the_changed_scenario(runner, tmp_path):
    out = tmp_path / "set"
    res = _invoke(runner, ["run", "paper-imu", "--no-noise", "--duration", "2", "--seed", "1",
                           "--set", "reference.j_lat_max=15", "--set", "sensors.y.markov_order=2",
                           "--set", "seed=5", "--json", "--out", str(out)])
    doc = json.loads(res.stdout)
    assert doc["status"] == "completed" and res.exit_code == 0, res.output
    assert doc["seed"] == 5 and doc["scenario"] == "paper-imu"
    sc = load_scenario(out / "scenario.toml")
    assert sc.reference.j_lat_max == 15.0 and sc.sensors.channels["y"].markov_order == 2
    assert sc.seed == 5 and sc.timing.duration_s == 2.0 and sc.noise is False


def test_the_help_examples_with_a_seed_have_noise_to_seed(runner, tmp_path, monkeypatch):
    """`run --help` showed `flatfree run my_scenario.toml --no-noise --seed 2 --out run1`,
    which says "note: --seed has no effect": each example with --seed, on the template of
    `scenario new` for its file, runs (briefly, without --out) with no such note."""
    import shlex

    monkeypatch.chdir(tmp_path)
    assert _invoke(runner, ["scenario", "new", "my_scenario.toml"]).exit_code == 0
    examples = []
    for cmd in ([], ["run"]):
        text = _invoke(runner, [*cmd, "--help"]).stdout
        examples += [ln.split("flatfree ", 1)[1] for ln in text.splitlines()
                     if ln.strip().startswith("flatfree run") and " --seed " in ln]
    assert len(examples) >= 2, examples
    for ex in examples:
        args = shlex.split(ex.split("  ")[0])  # the command, without its comment
        if "--out" in args:
            i = args.index("--out")
            del args[i:i + 2]
        res = _invoke(runner, [*args, "--duration", "0.01"])
        assert res.exit_code == 0, (ex, res.output)
        assert "has no effect" not in res.stderr, (ex, res.stderr)


def test_set_is_documented_in_the_help(runner):
    for cmd in ("run", "demo"):
        text = _invoke(runner, [cmd, "--help"]).stdout
        assert "--set FIELD=VALUE" in text, cmd
    assert "--set reference.j_lat_max=15 --set sensors.y.markov_order=2" in \
        _invoke(runner, ["run", "--help"]).stdout


def test_demo_set_changes_every_run_and_refuses_what_differs_between_them(runner, tmp_path):
    from flatfree.cli import DEMO_FIXED_FIELDS, InputError, _demo_tasks

    kw = {"track": None, "seed": 0, "duration_s": 2.0, "rec_duration_s": 2.0,
          "no_recorded": False, "noise": True}
    plain = _demo_tasks(**kw)
    tasks = _demo_tasks(**kw, settings=["timing.control_dt_s=0.002", "road.mu=0.9"])
    assert [(g, lab) for g, lab, _ in tasks] == [(g, lab) for g, lab, _ in plain]
    for (_, _, sc), (_, _, before) in zip(tasks, plain, strict=True):
        assert sc.timing.control_dt_s == 0.002 and sc.road.mu == 0.9
        assert sc.name == before.name and sc.controller == before.controller
        assert sc.reference == before.reference and sc.vehicle == before.vehicle
    for field in DEMO_FIXED_FIELDS:
        with pytest.raises(InputError, match="cannot be set for all of them"):
            _demo_tasks(**kw, settings=[f"{field}=1"])
    with pytest.raises(InputError, match="controller_settings"):
        _demo_tasks(**kw, settings=["controller_settings.alpha_lat=40"])
    # spelled with spaces, as the library reads it (reference.track for every run)
    with pytest.raises(InputError, match="reference.track cannot be set"):
        _demo_tasks(**kw, settings=["reference . track = Monza"])
    # or through the table that holds it (it took every run, the recorded ones too, to Monza)
    with pytest.raises(InputError, match="reference.track cannot be set"):
        _demo_tasks(**kw, settings=['reference={track = "Monza"}'])
    with pytest.raises(InputError, match="reference.track cannot be set"):
        _demo_tasks(**kw, settings=["reference="])  # the whole reference back to its default
    # an inline table merges its keys: the reference's other fields (its track) are each run's
    merged = _demo_tasks(**kw, settings=["reference={j_lat_max = 15}"])
    for (_, _, sc), (_, _, before) in zip(merged, plain, strict=True):
        assert sc.reference == dataclasses.replace(before.reference, j_lat_max=15.0)
    # a malformed setting: the library's message, once (not once per run)
    with pytest.raises(InputError, match=r"^setting seed: expected FIELD=VALUE, e.g. "
                                         r"reference.j_lat_max=15$"):
        _demo_tasks(**kw, settings=["seed"])
    # a bad value: exit 2 before any run, naming the run and the setting
    res = _invoke(runner, ["demo", "--out", str(tmp_path / "o"), "--set", "road.mu=-1"])
    assert res.exit_code == 2
    assert "paper, flatness" in res.stderr and "road.mu=-1" in res.stderr
    assert not (tmp_path / "o" / "report.html").exists()


def test_switching_to_the_natural_output_controller_takes_the_car_s_tuning():
    """From a flat-output base, --controller mfc-natural took empty settings (the peugeot406's
    alpha_lat 30) whatever the car; it now takes the car's (the same as from `paper`)."""
    from flatfree.cli import build_scenario
    from flatfree.scenarios import DALLARA_NATURAL_SETTINGS, NATURAL_SETTINGS

    for base in ("paper-flatness", "paper-mfc-flat"):
        sc = build_scenario(base, controller="mfc-natural", vehicle="dallara_av21")
        assert sc.controller_settings == DALLARA_NATURAL_SETTINGS
        assert build_scenario(base, controller="mfc-natural").controller_settings == \
            NATURAL_SETTINGS


def test_track_and_recording_options_drop_the_old_files_shape_settings(tmp_path):
    """A scenario file whose reference sets closed / smoothing_length_m (its track file's
    shape): --recording used to fail ("a track's setting") with no way to clear them, and
    --track kept another file's shape; both now drop them, and a --set gives them anew."""
    from flatfree.cli import build_scenario
    from flatfree.scenario import ReferenceSpec, Scenario

    f = tmp_path / "mine.toml"
    Scenario(reference=ReferenceSpec(track="Monza", closed=True, smoothing_length_m=30.0)
             ).save(f)
    rec = build_scenario(str(f), recording="LVMS_23_01_04_B")
    assert rec.reference.recording == "LVMS_23_01_04_B"
    assert (rec.reference.closed, rec.reference.smoothing_length_m) == (None, None)
    spa = build_scenario(str(f), track="Spa", settings=["reference.smoothing_length_m=40"])
    assert (spa.reference.track, spa.reference.closed,
            spa.reference.smoothing_length_m) == ("Spa", None, 40.0)
    assert build_scenario(str(f)).reference.smoothing_length_m == 30.0  # the file's, kept


def test_run_set_replaces_and_clears_the_faults(runner, tmp_path):
    """--set fault=[{...}] gives a run its faults from the command line, --set fault= clears a
    scenario file's (they could only be set in a file, and never removed)."""
    f = tmp_path / "faulty.toml"
    Scenario(timing=Timing(duration_s=1.0), faults=(
        Fault(kind="steer_limit", t_start_s=0.2, duration_s=0.5, value=0.001),)).save(f)
    cleared, replaced = tmp_path / "cleared", tmp_path / "replaced"
    res = _invoke(runner, ["run", str(f), "--no-noise", "--set", "fault=", "--json",
                           "--out", str(cleared)])
    assert res.exit_code == 0, res.output
    assert load_scenario(cleared / "scenario.toml").faults == ()
    res = _invoke(runner, ["run", str(f), "--no-noise", "--json", "--out", str(replaced),
                           "--set", ('fault=[{kind = "nan_measurement", channel = "y", '
                           't_start_s = 0.5, duration_s = 0.05}]')])
    assert res.exit_code == 0, res.output
    assert load_scenario(replaced / "scenario.toml").faults == (Fault(
        kind="nan_measurement", channel="y", t_start_s=0.5, duration_s=0.05),)
