"""Peak memory and time of training.data.io.read_imu_csv on a large recording (issue 15, item 9).

Writes a plausible imu-csv/1 file of ROWS rows (11 columns, 100 Hz, seeded) unless it exists, then
reads it in a child process and prints the child's peak RSS (resource.getrusage ru_maxrss) and
wall time, beside the size of the arrays the loader returns.

    .venv/bin/python benchmarks/load_memory.py [--rows 10000000] [--file /tmp/rows.csv]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

HEADER = "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z,temp"
WRITE_BLOCK = 500_000
SEED = 0

CHILD = """
import resource, sys, time
from training.data.io import read_imu_csv
t0 = time.perf_counter()
data = read_imu_csv(sys.argv[1])
print(len(data), time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
"""


def write_recording(path: Path, rows: int) -> None:
    """A level sensor at rest with noise, 25 °C, in a 20/40 µT field; t = k / 100 s."""
    rng = np.random.default_rng(SEED)
    with open(path, "w") as f:
        f.write(HEADER + "\n")
        for start in range(0, rows, WRITE_BLOCK):
            n = min(WRITE_BLOCK, rows - start)
            k = np.arange(start, start + n)
            cols = [k / 100.0, *rng.normal(0, 0.01, (3, n)), *rng.normal(0, 0.05, (2, n)),
                    -9.81 + rng.normal(0, 0.05, n), 20 + rng.normal(0, 0.3, n), rng.normal(0, 0.3, n),
                    40 + rng.normal(0, 0.3, n), 25 + rng.normal(0, 0.1, n)]
            np.savetxt(f, np.column_stack(cols), fmt=["%.2f"] + ["%.6g"] * 10, delimiter=",")
    path.with_suffix(".json").write_text(json.dumps({"format": "imu-csv/1", "rate_hz": 100.0}))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", type=int, default=10_000_000)
    p.add_argument("--file", type=Path, default=Path("/tmp/imufusion_rows.csv"))
    args = p.parse_args()
    if not args.file.is_file():
        write_recording(args.file, args.rows)
    out = subprocess.run([sys.executable, "-c", CHILD, str(args.file)], capture_output=True, text=True, check=True)
    rows, seconds, rss = out.stdout.split()
    arrays = int(rows) * len(HEADER.split(",")) * 8
    print(f"{args.file} ({args.file.stat().st_size / 1e9:.2f} GB, {int(rows)} rows): peak RSS "
          f"{int(rss) / 1e9:.2f} GB, arrays {arrays / 1e9:.2f} GB, {float(seconds):.1f} s")


if __name__ == "__main__":
    main()
