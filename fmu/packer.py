"""Assemble, compile and zip the ImuFusion FMU (FMI 2.0 or 3.0 co-simulation, sources + this
platform's binary + the win64 binary when the mingw-w64 cross compiler is installed).

Every FMU ships a reference result: extra/imufusion/reference_input.csv (a short built-in
recording) and reference_output.csv (the batch runtime's outputs for it, written at build time),
which tests and `fmu.validator` reproduce through the FMU, and extra/imufusion/aux_inputs.json:
which recording column each auxiliary input carries (the model's ModelArtefact.aux_inputs), so
that `imufmu run` feeds a recording's aux_* columns into the right inputs. The provenance record
(fmu.provenance: tool and version, build time, training recordings, calibrated triads and stages,
training notes) is extra/imufusion/provenance.json and is summarised in modelDescription.xml.
"""
from __future__ import annotations

import hashlib
import html
import json
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fmu.build_description import BUILD_DESCRIPTION, build_description_xml
from fmu.calibration_file import calibration_document
from fmu.compiler import (WIN64_COMPILER, WIN64_PACKAGE, check_fmi_version, compile_binary, compile_win64_binary,
                          fmu_source_files, win64_compiler)
from fmu.header import HEADER_NAME, coefficient_header
from fmu.model_description import MODEL_NAME, model_description_xml
from fmu.provenance import PROVENANCE_FILE, build_time, provenance_record, provenance_summary
from fmu.references import BASELINE, members as reference_members
from contract.variables import Variable, variable_table
from contract.errors import ModelError
from contract.layout import AUX_INPUTS, INPUTS, OUTPUTS, SETTINGS, settings_array

DEFAULT_DESCRIPTION = ("IMU calibration and attitude: temperature-compensated gyro, accelerometer and "
                       "magnetometer, adaptive-gain Euler-angle fusion")

#: Timestamp of every zip entry, so the same inputs give the same archive bytes.
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)

#: The reference input/output pair inside the FMU.
REFERENCE_INPUT = "extra/imufusion/reference_input.csv"
REFERENCE_OUTPUT = "extra/imufusion/reference_output.csv"
#: The model's auxiliary-input mapping inside the FMU (JSON list, ModelArtefact.aux_inputs).
AUX_INPUTS_FILE = "extra/imufusion/aux_inputs.json"

#: The built-in reference recording: 2 s at 100 Hz.
_REFERENCE_SAMPLES = 200
_REFERENCE_RATE_HZ = 100.0


def reference_recording() -> tuple[np.ndarray, np.ndarray]:
    """(t, inputs): the built-in reference recording, closed form (no random numbers).

    t: (200,) s at 100 Hz from 0; inputs: (200, len(INPUTS)) in contract.layout.INPUTS order — a
    sensor rocking in roll and pitch and turning in yaw, gravity and a 20/40 µT field rotated into
    the body frame, temperature rising from 20 to 30 °C, auxiliary input k = sin(k t) (unit-free).
    """
    t = np.arange(_REFERENCE_SAMPLES) / _REFERENCE_RATE_HZ
    roll, pitch, yaw = 0.3 * np.sin(1.3 * t), 0.2 * np.sin(0.9 * t + 0.5), 0.8 * t
    gyr = np.stack([0.39 * np.cos(1.3 * t), 0.18 * np.cos(0.9 * t + 0.5), np.full_like(t, 0.8)], axis=1)
    c, s = np.cos, np.sin
    zero, one = np.zeros_like(t), np.ones_like(t)
    rx = np.stack([one, zero, zero, zero, c(roll), -s(roll), zero, s(roll), c(roll)], axis=1).reshape(-1, 3, 3)
    ry = np.stack([c(pitch), zero, s(pitch), zero, one, zero, -s(pitch), zero, c(pitch)], axis=1).reshape(-1, 3, 3)
    rz = np.stack([c(yaw), -s(yaw), zero, s(yaw), c(yaw), zero, zero, zero, one], axis=1).reshape(-1, 3, 3)
    ned_to_body = np.transpose(rz @ ry @ rx, (0, 2, 1))  # (R_z R_y R_x)^T, R: body -> NED (ZYX)
    acc = ned_to_body @ np.array([0.0, 0.0, -9.80665])   # specific force at rest
    mag = ned_to_body @ np.array([20.0, 0.0, 40.0])      # µT, magnetic north and down
    temp = 20.0 + 5.0 * t
    aux = np.column_stack([np.sin(k * t) for k in range(1, len(AUX_INPUTS) + 1)])
    return t, np.column_stack([gyr, acc, mag, temp, aux])


