"""The earth field in the frame of an attitude reference: its norm, its dip and the angle between the
reference frame's north and magnetic north, from the sidecar, the IGRF model at the sidecar's site, or the
recording's own magnetometer.

An attitude reference ``ref_q`` rotates the body into the reference's own NED frame. For a GNSS-aided
INS that frame's north is true north; for a motion-capture hall or a robot cell it is wherever the
hall's or cell's x axis points, turned about the vertical by an angle nobody measured. The sidecar's
``earth_field.declination_deg`` is that angle (magnetic north east of the reference frame's north);
``null`` or absent means unknown (ARCHITECTURE.md, 'Canonical dataset'). `reference_field` resolves
norm, dip and that angle, each with where it came from:

- a number in the sidecar;
- the IGRF model at the sidecar's ``site`` (training.data.geomag) — for the declination only when the
  reference frame is geographic (``"reference": "gnss-ins"``): a hall's or a cell's frame is not;
- the recording's magnetometer seen through the reference attitude (`estimate_heading`): the
  magnetometer calibrated against the attitude reference with the field's direction in the reference
  frame left free — its heading is the angle, its dip the dip — over the samples whose field norm is
  undisturbed, with a jackknife uncertainty. Used when that uncertainty is at most
  MAX_HEADING_SIGMA_DEG; otherwise the angle stays unknown and the field reference is left out (the
  magnetometer then self-calibrates from invariants).

The norm is never taken from the magnetometer: a field reference scaled by the sensor's own norm would
calibrate the sensor against itself (without a sidecar norm or a site, `train` self-calibrates the
magnetometer to the recording's own norm, as before). The field's direction differs from place to
place indoors (steel in walls and floors: several degrees across a lab — on the undisturbed BROAD trials,
whose frame the data set's authors aligned with magnetic north, the trusted estimates range from −5.3°
to +0.1°), so the angle is the recording's: the mean over the places it was moved through.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from training.data.dataset import ImuData
from training.data.earth import EarthField
from training.frames import quat_to_matrix

#: Trust bound of an estimated heading offset [deg, 1σ]. The offset turns the derived field reference
#: about the vertical: an error ε moves it by H·ε (H the horizontal field: 13 µT at BROAD's 41.6 µT,
#: dip 71°, so 0.23 µT per degree), and moves the reference heading that evaluations compare against
#: by ε. At 1° both stay below what they are used to judge — a consumer magnetometer's noise and
#: quantisation (0.3–1 µT) and the 1.5–5° heading error of the attitude filters on BROAD
#: (docs/BENCHMARKS.md). A less certain angle would make the field reference worse than the
#: magnetometer's self-calibration from invariants, which needs no angle at all.
MAX_HEADING_SIGMA_DEG = 1.0
#: Samples whose field norm (calibrated by the fit) departs from the median by more than this many
#: robust σ (1.4826 · MAD) are disturbed (a magnet, steel, a motor nearby) and take no part.
NORM_SIGMAS = 3.0
#: Groups of the jackknife that gives the uncertainty. A group is a set of the field's directions in
#: the body (cells below), every BLOCKS-th visited cell: leaving one group out removes those directions,
#: so the uncertainty says how much the angle rests on which directions were seen — what the pose
#: changes (soft iron, a hard iron the rotations barely separate from the field, the reference's tilt
#: errors) shows, and samples that repeat one direction (a long still start) count once. Contiguous
#: blocks in time would count a still start several times: on the simulated protocol's first 50 s they
#: gave 0.35° for an error of 1.1°; these groups give 1.7°.
BLOCKS = 8
#: Fewest usable samples per group.
MIN_BLOCK_SAMPLES = 10
#: Direction cells: 6 bands of equal height in the body's z (equal area, Archimedes) × 12 sectors of
#: azimuth = 72 cells of ~30° × 30° (as training/selfcal/magnet.py counts coverage); a cell counts as
#: visited with MIN_CELL_SAMPLES samples.
COVERAGE_BANDS = 6
COVERAGE_SECTORS = 12
MIN_CELL_SAMPLES = 3
#: Fewest visited cells: two per jackknife group, 3 × 16 = 48 field components for the fit's 14
#: parameters. Fewer directions leave the magnetometer's matrix K free to turn with the field (a turn
#: about one axis only identifies no heading at all: K absorbs it).
MIN_CELLS = 2 * BLOCKS
#: Samples the fit uses at most (every k-th sample beyond): at 100–300 Hz neighbouring samples carry
#: the same attitude, so thinning to this many loses nothing but time (9 fits for the jackknife).
MAX_FIT_SAMPLES = 5000


@dataclass(frozen=True)
class HeadingEstimate:
    """The earth field's direction in the reference frame, fitted from the magnetometer: angle_deg
    (magnetic north east of the reference frame's north, in (−180, 180]), sigma_deg (its 1σ
    uncertainty, jackknife over direction groups), dip_deg and dip_sigma_deg (the same for the dip), samples used,
    residual_ut (RMS of the fit over them) and hard_iron_ut (3,) of the fit."""

    angle_deg: float
    sigma_deg: float
    dip_deg: float
    dip_sigma_deg: float
    samples: int
    residual_ut: float
    hard_iron_ut: tuple[float, float, float]

    @property
    def trusted(self) -> bool:
        """The angle is certain enough to derive a field reference from (MAX_HEADING_SIGMA_DEG)."""
        return self.sigma_deg <= MAX_HEADING_SIGMA_DEG

    def text(self) -> str:
        """'the reference frame is turned X° ± Y° from magnetic north, estimated from the magnetometer (…)'."""
        return (f"the reference frame is turned {self.angle_deg:.2f}° ± {self.sigma_deg:.2f}° from magnetic north "
                f"(magnetic north east of its north), estimated from the magnetometer ({self.samples} samples with "
                f"an undisturbed field, fit residual {self.residual_ut:.2g} µT RMS)")


def robust_sigma(x: np.ndarray) -> float:
    """1.4826 · median |x − median x| (the σ of a normal distribution)."""
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _direction(angles: np.ndarray) -> np.ndarray:
    """Unit vector (3,) in NED of [heading, dip] [rad]."""
    return np.array([np.cos(angles[1]) * np.cos(angles[0]), np.cos(angles[1]) * np.sin(angles[0]), np.sin(angles[1])])


def _fit_field(rot: np.ndarray, mag: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, K, b): unit field direction n (3,) in the reference frame, magnetometer matrix K (3, 3) [µT]
    and offset b (3,) [µT] of m_i = K R_iᵀ n + b, least squares over the samples (rot (N, 3, 3) body ->
    reference, mag (N, 3) µT). K is general — gains, soft iron, and the rotation between the
    magnetometer's axes and the reference's body axes — so none of them tilts or turns n.

    Bilinear in K and n; n = [cos θ cos ψ, cos θ sin ψ, sin θ] (heading ψ, dip θ) fixes the scale, det K > 0
    the sign. Start: K = I, where m_i = R_iᵀ v + b is linear in (v, b), then (K, b) given n (linear);
    then Levenberg-Marquardt on all 14 parameters (scipy.optimize.least_squares, analytic Jacobian:
    ∂r_i/∂K_aj = u_i,j e_a, ∂r_i/∂b = I, ∂r_i/∂(ψ, θ) = K R_iᵀ ∂n/∂(ψ, θ), u_i = R_iᵀ n)."""
    from scipy.optimize import least_squares
    count = len(mag)
    design = np.column_stack([np.transpose(rot, (0, 2, 1)).reshape(-1, 3), np.tile(np.eye(3), (count, 1))])
    v = np.linalg.lstsq(design, mag.ravel(), rcond=None)[0][:3]
    start_angles = _angles(v)
    u = np.tensordot(rot, _direction(start_angles), axes=([1], [0]))  # (N, 3) R_iᵀ n
    kb = np.linalg.lstsq(np.column_stack([u, np.ones(count)]), mag, rcond=None)[0]

    def unpack(p):
        return p[:9].reshape(3, 3), p[9:12], p[12:]

    def residual(p):
        k, b, angles = unpack(p)
        return (np.tensordot(rot, _direction(angles), axes=([1], [0])) @ k.T + b - mag).ravel()

    def jacobian(p):
        k, _, (psi, theta) = unpack(p)
        u = np.tensordot(rot, _direction(p[12:]), axes=([1], [0]))
        jac = np.zeros((count, 3, 14))
        for a in range(3):
            jac[:, a, 3 * a:3 * a + 3] = u
            jac[:, a, 9 + a] = 1.0
        dn = np.array([[-np.cos(theta) * np.sin(psi), -np.sin(theta) * np.cos(psi)],
                       [np.cos(theta) * np.cos(psi), -np.sin(theta) * np.sin(psi)],
                       [0.0, np.cos(theta)]])                          # ∂n/∂(ψ, θ)
        jac[:, :, 12:] = np.einsum("aj,njk->nak", k, np.tensordot(rot, dn, axes=([1], [0])))
        return jac.reshape(-1, 14)

    start = np.concatenate([kb[:3].T.ravel(), kb[3], start_angles])
    p = least_squares(residual, start, jac=jacobian, method="lm", xtol=1e-12, ftol=1e-12).x
    k, b, angles = unpack(p)
    n = _direction(angles)
    if np.linalg.det(k) < 0:                                           # the same fit as −K, −n
        n, k = -n, -k
    return n, k, b


