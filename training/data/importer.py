"""`imufmu import`: a user's recording (delimited text or MATLAB .mat) -> imu-csv/1 (CSV + sidecar).

The steps: read the header (training.data.source_table); map its columns to imu-csv/1's — from
--columns, else by name (training.data.column_names), else by a known format's header
(training.data.known_formats); take each quantity's unit from --units, else from the header, else
from the known format, else refuse naming the quantity and how to give it (training.data.units);
convert; make t start at 0 (a clock is shifted, a sample counter divided by the rate, no time
column: t = n / --rate); write with write_imu_csv and read the result back with read_imu_csv, so
that every check `train` makes applies — a problem the reader finds is reported against the input
file, its line and its column. The output appears only when the read-back succeeds.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contract.errors import DataError, ImuFusionError
from training.data import units as u
from training.data.column_names import AUX_PREFIX, TARGETS, quantity_of
from training.data.dataset import TRIADS, ImuData, triad_columns
from training.data.import_plan import Plan, make_plan
from training.data.import_summary import summary_text
from training.data.io import (FORMAT, read_imu_csv, recording_stem, report_load_notes, sidecar_path,
                              time_gap_note, time_gaps, write_imu_csv)
from training.data.sidecar import RATE_MAX_HZ, RATE_MIN_HZ, REFERENCES, check_sidecar
from training.data.source_table import Columns, SourceTable, open_table, read_columns

#: Significant digits of a rate taken from the median step (102.4 Hz stays 102.4; 99.21245… -> 99.2125).
RATE_DIGITS = 6
#: A rate below this [Hz] is said in the summary (t in ms read as s gives 0.1 Hz for a 100 Hz IMU); a
#: thermal soak log may be that slow, so it is not refused.
SLOW_RATE_HZ = 1.0


@dataclass(frozen=True)
class ImportOptions:
    """What the command line says: --columns and --units entries (repeatable texts), --rate [Hz],
    and the sidecar's --sensor, --reference, --earth-field NORM,DIP,DECL, --site LAT,LON,ALT_KM[,DATE]."""

    columns: tuple[str, ...] = ()
    units: tuple[str, ...] = ()
    rate_hz: float | None = None
    sensor: str | None = None
    reference: str = "none"
    earth_field: str | None = None
    site: str | None = None
    progress: bool | None = None


@dataclass(frozen=True)
class ImportResult:
    """The written recording, its sidecar, its row count and the printed summary."""

    path: Path
    sidecar: Path
    rows: int
    summary: str


def import_recording(source: str | Path, out: str | Path, options: ImportOptions = ImportOptions(),
                     shown: str | Path | None = None) -> ImportResult:
    """Convert `source` into the imu-csv/1 recording `out` (NAME.csv or NAME.csv.gz) and its sidecar;
    `shown`: the path the summary names (where `imufmu import` moves `out` when complete; default `out`)."""
    source, out = Path(source), Path(out)
    _check_out(source, out)
    if options.rate_hz is not None and not RATE_MIN_HZ <= options.rate_hz <= RATE_MAX_HZ:
        raise ImuFusionError(f"--rate {options.rate_hz:g}: expected a sample rate in Hz in "
                             f"[{RATE_MIN_HZ:.3g}, {RATE_MAX_HZ:g}]")
    meta = _sidecar_options(options)
    table = open_table(source)
    plan = make_plan(table, list(options.columns), list(options.units))
    columns = read_columns(table, list(dict.fromkeys(plan.mapping.values())), options.progress)
    t, rate_hz = _time(table, plan, columns, options.rate_hz)
    data = _imu_data(plan, columns, t, out)
    if meta["sensor"] is None and plan.fmt:
        meta["sensor"] = plan.fmt.sensor
    data.meta = {"format": FORMAT, "rate_hz": rate_hz, **meta,
                 "source": source.name + (f" ({plan.fmt.name} format)" if plan.fmt else ""),
                 "notes": _notes(source, plan)}
    written = _write_checked(data, out, table, plan, columns)
    shown = Path(shown) if shown is not None else out
    gaps = time_gap_note(shown, time_gaps(written.t, rate_hz))
    summary = summary_text(source, shown, table, plan, written, rate_hz, [*plan.notes, *filter(None, [gaps])])
    return ImportResult(out, sidecar_path(out), len(written), summary)


def _check_out(source: Path, out: Path) -> None:
    """ImuFusionError unless `out` is a '.csv' or '.csv.gz' path other than the input."""
    if not (out.name.endswith(".csv") or out.name.endswith(".csv.gz")) or not recording_stem(out):
        raise ImuFusionError(f"--out {out}: the output must be NAME.csv or NAME.csv.gz (imu-csv/1)")
    if out.resolve() == source.resolve():
        raise ImuFusionError(f"--out {out}: is the input file; choose another name")


