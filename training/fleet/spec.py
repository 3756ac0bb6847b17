"""Fleet files (TOML): a sensor unit type with its population spread, and the scenarios every unit
is recorded in.

    sensor = "../sensors/mems_grade.toml"   # the unit type; its [triad.spread] tables declare the spread
    [fleet]
    name = "mems_grade"
    calibration = ["calibration.toml"]     # scenario files (relative to this file): calibration recordings
    test = ["test_handheld.toml"]          # held-out test recordings with truth

The scenarios' own `sensor` lines are replaced by each drawn unit.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from contract.errors import ScenarioError
from training.simulator.population import spreads
from training.simulator.scenario import NAME_PATTERN, Scenario, load_scenario, read_toml
from training.simulator.toml_table import TomlTable


@dataclass(frozen=True)
class FleetSpec:
    """A validated fleet file: the unit type's sensor table (parsed TOML, with its spreads) and the
    calibration and test scenarios."""

    path: Path
    name: str
    sensor_path: Path
    sensor_raw: dict
    calibration: tuple[Scenario, ...]
    test: tuple[Scenario, ...]


def load_fleet(path: str | Path) -> FleetSpec:
    """Read and validate a fleet file; ScenarioError names the file and the key."""
    path = Path(path)
    top = TomlTable(read_toml(path), path, "top level")
    sensor_path = path.parent / top.string("sensor")
    head = top.table("fleet")
    name = head.string("name")
    if not NAME_PATTERN.match(name):
        raise head.fail("name", f"use only letters, digits, '_', '-', '.', got {name!r}")
    calibration = _scenarios(head, "calibration", path)
    test = _scenarios(head, "test", path)
    head.close()
    top.close()
    sensor_raw = read_toml(sensor_path)
    if not spreads(sensor_raw, sensor_path):
        raise ScenarioError(f"{sensor_path}: declares no [<triad>.spread] table: every unit of the fleet "
                            "would be the same sensor")
    names = [s.name for s in calibration + test]
    if len(set(names)) != len(names):
        raise head.fail("calibration", f"two scenarios have the same name ({', '.join(names)}): their "
                                       "recordings would overwrite one another")
    return FleetSpec(path, name, sensor_path, sensor_raw, calibration, test)


def _scenarios(head: TomlTable, key: str, path: Path) -> tuple[Scenario, ...]:
    """The scenario files listed under `key`, loaded (paths relative to the fleet file)."""
    files = head.strings(key)
    return tuple(load_scenario(path.parent / f) for f in files)