def _angles(n: np.ndarray) -> np.ndarray:
    """[heading, dip] [rad] of a field direction n in NED: atan2(E, N), atan2(D, horizontal)."""
    return np.array([np.arctan2(n[1], n[0]), np.arctan2(n[2], np.hypot(n[0], n[1]))])


def _undisturbed(rot: np.ndarray, mag: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(mask of the samples whose field norm is undisturbed, n, K, b): fit, drop the samples whose
    calibrated norm |K⁻¹(m − b)| departs from the median by more than NORM_SIGMAS robust σ, refit."""
    keep = np.ones(len(mag), bool)
    for _ in range(2):
        n, k, b = _fit_field(rot[keep], mag[keep])
        norm = np.linalg.norm(np.linalg.solve(k, (mag - b).T), axis=0)
        keep = np.abs(norm - np.median(norm[keep])) <= NORM_SIGMAS * max(robust_sigma(norm[keep]), 1e-9)
    return keep, n, k, b


def direction_cells(u: np.ndarray) -> np.ndarray:
    """Index (N,) of the COVERAGE_BANDS × COVERAGE_SECTORS equal-area cell of each unit direction u (N, 3)."""
    band = np.clip(((u[:, 2] + 1.0) * 0.5 * COVERAGE_BANDS).astype(int), 0, COVERAGE_BANDS - 1)
    sector = np.clip(((np.arctan2(u[:, 1], u[:, 0]) + np.pi) / (2 * np.pi) * COVERAGE_SECTORS).astype(int),
                     0, COVERAGE_SECTORS - 1)
    return band * COVERAGE_SECTORS + sector


def _groups(u: np.ndarray) -> list[np.ndarray] | str:
    """The jackknife's BLOCKS groups of sample indices by the cell of the field's body direction u (N, 3)
    (cell k of the visited ones -> group k mod BLOCKS), or why there are too few directions (text)."""
    cells = direction_cells(u)
    counts = np.bincount(cells, minlength=COVERAGE_BANDS * COVERAGE_SECTORS)
    visited = np.flatnonzero(counts >= MIN_CELL_SAMPLES)
    if len(visited) < MIN_CELLS:
        return (f"the field's direction in the body visits {len(visited)} of {COVERAGE_BANDS * COVERAGE_SECTORS} "
                f"direction cells, fewer than the {MIN_CELLS} the fit needs")
    group = np.full(COVERAGE_BANDS * COVERAGE_SECTORS, -1)
    group[visited] = np.arange(len(visited)) % BLOCKS
    return [np.flatnonzero(group[cells] == g) for g in range(BLOCKS)]


def estimate_heading(q: np.ndarray | None, mag: np.ndarray | None) -> HeadingEstimate | str:
    """The earth field's direction in the frame of the attitude reference q (N, 4) [w, x, y, z] (body
    -> reference frame), from the magnetometer mag (N, 3) [µT]: a HeadingEstimate, or the reason (text)
    why there is none.

    The fit (`_fit_field`) is the magnetometer's calibration against the attitude reference with the
    field direction free: m_i = K R(q_i)ᵀ n + b. Its heading is the angle, its dip the dip; both need
    the attitude to vary over MIN_CELLS directions of the field in the body (a still recording, or a turn
    about the vertical only, determines neither). Samples with a disturbed field norm are left out
    (`_undisturbed`). Uncertainty: delete-a-group jackknife over the BLOCKS direction groups (`_groups`),
    σ² = (B − 1)/B · Σ (θ_k − θ̄)², θ_k fitted without group k (Efron & Stein 1981)."""
    if q is None or mag is None:
        return "no attitude reference" if q is None else "no magnetometer"
    q, mag = np.asarray(q, dtype=np.float64), np.asarray(mag, dtype=np.float64)
    if not np.isfinite(mag).any():
        return "no magnetometer"
    ok = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(mag), axis=1) & (np.linalg.norm(q, axis=1) > 0.5)
    least = BLOCKS * MIN_BLOCK_SAMPLES
    rows = np.flatnonzero(ok)[::max(1, int(np.ceil(ok.sum() / MAX_FIT_SAMPLES)))]
    if len(rows) < least:
        return f"{int(ok.sum())} samples carry both the attitude reference and the magnetometer, fewer than {least}"
    rot = quat_to_matrix(q[rows] / np.linalg.norm(q[rows], axis=1, keepdims=True))
    mag = mag[rows]
    with np.errstate(all="ignore"):
        try:
            keep, n, k, b = _undisturbed(rot, mag)
        except np.linalg.LinAlgError:
            return "the attitude does not vary enough to separate the field from the magnetometer's offset"
        if keep.sum() < least:
            return f"only {int(keep.sum())} samples with an undisturbed field, fewer than {least}"
        rot, mag = rot[keep], mag[keep]
        full = _angles(n)
        residual = float(np.sqrt(np.mean((mag - (rot.transpose(0, 2, 1) @ n) @ k.T - b) ** 2)))
        parts = _groups(np.einsum("nji,j->ni", rot, n))
        if isinstance(parts, str):
            return parts
        left_out = []
        for part in parts:
            use = np.ones(len(mag), bool)
            use[part] = False
            try:
                left_out.append(_angles(_fit_field(rot[use], mag[use])[0]))
            except np.linalg.LinAlgError:
                left_out.append(np.full(2, np.nan))
    left_out = np.array(left_out)
    d = np.angle(np.exp(1j * (left_out - full)))                       # wrapped differences
    sigma = np.sqrt((BLOCKS - 1) / BLOCKS * np.sum((d - d.mean(axis=0)) ** 2, axis=0))
    if not np.all(np.isfinite(np.concatenate([full, sigma]))):
        return "the attitude does not vary enough to separate the field from the magnetometer's offset"
    return HeadingEstimate(angle_deg=float(np.rad2deg(full[0])), sigma_deg=float(np.rad2deg(sigma[0])),
                           dip_deg=float(np.rad2deg(full[1])), dip_sigma_deg=float(np.rad2deg(sigma[1])),
                           samples=int(len(mag)), residual_ut=residual, hard_iron_ut=tuple(float(v) for v in b))


#: Reference kinds whose frame is geographic (north = true north): their unknown declination is the
#: IGRF declination at the sidecar's site. A motion-capture hall's or a robot cell's frame is not.
GEOGRAPHIC_REFERENCES = ("gnss-ins",)


@dataclass(frozen=True)
class ReferenceField:
    """The earth field in the frame of a recording's attitude reference: norm_ut [µT], dip_deg [deg] and
    declination_deg [deg] (magnetic north east of the reference frame's north), each None when unknown,
    with `sources` {key: where it came from, or why it is unknown} and the magnetometer's `estimate`
    (HeadingEstimate, the reason there is none, or None when it was not needed)."""

    norm_ut: float | None
    dip_deg: float | None
    declination_deg: float | None
    sources: dict = field(default_factory=dict)
    estimate: HeadingEstimate | str | None = None

    def earth_field(self) -> EarthField | None:
        """The field (EarthField, declination = the reference frame's) when all three are known, else None."""
        if None in (self.norm_ut, self.dip_deg, self.declination_deg):
            return None
        return EarthField(self.norm_ut, self.dip_deg, self.declination_deg)

    def declination_rad(self) -> float:
        """The reference frame's angle [rad], 0 when unknown (then the attitude relative to magnetic north
        is the reference's own: right for a frame aligned with magnetic north, and the best guess left)."""
        return 0.0 if self.declination_deg is None else float(np.deg2rad(self.declination_deg))

    def text(self) -> str:
        """'norm 48.1 µT (the sidecar), dip …, declination …' for notes."""
        parts = []
        for key, label, unit in (("norm_ut", "norm", " µT"), ("dip_deg", "dip", "°"),
                                 ("declination_deg", "reference-frame declination", "°")):
            value = getattr(self, key)
            parts.append(f"{label} " + (f"{value:.4g}{unit} ({self.sources[key]})" if value is not None
                                        else f"unknown ({self.sources[key]})"))
        return ", ".join(parts)


def _sidecar(data: ImuData) -> dict:
    ef = data.meta.get("earth_field")
    return ef if isinstance(ef, dict) else {}


def _site(data: ImuData):
    """(IGRF field at the sidecar's site or None, the reason there is none)."""
    from training.data.geomag import site_field
    try:
        igrf = site_field(data.meta)
    except ValueError as e:
        return None, f"the site is malformed: {e}"
    return igrf, "no site in the sidecar" if igrf is None else ""


_CACHE: dict = {}
#: Resolved fields kept (by the content of the recording's attitude, field and sidecar): `train` asks for
#: each recording's field once per triad and again in its stages.
_CACHE_SIZE = 16


def _key(data: ImuData) -> str:
    import hashlib
    import json
    h = hashlib.blake2b(digest_size=16)
    for a in (data.ref_q, data.mag):
        if a is not None:
            h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(json.dumps({k: data.meta.get(k) for k in ("earth_field", "site", "reference")},
                        sort_keys=True, default=str).encode())
    return h.hexdigest()


def reference_field(data: ImuData) -> ReferenceField:
    """Resolve the earth field in the frame of `data`'s attitude reference (module docstring):
    norm: the sidecar, else IGRF at the site, else unknown; dip: the sidecar, else IGRF at the site, else
    the magnetometer's estimate; declination: the sidecar, else (a geographic reference, GEOGRAPHIC_REFERENCES)
    IGRF at the site, else the magnetometer's estimate when trusted (MAX_HEADING_SIGMA_DEG), else unknown."""
    key = _key(data)
    if key not in _CACHE:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = _resolve(data)
    return _CACHE[key]


def _resolve(data: ImuData) -> ReferenceField:
    side, values, sources = _sidecar(data), {}, {}
    complete = all(side.get(k) is not None for k in ("norm_ut", "dip_deg", "declination_deg"))
    igrf, no_site = (None, "") if complete else _site(data)
    kind = str(data.meta.get("reference") or "").lower()
    for key in ("norm_ut", "dip_deg", "declination_deg"):
        if side.get(key) is not None:
            values[key], sources[key] = float(side[key]), "the sidecar"
        elif igrf is not None and (key != "declination_deg" or kind in GEOGRAPHIC_REFERENCES):
            values[key], sources[key] = float(getattr(igrf, key)), "IGRF at the sidecar's site"
        else:
            values[key] = None
    estimate = None
    if values["dip_deg"] is None or values["declination_deg"] is None:
        estimate = estimate_heading(data.ref_q, data.mag if data.has("mag") else None)
    for key, attr, sigma in (("dip_deg", "dip_deg", "dip_sigma_deg"), ("declination_deg", "angle_deg", "sigma_deg")):
        if values[key] is not None:
            continue
        if isinstance(estimate, HeadingEstimate) and getattr(estimate, sigma) <= MAX_HEADING_SIGMA_DEG:
            values[key] = getattr(estimate, attr)
            sources[key] = (f"estimated from the magnetometer, ± {getattr(estimate, sigma):.2f}° "
                            f"({estimate.samples} samples)")
        elif isinstance(estimate, HeadingEstimate):
            sources[key] = (f"the magnetometer's estimate {getattr(estimate, attr):.1f}° ± {getattr(estimate, sigma):.1f}° "
                            f"is less certain than the {MAX_HEADING_SIGMA_DEG:g}° it needs")
        else:
            sources[key] = f"no estimate from the magnetometer: {estimate}"
    if values["norm_ut"] is None:
        sources["norm_ut"] = f"not in the sidecar, {no_site or 'no site latitude/longitude'}"
    return ReferenceField(values["norm_ut"], values["dip_deg"], values["declination_deg"], sources, estimate)


def field_reference_notes(data: ImuData) -> list[str]:
    """Notes (for `train`) on the earth field in the frame of `data`'s attitude reference when the sidecar
    does not give all of it: the angle estimated from the magnetometer with its uncertainty, or why the
    field reference is left out (the derived ref_mag's own note says where norm and dip came from).
    [] without an attitude reference or with the whole field in the sidecar."""
    if data.ref_q is None or data.ref_mag is not None or not data.has("mag"):
        return []
    resolved = reference_field(data)
    notes = []
    if isinstance(resolved.estimate, HeadingEstimate) and resolved.sources["declination_deg"].startswith("estimated"):
        notes.append(f"{data.name}: {resolved.estimate.text()}; the field reference and the attitude relative to "
                     "magnetic north use it")
    if resolved.earth_field() is None:
        notes.append(f"{data.name}: no field reference from ref_q — the earth field in its frame is incomplete "
                     f"({resolved.text()}); the magnetometer self-calibrates from invariants")
    return notes
