"""A user's recording as named columns of numbers: delimited text (CSV, optionally gzip) or MATLAB .mat.

Text: the first line that is not blank and not a comment ('#', '%', '//') is the header (required);
the delimiter — ',', ';', tab or whitespace — is the one that splits the header and the first data
rows into the same number of fields; with ';' or tab, a decimal comma ('1,25') is read as '1.25'.
Only the columns an import uses are parsed, block by block (BLOCK_LINES lines at a time, with a
tqdm bar for large files); a time column may hold clock stamps ('2024-05-01T12:00:00.125',
'12:00:00.125') instead of numbers. Every problem is a DataError naming the file, the line (as an
editor shows it) and the column.

MATLAB: variables and struct fields (dotted names, 'imu.gyro') that are numeric vectors are
columns; an N×k matrix gives the columns 'name(:,1)'..'name(:,k)'. v7.3 files are HDF5, which
scipy cannot read: they are refused with what to do instead.
"""
from __future__ import annotations

import csv
import gzip
import io
import re
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from contract.errors import DataError

#: Lines parsed at a time.
BLOCK_LINES = 1 << 16
#: A longer line is refused, so that a file without newlines (or a gzip bomb) costs one line of memory.
MAX_LINE_CHARS = 100_000
#: Files larger than this [bytes] show a progress bar while they are read.
PROGRESS_BYTES = 32 << 20
#: Data rows the delimiter sniffer looks at.
SNIFF_ROWS = 20
#: Candidate delimiters, in order of preference when several fit: (character, name in messages).
DELIMITERS = ((",", "','"), (";", "';'"), ("\t", "tab"), (None, "whitespace"))
COMMENT_PREFIXES = ("#", "%", "//")
MAT_V73_MARK = b"MATLAB 7.3"
_DECIMAL_COMMA = re.compile(r"^\s*[+-]?\d+,\d+\s*$")
_CLOCK = re.compile(r"^\s*(?:(?P<date>\d{4}-\d{2}-\d{2})[T ])?(?P<h>\d{1,2}):(?P<m>\d{2}):(?P<s>\d{2}(?:\.\d*)?)"
                    r"(?P<zone>Z|[+-]\d{2}:?\d{2})?\s*$")


@dataclass
class SourceTable:
    """The columns of a user's file. `names`: every column in file order; `kind`: 'text' or 'mat';
    `layout`: how it was read, for the summary ("',' delimited, header on line 1");
    `first_data_line`: editor line of the first data row (text) or 1 (MATLAB sample index)."""

    path: Path
    kind: str
    names: list[str]
    layout: str
    first_data_line: int = 1
    delimiter: str | None = None
    decimal_comma: bool = False
    encoding: str = "utf-8-sig"
    clock_columns: frozenset[str] = frozenset()                   # text: columns of clock stamps
    arrays: dict[str, np.ndarray] = field(default_factory=dict)   # MATLAB: name -> (N,) values
    dropped: dict[str, str] = field(default_factory=dict)         # MATLAB: name -> why it is no column


@dataclass
class Columns:
    """Parsed columns: name -> (N,) float64 (clock stamps in s since the epoch, or since midnight
    without a date); `lines`: (N,) editor line (text) or sample number (MATLAB) of each row."""

    values: dict[str, np.ndarray]
    lines: np.ndarray


def open_table(path: Path) -> SourceTable:
    """The header (text) or the variables (MATLAB) of `path`; DataError when it cannot be read."""
    if not path.is_file():
        raise DataError(path, "file not found" if not path.exists() else "is not a file")
    if path.suffix.lower() == ".mat":
        return _open_mat(path)
    return _open_text_table(path)


def read_columns(table: SourceTable, wanted: list[str], progress: bool | None = None) -> Columns:
    """The columns `wanted` of the table, parsed; progress: a tqdm bar (None: for files over PROGRESS_BYTES)."""
    if table.kind == "mat":
        n = len(next(iter(table.arrays.values()))) if table.arrays else 0
        return Columns({w: table.arrays[w] for w in wanted}, np.arange(1, n + 1))
    return _read_text_columns(table, wanted, progress)


# ----------------------------------------------------------------------------------- text


def _open_binary(path: Path):
    """The file as a binary stream (gunzipped for '.gz')."""
    return gzip.open(path, "rb") if path.name.lower().endswith(".gz") else open(path, "rb")