def _csv_text(t: np.ndarray, values: np.ndarray, names: tuple[str, ...]) -> str:
    """CSV with header 't,<names>' and every value written so that it reads back exactly."""
    rows = [",".join(["t", *names])]
    rows += [",".join(repr(float(v)) for v in (tk, *row)) for tk, row in zip(t, values)]
    return "\n".join(rows) + "\n"


def reference_files(outputs: np.ndarray) -> dict[str, str]:
    """The reference pair by FMU path: the built-in recording (`reference_recording`) and
    `outputs`, (N, len(OUTPUTS)) what the model gives for it (row k = the estimate for sample k)."""
    t, inputs = reference_recording()
    outputs = np.asarray(outputs, dtype=float)
    if outputs.shape != (t.size, len(OUTPUTS)):
        raise ModelError(f"the reference outputs have shape {outputs.shape}, expected ({t.size}, {len(OUTPUTS)})")
    return {REFERENCE_INPUT: _csv_text(t, inputs, INPUTS), REFERENCE_OUTPUT: _csv_text(t, outputs, OUTPUTS)}


def read_reference_csv(text: str) -> tuple[tuple[str, ...], np.ndarray]:
    """(column names, (N, columns) array) of a reference CSV written by `reference_files`."""
    lines = text.strip().splitlines()
    return tuple(lines[0].split(",")), np.array([[float(v) for v in line.split(",")] for line in lines[1:]])


def _settings_dict(settings: dict) -> dict[str, float]:
    """Every setting by name (defaults filled in); ModelError for an unknown name."""
    try:
        values = settings_array(settings)
    except KeyError as e:
        raise ModelError(str(e.args[0])) from e
    return {name: value for (name, _), value in zip(SETTINGS, values)}


def model_guid(coefficients: np.ndarray, settings: dict[str, float], sources: list[Path],
               variables: tuple[Variable, ...]) -> str:
    """GUID = SHA-256 of coefficients, settings, variable table and FMU sources, as {8-4-4-4-12} hex."""
    digest = hashlib.sha256()
    digest.update(repr([float(v) for v in np.asarray(coefficients, dtype=float)]).encode())
    digest.update(repr(sorted(settings.items())).encode())
    digest.update(repr(variables).encode())
    for path in sources:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    h = digest.hexdigest()
    return "{" + f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}" + "}"


def _table_html(title: str, variables: tuple[Variable, ...], settings: dict[str, float]) -> str:
    """One HTML table of variables with their units and descriptions."""
    rows = []
    for v in variables:
        start = settings[v.name] if v.causality == "parameter" else v.start
        start_text = "" if start is None else html.escape(str(start))
        unit = html.escape(v.unit or "")
        if v.display_unit:
            unit += f" (display {html.escape(v.display_unit)})"
        rows.append(f"<tr><td><code>{v.name}</code></td><td>{unit}</td><td>{start_text}</td>"
                    f"<td>{html.escape(v.description)}</td></tr>")
    return (f"<h2>{title}</h2>\n<table>\n<tr><th>name</th><th>unit</th><th>start</th><th>description</th></tr>\n"
            + "\n".join(rows) + "\n</table>")


