"""One FMU for every unit (issue 32): switching the unit a running FMU simulates costs a reset and setting
its parameters, and the generic FMU with a unit's set gives that unit's compiled FMU's outputs bit for bit.

    python benchmarks/unit_switch.py [--fleet TRAINED_DIR | --units 200] [--compiled 3] [--repeats 3]

Units: with --fleet, every unit of an `imufmu fleet train` output (its calibration.ssv: coefficients and
settings; its own compiled FMU is `imufmu build-fmu --model` of its model.json). Without it, a model trained on
scenarios/variants/diag_calibration_clean.toml and UNITS - 1 more made from it by seeded perturbations of every
triad's gain matrix (±2 %) and bias (±5 % of its scale), as a fleet's units differ (a synthetic fleet: the
switch cost does not depend on the values). For each FMI version, one instance of the generic FMU (`imufmu
build-fmu` without a model) cycles through every unit REPEATS times: reset, set its coefficient parameters (from
the ctypes arrays an importer holds per unit, one fmi2SetReal / fmi3SetFloat64 call) and its settings (fmpy,
one call each), initialise (the runtime checks and unpacks the whole set) — timed per switch — then runs the
FMU's own 2 s reference input; the first COMPILED units are also built as their own FMUs and their outputs
compared bit for bit. Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import gc
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from contract import coefficient_parameters as cp  # noqa: E402
from contract.layout import OFFSET_THERMAL, TRIAD_BLOCK, TRIAD_ORDER, identity_coefficients  # noqa: E402
from fmpy.fmi2 import fmi2Real, fmi2ValueReference  # noqa: E402
from fmpy.fmi3 import FMU3Slave, fmi3Float64, fmi3ValueReference  # noqa: E402
from fmu.calibration_file import FILE_NAME, read_calibration  # noqa: E402
from fmu.cosim import Stepper, _set_parameters, initialised_fmu, run_fmu, step_sizes  # noqa: E402
from fmu.packer import reference_recording  # noqa: E402
from training.artefact import coefficients_array, settings_dict  # noqa: E402
from training.fmu_build import build_fmu, build_fmu_from_model  # noqa: E402
from training.main_job import SCENARIO_DIR  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.train import train  # noqa: E402

#: Spread of the synthetic units: gain matrix elements (relative) and bias coefficients (relative to their size).
GAIN_SPREAD, BIAS_SPREAD = 0.02, 0.05
#: Issue 32's bound on one switch.
SWITCH_BOUND_S = 1e-3


def units(base: np.ndarray, n: int, seed: int = 0) -> list[np.ndarray]:
    """The base coefficient array and n - 1 seeded perturbations of its thermal blocks (A and b)."""
    rng = np.random.default_rng(seed)
    out = [base]
    for _ in range(n - 1):
        unit = base.copy()
        for k in range(len(TRIAD_ORDER)):
            block = OFFSET_THERMAL + k * TRIAD_BLOCK
            unit[block + 4:block + 13] *= 1.0 + GAIN_SPREAD * rng.uniform(-1, 1, 9)
            b = slice(block + 13 + 9, block + TRIAD_BLOCK - 3)
            unit[b] *= 1.0 + BIAS_SPREAD * rng.uniform(-1, 1, unit[b].size)
        out.append(unit)
    return out


def _prepared(fmu, coefficients: np.ndarray, references: list[int]):
    """A unit's coefficient parameters as the ctypes arrays the FMI call takes (what an importer holds per unit):
    (value references, their number, values, their number)."""
    fmi3 = isinstance(fmu, FMU3Slave)
    flat = np.asarray(coefficients, dtype=float).tolist()  # the parameters carry the array in its order
    real = fmi3Float64 if fmi3 else fmi2Real
    reference = fmi3ValueReference if fmi3 else fmi2ValueReference
    return (reference * len(references))(*references), len(references), (real * len(flat))(*flat), len(flat)


def fleet_units(folder: Path) -> list[tuple[np.ndarray, dict, Path]]:
    """(coefficients, settings, model.json) of every unit folder of a fleet train output, in name order."""
    out = []
    for ssv in sorted(Path(folder).glob(f"*/{FILE_NAME}")):
        coefficients, settings, _ = read_calibration(ssv)
        out.append((coefficients, settings, ssv.parent / "model.json"))
    if not out:
        raise SystemExit(f"{folder}: no unit folder with a {FILE_NAME} (an `imufmu fleet train` output?)")
    return out


def synthetic_units(n: int) -> list[tuple[np.ndarray, dict, None]]:
    """(coefficients, settings, None) of the synthetic fleet: one trained model and n - 1 perturbations."""
    artefact = train([simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))], seed=0,
                     progress=False)
    settings = settings_dict(artefact)
    return [(unit, settings, None) for unit in units(np.asarray(coefficients_array(artefact)), n)]


def _compiled(unit: tuple, path: Path, fmi: int) -> Path:
    """The unit's own compiled FMU: build-fmu --model of its model.json, or its coefficients and settings."""
    coefficients, settings, model = unit
    if model is not None:
        return build_fmu_from_model(model, path, fmi_version=fmi)
    return build_fmu(coefficients, settings, path, fmi_version=fmi)


