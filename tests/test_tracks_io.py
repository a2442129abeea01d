"""Track/recording files: bundled data intact and loadable, user files, and every bad-file error.

Reference values come from the PROVENANCE.md files shipped next to the data (parsed here, not
copied), i.e. from the people who copied and checked the data, not from this code.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from importlib import resources

import numpy as np
import pytest

import flatfree.tracks as T

DATA = resources.files("flatfree") / "data"


def _provenance_table(text: str, section: str) -> dict[str, dict[str, float]]:
    """Rows of the markdown table that follows ``### <section>`` in a PROVENANCE.md."""
    block = text.split(f"### {section}", 1)[1].split("\n#", 1)[0]
    rows = [ln for ln in block.splitlines() if ln.startswith("|")]
    head = [c.strip() for c in rows[0].strip("|").split("|")]
    out = {}
    for ln in rows[2:]:
        cells = [c.strip() for c in ln.strip("|").split("|")]
        out[cells[0]] = {"points": int(cells[head.index("points")]),
                         "length": float(cells[head.index("length [m]")])}
    return out


TRACKS_PROV = (DATA / "tracks" / "PROVENANCE.md").read_text(encoding="utf-8")
REC_PROV = (DATA / "recordings" / "PROVENANCE.md").read_text(encoding="utf-8")
CENTER = _provenance_table(TRACKS_PROV, "Centerlines")
RACELINE = _provenance_table(TRACKS_PROV, "Race lines")


# ---------------------------------------------------------------------------------------------
# bundled data
# ---------------------------------------------------------------------------------------------
def test_package_data_is_reachable_with_licenses():
    for rel in ("README.md", "tracks/LICENSE", "tracks/COPYING.GPL-3", "tracks/PROVENANCE.md",
                "recordings/LICENSE", "recordings/PROVENANCE.md"):
        f = DATA.joinpath(*rel.split("/"))
        assert f.is_file(), rel
    readme = (DATA / "README.md").read_text(encoding="utf-8")
    assert "OpenStreetMap contributors" in readme
    assert "LGPL-3.0" in readme and "GPL-3.0" in readme


@pytest.mark.parametrize("folder", ["tracks", "recordings"])
def test_bundled_files_are_byte_identical_to_provenance(folder):
    """The data must be shipped UNCHANGED: compare with the sha256 sums listed upstream."""
    text = (DATA / folder / "PROVENANCE.md").read_text(encoding="utf-8")
    sums = re.findall(r"^([0-9a-f]{64})\s+(\S+)$", text, flags=re.M)
    assert len(sums) >= 4
    for digest, rel in sums:
        data = DATA.joinpath(folder, *rel.split("/")).read_bytes()
        assert hashlib.sha256(data).hexdigest() == digest, rel


def test_names():
    assert T.track_names() == ["Budapest", "Catalunya", "IMS", "LVMS", "Monza", "Norisring", "Spa"]
    assert T.raceline_names() == ["Budapest", "Catalunya", "IMS", "Monza", "Norisring", "Spa"]
    assert T.recording_names() == ["LVMS_23_01_04_B"]


def _closing_gap_is_one_spacing(pts):
    """A bundled loop file ends one point spacing before its first point (geometry.py's
    _CLOSE_WARN_SPACINGS 1.5 leaves room above it; measured 1.0000-1.0002 on every TUMFTM
    centerline and race line); a file that marks its loop itself is not measured here."""
    if pts.closed is not None:
        return
    spacing = np.median(np.hypot(np.diff(pts.x), np.diff(pts.y)))
    gap = np.hypot(pts.x[-1] - pts.x[0], pts.y[-1] - pts.y[0])
    assert gap / spacing == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("name", sorted(CENTER))
