"""Read, write and validate imu-csv/1 recordings (see ARCHITECTURE.md, 'Canonical dataset').

A recording is `NAME.csv` or `NAME.csv.gz` plus an optional sidecar `NAME.json`. Reading
turns every malformed input into a `DataError` that names the file, the row (the line number
an editor shows: the header is line 1) and the column. Writing is exact (shortest round-trip
float text) and deterministic (gzip without timestamp or file name), so the same data gives
the same bytes.
"""
from __future__ import annotations

import gzip
import io
import json
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from training.dataset import REF_Q_COLUMNS, TRIADS, ImuData, triad_columns
from training.errors import DataError

FORMAT = "imu-csv/1"
REQUIRED_COLUMNS = ("t", *triad_columns("gyr"), *triad_columns("acc"),
                    *triad_columns("mag"), "temp")
REF_TRIADS = ("ref_gyr", "ref_acc", "ref_mag")
EVAL_MASK_COLUMN = "eval_mask"
AUX_PREFIX = "aux_"
FIRST_DATA_LINE = 2          # editor line number of the first sample (header is line 1)
GZIP_LEVEL = 6               # deterministic for a given zlib; level 9 is slower for little gain

# Unit plausibility, judged on robust statistics of the finite samples of a triad.
MIN_SAMPLES_FOR_UNIT_CHECK = 10
MAG_MEDIAN_NORM_MAX_UT = 1000.0   # Earth field is 25-65 µT; nT values are ~1000x larger
MAG_MEDIAN_NORM_MIN_UT = 5.0      # gauss values are 100x smaller (0.25-0.65 G)
GYR_P99_NORM_MAX_RAD_S = 35.0     # ≈ 2000 °/s, the largest common MEMS range
ACC_G_UNITS_RANGE = (0.5, 2.0)    # a median norm ≈ 1 means the file holds g, not m/s²
ACC_MEDIAN_NORM_MAX = 200.0       # ≈ 20 g sustained: mg or raw counts, not m/s²

# Time plausibility: t must be in seconds; gaps are reported, not refused.
RATE_TOLERANCE = 1.5         # median step of t vs the sidecar's 1/rate_hz: a larger factor either way is refused
MIN_MEDIAN_STEP_S = 1e-5     # without rate_hz: a smaller median step (faster than a 100 kHz IMU) is refused
#: A step longer than GAP_STEP_FACTOR × the nominal step (1/rate_hz, else the median step) is a
#: gap in time. The one definition of the threshold: the loader reports such gaps, and the runtime's
#: gap handling (re-initialising the attitude across a gap) is to use the same factor.
GAP_STEP_FACTOR = 5.0
TIME_UNITS = (("milliseconds", 1e3), ("microseconds", 1e6), ("nanoseconds", 1e9))  # t given in these


