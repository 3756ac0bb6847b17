"""Parameter sets and the reference experiment inside the FMU, laid out as the FMI Layered Standard for
references describes it (FMI-LS-REF v1.0.0-alpha, modelica/fmi-ls-ref; issue 32): a folder
`extra/org.fmi-standard.fmi-ls-ref/` whose `fmi-ls-manifest.xml` lists every file with its role —
`parameter` for a parameter set (an SSV file, fmu/calibration_file.py) with a label per variant
(`baseline` is the set the FMU was built with; a fleet's units are other labels), and
`experiment/smoke-test` for the reference input and output the FMU reproduces (fmu/packer.py's pair).

The manifest's root carries the attributes every layered standard's manifest must
(`fmi-ls:fmi-ls-name`, `-version`, `-description`: fmi3LayeredStandardManifest.xsd, which fmpy ships); its
`Reference` elements (role, label, file relative to the folder, description) follow the standard's
description of roles and labels; fmi-ls-ref's own XSD is not published with a release here, so the
elements are checked by `embedded_problems`, not against it.
"""
from __future__ import annotations

import re
import tempfile
import zipfile
from pathlib import Path

from lxml import etree

from contract import coefficient_parameters as cp
from contract.errors import DataError, ImuFusionError, one_line
from contract.schema import check_setting
from fmu.calibration_file import read_calibration

#: The layered standard's folder inside the FMU and its manifest.
FOLDER = "extra/org.fmi-standard.fmi-ls-ref"
MANIFEST = f"{FOLDER}/fmi-ls-manifest.xml"
LS_NAME, LS_VERSION = "org.fmi-standard.fmi-ls-ref", "1.0.0-alpha"
_LS_NAMESPACE = "http://fmi-standard.org/fmi-ls-manifest"
#: Roles of the files listed.
PARAMETER, SMOKE_TEST = "parameter", "experiment/smoke-test"
#: The label of the set the FMU was built with.
BASELINE = "baseline"
#: A variant's label: it names a file, so letters, digits, '-', '_' and '.' only (not first).
LABEL = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


def check_label(label: str) -> str:
    """`label` when it can name a variant; ValueError saying what a label may hold otherwise."""
    if not LABEL.match(label):
        raise ValueError(f"variant label {label!r}: use 1-64 letters, digits, '-', '_' or '.' (not first)")
    return label


def members(parameter_sets: dict[str, bytes], reference_input: str, reference_output: str) -> dict[str, bytes]:
    """Archive member -> bytes of the folder: every parameter set (label -> SSV bytes, BASELINE first),
    the smoke-test pair and the manifest listing them."""
    files = {f"parameters/{check_label(label)}.ssv": (PARAMETER, label, data,
                                                      "the parameter set the FMU was built with" if label == BASELINE
                                                      else f"parameter set {label}")
             for label, data in parameter_sets.items()}
    files["experiments/smoke-test/input.csv"] = (SMOKE_TEST, "input", reference_input.encode(),
                                                 "reference input: 2 s at 100 Hz (row k = sample k)")
    files["experiments/smoke-test/output.csv"] = (SMOKE_TEST, "output", reference_output.encode(),
                                                  "the outputs the FMU gives for it with the baseline set")
    out = {f"{FOLDER}/{name}": data for name, (_, _, data, _) in files.items()}
    out[MANIFEST] = _manifest({name: (role, label, text) for name, (role, label, _, text) in files.items()})
    return out


