"""The closed loop in Ecos (`python -m training.sensor.ecos_loop JOB.npz OUT.npy`; training.sensor.closed_loop.
run_ecospy writes JOB and starts it with the environment's lib folder on LD_LIBRARY_PATH, where ecospy's libtbb
lives).

Two models in one EcosSimulationStructure, "sensor" (ImuSensor) and "imu" (ImuFusion), the sensor's raw outputs
connected to the ImuFusion FMU's inputs of the same name (make_real_connection "sensor::gyr_x" -> "imu::gyr_x",
…, "sensor::temp" -> "imu::temp"). The trajectory source is a SimulationListener: before step k it sets the
truth of sample k on the sensor's inputs (and the ImuFusion FMU's aux inputs; before the first step, NaN on its
raw inputs: closed_loop.FIRST_RAW), after it reads the ImuFusion outputs. One sim.step(N) runs the whole
recording; Ecos's fixed-step master steps both instances from t to t + h, then transfers the connections.
"""
from __future__ import annotations

import sys

import numpy as np


def _set_parameters(sim, instance: str, rows: np.ndarray) -> None:
    """Set (name, type, value) rows on `instance` before initialisation (ecospy raises on an unknown name)."""
    for name, kind, value in rows:
        identifier, number = f"{instance}::{name}", float(value)
        if kind == "Boolean":
            sim.set_bool(identifier, bool(number))
        elif kind == "Integer":
            sim.set_integer(identifier, int(number))
        else:
            sim.set_real(identifier, number)


def main(job_path: str, out_path: str) -> None:
    from ecospy import EcosLib, EcosSimulation, EcosSimulationStructure
    from ecospy.EcosSimulation import SimulationListener
    from contract.layout import AUX_INPUTS, OUTPUTS
    from training.sensor.closed_loop import FIRST_RAW, FUSION_INSTANCE, RAW, SENSOR_INSTANCE
    job = np.load(job_path)
    names = [str(n) for n in job["names"]]
    values, aux = job["values"], job["aux"]
    n = values.shape[0]
    EcosLib.set_log_level("warn")
    rows = np.empty((n, len(OUTPUTS)))
    failures: list[str] = []

    class Trajectory(SimulationListener):
        """Sets sample k's truth before step k, reads the ImuFusion outputs after it."""

        def __init__(self, sim):
            self.sim = sim
            self.sensor_ids = [f"{SENSOR_INSTANCE}::{name}" for name in names]
            self.aux_ids = [f"{FUSION_INSTANCE}::{name}" for name in AUX_INPUTS]
            self.raw_ids = [f"{FUSION_INSTANCE}::{name}" for name in RAW]
            self.output_ids = [f"{FUSION_INSTANCE}::{name}" for name in OUTPUTS]

        def pre(self, info):
            try:
                k = int(info.iterations)
                for identifier, value in zip(self.sensor_ids, values[k]):
                    self.sim.set_real(identifier, float(value))
                for identifier, value in zip(self.aux_ids, aux[k]):
                    self.sim.set_real(identifier, float(value))
                if k == 0:  # nothing sampled yet: over what the connections carried at initialisation
                    for identifier in self.raw_ids:
                        self.sim.set_real(identifier, FIRST_RAW)
            except Exception as e:  # noqa: BLE001 - a callback from C cannot raise: reported after the run
                failures.append(f"step {info.iterations}: {type(e).__name__}: {e}")

        def post(self, info):
            try:
                rows[int(info.iterations) - 1] = [self.sim.get_real(i) for i in self.output_ids]
            except Exception as e:  # noqa: BLE001
                failures.append(f"after step {info.iterations}: {type(e).__name__}: {e}")

    with EcosSimulationStructure() as structure:
        structure.add_model(SENSOR_INSTANCE, str(job["sensor_fmu"]))
        structure.add_model(FUSION_INSTANCE, str(job["fusion_fmu"]))
        for name in RAW:
            structure.make_real_connection(f"{SENSOR_INSTANCE}::{name}", f"{FUSION_INSTANCE}::{name}")
        with EcosSimulation(structure=structure, step_size=float(job["step"])) as sim:
            _set_parameters(sim, SENSOR_INSTANCE, job["sensor_params"])
            _set_parameters(sim, FUSION_INSTANCE, job["fusion_params"])
            listener = Trajectory(sim)
            sim.add_listener("trajectory", listener)
            sim.init()
            sim.step(n)
            sim.remove_listener("trajectory")
            sim.terminate()
    if failures:
        raise RuntimeError(f"{len(failures)} listener call(s) failed; the first: {failures[0]}")
    np.save(out_path, rows)


if __name__ == "__main__":
    main(*sys.argv[1:3])
