"""The result of a simulation: named signals on a time grid, a status, and export.

A :class:`Trajectory` holds every logged signal (true states, measurements, references, commands,
applied inputs, Frenet errors, controller internals such as the estimated F) under a name, with its
unit. Signals are read by name, ``traj["lateral_error"]``, never by magic index. A status says how
the run ended; a run that left the track or went non-finite does not raise: it ends early, and
``status`` and ``status_time`` say so.
"""

from __future__ import annotations

import contextlib
import csv
import enum
import math
from collections.abc import Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from flatfree._validate import finite

__all__ = ["Status", "Trajectory"]


def _sidecar(path: Path) -> Path:
    """The JSON file beside a CSV export: ``run.csv`` -> ``run.csv.json``."""
    return path.with_name(path.name + ".json")


#: Set inside :func:`_adopting`: the arrays given are held by nobody else (the closed loop's
#: log, flatfree.simulation), and a Trajectory takes them as they are instead of copying them.
_ADOPT: ContextVar[bool] = ContextVar("flatfree_trajectory_adopt", default=False)


@contextlib.contextmanager
def _adopting() -> Iterator[None]:
    """Trajectories made in this block take their float64 arrays without a copy (still made
    read-only): for a producer that hands over arrays it no longer holds (a 10-minute run's
    log is 12 MB, and a copy doubles it at the run's peak)."""
    token = _ADOPT.set(True)
    try:
        yield
    finally:
        _ADOPT.reset(token)


def _float_array(name: str, values, adopt: bool) -> np.ndarray:
    """``values`` as float64: a copy, or (``adopt``) the array itself where it is one.

    Numbers only: text (``["1.0"]``, which numpy would parse), booleans and objects are a
    ``ValueError`` naming the signal ``name`` and the dtype, not a silent conversion."""
    a = np.asarray(values)
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name}: values of dtype {a.dtype} ({a.dtype.kind!r}): expected real "
                         "numbers (a float or integer array)")
    if adopt:
        return np.asarray(a, dtype=np.float64)
    return np.array(a, dtype=np.float64, copy=True)