def _encoding(path: Path) -> str:
    """'utf-8-sig' when the file's start decodes as UTF-8, else 'latin-1' (a Windows export with '°')."""
    try:
        with _open_binary(path) as f:
            head = f.read(1 << 16)
    except (OSError, EOFError, zlib.error) as exc:
        raise DataError(path, f"cannot read the file ({exc})") from None
    cut = head.rfind(b"\n") + 1 or len(head)
    try:
        head[:cut].decode("utf-8")
        return "utf-8-sig"
    except UnicodeDecodeError:
        return "latin-1"


def _open_text_table(path: Path) -> SourceTable:
    """Header, delimiter and decimal mark of a delimited text file."""
    encoding = _encoding(path)
    header, header_line, sample = None, 0, []
    try:
        with io.TextIOWrapper(_open_binary(path), encoding=encoding, newline=None) as f:
            line_number = 0
            while len(sample) < SNIFF_ROWS:
                line_number += 1
                line = _line(path, f, line_number)
                if not line:
                    break
                line = line.rstrip("\n")
                if header is None:
                    if line.strip() and not line.lstrip().startswith(COMMENT_PREFIXES):
                        header, header_line = line, line_number
                elif line.strip():
                    sample.append(line)
    except (OSError, EOFError, zlib.error, UnicodeDecodeError) as exc:
        raise DataError(path, f"cannot read as a text table ({exc})") from None
    if header is None:
        raise DataError(path, "file is empty (a header row with the column names is required)", row=1)
    if not sample:
        raise DataError(path, "no data rows after the header", row=header_line + 1)
    delimiter, name = _sniff(path, header, sample, header_line)
    names = _split(header, delimiter)
    if _looks_numeric(names):
        raise DataError(path, "the first row holds numbers, not column names: a header row is required "
                              "(add one, e.g. 't,gyr_x,gyr_y,gyr_z,...', or name the columns there)", row=header_line)
    decimal_comma = delimiter in (";", "\t") and any(_DECIMAL_COMMA.match(c) for row in sample
                                                     for c in _split(row, delimiter))
    first = _split(sample[0], delimiter)
    clock = frozenset(n for n, cell in zip(names, first) if _CLOCK.match(cell))
    skipped = f"; {header_line - 1} line(s) before it skipped" if header_line > 1 else ""
    layout = (f"{name}-delimited text, header on line {header_line}{skipped}"
              + (", decimal comma" if decimal_comma else ""))
    return SourceTable(path, "text", names, layout, header_line + 1, delimiter, decimal_comma, encoding, clock)


def _line(path: Path, stream: io.TextIOBase, line_number: int) -> str:
    """The next line with its newline ('' at the end of the file), at most MAX_LINE_CHARS characters,
    else a DataError naming it."""
    line = stream.readline(MAX_LINE_CHARS + 1)
    if len(line) > MAX_LINE_CHARS:
        raise DataError(path, f"line longer than {MAX_LINE_CHARS} characters", row=line_number)
    return line


def _split(line: str, delimiter: str | None) -> list[str]:
    """Fields of one line (quotes honoured; None: runs of whitespace)."""
    if delimiter is None:
        return line.split()
    return [c.strip() for c in next(csv.reader([line], delimiter=delimiter))]


def _looks_numeric(names: list[str]) -> bool:
    """True when every header field is a number (the file has no header row)."""
    try:
        [float(n) for n in names]
    except ValueError:
        return False
    return True


def _sniff(path: Path, header: str, sample: list[str], header_line: int) -> tuple[str | None, str]:
    """(delimiter, its name) that splits the header into ≥ 2 fields and most sampled rows into as many
    (a malformed row among them is then reported where it is, by the reader)."""
    for delimiter, name in DELIMITERS:
        width = len(_split(header, delimiter))
        if width >= 2 and 2 * sum(len(_split(row, delimiter)) == width for row in sample) > len(sample):
            return delimiter, name
    delimiter, name = next(((d, n) for d, n in DELIMITERS if len(_split(header, d)) >= 2), DELIMITERS[0])
    rows = Counter(len(_split(row, delimiter)) for row in sample).most_common(1)[0][0]
    raise DataError(path, f"cannot tell the delimiter: none of ',' ';' tab whitespace splits the header and most "
                          f"of the first {len(sample)} rows alike (by {name}: the header has "
                          f"{len(_split(header, delimiter))} fields, most rows {rows})", row=header_line)


