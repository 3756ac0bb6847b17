"""Declared types and ranges of the FMU parameters, with each bound named and derived (physics, or
the runtime's fixed array sizes). contract/variables.py gives every parameter one of these;
contract/schema.py checks values against them; tests/test_value_checks.py pins the C runtime's
ImuPipelineSettingsCheck to them bound by bound."""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SettingRange:
    """Declared type and range of one setting: Real, Integer (whole numbers) or Boolean (0 or 1).

    min/max [unit] are inclusive unless min_open/max_open (the bound itself is refused; FMI's
    min/max attributes cannot say so, so the FMU refuses it at initialisation); nonzero: 0 is
    refused too (likewise refused only at initialisation). unit: the FMI unit
    of a Real (None: dimensionless). typical (angles in rad only): a |value| above it is legal but
    looks like degrees given as rad (warned about in degrees, not refused).
    """

    type: str
    min: float
    max: float
    unit: str | None = None
    min_open: bool = False
    max_open: bool = False
    typical: float | None = None
    nonzero: bool = False


#: Named bounds of the settings, from physics and from the runtime's fixed-size arrays.
#: Declination: ±180° by definition; beyond 30° it occurs only near the magnetic poles (IGRF),
#: so a larger value more likely is degrees given as rad (2.5 "degrees" would be 143°).
DECLINATION_TYPICAL_RAD = math.radians(30.0)
#: Earth-field magnitude [µT]: the surface field is 22–67 µT; the bounds are the loader's
#: (training/data/io.py MAG_MEDIAN_NORM_MIN_UT/MAX_UT, pinned by tests/test_value_checks.py): a value
#: in gauss is 100× smaller, one in nT 1000× larger.
FIELD_NORM_MIN_UT = 5.0
FIELD_NORM_MAX_UT = 1000.0
#: Gyro white-noise density [rad/s/√Hz]: 0.1 is about 60× the noisiest MEMS gyro (~0.1 °/s/√Hz).
GYRO_NOISE_MAX = 0.1
#: Gyro rates of settings [rad/s] (residual bias, rest threshold): 1 rad/s = 57 °/s is no bias and no rest.
GYRO_RATE_SETTING_MAX = 1.0
#: Time constants and rejection time [s]: at most one day.
TIME_SETTING_MAX_S = 86400.0
#: Standard gravity [m/s²]: a rest threshold on the specific-force deviation above 1 g detects nothing.
STANDARD_GRAVITY = 9.80665
#: Particle filter (sources/ImuMagPf.h/.c ImuMagPfSettingsCheck): fixed array sizes and its ranges.
PF_MAX_PARTICLES = 512          # IMU_MAG_PF_MAX_PARTICLES
PF_MAX_DECIMATION = 1000
PF_MAX_SPHERE_BINS = 4          # IMU_MAG_PF_MAX_BIN_SIDE
PF_NOISE_MAX_UT = 100.0         # measurement and hard-iron process noise [µT]
PF_SPREAD_MAX_UT = 1.0e4        # hard-iron spreads [µT] (10 mT saturates any magnetometer)
PF_THRESHOLD_HIGH_MAX = 100.0   # ω1 relative to 1/N
#: Every bit of the Euler fusion's project additions (sources/ImuAttitude.h IMU_EULER_ALL_ADDITIONS; a test pins it).
EULER_ALL_ADDITIONS = 63
#: Time alignment [s]: a lag of a second is far beyond any sensor's (milliseconds); the runtime's
#: buffer (sources/ImuAlign.h IMU_ALIGN_CAPACITY samples) reaches back less at rates above 63 Hz.
LAG_MAX_S = 1.0
#: Largest FMI Integer (Int32): the seed's upper bound.
INT32_MAX = 2**31 - 1

REAL, INTEGER, BOOLEAN = "Real", "Integer", "Boolean"
FLAG = SettingRange(BOOLEAN, 0.0, 1.0)
TIME = SettingRange(REAL, 0.0, TIME_SETTING_MAX_S, "s", min_open=True)
UNIT_FRACTION = SettingRange(REAL, 0.0, 1.0)
LAG = SettingRange(REAL, -LAG_MAX_S, LAG_MAX_S, "s")
PF_SPREAD = SettingRange(REAL, 0.0, PF_SPREAD_MAX_UT, "uT")
#: A signed sensor axis (±1..±3); 0 and a triple that repeats or mirrors an axis are refused
#: together (training/mounting.py mounting_problem, ImuPipelineSettingsCheck).
MOUNT_AXIS = SettingRange(INTEGER, -3.0, 3.0, nonzero=True)
#: Settings that are only valid together (ImuMagPfSettingsCheck): with pf_rao_blackwell = 1 the
#: hard-iron spreads must be > 0 µT.
RAO_BLACKWELL_POSITIVE = ("pf_prior_spread_hard", "pf_change_spread_hard")
