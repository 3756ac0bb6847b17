"""What a built FMU is: its provenance record.

The record — generating tool and version, build time (UTC), the training recordings, which
triads and stages the compiled coefficients calibrate, the training notes — is written to
extra/imufusion/provenance.json and summarised in modelDescription.xml (generationTool,
generationDateAndTime, description). Triads and stages are read from the coefficient array
itself (contract.layout offsets), so the record says what the binary actually carries.
"""
from __future__ import annotations

import os
from collections.abc import Sequence
from datetime import datetime, timezone

import numpy as np

from contract.layout import OFFSET_ELM, OFFSET_PSOBP, OFFSET_TERMS, OFFSET_THERMAL, TRIAD_BLOCK, TRIAD_ORDER
from contract.version import DISTRIBUTION, package_version

#: The provenance record inside the FMU (JSON object, `provenance_record`).
PROVENANCE_FILE = "extra/imufusion/provenance.json"

#: ImuPsoBpMode of sources/ImuPsoBp.h (block entry 0).
PSOBP_MODES = {0: "off", 1: "full", 2: "residual"}


def generation_tool() -> str:
    """modelDescription generationTool: our distribution and its version."""
    return f"{DISTRIBUTION} {package_version()} (imufmu build-fmu)"


def build_time() -> str:
    """Build time, UTC, xs:dateTime to the second ('2026-11-24T03:10:11Z'); the environment's
    SOURCE_DATE_EPOCH [s since 1970, UTC] when set, so that rebuilds can be byte-identical."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    moment = datetime.fromtimestamp(int(epoch), timezone.utc) if epoch else datetime.now(timezone.utc)
    return moment.strftime("%Y-%m-%dT%H:%M:%SZ")


def calibration(coefficients: np.ndarray, settings: dict[str, float]) -> dict:
    """What the coefficients and parameter start values calibrate: per triad its enabled flag and
    temperature degree (applied when the parameter enable_thermal is 1), the ELM and PSO-BP stages
    (trained: their block is enabled; on: trained and their enable_* parameter starts at 1), the
    magnetometer particle filter (on: enable_pf starts at 1) and the number of correction terms."""
    c = np.asarray(coefficients, dtype=float)
    triads = {}
    for i, triad in enumerate(TRIAD_ORDER):
        block = c[OFFSET_THERMAL + i * TRIAD_BLOCK:]
        triads[triad] = {"enabled": bool(block[0]), "degree": int(block[3])}
    psobp = PSOBP_MODES.get(int(c[OFFSET_PSOBP]), "unknown")
    return {"thermal_on": bool(settings["enable_thermal"]), "triads": triads,
            "stages": {"elm": {"trained": bool(c[OFFSET_ELM]), "on": bool(c[OFFSET_ELM] and settings["enable_elm"])},
                       "psobp": {"trained": psobp, "on": psobp != "off" and bool(settings["enable_psobp"])},
                       "pf": {"on": bool(settings["enable_pf"])}},
            "correction_terms": int(c[OFFSET_TERMS])}


def provenance_record(coefficients: np.ndarray, settings: dict[str, float], built: str,
                      training_data: Sequence[dict] = (), notes: Sequence[str] = ()) -> dict:
    """The provenance record of an FMU built at `built` (build_time()) from these coefficients
    and settings; training_data: the artefact's [{'name', 'samples'}]; notes: its notes."""
    return {"generation_tool": generation_tool(), "distribution": DISTRIBUTION, "version": package_version(),
            "generation_date_and_time": built,
            "training_data": [dict(d) for d in training_data],
            "calibration": calibration(coefficients, settings),
            "notes": list(notes)}


def _calibration_text(calibrated: dict) -> str:
    """'triads calibrated: gyr (degree 2), acc (degree 0); pass-through: mag; stages on: PSO-BP residual, PF;
    trained but off (enable_*=0): ELM; 3 correction terms'."""
    on = [f"{t} (degree {v['degree']})" for t, v in calibrated["triads"].items() if v["enabled"]]
    off = [t for t, v in calibrated["triads"].items() if not v["enabled"]]
    stages = calibrated["stages"]
    trained = {"ELM": stages["elm"]["trained"], f"PSO-BP {stages['psobp']['trained']}": stages["psobp"]["trained"] != "off"}
    running = [name for name, on_ in zip(trained, (stages["elm"]["on"], stages["psobp"]["on"])) if on_]
    running += ["PF"] if stages["pf"]["on"] else []
    idle = [name for name, is_trained in trained.items() if is_trained and name not in running]
    return (f"triads calibrated: {', '.join(on) or 'none'}" + (f"; pass-through: {', '.join(off)}" if off else "")
            + ("" if calibrated["thermal_on"] else " (enable_thermal=0: not applied)")
            + f"; stages on: {', '.join(running) or 'none'}"
            + (f"; trained but off (enable_*=0): {', '.join(idle)}" if idle else "")
            + f"; {calibrated['correction_terms']} correction terms")


def provenance_summary(record: dict) -> str:
    """One paragraph for the modelDescription description: recordings, calibration, notes."""
    recordings = ", ".join(f"{d['name']} ({d['samples']} samples)" for d in record["training_data"])
    text = f"Trained on: {recordings or 'no recordings (untrained)'}. {_calibration_text(record['calibration'])}."
    if record["notes"]:
        text += " Training notes: " + " | ".join(record["notes"])
    return text
