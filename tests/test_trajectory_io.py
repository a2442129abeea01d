"""Trajectory files: CSV (plain, with a JSON sidecar) and Parquet, read back exactly."""

from __future__ import annotations

import csv
import json
import math
import re

import numpy as np
import pytest

from flatfree.trajectory import Status, Trajectory

UNITS = {"lateral_error": "m", "yaw_rate": "rad/s", "torque": "N m"}


def _traj(n=11, **kw):
    t = np.arange(n) * 1e-3
    # values whose shortest repr is long (1/3, pi multiples): a lossy text would show
    sig = {"lateral_error": np.sin(t * 1e3) / 3.0, "yaw_rate": np.pi * t,
           "torque": np.full(n, -300.0)}
    return Trajectory(time=t, signals=sig, units=UNITS, **kw)


def _same(a: Trajectory, b: Trajectory) -> None:
    assert a.names == b.names
    np.testing.assert_array_equal(a.time, b.time)
    for k in a.names:
        np.testing.assert_array_equal(a[k], b[k])
    assert dict(a.units) == dict(b.units)
    assert (a.status, a.status_time, dict(a.meta)) == (b.status, b.status_time, dict(b.meta))


@pytest.mark.parametrize("kw", [
    dict(meta={"seed": 3, "scenario": "paper"}),
    dict(status=Status.LEFT_TRACK, status_time=0.005),
])
def test_csv_round_trip_is_exact_with_status_and_meta(tmp_path, kw):
    tr = _traj(**kw)
    path = tr.to_csv(tmp_path / "run.csv")
    _same(tr, Trajectory.from_csv(path))
    side = json.loads((tmp_path / "run.csv.json").read_text())
    assert side["status"] == tr.status.value
    assert side["status_time"] == tr.status_time


def test_csv_sidecar_is_plain_json_read_with_one_loads(tmp_path):
    """The sidecar is one JSON object whose values are JSON values, not JSON texts: units and
    meta objects, status_time a number or null (the sidecar once held the Parquet metadata's
    texts, units and meta as JSON texts and status_time as the text "null", which took two
    json.loads). Meta values that are not JSON-native are written as str(value) and read back
    as that text."""
    meta = {"seed": 3, "scenario": "paper", "real_time_factor": 1234.5, "noise": False,
            "gains": [1.0, 2.5], "tuning": {"alpha": 0.5, "note": None}, "count": np.int64(7)}
    tr = _traj(meta=meta)
    path = tr.to_csv(tmp_path / "run.csv")
    side = json.loads((tmp_path / "run.csv.json").read_text())
    assert side == {"units": {"time": "s", **UNITS}, "status": "completed",
                    "status_time": None, "meta": {**meta, "count": "7"}}
    assert isinstance(side["units"], dict) and side["status_time"] is None
    back = Trajectory.from_csv(path)
    assert dict(back.meta) == {**meta, "count": "7"} and back.status_time is None
    left = _traj(status=Status.LEFT_TRACK, status_time=0.005)
    left.to_csv(tmp_path / "left.csv")
    side = json.loads((tmp_path / "left.csv.json").read_text())
    assert side["status"] == "left_track" and side["meta"] == {}
    assert type(side["status_time"]) is float and side["status_time"] == 0.005


@pytest.mark.parametrize("kw", [
    dict(meta={"seed": 3, "scenario": "paper"}),
    dict(status=Status.LEFT_TRACK, status_time=0.005, meta={"seed": 4}),
])
def test_csv_reads_sidecars_of_the_old_form_with_json_texts(tmp_path, kw):
    """A sidecar written before the fix, its units, status time and meta as JSON texts inside
    the JSON, reads back as the new form does."""
    tr = _traj(**kw)
    path = tr.to_csv(tmp_path / "run.csv")
    old = {"units": json.dumps({"time": "s", **UNITS}), "status": tr.status.value,
           "status_time": json.dumps(tr.status_time), "meta": json.dumps(dict(tr.meta))}
    (tmp_path / "run.csv.json").write_text(json.dumps(old, indent=1) + "\n")
    _same(tr, Trajectory.from_csv(path))


def test_parquet_metadata_stays_json_texts(tmp_path):
    """Parquet schema metadata holds texts: the units, status time and meta as JSON texts, the
    status as it is (the format the CSV sidecar no longer shares)."""
    import pyarrow.parquet as pq

    tr = _traj(status=Status.LEFT_TRACK, status_time=0.005, meta={"seed": np.int64(3)})
    md = pq.read_schema(tr.to_parquet(tmp_path / "run.parquet")).metadata
    assert json.loads(md[b"flatfree.units"]) == {"time": "s", **UNITS}
    assert md[b"flatfree.status"] == b"left_track"
    assert md[b"flatfree.status_time"] == b"0.005"
    assert json.loads(md[b"flatfree.meta"]) == {"seed": "3"}
    assert dict(Trajectory.from_parquet(tmp_path / "run.parquet").meta) == {"seed": "3"}
    done = _traj()
    md = pq.read_schema(done.to_parquet(tmp_path / "done.parquet")).metadata
    assert md[b"flatfree.status_time"] == b"null" and md[b"flatfree.meta"] == b"{}"