def _sidecar_options(options: ImportOptions) -> dict:
    """The sidecar fields the options give, checked (training.data.sidecar.check_sidecar)."""
    if options.reference not in REFERENCES:
        raise ImuFusionError(f"--reference {options.reference}: expected one of {', '.join(REFERENCES)}")
    meta = {"sensor": options.sensor, "reference": options.reference,
            "earth_field": _earth_field(options.earth_field) if options.earth_field else None}
    if options.site:
        meta["site"] = _site(options.site)
    try:
        check_sidecar(Path("sidecar"), {"format": FORMAT, **meta})
    except DataError as e:
        raise ImuFusionError(f"--earth-field {options.earth_field}: {e.problem}") from None
    return meta


def _number_or_none(text: str, option: str) -> float | None:
    """A number of an option's list; '', 'null' and '?' are None (unknown)."""
    if text.strip().lower() in ("", "null", "?", "none"):
        return None
    try:
        return float(text)
    except ValueError:
        raise ImuFusionError(f"{option}: '{text}' is not a number") from None


def _earth_field(text: str) -> dict:
    """--earth-field NORM_UT,DIP_DEG,DECLINATION_DEG (an empty entry: unknown) -> the sidecar entry."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ImuFusionError(f"--earth-field {text}: expected NORM_UT,DIP_DEG,DECLINATION_DEG, e.g. 48.6,64.1,2.9 "
                             "(leave an entry empty when unknown: 48.6,64.1,)")
    keys = ("norm_ut", "dip_deg", "declination_deg")
    return {k: _number_or_none(p, f"--earth-field {text}") for k, p in zip(keys, parts)}


def _site(text: str) -> dict:
    """--site LAT_DEG,LON_DEG,ALT_KM[,DATE] -> the sidecar's site (train takes the IGRF field there)."""
    from datetime import date
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (3, 4):
        raise ImuFusionError(f"--site {text}: expected LAT_DEG,LON_DEG,ALT_KM[,YYYY-MM-DD], e.g. 48.15,11.57,0.52,2024-05-01")
    lat, lon, alt = (_number_or_none(p, f"--site {text}") for p in parts[:3])
    bounds = ((lat, -90.0, 90.0, "latitude"), (lon, -180.0, 360.0, "longitude"), (alt, -1.0, 1000.0, "altitude [km]"))
    for value, low, high, what in bounds:
        if value is None or not low <= value <= high:
            raise ImuFusionError(f"--site {text}: {what} must be a number in [{low:g}, {high:g}]")
    site = {"latitude_deg": lat, "longitude_deg": lon, "altitude_km": alt}
    if len(parts) == 4:
        try:
            site["date"] = date.fromisoformat(parts[3]).isoformat()
        except ValueError:
            raise ImuFusionError(f"--site {text}: date '{parts[3]}' is not YYYY-MM-DD") from None
    return site


# -------------------------------------------------------------------------- time and data


def _time(table: SourceTable, plan: Plan, columns: Columns, rate_option: float | None) -> tuple[np.ndarray, float]:
    """(t [s] from 0, rate_hz for the sidecar) from the time column, a sample counter or --rate."""
    source = plan.mapping.get("t")
    n = len(columns.lines)
    if source is None:
        if rate_option is None:
            raise DataError(table.path, "no time column found (looked for t, time, timestamp, n_samples, ...): "
                                        "give --rate HZ for evenly spaced samples, or name it with "
                                        "--columns t=NAME --units t=s|ms|us|ns|samples")
        plan.notes.append(f"no time column: t = n / {rate_option:g} Hz")
        return np.arange(n) / rate_option, rate_option
    raw = columns.values[source]
    _check_increasing(table, source, raw, columns.lines)
    conversion = plan.conversions["t"]
    if conversion.unit == u.SAMPLES:
        rate = rate_option or (plan.fmt.rate_hz if plan.fmt else None)
        if rate is None:
            raise DataError(table.path, f"column '{source}' counts samples: give the rate with --rate HZ",
                            column=source)
        plan.conversions["t"] = u.Conversion("t", f"samples at {rate:g} Hz", 1.0 / rate)
        plan.notes.append(f"t = ({source} − {raw[0]:g}) / {rate:g} Hz" + ("" if rate_option else
                                                                            f" ({plan.fmt.name}; --rate overrides)"))
        return (raw - raw[0]) / rate, rate
    if raw[0] != 0.0:
        plan.notes.append(f"t starts at 0: '{source}' began at {raw[0]:.15g} {conversion.unit}, shifted")
    t = conversion.apply(raw - raw[0])
    if rate_option is not None or n < 2:
        return t, rate_option
    rate = float(f"{1.0 / float(np.median(np.diff(t))):.{RATE_DIGITS}g}")
    plan.notes.append(f"rate_hz {rate:g} from the median step of t (--rate sets it)")
    if rate < SLOW_RATE_HZ:
        plan.notes.append(f"WARNING: {rate:g} Hz is slow for an IMU; if '{source}' is not in {conversion.unit}, "
                          "give its unit with --units t=ms|us|ns")
    return t, rate


