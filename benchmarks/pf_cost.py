"""Per-sample cost of the chain with the particle filter, from C through the FMU, against VQF in the
same run (issue 18 item 4; docs/magpf.md, *Cost*): prints a Markdown table.

    python benchmarks/pf_cost.py [--trial 33] [--seconds S] [--repeats 3] [--out DIR]

1. Training stand-in (as `bench_magpf.broad_train`): the magnetometer calibration that training on
   BROAD 01 + 02 gives (batch ellipsoid fit, `bench_magpf.train_calibration`) and the filter
   settings `imufmu train` writes from that calibrated field (`pf_settings_from_calibration`),
   attitude_mode 1, rest_gyro_threshold 0.035, the trial's field norm and dip, `enable_pf` 1.
2. The FMU of those coefficients and settings, built by the project's builder
   (`training.fmu_build.build_fmu`, FMI 3), and the C host `benchmarks/c/pf_cost_host.c`, which
   dlopens the FMU's binary and co-simulates the recording sample by sample (set inputs, doStep,
   get outputs), timing that loop with clock_gettime; best of `--repeats` runs.
3. Rows: filter off (`enable_pf` 0); filter on while it holds the trained calibration (the samples
   before its first declared change, found with the batch runtime); filter at train's settings on
   the whole recording (held until the magnet is attached, adapting from then on); adapting from the
   start (`pf_hold_prior` 0); VQF (PyPI `vqf`, its C++ core through `VQF.updateBatch`, the whole
   recording in one call, 9D with default parameters), best of the same number of runs.
"""
from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy
import numpy as np

from contract.layout import INPUTS, OUTPUTS, settings_array
from fmu.compiler import FMPY_C_CODE, binary_path
from training.data.dataset import ImuData
from training.fmu_build import build_fmu
from training.runtime import run_batch

HOST_SOURCE = Path(__file__).resolve().parent / "c" / "pf_cost_host.c"
#: Compiler flags of the host (the FMU's own binary is built by the project's builder).
HOST_FLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Werror")
#: FMI 3 type of a parameter -> the host's kind letter.
HOST_KINDS = {"Float64": "r", "Int32": "i", "Boolean": "b"}
HARD_IRON = [OUTPUTS.index(n) for n in ("hard_iron_x", "hard_iron_y", "hard_iron_z")]
#: Trial of the table and the attitude settings of the training stand-in (bench_magpf.TRAIN_ATTITUDE).
DEFAULT_TRIAL = "33"


@dataclass(frozen=True)
class Fmu:
    """An extracted FMU binary: library path, instantiation token, value references by name,
    FMI 3 type by name."""

    library: Path
    token: str
    vr: dict
    kind: dict


@dataclass(frozen=True)
class Row:
    """One table row: label, samples timed, µs per sample (None: nothing to time)."""

    label: str
    samples: int
    us: float | None


def compile_host(out_dir: Path) -> Path:
    """Compile benchmarks/c/pf_cost_host.c into out_dir with env CC (default cc, as the runtime);
    RuntimeError with the compiler output."""
    host = out_dir / "pf_cost_host"
    cmd = [*(shlex.split(os.environ.get("CC", "cc")) or ["cc"]), *HOST_FLAGS, f"-I{FMPY_C_CODE}", str(HOST_SOURCE), "-o", str(host), "-ldl"]
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"pf_cost: cannot compile {HOST_SOURCE.name}: {result.stdout.strip()}")
    return host


def extract_fmu(fmu_path: Path, out_dir: Path) -> Fmu:
    """The FMU's FMI 3 binary extracted into out_dir, with its token and variables."""
    description = fmpy.read_model_description(str(fmu_path))
    member = binary_path(Path(), description.coSimulation.modelIdentifier, 3).as_posix()
    with zipfile.ZipFile(fmu_path) as zf:
        library = Path(zf.extract(member, out_dir))
    variables = description.modelVariables
    return Fmu(library, description.guid, {v.name: v.valueReference for v in variables},
               {v.name: v.type for v in variables})


def write_samples(path: Path, t: np.ndarray, inputs: np.ndarray) -> None:
    """Rows [t, h, inputs...] as float64 for the host (h: time to the next sample, the last
    repeats the previous one, as fmu.cosim.step_sizes)."""
    h = np.append(np.diff(t), np.diff(t)[-1:]) if len(t) > 1 else np.array([0.01])
    np.column_stack([t, h, inputs]).astype(np.float64).tofile(path)


def run_host(host: Path, fmu: Fmu, samples: Path, repeats: int, parameters: dict) -> float:
    """Best µs per sample of the host over `repeats` co-simulations with these parameters set."""
    args = [f"{HOST_KINDS[fmu.kind[name]]}:{fmu.vr[name]}={value!r}" for name, value in parameters.items()]
    cmd = [str(host), str(fmu.library), fmu.token, str(samples), str(repeats),
           ",".join(str(fmu.vr[n]) for n in INPUTS), ",".join(str(fmu.vr[n]) for n in OUTPUTS), *args]
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"pf_cost: the host failed: {result.stdout.strip()}")
    values = dict(line.split(" ", 1) for line in result.stdout.splitlines())
    return float(values["best_us_per_sample"])


