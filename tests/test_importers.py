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
fmu_path, out_path = sys.argv[1:]
EcosLib.set_log_level("warn")
t, raw = reference_recording()
rows = []
with EcosSimulationStructure() as structure:
    structure.add_model("imu", fmu_path)
    with EcosSimulation(structure=structure, step_size=float(t[1] - t[0])) as sim:
        for j, name in enumerate(INPUTS):
            sim.set_real(f"imu::{name}", float(raw[0, j]))
        sim.init()
        for k in range(t.size):
            for j, name in enumerate(INPUTS):
                sim.set_real(f"imu::{name}", float(raw[k, j]))
            sim.step(1)
            rows.append([sim.get_real(f"imu::{name}") for name in OUTPUTS])
        sim.terminate()
np.save(out_path, np.array(rows))
"""


def test_ecospy_and_fmpy_give_the_same_outputs(trained_fmu2, tmp_path):
    t, raw = reference_recording()
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(Path(sys.prefix) / "lib"), env.get("LD_LIBRARY_PATH")]))
    result = subprocess.run([sys.executable, "-c", _ECOSPY_SCRIPT, str(trained_fmu2), str(tmp_path / "ecos.npy")],
                            cwd=Path(__file__).parent.parent, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=300)
    assert result.returncode == 0, result.stdout
    ecos = np.load(tmp_path / "ecos.npy")
    fmpy_out = run_fmu(trained_fmu2, t, raw)
    assert ecos.shape == fmpy_out.shape and np.all(np.isfinite(ecos))
    np.testing.assert_allclose(ecos, fmpy_out, rtol=0, atol=IMPORTER_TOLERANCE)
    assert np.ptp(fmpy_out[:, 11]) > 1.0  # the yaw turns: the comparison covers a moving sensor