@pytest.mark.parametrize(("key", "value", "problem"), [
    ("units", ["m"], "expected an object"),
    ("meta", "{not json", "not JSON"),
    ("status_time", True, "expected a number or null"),
    ("status_time", "\"0.5\"", "expected a number or null"),
])
def test_csv_sidecar_of_the_wrong_types_is_named(tmp_path, key, value, problem):
    tr = _traj()
    path = tr.to_csv(tmp_path / "run.csv")
    side = tmp_path / "run.csv.json"
    desc = json.loads(side.read_text())
    side.write_text(json.dumps({**desc, key: value}))
    msg = f"{path}: {key} = {value!r} in run.csv.json: {problem}"
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory.from_csv(path)


def test_csv_is_plain_for_common_readers(tmp_path):
    """One header line and numbers: numpy's genfromtxt(names=True) and csv.DictReader read it
    (a leading comment line made both take the comment for the header)."""
    tr = _traj()
    path = tr.to_csv(tmp_path / "run.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "time [s],lateral_error [m],yaw_rate [rad/s],torque [N m]"
    assert len(lines) == 1 + len(tr)
    data = np.genfromtxt(path, delimiter=",", names=True)
    assert data.dtype.names == ("time_s", "lateral_error_m", "yaw_rate_rads", "torque_N_m")
    np.testing.assert_array_equal(data["lateral_error_m"], tr["lateral_error"])
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["yaw_rate [rad/s]"]) for r in rows] == tr["yaw_rate"].tolist()


def test_empty_trajectory_round_trips(tmp_path):
    tr = _traj(n=0, status=Status.NON_FINITE, status_time=0.0)
    _same(tr, Trajectory.from_csv(tr.to_csv(tmp_path / "empty.csv")))
    _same(tr, Trajectory.from_parquet(tr.to_parquet(tmp_path / "empty.parquet")))


def test_csv_reading_errors_name_the_file_and_the_problem(tmp_path):
    tr = _traj()
    path = tr.to_csv(tmp_path / "run.csv")
    (tmp_path / "run.csv.json").unlink()
    msg = (f"{path}: not a flatfree trajectory (no sidecar run.csv.json with its status and "
           "units beside it)")
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory.from_csv(path)
    tr.to_csv(path)
    text = path.read_text().splitlines()
    path.write_text("\n".join([text[0].replace("yaw_rate [rad/s]", "yaw_rate"), *text[1:]]))
    msg = f"{path}: header column 2 = 'yaw_rate': expected 'name [unit]'"
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory.from_csv(path)
    path.write_text("\n".join([*text[:3], text[3] + ",1.0"]))
    with pytest.raises(ValueError, match=f"^{re.escape(f'{path}: rows are not 4 numbers each')}$"):
        Trajectory.from_csv(path)
    side = tmp_path / "run.csv.json"
    side.write_text(json.dumps({"units": "{}", "status": "completed"}))
    path.write_text("\n".join(text))
    msg = f"{path}: not a flatfree trajectory (no status_time, meta in run.csv.json)"
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory.from_csv(path)


def test_a_missing_file_is_file_not_found_for_both_readers(tmp_path):
    # the CSV reader talked of a missing sidecar; both now say the file itself is missing
    with pytest.raises(FileNotFoundError, match=re.escape(f"{tmp_path / 'no.csv'}: no such file")):
        Trajectory.from_csv(tmp_path / "no.csv")
    with pytest.raises(FileNotFoundError):
        Trajectory.from_parquet(tmp_path / "no.parquet")


@pytest.mark.parametrize("bad, dtype", [(["1.0", "2.0"], "<U3"), ([True, False], "bool"),
                                        ([None, 1.0], "object")])
def test_signal_values_that_are_not_numbers_are_refused(bad, dtype):
    # numpy would parse the text and take the booleans as 0/1 silently
    msg = (f"signal 'a': values of dtype {dtype} ('{np.dtype(dtype).kind}'): expected real "
           "numbers (a float or integer array)")
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory(time=[0.0, 1.0], signals={"a": bad}, units={"a": "m"})
    with pytest.raises(ValueError, match=r"^time: values of dtype <U3"):
        Trajectory(time=bad if dtype == "<U3" else ["0.0", "1.0"], signals={}, units={})
    # integers are numbers
    assert Trajectory(time=[0, 1], signals={"a": [1, 2]}, units={"a": "m"})["a"].dtype == float


def test_parquet_round_trip_and_foreign_files(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    for tr in (_traj(meta={"seed": 3, "controller": "mfc-natural"}),
               _traj(status=Status.LEFT_TRACK, status_time=0.005)):
        _same(tr, Trajectory.from_parquet(tr.to_parquet(tmp_path / "run.parquet")))
    path = tmp_path / "foreign.parquet"
    table = pa.table({"time": [0.0, 1.0], "x": [1.0, 2.0]})
    pq.write_table(table, path)
    msg = (f"{path}: not a flatfree trajectory (no units, status, status_time, meta in its "
           "schema metadata)")
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory.from_parquet(path)
    partial = tmp_path / "partial.parquet"
    pq.write_table(table.replace_schema_metadata({b"flatfree.units": b'{"x": "m"}'}), partial)
    msg = (f"{partial}: not a flatfree trajectory (no status, status_time, meta in its schema "
           "metadata)")
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        Trajectory.from_parquet(partial)


@pytest.mark.parametrize("bad", [math.nan, "1.0", None])
def test_after_refuses_a_start_that_is_not_a_time(bad):
    with pytest.raises(ValueError, match=r"^t_start = .*: (must be finite|expected a real number)"):
        _traj().after(bad)
