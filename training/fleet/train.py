"""`imufmu fleet train FLEET_DIR --out OUT [--workers K | --scheduler ADDRESS]`: one model per unit.

Every unit folder of FLEET_DIR (a folder with a `calibration/` sub-folder of recordings, as
`simulate-fleet` writes, or with recordings of its own) is trained by the function behind
`imufmu train` (training.train.train_to_folder) in one Dask task, into OUT/<unit>/: the same
model.json, calibration.ssv and calibration.md as `imufmu train <its recordings> --out OUT/<unit>` gives. A unit that
fails is recorded with its reason and the fleet goes on. Then OUT/fleet.json and OUT/fleet.md
describe the population (training.fleet.population).
"""
from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from contract.errors import DataError
from training.fleet.engine import dask_client, run_tasks
from training.data.outputs import OutputError, forget_previous_run

#: Recording file names `imufmu train` reads.
RECORDING_PATTERNS = ("*.csv", "*.csv.gz")
#: Sub-folder of a unit folder holding its calibration recordings (training.fleet.simulate).
CALIBRATION_DIR = "calibration"
#: What describes a whole `fleet train` run in OUT (removed when the next run starts: a run stopped
#: half-way leaves none, so a later `--prior` cannot trust a population it did not compute).
FLEET_SUMMARIES = ("fleet.json", "fleet.md", "units.json", "ImuFusion.fmu")
#: The fleet's one FMU: the generic FMU with every trained unit's calibration.ssv embedded, labelled by unit.
FLEET_FMU = FLEET_SUMMARIES[-1]


@dataclass(frozen=True)
class UnitResult:
    """What training one unit gave: its model file, or the one-line reason it failed, and the compass
    rows its ELM learnt from (training.train.elm_rows, for the fleet ELM; None without a magnetometer
    reference)."""

    unit: str
    model: str | None
    reason: str | None
    elm_rows: tuple | None = field(default=None, repr=False, compare=False)

    def summary(self, out_dir: Path) -> dict:
        """units.json entry; the model named relative to out_dir (the folder the listing is written in:
        the listing stays true when `imufmu fleet train` moves its output into place)."""
        model = self.model and os.path.relpath(Path(self.model).resolve(), Path(out_dir).resolve())
        return {"unit": self.unit, "model": model, "reason": self.reason}


def unit_recordings(folder: Path) -> list[Path]:
    """The calibration recordings of a unit folder: those in its calibration/ sub-folder when it
    has one, else its own, sorted by name."""
    where = folder / CALIBRATION_DIR if (folder / CALIBRATION_DIR).is_dir() else folder
    return sorted(p for pattern in RECORDING_PATTERNS for p in where.glob(pattern))


def _unreadable(entry: Path) -> str | None:
    """Why the entry of a fleet folder that looks like a unit (a link, or a folder) cannot be read as
    one, else None: a link that loops or points nowhere, or a folder that cannot be listed."""
    try:
        entry.resolve(strict=True)
        if entry.is_dir():
            next(iter(sorted(entry.iterdir())), None)
    except RuntimeError:
        return "a symbolic link loop"
    except FileNotFoundError:
        return "a broken symbolic link"
    except OSError as e:
        return f"cannot be read ({e.strerror or e})"
    return None


def unit_folders(fleet_dir: Path) -> tuple[list[Path], list[UnitResult]]:
    """(sub-folders of fleet_dir that hold recordings, sorted by name; failed results of the entries
    that look like units but cannot be read: link loops, broken links, folders that cannot be listed);
    DataError when there is neither."""
    if not fleet_dir.is_dir():
        raise DataError(fleet_dir, "fleet folder not found")
    units, unreadable = [], []
    for entry in sorted(fleet_dir.iterdir()):
        reason = _unreadable(entry) if entry.is_symlink() or entry.is_dir() else None
        if reason is not None:
            unreadable.append(UnitResult(entry.name, None, f"{entry}: {reason}"))
        elif entry.is_dir() and unit_recordings(entry):
            units.append(entry)
    if not units and not unreadable:
        raise DataError(fleet_dir, "no unit folder with recordings (*.csv, *.csv.gz, or a calibration/ "
                                   "sub-folder of them)")
    return units, unreadable


def train_unit(folder: Path, out_dir: Path, seed: int) -> UnitResult:
    """Train one unit into out_dir/<unit> as `imufmu train` does (in a folder beside it, moved into
    place when complete: training.data.outputs.replace_folder); any failure becomes its reason (one line),
    never an exception: one unit never stops the fleet, and leaves no model of an earlier run."""
    from contract.errors import one_line
    from training.data.outputs import replace_folder
    from training.train import elm_rows, train_to_folder
    target = out_dir / folder.name
    try:
        done = replace_folder(target, lambda where: train_to_folder(unit_recordings(folder), where, seed=seed,
                                                                    progress=False, name=folder.name))
        return UnitResult(folder.name, str(target / done.model.name), None,
                          elm_rows(done.datasets, done.artefact.thermal, seed))
    except Exception as e:  # noqa: BLE001 - the reason is reported per unit, the fleet goes on
        return UnitResult(folder.name, None, one_line(f"{type(e).__name__}: {e}"))


def train_fleet(fleet_dir: str | Path, out_dir: str | Path, seed: int = 0, workers: int | None = None,
                scheduler: str | None = None, progress: bool = True) -> list[UnitResult]:
    """Train every unit folder of fleet_dir on Dask into out_dir; returns the results sorted by unit
    (an entry that cannot be read as a unit folder is a failed unit with its reason) and writes
    out_dir/units.json."""
    fleet_dir, out_dir = Path(fleet_dir), Path(out_dir)
    if out_dir.resolve() == fleet_dir.resolve():
        raise OutputError(f"{out_dir}: imufmu fleet train would write each unit's model over its input unit folder; "
                          "choose another --out")
    units, results = unit_folders(fleet_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    forget_previous_run(out_dir, FLEET_SUMMARIES, "units.json", [u.name for u in units] + [r.unit for r in results])
    if units:
        with dask_client(workers, scheduler) as client:
            results += [r for _, r in run_tasks(client, train_unit, units, "units", progress,
                                                out_dir=out_dir.resolve(), seed=seed)]
    results.sort(key=lambda r: r.unit)
    (out_dir / "units.json").write_text(json.dumps([r.summary(out_dir) for r in results], indent=1) + "\n")
    return results


def variant_label(unit: str) -> str:
    """The parameter-set label of a unit in the fleet FMU: its name, with every character a label cannot hold
    (fmu.references.LABEL) replaced by '_' and a leading one dropped."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", unit).lstrip("_.-")[:64] or "unit"


def write_fleet_fmu(results: list[UnitResult], out_dir: str | Path, fmi_version: int = 2) -> Path:
    """out_dir/FLEET_FMU: the generic FMU (training.fmu_build, prebuilt where no compiler is found) with the
    calibration.ssv of every trained unit embedded as the parameter set variant_label(unit)."""
    from fmu.calibration_file import FILE_NAME
    from training.fmu_build import build_fmu_from_model
    sets = {variant_label(r.unit): Path(r.model).parent / FILE_NAME for r in results if r.model}
    if len(sets) != sum(1 for r in results if r.model):
        raise DataError(out_dir, "two units' names give the same parameter-set label; rename one unit folder")
    return build_fmu_from_model(None, Path(out_dir) / FLEET_FMU, fmi_version=fmi_version, variants=sets)
