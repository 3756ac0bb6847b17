"""A tampered serialized FMU state is reported, never executed (issue 16 item 1).

Serialized states carry an FNV-1a 64 checksum of their body (ModelCore.c ModelStateChecksum, pinned
here by `fnv1a64`); a restored state's settings and coefficients are re-derived from its
parameters and the compiled-in coefficients, and its evolving counters and indices are checked
(model.c ModelDataRestoredProblem). Seeded mutations of real states -- bit flips, edits of every
integer field that indexes, sizes or switches something, truncation, extension, each with the
checksum kept or recomputed -- are restored into FMI 2 and FMI 3 instances of a shipped FMU
(fmpy) and, a subset, into an AddressSanitizer + UndefinedBehaviorSanitizer build of the sources
(tests/c/state_fuzz.c). Each is rejected with an Error and one message, or restored to a state
that runs 100 steps with finite outputs.
"""
from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from debian_tools import debian_tool
from fmpy.fmi1 import FMICallException

from contract.layout import INPUTS, identity_coefficients
from fmu.compiler import FMPY_C_CODE as FMI_HEADERS, SOURCE_DIR, fmu_source_files
from fmu.cosim import Stepper, initialised_fmu
from fmu.header import HEADER_NAME, coefficient_header
from training.fmu_build import build_fmu

C_HARNESS = Path(__file__).parent / "c" / "state_fuzz.c"
#: The particle filter on with 2 x 2 cells per cube face: its bin list and counters are in the state.
SETTINGS = {"enable_pf": 1, "pf_sphere_bins": 2}
FMPY_MUTATIONS = 1000   # per FMI version
ASAN_MUTATIONS = 400
RESTORED_STEPS = 100
STEP_SIZE = 0.01        # s
BASE_STEPS = 300
FNV_OFFSET, FNV_PRIME = 14695981039346656037, 1099511628211
CHECKSUM_OFFSET = 56    # ModelStateHeader: magic (4), size (4), guid (48), checksum (8)
#: Hostile values written into an int field (index/size limits of the stages and beyond).
INT_VALUES = [-(2 ** 31), -1, 0, 1, 2, 3, 24, 63, 64, 65, 96, 97, 1000, 100000, 2 ** 31 - 1]
#: Hostile values written into a double field.
DOUBLE_VALUES = [float("nan"), float("inf"), -1.0, 0.0, 0.5, 3.0, 97.0, 1e9, 1e308]


def fnv1a64(data: bytes) -> int:
    """FNV-1a 64 of data (the same constants as ModelCore.c ModelStateChecksum)."""
    h = FNV_OFFSET
    for b in data:
        h = ((h ^ b) * FNV_PRIME) & 0xFFFFFFFFFFFFFFFF
    return h


def reseal(state: bytearray, header_size: int) -> bytearray:
    """Write the checksum of the body (bytes after the header) into the header."""
    state[CHECKSUM_OFFSET:CHECKSUM_OFFSET + 8] = struct.pack("<Q", fnv1a64(bytes(state[header_size:])))
    return state