def _switch(fmu, prepared, settings: dict) -> None:
    """Reset the instance, set a unit's coefficients (prepared arrays) and settings, and initialise."""
    fmu.reset()
    vr, nvr, values, n = prepared
    if isinstance(fmu, FMU3Slave):
        _set_parameters(fmu, settings)
        fmu.fmi3SetFloat64(fmu.component, vr, nvr, values, n)
        fmu.enterInitializationMode(startTime=0.0)
    else:
        fmu.setupExperiment(startTime=0.0)
        _set_parameters(fmu, settings)
        fmu.fmi2SetReal(fmu.component, vr, nvr, values)
        fmu.enterInitializationMode()
    fmu.exitInitializationMode()


def _cycle(fmu_path: Path, sets: list[tuple], repeats: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """(seconds per switch, the outputs of the reference input per unit of the first cycle); sets: (coefficients,
    settings, …) per unit."""
    t, inputs = reference_recording()
    h = step_sizes(t, float(t[1] - t[0]))
    times, outputs = [], []
    with initialised_fmu(fmu_path) as fmu:
        fmi3 = isinstance(fmu, FMU3Slave)
        references = [fmu.value_references[name] for name in cp.parameter_values(sets[0][0], 3 if fmi3 else 2)]
        prepared = [(_prepared(fmu, coefficients, references), settings) for coefficients, settings, *_ in sets]
        stepper = Stepper(fmu)
        gc.disable()  # Python's collector pauses are the script's, not the FMU's
        for repeat in range(repeats):
            for unit, settings in prepared:
                start = time.perf_counter()
                _switch(fmu, unit, settings)
                times.append(time.perf_counter() - start)
                if repeat == 0:
                    rows = []
                    for k in range(len(t)):
                        stepper.set_inputs(inputs[k])
                        stepper.do_step(t[k], h[k])
                        rows.append(list(stepper.get_outputs()))
                    outputs.append(np.array(rows))
        gc.enable()
    return np.array(times), outputs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", type=int, default=200, help="synthetic units (without --fleet)")
    parser.add_argument("--fleet", type=Path, help="an `imufmu fleet train` output folder: its units")
    parser.add_argument("--compiled", type=int, default=3, help="units also built as their own FMU (bit equality)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    sets = fleet_units(args.fleet) if args.fleet else synthetic_units(args.units)
    t, inputs = reference_recording()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for fmi in (2, 3):
            generic = build_fmu(np.array(identity_coefficients()), {}, Path(tmp) / f"generic{fmi}.fmu", fmi_version=fmi)
            times, outputs = _cycle(generic, sets, args.repeats)
            equal, compiled = 0, min(args.compiled, len(sets))
            for k in tqdm(range(compiled), desc=f"compiled FMI {fmi} units", unit="unit", disable=compiled < 10):
                path = _compiled(sets[k], Path(tmp) / f"unit{k}_{fmi}.fmu", fmi)
                equal += int(np.array_equal(run_fmu(path, t, inputs), outputs[k]))
                path.unlink()
            rows.append((fmi, len(sets), len(times), 1e3 * np.median(times), 1e3 * np.percentile(times, 95),
                         1e3 * times.max(), equal, compiled))
    which = f"--fleet {args.fleet}" if args.fleet else f"--units {args.units}"
    print(f"`python benchmarks/unit_switch.py {which} --compiled {args.compiled} --repeats {args.repeats}`\n")
    print("| FMI | units | switches | median per switch, ms | 95th percentile, ms | largest, ms | "
          "units bit-equal to their compiled FMU |")
    print("|---|---|---|---|---|---|---|")
    for fmi, n, switches, median, p95, largest, equal, compiled in rows:
        print(f"| {fmi} | {n} | {switches} | {median:.3f} | {p95:.3f} | {largest:.3f} | {equal} of {compiled} |")
    under = all(r[4] < 1e3 * SWITCH_BOUND_S for r in rows)
    print(f"\n95th percentile of a switch {'under' if under else 'NOT under'} {1e3 * SWITCH_BOUND_S:g} ms; "
          f"every compiled unit bit-equal: {all(r[6] == r[7] for r in rows)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
