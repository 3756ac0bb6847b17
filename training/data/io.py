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
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contract.errors import DataError
from contract.layout import SETTINGS
from training.data import input_limits as limits
from training.data.dataset import REF_Q_COLUMNS, TRIADS, ImuData, triad_columns
from training.data.sidecar import check_sidecar

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
#: Streaming and size limits: a malformed file costs at most one block of rows before it is refused.
MAX_LINE_CHARS = 100_000     # a longer line is refused (an imu-csv/1 row is a few hundred characters)
BLOCK_CHARS = 4 * 2**20      # characters of text parsed at a time (about 40 k rows)
SEGMENT_ROWS = 2**20         # rows per storage segment (8 MiB per column: each one its own memory map)
WRITE_BLOCK_ROWS = 2**16     # rows formatted at a time when writing
MAX_SIDECAR_BYTES = 2**20    # a larger sidecar is refused (a sidecar is a few hundred bytes)
#: The runtime's field_norm setting [µT] when the sidecar gives no earth_field.norm_ut (contract/layout.py).
DEFAULT_FIELD_NORM_UT = dict(SETTINGS)["field_norm"]
#: (column index, low, high, unit, the C limit it mirrors) of a column the loader checks cell by cell.
ValueLimit = tuple[int, float, float, str, str]
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
    computation needs one. The file is streamed: each block of rows is checked as it is read
    (cells, time order, eval_mask, the runtime's input limits), so a malformed file fails at its
    first bad row, and memory stays near the size of the returned arrays (8 bytes per cell).
    """
    path = Path(path)
    meta = read_sidecar(path)
    rate_hz = meta.get("rate_hz")
    with _open_text(path) as stream:
        columns = _parse_header(path, _read_header(path, stream))
        store = _read_blocks(path, stream, columns, _value_limits(columns, meta))
    data = _to_imu_data(path, columns, store, meta)
    _check_time_unit(path, data.t, rate_hz)
    _check_units(path, data)
    _report_load_note(time_gap_note(path, time_gaps(data.t, rate_hz)))
    return data


def read_sidecar(path: str | Path) -> dict:
    """The sidecar metadata of recording `path` ({} when there is no sidecar; at most
    MAX_SIDECAR_BYTES; a UTF-8 BOM is accepted), its fields checked (training/data/sidecar.py)."""
    side = sidecar_path(path)
    if not side.is_file():
        return {}
    with open(side, "rb") as f:
        raw = f.read(MAX_SIDECAR_BYTES + 1)
    if len(raw) > MAX_SIDECAR_BYTES:
        raise DataError(side, f"sidecar is larger than {MAX_SIDECAR_BYTES // 1024} KiB")
    try:
        meta = json.loads(raw.decode("utf-8-sig"))
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise DataError(side, f"sidecar is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise DataError(side, "sidecar must be a JSON object")
    if meta.get("format") != FORMAT:
        raise DataError(side, f"sidecar 'format' is {_json_text(meta.get('format'))}, expected '{FORMAT}'")
    check_sidecar(side, meta)  # field types and ranges (training/data/sidecar.py)
    return meta


def _json_text(value) -> str:
    """Short JSON text of a sidecar value for a message (at most 60 characters)."""
    text = json.dumps(value, ensure_ascii=False)
    return text if len(text) <= 60 else text[:57] + "..."


@contextmanager
def _open_text(path: Path) -> Iterator[io.TextIOBase]:
    """The recording as a text stream (gunzipped for '.gz', UTF-8 with an optional BOM, any
    newline convention read as '\\n'); a decompression or decoding failure becomes a DataError."""
    try:
        binary = gzip.open(path, "rb") if path.name.endswith(".gz") else open(path, "rb")
    except FileNotFoundError:
        raise DataError(path, "file not found") from None
    except IsADirectoryError:
        raise DataError(path, "is a folder, not a file") from None
    with binary, io.TextIOWrapper(binary, encoding="utf-8-sig", newline=None) as text:
        try:
            yield text
        except (OSError, EOFError, zlib.error, UnicodeDecodeError) as exc:
            raise DataError(path, f"cannot read as {'gzip-compressed ' if path.name.endswith('.gz') else ''}"
                                  f"UTF-8 CSV ({exc})") from None


def _read_header(path: Path, stream: io.TextIOBase) -> str:
    """The header line (without newline); DataError when empty or longer than MAX_LINE_CHARS."""
    header = stream.readline(MAX_LINE_CHARS + 1)
    if len(header) > MAX_LINE_CHARS:
        raise DataError(path, f"line longer than {MAX_LINE_CHARS} characters", row=1)
    header = header.rstrip("\n")
    if not header.strip():
        raise DataError(path, "file is empty (no header row)", row=1)
    return header


def _parse_header(path: Path, header: str) -> list[str]:
    """Column names of the header line, checked against the imu-csv/1 schema."""
    if "," not in header:
        for name, sep in (("';'", ";"), ("a tab", "\t"), ("'|'", "|"), ("spaces", " ")):
            if sep in header.strip():
                raise DataError(path, f"columns are separated by {name}; imu-csv/1 separates them "
                                      "by ',' (and uses '.' as the decimal point)", row=1)
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


def _text_blocks(path: Path, stream: io.TextIOBase) -> Iterator[tuple[int, str]]:
    """(editor line of its first row, text) of consecutive blocks of whole data lines (about
    BLOCK_CHARS characters each, ending with '\\n'); DataError at a line longer than MAX_LINE_CHARS."""
    row, pending = FIRST_DATA_LINE, ""
    while True:
        piece = stream.read(BLOCK_CHARS)
        text = pending + piece
        cut = text.rfind("\n") + 1 if piece else len(text)
        block, pending = text[:cut], text[cut:]
        if block:
            lengths = list(map(len, block.split("\n")))
            if max(lengths) > MAX_LINE_CHARS:
                first = next(i for i, n in enumerate(lengths) if n > MAX_LINE_CHARS)
                raise DataError(path, f"line longer than {MAX_LINE_CHARS} characters", row=row + first)
            yield row, block if block.endswith("\n") else block + "\n"
            row += block.count("\n") + (not block.endswith("\n"))
        if len(pending) > MAX_LINE_CHARS:  # after the whole lines before it were checked
            raise DataError(path, f"line longer than {MAX_LINE_CHARS} characters", row=row)
        if not piece:
            return


class _RowStore:
    """Rows of float64 cells collected in segments of SEGMENT_ROWS rows. A segment is large enough
    for the allocator to give it its own memory map, so each one is returned to the system as soon
    as it is released: moving the rows out segment by segment never holds two copies of the data."""

    def __init__(self, width: int) -> None:
        self.width, self.rows, self._segments = width, 0, []

    def append(self, table: np.ndarray) -> None:
        """Copy the (k, width) table after the rows stored so far."""
        done = 0
        while done < len(table):
            used = self.rows % SEGMENT_ROWS
            if used == 0:
                self._segments.append(np.empty((SEGMENT_ROWS, self.width)))
            take = min(SEGMENT_ROWS - used, len(table) - done)
            self._segments[-1][used:used + take] = table[done:done + take]
            done += take
            self.rows += take

    def release(self) -> Iterator[np.ndarray]:
        """The stored rows, one segment at a time (first to last); each segment is dropped from the
        store before it is yielded, so it is freed once the caller lets go of it."""
        self._segments.reverse()
        left = self.rows
        while self._segments:
            segment = self._segments.pop()
            yield segment[:min(SEGMENT_ROWS, left)]
            left -= SEGMENT_ROWS


def _read_blocks(path: Path, stream: io.TextIOBase, columns: Sequence[str],
                 limits: list[ValueLimit]) -> _RowStore:
    """The data rows, each block checked as it is read:
    cells, blank lines (allowed only at the end), time finite and strictly increasing, eval_mask
    0/1 and the runtime's input limits."""
    store = _RowStore(len(columns))
    blank_row = None            # editor line of a blank line seen so far (an error if data follows)
    last_t = -np.inf
    for row, block in _text_blocks(path, stream):
        body = block.rstrip("\n")
        if body and blank_row is not None:
            raise DataError(path, "blank line inside the data", row=blank_row)
        if not body:
            blank_row = row if blank_row is None else blank_row
            continue
        _reject_blank_lines(path, body, row)
        if len(block) - len(body) > 1:
            blank_row = row + body.count("\n") + 1
        table = _parse_rows(path, body, columns, row)
        last_t = _check_time_block(path, table[:, 0], last_t, row)
        _check_block_values(path, table, columns, limits, row)
        store.append(table)
    if not store.rows:
        raise DataError(path, "no data rows after the header", row=FIRST_DATA_LINE)
    return store


def _parse_rows(path: Path, body: str, columns: Sequence[str], first_row: int) -> np.ndarray:
    """(rows, len(columns)) float64 table of data lines starting at editor line first_row; empty
    cells and 'nan' are NaN."""
    try:
        table = np.loadtxt(io.StringIO(_fill_empty_cells(body)), delimiter=",", comments=None,
                           ndmin=2, dtype=np.float64)
        if table.shape[1] == len(columns):
            return table
        problem = f"rows have {table.shape[1]} cells, expected {len(columns)}"
    except ValueError as exc:
        problem = f"cannot parse the data rows ({exc})"
    _locate_bad_cell(path, body, columns, first_row)
    raise DataError(path, problem, row=first_row)


def _reject_blank_lines(path: Path, body: str, first_row: int) -> None:
    """Raise DataError at the first blank line inside `body` (it would shift row numbers)."""
    if body.startswith("\n"):
        line = first_row
    else:
        pos = body.find("\n\n")
        if pos < 0:
            return
        line = first_row + body.count("\n", 0, pos) + 1
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


def _locate_bad_cell(path: Path, body: str, columns: Sequence[str], first_row: int) -> None:
    """Scan the data lines and raise DataError at the first ragged row or non-numeric cell."""
    for index, line in enumerate(body.split("\n")):
        row = first_row + index
        cells = line.split(",")
        if len(cells) != len(columns):
            raise DataError(path, f"row has {len(cells)} cells, expected {len(columns)}", row=row)
        for name, cell in zip(columns, cells):
            if cell.strip() and not _is_number(cell):
                raise DataError(path, f"not a number: {cell[:40]!r}", row=row, column=name)


def _is_number(cell: str) -> bool:
    """True when `cell` is a decimal number, 'nan' or 'inf' as numpy's parser reads it."""
    try:
        float(cell)
    except ValueError:
        return False
    return "_" not in cell


def _check_time_block(path: Path, t: np.ndarray, last_t: float, first_row: int) -> float:
    """DataError at the first time that is not finite or not after its predecessor (last_t: the
    last time of the previous block); returns the block's last time."""
    not_finite = np.flatnonzero(~np.isfinite(t))
    if not_finite.size:
        raise DataError(path, "time is not a finite number", row=first_row + int(not_finite[0]), column="t")
    previous = np.concatenate(([last_t], t[:-1]))
    not_increasing = np.flatnonzero(t <= previous)
    if not_increasing.size:
        i = int(not_increasing[0])
        raise DataError(path, f"time is not strictly increasing ({_num(t[i], 12)} s after "
                              f"{_num(previous[i], 12)} s)", row=first_row + i, column="t")
    return float(t[-1])


def _value_limits(columns: Sequence[str], meta: dict) -> list[ValueLimit]:
    """(column index, low, high, unit, where the limit comes from) of every column the runtime's
    input guard limits (training.data.input_limits): raw and reference triads, temperature."""
    field = (meta.get("earth_field") or {}).get("norm_ut") or DEFAULT_FIELD_NORM_UT
    per_triad = {"gyr": (limits.GYR_LIMIT_RAD_S, "rad/s", "IMU_GUARD_GYR_LIMIT"),
                 "acc": (limits.ACC_LIMIT_M_S2, "m/s²", "IMU_GUARD_ACC_LIMIT"),
                 "mag": (limits.MAG_SATURATION * field, "µT",
                         f"IMU_GUARD_MAG_SATURATION × field norm {_num(field)} µT")}
    out = []
    for i, name in enumerate(columns):
        triad = name.removeprefix("ref_")[:3]
        if name == "temp":
            out.append((i, limits.TEMP_MIN_C, limits.TEMP_MAX_C, "°C",
                        "IMU_GUARD_TEMP_MIN..IMU_GUARD_TEMP_MAX"))
        elif triad in per_triad and name.removeprefix("ref_")[3:] in ("_x", "_y", "_z"):
            bound, unit, source = per_triad[triad]
            out.append((i, -bound, bound, unit, source))
    return out


def _check_block_values(path: Path, table: np.ndarray, columns: Sequence[str], value_limits: list[ValueLimit],
                        first_row: int) -> None:
    """DataError at the first cell beyond the runtime's input limits (NaN is a missing value, not
    out of range) and at the first eval_mask that is not 0 or 1."""
    for i, low, high, unit, source in value_limits:
        values = table[:, i]
        bad = np.flatnonzero((values < low) | (values > high) | np.isinf(values))
        if bad.size:
            _check_block_unit(path, table, columns, columns[i])
            raise DataError(path, f"{_num(values[bad[0]])} {unit} is outside {_num(low)}..{_num(high)} {unit}, "
                                  f"the range the runtime accepts (sources/ImuGuard.h {source}); write an "
                                  "empty cell for a missing value", row=first_row + int(bad[0]), column=columns[i])
    if EVAL_MASK_COLUMN in columns:
        values = table[:, columns.index(EVAL_MASK_COLUMN)]
        bad = np.flatnonzero((values != 0) & (values != 1))
        if bad.size:
            raise DataError(path, f"eval_mask must be 0 or 1, found {_num(values[bad[0]])}",
                            row=first_row + int(bad[0]), column=EVAL_MASK_COLUMN)


def _check_block_unit(path: Path, table: np.ndarray, columns: Sequence[str], column: str) -> None:
    """DataError naming the suspected unit when the triad of `column` (e.g. 'mag_x', 'ref_gyr_y')
    in this block of rows betrays a wrong unit: a clearer message than its first out-of-range cell."""
    prefix = column.rsplit("_", 1)[0]
    if prefix not in (*TRIADS, *REF_TRIADS):
        return
    xyz = table[:, [columns.index(c) for c in triad_columns(prefix)]]
    norms = _finite_norms(xyz)
    problem = (_unit_problem(prefix.removeprefix("ref_"), norms, whole_numbers(xyz))
               if norms.size >= MIN_SAMPLES_FOR_UNIT_CHECK else None)
    if problem:
        raise DataError(path, problem, column=f"{prefix}_*")


def _to_imu_data(path: Path, columns: Sequence[str], store: _RowStore, meta: dict) -> ImuData:
    """Move the stored rows into an ImuData (optional groups None when absent), segment by segment:
    the peak memory is about one copy of the data plus one segment."""
    index = {name: i for i, name in enumerate(columns)}
    groups = {"t": ["t"], "gyr": triad_columns("gyr"), "acc": triad_columns("acc"),
              "mag": triad_columns("mag"), "temp": ["temp"], "ref_q": list(REF_Q_COLUMNS),
              **{p: triad_columns(p) for p in REF_TRIADS}, EVAL_MASK_COLUMN: [EVAL_MASK_COLUMN],
              **{n: [n] for n in columns if n.startswith(AUX_PREFIX)}}
    groups = {g: names for g, names in groups.items() if names[0] in index}
    arrays = {g: np.empty((store.rows, len(names))) for g, names in groups.items()}
    start = 0
    for block in store.release():
        for g, names in groups.items():
            arrays[g][start:start + len(block)] = block[:, [index[c] for c in names]]
        start += len(block)
    flat = {g: a[:, 0] for g, a in arrays.items() if len(groups[g]) == 1}
    return ImuData(
        t=flat["t"], gyr=arrays["gyr"], acc=arrays["acc"], mag=arrays["mag"], temp=flat["temp"],
        ref_q=arrays.get("ref_q"), ref_gyr=arrays.get("ref_gyr"), ref_acc=arrays.get("ref_acc"),
        ref_mag=arrays.get("ref_mag"),
        eval_mask=flat[EVAL_MASK_COLUMN] == 1 if EVAL_MASK_COLUMN in flat else None,
        aux={n: flat[n] for n in groups if n.startswith(AUX_PREFIX)},
        meta=meta, name=recording_stem(path))


# -------------------------------------------------------------------------- validation


def _num(x: float, digits: int = 4) -> str:
    """Short plain text of a number: `digits` significant digits, exponents without '+' or
    leading zeros (never a numpy repr)."""
    text = f"{float(x):.{digits}g}"
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
            f"the nominal {_num(gaps.nominal_step_s)} s); the runtime restarts the attitude across a step "
            f"longer than {_num(limits.GAP_STEPS)} nominal steps and counts a shorter loss as unmeasured motion, "
            "restarting once it could amount to 10° (docs/fmu.md, 'Time steps')")


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
    """Euclidean norms of the rows of an (N, 3) array whose three values are finite (an overflow
    to inf counts as not finite)."""
    with np.errstate(over="ignore", invalid="ignore"):
        norms = np.sqrt(np.einsum("ij,ij->i", xyz, xyz))
    return norms[np.isfinite(norms)]


