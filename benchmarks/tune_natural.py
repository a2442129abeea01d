"""Search the natural-output controller's settings for a more robust `paper` (issue 7).

Run as a script (each mode appends one JSON line per candidate to ``--out`` and prints the
best; nothing here is a test)::

    python benchmarks/tune_natural.py random --n 3000 --rng 10 --out r.jsonl
    python benchmarks/tune_natural.py local --n 2000 --start '{"alpha_lat": 52, ...}' --out l.jsonl
    python benchmarks/tune_natural.py factors --set alpha_lat=52 --set zeta_lat=1.45 ...
    python benchmarks/tune_natural.py random --fix curvature_term=true ...  # under every one
    python benchmarks/tune_natural.py robust --from r.jsonl --out rob.jsonl  # the survivors

What it screens, on the `paper` scenario (peugeot406, 10DoF, realistic sensors), with seeds
that the reviewed bands and the 100-seed tables of benchmarks/README.md do not use:

* **Spa's first 50 s** (``timing.duration_s`` 50: Eau Rouge at 30-33 s and the chicane at
  42-48 s, where the algebraic design loses its laps; ~0.08 s a run). A run counts as *bad*
  when it leaves the track or its max lateral error exceeds 4 cm (issue 7's 2x of 2 cm).
* **Norisring laps** (the default track, 2 cm asked): the max lateral error over the seeds.

Every candidate is a set of settings over the controller's defaults (``MfcNaturalSettings``;
`paper`'s own tuning, ``scenarios.NATURAL_SETTINGS``, is what this found, candidate C of
benchmarks/README.md). ``random`` draws candidates over the lateral loop's settings (ranges in
:data:`RANDOM`; half of them without the speed schedule, ``wn_lat_speed`` 0, half without the
position denoiser, ``denoise_lat`` 0, and ``derivative_lat`` either way) and drops one as soon
as it is worse on Spa than ``--max-bad`` (default: the defaults' count less 2); ``local``
perturbs the best candidates found so far (log-normal steps of 15 % on 1-3 settings,
:data:`LOCAL`; its start is measured whatever its Norisring figure) and keeps those within
``--nor-max`` on Norisring; ``robust`` takes the candidates of ``--from`` (a file of
``random`` or ``local``) that lost no Spa run and checks what the screens above do not see
(:func:`robust`): starts off the path (``initial_offset.py``'s runs, noise-free, a straight
path; :data:`ENGAGE`) and 0.2 s gaps in the position (``position_gap.py``'s runs; :data:`GAPS`);
``factors`` takes a candidate's changes against the defaults one
at a time and all but one at a time, to tell which of them matter. The summary at the end
reads the whole ``--out`` file (earlier runs appended to it included: one file per screen).
A screen is a selection, not a measurement: check a candidate with
``benchmarks/sweep_seeds.py --seeds 100 --set ...`` on every track before trusting it.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from sweep_seeds import parse_settings  # benchmarks/ is the script's folder (sys.path[0])

from flatfree.controllers.vehicle import MfcNaturalSettings
from flatfree.metrics import compute_metrics
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate

#: Ranges of the random search: (low, high) uniform, ``log`` for alpha_lat; ints for counts.
RANDOM = {"wn_lat": (5.0, 12.0), "zeta_lat": (0.6, 1.6), "wn_lat_speed": (15.0, 40.0),
          "wn_lat_ratio": (1.0, 2.0), "yaw_damping": (0.0, 1.0), "denoise_yaw": (0, 150),
          "window_lat": (50, 250), "alpha_lat": (15.0, 60.0), "denoise_lat": (5, 100)}
#: Bounds of the local search's steps (the speed loop's settings and the bound included).
LOCAL = {"wn_lat": (4.0, 14.0), "zeta_lat": (0.5, 2.0), "wn_lat_speed": (15.0, 45.0),
         "wn_lat_ratio": (1.0, 2.5), "yaw_damping": (0.05, 1.2), "alpha_lat": (15.0, 90.0),
         "kp_lon": (0.8, 5.0), "alpha_lon": (0.001, 0.005), "correction_max": (1.5, 8.0),
         "denoise_yaw": (0, 200), "window_lat": (50, 250), "window_lon": (40, 250)}
SPA_S = 50.0
#: Settings under every candidate and "the defaults" (``--fix``; e.g. ``curvature_term``).
FIXED: dict = {}
_DEFAULTS = MfcNaturalSettings()
BAD_M = 0.04


def run(track: str, seed: int, settings: dict, duration_s: float | None = None):
    """(completed, max lateral error [m]) of `paper` on ``track`` with ``settings`` over the
    controller's defaults (not over `paper`'s own tuning, NATURAL_SETTINGS, which this search
    found: every candidate and "the defaults" mean MfcNaturalSettings' values)."""
    sc = named_scenario("paper", track=track, seed=seed, duration_s=duration_s)
    sc = sc.with_(controller_settings={**FIXED, **settings})
    m = compute_metrics(simulate(sc))
    return m.status == "completed", m.lateral_error_max_m


