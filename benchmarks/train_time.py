"""Training time on the default calibration set (issue 18 item 3): `imufmu train` on the main job's
calibration recording (scenarios/calibration.toml, seed 0) as a user runs it, in a child process,
wall and CPU time [s] (the child's user + system time), median of RUNS runs, on a quiet machine
and with a second CPU-bound process running beside it (a busy loop in another process, as when the
machine is shared). The child runs without OMP_NUM_THREADS, as from a user's shell (torch sizes
its threads itself). The acceptance bound is 60 s wall in both.

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_time.py [--runs N]
"""
from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from training.main_job import DEFAULT_CALIBRATION, SCENARIO_DIR  # noqa: E402
from training.simulator.simulate import simulate_to_dir  # noqa: E402

#: Runs per condition (the median is reported).
RUNS = 3
#: Acceptance bound [s] of issue 18.
WALL_BOUND_S = 60.0


def _busy_loop() -> None:
    """A CPU-bound process: spins until terminated."""
    while True:
        pass


def _timed_train(data: Path, out: Path) -> tuple[float, float]:
    """(wall [s], CPU [s]) of one `imufmu train DATA --out OUT` child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}  # what a user's shell has
    subprocess.run([sys.executable, "-m", "training.cli", "train", str(data), "--out", str(out)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT, env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _condition(data: Path, work: Path, runs: int, loaded: bool) -> tuple[float, float]:
    """Median (wall, CPU) [s] over `runs` trainings, with a busy process beside them if `loaded`."""
    hog = multiprocessing.Process(target=_busy_loop, daemon=True) if loaded else None
    if hog is not None:
        hog.start()
    try:
        times = [_timed_train(data, work / f"run{k}") for k in range(runs)]
    finally:
        if hog is not None:
            hog.terminate()
            hog.join()
    return float(np.median([w for w, _ in times])), float(np.median([c for _, c in times]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=RUNS)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="imufusion-train-time-") as tmp:
        work = Path(tmp)
        data = simulate_to_dir(SCENARIO_DIR / DEFAULT_CALIBRATION, work / "data", seed=0)
        rows = [("quiet", _condition(data, work, args.runs, loaded=False)),
                ("beside a CPU-bound process", _condition(data, work, args.runs, loaded=True))]
    print(f"| machine | wall [s], median of {args.runs} | CPU [s], median of {args.runs} | wall ≤ {WALL_BOUND_S:g} s |")
    print("|---|---|---|---|")
    for label, (wall, cpu) in rows:
        print(f"| {label} | {wall:.1f} | {cpu:.1f} | {'yes' if wall <= WALL_BOUND_S else 'no'} |")


if __name__ == "__main__":
    main()
