"""Where the closed loop's time goes: each part of a lap timed alone on the lap's own data.

Run as a script (``python benchmarks/profile_closed_loop.py [scenario] [track]``, default
``paper``, the default track); it prints the figures of benchmarks/README.md "Closed loop"
(breakdown). Nothing here is a test.

1. The whole lap in the compiled loop (:func:`flatfree.simulation.simulate`): ns per plant step.
2. The lap again through the Python door with the built-in controller's own kernel
   (:func:`flatfree.controllers.vehicle.vehicle_step`; bit for bit the same trajectory, checked),
   logging every plant step and recording the controller's inputs at every control step.
3. On those recordings, each part alone in a compiled loop:

   - the plant: RK4 steps of the 10DoF model driven by the applied inputs of the lap, from the
     same initial state (:func:`flatfree.models.tendof.simulate_kernel`; it retraces the lap's
     states, checked);
   - the Frenet projection of the true poses (:func:`flatfree.tracks.project_points`; the loop
     projects the measured pose at every control step, and the true pose at the logged rows
     and wherever a check could decide: about once per plant step in all);
   - the controller: :func:`~flatfree.controllers.vehicle.vehicle_step` on the recorded
     measurements, references and applied inputs (fresh controller state).

4. ``simulate()`` end to end against the loop, and the preparation piece by piece: the
   reference, the flying-lap start speed, the whole ``prepare``, the sensor noise.

The parts do not add up to the whole: the loop is one dependency chain per step (plant ->
projection -> controller -> actuators -> plant), and the processor overlaps the work that is
off that chain (logging, the wheel diagnostics, the second projection's bookkeeping) with it.
"The rest" below is the whole minus the three parts.

The machine has 2 cores shared with other jobs: timings are noisy; the best of several
repeats is reported.
"""

from __future__ import annotations

import dataclasses
import math
import platform
import sys
import time

import numpy as np
from numba import njit

from flatfree._timing import best_time
from flatfree.controllers.vehicle import MEAS, vehicle_step
from flatfree.models.tendof import NU, simulate_kernel
from flatfree.scenario import Timing
from flatfree.scenarios import named_scenario
from flatfree.simulation import prepare, simulate
from flatfree.tracks import frenet_init, project_points


class _Recorder:
    """Python controller running the built-in kernel and recording its inputs."""

    def __init__(self, sc, n: int):
        self.prep = prepare(sc)
        self.c = self.prep.controller
        self.meas = np.empty((n, len(MEAS)))
        self.cref = np.empty((n, self.prep.cref.shape[1] - 1))
        self.applied = np.empty((n, 2))
        self.i = 0

    def reset(self):
        self.c.reset()

    def step(self, t, measurement, reference, applied):
        i = self.i
        self.meas[i] = measurement
        self.cref[i] = reference
        self.applied[i] = applied
        self.i += 1
        c = self.c
        return vehicle_step(c.kind, c.p_lon, c.s_lon, c.p_lat, c.s_lat, c.coef, c.f_lon, c.f_lat,
                            c.f_yaw, measurement, reference, applied[0], applied[1])


@njit  # not cached: it inlines flatfree kernels (flatfree._jitcache)
def _controller_only(kind, p_lon, s_lon, p_lat, s_lat, coef, f_lon, f_lat, f_yaw, meas, cref,
                     applied):
    acc = 0.0
    for k in range(meas.shape[0]):
        tw, de = vehicle_step(kind, p_lon, s_lon, p_lat, s_lat, coef, f_lon, f_lat, f_yaw,
                              meas[k], cref[k], applied[k, 0], applied[k, 1])
        acc += tw + de
    return acc


