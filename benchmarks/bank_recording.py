"""The recorded drive on a banked road: how much of the gap between the simulated and the
recorded steer the Las Vegas oval's banking explains (information for planning; not a test).

Run as a script (``python benchmarks/bank_recording.py``). The bank comes from the recording's
``roll`` column, which ``data/recordings/PROVENANCE.md`` calls doubtful ("do not rely on it"):
it reads 0 for the first ~110 s and then map-like steps (-9.0, -10.5, -14.2, -20.0 deg) that
match the oval's published banking (20 deg turns, 9 deg frontstretch) in the turns and on the
frontstretch. This script takes the bank at each point of the driven path from the nearest
recorded sample whose roll is not 0 (|roll| > 1e-3 rad; the early laps borrow the later
laps' values) and compares, for ``recorded`` and ``recorded-noise-free`` (seed 0), the
flat road with that banked road: max lateral error, the applied steer against the driver's
(RMS of the difference, slope of the least-squares line through the origin, correlation),
after the metrics' start-up interval.
"""

from __future__ import annotations

import dataclasses
import platform
import time
import warnings

import numpy as np
from scipy.spatial import cKDTree

from flatfree.cli import steer_rms_vs_recorded_deg
from flatfree.metrics import DEFAULT_STARTUP_S, compute_metrics
from flatfree.scenarios import named_scenario, recorded_steer
from flatfree.simulation import prepare, simulate
from flatfree.tracks import load_recording


def bank_profile(sc) -> tuple[tuple[float, float], ...]:
    """(s [m], bank [deg]) along the scenario's recorded path from the roll column."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = prepare(sc).reference
    raw = load_recording(sc.reference.recording)
    roll = np.asarray(raw["roll"], dtype=float)
    ok = np.isfinite(roll) & (np.abs(roll) > 1e-3)  # 0 (to 4e-8 rad): not read yet
    tree = cKDTree(np.column_stack((raw["x"][ok], raw["y"][ok])))
    _, idx = tree.query(np.column_stack((ref["x"], ref["y"])))
    bank = np.degrees(roll[ok][idx])
    s = np.asarray(ref["s_path"], dtype=float)
    pts, last = [], -np.inf
    for si, bi in zip(s, bank, strict=True):  # every 0.5 m or more, increasing
        if si > last + 0.5:
            pts.append((float(si), float(bi)))
            last = si
    return tuple(pts)


def steer_figures(tr, sc) -> tuple[float, float, float]:
    """RMS of steer - driver [deg] (as ``flatfree run --recording``), slope, correlation."""
    rec = recorded_steer(tr["t_ref"], sc)
    rms = steer_rms_vs_recorded_deg(tr, rec)
    keep = (tr.time >= tr.time[0] + DEFAULT_STARTUP_S) & np.isfinite(rec)
    sim, drv = np.asarray(tr["steer"])[keep], rec[keep]
    slope = float(np.dot(sim, drv) / np.dot(drv, drv))
    corr = float(np.corrcoef(sim, drv)[0, 1])
    return rms, slope, corr


def main() -> None:
    print(f"machine: {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    for name in ("recorded-noise-free", "recorded"):
        sc = named_scenario(name, seed=0)
        pts = bank_profile(sc)
        banks = np.array([b for _, b in pts])
        if name == "recorded-noise-free":
            print(f"bank profile: {len(pts)} points, {banks.min():.1f} to {banks.max():.1f} deg")
        for label, road in (("flat", sc.road),
                            ("banked", dataclasses.replace(sc.road, bank_deg=pts))):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                tr = simulate(sc.with_(road=road))
            m = compute_metrics(tr)
            rms, slope, corr = steer_figures(tr, sc)
            print(f"  {name:20s} {label:7s} {tr.status.value:10s} max lateral "
                  f"{100 * m.lateral_error_max_m:5.2f} cm  steer - driver RMS {rms:5.3f} deg  "
                  f"slope {slope:4.2f}  correlation {corr:4.2f}")


if __name__ == "__main__":
    main()