def _read_text_columns(table: SourceTable, wanted: list[str], progress: bool | None) -> Columns:
    """Parse the columns `wanted` of a text table, block by block."""
    from tqdm import tqdm
    index = [table.names.index(w) for w in wanted]
    size = table.path.stat().st_size
    show = size > PROGRESS_BYTES if progress is None else progress
    parts: list[np.ndarray] = []
    lines: list[np.ndarray] = []
    with open(table.path, "rb") as raw, tqdm(total=size, unit="B", unit_scale=True, disable=not show,
                                             desc=f"import: reading {table.path.name}") as bar:
        binary = gzip.GzipFile(fileobj=raw) if table.path.name.lower().endswith(".gz") else raw
        text = io.TextIOWrapper(binary, encoding=table.encoding, newline=None)
        try:
            for first, block in _blocks(table.path, text, table.first_data_line):
                rows, numbers = _data_rows(block, first)
                if not rows:
                    continue
                values = _parse_block(table, rows, numbers, index, wanted)
                parts.append(values)
                lines.append(numbers)
                bar.update(raw.tell() - bar.n)
        except (OSError, EOFError, zlib.error, UnicodeDecodeError) as exc:
            raise DataError(table.path, f"cannot read as a text table ({exc})") from None
    if not parts:
        raise DataError(table.path, "no data rows after the header", row=table.first_data_line)
    data = np.concatenate(parts)
    return Columns({w: data[:, k] for k, w in enumerate(wanted)}, np.concatenate(lines))


def _blocks(path: Path, text: io.TextIOBase, first_data_line: int):
    """(editor line of its first line, lines) of consecutive blocks of up to BLOCK_LINES data lines."""
    for number in range(1, first_data_line):
        _line(path, text, number)
    line_number = first_data_line
    while True:
        block = []
        while len(block) < BLOCK_LINES:
            line = _line(path, text, line_number + len(block))
            if not line:
                break
            block.append(line.rstrip("\n"))
        if not block:
            return
        yield line_number, block
        line_number += len(block)


def _data_rows(block: list[str], first: int) -> tuple[list[str], np.ndarray]:
    """The non-blank lines of a block and their editor line numbers."""
    keep = [i for i, line in enumerate(block) if line.strip()]
    return [block[i] for i in keep], first + np.array(keep, dtype=np.int64)


def _parse_block(table: SourceTable, rows: list[str], numbers: np.ndarray, index: list[int],
                 wanted: list[str]) -> np.ndarray:
    """(len(rows), len(wanted)) values of the wanted columns (clock stamps in seconds)."""
    _check_widths(table, rows, numbers)
    out = np.empty((len(rows), len(wanted)))
    cells = None
    numeric = []
    for k, (i, name) in enumerate(zip(index, wanted)):
        if name in table.clock_columns:
            cells = cells or [_split(r, table.delimiter) for r in rows]
            out[:, k] = _clock_seconds(table.path, cells, i, name, numbers)
        else:
            numeric.append(k)
    if numeric:
        out[:, numeric] = _numbers(table, rows, numbers, [index[k] for k in numeric], [wanted[k] for k in numeric])
    return out


