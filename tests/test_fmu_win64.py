"""The FMU's Windows x86-64 binary (binaries/win64 for FMI 2, binaries/x86_64-windows for FMI 3),
cross-compiled with mingw-w64: present, exporting exactly the FMI functions, importing only Windows
system DLLs, valid for fmpy and fmutool; fmu.pe read against mingw's objdump; and the linux-only
build when the cross compiler is missing; and the DLL loaded by a Windows C host (tests/c/win_host.c)
under wine, reproducing the FMU's reference output and restoring a serialized FMU state."""
from __future__ import annotations

import os
import re
import subprocess
import zipfile
from pathlib import Path, PureWindowsPath

import numpy as np
import pytest
from fmpy.validation import validate_fmu as fmpy_validate_fmu

import fmu.packer
from debian_tools import debian_tool
from contract.layout import INPUTS, OUTPUTS, identity_coefficients
from fmu.archive import extract_archive, read_description
from fmu.compiler import C_FLAGS, FMPY_C_CODE, WIN64_COMPILER, WIN64_PACKAGE, WIN64_PLATFORMS
from fmu.cosim import description_step_sizes
from fmu.packer import REFERENCE_INPUT, REFERENCE_OUTPUT, read_reference_csv
from fmu.pe import MACHINE_AMD64, read_pe
from fmu.validator import (EXPORTED_FUNCTIONS, REFERENCE_TOLERANCE, binary_member, binary_members,
                           exported_symbols, fmutool_problems, is_windows_system_dll, validate_fmu,
                           windows_image)
from training.fmu_build import build_fmu

#: mingw-w64's objdump, installed with the cross compiler (package WIN64_PACKAGE's dependency).
WIN64_OBJDUMP = "x86_64-w64-mingw32-objdump"
#: wine runs the Windows host and the DLL: Debian's wine64 (the 64-bit loader) and wine (the `wine`
#: command, only recommended by wine64, so named for apt set-ups without recommends); .ci/run installs both.
WINE, WINE_PACKAGES = "wine", "wine64 wine"
#: The Windows C host that LoadLibrary's the DLL and co-simulates it like fmu.cosim.run_fmu.
WIN_HOST_SOURCE = Path(__file__).parent / "c" / "win_host.c"


def _win64_member(fmi_version: int) -> str:
    """The Windows binary's path inside an FMI `fmi_version` FMU."""
    return binary_members(fmi_version)[WIN64_PLATFORMS[fmi_version]]


@pytest.fixture(scope="module", params=[2, 3], ids=["fmi2", "fmi3"])
def win_fmu(request, tmp_path_factory) -> tuple[Path, int]:
    """(FMU path, FMI version): an identity-coefficient FMU built with the cross compiler present."""
    debian_tool(WIN64_COMPILER, WIN64_PACKAGE)
    out = tmp_path_factory.mktemp(f"win64-fmi{request.param}") / "ImuFusion.fmu"
    return build_fmu(np.array(identity_coefficients()), {}, out, fmi_version=request.param), request.param


def test_fmu_carries_the_linux_and_the_win64_binary(win_fmu):
    path, version = win_fmu
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    assert {binary_member(version), _win64_member(version)} <= names
    assert _win64_member(version) == f"binaries/{('win64', 'x86_64-windows')[version - 2]}/ImuFusion.dll"


def test_win64_binary_exports_exactly_the_fmi_functions(win_fmu):
    path, version = win_fmu
    symbols = exported_symbols(path, WIN64_PLATFORMS[version])
    assert len(symbols) == {2: 34, 3: 75}[version]
    assert symbols == EXPORTED_FUNCTIONS[version]


def test_win64_binary_is_x86_64_and_imports_only_windows_system_dlls(win_fmu):
    path, version = win_fmu
    image = windows_image(path, WIN64_PLATFORMS[version])
    assert image.machine == MACHINE_AMD64
    assert image.imports and all(is_windows_system_dll(name) for name in image.imports), image.imports
    assert not any(re.search("libgcc|winpthread|libstdc", name, re.I) for name in image.imports)


def test_fmpy_fmutool_and_full_validation_pass_with_the_win64_binary(win_fmu):
    path, version = win_fmu
    assert fmpy_validate_fmu(str(path)) == []
    assert fmutool_problems(path) == []
    checks: list[tuple[str, int]] = []
    assert validate_fmu(path, checks) == []
    assert ("binaries", 0) in checks