def _check_units(path: Path, data: ImuData) -> None:
    """Raise DataError when a triad's magnitudes betray a wrong unit (nT, gauss, °/s, g)."""
    for triad in ("gyr", "acc", "mag", *REF_TRIADS):
        xyz = getattr(data, triad)
        if xyz is None:
            continue
        norms = _finite_norms(xyz)
        if norms.size < MIN_SAMPLES_FOR_UNIT_CHECK:
            continue
        problem = _unit_problem(triad.removeprefix("ref_"), norms, whole_numbers(xyz))
        if problem:
            raise DataError(path, problem, column=f"{triad}_*")


#: Share of a triad's finite values that must be whole numbers for it to look like raw ADC counts (a
#: value converted to a physical unit is a whole number only by chance).
WHOLE_NUMBER_SHARE = 0.99


def whole_numbers(xyz: np.ndarray) -> bool:
    """True when at least WHOLE_NUMBER_SHARE of the finite values of xyz (N, 3) are whole numbers and
    some are not zero: raw ADC counts."""
    values = xyz[np.isfinite(xyz)]
    return bool(values.size and np.any(values != 0)
                and np.mean(values == np.round(values)) >= WHOLE_NUMBER_SHARE)


def _counts_hint(kind: str) -> str:
    """How to convert raw counts of a triad (imufmu import's --units syntax)."""
    unit = {"gyr": "deg/s", "acc": "g", "mag": "uT"}[kind]
    return (f"; every value is a whole number: if these are raw ADC counts, convert them with the sensor's "
            f"sensitivity, e.g. imufmu import FILE --units {kind}=counts:1/SENSITIVITY{unit}")


