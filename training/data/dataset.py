"""The in-memory form of an imu-csv/1 recording (see ARCHITECTURE.md, 'Canonical dataset').

`ImuData` holds arrays only; reading and writing files lives in `training.data.io`.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from contract.layout import AUX_INPUTS

TRIADS = ("gyr", "acc", "mag")
AXES = ("x", "y", "z")
REF_Q_COLUMNS = ("ref_qw", "ref_qx", "ref_qy", "ref_qz")


def triad_columns(prefix: str) -> list[str]:
    """Column names of one triad, e.g. 'gyr' -> ['gyr_x', 'gyr_y', 'gyr_z']."""
    return [f"{prefix}_{a}" for a in AXES]


@dataclass
class ImuData:
    """One recording. Shapes: N samples; triads are (N, 3). Units: s, rad/s, m/s², µT, °C.

    Optional arrays are None when the file does not carry them. `meta` is the sidecar JSON
    (format, rate_hz, sensor, reference, earth_field{norm_ut, dip_deg, declination_deg}, ...).
    """

    t: np.ndarray                      # (N,) s, strictly increasing
    gyr: np.ndarray                    # (N, 3) rad/s, raw
    acc: np.ndarray                    # (N, 3) m/s², raw specific force
    mag: np.ndarray                    # (N, 3) µT, raw
    temp: np.ndarray                   # (N,) °C, NaN where unknown
    ref_q: np.ndarray | None = None    # (N, 4) [w, x, y, z], body -> NED (true north)
    ref_gyr: np.ndarray | None = None  # (N, 3) rad/s, true rate
    ref_acc: np.ndarray | None = None  # (N, 3) m/s², true specific force
    ref_mag: np.ndarray | None = None  # (N, 3) µT, true body-frame field
    eval_mask: np.ndarray | None = None  # (N,) bool
    aux: dict[str, np.ndarray] = field(default_factory=dict)  # 'aux_*' name -> (N,)
    meta: dict = field(default_factory=dict)
    name: str = "recording"

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def declination_rad(self) -> float:
        """Magnetic declination from the sidecar [rad] (0 when not given)."""
        ef = self.meta.get("earth_field") or {}
        return float(np.deg2rad(ef.get("declination_deg", 0.0) or 0.0))

    @property
    def field_norm_ut(self) -> float | None:
        """Earth-field magnitude from the sidecar [µT], or None."""
        ef = self.meta.get("earth_field") or {}
        v = ef.get("norm_ut")
        return None if v is None else float(v)

    def has(self, triad: str) -> bool:
        """True when the raw triad ('gyr', 'acc', 'mag') has at least one finite sample."""
        return bool(np.isfinite(getattr(self, triad)).any())

    def inputs(self, aux_columns: Sequence[str] = ()) -> np.ndarray:
        """(N, len(contract.layout.INPUTS)) array in runtime input order: gyr xyz, acc xyz, mag xyz,
        temp, then aux_1..aux_4. aux_k is this recording's column aux_columns[k-1] (NaN cells stay
        NaN), 0 where not mapped; pass a model's `[a["column"] for a in artefact.aux_inputs]`.
        Raises DataError naming the recording and the column when a mapped column is missing (every
        verb that runs a model on a recording reports it in one line).
        """
        from contract.errors import DataError
        if len(aux_columns) > len(AUX_INPUTS):
            raise DataError(self.name, f"{len(aux_columns)} auxiliary columns, the runtime has "
                                       f"{len(AUX_INPUTS)} auxiliary inputs")
        aux = np.zeros((len(self), len(AUX_INPUTS)))
        for k, column in enumerate(aux_columns):
            if column not in self.aux:
                raise DataError(self.name, f"the model reads column '{column}' into input {AUX_INPUTS[k]}, "
                                           f"but the recording has no such column (aux columns: "
                                           f"{', '.join(self.aux) or 'none'})")
            aux[:, k] = self.aux[column]
        return np.column_stack([self.gyr, self.acc, self.mag, self.temp, aux]).astype(np.float64)

    def slice(self, sel) -> "ImuData":
        """A new ImuData with the rows `sel` (slice, index array or boolean mask)."""
        def cut(a):
            return None if a is None else np.asarray(a)[sel]
        return ImuData(
            t=self.t[sel], gyr=self.gyr[sel], acc=self.acc[sel], mag=self.mag[sel],
            temp=self.temp[sel], ref_q=cut(self.ref_q), ref_gyr=cut(self.ref_gyr),
            ref_acc=cut(self.ref_acc), ref_mag=cut(self.ref_mag), eval_mask=cut(self.eval_mask),
            aux={k: v[sel] for k, v in self.aux.items()}, meta=dict(self.meta), name=self.name)

    def validate(self) -> None:
        """Check shapes and time order; raise ValueError naming the first problem."""
        n = len(self)
        for name in ("gyr", "acc", "mag", "ref_gyr", "ref_acc", "ref_mag"):
            a = getattr(self, name)
            if a is not None and a.shape != (n, 3):
                raise ValueError(f"{self.name}: '{name}' has shape {a.shape}, expected ({n}, 3)")
        if self.temp.shape != (n,):
            raise ValueError(f"{self.name}: 'temp' has shape {self.temp.shape}, expected ({n},)")
        if self.ref_q is not None and self.ref_q.shape != (n, 4):
            raise ValueError(f"{self.name}: 'ref_q' has shape {self.ref_q.shape}, expected ({n}, 4)")
        dt = np.diff(self.t)
        if n and (not np.all(np.isfinite(self.t)) or np.any(dt <= 0)):
            raise ValueError(f"{self.name}: time is not finite and strictly increasing")


def recording_parameters(data: ImuData) -> dict[str, float]:
    """FMU parameters that a recording's sidecar fixes: declination [rad] and field_norm [µT]."""
    params = {"declination": data.declination_rad}
    if data.field_norm_ut is not None:
        params["field_norm"] = data.field_norm_ut
    return params
