"""Which imu-csv/1 column a user's column is, from its name, and the unit its name carries.

A name is split into words (camelCase, spaces, '_', '-', '.', '/'), filler words such as 'raw' or
'imu' are dropped and the rest joined: 'Gyroscope X (deg/s)', 'gyro_x', 'GyroX', 'gx' and
'imu.gyr(:,1)' (column 1 of a MATLAB matrix) all become 'gyroscopex' / 'gyrox' / 'gx', which
the tables below map to gyr_x. A unit in brackets at the end — '(deg/s)', '[g]', '{uT}' — or as
the last word — 'acc_x_g', 'time_ms' — is returned with it. Recognition never guesses a unit.
"""
from __future__ import annotations

import re

from contract.errors import ImuFusionError
from training.data import units
from training.data.dataset import AXES, TRIADS, triad_columns

#: triad -> the words that name it before the axis letter ('gyro' + 'x').
TRIAD_WORDS = {
    "gyr": ("gyr", "gyro", "gyros", "gyroscope", "angularrate", "angularvelocity", "angvel", "omega", "w", "g"),
    "acc": ("acc", "accel", "accelerometer", "acceleration", "a"),
    "mag": ("mag", "magn", "magnetometer", "magnetic", "magneticfield", "compass", "m", "b"),
}
#: Names of a time column (joined words).
TIME_WORDS = ("t", "time", "times", "timestamp", "timestamps", "ts", "elapsed", "elapsedtime", "clock",
              "datetime", "epoch", "seconds", "sec")
#: Names of a sample counter: a time column in units of samples (t = (n - n[0]) / rate).
COUNTER_WORDS = ("n", "nsamples", "sample", "samples", "sampleindex", "samplenumber", "samplecount",
                 "index", "idx", "counter", "count", "packet", "packetcount", "packetnumber", "frame", "seq",
                 "sequence")
#: Names of a temperature column.
TEMP_WORDS = ("temp", "temperature", "tmp", "imutemp", "imutemperature", "sensortemp", "sensortemperature",
              "dietemp", "dietemperature", "thermometer")
#: Words that do not change what a column is ('raw gyro x', 'IMU.acc.x', 'data.mag').
FILLER_WORDS = ("raw", "imu", "sensor", "data", "meas", "measured", "uncalibrated", "uncal", "value", "values")
#: imu-csv/1 columns an import may write, and the groups a --columns entry may name.
TARGETS = ("t", *(c for p in TRIADS for c in triad_columns(p)), "temp")
AUX_PREFIX = "aux_"
_MATRIX_COLUMN = re.compile(r"^(?P<base>.*)\(:,(?P<k>[123])\)$")
_BRACKET_UNIT = re.compile(r"^(?P<base>.*?)\s*[\(\[\{]\s*(?P<unit>[^\)\]\}]*?)\s*[\)\]\}]\s*$")
_CAMEL = re.compile(r"(?<=[a-z])(?=[A-Z])")
_QUANTITY = {**{c: c[:3] for p in TRIADS for c in triad_columns(p)}, "t": "t", "temp": "temp"}


def _lookup_table() -> dict[str, str]:
    """joined words -> imu-csv/1 column."""
    table = {w: "t" for w in (*TIME_WORDS, *COUNTER_WORDS)}
    table.update({w: "temp" for w in TEMP_WORDS})
    for triad, words in TRIAD_WORDS.items():
        for word in words:
            for axis in AXES:
                table[word + axis] = f"{triad}_{axis}"
    return table


_TABLE = _lookup_table()


def quantity_of(target: str) -> str | None:
    """'gyr_x' -> 'gyr', 't' -> 't', 'temp' -> 'temp', 'aux_motor' -> None (copied as it is)."""
    return _QUANTITY.get(target)


def _words(text: str) -> list[str]:
    """Lower-case words of a name: camelCase, spaces and punctuation split it."""
    return [w for w in re.split(r"[^0-9a-zµμ°]+", _CAMEL.sub(" ", text).lower()) if w]