class Status(enum.Enum):
    """How a closed-loop run ended."""

    COMPLETED = "completed"
    LEFT_TRACK = "left_track"  # |e_y| beyond the track half-width
    NON_FINITE = "non_finite"  # a state became NaN or infinite

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True, slots=True)
class Trajectory:
    """Named signals logged on a common time grid.

    Parameters
    ----------
    time
        Sample times [s], strictly increasing, shape (n,).
    signals
        Signal name -> array of shape (n,). Copied and made read-only.
    units
        Signal name -> unit string (SI; ``"-"`` for dimensionless). Every signal needs one.
    status
        How the run ended.
    status_time
        Time [s] at which a run that did not complete stopped; ``None`` when completed.
    meta
        Free-form description of the run (scenario, controller, seed, real-time factor, ...).
    """

    time: np.ndarray
    signals: Mapping[str, np.ndarray]
    units: Mapping[str, str]
    status: Status = Status.COMPLETED
    status_time: float | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        adopt = _ADOPT.get()
        t = _float_array("time", self.time, adopt)
        if t.ndim != 1:
            raise ValueError(f"time has shape {t.shape}: expected a 1-D array")
        if not np.all(np.isfinite(t)):
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise ValueError(f"time[{i}] = {float(t[i])!r} s: must be finite")
        if t.size > 1 and not np.all(np.diff(t) > 0.0):
            i = int(np.flatnonzero(~(np.diff(t) > 0.0))[0])
            raise ValueError(f"time must be strictly increasing: time[{i + 1}] = "
                             f"{float(t[i + 1])!r} s after time[{i}] = {float(t[i])!r} s")
        t.flags.writeable = False
        sig: dict[str, np.ndarray] = {}
        for name, values in self.signals.items():
            a = _float_array(f"signal {name!r}", values, adopt)
            if a.shape != t.shape:
                raise ValueError(
                    f"signal {name!r} has shape {a.shape}, expected {t.shape} like time"
                )
            if name not in self.units:
                raise ValueError(f"signal {name!r} has no unit in units")
            a.flags.writeable = False
            sig[name] = a
        if not isinstance(self.status, Status):
            raise ValueError(f"status = {self.status!r}: expected a Status")
        if self.status is Status.COMPLETED and self.status_time is not None:
            raise ValueError(f"status_time = {self.status_time!r} s: must be None for a "
                             "completed run")
        if self.status is not Status.COMPLETED and self.status_time is None:
            raise ValueError(f"status {self.status} needs the status_time at which it happened")
        if self.status_time is not None:
            object.__setattr__(self, "status_time", finite("status_time", self.status_time, "s"))
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "signals", MappingProxyType(sig))
        object.__setattr__(self, "units", MappingProxyType(dict(self.units)))
        object.__setattr__(self, "meta", MappingProxyType(dict(self.meta)))

    # ----- access -----
    def __getitem__(self, name: str) -> np.ndarray:
        if name == "time":
            return self.time
        try:
            return self.signals[name]
        except KeyError:
            raise KeyError(
                f"no signal {name!r}; available: {', '.join(sorted(self.signals))}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name == "time" or name in self.signals

    def __iter__(self) -> Iterator[str]:
        return iter(self.signals)

    def __len__(self) -> int:
        return int(self.time.size)

    @property
    def names(self) -> list[str]:
        """Signal names, in logging order."""
        return list(self.signals)

    @property
    def completed(self) -> bool:
        """True when the run reached its end."""
        return self.status is Status.COMPLETED

    @property
    def duration(self) -> float:
        """Logged duration [s]."""
        return float(self.time[-1] - self.time[0]) if self.time.size else 0.0

    def after(self, t_start: float) -> Trajectory:
        """The part of the trajectory with time >= t_start [s] (status and meta kept)."""
        t0 = finite("t_start", t_start, "s")
        keep = self.time >= t0
        return Trajectory(
            time=self.time[keep],
            signals={k: v[keep] for k, v in self.signals.items()},
            units=self.units,
            status=self.status,
            status_time=self.status_time,
            meta=self.meta,
        )

    # ----- export -----
    def to_columns(self) -> dict[str, np.ndarray]:
        """``{"time": ..., name: ...}``, in logging order."""
        return {"time": self.time, **self.signals}

    def _description(self) -> dict[str, Any]:
        """Units (``time`` included), status, status time and meta, each as its natural JSON
        type: the CSV sidecar as it is; :meth:`_description_texts` for the Parquet metadata."""
        return {
            "units": {"time": "s", **dict(self.units)},
            "status": self.status.value,
            "status_time": None if self.status_time is None else float(self.status_time),
            "meta": dict(self.meta),
        }

    def _description_texts(self) -> dict[str, str]:
        """:meth:`_description` with every value as a text, as Parquet schema metadata needs:
        the status as it is, the others as JSON texts (meta values that are not JSON-native
        written as ``str(value)``)."""
        import json

        return {k: v if isinstance(v, str) else json.dumps(v, default=str)
                for k, v in self._description().items()}

    @classmethod
    def _from_description(cls, path, desc: Mapping[str, Any], cols: dict[str, np.ndarray],
                          where: str) -> Trajectory:
        """The inverse of :meth:`_description` with the file's columns.

        ``desc`` holds the units, status time and meta either as their JSON values (the CSV
        sidecar) or as JSON texts of them (the Parquet metadata, and CSV sidecars written before
        the sidecar held plain JSON): a text is decoded once.
        """
        import json

        missing = [k for k in ("units", "status", "status_time", "meta") if k not in desc]
        if missing:
            raise ValueError(f"{path}: not a flatfree trajectory (no {', '.join(missing)} in "
                             f"{where})")
        got = {}
        for key, kinds, expected in (("units", dict, "an object"), ("meta", dict, "an object"),
                                     ("status_time", (int, float, type(None)),
                                      "a number or null")):
            value = desc[key]
            if isinstance(value, str):
                try:
                    value = json.loads(value)
                except ValueError:
                    raise ValueError(f"{path}: {key} = {desc[key]!r:.80} in {where}: not "
                                     "JSON") from None
            if not isinstance(value, kinds) or isinstance(value, bool):
                raise ValueError(f"{path}: {key} = {desc[key]!r:.80} in {where}: expected "
                                 f"{expected}")
            got[key] = value
        units = got["units"]
        units.pop("time", None)
        time = cols.pop("time")
        return cls(time=time, signals=cols, units=units, status=Status(desc["status"]),
                   status_time=got["status_time"], meta=got["meta"])

    def to_csv(self, path: str | Path) -> Path:
        """Write a plain CSV file and a JSON sidecar beside it; return the CSV's path.

        The CSV has one header line, ``time [s],name [unit],...``, then one row per sample
        (every value as Python's shortest round-trip text, so :meth:`from_csv` reads the numbers
        back exactly): any CSV reader takes it as it is (numpy's ``genfromtxt(names=True)``,
        the ``csv`` module, pandas). The status, its time, the units and the meta, which a CSV
        has no place for, go to ``<path>.json`` (e.g. ``run.csv.json``), one JSON object read
        with one ``json.loads``: ``units`` an object (name -> unit, ``time`` included),
        ``status`` a text, ``status_time`` a number or null, ``meta`` an object (values that
        are not JSON-native, e.g. a numpy integer, written as ``str(value)``, so read back as
        text). :meth:`from_csv` reads both.
        """
        import json

        path = Path(path)
        cols = self.to_columns()
        header = ["time [s]"] + [f"{k} [{self.units[k]}]" for k in self.signals]
        data = np.column_stack(list(cols.values()))
        with path.open("w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for row in data:
                w.writerow([repr(float(x)) for x in row])
        side = _sidecar(path)
        side.write_text(json.dumps(self._description(), indent=1, default=str) + "\n",
                        encoding="utf-8")
        return path

    @classmethod
    def from_csv(cls, path: str | Path) -> Trajectory:
        """Read a file written by :meth:`to_csv` (the CSV and its ``.json`` sidecar).

        Sidecars of earlier versions, which held the units, status time and meta as JSON texts
        inside the JSON, are read too.
        """
        import json

        path = Path(path)
        if not path.exists():  # as from_parquet: the file itself is missing, not its sidecar
            raise FileNotFoundError(f"{path}: no such file")
        side = _sidecar(path)
        if not side.is_file():
            raise ValueError(f"{path}: not a flatfree trajectory (no sidecar {side.name} with "
                             "its status and units beside it)")
        desc = json.loads(side.read_text(encoding="utf-8"))
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
        if not rows:
            raise ValueError(f"{path}: empty file (expected a header line)")
        names = []
        for k, head in enumerate(rows[0]):
            name, sep, _ = head.partition(" [")
            if not sep or not head.endswith("]"):
                raise ValueError(f"{path}: header column {k} = {head!r}: expected 'name [unit]'")
            names.append(name)
        try:
            data = np.array(rows[1:], dtype=np.float64).reshape(len(rows) - 1, len(names))
        except ValueError:
            raise ValueError(f"{path}: rows are not {len(names)} numbers each") from None
        cols = {name: data[:, j].copy() for j, name in enumerate(names)}
        if "time" not in cols:
            raise ValueError(f"{path}: no 'time [s]' column")
        return cls._from_description(path, desc, cols, side.name)

    def to_parquet(self, path: str | Path) -> Path:
        """Write a Parquet file (pyarrow); units, status and meta go into the schema metadata."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        table = pa.table({k: pa.array(v) for k, v in self.to_columns().items()})
        meta = {f"flatfree.{k}".encode(): v.encode() for k, v in self._description_texts().items()}
        table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
        pq.write_table(table, path)
        return path

    @classmethod
    def from_parquet(cls, path: str | Path) -> Trajectory:
        """Read a file written by :meth:`to_parquet`."""
        import pyarrow.parquet as pq

        table = pq.read_table(path)
        md = table.schema.metadata or {}
        desc = {k.decode()[len("flatfree."):]: v.decode() for k, v in md.items()
                if k.startswith(b"flatfree.")}
        cols = {name: table.column(name).to_numpy() for name in table.column_names}
        return cls._from_description(path, desc, cols, "its schema metadata")

    def __repr__(self) -> str:
        st = "" if self.status_time is None else f" at t={self.status_time:.3f} s"
        dur = self.duration if math.isfinite(self.duration) else float("nan")
        return (f"Trajectory({len(self)} samples, {dur:.3f} s, status={self.status.value}{st}, "
                f"signals=[{', '.join(self.names)}])")
