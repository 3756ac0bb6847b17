"""The summary `imufmu import` prints: rows, duration and rate; per column the source column, the
imu-csv/1 column, the unit conversion and the range after conversion; each triad's norm; what the
file lacks and which columns were not imported; the command to run next."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from training.data.dataset import TRIADS, ImuData, triad_columns
from training.data.import_plan import Plan
from training.data.io import sidecar_path
from training.data.source_table import SourceTable
from training.data.units import QUANTITY_NAME, TARGET_UNIT


def _values(data: ImuData, target: str) -> np.ndarray:
    """(N,) values of one imu-csv/1 column of `data` ('gyr_y', 't', 'temp', 'aux_motor')."""
    if target in ("t", "temp"):
        return getattr(data, target)
    if target[:3] in TRIADS and target[3:] in ("_x", "_y", "_z"):
        return getattr(data, target[:3])[:, "xyz".index(target[-1])]
    return data.aux[target]


def _range(values: np.ndarray) -> str:
    """'min .. max' of the finite values (4 significant digits), 'all empty' when there are none."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return "all empty"
    return f"{finite.min():.4g} .. {finite.max():.4g}"


def column_table(plan: Plan, data: ImuData) -> list[str]:
    """One line per imported column: source -> target, conversion, range after conversion with its unit."""
    rows = [("source column", "column", "unit conversion", "range after conversion")]
    for target in ["t", *(c for p in TRIADS for c in triad_columns(p)), "temp",
                   *sorted(c for c in plan.mapping if c.startswith("aux_"))]:
        if target not in plan.mapping:
            continue
        conversion = plan.conversions.get(target)
        unit = TARGET_UNIT[conversion.quantity] if conversion else ""
        rows.append((plan.mapping[target], target, conversion.describe() if conversion else "copied as it is",
                     f"{_range(_values(data, target))} {unit}".rstrip()))
    widths = [max(len(r[k]) for r in rows) for k in range(3)]
    return ["  " + "  ".join(f"{cell:<{w}}" for cell, w in zip(r[:3], widths)) + "  " + r[3] for r in rows]


def triad_norms(data: ImuData) -> str:
    """'gyr |x| median 0.03 rad/s, max 5.1; acc …' for the triads the data hold."""
    parts = []
    for triad in TRIADS:
        norms = np.linalg.norm(getattr(data, triad), axis=1)
        norms = norms[np.isfinite(norms)]
        if norms.size:
            parts.append(f"{triad} |x| median {np.median(norms):.4g}, max {norms.max():.4g} {TARGET_UNIT[triad]}")
    return "norms: " + "; ".join(parts)


def summary_text(source: Path, out: Path, table: SourceTable, plan: Plan, data: ImuData, rate_hz: float | None,
                 notes: list[str]) -> str:
    """The whole summary (lines joined by newlines)."""
    fmt = f"{plan.fmt.name}, " if plan.fmt else ""
    duration = float(data.t[-1] - data.t[0]) if len(data) else 0.0
    rate = f"{rate_hz:g} Hz" if rate_hz else "rate unknown"
    lines = [f"imported {source} ({fmt}{table.layout})",
             f"  {len(data)} rows, {duration:.6g} s, {rate}", *column_table(plan, data), f"  {triad_norms(data)}"]
    absent = [f"{name} ({QUANTITY_NAME[name]})" for name in (*TRIADS, "temp")
              if f"{name}_x" not in plan.mapping and name not in plan.mapping]
    if absent:
        lines.append(f"  not in the file, written as empty cells: {', '.join(absent)}")
    lines += [f"  note: {note}" for note in notes]
    lines.append(f"  not imported: {', '.join(repr(d) for d in plan.dropped)}" if plan.dropped
                 else "  not imported: none (every column was used)")
    lines.append(f"wrote {out} and {sidecar_path(out)}")
    lines.append(f"next: imufmu train {out} --out model")
    return "\n".join(lines)
