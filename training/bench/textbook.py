"""Textbook calibration sessions side by side: `imufmu train` against the tool built for the session.

The Ferraris session of imucal (mad-lab-fau/imucal, `example_data/example_ferraris_session.csv`, MIT;
../shared/data/imucal_ferraris) is calibrated twice:

- by imucal's FerrarisCalibration (Ferraris et al., Sensors and Materials 7(5), 1995), from imucal's
  published section list (`ferraris_session_sections.json`: sample ranges of the six faces and three
  turns), as its README shows;
- by `imufmu train` on the raw recording as a new user would run it: no sections, no reference.

Both are judged by the same two invariants on the same samples:

- the gravity-norm spread: std/mean [%] of the calibrated specific-force norm of the mean of every
  rest found on the raw data (training.selfcal.rest; 17 rests on the six faces, some revisited a minute
  later), and of the six static sections' means that imucal fits (a calibrated accelerometer reads the
  same |g| in every pose; imucal's method meets it exactly on its six sections by construction, so the
  rests it did not see are the fairer judge);
- the rest-to-rest gravity-direction error: the rotation each tool's calibrated gyro integrates between
  two consecutive rests (found by training.selfcal.rest on the raw data, the same rests for both) must
  carry the calibrated gravity direction at the first rest to the one at the second (Tedaldi, Pretto,
  Menegatti, ICRA 2014); RMS of the angle left [°] over every pair of consecutive rests that turns by at
  least MIN_ROTATION_DEG (segments with less carry no gain information) within MAX_SEGMENT_S.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from training.data.dataset import ImuData
from training.frames import quat_to_matrix
from training.selfcal.rest import RestWindow, detect_rest
from training.selfcal.rotations import attitudes
from training.selfcal.segments import MAX_SEGMENT_S, MIN_SEGMENT_ROTATION_DEG

#: The six static sections of a Ferraris session (imucal's names).
FACES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
#: imucal's section names for the turns, in its FerrarisSignalRegions.
TURNS = ("x_rot", "y_rot", "z_rot")


@dataclass(frozen=True)
class Calibrated:
    """A tool's calibrated streams of one recording: specific force (N, 3) m/s² and rate (N, 3) rad/s,
    and its scale factors (raw per true, per raw axis) of the accelerometer and gyro (3,)."""

    name: str
    acc: np.ndarray
    gyr: np.ndarray
    acc_scale: np.ndarray
    gyr_scale: np.ndarray


def read_sections(path: Path) -> dict[str, tuple[int, int]]:
    """imucal's section list (JSON {name: {start, end}}, sample indices of the CSV) as {name: (start, end)}."""
    return {k: (int(v["start"]), int(v["end"])) for k, v in json.loads(Path(path).read_text()).items()}


def imucal_calibrated(data: ImuData, sections: dict[str, tuple[int, int]], rate_hz: float) -> Calibrated:
    """imucal's FerrarisCalibration of `data` from its sections (gyro in deg/s as imucal expects),
    applied to the whole recording."""
    import pandas as pd
    from imucal import FerrarisCalibration, ferraris_regions_from_section_list
    frame = pd.DataFrame(np.column_stack([data.acc, np.degrees(data.gyr)]),
                         columns=["acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z"])
    section_list = pd.DataFrame({"start": [a for a, _ in sections.values()],
                                 "end": [b for _, b in sections.values()]}, index=list(sections))
    regions = ferraris_regions_from_section_list(frame, section_list)
    info = FerrarisCalibration().compute(regions, rate_hz, from_acc_unit="m/s^2", from_gyr_unit="deg/s")
    acc, gyr = info.calibrate(data.acc, np.degrees(data.gyr), acc_unit="m/s^2", gyr_unit="deg/s")
    return Calibrated("imucal FerrarisCalibration (published sections)", acc, np.radians(gyr),
                      np.diag(info.K_a).copy(), np.diag(info.K_g).copy())


def face_norm_spread_pct(acc: np.ndarray, sections: dict[str, tuple[int, int]]) -> float:
    """std/mean [%] of the norms of the six faces' mean specific force (acc (N, 3) m/s²)."""
    norms = np.array([np.linalg.norm(acc[a:b].mean(axis=0)) for a, b in (sections[f] for f in FACES)])
    return float(100.0 * np.std(norms) / np.mean(norms))