def _check_widths(table: SourceTable, rows: list[str], numbers: np.ndarray) -> None:
    """DataError at the first row whose number of fields is not the header's."""
    d = table.delimiter
    if d is None:
        widths = np.fromiter((len(r.split()) for r in rows), dtype=np.int64, count=len(rows))
    elif any('"' in r for r in rows):
        widths = np.fromiter((len(_split(r, d)) for r in rows), dtype=np.int64, count=len(rows))
    else:
        widths = np.fromiter((r.count(d) + 1 for r in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(widths != len(table.names))
    if bad.size:
        raise DataError(table.path, f"row has {widths[bad[0]]} fields, the header has {len(table.names)}",
                        row=int(numbers[bad[0]]))


def _numbers(table: SourceTable, rows: list[str], numbers: np.ndarray, index: list[int],
             names: list[str]) -> np.ndarray:
    """(len(rows), len(index)) float64 of numeric columns; empty cells and 'nan' are NaN."""
    body = "\n".join(rows)
    if table.decimal_comma:
        body = body.replace(",", ".")
    if table.delimiter is not None:
        d = re.escape(table.delimiter)
        body = re.sub(rf"(^|{d})(?=[ \t]*(?:{d}|$))", r"\1nan", body, flags=re.M)
    try:
        return np.loadtxt(io.StringIO(body), delimiter=table.delimiter, usecols=index, ndmin=2,
                          dtype=np.float64, comments=None, quotechar='"')
    except ValueError:
        _locate_bad_cell(table, rows, numbers, index, names)
        raise DataError(table.path, "cannot parse the data rows", row=int(numbers[0])) from None


def _locate_bad_cell(table: SourceTable, rows: list[str], numbers: np.ndarray, index: list[int],
                     names: list[str]) -> None:
    """DataError at the first row that is too short or holds a cell of a used column that is no number."""
    for row, line in zip(numbers, rows):
        cells = _split(line, table.delimiter)
        if len(cells) != len(table.names):
            raise DataError(table.path, f"row has {len(cells)} fields, the header has {len(table.names)}",
                            row=int(row))
        for i, name in zip(index, names):
            cell = cells[i].replace(",", ".") if table.decimal_comma else cells[i]
            try:
                float(cell or "nan")
                if "_" in cell:  # Python reads '1_000', numpy does not
                    raise ValueError
            except ValueError:
                raise DataError(table.path, f"not a number: {cells[i][:40]!r}", row=int(row), column=name) from None


def _clock_seconds(path: Path, cells: list[list[str]], i: int, name: str, numbers: np.ndarray) -> np.ndarray:
    """Seconds of clock stamps (since the epoch with a date, since midnight without)."""
    out = np.empty(len(cells))
    for k, row in enumerate(cells):
        match = _CLOCK.match(row[i]) if i < len(row) else None
        if match is None:
            raise DataError(path, f"not a clock stamp like the first row's: {(row[i] if i < len(row) else '')[:40]!r}",
                            row=int(numbers[k]), column=name)
        seconds = int(match["h"]) * 3600 + int(match["m"]) * 60 + float(match["s"])
        if match["date"]:
            seconds += float(np.datetime64(match["date"], "D").astype(np.int64)) * 86400.0
        if match["zone"] and match["zone"] != "Z":
            zone = match["zone"].replace(":", "")
            seconds -= (1 if zone[0] == "+" else -1) * (int(zone[1:3]) * 3600 + int(zone[3:5]) * 60)
        out[k] = seconds
    return out


# --------------------------------------------------------------------------------- MATLAB


def _open_mat(path: Path) -> SourceTable:
    """The numeric variables and struct fields of a MATLAB file (v4 to v7) as columns of one length."""
    import scipy.io
    with open(path, "rb") as f:
        head = f.read(128)
    if MAT_V73_MARK in head:
        raise _v73_error(path)
    try:
        variables = scipy.io.loadmat(path, simplify_cells=True)
    except NotImplementedError:  # scipy's message for an HDF5-based file
        raise _v73_error(path) from None
    except Exception as exc:  # noqa: BLE001 - scipy raises many types on a malformed file
        raise DataError(path, f"cannot read as a MATLAB .mat file ({type(exc).__name__}: {exc})") from None
    arrays: dict[str, np.ndarray] = {}
    dropped: dict[str, str] = {}
    for name, value in variables.items():
        if not name.startswith("__"):
            _flatten(name, value, arrays, dropped, depth=0)
    lengths = Counter(len(a) for a in arrays.values() if len(a) > 1)
    if not lengths:
        raise DataError(path, "holds no numeric vector or matrix with more than one sample (variables: "
                              f"{', '.join(n for n in variables if not n.startswith('__')) or 'none'})")
    n = lengths.most_common(1)[0][0]
    for name in [k for k, a in arrays.items() if len(a) != n]:
        dropped[name] = f"{len(arrays.pop(name))} values, the file's columns have {n}"
    return SourceTable(path, "mat", list(arrays), f"MATLAB file, {len(arrays)} columns of {n} samples",
                       arrays=arrays, dropped=dropped)


def _v73_error(path: Path) -> DataError:
    """The refusal of a MATLAB v7.3 (HDF5) file, with what to do instead."""
    return DataError(path, "is a MATLAB v7.3 file (HDF5), which scipy cannot read: re-save it in MATLAB with "
                           "save(FILE, VARIABLES, '-v7') or export a CSV (writetable / writematrix)")


def _flatten(name: str, value, arrays: dict[str, np.ndarray], dropped: dict[str, str], depth: int) -> None:
    """Add the columns of one variable or struct field (structs recursively, dotted names)."""
    if isinstance(value, dict) and depth < 4:
        for key, inner in value.items():
            _flatten(f"{name}.{key}", inner, arrays, dropped, depth + 1)
        return
    array = np.asarray(value) if isinstance(value, (np.ndarray, int, float)) else None
    if array is None or array.dtype.kind not in "biuf":
        dropped[name] = f"not a numeric array ({type(value).__name__})"
        return
    if array.size == 1:
        dropped[name] = f"a single value, {float(array.ravel()[0]):g}"
        return
    if array.ndim <= 1:
        arrays[name] = np.atleast_1d(array).astype(np.float64)
    elif array.ndim == 2:
        matrix = array.T if array.shape[0] < array.shape[1] else array  # samples along the longer side
        for k in range(matrix.shape[1]):
            arrays[f"{name}(:,{k + 1})"] = matrix[:, k].astype(np.float64)
    else:
        dropped[name] = f"a {array.ndim}-dimensional array"
