"""A second FMI importer: the same recording through ecospy (Ecos, fmi4c) and through fmpy.

ecospy's engine loads libtbb from the `tbb` package, which lives in the environment's lib folder:
the ecospy run happens in a subprocess with that folder on LD_LIBRARY_PATH.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from fmu.cosim import run_fmu
from fmu.packer import reference_recording

#: Both importers run the same binary on the same samples; ecospy computes its communication
#: points as multiples of the step size, fmpy takes them from the recording, which may differ in
#: the last bit and so change the integration step by an ulp.
IMPORTER_TOLERANCE = 1e-12

#: Run by a fresh interpreter: co-simulate the reference recording with ecospy, save the outputs.
_ECOSPY_SCRIPT = """
import sys
import numpy as np
from ecospy import EcosLib, EcosSimulation, EcosSimulationStructure
from contract.layout import INPUTS, OUTPUTS
from fmu.packer import reference_recording
fmu_path, out_path, *calibration = sys.argv[1:]
EcosLib.set_log_level("warn")
t, raw = reference_recording()
rows = []
with EcosSimulationStructure() as structure:
    structure.add_model("imu", fmu_path)
    with EcosSimulation(structure=structure, step_size=float(t[1] - t[0])) as sim:
        for j, name in enumerate(INPUTS):
            sim.set_real(f"imu::{name}", float(raw[0, j]))
        if calibration:  # a unit's calibration.ssv, set as parameters before initialisation
            from contract import coefficient_parameters as cp
            from contract.variables import by_name
            from fmu.calibration_file import read_calibration
            coefficients, settings, _ = read_calibration(calibration[0])
            for name, value in cp.scalar_values(coefficients).items():
                sim.set_real(f"imu::{name}", value)
            for name, value in settings.items():
                kind = by_name(name).type
                setter = sim.set_bool if kind == "Boolean" else sim.set_integer if kind == "Integer" else sim.set_real
                setter(f"imu::{name}", bool(value) if kind == "Boolean" else int(value) if kind == "Integer" else value)
        sim.init()
        for k in range(t.size):
            for j, name in enumerate(INPUTS):
                sim.set_real(f"imu::{name}", float(raw[k, j]))
            sim.step(1)
            rows.append([sim.get_real(f"imu::{name}") for name in OUTPUTS])
        sim.terminate()
np.save(out_path, np.array(rows))
"""


def _ecospy(fmu: Path, out: Path, *calibration: Path) -> np.ndarray:
    """The reference recording through ecospy (in a subprocess: libtbb on LD_LIBRARY_PATH)."""
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(Path(sys.prefix) / "lib"), env.get("LD_LIBRARY_PATH")]))
    result = subprocess.run([sys.executable, "-c", _ECOSPY_SCRIPT, str(fmu), str(out), *map(str, calibration)],
                            cwd=Path(__file__).parent.parent, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=300)
    assert result.returncode == 0, result.stdout
    return np.load(out)


def test_ecospy_runs_a_generic_fmu_with_a_units_calibration_file(identity_fmu2, trained_fmu2, tmp_path):
    # issue 32: a second importer sets the unit's parameter set (SSV) in the FMU built without a calibration
    from fmu.calibration_file import write_calibration
    from fmu_cases import TRAINED_SETTINGS, trained_coefficients
    ssv = write_calibration(tmp_path / "unit.ssv", trained_coefficients(), TRAINED_SETTINGS)
    t, raw = reference_recording()
    np.testing.assert_allclose(_ecospy(identity_fmu2, tmp_path / "ecos.npy", ssv), run_fmu(trained_fmu2, t, raw),
                               rtol=0, atol=IMPORTER_TOLERANCE)


def test_ecospy_and_fmpy_give_the_same_outputs(trained_fmu2, tmp_path):
    t, raw = reference_recording()
    ecos = _ecospy(trained_fmu2, tmp_path / "ecos.npy")
    fmpy_out = run_fmu(trained_fmu2, t, raw)
    assert ecos.shape == fmpy_out.shape and np.all(np.isfinite(ecos))
    np.testing.assert_allclose(ecos, fmpy_out, rtol=0, atol=IMPORTER_TOLERANCE)
    assert np.ptp(fmpy_out[:, 11]) > 1.0  # the yaw turns: the comparison covers a moving sensor