def documentation_html(settings: dict[str, float], description: str, fmi_version: int,
                       variables: tuple[Variable, ...]) -> str:
    """documentation/index.html: what the FMU is, its conventions, bad-input handling, the
    reference result and its variables (the model's `variable_table`) with units."""
    by_causality = {c: tuple(v for v in variables if v.causality == c) for c in ("input", "output", "parameter")}
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{MODEL_NAME}</title></head>
<body>
<h1>{MODEL_NAME}</h1>
<p>{html.escape(description)}.</p>
<p>FMI {fmi_version}.0 co-simulation FMU with C sources. Each <code>fmi{fmi_version}DoStep(t, h)</code> consumes the one raw
sample whose inputs were set before it; afterwards the outputs are the estimate for the sample at
<code>t</code>, and <code>h</code> is the time to the next sample (step sizes may vary).</p>
<p>Bad input (not finite, saturated or implausible sensor values, temperatures outside [-60, 125] &#176;C,
a step size that is not finite and positive) never produces NaN or Inf outputs: the FMU skips the
bad triad, holds its last valid estimate, returns a Warning (a Discard for a bad step size, which
consumes nothing) and logs one message per episode in the category <code>logBadInput</code>.
Invalid parameters make initialisation fail with an Error naming the parameter and its range.</p>
<p>Reference result: <code>{REFERENCE_INPUT}</code> is a short recording and <code>{REFERENCE_OUTPUT}</code>
the outputs this FMU must give for it (row k = estimate for sample k, default parameters).</p>
<p>Conventions: body axes are the sensor axes; the navigation frame is magnetic NED; the quaternion
[w, x, y, z] (Hamilton) rotates body to magnetic NED; Euler angles are ZYX (yaw, pitch, roll);
heading = yaw + declination is the true heading. Units: rad/s, m/s&#178;, &#181;T, &#176;C, s.</p>
{_table_html("Inputs", by_causality["input"], settings)}
{_table_html("Outputs", by_causality["output"], settings)}
{_table_html("Parameters", by_causality["parameter"], settings)}
</body>
</html>
"""


def _zip_directory(directory: Path, out_path: Path) -> None:
    """Zip `directory` into out_path with sorted entries and fixed timestamps (deterministic)."""
    files = sorted(p for p in directory.rglob("*") if p.is_file())
    with zipfile.ZipFile(out_path, "w") as zf:
        for path in files:
            info = zipfile.ZipInfo(path.relative_to(directory).as_posix(), date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = (0o755 if path.suffix == ".so" else 0o644) << 16
            zf.writestr(info, path.read_bytes())


def compile_binaries(stage: Path, out_path: Path) -> None:
    """Compile the staged FMU's binaries: this platform's, and the win64 one when the mingw-w64
    cross compiler is installed; without it, one line on stderr says the FMU at out_path carries
    no win64 binary and how to install the compiler."""
    compile_binary(stage)
    compiler = win64_compiler()
    if compiler is None:
        print(f"{out_path}: win64 binary skipped: {WIN64_COMPILER} is not installed "
              f"(apt-get install {WIN64_PACKAGE})", file=sys.stderr)
    else:
        compile_win64_binary(stage, compiler)


def pack_fmu(coefficients: np.ndarray, settings: dict, out_path: str | Path, reference_outputs: np.ndarray,
              description: str = DEFAULT_DESCRIPTION,
              provenance: str = "untrained identity coefficients", fmi_version: int = 2,
              aux_inputs: Sequence[dict] = (), training_data: Sequence[dict] = (),
              notes: Sequence[str] = (), variants: dict[str, bytes] | None = None) -> Path:
    """Build ImuFusion.fmu for FMI `fmi_version` (2 or 3) at out_path and return its path.

    coefficients: (N_COEFFICIENTS,) flat array (contract/layout.py); settings: parameter start
    values by name (missing names take the defaults); reference_outputs: what the model gives for
    `reference_recording()` with these coefficients and settings (the caller runs the model: the
    packer knows no model, training.fmu_build does); provenance goes into the coefficient
    header's comment; aux_inputs: the model's ModelArtefact.aux_inputs (what aux_1.. carry);
    training_data and notes: the model's ModelArtefact.training_data and .notes, which go with the
    build time and what the coefficients calibrate into the provenance record (fmu.provenance).
    The FMU holds modelDescription.xml, sources/ (runtime + the version's FMI
    wrapper + the generated ImuCoefficientsData.h; FMI 3 also buildDescription.xml),
    documentation/index.html, the reference pair, aux_inputs.json and provenance.json in
    extra/imufusion/ and the compiled binaries (`compile_binaries`). modelDescription.xml's
    description is `description` followed by the provenance summary. extra/org.fmi-standard.fmi-ls-ref/
    (fmu.references) holds the parameter set the FMU is built with (label `baseline`), the `variants`
    given (label -> SSV bytes, fmu.calibration_file) and the reference pair as its smoke-test experiment.
    Raises ModelError for bad coefficients, settings or aux_inputs, BuildError when compilation
    fails or the FMI version is not 2 or 3.
    """
    out_path = Path(out_path)
    check_fmi_version(fmi_version)
    values = _settings_dict(settings)
    try:
        variables = variable_table(aux_inputs)
    except ValueError as e:
        raise ModelError(str(e)) from e
    sources = fmu_source_files(fmi_version=fmi_version)
    guid = model_guid(coefficients, values, sources, variables)
    header = coefficient_header(coefficients, values, guid, provenance)
    c_files = [p.name for p in sources if p.suffix == ".c"]
    built = build_time()
    record = provenance_record(coefficients, values, built, training_data, notes)
    files = {"modelDescription.xml": model_description_xml(values, guid, f"{description}. {provenance_summary(record)}",
                                                           c_files, fmi_version, aux_inputs, built, coefficients,
                                                           training_data),
             f"sources/{HEADER_NAME}": header,
             "documentation/index.html": documentation_html(values, description, fmi_version, variables),
             AUX_INPUTS_FILE: json.dumps([dict(a) for a in aux_inputs], indent=2, ensure_ascii=False) + "\n",
             PROVENANCE_FILE: json.dumps(record, indent=2, ensure_ascii=False) + "\n",
             **reference_files(reference_outputs)}
    baseline = calibration_document(coefficients, values, aux_inputs, name=BASELINE, description=description)
    files.update(reference_members({BASELINE: baseline, **(variants or {})}, files[REFERENCE_INPUT],
                                   files[REFERENCE_OUTPUT]))
    if fmi_version == 3:
        files[BUILD_DESCRIPTION] = build_description_xml(c_files)
    return stage_and_pack(sources, files, out_path)


def stage_and_pack(sources: list[Path], files: dict[str, str | bytes], out_path: Path) -> Path:
    """Copy `sources` into a staging folder's sources/, write `files` (archive member -> text or bytes), compile
    the binaries and zip the folder into out_path (through a .partial file, so a failed build leaves none)."""
    with tempfile.TemporaryDirectory(prefix="imufusion-fmu-") as tmp:
        stage = Path(tmp)
        (stage / "sources").mkdir()
        for path in sources:
            shutil.copyfile(path, stage / "sources" / path.name)
        for name, content in files.items():
            (stage / name).parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, bytes):
                (stage / name).write_bytes(content)
            else:
                (stage / name).write_text(content)
        compile_binaries(stage, out_path)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        partial = out_path.with_name(out_path.name + ".partial")
        _zip_directory(stage, partial)
        partial.replace(out_path)
    return out_path


def fmu_aux_columns(fmu_path: str | Path) -> list[str]:
    """The recording column each auxiliary input of the FMU at fmu_path carries, aux_1 first
    (extra/imufusion/aux_inputs.json); pass it to ImuData.inputs(aux_columns=...)."""
    try:
        with zipfile.ZipFile(fmu_path) as zf:
            return [entry["column"] for entry in json.loads(zf.read(AUX_INPUTS_FILE).decode())]
    except (KeyError, zipfile.BadZipFile, ValueError, TypeError) as e:  # ValueError: not JSON; TypeError: not a list of objects
        raise ModelError(f"{fmu_path}: not an ImuFusion FMU with auxiliary inputs ({e}); rebuild it "
                         "with imufmu build-fmu") from e
