"""What the FMU state costs: size and time per call of get, set (restore, with its field check and
re-derivation), serialize and deserialize (with its checksum), against one doStep, through fmpy,
for FMI 2 and FMI 3 FMUs with identity coefficients and the default settings (particle filter off
and on). A Monte-Carlo campaign restores a state per run: this says what that costs in steps.
Times are medians of 5 batches [µs per call] on this machine, fmpy's ctypes call included.

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/state_cost.py [--calls N]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from fmpy.fmi3 import FMU3Slave  # noqa: E402

from contract.layout import identity_coefficients  # noqa: E402
from fmu.cosim import initialised_fmu  # noqa: E402
from training.fmu_build import build_fmu  # noqa: E402

#: Calls per timed batch and batches per figure.
CALLS = 2000
BATCHES = 5
STEP_S = 0.01


def _per_call_us(call, calls: int) -> float:
    """Median over BATCHES of the mean time of `call()` [µs] in a batch of `calls`."""
    times = []
    for _ in range(BATCHES):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        times.append((time.perf_counter() - start) / calls * 1e6)
    return float(np.median(times))


def _verbs(fmu) -> dict:
    """The FMI state verbs of an FMU2Slave / FMU3Slave under one spelling."""
    if isinstance(fmu, FMU3Slave):
        return {"get": fmu.getFMUState, "set": fmu.setFMUState, "free": fmu.freeFMUState,
                "serialize": fmu.serializeFMUState, "deserialize": fmu.deserializeFMUState}
    return {"get": fmu.getFMUstate, "set": fmu.setFMUstate, "free": fmu.freeFMUstate,
            "serialize": fmu.serializeFMUstate, "deserialize": fmu.deSerializeFMUstate}


def _row(path: Path, label: str, parameters: dict, calls: int) -> str:
    """The table row of one FMU and parameter set: state size and per-call times of `calls`-call batches."""
    with initialised_fmu(path, parameters=parameters) as fmu:
        step = fmu.doStep if not isinstance(fmu, FMU3Slave) else (lambda t, h: fmu.doStep(t, h))
        for k in range(200):
            step(k * STEP_S, STEP_S)
        verbs = _verbs(fmu)
        state = verbs["get"]()
        blob = verbs["serialize"](state)
        costs = {
            "doStep": _per_call_us(lambda: step(2.0, STEP_S), calls),
            "get + free": _per_call_us(lambda: verbs["free"](verbs["get"]()), calls),
            "set": _per_call_us(lambda: verbs["set"](state), calls),
            "serialize": _per_call_us(lambda: verbs["serialize"](state), calls),
            "deserialize + free": _per_call_us(lambda: verbs["free"](verbs["deserialize"](blob)), calls),
        }
        verbs["free"](state)
    cells = " | ".join(f"{v:.1f}" for v in costs.values())
    return f"| {label} | {len(blob) / 1024:.1f} | {cells} | {costs['set'] / costs['doStep']:.1f} |"


def main() -> None:
    """Build the FMI 2 and FMI 3 FMUs, time the state verbs, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=CALLS, help=f"calls per timed batch (default {CALLS})")
    calls = parser.parse_args().calls
    rows = []
    with tempfile.TemporaryDirectory(prefix="imufusion-state-") as tmp:
        for fmi in (2, 3):
            path = build_fmu(np.asarray(identity_coefficients()), {}, Path(tmp) / f"fmi{fmi}.fmu", fmi_version=fmi)
            for label, parameters in (("particle filter off", {}), ("particle filter on", {"enable_pf": True})):
                rows.append(_row(path, f"FMI {fmi}, {label}", parameters, calls))
    print("| FMU | state [KiB] | doStep [µs] | get + free [µs] | set [µs] | serialize [µs] | "
          "deserialize + free [µs] | set / doStep |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