def recognise(name: str) -> tuple[str | None, str | None]:
    """(imu-csv/1 column or None, unit text from the name or None) of a user's column name.
    A sample counter ('n_samples', 'index') is 't' with unit 'samples'."""
    text, unit = name.strip(), None
    matrix = _MATRIX_COLUMN.match(text)
    axis = AXES[int(matrix["k"]) - 1] if matrix else ""
    text = matrix["base"] if matrix else text
    bracket = _BRACKET_UNIT.match(text)
    if bracket and bracket["unit"]:
        text, unit = bracket["base"], bracket["unit"]
    words = [w for w in _words(text) if w not in FILLER_WORDS]
    target = None
    if unit is None and len(words) > 1:  # a unit as the last word: 'acc_x_g', 'time_s', 'time_ms'
        head = _TABLE.get("".join(words[:-1]) + axis)
        if head is not None and units.lookup(quantity_of(head), words[-1]) is not None:
            target, unit = head, words[-1]
    target = target or _TABLE.get("".join(words) + axis)
    if target == "t" and "".join(words) in COUNTER_WORDS and unit is None:
        unit = units.SAMPLES
    return target, unit


def matrix_base(name: str) -> str | None:
    """'gyro(:,2)' -> 'gyro' (a column of a MATLAB matrix), else None."""
    match = _MATRIX_COLUMN.match(name.strip())
    return match["base"] if match else None


def parse_columns_option(texts: list[str] | None, available: list[str]) -> dict[str, str]:
    """--columns 't=Time,gyr_x=GyroX,...' or the triad form 'gyr=GX,GY,GZ' (repeatable; for a MATLAB
    file 'gyr=gyro' names an N×3 matrix) -> {imu-csv/1 column: source column}; ImuFusionError naming
    the entry when a target or a source column is unknown."""
    out: dict[str, str] = {}
    for target, sources in _entries(texts):
        if target in TRIADS:
            if len(sources) == 1:
                sources = _matrix_columns(target, sources[0], available)
            if len(sources) != 3:
                raise ImuFusionError(f"--columns {target}={','.join(sources)}: a triad takes three columns "
                                     f"(x, y, z), e.g. {target}=X,Y,Z; or name each, {target}_x=X,...")
            pairs = zip(triad_columns(target), sources)
        elif target in TARGETS or (target.startswith(AUX_PREFIX) and len(target) > len(AUX_PREFIX)):
            if len(sources) != 1:
                raise ImuFusionError(f"--columns {target}={','.join(sources)}: {target} takes one column")
            pairs = [(target, sources[0])]
        else:
            raise ImuFusionError(f"--columns {target}=...: unknown target '{target}' (known: "
                                 f"{', '.join(TARGETS)}, gyr, acc, mag, aux_NAME)")
        for column, source in pairs:
            out[column] = find_column(source, available, f"--columns {column}={source}")
    return out


def _entries(texts: list[str] | None) -> list[tuple[str, list[str]]]:
    """(target, [source, ...]) of every 'TARGET=SOURCE[,SOURCE...]' entry: a comma-separated word
    without '=' continues the entry before it."""
    entries: list[tuple[str, list[str]]] = []
    for text in texts or []:
        for piece in text.split(","):
            target, sep, source = piece.partition("=")
            if sep:
                entries.append((target.strip().lower(), [source.strip()]))
            elif entries and piece.strip():
                entries[-1][1].append(piece.strip())
            elif piece.strip():
                raise ImuFusionError(f"--columns '{text}': expected TARGET=COLUMN entries, e.g. "
                                     "t=Time,gyr=GX,GY,GZ,acc_x=AccX")
    return entries


def _matrix_columns(triad: str, base: str, available: list[str]) -> list[str]:
    """The three columns 'base(:,1)'.. of a MATLAB N×3 matrix, else [base] (one column)."""
    names = [f"{base}(:,{k})" for k in (1, 2, 3)]
    return names if all(n in available for n in names) else [base]


def find_column(source: str, available: list[str], origin: str) -> str:
    """The column of `available` named `source` (exactly, else ignoring case and surrounding spaces);
    ImuFusionError naming `origin` and listing the columns when there is none or more than one."""
    if source in available:
        return source
    folded = [c for c in available if c.strip().lower() == source.strip().lower()]
    if len(folded) == 1:
        return folded[0]
    shown = ", ".join(f"'{c}'" for c in available[:30]) + (", …" if len(available) > 30 else "")
    problem = "matches more than one column" if folded else "no such column"
    raise ImuFusionError(f"{origin}: {problem}; the file's columns: {shown}")
