"""Co-simulate the ImuFusion FMU (FMI 2.0 or 3.0) with fmpy, one communication step per sample."""
from __future__ import annotations

import ctypes
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2ValueReference
from fmpy.fmi3 import FMU3Slave, fmi3Boolean, fmi3Float64, fmi3ValueReference
from tqdm import tqdm

from fmu.archive import extract_archive, extracted_binary, read_description
from fmu.fmi2_logger import callbacks_for, release
from contract import coefficient_parameters
from contract.sensor_variables import MODEL_NAME as SENSOR_MODEL_NAME, SENSOR_VARIABLES
from contract.variables import by_name
from contract.errors import ImuFusionError, one_line
from contract.layout import INPUTS, OUTPUTS
from contract.schema import check_setting
from fmu.model_description import MODEL_NAME

_STATUS = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")

#: fmi2Status / fmi3Status values that doStep may return without failing.
OK, WARNING, DISCARD = 0, 1, 2


#: An FmuError's message quotes at most this many of the FMU's last log messages (all are in .log).
LOG_MESSAGES_QUOTED = 3


class FmuError(ImuFusionError):
    """An FMI call failed; the one-line message carries the call and the FMU's last log messages,
    `log` all of them."""

    def __init__(self, message: str, log: list[str] | None = None):
        super().__init__(message)
        self.log = list(log or [])


class _Log:
    """Collects the FMU's log messages through an fmi2 logger or an fmi3 logMessage callback."""

    def __init__(self) -> None:
        self.messages: list[str] = []
        self.callbacks, self._key = callbacks_for(self.log3)

    def close(self) -> None:
        """Stop receiving messages (after the FMU instance is freed)."""
        release(self._key)

    def log3(self, environment, status: int, category: bytes, message: bytes) -> None:
        """fmi3LogMessageCallback: remember '[STATUS] category: message'."""
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        self.messages.append(f"[{label}] {category.decode(errors='replace')}: {message.decode(errors='replace')}")

    def error(self, what: str) -> FmuError:
        """A one-line FmuError for `what` quoting the last LOG_MESSAGES_QUOTED messages logged so far
        (all of them in its `log`)."""
        quoted = self.messages[-LOG_MESSAGES_QUOTED:]
        earlier = len(self.messages) - len(quoted)
        log = " | ".join(one_line(m) for m in quoted) if quoted else "(the FMU logged nothing)"
        more = f" ({earlier} earlier messages)" if earlier else ""
        return FmuError(f"{one_line(what)}; FMU log{more}: {log}", self.messages)


def value_reference(fmu: FMU2Slave | FMU3Slave, name: str) -> int:
    """The value reference that the FMU's own modelDescription.xml declares for variable `name`
    (`initialised_fmu` attaches the map); FmuError when it declares no such variable. Inputs and
    parameters are set and outputs read by these, never by our variable table, so that a model
    description that does not match the binary makes the reference result differ."""
    try:
        return fmu.value_references[name]
    except KeyError:
        raise FmuError(f"the FMU's model description declares no variable '{name}'") from None


class Stepper:
    """Raw per-sample FMI calls on an initialised FMU2Slave or FMU3Slave: set the inputs,
    doStep, get the outputs (the ImuFusion FMU's contract.layout INPUTS / OUTPUTS order, or the
    names given, by the value references of the FMU's model description)."""

    def __init__(self, fmu: FMU2Slave | FMU3Slave, inputs: Sequence[str] = INPUTS,
                 outputs: Sequence[str] = OUTPUTS) -> None:
        self.fmu = fmu
        self.fmi3 = isinstance(fmu, FMU3Slave)
        real, vr = (fmi3Float64, fmi3ValueReference) if self.fmi3 else (fmi2Real, fmi2ValueReference)
        self.n_in, self.n_out = len(inputs), len(outputs)
        self.vr_in = (vr * self.n_in)(*(value_reference(fmu, n) for n in inputs))
        self.vr_out = (vr * self.n_out)(*(value_reference(fmu, n) for n in outputs))
        self.values_in = (real * self.n_in)()
        self.values_out = (real * self.n_out)()
        self._flags = [fmi3Boolean() for _ in range(3)]
        self._last_time = fmi3Float64()

    def set_inputs(self, values) -> None:
        """Set the raw inputs: (len(INPUTS),) rad/s, m/s², µT, °C, auxiliary inputs (NaN and Inf
        are passed as they are)."""
        self.values_in[:] = [float(v) for v in values]
        n = self.n_in
        if self.fmi3:
            self.fmu.fmi3SetFloat64(self.fmu.component, self.vr_in, n, self.values_in, n)
        else:
            self.fmu.fmi2SetReal(self.fmu.component, self.vr_in, n, self.values_in)

    def do_step(self, t: float, h: float) -> int:
        """doStep(t, h); returns OK, WARNING or DISCARD; FMICallException for Error and worse."""
        try:
            if self.fmi3:
                return self.fmu.fmi3DoStep(self.fmu.component, float(t), float(h), fmi3Boolean(True),
                                           *(ctypes.byref(f) for f in self._flags), ctypes.byref(self._last_time))
            return self.fmu.fmi2DoStep(self.fmu.component, float(t), float(h), 1)
        except FMICallException as e:
            if e.status == DISCARD:
                return DISCARD
            raise

    def get_outputs(self) -> np.ndarray:
        """(len(OUTPUTS),) current outputs."""
        n = self.n_out
        if self.fmi3:
            self.fmu.fmi3GetFloat64(self.fmu.component, self.vr_out, n, self.values_out, n)
        else:
            self.fmu.fmi2GetReal(self.fmu.component, self.vr_out, n, self.values_out)
        return np.array(self.values_out[:])