def test_pe_reader_agrees_with_mingw_objdump(win_fmu, tmp_path):
    objdump = debian_tool(WIN64_OBJDUMP, WIN64_PACKAGE)
    path, version = win_fmu
    with zipfile.ZipFile(path) as zf:
        dll = Path(zf.extract(_win64_member(version), tmp_path))
    dump = subprocess.run([objdump, "-p", str(dll)], stdout=subprocess.PIPE, text=True, check=True).stdout
    table = dump.split("[Ordinal/Name Pointer] Table", 1)[1].split("\n\n", 1)[0]
    names = set(re.findall(r"^\s*\[\s*\d+\]\s+(\S+)\s*$", table, re.M))
    dlls = re.findall(r"^\s*DLL Name: (\S+)\s*$", dump, re.M)
    image = read_pe(dll.read_bytes())
    assert names == image.exports and len(names) == len(EXPORTED_FUNCTIONS[version])
    assert tuple(dlls) == image.imports


def test_pe_reader_refuses_foreign_files_and_never_misreads_a_truncated_dll(win_fmu):
    """A truncated DLL either raises ValueError (a table lies beyond the cut) or, when the cut
    only drops bytes the reader does not need (trailing sections), reads exactly as the whole."""
    path, version = win_fmu
    with zipfile.ZipFile(path) as zf:
        data = zf.read(_win64_member(version))
        elf = zf.read(binary_member(version))
    for foreign in (elf, b"", b"MZ"):
        with pytest.raises(ValueError):
            read_pe(foreign)
    whole, refused = read_pe(data), 0
    for cut in range(0, len(data), 997):
        try:
            assert read_pe(data[:cut]) == whole
        except ValueError:
            refused += 1
    assert refused > 0


def test_validate_names_a_win64_binary_with_foreign_exports_and_imports(win_fmu, tmp_path):
    """A DLL that exports a non-FMI function and imports a DLL Windows lacks (helper.dll) replaces
    the win64 binary: validate reports the extra export, the missing FMI functions and the import,
    each naming the win64 member."""
    cc = debian_tool(WIN64_COMPILER, WIN64_PACKAGE)
    path, version = win_fmu
    (tmp_path / "helper.c").write_text("__declspec(dllexport) int helper(void) { return 1; }\n")
    (tmp_path / "bad.c").write_text("int helper(void);\n"
                                    "__declspec(dllexport) int ImuExtra(void) { return helper(); }\n")
    subprocess.run([cc, "-shared", str(tmp_path / "helper.c"), "-o", str(tmp_path / "helper.dll")], check=True)
    subprocess.run([cc, "-shared", str(tmp_path / "bad.c"), str(tmp_path / "helper.dll"), "-o",
                    str(tmp_path / "bad.dll")], check=True)
    tampered = tmp_path / "tampered.fmu"
    member = _win64_member(version)
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(tampered, "w") as dst:
        for info in src.infolist():
            dst.writestr(info, (tmp_path / "bad.dll").read_bytes() if info.filename == member else src.read(info))
    problems = validate_fmu(tampered)
    assert f"{member}: exports non-FMI symbols: ImuExtra" in problems
    assert any(p.startswith(f"{member}: lacks FMI functions: ") for p in problems)
    assert f"{member}: imports DLLs that Windows does not have: helper.dll" in problems
    assert all(p.startswith(member) for p in problems)  # the linux binary is fine


