"""The comparison with the paper and a self-contained HTML report.

:class:`RunResult` holds one run (its scenario, trajectory and metrics, or the reason it could
not run). :func:`comparison_rows` puts the runs beside the paper's figures (NOTES.md "Results to
compare with"), :func:`format_table` prints them for a terminal, and :func:`write_report` writes
one HTML file that needs nothing else to open: the figures are embedded as base64 PNG, there is
no script, no external style sheet, no font or image fetched (a Content-Security-Policy forbids
any network access), and every string that comes from a user's file (scenario names,
descriptions, paths, settings, TOML text) is escaped with :func:`html.escape`.

References
----------
[paper] the paper (docs/README.md), Section 4.
[NOTES] docs/NOTES.md, "Results to compare with".
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import math
import os
import platform
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from flatfree.metrics import Metrics
from flatfree.scenario import Scenario
from flatfree.trajectory import Trajectory

__all__ = [
    "PAPER_RESULTS",
    "PaperClaim",
    "RunResult",
    "comparison_rows",
    "format_table",
    "machine_info",
    "write_report",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class PaperClaim:
    """What the paper reports for one controller (NOTES.md "Results to compare with").

    A bound is ``(relation, value)`` with relation ``"<"``, ``"<="`` or ``">"`` applied to the
    run's *maximum* error (the paper states maxima read off its Figure 5).
    """

    title: str
    lateral_m: tuple[str, float]
    yaw_deg: tuple[str, float]

    @staticmethod
    def _holds(rel: str, value: float, bound: float) -> bool | None:
        if value is None or not math.isfinite(value):
            return None
        return {"<": value < bound, "<=": value <= bound, ">": value > bound}[rel]

    def lateral_text(self) -> str:
        return f"{self.lateral_m[0]} {self.lateral_m[1] * 100:g} cm"

    def yaw_text(self) -> str:
        return f"{self.yaw_deg[0]} {self.yaw_deg[1]:g} deg"

    def agrees(self, m: Metrics | None) -> tuple[bool | None, bool | None]:
        """(lateral agrees, yaw agrees), None when the metric is not available."""
        if m is None:
            return None, None
        return (self._holds(self.lateral_m[0], m.lateral_error_max_m, self.lateral_m[1]),
                self._holds(self.yaw_deg[0], m.yaw_error_max_deg, self.yaw_deg[1]))


#: The paper's Section 4 figures per controller (CLI names). NOTES.md "Results to compare with".
PAPER_RESULTS: dict[str, PaperClaim] = {
    "mfc-natural": PaperClaim(title="model-free control, natural outputs",
                              lateral_m=("<", 0.02), yaw_deg=("<=", 0.51)),
    "mfc-flat": PaperClaim(title="model-free control, flat outputs",
                           lateral_m=(">", 0.10), yaw_deg=(">", 1.0)),
    "flatness": PaperClaim(title="flatness-based control",
                           lateral_m=(">", 0.10), yaw_deg=(">", 10.0)),
}


@dataclass(frozen=True, slots=True, kw_only=True)
class RunResult:
    """One run of a comparison: what ran, what came out, or why it could not run.

    Parameters
    ----------
    label : str
        Row label (usually the controller's CLI name).
    scenario : Scenario
    trajectory, metrics : optional
        None when the run could not be made (``error`` says why).
    error : str, optional
        Why the run is missing (e.g. a controller not wired into the closed loop yet).
    extra : mapping
        More numbers for the table (e.g. ``steer_rms_vs_recorded_deg``).
    """

    label: str
    scenario: Scenario
    trajectory: Trajectory | None = None
    metrics: Metrics | None = None
    error: str | None = None
    extra: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if (self.metrics is None) == (self.error is None):
            raise ValueError(f"run {self.label!r}: give metrics, or an error saying why none")

    @property
    def ok(self) -> bool:
        """True when the run exists and completed."""
        return self.metrics is not None and self.metrics.status == "completed"


def _fmt(v: float | None, scale: float = 1.0, digits: int = 2) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    return f"{v * scale:.{digits}f}"


def _verdict(a: bool | None, rel: str) -> str:
    """``yes`` when the run's error meets the paper's relation; else which side it is on (the
    paper reports some designs' errors as large, ``> bound``: smaller is then no defect)."""
    if a is None:
        return "-"
    if a:
        return "yes"
    return "no (smaller)" if rel == ">" else "no (larger)"


#: Columns of the comparison table: (key, header).
TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("controller", "controller"),
    ("status", "status"),
    ("lat_max_cm", "lat max cm"),
    ("lat_rms_cm", "lat rms cm"),
    ("yaw_max_deg", "yaw max deg"),
    ("yaw_rms_deg", "yaw rms deg"),
    ("course_max_deg", "course max deg"),
    ("speed_rms", "v rms m/s"),
    ("steer_rate_rms", "steer rate rms rad/s"),
    ("torque_rate_rms", "torque rate rms kN m/s"),
    ("rtf", "x realtime"),
    ("paper_lat", "paper lat"),
    ("paper_yaw", "paper yaw"),
    ("agrees", "as paper lat, yaw"),
)


#: Columns shown as text (left-aligned); the others are numbers.
_TEXT_COLUMNS = ("controller", "status", "paper_lat", "paper_yaw", "agrees")


def comparison_rows(results: Sequence[RunResult]) -> list[dict[str, str]]:
    """One row of display strings per run, beside the paper's figures (:data:`PAPER_RESULTS`)."""
    rows = []
    for r in results:
        claim = PAPER_RESULTS.get(r.scenario.controller)
        m = r.metrics
        lat_ok, yaw_ok = claim.agrees(m) if claim else (None, None)
        status = m.status if m is not None else f"not run: {r.error}"
        rows.append({
            "controller": r.label,
            "status": status,
            "lat_max_cm": _fmt(m.lateral_error_max_m if m else None, 100.0),
            "lat_rms_cm": _fmt(m.lateral_error_rms_m if m else None, 100.0),
            "yaw_max_deg": _fmt(m.yaw_error_max_deg if m else None),
            "yaw_rms_deg": _fmt(m.yaw_error_rms_deg if m else None),
            # heading of the CoG velocity against the path: the controller's part of the yaw
            # error (metrics.py); the rest is the car's sideslip against the reference model's
            "course_max_deg": _fmt(m.course_error_max_deg if m else None),
            "speed_rms": _fmt(m.speed_error_rms_mps if m else None),
            # the effort (issue 7's "steering rate and torque effort"): a noisy or limit-cycling
            # loop shows here before it shows in the errors
            "steer_rate_rms": _fmt(m.steer_rate_rms_radps if m else None, digits=3),
            "torque_rate_rms": _fmt(m.torque_rate_rms_nmps if m else None, 1e-3, digits=1),
            "rtf": _fmt(m.real_time_factor if m else None, digits=0),
            "paper_lat": claim.lateral_text() if claim else "-",
            "paper_yaw": claim.yaw_text() if claim else "-",
            "agrees": (f"{_verdict(lat_ok, claim.lateral_m[0])}, "
                       f"{_verdict(yaw_ok, claim.yaw_deg[0])}"
                       if m is not None and m.status == "completed" and claim is not None
                       else "-"),
        })
    return rows


def format_table(results: Sequence[RunResult]) -> str:
    """The comparison as a fixed-width text table (for a terminal)."""
    rows = comparison_rows(results)
    heads = [h for _, h in TABLE_COLUMNS]
    keys = [k for k, _ in TABLE_COLUMNS]
    # a long "not run: ..." status goes below the table, not into the column
    notes = []
    for row in rows:
        if row["status"].startswith("not run: "):
            notes.append(f"{row['controller']}: {row['status']}")
            row["status"] = "not run"
    widths = [max(len(h), *(len(row[k]) for row in rows)) if rows else len(h)
              for k, h in zip(keys, heads, strict=True)]
    line = "  ".join(h.ljust(w) for h, w in zip(heads, widths, strict=True))
    out = [line, "  ".join("-" * w for w in widths)]
    for row in rows:
        out.append("  ".join(row[k].ljust(w) if k in _TEXT_COLUMNS else row[k].rjust(w)
                             for k, w in zip(keys, widths, strict=True)).rstrip())
    out.extend(notes)
    out.append("paper: max errors of its Section 4 (docs/NOTES.md, 'Results to compare with'); "
               "as paper: our max error meets the paper's bound, else it is smaller or larger "
               "(completed runs only); course: "
               "CoG velocity direction vs path heading (the controller's part of the yaw error)")
    return "\n".join(out)


def machine_info() -> dict[str, str]:
    """Versions of flatfree and its main dependencies, and the machine (for a report)."""
    info: dict[str, str] = {}
    for pkg in ("flatfree", "numpy", "scipy", "numba", "matplotlib", "pyarrow"):
        try:
            info[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            info[pkg] = "not installed"
    info["python"] = platform.python_version()
    info["platform"] = platform.platform()
    info["machine"] = platform.machine()
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info["cpu"] = cpu or "unknown"
    info["cores"] = str(os.cpu_count() or "unknown")
    info["date (UTC)"] = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S")
    return info


# ------------------------------------------------------------------------------------------
# HTML
# ------------------------------------------------------------------------------------------
_CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 2em auto; color: #222; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.3em 0.6em; text-align: left; vertical-align: top; }
th { background: #eee; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
pre { background: #f6f6f6; padding: 0.6em; overflow-x: auto; font-size: 0.8em; }
.note { color: #8a4b00; }
"""

_NUM = ' class="num"'
_CSP = ("default-src 'none'; img-src data:; style-src 'unsafe-inline'; "
        "base-uri 'none'; form-action 'none'")


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _img_tag(png: Path | bytes, alt: str) -> str:
    data = png if isinstance(png, bytes) else Path(png).read_bytes()
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ValueError(f"figure {alt!r}: not a PNG image")
    b64 = base64.b64encode(data).decode("ascii")
    return f'<img src="data:image/png;base64,{b64}" alt="{_e(alt)}">'


def _settings_table(sc: Scenario) -> str:
    ref = sc.reference
    duration = ("the reference's" if sc.timing.duration_s is None
                else f"{sc.timing.duration_s:g} s")
    items = [
        ("name", sc.name), ("description", sc.description), ("vehicle", sc.vehicle),
        ("plant", sc.plant), ("controller", sc.controller),
        ("reference", f"track {ref.track} ({ref.line})" if ref.track is not None
         else f"recording {ref.recording}"),
        ("speed profile", (f"a_lat <= {ref.a_lat_max:g} m/s^2, a_drive <= {ref.a_drive_max:g} "
                           f"m/s^2, a_brake <= {ref.a_brake_max:g} m/s^2, v <= {ref.v_max:g} m/s"
                           + (f", lateral jerk <= {ref.j_lat_max:g} m/s^3"
                              if math.isfinite(ref.j_lat_max) else "")
                           + (", drive limit" if ref.drive_limit else ""))),
        ("timing", (f"plant {sc.timing.plant_dt_s:g} s, control {sc.timing.control_dt_s:g} s, "
                    f"log {sc.timing.log_dt_s:g} s, duration {duration}")),
        ("noise", "on" if sc.noise else "off"), ("seed", sc.seed),
        ("road friction", sc.road.mu),
    ]
    if sc.vehicle_overrides:
        items.append(("vehicle overrides", ", ".join(f"{k} = {v}" for k, v in
                                                     sc.vehicle_overrides.items())))
    if sc.controller_settings:
        items.append(("controller settings", ", ".join(f"{k} = {v}" for k, v in
                                                       sc.controller_settings.items())))
    body = "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in items)
    return f"<table class=\"settings\">{body}</table>"


def write_report(
    path: str | Path,
    results: Sequence[RunResult],
    figures: Iterable[tuple[str, Path | bytes]] = (),
    *,
    title: str = "flatfree: the paper reproduced",
    scenarios: Mapping[str, Scenario] | None = None,
    notes: Sequence[str] = (),
    extra_tables: Mapping[str, Sequence[RunResult]] | None = None,
    info: Mapping[str, str] | None = None,
) -> Path:
    """Write one self-contained HTML report.

    Parameters
    ----------
    path : str or Path
        The HTML file to write (its folder is created).
    results : sequence of RunResult
        The comparison table, one row per run (:func:`comparison_rows`).
    figures : iterable of (caption, PNG path or bytes)
        Embedded in order as base64 ``data:`` images.
    title : str
    scenarios : mapping label -> Scenario, optional
        Settings shown (default: each result's scenario), with the TOML text of each.
    notes : sequence of str
        Free text shown under the table (escaped).
    extra_tables : mapping heading -> results, optional
        Further comparison tables (e.g. the recorded reference).
    info : mapping, optional
        Versions and machine (default :func:`machine_info`).

    Returns
    -------
    Path
    """
    path = Path(path)
    info = dict(machine_info() if info is None else info)
    if scenarios is None:
        scenarios = {r.label: r.scenario for r in results}

    def table(rs: Sequence[RunResult], cls: str) -> str:
        rows = comparison_rows(rs)
        head = "".join(f"<th>{_e(h)}</th>" for _, h in TABLE_COLUMNS)
        extra_keys = sorted({k for r in rs for k in r.extra})
        head += "".join(f"<th>{_e(k)}</th>" for k in extra_keys)
        body = []
        for r, row in zip(rs, rows, strict=True):
            cells = "".join(
                f"<td{'' if k in _TEXT_COLUMNS else _NUM}>{_e(row[k])}</td>"
                for k, _ in TABLE_COLUMNS)
            cells += "".join(f"<td class=\"num\">{_e(_fmt(r.extra.get(k)))}</td>"
                             for k in extra_keys)
            body.append(f"<tr class=\"run\" data-controller=\"{_e(r.label)}\">{cells}</tr>")
        return (f"<table class=\"{cls}\"><thead><tr>{head}</tr></thead>"
                f"<tbody>{''.join(body)}</tbody></table>")

    parts = [
        "<!DOCTYPE html>",
        "<html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<meta http-equiv=\"Content-Security-Policy\" content=\"{_CSP}\">",
        f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        "<h2>Comparison with the paper</h2>",
        table(results, "comparison"),
        ("<p>Paper: the maximum errors of its Section 4 (10DoF Peugeot 406, recorded track), "
         "as corrected in docs/NOTES.md &#8220;Results to compare with&#8221;. "
         "&#8220;as paper&#8221;: our maximum error meets the paper's bound (yes), or is "
         "smaller or larger than it (completed runs only: a run that left the track is not "
         "compared). &#8220;course&#8221;: the "
         "direction of the CoG velocity against the path heading, the part of the yaw error a "
         "steering law controls; the rest is the car's sideslip against the reference "
         "model's.</p>"),
    ]
    for n in notes:
        parts.append(f"<p class=\"note\">{_e(n)}</p>")
    for heading, rs in (extra_tables or {}).items():
        parts.append(f"<h2>{_e(heading)}</h2>")
        parts.append(table(rs, "comparison-extra"))
    parts.append("<h2>Figures</h2>")
    for caption, png in figures:  # unnumbered: the captions cite the paper's numbers
        parts.append(f"<figure>{_img_tag(png, caption)}"
                     f"<figcaption>{_e(caption)}</figcaption></figure>")
    parts.append("<h2>Scenario settings</h2>")
    for label, sc in scenarios.items():
        parts.append(f"<h3>{_e(label)}</h3>")
        parts.append(_settings_table(sc))
        parts.append(f"<details><summary>TOML</summary><pre>{_e(sc.to_toml())}</pre>"
                     "</details>")
    parts.append("<h2>Versions and machine</h2>")
    parts.append("<table class=\"machine\">" + "".join(
        f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in info.items()) + "</table>")
    parts.append("</body></html>")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