def main() -> None:
    name = sys.argv[1] if len(sys.argv) > 1 else "paper"
    track = sys.argv[2] if len(sys.argv) > 2 else None
    sc = named_scenario(name) if track is None else named_scenario(name, track=track)
    if sc.plant != "10dof" or sc.timing.control_every != 1:
        raise SystemExit("this profile assumes the 10DoF plant and control at the plant rate")
    print(f"machine: {platform.processor() or platform.machine()}, python "
          f"{platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    simulate(sc.with_(timing=Timing(duration_s=1.0)))  # JIT warm-up
    runs = [simulate(sc) for _ in range(5)]
    tr = max(runs, key=lambda r: r.meta["real_time_factor"])
    dt = sc.timing.plant_dt_s
    whole = dt / tr.meta["real_time_factor"]  # the factor counts the steps the loop ran
    print(f"{name} on {sc.reference.track}: {tr.status.value} after {tr.duration:.1f} s")
    print(f"  whole loop (best of 5)            {whole * 1e9:7.1f} ns/step "
          f"({tr.meta['real_time_factor']:.0f}x real time)")

    # the same lap through the Python door, logged at every plant step
    # (the same timing but the log: the same sensor noise)
    fine = sc.with_(timing=dataclasses.replace(sc.timing, log_dt_s=dt))
    rec = _Recorder(fine, prepare(fine).n_steps + 1)
    tr_py = simulate(fine, controller=rec)
    m = rec.i
    every = sc.timing.log_every
    k_log = min(len(tr), len(tr_py["x"][::every]))
    same = np.array_equal(tr_py["x"][::every][:k_log], tr["x"][:k_log])
    print(f"  (recorded {m} control steps through the Python door; same trajectory: {same})")

    # 1) the plant alone, driven by the applied inputs
    prep = rec.prep
    from flatfree.models.tendof import TenDoF

    model = TenDoF(prep.vehicle)
    tpf = prep.vehicle.tire_front.to_array()
    tpr = prep.vehicle.tire_rear.to_array()
    steps = len(tr_py) - 1
    us = np.zeros((steps, NU))
    us[:, 0] = tr_py["torque"][:steps]
    us[:, 1] = tr_py["steer"][:steps]
    us[:, 2:6] = sc.road.mu if not sc.road.patches else np.nan  # flat road: bank 0
    if sc.road.patches:
        raise SystemExit("friction patches: not supported by this profile")
    xs = np.empty((steps + 1, prep.x0.size))
    t_plant = best_time(simulate_kernel, prep.x0, us, dt, model.params, tpf, tpr, xs) / steps
    retraced = np.array_equal(xs[1:, 0], tr_py["x"][1:steps + 1])
    print(f"  plant alone (10DoF RK4)            {t_plant * 1e9:7.1f} ns/step "
          f"(retraces the lap: {retraced})")

    # 2) the Frenet projection of the true poses
    g = prep.reference.path.geometry
    closed = prep.reference.path.closed
    px = np.ascontiguousarray(tr_py["x"])
    py = np.ascontiguousarray(tr_py["y"])
    ps = np.ascontiguousarray(tr_py["psi"])
    seg0 = frenet_init(g, closed, px[0], py[0], ps[0])
    t_proj = best_time(project_points, g, closed, px, py, ps, seg0) / len(px)
    print(f"  one Frenet projection              {t_proj * 1e9:7.1f} ns/step "
          f"(the loop: the measured pose each control step, the true pose at logged rows)")

    # 3) the controller alone on its recorded inputs (fresh state each repeat; the first
    # repeat compiles)
    best = math.inf
    for _ in range(6):
        c = prepare(fine).controller
        t0 = time.perf_counter()
        _controller_only(c.kind, c.p_lon, c.s_lon, c.p_lat, c.s_lat, c.coef, c.f_lon, c.f_lat,
                         c.f_yaw, rec.meas[:m], rec.cref[:m], rec.applied[:m])
        best = min(best, time.perf_counter() - t0)
    t_ctrl = best / m
    print(f"  controller alone (vehicle_step)    {t_ctrl * 1e9:7.1f} ns/step")
    rest = whole - t_plant - t_proj - t_ctrl
    print(f"  the rest (whole - the three)       {rest * 1e9:7.1f} ns/step (sensors, the true "
          "pose's projections, references, actuators, logging, loop; minus overlap)")

    # 4) simulate() end to end: what a run costs besides the loop, each piece timed alone
    _end_to_end(sc, tr)


def _end_to_end(sc, tr) -> None:
    """simulate()'s wall time beside the loop's, and its preparation piece by piece (best of
    5 each): the reference, the flying-lap start speed, the whole prepare (and a process's
    first, the bundled track and car built again: the two alone), the sensor noise the lap
    draws (a block at a time, up to the block of its last step)."""
    from flatfree.controllers.vehicle import unread_channels
    from flatfree.sensors import SENSOR_CHANNELS
    from flatfree.simulation import _NOISE_BLOCK, flying_lap_speed, reference_of
    from flatfree.tracks import load_track
    from flatfree.tracks.loaders import _bundled_track
    from flatfree.vehicles.params import _preset

    prep = prepare(sc)
    ref = prep.reference
    n_ctrl = prep.n_steps // sc.timing.control_every + 1
    # the control steps the lap ran (the noise up to the end of the block of its last one; the
    # loop may have run up to a log period past the last logged row)
    n_run = int(round((tr.duration + sc.timing.log_dt_s) / sc.timing.control_dt_s)) + 1

    def best(fn) -> float:
        return best_time(fn, repeats=5)

    def cold(fn):  # the bundled track and car built again, as in a process's first run
        def call():
            _bundled_track.cache_clear()
            _preset.cache_clear()
            fn()
        return call

    total = best(lambda: simulate(sc))
    loop = tr.meta["wall_time_s"]
    print(f"simulate() end to end (best of 5)     {total * 1e3:7.1f} ms "
          f"({tr.duration / total:.0f}x real time; the loop {loop * 1e3:.1f} ms of it)")
    print(f"  prepare                            {best(lambda: prepare(sc)) * 1e3:7.1f} ms "
          f"(a process's first: {best(cold(lambda: prepare(sc))) * 1e3:.1f} ms)")
    print(f"    the bundled track's build        "
          f"{best(cold(lambda: load_track(sc.reference.track))) * 1e3:7.1f} ms")
    print(f"    the vehicle preset's files       "
          f"{best(cold(sc.load_vehicle)) * 1e3:7.1f} ms")
    print(f"    reference (track, profile)       {best(lambda: reference_of(sc)) * 1e3:7.1f} ms")
    fly = best(lambda: flying_lap_speed(ref["s_path"], ref["vx"], prep.vehicle, closed=True))
    print(f"    flying-lap start speed           {fly * 1e3:7.1f} ms")
    unread = unread_channels(prep.controller)  # the channels the controller reads, as the loop

    def draw():
        cs = sc.effective_sensors.compile(SENSOR_CHANNELS, sc.timing.control_dt_s, n_ctrl,
                                          sc.seed, block=_NOISE_BLOCK, unread=unread)
        while cs.first_step + cs.noise.shape[1] < n_run:
            cs.next_block()
        return cs.first_step + cs.noise.shape[1]

    drawn = draw()
    print(f"  sensor noise                       {best(draw) * 1e3:7.1f} ms "
          f"({drawn} control steps x {len(SENSOR_CHANNELS) - len(unread)} channels, in blocks of "
          f"{_NOISE_BLOCK}; the allotted duration has {n_ctrl})")


if __name__ == "__main__":
    main()