def _check_arrays(t: np.ndarray, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t as (N,) strictly increasing float64, inputs as (N, len(INPUTS)) float64; FmuError otherwise."""
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


def description_step_sizes(description, t: np.ndarray) -> np.ndarray:
    """(N,) communication step sizes [s] that run_fmu uses for the sample times t [s]: `step_sizes`
    with, for a single sample, the default experiment's step size of the FMU's model description
    `description` (fmpy ModelDescription; 1 s when it declares none)."""
    experiment = description.defaultExperiment
    return step_sizes(t, experiment.stepSize if experiment is not None and experiment.stepSize else 1.0)


def _set_parameters(fmu: FMU2Slave | FMU3Slave, parameters: dict) -> None:
    """Set parameters by name (Real, Integer or Boolean) at the value references of the FMU's model
    description; FmuError for names that are not parameters."""
    fmi3 = isinstance(fmu, FMU3Slave)
    for name, value in parameters.items():
        try:
            variable = by_name(name) if fmu.model_identifier == MODEL_NAME else fmu.table[name]
        except KeyError as e:
            raise FmuError(f"{fmu.model_identifier}: unknown parameter {e.args[0]!r}") from e
        if variable.causality != "parameter":
            raise FmuError(f"'{name}' is an {variable.causality}, not a parameter")
        if variable.type != "Real" and value != int(value):  # bool(0.5) or int(2.9) would pass the FMU a different value
            raise FmuError(f"{name} must be a whole number, got {value!r}")
        if fmu.model_identifier == MODEL_NAME and variable.type != "Real":
            try:
                value = check_setting(name, value)
            except ValueError as e:
                raise FmuError(str(e)) from None
        vr = [value_reference(fmu, name)]
        if variable.type == "Boolean":
            fmu.setBoolean(vr, [bool(value)])
        elif variable.type == "Integer":
            (fmu.setInt32 if fmi3 else fmu.setInteger)(vr, [int(value)])
        else:
            (fmu.setFloat64 if fmi3 else fmu.setReal)(vr, [float(value)])


def _set_coefficients(fmu: FMU2Slave | FMU3Slave, coefficients) -> None:
    """Set the coefficient parameters (contract/coefficient_parameters.py: FMI 3 one array per block, FMI 2
    one scalar per coefficient) from a whole coefficient array, at the value references of the FMU's model
    description; FmuError for an array of another length or an FMU without them."""
    fmi3 = isinstance(fmu, FMU3Slave)
    try:
        values = coefficient_parameters.parameter_values(coefficients, 3 if fmi3 else 2)
    except ValueError as e:
        raise FmuError(f"calibration: {e}") from None
    missing = [name for name in values if name not in fmu.value_references]
    if missing:
        raise FmuError(f"the FMU has no coefficient parameters ({missing[0]}, ...): it was built before they "
                       "existed; rebuild it with imufmu build-fmu")
    # either version's parameters, in order, carry the whole array in its own order (contract/coefficient_parameters.py)
    (fmu.setFloat64 if fmi3 else fmu.setReal)([fmu.value_references[name] for name in values],
                                              np.asarray(coefficients, dtype=float).tolist())


def step_samples(fmu: FMU2Slave | FMU3Slave, t: np.ndarray, inputs: np.ndarray, h: np.ndarray,
                 progress: bool = False, statuses: list[int] | None = None) -> np.ndarray:
    """Per sample k: set inputs[k], doStep(t[k], h[k]), get the outputs; returns (N, len(OUTPUTS)).

    fmu: an initialised FMU (see `initialised_fmu`); t, h: (N,) [s]; inputs: (N, len(INPUTS)). The doStep
    status of each sample (OK, WARNING or DISCARD) is appended to `statuses` when given.
    """
    stepper = Stepper(fmu)
    result = np.empty((len(t), len(OUTPUTS)))
    for k in tqdm(range(len(t)), desc="co-simulation", unit="sample", disable=not progress):
        stepper.set_inputs(inputs[k])
        status = stepper.do_step(t[k], h[k])
        if statuses is not None:
            statuses.append(status)
        result[k] = stepper.get_outputs()
    return result


def _instantiate(fmu_path: str | Path, unzipdir: str, log: _Log, instance_name: str) -> FMU2Slave | FMU3Slave:
    """Load the binary and instantiate an FMU2Slave or FMU3Slave whose `value_references` maps
    every variable name of its model description to its value reference; FmuError with the log on
    failure."""
    description = read_description(fmu_path, unzipdir)
    library = extracted_binary(fmu_path, unzipdir, description)
    cls = FMU3Slave if description.fmiVersion.startswith("3") else FMU2Slave
    try:
        fmu = cls(guid=description.guid, unzipDirectory=unzipdir, libraryPath=str(library),
                  modelIdentifier=description.coSimulation.modelIdentifier, instanceName=instance_name)
    except Exception as e:  # fmpy raises bare Exception, ctypes OSError for a binary that does not load
        raise FmuError(f"{fmu_path}: cannot load the FMU's binary ({one_line(str(e))})") from None
    fmu.value_references = {v.name: v.valueReference for v in description.modelVariables}
    fmu.model_identifier = description.coSimulation.modelIdentifier
    fmu.table = {v.name: v for v in SENSOR_VARIABLES} if fmu.model_identifier == SENSOR_MODEL_NAME else {}
    try:
        if cls is FMU3Slave:
            fmu.instantiate(logMessage=log.log3)
        else:
            fmu.instantiate(callbacks=log.callbacks)
    except Exception as e:
        fmu.freeLibrary()
        raise log.error(f"{fmu_path}: instantiation failed: {e}") from e
    return fmu


def _initialise(fmu: FMU2Slave | FMU3Slave, start_time: float, parameters: dict, coefficients=None) -> None:
    """Start the experiment at start_time [s], set the parameters by name (and, when given, the coefficient
    parameters from a whole coefficient array) and initialise."""
    if not isinstance(fmu, FMU3Slave):
        fmu.setupExperiment(startTime=float(start_time))
    _set_parameters(fmu, parameters)
    if coefficients is not None:
        _set_coefficients(fmu, coefficients)
    if isinstance(fmu, FMU3Slave):
        fmu.enterInitializationMode(startTime=float(start_time))
    else:
        fmu.enterInitializationMode()
    fmu.exitInitializationMode()


@contextmanager
def fmu_runner(fmu_path: str | Path, instance_name: str = "ImuFusion") -> Iterator[Callable]:
    """Extract and instantiate the FMU once and yield run(t, inputs, parameters, coefficients) -> outputs, which
    co-simulates one recording as `run_fmu` does (coefficients: a unit's whole coefficient array, set as the
    coefficient parameters, or None for the FMU's own); every run after the first resets the instance
    (fmi2Reset / fmi3Reset: every variable back to its start value) instead of instantiating
    again, as fmpy's parameter-variation example does. FmuError with the FMU's log on failure."""
    unzipdir = tempfile.mkdtemp(prefix="imufusion-fmu-")
    log = _Log()
    fmu = None
    try:
        extract_archive(fmu_path, unzipdir)
        description = read_description(fmu_path, unzipdir)
        fmu = _instantiate(fmu_path, unzipdir, log, instance_name)
        runs = 0

        def run(t: np.ndarray, inputs: np.ndarray, parameters: dict | None = None, coefficients=None) -> np.ndarray:
            nonlocal runs
            t, inputs = _check_arrays(t, inputs)
            try:
                if runs:
                    fmu.reset()
                runs += 1
                _initialise(fmu, float(t[0]), parameters or {}, coefficients)
                return step_samples(fmu, t, inputs, description_step_sizes(description, t))
            except FMICallException as e:
                raise log.error(f"{fmu_path}: {e}") from e
        yield run
    finally:
        if fmu is not None:
            fmu.freeInstance()
        log.close()
        shutil.rmtree(unzipdir, ignore_errors=True)


@contextmanager
def initialised_fmu(fmu_path: str | Path, start_time: float = 0.0, parameters: dict | None = None,
                    instance_name: str = "ImuFusion", coefficients=None) -> Iterator[FMU2Slave | FMU3Slave]:
    """Extract and instantiate the FMU (FMI 2 or 3), start the experiment at start_time [s], set
    the parameters by name (and the coefficient parameters from `coefficients`, a whole coefficient array,
    when given), initialise, and yield the FMU2Slave / FMU3Slave ready for doStep;
    its `log_messages` list collects the FMU's log ('[STATUS] category: message') and its
    `value_references` maps the names of its model description to their value references. Terminate,
    free and clean up afterwards. Every failing FMI call inside the block becomes an FmuError
    that carries the FMU's log messages.
    """
    unzipdir = tempfile.mkdtemp(prefix="imufusion-fmu-")
    log = _Log()
    fmu = None
    try:
        extract_archive(fmu_path, unzipdir)
        fmu = _instantiate(fmu_path, unzipdir, log, instance_name)
        fmu.log_messages = log.messages
        try:
            _initialise(fmu, start_time, parameters or {}, coefficients)
            yield fmu
            fmu.terminate()
        except FMICallException as e:
            raise log.error(f"{fmu_path}: {e}") from e
    finally:
        if fmu is not None:
            fmu.freeInstance()
        log.close()
        shutil.rmtree(unzipdir, ignore_errors=True)


def run_fmu(fmu_path: str | Path, t: np.ndarray, inputs: np.ndarray, parameters: dict | None = None,
            progress: bool = False, log: list[str] | None = None, coefficients=None) -> np.ndarray:
    """Run the FMU (FMI 2 or 3) over a recording and return its outputs.

    t: (N,) sample times [s], strictly increasing (steps may vary); inputs: (N, len(INPUTS)) raw
    samples in contract.layout.INPUTS order (rad/s, m/s², µT, °C, auxiliary inputs; NaN allowed;
    ImuData.inputs(aux_columns=fmu.packer.fmu_aux_columns(fmu_path))); parameters: start values by
    name. Each sample is set, then doStep(t_k, t_{k+1} - t_k) consumes it (the last step repeats
    the previous step size). Returns (N, len(OUTPUTS)) outputs in contract.layout.OUTPUTS order; row k is the
    estimate for sample k. Raises FmuError carrying the FMU's log when an FMI call fails. When `log`
    is a list, the FMU's log messages ('[STATUS] category: message') are appended to it. `coefficients`: a
    whole coefficient array (contract/layout.py) set as the coefficient parameters before initialisation (a
    calibration for the FMU's own compiled-in one).
    """
    t, inputs = _check_arrays(t, inputs)
    h = description_step_sizes(read_description(fmu_path), t)
    with initialised_fmu(fmu_path, float(t[0]), parameters, coefficients=coefficients) as fmu:
        out = step_samples(fmu, t, inputs, h, progress)
        if log is not None:
            log.extend(fmu.log_messages)
        return out


def run_named(fmu_path: str | Path, t: np.ndarray, inputs: dict[str, np.ndarray], outputs: Sequence[str],
              parameters: dict | None = None) -> np.ndarray:
    """Run any FMU of this tree (the virtual sensor, say) over samples t [s]: inputs by name ((N,) each), set
    before each doStep(t_k, t_{k+1} - t_k); returns (N, len(outputs)), row k after the step of sample k."""
    names = list(inputs)
    values = np.column_stack([np.asarray(inputs[n], dtype=float) for n in names])
    t = np.asarray(t, dtype=float)
    h = description_step_sizes(read_description(fmu_path), t)
    with initialised_fmu(fmu_path, float(t[0]), parameters) as fmu:
        stepper = Stepper(fmu, names, outputs)
        result = np.empty((t.size, len(outputs)))
        for k in range(t.size):
            stepper.set_inputs(values[k])
            stepper.do_step(t[k], h[k])
            result[k] = stepper.get_outputs()
        return result
