"""The runtime integrates with the importer's step sizes and treats a long step as a gap (issue 15, item 6).

Each doStep consumes one sample; the next sample comes the communication step size h later
(docs/fmu.md). The FMU used to difference the absolute times t instead: an importer that
accumulates its clock (t += h) at t0 = 1e14 s, where doubles are 0.016 s apart, fed it steps of
0.0156 s for 0.01 s (11.5 ° of attitude error in the issue). A step longer than
IMU_GUARD_GAP_STEPS nominal steps (sources/ImuGuard.h) is a gap: nothing is integrated across it,
the attitude restarts as at power-on and the FMU warns once.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from contract import layout
from contract.ranges import STANDARD_GRAVITY
from fmu.compiler import SOURCE_DIR
from fmu.cosim import OK, WARNING, Stepper, initialised_fmu
from fmu.packer import reference_recording
from training import runtime

#: s, the communication step of the importer, and the far clock of the issue.
STEP_S, FAR_START_S = 0.01, 1e14
#: °: largest difference of roll, pitch, yaw between the runs at t0 = 1e14 s and t0 = 0 (the
#: FMU no longer reads the absolute time, so the runs agree exactly; the old FMU differed by
#: tens of degrees within the 2 s of the reference recording).
FAR_CLOCK_BOUND_DEG = 0.01
#: rad/s, yaw rate of the gap recording (gyro only: no magnetometer).
YAW_RATE = 0.5
EULER = [layout.OUTPUTS.index(n) for n in ("roll", "pitch", "yaw")]
YAW = layout.OUTPUTS.index("yaw")


def gap_steps() -> float:
    """IMU_GUARD_GAP_STEPS of sources/ImuGuard.h: the named gap threshold [nominal steps]."""
    text = (SOURCE_DIR / "ImuGuard.h").read_text()
    return float(re.search(r"#define IMU_GUARD_GAP_STEPS ([0-9.eE+-]+)", text).group(1))


def run_with_clock(fmu_path, start: float, inputs: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, list[int], list[str]]:
    """(outputs, statuses, log) of the FMU stepped like an importer that accumulates t += h from `start` [s]."""
    outputs, statuses = [], []
    with initialised_fmu(fmu_path, start) as fmu:
        stepper, t = Stepper(fmu), start
        for k in range(len(inputs)):
            stepper.set_inputs(inputs[k])
            statuses.append(stepper.do_step(t, h[k]))
            outputs.append(stepper.get_outputs())
            t += h[k]
        log = list(fmu.log_messages)
    return np.array(outputs), statuses, log


def test_a_far_importer_clock_gives_the_attitude_of_a_clock_at_zero(identity_fmu2):
    _, x = reference_recording()  # 2 s rocking and turning at 0.8 rad/s, 100 Hz
    h = np.full(len(x), STEP_S)
    assert FAR_START_S + STEP_S - FAR_START_S != STEP_S  # the clock cannot represent the step there
    near, _, _ = run_with_clock(identity_fmu2, 0.0, x, h)
    far, statuses, _ = run_with_clock(identity_fmu2, FAR_START_S, x, h)
    assert set(statuses) == {OK}
    difference = np.degrees(np.abs(np.angle(np.exp(1j * (far[:, EULER] - near[:, EULER])))))
    assert float(difference.max()) <= FAR_CLOCK_BOUND_DEG


def turning_without_field(n: int) -> np.ndarray:
    """(n, len(INPUTS)) a level sensor turning at YAW_RATE about down, no magnetometer (NaN)."""
    x = np.zeros((n, len(layout.INPUTS)))
    x[:, 2] = YAW_RATE
    x[:, 5] = -STANDARD_GRAVITY
    x[:, 6:9] = np.nan
    x[:, 9] = 25.0
    return x


@pytest.mark.parametrize("factor, integrated", [(0.9, True), (1.1, False)])
def test_a_step_beyond_the_gap_threshold_is_not_integrated(factor, integrated):
    # Without a magnetometer yaw is the gyro's integral: a step below the threshold advances it by
    # rate x step, a gap leaves it where it was (the motion during a gap was never measured).
    n, k = 200, 100
    steps = np.full(n, STEP_S)
    steps[k] = factor * gap_steps() * STEP_S
    t = np.concatenate([[0.0], np.cumsum(steps[1:])])
    out = runtime.run_batch(np.array(layout.identity_coefficients()),
                            np.array(layout.settings_array({"rest_gyro_threshold": 0.0})), t, turning_without_field(n))
    advance = np.angle(np.exp(1j * (out[k, YAW] - out[k - 1, YAW])))
    expected = YAW_RATE * steps[k] if integrated else 0.0
    assert advance == pytest.approx(np.angle(np.exp(1j * expected)), abs=1e-9)


def test_the_fmu_warns_once_for_a_gap_and_equals_the_batch_runtime(identity_fmu2):
    # Steps of 2^-7 s and a gap of 2^12 s (an hour and a bit): the batch's sample times are then
    # exact sums, so their differences are the FMU's step sizes to the bit.
    n, k = 200, 100
    h = np.full(n, 2.0 ** -7)
    h[k - 1] = 4096.0  # the sample after doStep k-1 comes 4096 s later
    x = turning_without_field(n)
    out, statuses, log = run_with_clock(identity_fmu2, 0.0, x, h)
    assert statuses[k] == WARNING and statuses[:k] + statuses[k + 1:] == [OK] * (n - 1)
    gaps = [m for m in log if "a gap of 4096 s" in m]
    assert len(gaps) == 1 and gaps[0].startswith("[WARNING]")
    t = np.concatenate([[0.0], np.cumsum(h[:-1])])
    batch = runtime.run_batch(np.array(layout.identity_coefficients()), np.array(layout.settings_array()), t, x)
    np.testing.assert_allclose(out, batch, rtol=0, atol=1e-12, equal_nan=True)  # tests/fmu_cases.py GOLDEN_TOLERANCE