def test_without_the_cross_compiler_the_fmu_is_built_for_linux_and_says_so(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(fmu.packer, "win64_compiler", lambda: None)
    out = build_fmu(np.array(identity_coefficients()), {}, tmp_path / "ImuFusion.fmu")
    lines = capsys.readouterr().err.splitlines()
    assert lines == [f"{out}: win64 binary skipped: {WIN64_COMPILER} is not installed "
                     f"(apt-get install {WIN64_PACKAGE})"]
    with zipfile.ZipFile(out) as zf:
        names = zf.namelist()
    assert binary_member(2) in names and _win64_member(2) not in names
    assert validate_fmu(out) == []


@pytest.fixture(scope="module")
def wine_env(tmp_path_factory) -> dict[str, str]:
    """The environment for wine: a fresh prefix (~/.wine is left alone; wine creates the prefix on
    its first run, ~5 s), no debug output, and no offer to install .NET (mscoree) or the HTML
    engine (mshtml), which the host does not use."""
    debian_tool(WINE, WINE_PACKAGES)
    return dict(os.environ, WINEPREFIX=str(tmp_path_factory.mktemp("wineprefix")), WINEDEBUG="-all",
                WINEDLLOVERRIDES="mscoree,mshtml=")


@pytest.fixture(scope="module")
def win_host(tmp_path_factory) -> Path:
    """tests/c/win_host.c cross-compiled into a Windows .exe with the FMU's warning flags."""
    cc = debian_tool(WIN64_COMPILER, WIN64_PACKAGE)
    exe = tmp_path_factory.mktemp("win-host") / "win_host.exe"
    subprocess.run([cc, "-Wall", "-Wextra", "-Wpedantic", *C_FLAGS.split(), f"-I{FMPY_C_CODE}", str(WIN_HOST_SOURCE),
                    "-o", str(exe)], check=True)
    return exe


def _write_host_data(unzipdir: Path, description, t: np.ndarray, inputs: np.ndarray) -> None:
    """The data files win_host reads, in unzipdir: the value references of INPUTS and OUTPUTS that
    the FMU's model description `description` declares (uint32), and per sample [t_k, h_k, inputs]
    (float64; s, s, the INPUTS units) with run_fmu's step sizes h."""
    vr = {v.name: v.valueReference for v in description.modelVariables}
    np.array([vr[name] for name in INPUTS], "<u4").tofile(unzipdir / "vr_in.bin")
    np.array([vr[name] for name in OUTPUTS], "<u4").tofile(unzipdir / "vr_out.bin")
    np.column_stack([t, description_step_sizes(description, t), inputs]).astype("<f8").tofile(unzipdir / "samples.bin")


@pytest.fixture(scope="module")
def wine_reference_run(win_fmu, wine_env, win_host, tmp_path_factory):
    """The FMU's reference input co-simulated by its DLL under wine, with the FMU state saved
    half-way and restored after the last sample: (expected outputs, outputs, the outputs after the
    restore for the second half, index of the restored sample), outputs (N, len(OUTPUTS))."""
    path, version = win_fmu
    unzipdir = tmp_path_factory.mktemp(f"wine-fmi{version}")
    extract_archive(path, unzipdir)
    description = read_description(path, unzipdir)
    with zipfile.ZipFile(path) as zf:
        in_names, inputs = read_reference_csv(zf.read(REFERENCE_INPUT).decode())
        out_names, expected = read_reference_csv(zf.read(REFERENCE_OUTPUT).decode())
    assert in_names == ("t", *INPUTS) and out_names == ("t", *OUTPUTS)
    _write_host_data(unzipdir, description, inputs[:, 0], inputs[:, 1:])
    restored = len(inputs) // 2
    dll = PureWindowsPath(_win64_member(version))   # relative to the working directory
    run = subprocess.run([WINE, str(win_host), str(version), str(dll), description.guid, str(restored)],
                         cwd=unzipdir, env=wine_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert run.returncode == 0, run.stderr
    outputs = np.fromfile(unzipdir / "outputs.bin", "<f8").reshape(-1, len(OUTPUTS))
    replay = np.fromfile(unzipdir / "replay.bin", "<f8").reshape(-1, len(OUTPUTS))
    return expected[:, 1:], outputs, replay, restored


def test_win64_dll_reproduces_the_reference_output_under_wine(wine_reference_run):
    """The DLL under wine (mingw's code, wine's msvcrt libm) gives the reference output within
    the Linux binary's bound (measured: 2.8e-17 for FMI 2 and 3, roll at one sample)."""
    expected, outputs, _, _ = wine_reference_run
    assert outputs.shape == expected.shape
    error = float(np.max(np.abs(outputs - expected)))
    assert error <= REFERENCE_TOLERANCE


def test_win64_dll_restores_a_serialized_state_under_wine(wine_reference_run):
    """Saved (get, serialize) before sample k and restored (deserialize, set) after the run, the
    DLL repeats samples k.. bit for bit: the same binary does the same arithmetic."""
    _, outputs, replay, restored = wine_reference_run
    np.testing.assert_array_equal(replay, outputs[restored:])
