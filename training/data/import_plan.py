"""The plan of an import: which imu-csv/1 column each of a user's columns becomes, and with which unit
conversion. --columns entries first, then the columns' names (training.data.column_names), then a
known format's header (training.data.known_formats); units from --units, else the header, else the
known format — a quantity without any is refused, naming its columns and the option that gives it."""
from __future__ import annotations

from dataclasses import dataclass

from contract.errors import DataError
from training.data import units as u
from training.data.column_names import parse_columns_option, quantity_of, recognise
from training.data.dataset import TRIADS, triad_columns
from training.data.known_formats import KnownFormat, known_format
from training.data.source_table import SourceTable


@dataclass
class Plan:
    """How the file becomes imu-csv/1: target column -> source column, target -> Conversion (none for
    aux_*), the columns left out, the known format, and notes for the summary."""

    mapping: dict[str, str]
    conversions: dict[str, u.Conversion]
    dropped: list[str]
    fmt: KnownFormat | None
    notes: list[str]


def make_plan(table: SourceTable, columns: list[str], units: list[str]) -> Plan:
    """Map the table's columns to imu-csv/1 columns (`columns`: the --columns texts) and find each one's
    unit conversion (`units`: the --units texts)."""
    fmt = known_format(table.names)
    mapping = parse_columns_option(columns, table.names)
    notes = [f"recognised the {fmt.name} format by its header"] if fmt else []
    _recognise_rest(table, mapping)
    _check_triads(table, mapping)
    conversions = _conversions(table, mapping, u.parse_units_option(units), fmt, notes)
    used = set(mapping.values())
    dropped = [n for n in table.names if n not in used]
    dropped += [f"{n} ({why})" for n, why in table.dropped.items()]
    return Plan(mapping, conversions, dropped, fmt, notes)


def _recognise_rest(table: SourceTable, mapping: dict[str, str]) -> None:
    """Add the targets that --columns left open, recognised by the columns' names (a clock beats a
    counter for t); ImuFusionError when two columns claim one target."""
    used = set(mapping.values())
    found: dict[str, list[str]] = {}
    for name in table.names:
        target, _ = recognise(name)
        if target and name not in used and target not in mapping:
            found.setdefault(target, []).append(name)
    if len(found.get("t", [])) > 1:
        clocks = [n for n in found["t"] if recognise(n)[1] != u.SAMPLES]
        found["t"] = clocks or found["t"]
    for target, names in found.items():
        if len(names) > 1:
            listed = " and ".join(f"'{n}'" for n in names)
            raise DataError(table.path, f"columns {listed} both look like {target}: choose one with "
                                        f"--columns {target}=NAME")
        mapping[target] = names[0]


def _check_triads(table: SourceTable, mapping: dict[str, str]) -> None:
    """DataError when a triad has one or two of its axes, or when no triad was found at all."""
    for triad in TRIADS:
        have = [c for c in triad_columns(triad) if c in mapping]
        if 0 < len(have) < 3:
            missing = [c for c in triad_columns(triad) if c not in mapping]
            got = ", ".join(f"{c} <- '{mapping[c]}'" for c in have)
            raise DataError(table.path, f"{u.QUANTITY_NAME[triad]}: found {got} but no {' or '.join(missing)}; "
                                        f"name its columns with --columns {triad}=X,Y,Z")
    if not any(f"{triad}_x" in mapping for triad in TRIADS):
        shown = ", ".join(f"'{n}'" for n in table.names[:30])
        raise DataError(table.path, f"no column recognised as a gyroscope, accelerometer or magnetometer axis "
                                    f"(columns: {shown}); name them with --columns gyr=X,Y,Z,acc=X,Y,Z,mag=X,Y,Z")


def _conversions(table: SourceTable, mapping: dict[str, str], given: dict[str, u.Conversion],
                 fmt: KnownFormat | None, notes: list[str]) -> dict[str, u.Conversion]:
    """target -> Conversion: --units wins over the header, the header over a known format; a
    quantity without any is refused, naming it and the option that gives it."""
    out: dict[str, u.Conversion] = {}
    for target, source in mapping.items():
        quantity = quantity_of(target)
        if quantity is None:
            continue
        if target == "t" and source in table.clock_columns:  # the stamps carry their unit
            out[target] = u.Conversion("t", "clock stamps", 1.0)
            continue
        header_unit = recognise(source)[1]
        if quantity in given:
            out[target] = given[quantity]
            if header_unit and u.lookup(quantity, header_unit) != (given[quantity].scale, given[quantity].offset):
                notes.append(f"--units {quantity}={given[quantity].unit} overrides the header's '{header_unit}' "
                             f"of '{source}'")
        elif header_unit:
            out[target] = u.parse_unit(quantity, header_unit, f"{table.path}: column '{source}'")
        elif fmt and quantity in fmt.units:
            out[target] = u.parse_unit(quantity, fmt.units[quantity], fmt.name)
    lacking: dict[str, list[str]] = {}
    for target, source in mapping.items():
        if quantity_of(target) and target not in out:
            lacking.setdefault(quantity_of(target), []).append(source)
    if lacking:
        raise DataError(table.path, _missing_units(lacking))
    unused = [q for q in given if not any(quantity_of(t) == q for t in mapping)]
    if unused:
        notes.append(f"--units {', '.join(unused)} unused: the file has no such column")
    return out


def _missing_units(lacking: dict[str, list[str]]) -> str:
    """The message for quantities whose columns name no unit: which, and the --units that gives them."""
    example = {"gyr": "deg/s", "acc": "g", "mag": "uT", "t": "s", "temp": "C"}
    option = "--units " + ",".join(f"{q}={example[q]}" for q in lacking)
    if len(lacking) > 1:
        listed = "; ".join(f"{u.QUANTITY_NAME[q]} {', '.join(repr(s) for s in names)}" for q, names in lacking.items())
        return (f"no unit for {listed}: give the units the file holds with --units, e.g. {option.removeprefix('--units ')} (the units known: "
                "imufmu import --help), or name them in the header, e.g. 'GyroX (deg/s)'")
    (quantity, sources), = lacking.items()
    listed = ", ".join(f"'{s}'" for s in sources)
    return (f"{u.QUANTITY_NAME[quantity]} column{'s' if len(sources) > 1 else ''} {listed} carr"
            f"{'y' if len(sources) > 1 else 'ies'} no unit: give it with {option} "
            f"(known: {u.OFFERED[quantity]}; raw counts: {u.COUNTS_EXAMPLE[quantity]}), or name it in the "
            f"header, e.g. '{sources[0]} ({example[quantity]})'")
