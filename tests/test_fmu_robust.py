"""Bad input, invalid parameters and memory safety of the FMU glue (model.c + FMI wrappers).

The C checks compile the FMU sources directly: warning-free under gcc and clang, a C test suite
(tests/c/test_glue.c) under AddressSanitizer + UndefinedBehaviorSanitizer, no mutable global
state in any object file, and a dlopen co-simulation driver (tests/c/cosim_driver.c) under
valgrind memcheck. clang and valgrind come from Debian; CI installs them (.ci/run).
"""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

from debian_tools import debian_tool
from contract.layout import INPUTS, identity_coefficients
from fmu.compiler import FMPY_C_CODE as FMI_HEADERS, SOURCE_DIR, binary_path, fmu_source_files
from fmu.cosim import DISCARD, OK, WARNING, FmuError, Stepper, initialised_fmu, run_fmu
from fmu.header import HEADER_NAME, coefficient_header
from fmu.packer import reference_recording

C_TESTS = Path(__file__).parent / "c"
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror"]

#: Bad-input kinds: (name, input name or "h" for the step size, value, expected doStep status).
BAD_INPUTS = [
    ("gyroscope NaN", "gyr_x", np.nan, WARNING),
    ("gyroscope +Inf", "gyr_y", np.inf, WARNING),
    ("gyroscope absurd 1e300 rad/s", "gyr_z", 1e300, WARNING),
    ("accelerometer -Inf", "acc_x", -np.inf, WARNING),
    ("accelerometer absurd 1e6 m/s2", "acc_z", 1e6, WARNING),
    ("magnetometer NaN", "mag_y", np.nan, WARNING),
    ("magnetometer saturated axis 5000 uT", "mag_x", 5000.0, WARNING),
    ("magnetometer all-zero field", "mag_all", 0.0, WARNING),
    ("temperature NaN", "temp", np.nan, WARNING),
    ("temperature 400 degC (above range)", "temp", 400.0, WARNING),
    ("temperature -100 degC (below range)", "temp", -100.0, WARNING),
    ("step size 0", "h", 0.0, DISCARD),
    ("step size -0.01 s", "h", -0.01, DISCARD),
    ("step size NaN", "h", np.nan, DISCARD),
]


@pytest.fixture(scope="module")
def header_dir(tmp_path_factory) -> Path:
    """A folder with a generated ImuCoefficientsData.h (identity coefficients) for direct C builds."""
    folder = tmp_path_factory.mktemp("header")
    (folder / HEADER_NAME).write_text(
        coefficient_header(np.array(identity_coefficients()), {}, "{c-tests}", "C tests"))
    return folder


def _compile(command: list[str]) -> None:
    """Run a compiler command; fail the test with its output."""
    result = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert result.returncode == 0, f"{' '.join(command)}\n{result.stdout}"


@pytest.mark.parametrize("name, where, value, expected", BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS])
def test_bad_input_is_held_with_one_warning_per_episode(identity_fmu3, name, where, value, expected):
    t, raw = reference_recording()
    h = np.full(t.size, t[1] - t[0])
    bad = slice(80, 120)
    if where == "h":
        h[bad] = value
    elif where == "mag_all":
        raw[bad, 6:9] = value
    else:
        raw[bad, INPUTS.index(where)] = value
    with initialised_fmu(identity_fmu3) as fmu:
        stepper, statuses, outputs = Stepper(fmu), [], []
        for k in range(t.size):
            stepper.set_inputs(raw[k])
            statuses.append(stepper.do_step(t[k], h[k]))
            outputs.append(stepper.get_outputs())
        messages = [m for m in fmu.log_messages if "logBadInput" in m and m.startswith("[WARNING]")]
    outputs = np.array(outputs)
    assert np.all(np.isfinite(outputs)), name
    assert statuses[bad] == [expected] * 40 and set(statuses[:80] + statuses[120:]) == {OK}
    assert len(messages) == 1, messages
    if expected == DISCARD:  # nothing consumed: the estimate is held exactly
        assert np.all(outputs[bad] == outputs[79])