def spa(settings: dict, seeds, give_up: int | None = None) -> dict:
    """Bad runs of Spa's first 50 s over ``seeds`` (stops once more than ``give_up``)."""
    bad = left = 0
    worst = 0.0
    for i, seed in enumerate(seeds):
        ok, e = run("Spa", seed, settings, SPA_S)
        left += not ok
        bad += (not ok) or e > BAD_M
        worst = max(worst, e) if ok else worst
        if give_up is not None and bad > give_up:
            return {"spa_bad": bad, "spa_runs": i + 1, "spa_left": left}
    return {"spa_bad": bad, "spa_runs": len(seeds), "spa_left": left, "spa_max_m": worst}


def norisring(settings: dict, seeds, give_up: float = math.inf) -> dict:
    """Max lateral error of Norisring laps over ``seeds`` (9.9 m for a lap not completed)."""
    worst = 0.0
    for i, seed in enumerate(seeds):
        ok, e = run("Norisring", seed, settings)
        worst = max(worst, e if ok else 9.9)
        if worst > give_up:
            return {"nor_max_m": worst, "nor_runs": i + 1}
    return {"nor_max_m": worst, "nor_runs": len(seeds)}


#: Starts off the path of the ``robust`` mode: (speed [m/s], offset [m]), 12 s runs; a start
#: passes when the car is within 1 cm of the path at the end (initial_offset.py: session 21's
#: settings pass every start of its grid, 0.05-3 m at 5-40 m/s).
ENGAGE = ((10.0, 0.05), (20.0, 0.05), (40.0, 0.1), (20.0, 0.3), (40.0, 1.0))
#: Position gaps of the ``robust`` mode: (start [s], length [s]) on Norisring, seed 0, 25 s runs
#: (position_gap.py: session 21's settings complete all three).
GAPS = ((11.0, 0.2), (12.0, 0.2), (13.0, 0.2))


def robust(settings: dict) -> dict:
    """Starts off the path that do not settle, and position gaps that lose the track, of
    ``settings`` over :data:`FIXED` and the controller's defaults."""
    import initial_offset  # benchmarks/
    import position_gap

    full = MfcNaturalSettings(**{**FIXED, **settings})
    unsettled = [f"{v:g} m/s {e0:g} m" for v, e0 in ENGAGE
                 if not initial_offset.run(full, v, e0, seconds=12.0)[2] < 12.0]
    lost = []
    for t0, dur in GAPS:
        _, m = position_gap.run_settings({**FIXED, **settings}, t0, dur)
        if m.status != "completed":
            lost.append(f"{dur:g} s at {t0:g} s")
    return {"unsettled": unsettled, "gaps_lost": lost}


def _draw(rng: np.random.Generator, ranges: dict) -> dict:
    s = {}
    for k, (lo, hi) in ranges.items():
        if k == "alpha_lat":
            s[k] = round(float(np.exp(rng.uniform(np.log(lo), np.log(hi)))), 1)
        elif isinstance(lo, int):
            s[k] = int(rng.integers(lo, hi + 1))
            if s[k] == 1:  # a denoiser of 1 sample is not one (the settings refuse it): off
                s[k] = 0
        else:
            s[k] = round(float(rng.uniform(lo, hi)), 2)
    if rng.random() < 0.5:
        s["wn_lat_speed"] = 0.0  # no speed schedule
    if rng.random() < 0.5:
        s["denoise_lat"] = 0
    s["derivative_lat"] = str(rng.choice(["model", "algebraic"]))
    return s


def _step(s: dict, rng: np.random.Generator, scale: float = 0.15) -> dict:
    t = dict(s)
    for key in rng.choice(list(LOCAL), size=int(rng.integers(1, 4)), replace=False):
        k = str(key)
        lo, hi = LOCAL[k]
        v = t.get(k, _default(k))
        if isinstance(lo, int):
            t[k] = int(np.clip(round(max(v, 5) * math.exp(rng.normal(0.0, scale))), lo, hi))
        else:
            t[k] = round(float(np.clip(v * math.exp(rng.normal(0.0, scale)), lo, hi)), 3)
    return t