def test_every_bundled_centerline_loads_and_matches_provenance(name):
    pts = T.read_track_points(name)
    assert len(pts.x) == CENTER[name]["points"]  # nothing dropped
    # the raw polyline is what PROVENANCE measured (printed to 0.1 m)
    assert pts.polyline_length(True) == pytest.approx(CENTER[name]["length"], abs=0.051)
    _closing_gap_is_one_spacing(pts)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # closed by the detection, across one spacing: silently
        trk = T.load_track(name)
    assert trk.closed
    # issue 4: the length matches PROVENANCE.md within 1 %; it does within 1e-3 (measured
    # <= 1.7e-4: the smoothing's cut corners against the raw polyline)
    assert trk.length == pytest.approx(CENTER[name]["length"], rel=1e-3)
    assert np.isfinite(trk.w_left).all() and np.isfinite(trk.w_right).all()
    assert abs(trk.turning_number) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("name", sorted(RACELINE))
def test_every_bundled_raceline_loads_and_matches_provenance(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        trk = T.load_track(name, raceline=True)
    assert trk.closed
    pts = T.read_track_points(name, raceline=True)
    _closing_gap_is_one_spacing(pts)
    assert len(pts.x) == RACELINE[name]["points"]
    assert trk.length == pytest.approx(RACELINE[name]["length"], rel=1e-3)  # measured 1.2e-4
    assert np.isnan(trk.w_left).all()  # a race line file has no widths: unknown, not invented


def test_lvms_centerline_from_bounds():
    """The bounds are 15.0 m apart (PROVENANCE); the midline of two offset curves of a
    convex loop is as long as the mean of the two bounds."""
    m_in = re.search(r"lvms_inner_bound\.csv: points \d+, cols 2, length ([\d.]+) m", REC_PROV)
    m_out = re.search(r"lvms_outer_bound\.csv: points \d+, cols 2, length ([\d.]+) m", REC_PROV)
    expected = 0.5 * (float(m_in.group(1)) + float(m_out.group(1)))
    trk = T.load_track("lvms")
    assert trk.closed and trk.turning_number == pytest.approx(1.0, abs=1e-9)  # counter-clockwise
    assert trk.length == pytest.approx(expected, rel=0.01)
    # 15.0 m wide: half on each side (bounds spaced 1 m: foot points exact to ~1 cm)
    assert np.allclose(trk.w_left, 7.5, atol=0.05) and np.allclose(trk.w_right, 7.5, atol=0.05)


def test_names_are_case_insensitive_and_a_user_copy_loads_the_same(tmp_path):
    a = T.load_track("Norisring")
    b = T.load_track("NORISRING")
    c = T.load_track("norisring.csv")
    f = tmp_path / "my_track.csv"
    f.write_bytes((DATA / "tracks" / "Norisring.csv").read_bytes())
    d = T.load_track(f)
    e = T.load_track(str(f))
    for other in (b, c, d, e):
        np.testing.assert_array_equal(a.geometry, other.geometry)
    assert d.name == "my_track"


def test_a_written_track_reads_back_as_its_nodes(tmp_path):
    """Track.to_csv: the reader gets the nodes bit for bit, the widths in TUMFTM order, a closed
    track's loop from the closing repeat (an open path's file has none)."""
    smooth = T.load_track("Norisring", smoothing_length=40.0)
    pts = T.read_track_points(smooth.to_csv(tmp_path / "smooth.csv"))
    assert pts.closed is True  # the closing repeat, dropped by the reader
    for got, want in ((pts.x, smooth.x), (pts.y, smooth.y), (pts.w_left, smooth.w_left),
                      (pts.w_right, smooth.w_right)):
        np.testing.assert_array_equal(got, want[:-1])
    assert T.load_track(tmp_path / "smooth.csv").closed
    # widths unknown (a race line): plain x, y; an open path is read back open
    line = T.load_track("Monza", raceline=True)
    assert np.isnan(line.w_left).all()
    f = line.to_csv(tmp_path / "line.csv")
    assert f.read_text().splitlines()[0] == "# x_m,y_m"
    arc = T.Track.from_points(100 * np.sin(np.linspace(0, 2, 50)),
                              100 * (1 - np.cos(np.linspace(0, 2, 50))), closed=False)
    pts = T.read_track_points(arc.to_csv(tmp_path / "arc.csv"))
    assert pts.closed is None
    np.testing.assert_array_equal(pts.x, arc.x)
    assert not T.load_track(tmp_path / "arc.csv").closed


def test_bundled_name_is_the_loaders_lookup(tmp_path, monkeypatch):
    """One name lookup (case-insensitive, blanks and .csv ignored; a track may be a recording's
    name) that the loaders use and the scenario spells its names with."""
    from flatfree.tracks._io import bundled_name

    assert bundled_name("monza") == "Monza" and bundled_name(" SPA.csv ") == "Spa"
    assert bundled_name("lvms") == "LVMS"
    assert bundled_name("lvms_23_01_04_b") == "LVMS_23_01_04_B"  # a recording as a track
    assert bundled_name("lvms_23_01_04_b", "recording") == "LVMS_23_01_04_B"
    assert bundled_name("Monza", "recording") is None
    assert bundled_name("monza", "raceline") == "Monza"
    assert bundled_name("lvms", "raceline") is None  # no race line of the oval
    for other in ("Nurburgring", "data/monza.csv", "", 3, None):
        assert bundled_name(other) is None, other
    with pytest.raises(ValueError, match=r"^kind = 'circuit': must be one of track, raceline, "
                                         r"recording$"):
        bundled_name("Monza", "circuit")
    # a file of that name is read first; else the name, in any spelling, is the bundled file
    monkeypatch.chdir(tmp_path)
    (tmp_path / "monza").write_text("# x_m,y_m\n")
    with pytest.raises(ValueError, match="monza: no data rows"):
        T.load_track("monza")
    assert T.load_track("MONZA").name == "Monza"


def test_unknown_name_lists_the_valid_ones():
    with pytest.raises(ValueError, match=r"unknown track 'Nurburgring'.*Monza"):
        T.load_track("Nurburgring")
    with pytest.raises(ValueError, match="file not found"):
        T.load_track("/nonexistent/dir/track.csv")


def test_a_file_that_cannot_be_read_is_named(tmp_path):
    """Any OS error reading a CSV (here a folder) is a ValueError naming it, no traceback."""
    from flatfree.tracks._io import read_csv

    with pytest.raises(ValueError, match=r"^mine\.csv: cannot read it \(Is a directory\)$"):
        read_csv(tmp_path, "mine.csv")


def test_a_race_line_is_bundled_only(tmp_path):
    """raceline=True on a user's file used to return the file's centerline, renamed "...
    raceline": there are bundled race lines only, so a file (or a path) is refused by name."""
    f = tmp_path / "my.csv"
    f.write_bytes((DATA / "tracks" / "Monza.csv").read_bytes())
    names = "Budapest, Catalunya, IMS, Monza, Norisring, Spa"
    for given in (f, str(f), tmp_path / "absent.csv"):
        with pytest.raises(ValueError, match=rf"^'{re.escape(str(given))}': race lines are "
                                             rf"bundled only \(for {names}\); read a file"):
            T.load_track(given, raceline=True)
    assert T.load_track(f).name == "my"  # the same file as a track
    with pytest.raises(ValueError, match=rf"^unknown raceline 'lvms'; bundled names: {names}$"):
        T.read_track_points("lvms", raceline=True)


def test_a_sparse_open_road_is_not_closed_silently(tmp_path):
    """An out-and-back road digitised every 10 m ends 24 m (2.4 spacings) from its start: the
    detection closes it with a segment no data has (a 664 m lap for a 638 m road). Warned,
    naming the file, the gap and closed=False, which keeps it open."""
    out = np.arange(0.0, 301.0, 10.0)
    a = np.linspace(0.0, np.pi, 5)[1:-1]
    xy = np.concatenate([np.column_stack([out, 0.0 * out]),
                         np.column_stack([300 + 12 * np.sin(a), 12 - 12 * np.cos(a)]),
                         np.column_stack([out[::-1], 0.0 * out + 24.0])])
    f = _write(tmp_path, ["x,y", *(f"{float(p):.6f},{float(q):.6f}" for p, q in xy)], "road.csv")
    with pytest.warns(UserWarning, match=rf"^road \({re.escape(str(f))}\): closed into a loop "
                                         r"because its end is 24 m from its start.*closed=False"):
        assert T.load_track(f).closed
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not T.load_track(f, closed=False).closed


def test_plain_xy_files_with_and_without_header(tmp_path):
    th = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    rows = "\n".join(f"{30 * np.cos(t):.9f},{30 * np.sin(t):.9f}" for t in th)
    for header in ("", "x,y\n", "# x_m,y_m\n"):
        f = tmp_path / f"c{len(header)}.csv"
        f.write_text(header + rows + "\n")
        trk = T.load_track(f)
        assert trk.closed  # end->start gap = one spacing
        assert trk.length == pytest.approx(2 * np.pi * 30, rel=1e-6)  # measured 1.8e-7


def test_closing_repeat_marks_a_loop(tmp_path):
    th = np.linspace(0, 2 * np.pi, 9)  # last point == first
    f = tmp_path / "loop.csv"
    f.write_text("\n".join(f"{float(10 * np.cos(t))!r},{float(10 * np.sin(t))!r}" for t in th))
    pts = T.read_track_points(f)
    assert pts.closed is True and len(pts.x) == 8


def test_headerless_tum_file_reads_widths_in_tum_order(tmp_path):
    f = tmp_path / "t.csv"
    f.write_text("0,0,1,2\n5,0,1,2\n10,0,1,2\n15,0,1,2\n20,0,1,2\n")
    pts = T.read_track_points(f)
    assert (pts.w_right == 1).all() and (pts.w_left == 2).all()


# ---------------------------------------------------------------------------------------------
# bad files: each error names the file and the line
# ---------------------------------------------------------------------------------------------
GOOD = ["0.0,0.0,5.0,5.0", "5.0,0.0,5.0,5.0", "10.0,1.0,5.0,5.0", "15.0,3.0,5.0,5.0",
        "20.0,6.0,5.0,5.0"]
HEADER = "# x_m,y_m,w_tr_right_m,w_tr_left_m"


def _write(tmp_path, lines, name="bad.csv"):
    f = tmp_path / name
    f.write_text("\n".join(lines) + "\n")
    return f


@pytest.mark.parametrize(
    "lines, pattern",
    [
        # missing column (header names only three of the four TUMFTM columns)
        (["# x_m,y_m,w_tr_right_m", *[",".join(r.split(",")[:3]) for r in GOOD]],
         r"bad\.csv, line 1: missing column\(s\) \['w_tr_left_m'\]"),
        # a row with a missing cell
        ([HEADER, *GOOD[:2], "10.0,1.0,5.0", *GOOD[3:]], r"bad\.csv, line 4: expected 4 values"),
        # non-numeric cell
        ([HEADER, *GOOD[:3], "15.0,abc,5.0,5.0", GOOD[4]],
         r"bad\.csv, line 5, column 'y': 'abc' is not a number"),
        # NaN
        ([HEADER, GOOD[0], "5.0,nan,5.0,5.0", *GOOD[2:]],
         r"bad\.csv, line 3, column 'y': 'nan' is not finite"),
        # infinity in a width
        ([HEADER, *GOOD[:4], "20.0,6.0,inf,5.0"],
         r"bad\.csv, line 6, column 'w_tr_right': 'inf' is not finite"),
        # fewer than 4 points
        ([HEADER, *GOOD[:3]], (r"bad\.csv: 3 point\(s\); a path needs at least 4 \(last at "
                               r"line 4\)")),
        # repeated point
        ([HEADER, *GOOD[:3], GOOD[2], *GOOD[3:]],
         (r"bad\.csv, line 5: repeated point \(10\.0, 1\.0\) equals the previous point "
          r"\(line 4\)")),
        # zero-length segment (distinct numbers, 1e-9 m apart)
        ([HEADER, *GOOD[:3], "10.000000001,1.0,5.0,5.0", *GOOD[3:]],
         (r"bad\.csv, line 5: zero-length segment from the previous point \(line 4\): "
          r"length 1e-09 m < 1e-06 m")),
        # negative width
        ([HEADER, *GOOD[:2], "10.0,1.0,-1.0,5.0", *GOOD[3:]],
         r"bad\.csv, line 4, column 'w_tr_right_m': width -1\.0 m must be >= 0"),
        # no header and an unknown number of columns
        (["0,0,1", "1,0,1", "2,0,1", "3,0,1"], r"bad\.csv, line 1: 3 columns and no header"),
        # header without x or y
        (["a,b", "0,0", "1,0", "2,1", "3,3"],
         r"bad\.csv, line 1: missing column\(s\) \['x', 'y'\]"),
        # empty
        (["# x_m,y_m"], r"bad\.csv: no data rows"),
    ],
    ids=["missing-column", "short-row", "non-numeric", "nan", "inf", "too-few", "repeated",
         "zero-length", "negative-width", "no-header", "no-xy", "empty"],
)
def test_bad_track_files(tmp_path, lines, pattern):
    f = _write(tmp_path, lines)
    with pytest.raises(ValueError, match=pattern):
        T.load_track(f)


def test_comment_and_blank_lines_keep_line_numbers(tmp_path):
    lines = [HEADER, "", "# a comment", *GOOD[:2], "", "10.0,oops,5.0,5.0", *GOOD[3:]]
    with pytest.raises(ValueError, match=r"line 7, column 'y'"):
        T.load_track(_write(tmp_path, lines))


@pytest.mark.parametrize("header", ["x(m),y(m)", "x [m], y [m]", "# x (m),y[m]", "X_m,Y_m",
                                    "# x_m,y_m"])
def test_a_header_may_give_the_si_unit(tmp_path, header):
    th = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    f = _write(tmp_path, [header, *(f"{30 * np.cos(t):.9f},{30 * np.sin(t):.9f}" for t in th)])
    assert T.load_track(f).length == pytest.approx(2 * np.pi * 30, rel=1e-6)


XY = [",".join(r.split(",")[:2]) for r in GOOD]


@pytest.mark.parametrize(("lines", "pattern"), [
    (["x(km),y(km)", *XY], (r"column 'x': unit 'km' is not accepted; the values must be in 'm' "
                            r"\(header 'x\(km\)'; units are not converted\)")),
    (["x (ft),y (ft)", *XY], r"column 'x': unit 'ft'"),
    (["# x [m],y [mm]", *XY], r"column 'y': unit 'mm'"),
    (["# x_m,y_m,w_tr_right (cm),w_tr_left_m", *GOOD], r"column 'w_tr_right': unit 'cm'"),
])
def test_a_header_unit_other_than_si_is_refused(tmp_path, lines, pattern):
    """x(km) and x (ft) used to load as metres (the unit was stripped), x [m] was "missing
    column(s) ['x', 'y']": no conversion, so any unit but the column's is an error."""
    f = _write(tmp_path, lines)
    with pytest.raises(ValueError, match=f"^{re.escape(str(f))}, line 1, {pattern}"):
        T.load_track(f)


def test_in_memory_points_are_checked_too():
    x = np.array([0.0, 1.0, 1.0, 2.0, 3.0])
    y = np.array([0.0, 0.0, 0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match=r"point 2: repeated point"):
        T.Track.from_points(x, y)
    with pytest.raises(ValueError, match=r"point 1: x is not finite"):
        T.Track.from_points([0, np.nan, 2, 3], [0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"ds = -1.0 m"):
        T.Track.from_points([0, 1, 2, 3], [0, 1, 2, 3], ds=-1.0)


REC_HEADER = ("# time(s),x(m),y(m),vx(m/s),vy(m/s),phi(rad),delta(rad),omega(rad/s),ax(m/s^2),"
              "deltadelta(rad/s),wheel_fl(kmph),wheel_fr(kmph),wheel_rl(kmph),wheel_rr(kmph),"
              "roll(rad),throttle_ped_cmd(%),brake_ped_cmd(kPa)")


def _rec_rows(n=6):
    return [",".join([f"{100 + 0.04 * k:.2f}", f"{k * 1.0}", "0", "25", "0", "0", "0.01", "0",
                      "0", "0", "90", "90", "90", "90", "0", "10", "0"]) for k in range(n)]


def test_recording_file_errors(tmp_path):
    rows = _rec_rows()
    rows[3] = rows[3].replace("100.12", "100.04", 1)  # time goes back
    f = _write(tmp_path, [REC_HEADER, *rows], "rec.csv")
    with pytest.raises(ValueError, match=r"rec\.csv, line 5, column 'time': 100\.04 s does not "
                                         r"increase \(previous 100\.08 s at line 4\)"):
        T.load_recording(f)
    f = _write(tmp_path, ["# time(s),x(m),y(m),vx(m/s)", "0,0,0,1", "1,1,0,1", "2,2,0,1",
                          "3,3,0,1"], "rec2.csv")
    with pytest.raises(ValueError, match=r"rec2\.csv, line 1: recording header lacks column\(s\) "
                                         r"\['phi', 'delta'\]"):
        T.load_recording(f)
    f = _write(tmp_path, [HEADER, *GOOD], "notrec.csv")
    with pytest.raises(ValueError, match="not a recording"):
        T.load_recording(f)


def test_user_recording_loads_like_the_bundled_one(tmp_path):
    f = _write(tmp_path, [REC_HEADER, *_rec_rows(40)], "mine.csv")
    rec = T.load_recording(f)
    assert len(rec) == 40 and rec.bounds is None
    assert rec.t[0] == 0.0 and rec.t0_epoch == pytest.approx(100.0)
    np.testing.assert_allclose(rec["vx"], 25.0)
    # the documented units only (PROVENANCE.md), never converted: vx in km/h is refused
    for old, new, msg in (("vx(m/s)", "vx(km/h)", "column 'vx': unit 'km/h'"),
                          ("phi(rad)", "phi [deg]", "column 'phi': unit 'deg'"),
                          ("time(s)", "time(ms)", "column 'time': unit 'ms'")):
        f = _write(tmp_path, [REC_HEADER.replace(old, new), *_rec_rows(40)], "units.csv")
        with pytest.raises(ValueError, match=f"^{re.escape(f'{f}, line 1, {msg}')}"):
            T.load_recording(f)
        with pytest.raises(ValueError, match=f"^{re.escape(f'{f}, line 1, {msg}')}"):
            T.load_track(f)  # a recording's path: the same reader


def test_free_text_comments_are_not_headers(tmp_path):
    f = _write(tmp_path, ["# my own track, surveyed 2024", "# units: metres", HEADER, *GOOD],
               "commented.csv")
    pts = T.read_track_points(f)
    assert (pts.w_left == 5.0).all() and len(pts.x) == 5
    f = _write(tmp_path, ["# surveyed by hand, in metres, 2024", "0,0", "5,0", "10,1", "15,3"],
               "xy.csv")
    assert len(T.read_track_points(f).x) == 4


def test_short_first_row_is_reported_against_the_header(tmp_path):
    f = _write(tmp_path, [HEADER, "0.0,0.0,5.0", *GOOD[1:]])
    with pytest.raises(ValueError, match=r"bad\.csv, line 2: expected 4 values"):
        T.load_track(f)


def _stadium(spacing: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed stadium (straights 600 m, turns of radius 100 m), counter-clockwise, starting
    at the middle of the lower straight: point 0 at (0, 0), heading +x."""
    pts = [np.column_stack([np.arange(0.0, 300.0, spacing), np.zeros(300)])]
    a = np.arange(0.0, np.pi, spacing / 100.0)
    pts.append(np.column_stack([300.0 + 100.0 * np.sin(a), 100.0 - 100.0 * np.cos(a)]))
    pts.append(np.column_stack([np.arange(300.0, -300.0, -spacing), np.full(600, 200.0)]))
    pts.append(np.column_stack([-300.0 - 100.0 * np.sin(a), 100.0 + 100.0 * np.cos(a)]))
    pts.append(np.column_stack([np.arange(-300.0, 0.0, spacing), np.zeros(300)]))
    xy = np.concatenate(pts)
    return xy[:, 0].copy(), xy[:, 1].copy()


def test_bridge_closure_leaves_a_straight_and_removes_a_bump_on_it():
    """Exact on a line: on a straight (the parabolas through each side are the line, so the
    quintic is), the bridge moves no point by more than round-off, and a bump of 0.8 m inside
    the stretch (larger than the LVMS artefact's 0.7 m) is taken back onto the line; every point
    outside the stretch keeps its coordinates bit for bit."""
    from flatfree.tracks.loaders import bridge_closure

    x, y = _stadium()
    bx, by = bridge_closure(x, y, 40.0, 50.0)
    assert np.abs(by - y).max() < 1e-9 and np.abs(bx - x).max() < 1e-9
    lower = y == 0.0  # the lower straight, |x| < 300 m
    bump = np.where(lower & (x > -30.0) & (x < 40.0),
                    0.8 * np.sin(np.pi * (x + 30.0) / 70.0) ** 2, 0.0)
    bx, by = bridge_closure(x, y + bump, 40.0, 50.0)
    assert np.abs(by[lower]).max() < 1e-9  # back on the straight y = 0
    np.testing.assert_array_equal(bx, x)  # moved across the chord (here: y) only
    out = ~((x > -40.5) & (x < 50.5) & lower)
    np.testing.assert_array_equal(by[out], (y + bump)[out])


def test_bridge_closure_refuses_a_stretch_it_cannot_bridge():
    from flatfree.tracks.loaders import bridge_closure

    x, y = _stadium()
    for (before, after, fit), msg in (((0.0, 50.0, 30.0), "before = 0.0 m: must be > 0"),
                                      ((40.0, -1.0, 30.0), "after = -1.0 m: must be > 0"),
                                      ((40.0, 50.0, 0.0), "fit = 0.0 m: must be > 0"),
                                      ((40.0, "50", 30.0), "after = '50' m: expected a real"),
                                      ((700.0, 700.0, 30.0), "before + after + 2 fit = 1460 m")):
        with pytest.raises(ValueError, match=f"^{re.escape(msg)}"):
            bridge_closure(x, y, before, after, fit=fit)
    with pytest.raises(ValueError, match=rf"^y: expected {x.size} values, got {x.size - 1}$"):
        bridge_closure(x, y[:-1], 40.0, 50.0)
    with pytest.raises(ValueError, match=r"^x \(shape \(\d+,\)\): expected real numbers"):
        bridge_closure(["a"] * x.size, y, 40.0, 50.0)


def test_a_bundled_track_is_built_once_and_a_file_of_its_name_is_still_the_file(tmp_path,
                                                                               monkeypatch):
    """load_track caches bundled tracks per process (a Track is immutable): the same arguments
    give the same object, equal to one built afresh; other arguments another; a file in the
    current directory named like a bundled track is read as that file (the loaders' rule), not
    taken from the cache."""
    from flatfree.tracks.loaders import _build_track, read_track_points

    a = T.load_track("Norisring")
    assert T.load_track(" norisring ") is a
    fresh = _build_track(read_track_points("Norisring"), False, None, T.DEFAULT_DS, None)
    np.testing.assert_array_equal(a.geometry, fresh.geometry)
    assert (a.name, a.closed, a.source) == (fresh.name, fresh.closed, fresh.source)
    assert not a.geometry.flags.writeable
    smooth = T.load_track("Norisring", smoothing_length=60.0)
    assert smooth is not a and smooth.length != a.length
    assert T.load_track("Norisring", raceline=True).name == "Norisring raceline"
    # a user's Norisring.csv in the current directory: the file, shifted 1 km east
    monkeypatch.chdir(tmp_path)
    src = DATA / "tracks" / "Norisring.csv"
    lines = src.read_text().splitlines()
    out = []
    for line in lines:
        if line.startswith("#") or not line.strip():
            out.append(line)
            continue
        x, rest = line.split(",", 1)
        out.append(f"{float(x) + 1000.0},{rest}")
    (tmp_path / "Norisring.csv").write_text("\n".join(out) + "\n")
    mine = T.load_track("Norisring.csv")
    assert mine is not a
    np.testing.assert_allclose(mine.geometry[:, 1] - 1000.0, a.geometry[:, 1], atol=1e-6)


def test_the_track_cache_does_not_skip_the_builders_checks_or_share_a_writeable_array():
    """Review finds: an argument equal to a cached key (np.float32(0.5) == 0.5, True == 1) was
    served from the cache without the builder's check that refuses it; a read-only geometry
    could be made writeable again and change the track every caller shares."""
    import numpy as np

    T.load_track("Monza", ds=0.5)
    with pytest.raises(ValueError, match=r"^ds = np\.float32\(0\.5\) m: must be a finite "):
        T.load_track("Monza", ds=np.float32(0.5))
    with pytest.raises(ValueError, match=r"^ds = \[0\.5\] m: must be a finite "):
        T.load_track("Monza", ds=[0.5])  # unhashable: built, and refused, as before the cache
    a = T.load_track("Monza")
    with pytest.raises(ValueError, match="cannot set WRITEABLE flag"):
        a.geometry.flags.writeable = True
    assert not T.Track(name="x", closed=a.closed, geometry=a.geometry).geometry.flags.writeable
    mine = np.array(a.geometry)  # a caller's own array stays the caller's: writeable
    T.Track(name="y", closed=a.closed, geometry=mine)
    assert mine.flags.writeable


def test_a_bundled_name_in_another_spelling_is_the_bundled_track_whatever_the_folder_holds(
        tmp_path, monkeypatch):
    """Review find: a file named ``Norisring`` (no suffix) in the current folder was read for
    ``load_track("norisring")`` (the cache looked the name up as the bundled track, and its
    build looked it up again as a file) and then served for every spelling. The file is read
    for its own spelling only, as before the cache; a build that fails with a hashable
    argument fails once (it was built again on its TypeError)."""
    import numpy as np

    monkeypatch.chdir(tmp_path)
    th = np.linspace(0.0, 2.0 * np.pi, 400, endpoint=False)
    (tmp_path / "Norisring").write_text(
        "x_m,y_m\n" + "\n".join(f"{100 * np.cos(t)},{100 * np.sin(t)}" for t in th) + "\n")
    bundled = T.load_track("norisring", ds=0.7)  # a key no other test builds: a fresh build
    assert bundled.length == pytest.approx(2296.0, abs=1.0)
    assert T.load_track("NORISRING", ds=0.7) is bundled
    assert T.load_track("Norisring", ds=0.7).length == pytest.approx(2 * np.pi * 100, rel=1e-3)
    with pytest.raises(TypeError) as info:
        T.load_track("Monza", smoothing_length="20")
    assert info.value.__context__ is None  # raised by one build, not by a second one


def test_a_smoothing_that_distorts_the_path_is_said_and_one_that_erases_it_refused(tmp_path):
    """A user's review: reference.smoothing_length_m = 5000 shrank Norisring (2296 m) to 3.5 m
    and 1e6 to nothing, without a word. Above a quarter of the path it is refused, naming the
    value and the path's length; where it shortens the path by more than 2 % it is said
    (Norisring at 200 m: 2296 -> 2208 m); the default, 20 m, moves it by 0.02 %."""
    with pytest.raises(ValueError, match=r"^smoothing_length = 1000\.0 m: longer than a quarter "
                                         r"of the path \(2296 m\), whose shape it would smooth "
                                         r"away \(a scenario's reference\.smoothing_length_m\)$"):
        T.load_track("Norisring", smoothing_length=1000.0)
    for _ in range(2):  # built once per process (the cache), said on every call
        with pytest.warns(UserWarning, match=r"smoothing_length = 200 m shortens the path from "
                                             r"2296 m to 2208 m \(3\.8 %\)"):
            T.load_track("Norisring", smoothing_length=200.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        T.load_track("Norisring", smoothing_length=100.0)  # 1.1 %: not said


def test_a_forced_loop_across_a_gap_is_said(tmp_path):
    """closed=True joined a road's ends 1.5 km apart into a loop silently (a user's review):
    said when the closing segment spans 3 or more point spacings, as the detection's rule."""
    x = np.arange(0.0, 1501.0, 10.0)
    f = tmp_path / "straight.csv"
    f.write_text("x,y\n" + "".join(f"{v:.1f},{0.01 * v:.3f}\n" for v in x))
    with pytest.warns(UserWarning, match=r"^straight \(.*\): closed=True joins its end to its "
                                         r"start across 1\.5e\+03 m"):
        T.load_track(f, closed=True, smoothing_length=0.0)
