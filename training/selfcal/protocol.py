"""Which calibration protocol a recording follows, recognised from what the self-calibration found in it,
and what each part of it identified.

Protocols (docs/calibration.md, "Recordings train recognises"):

- **Ferraris** (Ferraris et al., Sensors and Materials 7(5), 1995; imucal): the six faces of a box
  (training.selfcal.faces) and full turns about each axis held vertical (training.selfcal.turns);
- **multi-pose** (Tedaldi, Pretto, Menegatti, ICRA 2014): at least MULTI_POSE_POSES distinct poses joined
  by moves; **the ImuFusion protocol** (docs/calibration.md) adds full turns about each axis
  (PROTOCOL_FULL_TURNS, from a corner) and a tumble (the field over TUMBLE_COVERAGE of the sphere);
- **rests only at the ends** (a robot or vehicle log): every rest within END_SHARE of a recording's
  start or end;
- **a static log**: one pose, no motion between rests;
- otherwise **a plain log** with a few rests.

What a part identified comes from the regularised fits (training.selfcal.regularised): each fitted
parameter names the residual group that informed it most; the parts are those groups.
"""
from __future__ import annotations

from training.selfcal.rest import RestWindow

#: Distinct poses (gravity directions ≥ 12° apart) that make a multi-pose session: the gravity-norm fit
#: has 9 unknowns.
MULTI_POSE_POSES = 9
#: Share of a recording's duration at each end within which all rests of an "ends only" log lie.
END_SHARE = 0.15
#: Field-direction coverage (share of the sphere's cells, training.selfcal.magnet) of a tumble.
TUMBLE_COVERAGE = 0.5
#: Full turns (about any axis, between rests of one pose) of the ImuFusion protocol: one about each axis.
PROTOCOL_FULL_TURNS = 3
#: What each residual group of the fits is, in the words of the protocol.
PARTS = {"gravity norm": "gravity norm at the rests", "face directions": "the six faces of the box",
         "gravity directions": "rotation between rests (gravity)", "field directions": "rotation between rests (field)",
         "closed turns": "full turns (known angle)"}


def _ends_only(windows: list[RestWindow], spans: dict[int, tuple[float, float]]) -> bool:
    """True when every rest of every recording lies within END_SHARE of that recording's start or end."""
    rests = [w for w in windows if w.kind == "rest"]
    if not rests:
        return False
    for w in rests:
        t0, t1 = spans[w.dataset]
        edge = END_SHARE * (t1 - t0)
        if not (w.t_stop <= t0 + edge or w.t_start >= t1 - edge):
            return False
    return True


def protocol_name(report: dict, windows: list[RestWindow], spans: dict[int, tuple[float, float]]) -> str:
    """The protocol the self-calibration report (per triad, training.selfcal) and its windows show;
    spans: {recording index: (first, last) time [s]}."""
    acc, gyr, mag = report.get("acc", {}), report.get("gyr", {}), report.get("mag", {})
    poses, turns = int(acc.get("poses") or 0), len(gyr.get("closed_turns") or [])
    segments = int(gyr.get("segments") or 0)
    if acc.get("faces"):
        return f"Ferraris: the six faces of a box and {turns} full turn(s) about a vertical axis" if turns else \
            "the six faces of a box (Ferraris, without its full turns)"
    if poses >= MULTI_POSE_POSES and segments:
        coverage = float(mag.get("coverage") or 0.0)
        full = int(gyr.get("full_turns") or 0)
        ours = full >= PROTOCOL_FULL_TURNS and coverage >= TUMBLE_COVERAGE
        return (f"{'the ImuFusion protocol (docs/calibration.md)' if ours else 'multi-pose (Tedaldi et al.)'}: "
                f"{poses} poses, {segments} moves between rests, {full} full turn(s)"
                + (f", field directions over {100 * coverage:.0f} % of the sphere" if mag.get("coverage") is not None else ""))
    rests = sum(w.kind == "rest" for w in windows)
    if _ends_only(windows, spans):
        return f"a log with rests only at its ends (robot or vehicle): {rests} rest(s), {segments} usable move(s)"
    if poses <= 1 and not segments:
        return f"a static log: {rests} rest(s) in one pose"
    return f"a plain log: {rests} rest(s), {poses} pose(s), {segments} move(s) between rests"


def identified_by_part(report: dict) -> dict[str, list[str]]:
    """{part: ['acc gain x', 'gyr gain z', ...]}: the parameters each part of the recording determined
    (held ones left out); the gyro bias counts for the rests."""
    out: dict[str, list[str]] = {}
    for triad in ("acc", "gyr"):
        for p in report.get(triad, {}).get("parameters") or []:
            if not p["held"] and p["from"]:
                out.setdefault(PARTS.get(p["from"], p["from"]), []).append(f"{triad} {p['label']}")
    if int(report.get("gyr", {}).get("bias_rests") or 0):
        out.setdefault("the rests", []).append("gyr bias")
    if str(report.get("mag", {}).get("fitted", "nothing")) != "nothing":
        out.setdefault("field over the recording", []).append(f"mag {report['mag']['fitted']}")
    return out


def recognise(report: dict, windows: list[RestWindow], spans: dict[int, tuple[float, float]]) -> dict:
    """{'name': the protocol, 'identified': {part: parameters}} (JSON-ready)."""
    return {"name": protocol_name(report, windows, spans), "identified": identified_by_part(report)}


def recording_spans(datasets) -> dict[int, tuple[float, float]]:
    """{index: (first, last) time [s]} of each recording (0, 0 when empty)."""
    return {i: (float(d.t[0]), float(d.t[-1])) if len(d) else (0.0, 0.0) for i, d in enumerate(datasets)}
