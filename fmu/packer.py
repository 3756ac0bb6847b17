"""Assemble, compile and zip the ImuFusion FMU (FMI 2.0 co-simulation, source + linux64 binary)."""
from __future__ import annotations

import hashlib
import html
import shutil
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from fmu.compiler import compile_binary, fmu_source_files
from fmu.header import HEADER_NAME, coefficient_header
from fmu.model_description import MODEL_NAME, model_description_xml
from fmu.variables import VARIABLES, Variable
from training.errors import ModelError
from training.layout import SETTINGS, settings_array

DEFAULT_DESCRIPTION = ("IMU calibration and attitude: temperature-compensated gyro, accelerometer and "
                       "magnetometer, adaptive-gain Euler-angle fusion")

#: Timestamp of every zip entry, so the same inputs give the same archive bytes.
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def _settings_dict(settings: dict) -> dict[str, float]:
    """Every setting by name (defaults filled in); ModelError for an unknown name."""
    try:
        values = settings_array(settings)
    except KeyError as e:
        raise ModelError(str(e.args[0])) from e
    return {name: value for (name, _), value in zip(SETTINGS, values)}


def model_guid(coefficients: np.ndarray, settings: dict[str, float], sources: list[Path]) -> str:
    """GUID = SHA-256 of coefficients, settings, variable table and FMU sources, as {8-4-4-4-12} hex."""
    digest = hashlib.sha256()
    digest.update(repr([float(v) for v in np.asarray(coefficients, dtype=float)]).encode())
    digest.update(repr(sorted(settings.items())).encode())
    digest.update(repr(VARIABLES).encode())
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


def documentation_html(settings: dict[str, float], description: str) -> str:
    """documentation/index.html: what the FMU is, its conventions and its variables with units."""
    by_causality = {c: tuple(v for v in VARIABLES if v.causality == c) for c in ("input", "output", "parameter")}
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{MODEL_NAME}</title></head>
<body>
<h1>{MODEL_NAME}</h1>
<p>{html.escape(description)}.</p>
<p>FMI 2.0 co-simulation FMU with C sources. Each <code>fmi2DoStep(t, h)</code> consumes the one raw
sample whose inputs were set before it; afterwards the outputs are the estimate for the sample at
<code>t</code>, and <code>h</code> is the time to the next sample (step sizes may vary).</p>
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


def build_fmu(coefficients: np.ndarray, settings: dict, out_path: str | Path,
              description: str = DEFAULT_DESCRIPTION,
              provenance: str = "untrained identity coefficients") -> Path:
    """Build ImuFusion.fmu at out_path and return its path.

    coefficients: (N_COEFFICIENTS,) flat array (training/layout.py); settings: parameter start
    values by name (missing names take the defaults); provenance goes into the coefficient
    header's comment. The FMU holds modelDescription.xml, sources/ (runtime + FMI 2.0 glue + the
    generated ImuCoefficientsData.h), documentation/index.html and the compiled binary.
    Raises ModelError for bad coefficients or settings, BuildError when compilation fails.
    """
    out_path = Path(out_path)
    values = _settings_dict(settings)
    sources = fmu_source_files()
    guid = model_guid(coefficients, values, sources)
    header = coefficient_header(coefficients, values, guid, provenance)
    with tempfile.TemporaryDirectory(prefix="imufusion-fmu-") as tmp:
        stage = Path(tmp)
        (stage / "sources").mkdir()
        for path in sources:
            shutil.copyfile(path, stage / "sources" / path.name)
        (stage / "sources" / HEADER_NAME).write_text(header)
        c_files = [p.name for p in sources if p.suffix == ".c"]
        (stage / "modelDescription.xml").write_text(model_description_xml(values, guid, description, c_files))
        (stage / "documentation").mkdir()
        (stage / "documentation" / "index.html").write_text(documentation_html(values, description))
        compile_binary(stage)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        partial = out_path.with_name(out_path.name + ".partial")
        _zip_directory(stage, partial)
        partial.replace(out_path)
    return out_path
