"""Provenance (issue 16 item 7): the FMU says what it is in modelDescription.xml and
extra/imufusion/provenance.json, `imufmu --version`, an example in every verb's --help,
`imufmu validate` lists its checks, model.json records our distribution under its own name."""
from __future__ import annotations

import json
import re
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from contract import __version__
from contract.layout import STAGE_BLOCKS
from contract.version import DISTRIBUTION, package_version
from fmu.provenance import PROVENANCE_FILE, build_time
from fmu.validator import VALIDATION_CHECKS
from training.artefact import ModelArtefact, load_artefact
from training.cli import EXAMPLES, build_parser, main
from training.models import elm
from training.models.thermal import ThermalModel

PYPROJECT = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())["project"]

#: One correction term (gyro g-sensitivity on gyr_x), bounds in m/s².
TERM = {"name": "g-sensitivity", "target": "gyr_x", "a": "acc_x", "b": None, "coefficient": 1e-4,
        "lo": -50.0, "hi": 50.0}


def elm_block() -> list[float]:
    """A trained ELM block (sources/ImuElm.h): enabled, tanh, 1 hidden node, a ±100 µT box, all
    weights zero; its parameter enable_elm stays at the default 0 (trained but off)."""
    block = [0.0] * STAGE_BLOCKS["elm"]
    block[0], block[2] = 1.0, 1.0
    block[3:15] = [-100.0] * 3 + [100.0] * 3 + [-100.0] * 3 + [100.0] * 3
    return block


def small_artefact() -> ModelArtefact:
    """Identity gyro and accelerometer, magnetometer passed through, one term, a trained ELM
    left off, the PF on."""
    return ModelArtefact(seed=0, thermal={"gyr": ThermalModel.identity(), "acc": ThermalModel.identity(),
                                          "mag": ThermalModel.identity(enabled=False)},
                         settings={"enable_pf": 1.0},
                         training_data=[{"name": "bench_a.csv.gz", "samples": 12000},
                                        {"name": "bench_b.csv", "samples": 345}],
                         notes=["magnetometer: no field reference, passed through", "gyro degree 0: one plateau"],
                         terms=[dict(TERM)], elm=elm.from_block(np.array(elm_block())))


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> tuple[ModelArtefact, Path]:
    artefact = small_artefact()
    return artefact, artefact.save(tmp_path_factory.mktemp("model") / "model.json")


@pytest.fixture(scope="module", params=[2, 3])
def built(request, model, tmp_path_factory) -> Path:
    """The small model built by `imufmu build-fmu` for FMI 2 and FMI 3."""
    out = tmp_path_factory.mktemp(f"fmi{request.param}") / "ImuFusion.fmu"
    assert main(["build-fmu", "--model", str(model[1]), "--out", str(out), "--fmi", str(request.param)]) == 0
    return out


def _record(fmu: Path) -> dict:
    with zipfile.ZipFile(fmu) as zf:
        return json.loads(zf.read(PROVENANCE_FILE).decode())


def test_extra_file_equals_the_artefact(built, model):
    artefact = model[0]
    record = _record(built)
    assert record["distribution"] == DISTRIBUTION and record["version"] == PYPROJECT["version"]
    assert record["training_data"] == artefact.training_data
    assert record["notes"] == artefact.notes
    assert record["calibration"] == {
        "thermal_on": True,
        "triads": {t: {"enabled": artefact.thermal[t].enabled, "degree": artefact.thermal[t].degree}
                   for t in ("gyr", "acc", "mag")},
        "stages": {"elm": {"trained": True, "on": False}, "psobp": {"trained": "off", "on": False},
                   "pf": {"on": True}},
        "correction_terms": len(artefact.terms)}
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", record["generation_date_and_time"])


def test_model_description_carries_the_provenance(built, model):
    artefact = model[0]
    record = _record(built)
    md = read_model_description(str(built), validate=False)
    assert md.generationTool == record["generation_tool"]
    assert PYPROJECT["name"] in md.generationTool and PYPROJECT["version"] in md.generationTool
    assert md.generationDateAndTime == record["generation_date_and_time"]
    for d in artefact.training_data:
        assert f"{d['name']} ({d['samples']} samples)" in md.description
    for note in artefact.notes:
        assert note in md.description
    assert "triads calibrated: gyr (degree 0), acc (degree 0); pass-through: mag" in md.description
    assert "stages on: PF; trained but off (enable_*=0): ELM; 1 correction terms" in md.description


def test_validate_lists_every_check_with_its_result(built, capsys):
    assert main(["validate", str(built)]) == 0  # also: the new attributes pass fmpy and fmutool -check
    out = capsys.readouterr().out
    assert [line for line in out.splitlines() if line.startswith("check ")] == \
        [f"check {name}: ok" for name in VALIDATION_CHECKS]


def test_validate_says_which_checks_did_not_run(tmp_path, capsys):
    broken = tmp_path / "broken.fmu"
    broken.write_bytes(b"PK\x05\x06" + bytes(18))  # an empty zip: no modelDescription.xml
    assert main(["validate", str(broken)]) == 1
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("check ")]
    assert lines[0] == "check archive: FAILED (1 problem(s))"
    assert lines[1:] == [f"check {name}: not run (an earlier check failed)" for name in VALIDATION_CHECKS[1:]]


def test_version_prints_the_pyproject_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"imufmu ({PYPROJECT['name']}) {PYPROJECT['version']}"
    assert DISTRIBUTION == PYPROJECT["name"] and package_version() == __version__ == PYPROJECT["version"]


def test_every_verb_help_shows_an_example():
    verbs = build_parser()._subparsers._group_actions[0].choices
    assert set(verbs) == set(EXAMPLES)
    for verb, parser in verbs.items():
        text = parser.format_help()
        assert "example" in text and f"imufmu {verb} " in text


def test_build_time_is_utc_and_honours_source_date_epoch(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "86400")
    assert build_time() == "1970-01-02T00:00:00Z"


def test_model_json_records_our_distribution_not_xio_imufusion(model):
    libraries = json.loads(model[1].read_text())["libraries"]
    assert "imufusion" not in libraries
    assert libraries[PYPROJECT["name"]] == PYPROJECT["version"]


def test_old_model_json_with_the_imufusion_key_still_loads(tmp_path, model):
    doc = json.loads(model[1].read_text())
    doc["libraries"] = {name: v for name, v in doc["libraries"].items() if name != DISTRIBUTION} | {"imufusion": "0.1.0"}
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    libraries = load_artefact(old).libraries
    assert "imufusion" not in libraries and libraries[DISTRIBUTION] == "0.1.0"