def _default(key: str):
    return getattr(_DEFAULTS, key)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("random", "local", "factors", "robust"))
    ap.add_argument("--from", dest="src", default=None, help="robust: a file of candidates")
    ap.add_argument("--n", type=int, default=500, help="candidates (random, local)")
    ap.add_argument("--rng", type=int, default=0, help="seed of the search's own draws")
    ap.add_argument("--start", default="{}", help="local: the first candidate (JSON)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="factors: the candidate's changes against the defaults")
    ap.add_argument("--fix", action="append", default=[], metavar="KEY=VALUE",
                    help="a setting under every candidate and the defaults (all modes)")
    ap.add_argument("--alpha-range", default=",".join(map(str, RANDOM["alpha_lat"])),
                    metavar="LO,HI",
                    help="random: alpha_lat's range (log-uniform)")
    ap.add_argument("--spa-seeds", default="200,236", help="first,stop of Spa's seeds")
    ap.add_argument("--nor-seeds", default="200,206", help="first,stop of Norisring's seeds")
    ap.add_argument("--max-bad", type=int, default=None, help="random: drop above this")
    ap.add_argument("--nor-max", type=float, default=0.0195, help="local: Norisring gate [m]")
    ap.add_argument("--out", default="tune_natural.jsonl")
    args = ap.parse_args(argv)
    spa_seeds = range(*map(int, args.spa_seeds.split(",")))
    nor_seeds = range(*map(int, args.nor_seeds.split(",")))
    rng = np.random.default_rng(args.rng)
    FIXED.update(parse_settings(args.fix))
    ranges = {**RANDOM, "alpha_lat": tuple(map(float, args.alpha_range.split(",")))}

    if args.mode == "robust":
        if args.src is None:
            ap.error("robust needs --from FILE (the candidates of a random or local run)")
        with open(args.src) as f:
            cands = [json.loads(line) for line in f]
        cands = [r for r in cands if r.get("spa_bad") == 0 and "nor_max_m" in r]
        for r in cands:  # the settings the screen ran under, unless --fix says otherwise
            r["settings"] = {**r.get("fixed", {}), **r["settings"]}
        cands.sort(key=lambda r: max(r["nor_max_m"] / 0.02, r["spa_max_m"] / 0.04))
        with open(args.out, "a") as f:
            for cand in cands[:args.n]:
                t0 = time.perf_counter()
                r = {**cand, **robust(cand["settings"])}
                r["wall_s"] = round(time.perf_counter() - t0, 2)
                f.write(json.dumps(r) + "\n")
                f.flush()
                print(r, flush=True)
        return

    if args.mode == "factors":
        new = parse_settings(args.set)
        sets = {"defaults": {}, "all": new}
        for k in new:
            sets[f"only {k}"] = {k: new[k]}
            sets[f"all but {k}"] = {j: v for j, v in new.items() if j != k}
        for name, s in sets.items():
            r = {**spa(s, spa_seeds), **norisring(s, nor_seeds)}
            print(f"{name:28s} Spa {SPA_S:g} s: left {r['spa_left']}/{r['spa_runs']}, bad "
                  f"{r['spa_bad']}, max {100 * r['spa_max_m']:.2f} cm; Norisring max "
                  f"{100 * r['nor_max_m']:.2f} cm", flush=True)
        return

    base = {**spa({}, spa_seeds), **norisring({}, nor_seeds)}
    print("defaults", base, flush=True)
    max_bad = max(base["spa_bad"] - 2, 0) if args.max_bad is None else args.max_bad
    elites = []
    if args.mode == "local":
        first = json.loads(args.start)
        elites.append({"settings": first, **spa(first, spa_seeds), **norisring(first, nor_seeds)})
    with open(args.out, "a") as f:
        for _ in range(args.n):
            t0 = time.perf_counter()
            if args.mode == "random":
                s = _draw(rng, ranges)
                r = {"settings": s, **spa(s, spa_seeds, max_bad)}
                if r["spa_runs"] == len(spa_seeds) and r["spa_bad"] <= max_bad:
                    r.update(norisring(s, nor_seeds))
            else:
                s = _step(elites[int(rng.integers(len(elites)))]["settings"], rng)
                r = {"settings": s, **norisring(s, nor_seeds, args.nor_max)}
                if r["nor_max_m"] <= args.nor_max:
                    best = min(e["spa_bad"] for e in elites)
                    r.update(spa(s, spa_seeds, best + 2))
                    if "spa_max_m" in r:
                        elites = sorted([*elites, r], key=lambda e: (e["spa_bad"],
                                                                     e.get("spa_max_m", 9.0)))[:8]
            r["wall_s"] = round(time.perf_counter() - t0, 2)
            r["fixed"] = FIXED  # the settings under the candidate (--fix)
            f.write(json.dumps(r) + "\n")
            f.flush()
    with open(args.out) as f:
        done = [json.loads(line) for line in f]
    done = [r for r in done if "spa_max_m" in r and "nor_max_m" in r]
    for r in sorted(done, key=lambda r: (r["spa_bad"], r["nor_max_m"]))[:5]:
        print(r, flush=True)


if __name__ == "__main__":
    main()