def vqf_us(data: ImuData, repeats: int) -> float:
    """Best µs per sample of VQF 9D (default parameters) on the recording, one updateBatch call."""
    from vqf import VQF
    gyr, acc, mag = (np.ascontiguousarray(a, dtype=np.float64) for a in (data.gyr, data.acc, data.mag))
    ts = float(np.median(np.diff(data.t)))
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        VQF(ts).updateBatch(gyr, acc, mag)
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / len(data)


def held_samples(coefficients: np.ndarray, settings: dict, t: np.ndarray, inputs: np.ndarray) -> int:
    """Samples before the filter first leaves the trained calibration (its hard-iron output moves),
    from the batch runtime: the stretch over which the filter only holds."""
    hard = run_batch(coefficients, settings_array(settings), t, inputs)[:, HARD_IRON]
    moved = np.flatnonzero(np.any(hard != hard[0], axis=1))
    return int(moved[0]) if moved.size else len(t)


def measure(data: ImuData, coefficients: np.ndarray, settings: dict, out_dir: Path, repeats: int) -> list[Row]:
    """The table's rows for a recording, the model's coefficients and settings (enable_pf set to 1
    in the FMU; the rows switch it and pf_hold_prior as parameters)."""
    settings = {**settings, "enable_pf": 1.0}
    t, inputs = data.t - data.t[0], data.inputs()
    fmu = extract_fmu(build_fmu(np.asarray(coefficients, dtype=float), settings, out_dir / "ImuFusion.fmu",
                                fmi_version=3), out_dir)
    host = compile_host(out_dir)
    whole = out_dir / "samples.bin"
    write_samples(whole, t, inputs)
    held = held_samples(coefficients, settings, t, inputs)
    hold = float(settings.get("pf_hold_prior", 1.0))
    rows = [Row("filter off (enable_pf 0)", len(t), run_host(host, fmu, whole, repeats, {"enable_pf": 0}))]
    held_us = None
    if held > 1:
        prefix = out_dir / "held.bin"
        write_samples(prefix, t[:held], inputs[:held])
        held_us = run_host(host, fmu, prefix, repeats, {"enable_pf": 1})
    rows.append(Row("filter held: the trained calibration, before the first declared change", held, held_us))
    rows.append(Row(f"filter at train's settings, whole recording (pf_hold_prior {hold:g}: held, adapting "
                    "after each declared change)", len(t), run_host(host, fmu, whole, repeats, {"enable_pf": 1})))
    rows.append(Row("filter adapting from the start (pf_hold_prior 0)", len(t),
                    run_host(host, fmu, whole, repeats, {"enable_pf": 1, "pf_hold_prior": 0})))
    rows.append(Row("VQF 9D (vqf.VQF.updateBatch, C++ core, default parameters)", len(t), vqf_us(data, repeats)))
    return rows


def table(rows: list[Row]) -> str:
    """Markdown table: µs per sample and × VQF (the last row)."""
    reference = rows[-1].us
    lines = ["| configuration | samples | µs/sample | × VQF |", "|---|---|---|---|"]
    for row in rows:
        cells = ("—", "—") if row.us is None else (f"{row.us:.2f}", f"{row.us / reference:.2f}")
        lines.append(f"| {row.label} | {row.samples} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)


def trained_model(data: ImuData) -> tuple[np.ndarray, dict]:
    """(coefficients, settings) of the training stand-in on BROAD 01 + 02 for a BROAD recording."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_magpf
    from training.models import pf_settings
    _, norm, coefficients, calibrated, t = bench_magpf.train_calibration()
    rate = float(bench_magpf._trial(bench_magpf.TRAIN_TRIALS[0]).meta["rate_hz"])
    derived = pf_settings.pf_settings_from_calibration(calibrated, t, norm, rate)
    earth = data.meta["earth_field"]
    settings = {"field_norm": float(earth["norm_ut"]), "field_dip": float(np.deg2rad(earth["dip_deg"])),
                **bench_magpf.TRAIN_ATTITUDE, **derived}
    return coefficients, settings


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--trial", default=DEFAULT_TRIAL, help="BROAD trial number (default 33, magnet at 2 cm)")
    p.add_argument("--seconds", type=float, default=None, help="only the first S seconds of the trial")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", default=None, help="folder for the FMU, host and samples (default: a temporary one)")
    a = p.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_magpf
    if not bench_magpf.BROAD.is_dir():
        print(f"pf_cost: BROAD data not found at {bench_magpf.BROAD}", file=sys.stderr)
        return 1
    data = bench_magpf._trial(a.trial)
    if a.seconds is not None:
        data = data.slice(slice(0, int(a.seconds * float(data.meta["rate_hz"]))))
    coefficients, settings = trained_model(data)
    with tempfile.TemporaryDirectory(prefix="pf_cost-") as tmp:
        out_dir = Path(a.out) if a.out else Path(tmp)
        out_dir.mkdir(parents=True, exist_ok=True)
        rows = measure(data, coefficients, settings, out_dir, a.repeats)
    print(f"BROAD {data.name}: {len(data)} samples at {float(data.meta['rate_hz']):.1f} Hz; µs per sample, "
          f"best of {a.repeats}; settings {settings}\n")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