@pytest.mark.parametrize("name, value, expected", [
    ("field_norm", 0.0, "field_norm must be finite and within [5, 1000] uT"),
    ("field_norm", -5.0, "field_norm must be finite and within [5, 1000] uT"),
    ("gyro_noise", -1e-4, "gyro_noise must be finite and within [0, 0.1]"),
    ("gyro_bias_residual", np.inf, "gyro_bias_residual must be finite and within [0, 1]"),
    ("mse_time_constant", 0.0, "mse_time_constant must be finite and within (0, 86400] s"),
    ("angle_noise", np.nan, "angle_noise must be finite and within (0, 3.141593] rad"),
    ("declination", np.inf, "declination must be finite"),
])
def test_invalid_parameter_is_an_initialisation_error_naming_it(identity_fmu3, name, value, expected):
    t, raw = reference_recording()
    with pytest.raises(FmuError, match="fmi3ExitInitializationMode: invalid parameter") as info:
        run_fmu(identity_fmu3, t[:3], raw[:3], parameters={name: value})
    assert expected in str(info.value)


def _compile_objects(compiler: str, header_dir: Path, out_dir: Path) -> list[Path]:
    """Compile every FMU source of both FMI versions to an object file with the strict flags."""
    cc = debian_tool(compiler)
    files = sorted({p for version in (2, 3) for p in fmu_source_files(fmi_version=version) if p.suffix == ".c"})
    objects = []
    for source in files:
        objects.append(out_dir / (source.stem + ".o"))
        _compile([cc, *STRICT, "-O2", "-fPIC", "-fno-common", "-c", f"-I{header_dir}", f"-I{SOURCE_DIR}",
                  f"-I{FMI_HEADERS}", str(source), "-o", str(objects[-1])])
    return objects


@pytest.fixture(scope="module")
def gcc_objects(header_dir, tmp_path_factory) -> list[Path]:
    """The FMU sources compiled by gcc (once for the module)."""
    return _compile_objects("gcc", header_dir, tmp_path_factory.mktemp("gcc"))


def test_sources_compile_warning_free_under_gcc(gcc_objects):
    assert {p.stem for p in gcc_objects} >= {"model", "fmi2Functions", "fmi3Functions"}


def test_sources_compile_warning_free_under_clang(header_dir, tmp_path):
    assert len(_compile_objects("clang", header_dir, tmp_path)) > 3


def test_no_mutable_global_state(gcc_objects):
    nm = debian_tool("nm")
    writable = []
    for obj in gcc_objects:
        symbols = subprocess.run([nm, "-f", "sysv", str(obj)], stdout=subprocess.PIPE, text=True, check=True).stdout
        for line in symbols.splitlines():
            fields = [f.strip() for f in line.split("|")]
            # Writable sections; .data.rel.ro holds const tables of pointers (read-only after loading).
            if len(fields) == 7 and fields[6].startswith((".data", ".bss", "COMMON", ".sdata", ".sbss")) \
                    and not fields[6].startswith(".data.rel.ro"):
                writable.append(f"{obj.name}: {fields[0]} in {fields[6]}")
    assert writable == []  # only code and read-only data: instances share nothing


def test_c_glue_suite_under_address_and_undefined_behaviour_sanitizers(header_dir, tmp_path):
    cc = debian_tool("gcc")
    sources = [p for p in fmu_source_files(fmi_version=3) if p.suffix == ".c"]
    program = tmp_path / "test_glue"
    _compile([cc, *STRICT, "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
              "-fno-omit-frame-pointer", f"-I{header_dir}", f"-I{SOURCE_DIR}", f"-I{FMI_HEADERS}",
              str(C_TESTS / "test_glue.c"), *map(str, sources), "-o", str(program), "-lm"])
    result = subprocess.run([str(program)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    assert result.returncode == 0, result.stdout
    assert result.stdout.strip().endswith(" 0 failed"), result.stdout


def test_cosimulation_under_valgrind_has_no_errors_or_leaks(identity_fmu3, tmp_path):
    valgrind, cc = debian_tool("valgrind"), debian_tool("gcc")
    driver = tmp_path / "cosim_driver"
    _compile([cc, *STRICT, "-g", f"-I{FMI_HEADERS}", f"-I{SOURCE_DIR}", str(C_TESTS / "cosim_driver.c"),
              "-o", str(driver), "-ldl", "-lm"])
    member = binary_path(Path(), "ImuFusion", 3).as_posix()
    with zipfile.ZipFile(identity_fmu3) as zf:
        library = zf.extract(member, tmp_path)
    token = fmpy.read_model_description(str(identity_fmu3)).guid
    result = subprocess.run([valgrind, "-q", "--leak-check=full", "--show-leak-kinds=all",
                             "--errors-for-leak-kinds=all", "--error-exitcode=3", str(driver), library, token],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    assert result.returncode == 0, result.stdout
    assert "driver: 0 failures" in result.stdout
    assert "logBadInput" in result.stdout  # the bad stretch was reported
