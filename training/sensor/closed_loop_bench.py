"""The closed loop measured on the main job's evaluation recordings (docs/virtual_sensor.md, "Closed loop"):

    python -m training.sensor.closed_loop_bench OUT      (OUT: an `imufmu pipeline --out OUT` folder)

builds the virtual-sensor FMU of OUT/model/model.json with the noise figures `train` characterised from the
calibration's rests (its "noise" block: what issue 34's round trip asks for; `--noise datasheet`: instead the
noise the simulator gives the mems_grade unit, scenarios/sensors/mems_grade.toml via training.sensor.datasheet,
the figures OUT/data's recordings were simulated with), then prints three tables:

1. the loop's delay: eval_rotations noise off, the corrected rate error for each shift of the outputs
   (closed_loop.ALIGNMENT_STEPS is where it vanishes);
2. each evaluation recording's truth through the sensor and OUT/ImuFusion.fmu in Ecos (seed 0) beside the main
   job's figure for the recording itself (OUT/summary.json);
3. the two importers: their run times, ecospy against fmpy on Ecos's grid (bit for bit), and on the recording's
   own times (the largest metric difference).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from training.reports.report import ROWS
from training.sensor import closed_loop as cl

#: The simulated unit of the main job's recordings.
MEMS_GRADE = Path(__file__).resolve().parents[2] / "scenarios" / "sensors" / "mems_grade.toml"
#: Header rows of the tables printed (training/bench/doc_tables.py).
ALIGNMENT_HEADER = "| outputs shifted by [steps] | corrected rate error RMS [°/s], noise off |"
ACCURACY_HEADER = ("| recording | error | main job: the recording through ImuFusion | closed loop: its truth through "
                   "ImuSensor and ImuFusion (ecospy, seed 0) | closed ÷ main |")
IMPORTER_HEADER = ("| recording | samples | ecospy [s] | fmpy [s] | ecospy = fmpy on Ecos's grid | largest metric "
                   "difference, fmpy on the recording's times |")


def _number(v) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{v:.4g}"


def _bench(out: Path, seed: int, noise: str = "model") -> list[str]:
    from training.data.io import read_imu_csv
    from training.sensor.build import build_sensor_fmu
    from training.sensor.datasheet import datasheet_noise
    fusion = out / "ImuFusion.fmu"
    main_job = {s["name"]: s["corrected"] for s in json.loads((out / "summary.json").read_text())["scenarios"]}
    recordings = sorted((out / "data").glob("eval_*.csv.gz"))
    lines = []
    with tempfile.TemporaryDirectory(prefix="imufusion-loop-") as tmp:
        sensor, plan = build_sensor_fmu(out / "model" / "model.json", Path(tmp) / "ImuSensor.fmu", 2,
                                        overrides=datasheet_noise(MEMS_GRADE) if noise == "datasheet" else {})
        lines += [f"Sensor noise: {'mems_grade data sheet' if noise == 'datasheet' else 'the model (' + plan.source + ')'}; "
                  f"{len(plan.unsupported) if noise == 'model' else 0} figures not characterised (0)", ""]
        rotations = next(p for p in recordings if p.name.startswith("eval_rotations"))
        traj = cl.trajectory(read_imu_csv(rotations), fusion)
        quiet = cl.run_fmpy(sensor, fusion, traj, cl.sensor_parameters(seed, traj.sensor_parameters, {"noise": 0.0}),
                            traj.fusion_parameters)
        lines += [f"Delay: {rotations.name}, noise off", "", ALIGNMENT_HEADER, "|---:|---:|"]
        lines += [f"| {s} | {v:.3g} |" for s, v in cl.alignment_scan(quiet, traj.body, (0, 1, 2, 3)).items()]
        accuracy = [ACCURACY_HEADER, "|---|---|---:|---:|---:|"]
        importers = [IMPORTER_HEADER, "|---|---:|---:|---:|---|---:|"]
        for path in recordings:
            data = read_imu_csv(path)
            start = time.perf_counter()
            ecos = cl.closed_loop(sensor, fusion, data, seed=seed, importer="ecospy")
            ecos_s = time.perf_counter() - start
            start = time.perf_counter()
            own = cl.closed_loop(sensor, fusion, data, seed=seed, importer="fmpy")
            fmpy_s = time.perf_counter() - start
            traj = cl.trajectory(data, fusion)
            on_grid = cl.run_fmpy(sensor, fusion, traj, ecos.sensor_parameters, traj.fusion_parameters,
                                  t=cl.ecos_grid(len(traj.t), ecos.step_s), h=ecos.step_s)
            equal = np.array_equal(ecos.stepped, on_grid, equal_nan=True)
            worst = max(abs(own.metrics[k] - ecos.metrics[k]) for k in ecos.metrics)
            importers.append(f"| {data.name} | {len(data)} | {ecos_s:.1f} | {fmpy_s:.1f} | "
                             f"{'yes, bit for bit' if equal else 'NO'} | {worst:.2g} |")
            reference = main_job.get(data.name, {})
            for key, label in ROWS:
                main, loop = reference.get(key), ecos.metrics[key]
                ratio = loop / main if main else float("nan")
                accuracy.append(f"| {data.name} | {label} | {_number(main)} | {_number(loop)} | {_number(ratio)} |")
    return lines + ["", "Accuracy against truth", "", *accuracy, "", "Importers", "", *importers]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m training.sensor.closed_loop_bench", description=__doc__.split("\n")[0])
    p.add_argument("out", help="an `imufmu pipeline --out OUT` folder (model/model.json, ImuFusion.fmu, data/, "
                               "summary.json)")
    p.add_argument("--seed", type=int, default=0, help="the sensor's noise seed (default 0)")
    p.add_argument("--noise", choices=("model", "datasheet"), default="model",
                   help="the sensor's noise: the model's characterised figures (default) or mems_grade's data sheet")
    args = p.parse_args(argv)
    print("\n".join(_bench(Path(args.out), args.seed, args.noise)))


if __name__ == "__main__":
    main()
