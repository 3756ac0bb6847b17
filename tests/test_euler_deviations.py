"""benchmarks/euler_deviations.py, which measures two deviations of the Euler fusion from its source
(docs/euler.md "As written / as built"): its Python form of the source's filter must be the C filter,
its heading formulas must be the product's and the source's, and its propagation through R must be
the closed form of the ZYX kinematics."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

import euler_deviations as ed  # noqa: E402
from training.data.reference import reference_euler_magnetic  # noqa: E402
from training.frames import wrap_angle  # noqa: E402

#: The first 20 s of the simulated recording: enough motion to exercise every branch, ~1 s to run.
SAMPLES = 2000
#: rad: the Python form does the C filter's operations in another order (Rodrigues vs the C series,
#: no re-orthonormalisation); over the 24 000 simulated samples it stays within 1.5e-12° (3e-14 rad) of
#: it, over a BROAD trial within 2e-10° (the table's last column), so 1e-9 rad separates rounding from any
#: difference of method.
TWIN_TOLERANCE = 1e-9


@pytest.fixture(scope="module")
def recording():
    """The script's simulated recording (seed 0), its first SAMPLES samples."""
    return ed.first_samples(ed.simulated_recording(0), SAMPLES)


def test_the_python_source_form_is_the_c_filter(recording):
    s = ed.settings(recording, ed.SOURCE)
    out = ed.run(recording, s)
    gyr, acc, mag = (out[:, cols] for cols in ed.TRIAD_COLUMNS)
    python = ed.euler_fusion(recording.t - recording.t[0], gyr, acc, mag, s, ed.grow_diagonal)
    assert np.max(np.abs(wrap_angle(python - out[:, ed.EULER_COLUMNS]))) < TWIN_TOLERANCE


def test_the_product_formula_gives_the_heading_and_the_literal_one_its_mirror(recording):
    """With the true field and the true tilt the product's formula is exact and the source's literal
    one is π − ψ."""
    out = np.zeros((len(recording), len(ed.layout.OUTPUTS)))
    ref = reference_euler_magnetic(recording)
    out[:, ed.EULER_COLUMNS] = ref
    out[:, ed.TRIAD_COLUMNS[2]] = recording.ref_mag
    formula, literal = ed.heading_errors_deg(recording, out)
    mirrored = np.degrees(np.sqrt(np.mean(wrap_angle(np.pi - 2.0 * ref[:, 2]) ** 2)))
    assert formula < 1e-6
    assert literal == pytest.approx(mirrored, abs=1e-6)


def test_the_propagation_through_r_is_the_zyx_kinematics():
    """From P = 0 at rest, one step adds q·E Eᵀ: level, q on each angle (the product's growth); at pitch
    θ, roll and yaw grow by q / cos²θ."""
    q, pitch = 1e-6, math.radians(60.0)
    level = np.zeros(3)
    assert np.allclose(ed.grow_through_rotation(np.zeros((3, 3)), level, level, np.eye(3), q),
                       ed.grow_diagonal(np.zeros((3, 3)), level, level, np.eye(3), q), rtol=0, atol=1e-18)
    tilted = np.array([0.0, pitch, 0.0])
    p = ed.grow_through_rotation(np.zeros((3, 3)), tilted, tilted, np.eye(3), q)
    assert np.diag(p) == pytest.approx([q / math.cos(pitch) ** 2, q, q / math.cos(pitch) ** 2], rel=1e-12)
