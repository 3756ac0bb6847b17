"""Numpy twin of the FMU's quaternion attitude filter (attitude_mode = 1; sources/ImuAttitude.c,
ImuAttitudeQuaternion.c, ImuAttitudeStep.c, ImuLowPass.c, ImuMotionBias.c, ImuRestDetector.c), sample by
sample.

It reads as the algorithm (q = Rz(heading offset) ⊗ qAcc ⊗ qGyr): the rest-detector gyro bias, the
strapdown qGyr with the rate held over the step (gyro_hold) or its trapezoid, the specific force
low-passed in the almost-inertial frame by a second-order Butterworth filter that levels qAcc (its
turn also updates the gyro bias in motion with motion_bias), the heading offset from the field with norm/dip rejection (none with mag_heading = 0), and the restart after integration-error
bursts. tests/test_attitude_twin.py pins it to the C filter sample for sample; it is the reference to
read and to try changes on, not a second runtime (the pipeline around the filter — calibration,
mounting, time alignment, gaps — stays in C only).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Constants of the C sources (each named there; tests/test_attitude_twin.py fails when they part).
GRAVITY = 9.80665                 # ImuAttitude.h IMU_ATTITUDE_GRAVITY
REST_BIAS_TIME = 2.0              # ImuAttitude.c IMU_ATTITUDE_REST_BIAS_TIME [s]
REST_FILTER_TIME = 0.5            # ImuRestDetector.h IMU_REST_FILTER_TIME [s]
REST_MIN_TIME = 1.5               # ImuRestDetector.h IMU_REST_MIN_TIME [s]
UNTRACKED_MOTION = 1.0            # ImuAttitudePrivate.h IMU_ATTITUDE_UNTRACKED_MOTION [rad/s]
RESTART_VARIANCE = 0.0304617420   # ImuAttitudePrivate.h IMU_ATTITUDE_RESTART_VARIANCE [rad²]
MISSING_STEPS = 1.5               # ImuAttitudeStep.c IMU_ATTITUDE_MISSING_STEPS
STEP_HISTORY = 5                  # ImuGuard.h IMU_GUARD_STEP_HISTORY
SMOOTH_ANGULAR_ACCEL = 1000.0     # ImuAttitudeStep.c IMU_ATTITUDE_SMOOTH_ANGULAR_ACCEL [rad/s²]
MAG_NORM_TOLERANCE = 0.1          # ImuAttitudeQuaternion.c IMU_ATTITUDE_MAG_NORM_TOLERANCE
MAG_DIP_TOLERANCE = 0.1745329252  # ImuAttitudeQuaternion.c IMU_ATTITUDE_MAG_DIP_TOLERANCE [rad]
MAG_RECOVERY = 2.0                # ImuAttitudeQuaternion.c IMU_ATTITUDE_MAG_RECOVERY
MAG_MIN_CLEAN_TIME = 0.5          # ImuAttitudePrivate.h IMU_ATTITUDE_MAG_MIN_CLEAN_TIME [s]
BIAS_SIGMA_INIT = 0.5             # ImuMotionBias.c IMU_MOTION_BIAS_SIGMA_INIT [°/s]
BIAS_FORGETTING_TIME = 100.0      # ImuMotionBias.c IMU_MOTION_BIAS_FORGETTING_TIME [s]
BIAS_SIGMA_MOTION = 0.1           # ImuMotionBias.c IMU_MOTION_BIAS_SIGMA_MOTION [°/s]
BIAS_VERTICAL_FORGETTING = 1e-4   # ImuMotionBias.c IMU_MOTION_BIAS_VERTICAL_FORGETTING
BIAS_CLIP = 2.0                   # ImuMotionBias.c IMU_MOTION_BIAS_CLIP [°/s]


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of two [w, x, y, z] quaternions."""
    return np.array([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v turned by the unit quaternion q (q ⊗ [0, v] ⊗ q*)."""
    u = q[1:]
    t = 2.0 * np.cross(u, v)
    return v + q[0] * t + np.cross(u, t)


def _normalised(q: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(q))
    return q / n if n > 0.0 and math.isfinite(n) else np.array([1.0, 0.0, 0.0, 0.0])


def quat_integrate(q: np.ndarray, w: np.ndarray, dt: float) -> np.ndarray:
    """q ⊗ exp(w dt / 2), normalised."""
    angle = float(np.linalg.norm(w)) * dt
    s = 0.5 - angle * angle / 48.0 if angle < 1e-4 else math.sin(0.5 * angle) / angle
    return _normalised(quat_multiply(q, np.concatenate([[math.cos(0.5 * angle)], s * w * dt])))


def wrap(angle: float) -> float:
    """angle [rad] wrapped into (-π, π] (ImuMath.c ImuWrapAngle)."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


@dataclass
class LowPass:
    """Second-order Butterworth low-pass of a 3-vector (ImuLowPass.c), started by the mean of its
    first tau seconds."""

    state: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    output: np.ndarray = field(default_factory=lambda: np.zeros(3))
    total: np.ndarray | float = 0.0
    mean_time: float = 0.0
    count: int = 0
    initialised: bool = False

    def step(self, x: np.ndarray, tau: float, dt: float) -> np.ndarray:
        """The filtered x after a step dt [s] with time constant tau [s]."""
        if not dt > 0.0:
            return self.output.copy() if self.count else x.copy()
        c = math.tan(math.pi * (math.sqrt(2.0) / (2.0 * math.pi * tau)) * dt)
        d = c * c + math.sqrt(2.0) * c + 1.0
        b0, a1, a2 = c * c / d, 2.0 * (c * c - 1.0) / d, (1.0 - math.sqrt(2.0) * c + c * c) / d
        if not self.initialised:
            self.count, self.mean_time, self.total = self.count + 1, self.mean_time + dt, self.total + x
            self.output = self.total / self.count
            if self.mean_time >= tau:
                self.state = np.stack([self.output * (1.0 - b0), self.output * (b0 - a2)])
                self.initialised = True
            return self.output.copy()
        y = b0 * x + self.state[0]
        self.state = np.stack([2.0 * b0 * x - a1 * y + self.state[1], b0 * x - a2 * y])
        self.output = y
        return y.copy()


@dataclass
class RestDetector:
    """Rate and specific force low-passed; rest once both stay near them long enough (ImuRestDetector.c)."""

    gyr_lp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    acc_lp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rest_time: float = 0.0
    initialised: bool = False

    def update(self, gyr: np.ndarray, acc: np.ndarray, dt: float, gyro_threshold: float,
               acc_threshold: float) -> bool:
        """True while at rest."""
        if not self.initialised:
            self.gyr_lp, self.acc_lp, self.initialised = gyr.copy(), acc.copy(), True
            return False
        alpha = 1.0 - math.exp(-dt / REST_FILTER_TIME) if dt > 0.0 else 0.0
        self.gyr_lp = self.gyr_lp + alpha * (gyr - self.gyr_lp)
        self.acc_lp = self.acc_lp + alpha * (acc - self.acc_lp)
        quiet = (not np.any(np.abs(self.gyr_lp) > gyro_threshold)
                 and float(np.sum((gyr - self.gyr_lp) ** 2)) < gyro_threshold ** 2
                 and float(np.sum((acc - self.acc_lp) ** 2)) < acc_threshold ** 2)
        self.rest_time = self.rest_time + dt if quiet else 0.0
        return self.rest_time >= REST_MIN_TIME


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """3×3 rotation matrix of the unit quaternion q (ImuQuaternion.c ImuQuaternionToMatrix)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


class MotionBias:
    """Kalman estimate of the gyro bias from the inclination correction's rate (ImuMotionBias.c)."""

    def __init__(self):
        self.covariance = math.radians(BIAS_SIGMA_INIT) ** 2 * np.eye(3)
        self.restart()

    def restart(self) -> None:
        """The low-passes restart with the next step; the covariance is kept."""
        self.rotation_lp, self.rotated_bias_lp = LowPass(), LowPass()

    def update(self, q6d: np.ndarray, up: np.ndarray, rate_error: float, tau: float, dt: float, observe: bool,
               bias: np.ndarray) -> np.ndarray:
        """The bias [rad/s] after one step dt [s]: q6d body -> level frame after the correction, up the
        unit low-passed specific force before it, rate_error [rad/s] the inclination-rate error an
        unaveraged linear acceleration may cause; measured only with observe."""
        r = rotation_matrix(q6d)
        h = self.rotation_lp.step(r.ravel(), tau, dt).reshape(3, 3)
        rotated_bias = self.rotated_bias_lp.step(r @ bias, tau, dt)
        p = math.radians(BIAS_SIGMA_MOTION) ** 2
        v = p * dt / BIAS_FORGETTING_TIME
        ceiling = math.radians(BIAS_SIGMA_INIT) ** 2
        for i in range(3):
            if self.covariance[i, i] < ceiling:
                self.covariance[i, i] += v
        if not observe:
            return bias
        e = np.array([up[1] / dt, -up[0] / dt, 0.0]) + np.array([rotated_bias[0], rotated_bias[1], 0.0]) - h @ bias
        e = np.clip(e, -math.radians(BIAS_CLIP), math.radians(BIAS_CLIP))
        w = (p * p / v + p) * (1.0 + rate_error * rate_error / p)
        gain = self.covariance @ h.T @ np.linalg.inv(h @ self.covariance @ h.T + np.diag([w, w, w / BIAS_VERTICAL_FORGETTING]))
        self.covariance = self.covariance - gain @ h @ self.covariance
        return bias + gain @ e


class QuaternionFilter:
    """The quaternion attitude filter; settings by their FMU names (contract/variables.py)."""

    def __init__(self, settings: dict[str, float]):
        self.s = settings
        self.q_gyr = np.array([1.0, 0.0, 0.0, 0.0])
        self.q_acc = np.array([1.0, 0.0, 0.0, 0.0])
        self.acc_lp = LowPass()
        self.rest = RestDetector()
        self.at_rest = False
        self.motion_bias = MotionBias()
        self.bias = np.zeros(3)
        self.previous_rate = np.zeros(3)
        self.nominal_step = 0.0
        self.heading_offset = 0.0
        self.mag_rejected = 0.0
        self.mag_clean = MAG_MIN_CLEAN_TIME  # a field never rejected counts as clean
        self.mag_samples = 0.0
        self.step_error = 0.0
        self.tilt_initialised = False
        self.yaw_initialised = False
        self.mag_disturbed = False

    def _step_rate(self, gyr: np.ndarray) -> np.ndarray:
        if self.s["gyro_hold"]:
            return gyr
        return 0.5 * (self.previous_rate + gyr)

    def _step_variance(self, gyr: np.ndarray, dt: float) -> float:
        change = 0.5 * np.maximum(np.abs(gyr - self.previous_rate) - SMOOTH_ANGULAR_ACCEL * dt, 0.0) * dt
        variance = float(np.sum(change ** 2))
        if self.nominal_step > 0.0 and dt > MISSING_STEPS * self.nominal_step:
            variance += (UNTRACKED_MOTION * (dt - self.nominal_step)) ** 2
        return variance

    def _predict(self, gyr: np.ndarray, dt: float) -> None:
        if not dt > 0.0:
            return
        self.step_error *= math.exp(-dt / self.s["tau_acc"])
        self.q_gyr = quat_integrate(self.q_gyr, self._step_rate(gyr), dt)
        self.step_error += self._step_variance(gyr, dt)
        if self.step_error > RESTART_VARIANCE:
            self.step_error, self.tilt_initialised = 0.0, False
            self.mag_samples = self.mag_rejected = 0.0
            self.mag_clean = MAG_MIN_CLEAN_TIME

    def _tilt(self, acc: np.ndarray, dt: float) -> None:
        if not self.tilt_initialised:
            self.acc_lp = LowPass()
            self.motion_bias.restart()
        e = quat_rotate(self.q_acc, self.acc_lp.step(quat_rotate(self.q_gyr, acc), self.s["tau_acc"], dt))
        n = float(np.linalg.norm(e))
        if not n > 0.0:
            return
        turn = np.array([1.0 - e[2] / n, -e[1] / n, e[0] / n, 0.0])  # shortest turn of e onto up (0, 0, -1)
        if turn[0] < 1e-12:
            turn = np.array([0.0, 1.0, 0.0, 0.0])
        self.q_acc = _normalised(quat_multiply(_normalised(turn), self.q_acc))
        if self.s["motion_bias"] and dt > 0.0:
            # linear acceleration: the norm's departure beyond the still accelerometer's own scale error
            excess = abs(n - GRAVITY) - self.s["acc_norm_tolerance"] * GRAVITY
            rate_error = max(0.0, excess) / (GRAVITY * self.s["tau_acc"])
            self.bias = self.motion_bias.update(quat_multiply(self.q_acc, self.q_gyr), e / n, rate_error,
                                                self.s["tau_acc"], dt, self.tilt_initialised and not self.at_rest,
                                                self.bias)
        self.tilt_initialised = True

    def _disturbed(self, m: np.ndarray) -> bool:
        norm = float(np.linalg.norm(m))
        dip = math.atan2(m[2], math.hypot(m[0], m[1]))
        return (abs(norm - self.s["field_norm"]) > MAG_NORM_TOLERANCE * self.s["field_norm"]
                or abs(dip - self.s["field_dip"]) > MAG_DIP_TOLERANCE)

    def _heading(self, mag: np.ndarray, dt: float) -> None:
        m = quat_rotate(quat_multiply(self.q_acc, self.q_gyr), mag)
        if not np.linalg.norm(m) > 0.0:
            return
        off = self._disturbed(m)
        self.mag_clean = 0.0 if off else self.mag_clean + dt
        if self.yaw_initialised and self.s["mag_reject_time"] > 0.0 and (off or self.mag_clean < MAG_MIN_CLEAN_TIME):
            if self.mag_rejected < self.s["mag_reject_time"]:
                self.mag_rejected += dt
                self.mag_disturbed = True
                return
        else:
            self.mag_rejected = max(0.0, self.mag_rejected - MAG_RECOVERY * dt)
        self.mag_samples += 1.0
        k = max(1.0 - math.exp(-dt / self.s["tau_mag"]) if dt > 0.0 else 0.0, 1.0 / self.mag_samples)
        self.heading_offset = wrap(self.heading_offset + k * wrap(-math.atan2(m[1], m[0]) - self.heading_offset))
        self.yaw_initialised = True

    def update(self, gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray, dt: float, nominal_step: float) -> np.ndarray:
        """One sample of corrected gyr [rad/s], acc [m/s²], mag [µT] (finite), dt [s] after the
        previous (0 first), nominal_step [s] the sampling step before it (nominal_steps); returns the
        body -> magnetic NED quaternion [w, x, y, z], w ≥ 0."""
        self.nominal_step = nominal_step
        if self.s["rest_gyro_threshold"] > 0.0 and dt > 0.0:
            self.at_rest = self.rest.update(gyr, acc, dt, self.s["rest_gyro_threshold"], self.s["rest_acc_threshold"])
            if self.at_rest:
                self.bias = self.bias + (1.0 - math.exp(-dt / REST_BIAS_TIME)) * (self.rest.gyr_lp - self.bias)
        rate = gyr - self.bias
        self.mag_disturbed = False
        self._predict(rate, dt)
        self._tilt(acc, dt)
        if self.s["mag_heading"]:
            self._heading(mag, dt)
        self.previous_rate = rate
        half = 0.5 * self.heading_offset
        q = quat_multiply(np.array([math.cos(half), 0.0, 0.0, math.sin(half)]),
                          quat_multiply(self.q_acc, self.q_gyr))
        return q if q[0] >= 0.0 else -q


def run_twin(settings: dict[str, float], t: np.ndarray, gyr: np.ndarray, acc: np.ndarray,
             mag: np.ndarray) -> np.ndarray:
    """(N, 4) body -> magnetic NED quaternions of the filter over a recording of finite samples."""
    f = QuaternionFilter(settings)
    steps = np.diff(t, prepend=t[0])
    nominal = nominal_steps(steps)
    return np.array([f.update(gyr[k], acc[k], mag[k], float(steps[k]), nominal[k]) for k in range(len(t))])


def nominal_steps(steps: np.ndarray) -> list[float]:
    """The guard's nominal step [s] before each sample (sources/ImuGuard.c ImuGuardNominalStep):
    the median of the last STEP_HISTORY steps (positive steps of a recording without gaps; the
    upper of the middle two while fewer are known), 0 before the first step."""
    history: list[float] = []
    nominal = []
    for k, step in enumerate(steps):
        nominal.append(sorted(history)[len(history) // 2] if history else 0.0)
        if k > 0:
            history = (history + [float(step)])[-STEP_HISTORY:]
    return nominal