def _unit_problem(kind: str, norms: np.ndarray, counts: bool = False) -> str | None:
    """Description of a suspected unit error of a 'gyr'/'acc'/'mag' triad, or None; counts: its values
    are whole numbers (raw ADC counts are then named instead of a wrong physical unit)."""
    if kind == "mag":
        median = float(np.median(norms))
        if median > MAG_MEDIAN_NORM_MAX_UT:
            return f"magnetometer median norm is {median:.4g}: looks like nT, expected µT" + (_counts_hint(kind) if counts else "")
        if median < MAG_MEDIAN_NORM_MIN_UT:
            return f"magnetometer median norm is {median:.4g}: looks like gauss, expected µT"
    elif kind == "gyr":
        p99 = float(np.percentile(norms, 99))
        if p99 > GYR_P99_NORM_MAX_RAD_S:
            return (f"gyroscope 99th-percentile rate is {p99:.4g}: looks like deg/s given as "
                    f"rad/s, expected rad/s" + (_counts_hint(kind) if counts else ""))
    elif kind == "acc":
        median = float(np.median(norms))
        low, high = ACC_G_UNITS_RANGE
        if low <= median <= high:
            return f"accelerometer median norm is {median:.4g}: looks like g, expected m/s²"
        if median > ACC_MEDIAN_NORM_MAX:
            return (f"accelerometer median norm is {median:.4g}: looks like mg or raw counts, "
                    f"expected m/s²" + (_counts_hint(kind) if counts else ""))
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
    with _output_stream(path) as out:  # block by block: memory stays near the arrays' size
        out.write((",".join(names) + "\n").encode("utf-8"))
        for start in range(0, len(data), WRITE_BLOCK_ROWS):
            block = [_format_column(c[start:start + WRITE_BLOCK_ROWS]) for c in columns]
            out.write("".join(",".join(row) + "\n" for row in zip(*block)).encode("utf-8"))
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


@contextmanager
def _output_stream(path: Path) -> Iterator[io.BufferedIOBase]:
    """A binary stream writing `path`, gzip-compressed without timestamp or file name when it ends in
    .gz (the bytes do not depend on how the payload is split into writes)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        if not path.name.endswith(".gz"):
            yield f
            return
        with gzip.GzipFile(filename="", mode="wb", fileobj=f, mtime=0, compresslevel=GZIP_LEVEL) as gz:
            yield gz


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