def mutations(base: bytes, fields: dict[str, tuple[int, int]], header_size: int, n: int,
              seed: int) -> list[tuple[str, bytes, bool]]:
    """n mutated copies of a serialized state: (description, bytes, must_reject). The first ones
    edit every field of `fields` (name -> (offset, size)) with a resealed checksum; the rest are
    random bit flips, field edits, truncations and extensions, half of those resealed."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str, bytes, bool]] = []
    names = sorted(fields)
    for name in names:  # every listed field at least once, resealed: the field check must hold
        out.append(_edit(base, name, *fields[name], rng, header_size, reseal_it=True))
    while len(out) < n:
        kind = rng.integers(4)
        resealed = bool(rng.integers(2))
        if kind == 0:
            state = bytearray(base)
            for _ in range(rng.integers(1, 9)):
                bit = int(rng.integers(header_size * 8, len(state) * 8))
                state[bit // 8] ^= 1 << (bit % 8)
            out.append((f"bit flips (resealed {resealed})", bytes(reseal(state, header_size) if resealed else state),
                        not resealed))
        elif kind == 1:
            name = names[rng.integers(len(names))]
            out.append(_edit(base, name, *fields[name], rng, header_size, reseal_it=resealed))
        elif kind == 2:
            out.append(("truncated", base[:int(rng.integers(0, len(base)))], True))
        else:
            out.append(("extended", base + bytes(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8)), True))
    return out


def _edit(base: bytes, name: str, offset: int, size: int, rng, header_size: int, reseal_it: bool):
    """One field of base set to a hostile value (int32 or double by size)."""
    state = bytearray(base)
    if size == 4:
        value = INT_VALUES[rng.integers(len(INT_VALUES))]
        state[offset:offset + 4] = struct.pack("<i", value)
    else:
        value = DOUBLE_VALUES[rng.integers(len(DOUBLE_VALUES))]
        state[offset:offset + 8] = struct.pack("<d", value)
    changed = bytes(state) != base
    if reseal_it:
        reseal(state, header_size)
    return f"{name} = {value} (resealed {reseal_it})", bytes(state), changed and not reseal_it


@pytest.fixture(scope="module")
def harness(tmp_path_factory) -> Path:
    """tests/c/state_fuzz.c with the FMI 3 sources under ASan + UBSan (identity coefficients)."""
    cc = debian_tool("gcc")
    folder = tmp_path_factory.mktemp("state_fuzz")
    (folder / HEADER_NAME).write_text(
        coefficient_header(np.array(identity_coefficients()), {}, "{state-fuzz}", "state fuzz test"))
    program = folder / "state_fuzz"
    sources = [str(p) for p in fmu_source_files(fmi_version=3) if p.suffix == ".c"]
    result = subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-g", "-O1",
                             "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer",
                             f"-I{folder}", f"-I{SOURCE_DIR}", f"-I{FMI_HEADERS}", str(C_HARNESS), *sources,
                             "-o", str(program), "-lm"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert result.returncode == 0, result.stdout
    return program


@pytest.fixture(scope="module")
def layout(harness) -> dict[str, tuple[int, int]]:
    """ModelState member -> (offset, size) as the compiler lays it out (the harness prints it)."""
    lines = subprocess.run([str(harness), "layout"], check=True, stdout=subprocess.PIPE, text=True).stdout
    return {name: (int(offset), int(size)) for name, offset, size in (line.split() for line in lines.splitlines())}


@pytest.fixture(scope="module")
def header_size(layout) -> int:
    """Bytes of ModelStateHeader: phase is the first member after it."""
    return layout["phase"][0]


def _fmu(tmp_path_factory, version: int) -> Path:
    return build_fmu(np.array(identity_coefficients()), SETTINGS, tmp_path_factory.mktemp(f"fuzz{version}") / "ImuFusion.fmu",
                     fmi_version=version)


def _sample(k: int) -> np.ndarray:
    """Sample k of a turning, rocking sensor (the same motion as tests/c/state_fuzz.c)."""
    t = k * STEP_SIZE
    roll, pitch, yaw = 0.3 * np.sin(1.3 * t), 0.2 * np.sin(0.9 * t), 0.5 * t
    x = np.zeros(len(INPUTS))
    x[:10] = [0.39 * np.cos(1.3 * t), 0.18 * np.cos(0.9 * t), 0.5,
              9.80665 * np.sin(pitch), -9.80665 * np.sin(roll) * np.cos(pitch), -9.80665 * np.cos(roll) * np.cos(pitch),
              20.0 * np.cos(yaw) + 3.0, -20.0 * np.sin(yaw) - 2.0, 40.0, 20.0 + 0.5 * t]
    return x


SAMPLES = np.array([_sample(k) for k in range(BASE_STEPS + RESTORED_STEPS)])


def _run(stepper: Stepper, first: int, count: int) -> str:
    """Step `count` samples from sample `first`: 'finite', 'nonfinite' or 'steperror'."""
    finite = True
    for k in range(first, first + count):
        stepper.set_inputs(SAMPLES[k])
        try:
            stepper.do_step(k * STEP_SIZE, STEP_SIZE)
        except FMICallException:
            return "steperror"
        finite &= bool(np.all(np.isfinite(stepper.get_outputs())))
    return "finite" if finite else "nonfinite"


def _fuzz_fmpy(fmu_path: Path, layout, header_size: int, seed: int) -> list[tuple[str, str, str]]:
    """Restore FMPY_MUTATIONS mutations of a real state into one instance (the clean state set
    back between them): (description, outcome, message) per mutation; also checks the rules."""
    results = []
    with initialised_fmu(fmu_path, 0.0, SETTINGS) as fmu:
        stepper = Stepper(fmu)
        assert _run(stepper, 0, BASE_STEPS) == "finite"
        clean = fmu.getFMUState()
        base = bytes(fmu.serializeFMUState(clean))
        assert struct.unpack_from("<Q", base, CHECKSUM_OFFSET)[0] == fnv1a64(base[header_size:])
        for description, state, must_reject in mutations(base, layout, header_size, FMPY_MUTATIONS, seed):
            logged = len(fmu.log_messages)
            try:
                restored = fmu.deserializeFMUState(state)
                try:
                    fmu.setFMUState(restored)
                finally:
                    fmu.freeFMUState(restored)
                outcome = _run(stepper, BASE_STEPS, RESTORED_STEPS)
            except FMICallException:
                outcome = "rejected"
            errors = [m for m in fmu.log_messages[logged:] if m.startswith("[ERROR]")]
            results.append((description, outcome, errors[0] if errors else ""))
            _check(description, outcome, len(errors), must_reject)
            fmu.setFMUState(clean)
        fmu.freeFMUState(clean)
    return results


def _check(description: str, outcome: str, errors: int, must_reject: bool) -> None:
    """The rule every mutation must satisfy."""
    if must_reject:
        assert outcome == "rejected", description
    if outcome == "rejected":
        assert errors == 1, f"{description}: {errors} error messages"
    elif outcome == "steperror":  # a valid restored phase that does not step (Instantiated, Terminated, ...)
        assert description.startswith("phase") or description.startswith("bit flips"), description
    else:
        assert outcome == "finite", description


def test_checksum_is_fnv1a64_of_the_body_and_pinned():
    assert fnv1a64(b"") == FNV_OFFSET
    assert fnv1a64(b"a") == 0xAF63DC4C8601EC8C  # the published FNV-1a 64 test vector


@pytest.mark.parametrize("version", [2, 3])
def test_mutated_states_are_rejected_or_run_finite_through_the_shipped_binary(tmp_path_factory, layout, header_size,
                                                                            version):
    results = _fuzz_fmpy(_fmu(tmp_path_factory, version), layout, header_size, seed=16 + version)
    outcomes = [r[1] for r in results]
    assert len(results) >= FMPY_MUTATIONS
    assert outcomes.count("rejected") > 0 and outcomes.count("finite") > 0
    messages = {r[2] for r in results if r[1] == "rejected"}
    assert any("checksum" in m for m in messages)
    assert any("invalid FMU state" in m for m in messages)  # a resealed state caught by the field check


def test_resealed_edits_of_indices_are_rejected_with_the_field_named(tmp_path_factory, layout, header_size):
    """Each edit alone would index out of bounds (ImuAlign.c, ImuMagPf.c) on the old code."""
    fmu_path = _fmu(tmp_path_factory, 3)
    with initialised_fmu(fmu_path, 0.0, SETTINGS) as fmu:
        stepper = Stepper(fmu)
        _run(stepper, 0, BASE_STEPS)
        base = bytes(fmu.serializeFMUState(fmu.getFMUState()))
        for name, value, word in [("model.runtime.pipeline.align.head", 100000, "head"),
                                  ("model.runtime.pipeline.pf.binCount", 97, "bin"),
                                  ("model.runtime.pipeline.pf.binUsed[5]", 1, "bin"),
                                  ("model.runtime.pipeline.pf.sampleCounter", -5, "sample counter")]:
            offset, _ = layout[name]
            state = bytearray(base)
            state[offset:offset + 4] = struct.pack("<i", value)
            logged = len(fmu.log_messages)
            with pytest.raises(FMICallException):
                fmu.setFMUState(fmu.deserializeFMUState(bytes(reseal(state, header_size))))
            message = fmu.log_messages[logged:]
            assert len(message) == 1 and "invalid FMU state" in message[0] and word in message[0], message


def _align_newest(layout, base: bytes) -> tuple[int, int]:
    """(offset, size) of align.time[head] in base (the newest buffered time)."""
    head = struct.unpack_from("<i", base, layout["model.runtime.pipeline.align.head"][0])[0]
    return layout["model.runtime.pipeline.align.time[0]"][0] + 8 * head, 8


@pytest.mark.parametrize("name, value, words", [
    ("model.runtime.guard.clock", 1e300, "clock"),
    ("model.runtime.guard.clock", float("nan"), "clock"),
    ("model.runtime.guard.clock", -1.0, "clock"),
    ("align newest time", 1e300, "time-alignment"),
    ("model.runtime.pipeline.terms.lastTime", 1e300, "correction terms"),
    ("model.runtime.pipeline.psobp.time", 1e300, "PSO-BP"),
    ("model.runtime.pipeline.attitude.accLowPass.count", -1, "low-pass"),
    ("model.runtime.pipeline.attitude.motionBias.rotatedBias.count", -7, "low-pass"),
    ("model.runtime.pipeline.attitude.nominalStep", float("inf"), "nominal step"),
])
def test_resealed_clocks_and_filter_counts_outside_what_a_run_can_reach_are_rejected(tmp_path_factory, layout,
                                                                                   header_size, name, value, words):
    """Issue 31 item 10: each of these, resealed, was accepted by the old code and changed every later
    step (a clock or a buffered time at 1e300 stops the time-alignment buffer and the terms from
    advancing; a low-pass count of -1 divides by zero at the next sample). A valid run cannot reach
    them: the newest buffered time and the terms' last time equal the guard's clock, which resolves
    the nominal step; the counts are >= 0."""
    fmu_path = _fmu(tmp_path_factory, 3)
    with initialised_fmu(fmu_path, 0.0, SETTINGS) as fmu:
        stepper = Stepper(fmu)
        _run(stepper, 0, BASE_STEPS)
        base = bytes(fmu.serializeFMUState(fmu.getFMUState()))
        offset, size = _align_newest(layout, base) if name == "align newest time" else layout[name]
        state = bytearray(base)
        state[offset:offset + size] = struct.pack("<i", value) if size == 4 else struct.pack("<d", value)
        logged = len(fmu.log_messages)
        with pytest.raises(FMICallException):
            fmu.setFMUState(fmu.deserializeFMUState(bytes(reseal(state, header_size))))
        message = fmu.log_messages[logged:]
        assert len(message) == 1 and "invalid FMU state" in message[0] and words in message[0], message


def test_mutated_states_under_address_and_undefined_behaviour_sanitizers(harness, layout, header_size, tmp_path):
    base_path = tmp_path / "base.bin"
    subprocess.run([str(harness), "base", str(base_path)], check=True)
    base = base_path.read_bytes()
    cases = mutations(base, layout, header_size, ASAN_MUTATIONS, seed=1616)
    records = tmp_path / "records.bin"
    records.write_bytes(b"".join(struct.pack("<Q", len(state)) + state for _, state, _ in cases))
    result = subprocess.run([str(harness), "restore", str(records)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stdout[-3000:]  # a sanitizer report exits non-zero
    lines = result.stdout.splitlines()
    assert len(lines) == len(cases)
    for (description, _, must_reject), line in zip(cases, lines):
        outcome = line.split(" ", 1)[0]
        _check(description, outcome, 1 if outcome == "rejected" and len(line) > len("rejected ") else 0, must_reject)
