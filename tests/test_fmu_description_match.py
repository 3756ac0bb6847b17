"""`validate` catches a model description that does not match what the FMU implements (issue 16
item 4): it passed one whose value references of gyr_x and gyr_y were swapped.

Each case builds nothing new: it rewrites modelDescription.xml of a built FMU (FMI 2 and FMI 3)
and expects the exact problem lines of fmu.description_check, the binary-level check and, for a
swap, the reference result (fmu.cosim now maps inputs and outputs by the description's names).
"""
from __future__ import annotations

import re
import zipfile
from collections.abc import Callable
from pathlib import Path


from contract import coefficient_parameters
from fmu.description_check import CONFIG_MEMBER, behaviour_problems, description_problems
from fmu.validator import reference_problems, validate_fmu
from fmu_cases import TRAINED_SETTINGS, trained_coefficients
from training.cli import main

MD = "modelDescription.xml"
TABLE = "the variable table (contract/variables.py)"


def _rewritten(fmu: Path, out: Path, edit: Callable[[str], str] | None = None, drop: str | None = None) -> Path:
    """A copy of fmu at out whose modelDescription.xml is edit(text) (which must change it), without
    member `drop`."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as target:
        for info in source.infolist():
            if info.filename == drop:
                continue
            data = source.read(info)
            if info.filename == MD and edit is not None:
                changed = edit(data.decode())
                assert changed != data.decode()
                data = changed.encode()
            target.writestr(info, data)
    return out


def _element(xml: str, name: str) -> tuple[int, int]:
    """(start, end) of the variable `name` in a model description: its ScalarVariable (FMI 2) or
    its typed element (FMI 3)."""
    start = xml.index(f'name="{name}"')
    closing = "</ScalarVariable>" if "<ScalarVariable" in xml else "/>"
    return start, xml.index(closing, start)


def _set(name: str, attribute: str, value: str) -> Callable[[str], str]:
    """An edit that sets `attribute` of variable `name` (wherever in its element it is) to value."""
    def edit(xml: str) -> str:
        start, end = _element(xml, name)
        element, count = re.subn(rf'\b{attribute}="[^"]*"', f'{attribute}="{value}"', xml[start:end])
        assert count == 1
        return xml[:start] + element + xml[end:]
    return edit


def _swap(a: str, b: str) -> Callable[[str], str]:
    """An edit that swaps the value references of variables a and b."""
    def edit(xml: str) -> str:
        vr_a, vr_b = (re.search(rf'name="{n}" valueReference="(\d+)"', xml).group(1) for n in (a, b))
        return _set(b, "valueReference", vr_a)(_set(a, "valueReference", vr_b)(xml))
    return edit


def _vr_line(name: str, declared: int, true: int) -> str:
    """The problem line for a variable declared at value reference `declared` instead of `true`."""
    return f"{name}: {MD} says valueReference {declared}; {TABLE} says {true}; {CONFIG_MEMBER} says {true}"


def test_the_untouched_fmu_validates_with_every_check(trained_fmu):
    checks: list[tuple[str, int]] = []
    assert validate_fmu(trained_fmu, checks) == []
    assert ("description matches sources", 0) in checks and ("description matches binary", 0) in checks


def test_swapped_input_references_are_named(trained_fmu, tmp_path, capsys):
    swapped = _rewritten(trained_fmu, tmp_path / "swapped.fmu", _swap("gyr_x", "gyr_y"))
    checks: list[tuple[str, int]] = []
    assert validate_fmu(swapped, checks) == [_vr_line("gyr_x", 1, 0), _vr_line("gyr_y", 0, 1)]
    assert ("description matches sources", 2) in checks
    assert main(["validate", str(swapped)]) == 1
    captured = capsys.readouterr()
    assert captured.err.strip() == f"imufmu validate: error: {swapped}: 2 problem(s); the first: {_vr_line('gyr_x', 1, 0)}"
    assert f"problem: {_vr_line('gyr_y', 0, 1)}" in captured.out.splitlines()


def test_the_binary_and_the_reference_result_catch_the_swap_without_the_sources(trained_fmu, tmp_path):
    """Binary-only or edited sources: the binary's behaviour and the reference run still tell."""
    swapped = _rewritten(trained_fmu, tmp_path / "swapped.fmu", _swap("gyr_x", "gyr_y"))
    problems = behaviour_problems(swapped)
    assert [p.split(":")[0] for p in problems] == ["gyr_x", "gyr_y"]
    assert "gyr_x: stepping it (valueReference 1) should move rate_x most" in problems[0]
    assert reference_problems(swapped)[0].startswith("the FMU does not reproduce its reference output")


