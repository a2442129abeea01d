"""The accelerometer-aided natural-output controller (``paper-imu``) beyond the seed sweeps.

Run as a script::

    python benchmarks/imu_sensitivity.py                     # every section, ~3 minutes
    python benchmarks/imu_sensitivity.py --only bias,recorded
    python benchmarks/imu_sensitivity.py --set yaw_damping=0 --only sensitivity

Sections (the tables of benchmarks/README.md "Closed loop", "Acceleration-aided F"):

``sensitivity``
    One sensor change at a time against the realistic set (max lateral error [cm], Norisring
    and Spa, seeds 0-1): accelerometer noise and bias, position noise, the observer's
    bandwidth and filter, accelerometer and whole-suite sample rates and delays.
``bias``
    The optional bias state of the observer (``observer_bias_wn`` 0 / 0.5 / 1 / 2 / 5 rad/s)
    against a 0.5 m/s^2 accelerometer bias, 1 cm of position noise and every channel at 100 Hz
    (seeds 0-2).
``recorded``
    The steer against the recorded driver's on the recording, both estimators, with and without
    noise: correlation and mean |steer| (read on the reference clock, as ``flatfree run
    --recording`` does).
``yaw``
    The yaw error's sideslip gap: max |beta_10DoF - beta_ref| for the implemented (quasi-static,
    linear 3DoF) reference and for a dynamic one, the sideslip of the 3DoF plant driven round
    the lap by the same controller (noise-free).
``understeer``
    The algebraic ``paper`` on a peugeot406 whose rear tyres are 1.3x stiffer in cornering
    (an understeering variant written to a temporary vehicle file), seeds 0-3: max yaw error
    and completion against the preset.

``--set KEY=VALUE`` overrides the controller settings of every ``paper-imu`` run (e.g. the
figures of the first, damper-less setting: ``--set yaw_damping=0 --set denoise_yaw=50``).
Nothing here is a test.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from importlib import resources
from pathlib import Path

import numpy as np
from sweep_seeds import parse_settings  # benchmarks/ is the script's folder (sys.path[0])

from flatfree.metrics import compute_metrics
from flatfree.scenarios import REALISTIC_SENSORS, named_scenario, recorded_steer
from flatfree.sensors import SensorSuite
from flatfree.simulation import prepare, simulate

_CH = dict(REALISTIC_SENSORS.channels)
_SCALED = ("noise_std", "bias")


def _suite(names=(), **change) -> SensorSuite:
    """The realistic set with ``change`` on the channels ``names`` (noise and bias as factors,
    rate and delay as values)."""
    out = dict(_CH)
    for k in names:
        out[k] = dataclasses.replace(_CH[k], **{
            a: getattr(_CH[k], a) * v if a in _SCALED else v for a, v in change.items()})
    return SensorSuite(out)


def _run(name, track, seed, settings, sensors=None):
    sc = named_scenario(name, track=track, seed=seed)
    if sensors is not None:
        sc = sc.with_(sensors=sensors)
    if settings:
        sc = sc.with_(controller_settings={**sc.controller_settings, **settings})
    tr = simulate(sc)
    return tr, compute_metrics(tr)


def _cell(m) -> str:
    return f"{100 * m.lateral_error_max_m:.2f}" + ("" if m.status == "completed" else " LEFT")


def sensitivity(settings):
    everything = tuple(_CH)
    cases = [
        ("none (the scenario)", _suite(), {}),
        ("accelerometer noise x4", _suite(("ax", "ay"), noise_std=4.0), {}),
        ("ay bias x10", _suite(("ay",), bias=10.0), {}),
        ("position noise x10", _suite(("x", "y"), noise_std=10.0), {}),
        ("position noise x10, observer_wn 10", _suite(("x", "y"), noise_std=10.0),
         {"observer_wn": 10.0}),
        ("position noise x10, observer_wn 5", _suite(("x", "y"), noise_std=10.0),
         {"observer_wn": 5.0}),
        ("observer_wn 5", _suite(), {"observer_wn": 5.0}),
        ("observer_wn 10", _suite(), {"observer_wn": 10.0}),
        ("observer_wn 40", _suite(), {"observer_wn": 40.0}),
        ("imu_filter_s 1 ms", _suite(), {"imu_filter_s": 0.001}),
        ("imu_filter_s 20 ms", _suite(), {"imu_filter_s": 0.02}),
        ("accelerometers at 250 Hz", _suite(("ax", "ay"), rate_hz=250.0), {}),
        ("accelerometers at 100 Hz", _suite(("ax", "ay"), rate_hz=100.0), {}),
        ("accelerometers 5 ms late", _suite(("ax", "ay"), delay_s=0.005), {}),
        ("accelerometers 10 ms late", _suite(("ax", "ay"), delay_s=0.010), {}),
        ("every channel at 100 Hz", _suite(everything, rate_hz=100.0), {}),
        ("every channel 5 ms late", _suite(everything, delay_s=0.005), {}),
    ]
    print("sensitivity: paper-imu, max lateral error [cm], Norisring seeds 0 1 | Spa seeds 0 1")
    for label, sensors, extra in cases:
        cells = [_cell(_run("paper-imu", tr, seed, {**settings, **extra}, sensors)[1])
                 for tr in ("Norisring", "Spa") for seed in (0, 1)]
        print(f"  {label:38s} {cells[0]:>6s} {cells[1]:>6s} | {cells[2]:>6s} {cells[3]:>6s}",
              flush=True)
    for label, sensors in (("every channel at 100 Hz", _suite(everything, rate_hz=100.0)),
                           ("every channel 5 ms late", _suite(everything, delay_s=0.005))):
        cells = [_cell(_run("paper", tr, seed, {}, sensors)[1])
                 for tr in ("Norisring", "Spa") for seed in (0, 1)]
        print(f"  algebraic paper, {label:21s} {' '.join(cells)}", flush=True)


def bias(settings):
    cases = [("ay bias 0.5 m/s^2", _suite(("ay",), bias=50.0)),
             ("position noise x10", _suite(("x", "y"), noise_std=10.0)),
             ("every channel at 100 Hz", _suite(tuple(_CH), rate_hz=100.0))]
    print("bias state: paper-imu, max lateral error [cm], Norisring seeds 0-2 | Spa seeds 0-2")
    for wb in (0.0, 0.5, 1.0, 2.0, 5.0):
        for label, sensors in cases:
            cells = [_cell(_run("paper-imu", tr, seed, {**settings, "observer_bias_wn": wb},
                                sensors)[1]) for tr in ("Norisring", "Spa") for seed in range(3)]
            print(f"  observer_bias_wn {wb:3.1f}  {label:24s} {' '.join(cells[:3])} | "
                  f"{' '.join(cells[3:])}", flush=True)


def recorded(settings):
    print("recorded: the controller's steer against the driver's (reference clock)")
    for name in ("recorded-imu", "recorded"):
        for sfx in ("", "-noise-free"):
            sc = named_scenario(name + sfx)
            if settings and name == "recorded-imu":
                sc = sc.with_(controller_settings={**sc.controller_settings, **settings})
            tr = simulate(sc)
            m = compute_metrics(tr)
            drv = recorded_steer(tr["t_ref"], sc)
            corr = float(np.corrcoef(tr["steer"], drv)[0, 1])
            print(f"  {name + sfx:26s} max {100 * m.lateral_error_max_m:.2f} cm, yaw "
                  f"{m.yaw_error_max_deg:.2f} deg, correlation {corr:.3f}, mean |steer| "
                  f"{np.mean(np.abs(tr['steer'])):.4f} rad (driver "
                  f"{np.mean(np.abs(drv)):.4f})", flush=True)


def yaw(settings):
    print("yaw: max |beta_10DoF - beta_ref| [deg] after 1 s, noise-free paper-imu")
    for tr in ("Norisring", "Budapest", "Monza"):
        sc = named_scenario("paper-imu-noise-free", track=tr)
        if settings:
            sc = sc.with_(controller_settings={**sc.controller_settings, **settings})
        t10, t3 = simulate(sc), simulate(sc.with_(plant="3dof"))
        p = prepare(sc)
        b10 = np.arctan2(t10["vy"], t10["vx"])
        b3 = np.interp(t10["s"], t3["s"], np.arctan2(t3["vy"], t3["vx"]))
        bref = np.interp(t10["s"], p.reference["s_path"], p.beta_ref)
        after = t10.time > 1.0
        print(f"  {tr:10s} quasi-static linear 3DoF reference "
              f"{np.degrees(np.abs(b10 - bref)[after].max()):.2f}, dynamic 3DoF (3DoF plant, "
              f"same controller, {t3.status}) {np.degrees(np.abs(b10 - b3)[after].max()):.2f}",
              flush=True)
        # where the gap peaks: the car's and the path's yaw rates around it
        i = int(np.argmax(np.abs(b10 - bref) * after))
        near = np.abs(t10.time - t10.time[i]) <= 0.5
        kappa = np.interp(t10["s"], p.reference["s_path"], p.reference["kappa"])
        print(f"             the gap peaks at t = {t10.time[i]:.2f} s, vx {t10['vx'][i]:.1f} m/s: "
              f"beta {np.degrees(b10[i]):.2f} deg against the reference's "
              f"{np.degrees(bref[i]):.2f}; within 0.5 s max |r| {np.abs(t10['r'][near]).max():.2f} "
              f"rad/s, max |vx kappa| {np.abs(t10['vx'] * kappa)[near].max():.2f} rad/s, "
              f"max |course error| {np.degrees(np.abs(t10['course_error'][near]).max()):.2f} deg",
              flush=True)


def understeer(_settings):
    src = resources.files("flatfree.vehicles").joinpath("data", "peugeot406.toml").read_text()
    old = 'tire_rear = "pacejka2006_205_60R15"'
    if old not in src:
        raise SystemExit("peugeot406.toml no longer names its rear tyre as expected")
    text = src.replace(old, 'tire_rear = { set = "pacejka2006_205_60R15", lambda_ky = 1.3 }')
    text = text.replace('name = "peugeot406"', 'name = "peugeot406_rear_x1.3"')
    print("understeer: algebraic paper, seeds 0-3, max yaw [deg] and laps completed")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "peugeot406_rear_x1.3.toml"
        path.write_text(text)
        for tr in ("Norisring", "Spa", "Budapest", "Monza"):
            cells = []
            for vehicle in (None, str(path)):
                ms = []
                for seed in range(4):
                    sc = named_scenario("paper", track=tr, seed=seed)
                    if vehicle:
                        sc = sc.with_(vehicle=vehicle)
                    ms.append(compute_metrics(simulate(sc)))
                done = [m for m in ms if m.status == "completed"]
                worst = max(m.yaw_error_max_deg for m in done) if done else float("nan")
                cells.append(f"{worst:.2f} deg, {len(done)}/4")
            print(f"  {tr:10s} preset {cells[0]:14s} rear x1.3 {cells[1]}", flush=True)


_SECTIONS = {"sensitivity": sensitivity, "bias": bias, "recorded": recorded,
             "yaw": yaw, "understeer": understeer}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(_SECTIONS), help="comma-separated sections")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="controller setting of every paper-imu run (repeatable)")
    args = ap.parse_args(argv)
    settings = parse_settings(args.set)
    t0 = time.perf_counter()
    for name in args.only.split(","):
        if name not in _SECTIONS:
            raise SystemExit(f"--only {name!r}: sections are {', '.join(_SECTIONS)}")
        _SECTIONS[name](settings)
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