def recording_stem(path: str | Path) -> str:
    """File name without '.csv' or '.csv.gz', e.g. 'trial.csv.gz' -> 'trial'."""
    name = Path(path).name
    for suffix in (".csv.gz", ".csv"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return Path(name).stem


def sidecar_path(path: str | Path) -> Path:
    """Path of the sidecar JSON that belongs to a recording: 'NAME.csv[.gz]' -> 'NAME.json'."""
    path = Path(path)
    return path.with_name(recording_stem(path) + ".json")


# ----------------------------------------------------------------------------- reading


def read_imu_csv(path: str | Path) -> ImuData:
    """Read and validate one imu-csv/1 recording and its sidecar; raise DataError if malformed.

    Returns an ImuData named after the file stem, with optional arrays None when absent.
    Raw triads may be all-NaN (a sensor that was not recorded); use `require_sensors` where a
    computation needs one.
    """
    path = Path(path)
    meta = read_sidecar(path)
    header, body = _read_text(path)
    columns = _parse_header(path, header)
    table = _parse_body(path, body, columns)
    data = _to_imu_data(path, columns, table, meta)
    _check_time(path, data.t)
    rate_hz = _sidecar_rate(path, meta)
    _check_time_unit(path, data.t, rate_hz)
    _check_units(path, data)
    _report_load_note(time_gap_note(path, time_gaps(data.t, rate_hz)))
    return data


def read_sidecar(path: str | Path) -> dict:
    """The sidecar metadata of recording `path` ({} when there is no sidecar)."""
    side = sidecar_path(path)
    if not side.is_file():
        return {}
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(side, f"sidecar is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise DataError(side, "sidecar must be a JSON object")
    if meta.get("format") != FORMAT:
        raise DataError(side, f"sidecar 'format' is {meta.get('format')!r}, expected '{FORMAT}'")
    return meta


def _read_text(path: Path) -> tuple[str, str]:
    """Decompressed text of the file split into (header line, data lines)."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DataError(path, "file not found") from None
    try:
        if path.name.endswith(".gz"):
            raw = gzip.decompress(raw)
        text = raw.decode("utf-8-sig")
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise DataError(path, f"cannot read as UTF-8 CSV ({exc})") from None
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    header, _, body = text.partition("\n")
    if not header.strip():
        raise DataError(path, "file is empty (no header row)", row=1)
    return header, body


def _parse_header(path: Path, header: str) -> list[str]:
    """Column names of the header line, checked against the imu-csv/1 schema."""
    columns = [c.strip().strip('"') for c in header.split(",")]
    seen: set[str] = set()
    for name in columns:
        if name in seen:
            raise DataError(path, "duplicate column", row=1, column=name)
        seen.add(name)
        if not _is_known_column(name):
            raise DataError(path, "unknown column (imu-csv/1 allows the sensor columns, "
                                  "ref_*, eval_mask and aux_*)", row=1, column=name)
    for name in REQUIRED_COLUMNS:
        if name not in seen:
            raise DataError(path, "missing required column", row=1, column=name)
    for group in (REF_Q_COLUMNS, *(triad_columns(p) for p in REF_TRIADS)):
        present = [c for c in group if c in seen]
        if present and len(present) != len(group):
            missing = [c for c in group if c not in seen]
            raise DataError(path, f"columns {', '.join(group)} come all together or not at "
                                  f"all; missing {', '.join(missing)}", row=1, column=missing[0])
    return columns


def _is_known_column(name: str) -> bool:
    """True for a column name that imu-csv/1 defines."""
    known = {*REQUIRED_COLUMNS, *REF_Q_COLUMNS, EVAL_MASK_COLUMN}
    known.update(c for p in REF_TRIADS for c in triad_columns(p))
    return name in known or (name.startswith(AUX_PREFIX) and len(name) > len(AUX_PREFIX))


def _parse_body(path: Path, body: str, columns: Sequence[str]) -> np.ndarray:
    """(N, len(columns)) float64 table of the data lines; empty cells and 'nan' are NaN."""
    body = body.rstrip("\n")
    if not body:
        raise DataError(path, "no data rows after the header", row=FIRST_DATA_LINE)
    _reject_blank_lines(path, body)
    try:
        table = np.loadtxt(io.StringIO(_fill_empty_cells(body)), delimiter=",", comments=None,
                           ndmin=2, dtype=np.float64)
        if table.shape[1] == len(columns):
            return table
        problem = f"rows have {table.shape[1]} cells, expected {len(columns)}"
    except ValueError as exc:
        problem = f"cannot parse the data rows ({exc})"
    _locate_bad_cell(path, body, columns)
    raise DataError(path, problem)


def _reject_blank_lines(path: Path, body: str) -> None:
    """Raise DataError at the first blank line inside the data (it would shift row numbers)."""
    if body.startswith("\n"):
        line = FIRST_DATA_LINE
    else:
        pos = body.find("\n\n")
        if pos < 0:
            return
        line = FIRST_DATA_LINE + body.count("\n", 0, pos) + 1
    raise DataError(path, "blank line inside the data", row=line)


def _fill_empty_cells(body: str) -> str:
    """Write 'nan' into every empty cell so that numpy's fast parser accepts the text."""
    # Two passes: the first fills every other gap in a run of commas, the second the rest.
    body = body.replace(",,", ",nan,").replace(",,", ",nan,")
    body = body.replace(",\n", ",nan\n").replace("\n,", "\nnan,")
    if body.startswith(","):
        body = "nan" + body
    if body.endswith(","):
        body += "nan"
    return body


def _locate_bad_cell(path: Path, body: str, columns: Sequence[str]) -> None:
    """Scan the data lines and raise DataError at the first ragged row or non-numeric cell."""
    for index, line in enumerate(body.split("\n")):
        row = FIRST_DATA_LINE + index
        cells = line.split(",")
        if len(cells) != len(columns):
            raise DataError(path, f"row has {len(cells)} cells, expected {len(columns)}", row=row)
        for name, cell in zip(columns, cells):
            if cell.strip() and not _is_number(cell):
                raise DataError(path, f"not a number: {cell!r}", row=row, column=name)


def _is_number(cell: str) -> bool:
    """True when `cell` is a decimal number, 'nan' or 'inf' as numpy's parser reads it."""
    try:
        float(cell)
    except ValueError:
        return False
    return "_" not in cell


def _to_imu_data(path: Path, columns: Sequence[str], table: np.ndarray, meta: dict) -> ImuData:
    """Assemble the parsed table into an ImuData (optional groups None when absent)."""
    index = {name: i for i, name in enumerate(columns)}

    def take(names: Sequence[str]) -> np.ndarray:
        return np.ascontiguousarray(table[:, [index[n] for n in names]])

    def optional(names: Sequence[str]) -> np.ndarray | None:
        return take(names) if names[0] in index else None

    return ImuData(
        t=take(["t"])[:, 0], gyr=take(triad_columns("gyr")), acc=take(triad_columns("acc")),
        mag=take(triad_columns("mag")), temp=take(["temp"])[:, 0],
        ref_q=optional(REF_Q_COLUMNS), ref_gyr=optional(triad_columns("ref_gyr")),
        ref_acc=optional(triad_columns("ref_acc")), ref_mag=optional(triad_columns("ref_mag")),
        eval_mask=_eval_mask(path, table[:, index[EVAL_MASK_COLUMN]])
        if EVAL_MASK_COLUMN in index else None,
        aux={n: table[:, i].copy() for n, i in index.items() if n.startswith(AUX_PREFIX)},
        meta=meta, name=recording_stem(path))


def _eval_mask(path: Path, values: np.ndarray) -> np.ndarray:
    """(N,) bool mask from a column of 0/1 values; anything else is a DataError."""
    bad = np.flatnonzero((values != 0) & (values != 1))
    if bad.size:
        raise DataError(path, f"eval_mask must be 0 or 1, found {values[bad[0]]!r}",
                        row=FIRST_DATA_LINE + int(bad[0]), column=EVAL_MASK_COLUMN)
    return values == 1


# -------------------------------------------------------------------------- validation


def _check_time(path: Path, t: np.ndarray) -> None:
    """Raise DataError at the first row whose time is not finite or not after its predecessor."""
    not_finite = np.flatnonzero(~np.isfinite(t))
    if not_finite.size:
        raise DataError(path, "time is not a finite number",
                        row=FIRST_DATA_LINE + int(not_finite[0]), column="t")
    not_increasing = np.flatnonzero(np.diff(t) <= 0)
    if not_increasing.size:
        i = int(not_increasing[0]) + 1
        raise DataError(path, f"time is not strictly increasing ({t[i]!r} s after {t[i - 1]!r} s)",
                        row=FIRST_DATA_LINE + i, column="t")


def _sidecar_rate(path: Path, meta: dict) -> float | None:
    """The sidecar's rate_hz [Hz], None when absent; DataError (naming the sidecar) when not a
    positive finite number."""
    rate = meta.get("rate_hz")
    if rate is None:
        return None
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not np.isfinite(rate) or rate <= 0:
        raise DataError(sidecar_path(path), f"sidecar 'rate_hz' is {rate!r}, expected a positive number [Hz]")
    return float(rate)


def _num(x: float) -> str:
    """Short text of a number: 4 significant digits, exponents without '+' or leading zeros."""
    text = f"{x:.4g}"
    mantissa, e, exponent = text.partition("e")
    return mantissa + (f"e{int(exponent)}" if e else "")


def _check_time_unit(path: Path, t: np.ndarray, rate_hz: float | None) -> None:
    """Raise DataError when the median step of t betrays a time not in seconds: against the
    sidecar's 1/rate_hz (beyond RATE_TOLERANCE either way), else below MIN_MEDIAN_STEP_S."""
    if t.size < 2:
        return
    median = float(np.median(np.diff(t)))
    if rate_hz is None:
        if median < MIN_MEDIAN_STEP_S:
            raise DataError(path, f"t steps by {_num(median)} (median), less than {_num(MIN_MEDIAN_STEP_S)} s "
                                  f"(a {_num(1e-3 / MIN_MEDIAN_STEP_S)} kHz IMU): t does not look like "
                                  f"seconds; convert t to seconds (or give rate_hz in the sidecar)",
                            column="t")
        return
    factor = median * rate_hz
    if 1.0 / RATE_TOLERANCE <= factor <= RATE_TOLERANCE:
        return
    said = (f"t steps by {_num(median)} (median) but the sidecar says rate_hz {_num(rate_hz)} "
            f"(step {_num(1.0 / rate_hz)} s)")
    for unit, scale in TIME_UNITS:
        if 1.0 / RATE_TOLERANCE <= factor / scale <= RATE_TOLERANCE:
            raise DataError(path, f"{said}: t looks like {unit} (factor {_num(factor)}); convert t to seconds",
                            column="t")
    raise DataError(path, f"{said}: a factor {_num(factor)} apart (tolerance {_num(RATE_TOLERANCE)}× either "
                          f"way); give t in seconds and the sidecar's rate_hz in Hz", column="t")


@dataclass(frozen=True)
class TimeGaps:
    """Steps of t longer than GAP_STEP_FACTOR × the nominal step [s] (1/rate_hz, else the median
    step): how many, the longest and the time of the sample before it (NaN when there is none)."""

    nominal_step_s: float
    count: int
    longest_s: float
    longest_at_s: float

    @property
    def threshold_s(self) -> float:
        """Steps longer than this [s] are gaps."""
        return GAP_STEP_FACTOR * self.nominal_step_s


def time_gaps(t: np.ndarray, rate_hz: float | None = None) -> TimeGaps:
    """The gaps in the sample times t [s] (strictly increasing); nominal step 1/rate_hz [Hz] when
    given, else the median step."""
    steps = np.diff(np.asarray(t, dtype=np.float64))
    if steps.size == 0:
        return TimeGaps(np.nan, 0, np.nan, np.nan)
    nominal = 1.0 / rate_hz if rate_hz else float(np.median(steps))
    gaps = np.flatnonzero(steps > GAP_STEP_FACTOR * nominal)
    if gaps.size == 0:
        return TimeGaps(nominal, 0, np.nan, np.nan)
    i = int(gaps[np.argmax(steps[gaps])])
    return TimeGaps(nominal, int(gaps.size), float(steps[i]), float(t[i]))


def time_gap_note(path: str | Path, gaps: TimeGaps) -> str | None:
    """One line reporting the gaps of recording `path`, None when it has none."""
    if gaps.count == 0:
        return None
    return (f"{path}: {gaps.count} gap{'s' if gaps.count > 1 else ''} in time (longest "
            f"{_num(gaps.longest_s)} s at t = {_num(gaps.longest_at_s)} s; steps > {_num(GAP_STEP_FACTOR)} × "
            f"the nominal {_num(gaps.nominal_step_s)} s); the attitude filters count the lost time as "
            "unmeasured motion and restart once it could amount to 10° (README, 'Recovery from transients')")


_LOAD_NOTE_SINK: ContextVar[Callable[[str], None] | None] = ContextVar("imu_load_note_sink", default=None)


@contextmanager
def report_load_notes(sink: Callable[[str], None]) -> Iterator[None]:
    """Within the block, every note of read_imu_csv (gaps in time: one line per file) goes to
    `sink` (e.g. print, or a list's append); outside any such block the notes are dropped."""
    token = _LOAD_NOTE_SINK.set(sink)
    try:
        yield
    finally:
        _LOAD_NOTE_SINK.reset(token)


def _report_load_note(note: str | None) -> None:
    """Pass a load note to the active report_load_notes sink, if any."""
    sink = _LOAD_NOTE_SINK.get()
    if note and sink is not None:
        sink(note)


def _finite_norms(xyz: np.ndarray) -> np.ndarray:
    """Euclidean norms of the rows of an (N, 3) array whose three values are finite."""
    rows = xyz[np.isfinite(xyz).all(axis=1)]
    return np.sqrt(np.einsum("ij,ij->i", rows, rows))


def _check_units(path: Path, data: ImuData) -> None:
    """Raise DataError when a triad's magnitudes betray a wrong unit (nT, gauss, °/s, g)."""
    for triad in ("gyr", "acc", "mag", *REF_TRIADS):
        xyz = getattr(data, triad)
        if xyz is None:
            continue
        norms = _finite_norms(xyz)
        if norms.size < MIN_SAMPLES_FOR_UNIT_CHECK:
            continue
        problem = _unit_problem(triad.removeprefix("ref_"), norms)
        if problem:
            raise DataError(path, problem, column=f"{triad}_*")


def _unit_problem(kind: str, norms: np.ndarray) -> str | None:
    """Description of a suspected unit error of a 'gyr'/'acc'/'mag' triad, or None."""
    if kind == "mag":
        median = float(np.median(norms))
        if median > MAG_MEDIAN_NORM_MAX_UT:
            return f"magnetometer median norm is {median:.4g}: looks like nT, expected µT"
        if median < MAG_MEDIAN_NORM_MIN_UT:
            return f"magnetometer median norm is {median:.4g}: looks like gauss, expected µT"
    elif kind == "gyr":
        p99 = float(np.percentile(norms, 99))
        if p99 > GYR_P99_NORM_MAX_RAD_S:
            return (f"gyroscope 99th-percentile rate is {p99:.4g}: looks like deg/s given as "
                    f"rad/s, expected rad/s")
    elif kind == "acc":
        median = float(np.median(norms))
        low, high = ACC_G_UNITS_RANGE
        if low <= median <= high:
            return f"accelerometer median norm is {median:.4g}: looks like g, expected m/s²"
        if median > ACC_MEDIAN_NORM_MAX:
            return (f"accelerometer median norm is {median:.4g}: looks like mg or raw counts, "
                    f"expected m/s²")
    return None


def require_sensors(data: ImuData, triads: Iterable[str], path: str | Path, purpose: str) -> None:
    """Raise DataError when one of `triads` ('gyr', 'acc', 'mag' or 'temp') has no finite sample.

    `purpose` names the computation that needs the sensor, e.g. 'attitude estimation'.
    """
    for triad in triads:
        if triad not in (*TRIADS, "temp"):
            raise ValueError(f"unknown sensor {triad!r}; expected one of {TRIADS + ('temp',)}")
        if not np.isfinite(getattr(data, triad)).any():
            raise DataError(path, f"sensor '{triad}' is all-NaN; {purpose} needs it")


# ----------------------------------------------------------------------------- writing


def write_imu_csv(data: ImuData, path: str | Path) -> Path:
    """Write `data` as imu-csv/1 (gzip when `path` ends with '.gz') plus its sidecar JSON.

    Floats are written as their shortest exact text (repr), NaN as an empty cell, eval_mask as
    0/1. Optional columns appear only when present. Returns the path of the CSV file.
    """
    path = Path(path)
    data.validate()
    names, columns = _output_columns(data)
    text = ",".join(names) + "\n" + "".join(
        ",".join(row) + "\n" for row in zip(*(_format_column(c) for c in columns)))
    _write_bytes(path, text.encode("utf-8"))
    meta = {"format": FORMAT, **{k: v for k, v in data.meta.items() if k != "format"}}
    sidecar_path(path).write_text(json.dumps(meta, indent=1, ensure_ascii=False) + "\n",
                                  encoding="utf-8")
    return path


def _output_columns(data: ImuData) -> tuple[list[str], list[np.ndarray]]:
    """Column names and (N,) arrays of the columns `data` carries, in canonical order."""
    n = len(data)
    names = ["t"]
    columns = [data.t]
    groups = [(triad_columns("gyr"), data.gyr), (triad_columns("acc"), data.acc),
              (triad_columns("mag"), data.mag), (["temp"], data.temp[:, None]),
              (list(REF_Q_COLUMNS), data.ref_q),
              *((triad_columns(p), getattr(data, p)) for p in REF_TRIADS)]
    if data.eval_mask is not None:
        groups.append(([EVAL_MASK_COLUMN], np.asarray(data.eval_mask, dtype=bool)[:, None]))
    for name, values in data.aux.items():
        if not name.startswith(AUX_PREFIX) or np.shape(values) != (n,):
            raise ValueError(f"{data.name}: aux entry {name!r} must be named 'aux_*' and have "
                             f"shape ({n},), got {np.shape(values)}")
        groups.append(([name], np.asarray(values)[:, None]))
    for group_names, values in groups:
        if values is not None:
            names.extend(group_names)
            columns.extend(values.T)
    return names, columns


def _format_column(values: np.ndarray) -> list[str]:
    """Cell texts of one column: shortest round-trip float text, '' for NaN, 0/1 for bool."""
    if values.dtype == bool:
        return ["1" if v else "0" for v in values.tolist()]
    return ["" if v != v else repr(v) for v in np.asarray(values, dtype=np.float64).tolist()]


def _write_bytes(path: Path, payload: bytes) -> None:
    """Write `payload`, gzip-compressed without timestamp or file name when path ends in .gz."""
    if path.name.endswith(".gz"):
        buffer = io.BytesIO()
        with gzip.GzipFile(filename="", mode="wb", fileobj=buffer, mtime=0,
                           compresslevel=GZIP_LEVEL) as gz:
            gz.write(payload)
        payload = buffer.getvalue()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(payload)


# ---------------------------------------------------------------------------- folders


def load_many(paths: Iterable[str | Path]) -> list[ImuData]:
    """Read several recordings in the given order (the first malformed one raises DataError)."""
    return [read_imu_csv(p) for p in paths]


def find_recordings(folder: str | Path) -> list[Path]:
    """Sorted paths of the '*.csv' and '*.csv.gz' files directly inside `folder`."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(folder, "folder not found")
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and (p.name.endswith(".csv") or p.name.endswith(".csv.gz")))
