"""Training time on the default calibration set (issue 18 item 3): `imufmu train` on the main job's
calibration recording (scenarios/calibration.toml, seed 0) as a user runs it, in a child process,
wall and CPU time [s] (the child's user + system time), median of RUNS runs, on a quiet machine
and with a second CPU-bound process running beside it (a busy loop in another process, as when the
machine is shared). The child runs without OMP_NUM_THREADS, as from a user's shell (torch sizes
its threads itself). The acceptance bound is 60 s wall in both.

With --profile it says instead where the time of one training goes: the child runs under cProfile
and each stage of `train` is the cumulative time of the function that runs it (PROFILE_STAGES).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_time.py [--runs N] [--profile] [--data CSV]
"""
from __future__ import annotations

import argparse
import multiprocessing
import os
import pstats
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


#: (stage, function that runs it: file suffix and name) of one `imufmu train`, in the order they run.
PROFILE_STAGES = (("reading the recordings", "training/data/io.py", "read_imu_csv"),
                  ("gain/bias fits against the reference", "training/train.py", "_reference_fits"),
                  ("self-calibration (triads without reference)", "training/train.py", "_self_calibrated"),
                  ("ELM stage (held-out folds, final fit)", "training/train.py", "_elm_stage"),
                  ("PSO-BP stage (held-out decision, final fit)", "training/train.py", "_psobp_stage"),
                  ("held-out refit of every triad", "training/train.py", "_held_out"),
                  ("calibration report and plots", "training/reports/calibration_report.py",
                   "write_calibration_report"))


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
        times = [_timed_train(data, work / f"{'loaded' if loaded else 'quiet'}_run{k}") for k in range(runs)]
    finally:
        if hog is not None:
            hog.terminate()
            hog.join()
    return float(np.median([w for w, _ in times])), float(np.median([c for _, c in times]))


def _cumulative(stats: pstats.Stats, file_suffix: str, name: str) -> float:
    """Cumulative time [s] of the function `name` defined in a file ending with `file_suffix`
    (0 when it did not run)."""
    return sum(row[3] for (file, _, function), row in stats.stats.items()
               if function == name and file.endswith(file_suffix))


def profile_table(data: Path, out: Path) -> str:
    """Markdown table: where one `imufmu train DATA` spends its wall time, by stage (PROFILE_STAGES),
    with Python's start-up and imports as the rest of the process."""
    prof = out / "train.prof"
    subprocess.run([sys.executable, "-m", "cProfile", "-o", str(prof), "-m", "training.cli", "train", str(data),
                    "--out", str(out / "model")], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, cwd=ROOT)
    stats = pstats.Stats(str(prof))
    total = _cumulative(stats, "training/cli.py", "main")
    rows = [(label, _cumulative(stats, suffix, name)) for label, suffix, name in PROFILE_STAGES]
    rows.append(("the rest: argument parsing with the imports it triggers (torch), summary",
                 total - sum(t for _, t in rows)))
    lines = ["| stage | time [s] | share |", "|---|---|---|"]
    lines += [f"| {label} | {t:.1f} | {100 * t / total:.0f} % |" for label, t in rows]
    lines.append(f"| total (`training.cli.main`, under cProfile) | {total:.1f} | 100 % |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=RUNS)
    parser.add_argument("--profile", action="store_true", help="where the time of one training goes, by stage")
    parser.add_argument("--data", type=Path, help="train on this recording instead of the default calibration set")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="imufusion-train-time-") as tmp:
        work = Path(tmp)
        data = args.data or simulate_to_dir(SCENARIO_DIR / DEFAULT_CALIBRATION, work / "data", seed=0)
        if args.profile:
            print(profile_table(data, work))
            return
        rows = [("quiet", _condition(data, work, args.runs, loaded=False)),
                ("beside a CPU-bound process", _condition(data, work, args.runs, loaded=True))]
    print(f"| machine | wall [s], median of {args.runs} | CPU [s], median of {args.runs} | wall ≤ {WALL_BOUND_S:g} s |")
    print("|---|---|---|---|")
    for label, (wall, cpu) in rows:
        print(f"| {label} | {wall:.1f} | {cpu:.1f} | {'yes' if wall <= WALL_BOUND_S else 'no'} |")


if __name__ == "__main__":
    main()
