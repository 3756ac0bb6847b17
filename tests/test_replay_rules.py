"""The rule by which a replay of the referenced calibration recordings changes what `train` writes
(training.attitude.replay): only a change that lowers the attitude error on every recording is taken,
for the replayed filter settings and for each triad's reference-derived calibration. The replay itself
is replaced by a table of per-recording errors, so each case states what the rule must decide."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from training.artefact import ModelArtefact
from training.attitude import replay
from training.models.thermal import ThermalModel


@dataclass
class _Recording:
    name: str
    ref_q: np.ndarray


_SETS = [_Recording("trial_a", np.ones((800, 4))), _Recording("trial_b", np.ones((800, 4)))]


@pytest.mark.parametrize("candidate, incumbent, taken", [
    ([1.0, 1.3], [1.1, 1.4], True),     # lower on both
    ([0.9, 1.5], [1.1, 1.4], False),    # much lower on one, higher on the other (lower in total)
    ([1.1, 1.3], [1.1, 1.4], False),    # equal on one
    ([], [], False),                    # nothing replayed
])
def test_a_change_is_taken_only_when_every_recording_agrees(candidate, incumbent, taken):
    assert replay.lower_on_every(candidate, incumbent) is taken


def _replay_table(monkeypatch, table: dict[float, list[float]]):
    """replayed answers from `table` (motion_bias value -> per-recording RMSE; the total their RMS);
    gyro_hold's alternative is always worse."""
    def per(coefficients, settings, sets):
        return [v + (0.5 if settings.get("gyro_hold") == 0.0 else 0.0) for v in table[settings["motion_bias"]]]
    monkeypatch.setattr(replay, "replayed", lambda c, s, sets: (per(c, s, sets),
                                                                float(np.sqrt(np.mean(np.square(per(c, s, sets)))))))
    monkeypatch.setattr(replay, "referenced", lambda datasets: _SETS)


def test_the_default_stays_when_one_recording_prefers_the_alternative_and_the_other_does_not(monkeypatch):
    """BROAD 01 + 02's case: motion_bias = 0 much better on the first, worse on the second."""
    _replay_table(monkeypatch, {1.0: [1.233, 1.375], 0.0: [1.005, 1.401]})
    notes: list[str] = []
    chosen = replay.choose_by_replay(np.zeros(1), {"gyro_hold": 1.0, "motion_bias": 1.0}, [], notes)
    assert chosen["motion_bias"] == 1.0
    note = next(n for n in notes if n.startswith("motion_bias = 1"))
    assert "0 is lower in total but not on every recording" in note and "trial_a: 1.233° / 1.005°" in note


def test_the_alternative_is_written_when_every_recording_prefers_it(monkeypatch):
    _replay_table(monkeypatch, {1.0: [1.233, 1.375], 0.0: [1.005, 1.301]})
    notes: list[str] = []
    chosen = replay.choose_by_replay(np.zeros(1), {"gyro_hold": 1.0, "motion_bias": 1.0}, [], notes)
    assert chosen == {"gyro_hold": 1.0, "motion_bias": 0.0}
    assert not any("not on every recording" in n for n in notes)


def _artefact(gains: dict[str, float], reference: str) -> ModelArtefact:
    thermal = {t: ThermalModel(True, 25.0, 1.0, 0, np.eye(3) * g, np.zeros((3, 0)), np.zeros((3, 1)))
               for t, g in gains.items()}
    return ModelArtefact(seed=0, thermal=thermal, settings={},
                         fit_stats={t: {"reference": reference} for t in gains})


def test_a_triad_keeps_its_reference_derived_calibration_only_where_every_recording_improves(monkeypatch):
    """Reference-derived gyro: better on one recording, worse on the other -> self-calibrated and said
    loudly; reference-derived accelerometer: better on both -> kept; magnetometer: no change -> not kept."""
    blind = _artefact({"gyr": 1.0, "acc": 1.0, "mag": 1.0}, "none")
    derived = _artefact({"gyr": 2.125, "acc": 3.375, "mag": 1.0}, "attitude")
    errors = {"none": [1.2, 1.4], "gyr": [1.1, 1.5], "acc": [1.1, 1.3]}

    def per(coefficients, settings, sets):
        changed = [t for t, k in (("gyr", 2.125), ("acc", 3.375)) if np.isclose(coefficients, k).any()]
        return errors[changed[0] if changed else "none"], float("nan")
    monkeypatch.setattr(replay, "replayed", per)
    monkeypatch.setattr(replay, "referenced", lambda datasets: _SETS)
    kept, notes = replay.triads_the_reference_improves(derived, blind, [])
    assert kept == ("acc",)
    assert notes[0].startswith(f"{replay.REFERENCE_JUDGED} for the gyroscope") and "NOT exported" in notes[0]
    assert notes[1].startswith(f"{replay.REFERENCE_KEPT} for the accelerometer")
    assert notes[2].startswith(f"{replay.REFERENCE_JUDGED} for the magnetometer")


def test_a_reference_that_cannot_be_replayed_keeps_its_calibration_and_says_it_was_not_judged(monkeypatch):
    """No reference sample inside any eval_mask: every replay is NaN, nothing can be judged, so the
    calibration derived from the reference stays (it is what the data offer) and the note says so."""
    monkeypatch.setattr(replay, "replayed", lambda c, s, sets: ([float("nan")] * len(sets), float("nan")))
    monkeypatch.setattr(replay, "referenced", lambda datasets: _SETS)
    derived = _artefact({"gyr": 2.125, "acc": 1.0, "mag": 1.0}, "attitude")
    kept, notes = replay.triads_the_reference_improves(derived, _artefact({"gyr": 1.0, "acc": 1.0, "mag": 1.0}, "none"), [])
    assert kept == ("gyr", "acc", "mag")
    assert notes == [f"{replay.REFERENCE_KEPT} for the gyroscope, accelerometer, magnetometer, not judged: no "
                     "recording has a reference sample inside its eval_mask to replay"]
