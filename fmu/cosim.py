"""Co-simulate the ImuFusion FMU with fmpy's FMU2Slave, one communication step per sample."""
from __future__ import annotations

import ctypes
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Real, fmi2ValueReference)
from fmpy.logging import addLoggerProxy  # formats the logger's variadic message natively
from tqdm import tqdm

from fmu.variables import by_name
from training.errors import ImuFusionError
from training.layout import INPUTS, OUTPUTS

_STATUS = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")


class FmuError(ImuFusionError):
    """An FMI call failed; the message carries the call and the FMU's log messages."""


class _Log:
    """Collects the FMU's log messages through an fmi2 logger callback."""

    def __init__(self) -> None:
        self.messages: list[str] = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(ctypes.byref(self.callbacks))

    def _log(self, environment, instance_name: bytes, status: int, category: bytes, message: bytes) -> None:
        """fmi2CallbackLogger: remember '[STATUS] category: message'."""
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        self.messages.append(f"[{label}] {category.decode(errors='replace')}: {message.decode(errors='replace')}")

    def error(self, what: str) -> FmuError:
        """An FmuError for `what`, with every message logged so far."""
        log = "\n".join(self.messages) if self.messages else "(the FMU logged nothing)"
        return FmuError(f"{what}\nFMU log:\n{log}")


def _check_arrays(t: np.ndarray, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t as (N,) strictly increasing float64, inputs as (N, 10) float64; FmuError otherwise."""
    t = np.asarray(t, dtype=float)
    inputs = np.asarray(inputs, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise FmuError(f"t must be a non-empty 1-D array, got shape {t.shape}")
    if inputs.shape != (t.size, len(INPUTS)):
        raise FmuError(f"inputs must have shape ({t.size}, {len(INPUTS)}), got {inputs.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise FmuError("t must be finite and strictly increasing")
    return t, inputs


def step_sizes(t: np.ndarray, default: float) -> np.ndarray:
    """(N,) communication step sizes [s]: time to the next sample; the last repeats the previous
    one (`default` when there is a single sample)."""
    if t.size == 1:
        return np.array([default])
    h = np.diff(t)
    return np.append(h, h[-1])


def _set_parameters(fmu: FMU2Slave, parameters: dict) -> None:
    """Set parameters by name (Real or Boolean); FmuError for names that are not parameters."""
    for name, value in parameters.items():
        try:
            variable = by_name(name)
        except KeyError as e:
            raise FmuError(str(e.args[0])) from e
        if variable.causality != "parameter":
            raise FmuError(f"'{name}' is an {variable.causality}, not a parameter")
        if variable.type == "Boolean":
            fmu.setBoolean([variable.value_reference], [bool(value)])
        else:
            fmu.setReal([variable.value_reference], [float(value)])


def step_samples(fmu: FMU2Slave, t: np.ndarray, inputs: np.ndarray, h: np.ndarray,
                 progress: bool = False) -> np.ndarray:
    """Per sample k: set inputs[k], doStep(t[k], h[k]), get the outputs; returns (N, 20).

    fmu: an initialised FMU (see `initialised_fmu`); t, h: (N,) [s]; inputs: (N, 10).
    """
    n_in, n_out = len(INPUTS), len(OUTPUTS)
    vr_in = (fmi2ValueReference * n_in)(*(by_name(n).value_reference for n in INPUTS))
    vr_out = (fmi2ValueReference * n_out)(*(by_name(n).value_reference for n in OUTPUTS))
    values_in = (fmi2Real * n_in)()
    values_out = (fmi2Real * n_out)()
    result = np.empty((len(t), n_out))
    for k in tqdm(range(len(t)), desc="co-simulation", unit="sample", disable=not progress):
        values_in[:] = [float(v) for v in inputs[k]]
        fmu.fmi2SetReal(fmu.component, vr_in, n_in, values_in)
        fmu.fmi2DoStep(fmu.component, float(t[k]), float(h[k]), 1)
        fmu.fmi2GetReal(fmu.component, vr_out, n_out, values_out)
        result[k] = values_out[:]
    return result


@contextmanager
def initialised_fmu(fmu_path: str | Path, start_time: float = 0.0,
                    parameters: dict | None = None) -> Iterator[FMU2Slave]:
    """Extract and instantiate the FMU, set up the experiment at start_time [s], set the
    parameters by name, initialise, and yield the FMU2Slave ready for doStep; terminate, free
    and clean up afterwards. Every failing FMI call inside the block becomes an FmuError that
    carries the FMU's log messages.
    """
    description = read_model_description(str(fmu_path))
    unzipdir = extract(str(fmu_path))
    log = _Log()
    fmu = None
    try:
        fmu = FMU2Slave(guid=description.guid, unzipDirectory=unzipdir,
                        modelIdentifier=description.coSimulation.modelIdentifier, instanceName="ImuFusion")
        try:
            fmu.instantiate(callbacks=log.callbacks)
        except Exception as e:
            fmu.freeLibrary()
            fmu = None
            raise log.error(f"fmi2Instantiate failed: {e}") from e
        try:
            fmu.setupExperiment(startTime=float(start_time))
            _set_parameters(fmu, parameters or {})
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            yield fmu
            fmu.terminate()
        except FMICallException as e:
            raise log.error(str(e)) from e
    finally:
        if fmu is not None:
            fmu.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)


def run_fmu(fmu_path: str | Path, t: np.ndarray, inputs: np.ndarray, parameters: dict | None = None,
            progress: bool = False) -> np.ndarray:
    """Run the FMU over a recording and return its outputs.

    t: (N,) sample times [s], strictly increasing (steps may vary); inputs: (N, 10) raw samples in
    training.layout.INPUTS order (rad/s, m/s², µT, °C; NaN allowed); parameters: start values by
    name. Each sample is set, then doStep(t_k, t_{k+1} - t_k) consumes it (the last step repeats
    the previous step size). Returns (N, 20) outputs in training.layout.OUTPUTS order; row k is the
    estimate for sample k. Raises FmuError carrying the FMU's log when an FMI call fails.
    """
    t, inputs = _check_arrays(t, inputs)
    experiment = read_model_description(str(fmu_path)).defaultExperiment
    h = step_sizes(t, experiment.stepSize if experiment is not None and experiment.stepSize else 1.0)
    with initialised_fmu(fmu_path, float(t[0]), parameters) as fmu:
        return step_samples(fmu, t, inputs, h, progress)
