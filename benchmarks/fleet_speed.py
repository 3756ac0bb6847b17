"""Fleet training on Dask (issue 19 acceptance): N simulated units, one with a 10× gyro bias and one
with a recording cut short, trained by `imufmu fleet train` with 1 and with 2 workers of the local
cluster. Prints the wall times and their ratio (bound 0.6 on a 2-core machine), whether the two runs
wrote identical models, the outliers named and the failed units with their reasons.

Usage: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_speed.py [--devices 200] [--work DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from tqdm import tqdm  # noqa: E402

from training.fleet.report import write_fleet_report  # noqa: E402
from training.fleet.simulate import simulate_unit, unit_name  # noqa: E402
from training.fleet.spec import load_fleet  # noqa: E402
from training.fleet.train import train_fleet  # noqa: E402

FLEET = ROOT / "scenarios" / "fleet" / "mems_grade.toml"
#: The faulty units, as shares of the fleet: one with ten times its drawn gyro bias, one whose
#: calibration recording is cut short.
BIASED_SHARE, CUT_SHARE = 1 / 3, 2 / 3
#: Bound of issue 19 on wall(2 workers) / wall(1 worker).
RATIO_BOUND = 0.6


def simulate(devices: int, folder: Path) -> None:
    """The fleet with its two faulty units."""
    spec = load_fleet(FLEET)
    biased, cut_unit = int(devices * BIASED_SHARE), int(devices * CUT_SHARE)
    for k in tqdm(range(devices), desc="simulate", unit="unit"):
        simulate_unit(spec, k, 0, folder, {"gyr.bias_dps": 10.0} if k == biased else None)
    print(f"{unit_name(biased)}: gyro bias × 10; {unit_name(cut_unit)}: calibration recording cut short")
    cut = folder / unit_name(cut_unit) / "calibration" / "calibration.csv.gz"
    cut.write_bytes(cut.read_bytes()[:5000])


def timed(folder: Path, out: Path, workers: int) -> tuple[float, list]:
    """(wall [s], results) of one fleet training."""
    start = time.perf_counter()
    results = train_fleet(folder, out, workers=workers)
    return time.perf_counter() - start, results


def models_equal(a: Path, b: Path, units: list[str]) -> bool:
    """True when every unit's model.json agrees between the two output folders but for its clock
    fields ('created', the ELM's 'train_time_s')."""
    def content(path: Path) -> str:
        return "\n".join(line for line in path.read_text().splitlines()
                         if '"created"' not in line and '"train_time_s"' not in line)
    return all(content(a / u / "model.json") == content(b / u / "model.json")
               for u in units if (a / u / "model.json").is_file())


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--devices", type=int, default=200)
    p.add_argument("--work", type=Path, default=None, help="keep the fleet and the models here")
    a = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="imufusion-fleet-") as tmp:
        work = a.work or Path(tmp)
        simulate(a.devices, work / "fleet")
        one, results = timed(work / "fleet", work / "one", 1)
        two, _ = timed(work / "fleet", work / "two", 2)
        _, _, doc = write_fleet_report(results, work / "two")
        same = models_equal(work / "one", work / "two", [r.unit for r in results])
    print(f"\n| units | wall, 1 worker [s] | wall, 2 workers [s] | ratio (bound {RATIO_BOUND:g}) | models equal |")
    print("|---|---|---|---|---|")
    print(f"| {a.devices} | {one:.0f} | {two:.0f} | {two / one:.2f} | {'yes' if same else 'NO'} |")
    print(f"\noutliers (> {doc['outlier_sigmas']:g} robust σ):")
    for o in doc["outliers"]:
        print(f"- {o['unit']}: {o['parameter']} = {o['value']:.4g} {o['unit_of_value']}, {o['distance']:.1f} robust σ")
    print("failed units:")
    for f in doc["failed"]:
        print(f"- {f['unit']}: {f['reason']}")
    print(json.dumps({"trained": doc["trained"], "failed": len(doc["failed"])}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
