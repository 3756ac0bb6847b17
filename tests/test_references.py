"""Parameter sets inside the FMU (fmu/references.py, the FMI-LS-REF layout of issue 32): every FMU carries
the set it was built with (`baseline`) and the reference experiment under extra/org.fmi-standard.fmi-ls-ref/,
listed in fmi-ls-manifest.xml; `imufmu validate` checks every embedded set against the model description
and the layout and names the set that does not fit."""
from __future__ import annotations

import zipfile

import numpy as np
import pytest

from contract.layout import identity_coefficients
from fmu.archive import read_description
from fmu.calibration_file import calibration_document
from fmu.references import BASELINE, FOLDER, MANIFEST, check_label, embedded_problems, members, parameter_sets, read_embedded
from fmu.packer import REFERENCE_INPUT, REFERENCE_OUTPUT
from fmu_cases import TRAINED_SETTINGS, trained_coefficients


def _with_sets(fmu, out, sets: dict[str, bytes]):
    """A copy of fmu whose FMI-LS-REF folder holds `sets` (label -> SSV bytes) beside its baseline."""
    with zipfile.ZipFile(fmu) as source:
        baseline = parameter_sets(fmu)[BASELINE]
        folder = members({BASELINE: baseline, **sets}, source.read(REFERENCE_INPUT).decode(),
                         source.read(REFERENCE_OUTPUT).decode())
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as target:
            for info in source.infolist():
                if not info.filename.startswith(FOLDER):
                    target.writestr(info, source.read(info))
            for name, data in folder.items():
                target.writestr(name, data)
    return out


def test_every_fmu_carries_the_set_it_was_built_with(trained_fmu):
    assert list(parameter_sets(trained_fmu)) == [BASELINE]
    coefficients, settings, _ = read_embedded(trained_fmu, BASELINE)
    np.testing.assert_array_equal(coefficients, trained_coefficients())
    for name, value in TRAINED_SETTINGS.items():
        assert settings[name] == float(value), name
    with zipfile.ZipFile(trained_fmu) as zf:
        manifest = zf.read(MANIFEST).decode()
    assert 'role="experiment/smoke-test"' in manifest and 'fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-ref"' in manifest


def test_validate_names_an_embedded_set_that_does_not_fit(identity_fmu, tmp_path):
    good = calibration_document(np.array(identity_coefficients()), {"field_norm": 48.0})
    bad = calibration_document(np.array(identity_coefficients()), {"field_norm": -5.0})
    fmu = _with_sets(identity_fmu, tmp_path / "sets.fmu", {"unit-good": good, "unit-bad": bad})
    assert list(parameter_sets(fmu)) == [BASELINE, "unit-good", "unit-bad"]
    problems = embedded_problems(fmu, read_description(fmu))
    assert len(problems) == 1 and problems[0].startswith("parameter set 'unit-bad': field_norm"), problems
    assert read_embedded(fmu, "unit-good")[1]["field_norm"] == 48.0


def test_a_missing_set_is_named_with_the_labels_the_fmu_has(identity_fmu2):
    with pytest.raises(Exception, match="no parameter set 'unit-Z' \\(it has: baseline\\)"):
        read_embedded(identity_fmu2, "unit-Z")


@pytest.mark.parametrize("label", ["", "-x", "a/b", "x" * 65, "unit A"])
def test_a_label_must_be_able_to_name_a_file(label):
    with pytest.raises(ValueError, match="variant label"):
        check_label(label)


def test_fmpy_applies_an_embedded_variant(identity_fmu, trained_fmu, fmi_version, tmp_path):
    # fmpy's own simulate_fmu with the start values of a parameter set embedded in the FMU built without a
    # calibration gives the outputs of the FMU the set was compiled into
    from fmpy import simulate_fmu
    from contract.layout import INPUTS, OUTPUTS
    from fmu.calibration_file import start_values
    from fmu.packer import reference_recording
    unit = calibration_document(trained_coefficients(), TRAINED_SETTINGS)
    fmu = _with_sets(identity_fmu, tmp_path / "sets.fmu", {"unit-A": unit})
    coefficients, settings, _ = read_embedded(fmu, "unit-A")
    t, raw = reference_recording()
    signals = np.zeros(len(t), dtype=[("time", float)] + [(name, float) for name in INPUTS])
    signals["time"] = t
    for j, name in enumerate(INPUTS):
        signals[name] = raw[:, j]
    run = dict(input=signals, output=list(OUTPUTS), step_size=float(t[1] - t[0]), stop_time=float(t[-1]))
    applied = simulate_fmu(str(fmu), start_values=start_values(coefficients, settings, fmi_version), **run)
    compiled = simulate_fmu(str(trained_fmu), **run)
    for name in OUTPUTS:
        np.testing.assert_array_equal(applied[name], compiled[name], err_msg=name)