def rest_norm_spread_pct(acc: np.ndarray, windows: list[RestWindow]) -> float:
    """std/mean [%] of the norms of the rests' mean specific force (acc (N, 3) m/s²)."""
    norms = np.array([np.linalg.norm(acc[w.start:w.stop].mean(axis=0)) for w in windows])
    return float(100.0 * np.std(norms) / np.mean(norms))


def _segments(data: ImuData, windows: list[RestWindow]) -> list[tuple[int, int, int, int]]:
    """(first window, second window, begin sample, end sample) of consecutive rests of `data` whose
    motion lasts at most MAX_SEGMENT_S and turns by at least MIN_SEGMENT_ROTATION_DEG (raw gyro)."""
    out = []
    for k in range(len(windows) - 1):
        a, b = windows[k], windows[k + 1]
        begin, end = a.stop - 1, b.start
        if end <= begin or data.t[end] - data.t[begin] > MAX_SEGMENT_S:
            continue
        turned = np.degrees(np.sum(np.linalg.norm(data.gyr[begin:end], axis=1) * np.diff(data.t[begin:end + 1])))
        if turned >= MIN_SEGMENT_ROTATION_DEG:
            out.append((k, k + 1, begin, end))
    return out


def rest_to_rest_error_deg(data: ImuData, cal: Calibrated, windows: list[RestWindow]) -> tuple[float, int]:
    """(RMS [°], pairs) of the gravity-direction error between consecutive rests (see the module
    docstring) for the calibrated streams `cal` of `data`."""
    errors = []
    for ka, kb, begin, end in _segments(data, windows):
        w = cal.gyr[begin:end + 1]
        inc = 0.5 * (w[:-1] + w[1:]) * np.diff(data.t[begin:end + 1])[:, None]
        rotation = quat_to_matrix(attitudes(inc[None])[0, -1])
        start = cal.acc[windows[ka].start:windows[ka].stop].mean(axis=0)
        stop = cal.acc[windows[kb].start:windows[kb].stop].mean(axis=0)
        predicted = rotation.T @ (start / np.linalg.norm(start))
        errors.append(np.degrees(np.arccos(np.clip(predicted @ stop / np.linalg.norm(stop), -1, 1))))
    return float(np.sqrt(np.mean(np.square(errors)))), len(errors)


@dataclass(frozen=True)
class TwinResult:
    """A simulated twin trained without its truth: the scenario, the artefact, the recording trained on,
    and the errors against the simulator's truth at TWIN_TEMP_C: scale factors [%] and non-orthogonality
    [°] per triad (3,) each."""

    scenario: object
    artefact: object
    data: ImuData
    scale_error_pct: dict
    nonorthogonality_error_deg: dict


#: The twins' sensor temperature [°C]: the truth of a calibration is evaluated there.
TWIN_TEMP_C = 25.0


def truth_summary(scenario, triad: str, temp_c: float = TWIN_TEMP_C) -> dict:
    """training.selfcal.accel.gain_summary of the exact calibration of the simulated sensor's triad."""
    from training.selfcal.accel import gain_summary
    return gain_summary(np.linalg.inv(getattr(scenario.sensor, triad).response(temp_c)))


def trained_twin(path: Path, seed: int = 0) -> TwinResult:
    """Simulate the scenario at `path`, drop its truth columns, `train` on it and compare with the truth."""
    from dataclasses import replace
    from training.selfcal.accel import gain_summary
    from training.simulator import load_scenario, simulate
    from training.train import train
    scenario = load_scenario(path)
    data = simulate(scenario, seed=seed)
    blind = replace(data, ref_q=None, ref_gyr=None, ref_acc=None, ref_mag=None, meta={**data.meta, "reference": "none"})
    artefact = train([blind], seed=seed, progress=False)
    scale, nonorth = {}, {}
    for triad in ("acc", "gyr"):
        truth, fitted = truth_summary(scenario, triad), gain_summary(artefact.thermal[triad].A)
        scale[triad] = 100.0 * (np.array(fitted["scale_factors"]) - truth["scale_factors"])
        nonorth[triad] = np.array([fitted["nonorthogonality_deg"][k] - truth["nonorthogonality_deg"][k]
                                   for k in truth["nonorthogonality_deg"]])
    return TwinResult(scenario, artefact, blind, scale, nonorth)


def rests(data: ImuData) -> list[RestWindow]:
    """The rests (not holds) of `data` found on the raw signals: the pairs both tools are judged on."""
    return [w for w in detect_rest(data).windows if w.kind == "rest"]