def with_parameter_sets(fmu_path: str | Path, sets: dict[str, bytes], out_path: str | Path) -> Path:
    """Copy the FMU at fmu_path to out_path with `sets` (label -> SSV bytes) embedded beside the sets
    it has (its folder rewritten by `members`, every other member copied as it is): a variant needs no new
    binary. ValueError when a label is taken already."""
    existing = parameter_sets(fmu_path)
    taken = sorted(set(existing) & set(sets))
    if taken:
        raise ValueError(f"{fmu_path} has a parameter set '{taken[0]}' already")
    with zipfile.ZipFile(fmu_path) as source:
        folder = members({**existing, **sets}, *(source.read(f"{FOLDER}/experiments/smoke-test/{name}.csv")
                                                            .decode() for name in ("input", "output")))
        with zipfile.ZipFile(out_path, "w") as out:
            for info in source.infolist():
                if not info.filename.startswith(FOLDER + "/"):
                    out.writestr(info, source.read(info))
            for name, data in folder.items():
                out.writestr(zipfile.ZipInfo(name, date_time=source.getinfo(MANIFEST).date_time), data,
                             compress_type=zipfile.ZIP_DEFLATED)
    return Path(out_path)


def _manifest(files: dict[str, tuple[str, str, str]]) -> bytes:
    """The manifest's bytes: file -> (role, label, description)."""
    attribute = f"{{{_LS_NAMESPACE}}}"
    root = etree.Element("fmiLayeredStandardManifest", nsmap={"fmi-ls": _LS_NAMESPACE})
    root.set(attribute + "fmi-ls-name", LS_NAME)
    root.set(attribute + "fmi-ls-version", LS_VERSION)
    root.set(attribute + "fmi-ls-description", "References of this FMU: its parameter sets (SSP SSV) and the "
                                               "reference experiment it reproduces")
    for name, (role, label, text) in files.items():
        etree.SubElement(root, "Reference", role=role, label=label, file=name, description=text)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + etree.tostring(root, encoding="UTF-8", pretty_print=True)


def parameter_sets(fmu_path: str | Path) -> dict[str, bytes]:
    """Label -> SSV bytes of every parameter set the FMU's manifest lists (empty without a manifest);
    DataError naming the FMU when the manifest lists a file it lacks or is malformed."""
    with zipfile.ZipFile(fmu_path) as zf:
        if MANIFEST not in zf.namelist():
            return {}
        try:
            root = etree.fromstring(zf.read(MANIFEST), etree.XMLParser(resolve_entities=False, no_network=True))
            listed = {e.get("label"): f"{FOLDER}/{e.get('file')}" for e in root.iterfind("Reference")
                      if e.get("role") == PARAMETER}
            return {label: zf.read(member) for label, member in listed.items()}
        except (etree.XMLSyntaxError, KeyError) as e:
            raise DataError(fmu_path, f"{MANIFEST}: {one_line(str(e))}") from None


def read_embedded(fmu_path: str | Path, label: str):
    """read_calibration of the FMU's parameter set `label`; ImuFusionError naming the labels it has."""
    sets = parameter_sets(fmu_path)
    if label not in sets:
        raise ImuFusionError(f"{fmu_path}: no parameter set '{label}' (it has: {', '.join(sets) or 'none'})")
    with tempfile.TemporaryDirectory(prefix="imufusion-set-") as tmp:
        path = Path(tmp) / f"{label}.ssv"
        path.write_bytes(sets[label])
        return read_calibration(path)


def embedded_problems(fmu_path: str | Path, description) -> list[str]:
    """Every embedded parameter set that does not fit the FMU: unreadable or another layout
    (read_calibration), a setting outside its declared range, or a parameter the model description
    (an fmpy ModelDescription) lacks. One line each, naming the set."""
    names = {v.name for v in description.modelVariables}
    fmi3 = description.fmiVersion.startswith("3")
    problems = []
    try:
        sets = parameter_sets(fmu_path)
    except DataError as e:
        return [str(e)]
    for label in sets:
        try:
            coefficients, settings, _ = read_embedded(fmu_path, label)
        except ImuFusionError as e:
            problems.append(f"parameter set '{label}': {e}")
            continue
        wanted = list(cp.parameter_values(coefficients, 3 if fmi3 else 2)) + list(settings)
        missing = [name for name in wanted if name not in names]
        if missing:
            problems.append(f"parameter set '{label}': {missing[0]} is not a variable of the model description")
        for name, value in settings.items():
            try:
                check_setting(name, value)
            except ValueError as e:
                problems.append(f"parameter set '{label}': {e}")
    return problems
