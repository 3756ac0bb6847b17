"""Issue 35's acceptance table: BROAD trials 01 + 02 trained with and without ref_q (the latter from copies
written without the reference columns), both FMUs run through fmpy over the 20 BROAD trials; at every rest
their quaternions agree within 2° (training.bench.frame_agreement). Prints the table of docs/fmu.md (Frames).

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/frame_agreement.py [--trials 01 02 ...] [--seconds S]
       [--train-seconds S] [--keep DIR]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from training.bench.frame_agreement import frame_agreement, print_table  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", nargs="+", help="trial numbers (default: all 20)")
    parser.add_argument("--seconds", type=float, help="run only each trial's first seconds")
    parser.add_argument("--train-seconds", type=float, help="train on only the first seconds of 01 and 02")
    parser.add_argument("--keep", help="folder for the models and FMUs (default: a temporary one)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="imufusion-frames-") as tmp:
        rows = frame_agreement(Path(args.keep or tmp), args.trials, args.seconds, args.train_seconds)
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
