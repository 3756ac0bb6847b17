"""How precisely does `imufmu diagnose` read an effect? The in-calibration case of
benchmarks/diagnose_effects.py repeated over simulation seeds: the spread of each reading is what the
sensor noise and the motion leave, the yardstick for a reading's error in one run.

    python benchmarks/reading_spread.py [--effect mag_field_cross] [--seeds 6]

Each seed simulates the calibration recording (scenarios/variants/diag_calibration_clean.toml) and the
held-out hand-held recording (diag_effects.toml) anew — trajectories and noise — injects the effect of
tests/effects.py into both, trains on the first and diagnoses the second at the defaults. Prints, per
coefficient that reads the effect, the injected value, the term that removes it in the calibrated axes the
FMU's terms act in (`calibrated_scale`), the mean and standard deviation over the seeds of what the diagnosed
model carries, and each seed's relative error against both.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from effects import EFFECTS  # noqa: E402
from training.artefact import load_artefact  # noqa: E402
from training.data.io import write_imu_csv  # noqa: E402
from training.diagnosis.diagnose import diagnose  # noqa: E402
from training.simulator import load_scenario, simulate  # noqa: E402
from training.train import train  # noqa: E402

VARIANTS = ROOT / "scenarios" / "variants"
#: effect -> {(term target, a, b): the injected coefficient in the terms' units}, at tests/effects.py's defaults.
READ_BY = {
    "mag_field_cross": {("mag_x", "mag_x", "mag_y"): 1.5e-3, ("mag_y", "mag_y", "mag_z"): -1.2e-3,
                        ("mag_z", "mag_x", "mag_z"): 1.5e-3},
    "gyro_rate_scale": {(f"gyr_{a}", f"gyr_{a}", f"abs_gyr_{a}"): v for a, v in zip("xyz", (0.01, -0.008, 0.012))},
    "acc_cross_nonlinearity": {("acc_x", "acc_x", "acc_y"): 3e-3, ("acc_y", "acc_y", "acc_z"): -3e-3,
                               ("acc_z", "acc_x", "acc_z"): 3e-3},
}


def calibrated_scale(scenario, triad: str) -> np.ndarray:
    """(3,) the diagonal of the inverse of the sensor's linear response at 25 °C (scale, misalignment and, for
    the field, soft iron; training.simulator.sensors): an effect the generator adds to the RAW triad reaches the
    calibrated triad, where the FMU's terms act, multiplied by it, so the term that removes k·p(x) on component
    i is k times its i-th element."""
    sensor = scenario.sensor
    response = getattr(sensor, triad).response(25.0)
    if triad == "mag":
        response = response @ sensor.mag_distortion.soft_iron
    return np.diag(np.linalg.inv(response))


def _read(model: Path, keys) -> np.ndarray:
    terms = load_artefact(model).terms
    return np.array([sum(t["coefficient"] for t in terms if (t["target"], t["a"], t["b"]) == key) for key in keys])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effect", choices=sorted(READ_BY), default="mag_field_cross")
    parser.add_argument("--seeds", type=int, default=6, help="simulation seeds 1..N (default 6)")
    args = parser.parse_args(argv)
    from tqdm import tqdm
    effect, keys = EFFECTS[args.effect], list(READ_BY[args.effect])
    injected = np.array(list(READ_BY[args.effect].values()))
    reads = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in tqdm(range(1, args.seeds + 1), desc="seeds", unit="seed"):
            work = Path(tmp) / str(seed)
            calibration = simulate(load_scenario(VARIANTS / "diag_calibration_clean.toml"), seed=100 + seed)
            held_out = simulate(load_scenario(VARIANTS / "diag_effects.toml"), seed=200 + seed)
            model = train([effect(calibration, np.random.default_rng(seed))], seed=0, progress=False).save(
                work / "model" / "model.json")
            path = write_imu_csv(effect(held_out, np.random.default_rng(1000 + seed)), work / "diag.csv.gz")
            diagnose([path], model, work / "report", seed=0, plots=False, progress=False, limits=False)
            reads.append(_read(work / "report" / "model.json", keys))
    reads = np.array(reads)
    scale = calibrated_scale(load_scenario(VARIANTS / "diag_calibration_clean.toml"), effect.target)
    calibrated = np.array([injected[j] * scale["xyz".index(key[0][-1])] for j, key in enumerate(keys)])
    print(f"{args.effect}, {args.seeds} seeds (`python benchmarks/reading_spread.py --effect {args.effect} "
          f"--seeds {args.seeds}`):\n")
    print("| term | injected (raw axes) | the term that removes it (calibrated axes) | mean read | standard deviation "
          "| relative error per seed, against the raw / the calibrated value |")
    print("|---|---|---|---|---|---|")
    for j, key in enumerate(keys):
        raw = ", ".join(f"{100 * e:+.1f}" for e in (reads[:, j] - injected[j]) / abs(injected[j]))
        cal = ", ".join(f"{100 * e:+.1f}" for e in (reads[:, j] - calibrated[j]) / abs(calibrated[j]))
        print(f"| {key[0]} × {key[1]}·{key[2]} | {injected[j]:.4g} | {calibrated[j]:.4g} | {reads[:, j].mean():.4g} | "
              f"{reads[:, j].std(ddof=1):.2g} ({100 * reads[:, j].std(ddof=1) / abs(injected[j]):.1f} %) | "
              f"{raw} % / {cal} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