def test_swapped_output_references_are_named(trained_fmu, tmp_path):
    swapped = _rewritten(trained_fmu, tmp_path / "swapped.fmu", _swap("rate_x", "rate_y"))
    assert validate_fmu(swapped) == [_vr_line("rate_x", 11, 10), _vr_line("rate_y", 10, 11)]
    # The binary moves what the description calls rate_y when gyr_x steps.
    assert [p.split(":")[0] for p in behaviour_problems(swapped)] == ["gyr_x", "gyr_y"]
    assert reference_problems(swapped)[0].startswith("the FMU does not reproduce its reference output")


def test_a_changed_parameter_start_is_named(trained_fmu, tmp_path):
    changed = _rewritten(trained_fmu, tmp_path / "start.fmu", _set("field_norm", "start", "49.0"))
    compiled = TRAINED_SETTINGS["field_norm"]
    assert validate_fmu(changed) == [
        f"field_norm: {MD} says start 49.0; sources/ImuCoefficientsData.h says {compiled!r}"]
    assert behaviour_problems(changed) == [
        f"field_norm (valueReference 38, Real): {MD} says start 49.0; the binary holds {compiled!r}"]


def test_a_changed_coefficient_start_is_named(trained_fmu, fmi_version, tmp_path):
    # the coefficient parameters' start values are the coefficients compiled in (t0 of the gyro's thermal block)
    block = coefficient_parameters.BLOCKS[1]
    values = coefficient_parameters.block_values(trained_coefficients())[block.parameter]
    values[1] += 1.0
    name, text = ((block.parameter, " ".join(repr(v) for v in values)) if fmi_version == 3
                  else (coefficient_parameters.scalar_name(block, 1), repr(values[1])))
    def edit(xml: str) -> str:  # the element's own start, not its <Dimension start=...> (FMI 3)
        at = xml.index(f'name="{name}"')
        return xml[:at] + re.sub(r'\bstart="[^"]*"', f'start="{text}"', xml[at:], count=1)
    changed = _rewritten(trained_fmu, tmp_path / "coefficient.fmu", edit)
    problems = validate_fmu(changed)
    assert len(problems) == 1 and problems[0].startswith(f"{name}: {MD} says start "), problems
    assert "sources/ImuCoefficientsData.h says" in problems[0]
    behaviour = behaviour_problems(changed)
    assert len(behaviour) == 1 and behaviour[0].startswith(f"{name} (valueReference"), behaviour


def test_a_changed_causality_is_named(trained_fmu, tmp_path):
    # input -> local passes fmpy's schema checks when the start value stays exact
    changed = _rewritten(trained_fmu, tmp_path / "causality.fmu", _set("gyr_x", "causality", 'local" initial="exact'))
    assert validate_fmu(changed) == [f"gyr_x: {MD} says causality local; {TABLE} says input"]


def test_missing_sources_are_a_problem(trained_fmu, tmp_path):
    stripped = _rewritten(trained_fmu, tmp_path / "nosources.fmu", drop=CONFIG_MEMBER)
    assert description_problems(stripped) == [
        f"{stripped}: the FMU has no {CONFIG_MEMBER}: its model description cannot be checked against its sources"]
