"""The LVMS bound files' loop-closure artefact and its bridge: the figures quoted by
``flatfree.tracks.loaders.LVMS_SEAM_M`` / ``LVMS_SMOOTHING_LENGTH``, tests/test_tracks_geometry.py
and benchmarks/README.md "The LVMS start line: a data artefact, bridged" (session 13).

Run as a script (``python benchmarks/lvms_seam.py``, ~10 s). It prints

1. the bulge of each bound file around its first point: how far the bridge of
   ``LVMS_SEAM_M`` (``bridge_closure``, fitted on the 30 m beyond either end) moves its points;
2. the midline's curvature over the bridged stretch, without and with the bridge, at the LVMS
   cut-off (60 m) and the default (20 m), the bridge's largest move, and the lap's curvature
   range (the oval has no right-hand bend: negative curvature is a wiggle of the data);
3. the recorded car's distance from the centerline over the 100 m around the start line (its
   span on each pass, without and with the bridge) and, for scale, its median span over 100 m
   windows on the rest of the lap;
4. the closed loop's start (`paper-noise-free`, peugeot406): the profile's speed at the line,
   the start speed, the speed at the end of a lap, the max lateral error of the first 15 s
   after the start-up, the start state's yaw acceleration and the largest steer command of the
   first 0.6 s, on the bridged and on the unbridged centerline.

Nothing here is a test.
"""

from __future__ import annotations

import os
import tempfile
import warnings

import numpy as np

from flatfree.models.tendof import TenDoF
from flatfree.scenarios import named_scenario
from flatfree.simulation import prepare, simulate
from flatfree.tracks import _io, load_recording
from flatfree.tracks.geometry import GC
from flatfree.tracks.loaders import (
    LVMS_SEAM_M,
    LVMS_SMOOTHING_LENGTH,
    bridge_closure,
    lvms_centerline,
)


def _signed(s: np.ndarray, length: float) -> np.ndarray:
    return np.where(s > 0.5 * length, s - length, s)


def _bulge(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed arc length from the first point and the bridge's sideways move [m] there."""
    bx, by = bridge_closure(x, y, *LVMS_SEAM_M)
    seg = np.hypot(np.diff(x, append=x[0]), np.diff(y, append=y[0]))
    s = _signed(np.r_[0.0, np.cumsum(seg[:-1])], float(seg.sum()))
    return s, np.hypot(bx - x, by - y)


def _start(track: str) -> str:
    sc = named_scenario("paper-noise-free", track=track)
    prep = prepare(sc)
    model = TenDoF(prep.vehicle)
    r_dot = model.rhs(prep.x0, model.inputs(0.0, prep.steer0))[5]
    lap = simulate(sc)
    first = simulate(named_scenario("paper-noise-free", track=track, duration_s=15.0))
    keep = first.time >= sc.timing.startup_s
    early = first.time <= 0.6
    ref = prep.reference
    near = ref["s_path"] < 70.0
    a_lat = ref["vx"][near] ** 2 * ref["kappa"][near]  # the profile's, within 70 m of the line
    return (f"profile {ref['vx'][0]:.2f} m/s at the line (lateral acceleration "
            f"{a_lat.min():+.2f} / {a_lat.max():+.2f} m/s^2 in the first 70 m), start "
            f"{prep.x0[3]:.2f}, "
            f"end of lap {lap['vx'][-1]:.2f} m/s ({lap.status.value}); first 15 s: max lateral "
            f"{100 * np.max(np.abs(first['lateral_error'][keep])):.2f} cm ({first.status.value}); "
            f"start r' {r_dot:+.3f} rad/s^2, max |steer command| in 0.6 s "
            f"{np.degrees(np.max(np.abs(first['steer_cmd'][early]))):.2f} deg")


def main() -> None:
    warnings.simplefilter("ignore")
    before, after = LVMS_SEAM_M
    print("1. the bridge's move of each bound file's points [cm] (s [m]: move)")
    for fname in _io.LVMS_BOUNDS:
        raw = _io.read_csv(_io.bundled_recording_file(fname), fname)
        s, d = _bulge(raw.col("x")[:-1], raw.col("y")[:-1])  # the closing repeat dropped
        order = np.argsort(s)
        shown = " ".join(f"{s[k]:.0f}:{100 * d[k]:.0f}" for k in order[np.abs(s[order]) < 50][::8])
        print(f"  {fname}: max {100 * d.max():.0f} cm at {s[np.argmax(d)]:+.0f} m; {shown}")

    print(f"2. curvature [1/m] over the stretch (-{before:g}, +{after:g}) m and over the lap")
    raw_pts = lvms_centerline(bridge_seam=False)
    pts = lvms_centerline()
    move = np.hypot(pts.x - raw_pts.x, pts.y - raw_pts.y)
    print(f"  the bridge moves {np.count_nonzero(move)} points, by up to {move.max():.3f} m")
    for cut_off in (LVMS_SMOOTHING_LENGTH, 20.0):
        for label, p in (("without the bridge", raw_pts), ("bridged", pts)):
            g = p.to_track(smoothing_length=cut_off).geometry
            k = g[:, GC.KAPPA]
            sg = _signed(g[:, GC.S], g[-1, GC.S])
            st = (sg > -before) & (sg < after)
            i, j = np.argmin(np.where(st, k, np.inf)), np.argmax(np.where(st, k, -np.inf))
            wide = np.abs(sg) < 70.0
            jw = np.argmax(np.where(wide, k, -np.inf))
            print(f"  cut-off {cut_off:g} m, {label:18s}: stretch min {k[i]:+.5f} at "
                  f"{sg[i]:+.0f} m, max {k[j]:+.5f} at {sg[j]:+.0f} m (within 70 m: max "
                  f"{k[jw]:+.5f} at {sg[jw]:+.0f} m); lap min {k.min():+.5f}, "
                  f"max {k.max():+.5f}")

    print("3. the recorded car's distance from the centerline, 30 m before to 70 m after "
          "the line")
    rec = load_recording().on_track()
    for label, p in (("without the bridge", raw_pts), ("bridged", pts)):
        t = p.to_track()
        pr = t.project(rec["x"], rec["y"], rec.psi)
        sg = _signed(pr["s"], t.length)
        near = np.flatnonzero((sg > -30.0) & (sg < 70.0))
        spans = [np.ptp(pr["e_y"][i]) for i in np.split(near, np.flatnonzero(np.diff(near) > 1)
                                                          + 1)]
        print(f"  {label:18s}: span per pass " + " / ".join(f"{100 * v:.0f}" for v in spans)
              + " cm")
    spans = []
    for c in np.arange(150.0, t.length - 150.0, 25.0):
        w = np.flatnonzero((pr["s"] > c - 50.0) & (pr["s"] < c + 50.0))
        spans += [np.ptp(pr["e_y"][i]) for i in np.split(w, np.flatnonzero(np.diff(w) > 1) + 1)
                  if i.size > 50]
    print(f"  elsewhere (100 m windows, {len(spans)}): median span {np.median(spans):.2f} m")

    print("4. the closed loop's start, paper-noise-free")
    print(f"  bridged: {_start('LVMS')}")
    with tempfile.TemporaryDirectory() as folder:
        csv = raw_pts.to_track(name="LVMS unbridged").to_csv(
            os.path.join(folder, "LVMS_unbridged.csv"))
        print(f"  without the bridge: {_start(str(csv))}")


if __name__ == "__main__":
    main()
