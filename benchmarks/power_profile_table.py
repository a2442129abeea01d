"""Lap time and top speed of the friction-only vs the power-aware speed profile (tracks/speed.py).

Run as a script (``python benchmarks/power_profile_table.py``): prints the table of
benchmarks/README.md "Power-aware speed profile" (every bundled track, peugeot406 and
dallara_av21, v_max 50 and 90 m/s, with the top speed of ``simulation.flying_lap_speed`` on the
friction-only profile) and the cost of ``speed_profile`` on Spa. Nothing here is a test.
"""
import time

import numpy as np

import flatfree.tracks as T
from flatfree.simulation import flying_lap_speed
from flatfree.vehicles import load_vehicle

for vn in ("peugeot406", "dallara_av21"):
    veh = load_vehicle(vn)
    for vmax in (50.0, 90.0):
        lim = T.SpeedLimits(v_max=vmax)
        for name in T.track_names():
            trk = T.load_track(name)
            p0 = T.speed_profile(trk, lim)
            p1 = T.speed_profile(trk, lim, vehicle=veh)
            fl = flying_lap_speed(trk.s, p0.v, veh, closed=True)
            print(f"| {vn:12s} | {vmax:4.0f} | {name:9s} | {p0.duration:7.2f} | "
                  f"{p1.duration:7.2f} | {p0.v.max():5.2f} | {p1.v.max():5.2f} | {fl.max():5.2f} |")
veh = load_vehicle("peugeot406")
trk = T.load_track("Spa")
for label, kw in (("friction only", {}), ("peugeot406", {"vehicle": veh})):
    T.speed_profile(trk, **kw)
    ts = []
    for _ in range(7):
        t0 = time.perf_counter()
        for _ in range(20):
            T.speed_profile(trk, **kw)
        ts.append((time.perf_counter() - t0) / 20)
    print(f"{label} Spa speed_profile best {min(ts) * 1e3:.2f} ms "
          f"median {np.median(ts) * 1e3:.2f} ms")