def _check_increasing(table: SourceTable, source: str, raw: np.ndarray, lines: np.ndarray) -> None:
    """DataError at the first time that is not a finite number or not after the one before it."""
    bad = np.flatnonzero(~np.isfinite(raw))
    if bad.size:
        raise _row_error(table, "time is not a finite number (an empty cell?)", lines[bad[0]], source)
    steps = np.flatnonzero(np.diff(raw) <= 0)
    if steps.size:
        k = int(steps[0]) + 1
        raise _row_error(table, f"time is not strictly increasing ({raw[k]:.15g} after {raw[k - 1]:.15g}); "
                                "sort the rows by time or drop the repeated rows", lines[k], source)


def _row_error(table: SourceTable, problem: str, line: int, column: str | None) -> DataError:
    """A DataError at an input row: the editor line of a text file, the sample number of a MATLAB file."""
    if table.kind == "mat":
        return DataError(table.path, f"sample {int(line)}: {problem}", column=column)
    return DataError(table.path, problem, row=int(line), column=column)


def _imu_data(plan: Plan, columns: Columns, t: np.ndarray, out: Path) -> ImuData:
    """The converted arrays as ImuData (a triad or temperature the file lacks is NaN)."""
    n = len(t)

    def converted(target: str) -> np.ndarray:
        if target not in plan.mapping:
            return np.full(n, np.nan)
        values = columns.values[plan.mapping[target]]
        return plan.conversions[target].apply(values) if target in plan.conversions else values.copy()

    triads = {p: np.column_stack([converted(c) for c in triad_columns(p)]) for p in TRIADS}
    aux = {c: converted(c) for c in plan.mapping if c.startswith(AUX_PREFIX)}
    return ImuData(t=t, temp=converted("temp"), aux=aux, name=recording_stem(out), **triads)


def _notes(source: Path, plan: Plan) -> str:
    """The sidecar's notes: what was converted (per quantity), what is absent, what was dropped."""
    groups: dict[tuple[str, str], list[str]] = {}
    for target, conversion in plan.conversions.items():
        groups.setdefault((conversion.quantity, conversion.describe()), []).append(f"'{plan.mapping[target]}'")
    done = [f"{quantity} {', '.join(names)}: {what}" for (quantity, what), names in groups.items()]
    absent = [name for name in (*TRIADS, "temp") if f"{name}_x" not in plan.mapping and name not in plan.mapping]
    text = f"Imported by imufmu import from {source.name}" + (f" ({plan.fmt.name} format)" if plan.fmt else "")
    text += ". Converted: " + "; ".join(done) + "."
    text += f" Notes: {'; '.join(plan.notes)}." if plan.notes else ""
    if absent:
        text += f" Not in the file (empty cells): {', '.join(absent)}."
    if plan.dropped:
        text += f" Columns not imported: {', '.join(plan.dropped)}."
    return text


def _write_checked(data: ImuData, out: Path, table: SourceTable, plan: Plan, columns: Columns) -> ImuData:
    """Write `data` beside `out` under a temporary name, read it back with read_imu_csv (every check
    of the loader), then move it to `out`; a loader problem becomes a DataError on the input file."""
    suffix = ".csv.gz" if out.name.endswith(".gz") else ".csv"
    temporary = out.with_name(f".{recording_stem(out)}.importing{suffix}")
    try:
        write_imu_csv(data, temporary)
        with report_load_notes(lambda note: None):  # the summary reports gaps against `out`
            written = read_imu_csv(temporary)
        os.replace(sidecar_path(temporary), sidecar_path(out))
        os.replace(temporary, out)
    except DataError as e:
        raise _input_error(e, table, plan, columns) from None
    finally:
        for path in (temporary, sidecar_path(temporary)):
            path.unlink(missing_ok=True)
    written.name = recording_stem(out)
    return written


def _input_error(error: DataError, table: SourceTable, plan: Plan, columns: Columns) -> DataError:
    """The loader's DataError on the written file, restated for the input: its line, its columns and
    the conversion that was applied."""
    target = (error.column or "").removesuffix("_*")
    targets = triad_columns(target) if target in TRIADS else [target] if target in TARGETS else []
    sources = [plan.mapping[c] for c in targets if c in plan.mapping]
    problem = error.problem
    conversion = next((plan.conversions[c] for c in targets if c in plan.conversions), None)
    if conversion is not None:
        quantity = quantity_of(targets[0])
        problem += (f" (after converting {conversion.describe()}; if the file holds another unit, give it with "
                    f"--units {quantity}=UNIT)")
    line = columns.lines[error.row - 2] if error.row is not None and 2 <= error.row < len(columns.lines) + 2 else None
    column = ", ".join(sources) or None
    if line is None:
        return DataError(table.path, problem, column=column)
    return _row_error(table, problem, line, column)
