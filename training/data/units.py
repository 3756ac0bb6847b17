"""The units a user's file may carry and their conversion to imu-csv/1's units (rad/s, m/s², µT, s, °C).

One vocabulary per quantity, looked up case-insensitively with spaces, '^' and '²' removed (so
'deg/s', 'DEG/S', '°/s' and 'dps' are one unit); the quantity decides what a name means ('g' is
standard gravity for the accelerometer, 'G' gauss for the magnetometer). Raw ADC counts carry the
value of one LSB in a unit of that vocabulary: `counts:0.0152587890625deg/s`, `counts:1/131deg/s`
(a sensitivity of 131 LSB per °/s), optionally with an offset in that unit for a temperature
sensor, `counts:0.00294118C+36.53` (°C = counts · 0.00294118 + 36.53).

A conversion is x_SI = x · scale + offset; with offset 0 it is one multiplication by a scale
computed once (deg/s -> rad/s multiplies by π/180, which reproduces np.deg2rad bit for bit).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from contract.errors import ImuFusionError
from training.data.earth import STANDARD_GRAVITY  # the factor of a file in g [m/s²]
#: quantity -> the unit of imu-csv/1 it converts to.
TARGET_UNIT = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT", "t": "s", "temp": "°C"}
#: quantity -> what it is, for messages.
QUANTITY_NAME = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer", "t": "time",
                 "temp": "temperature"}
#: A time column that counts samples: t = (n - n[0]) / rate, so it needs a rate (--rate).
SAMPLES = "samples"

_DEG = math.pi / 180.0
#: quantity -> {unit name (normalised by _key) -> (scale, offset) to the target unit}.
_VOCABULARY: dict[str, dict[str, tuple[float, float]]] = {
    "gyr": {"rad/s": (1.0, 0.0), "rads": (1.0, 0.0), "radps": (1.0, 0.0), "rad/sec": (1.0, 0.0),
            "deg/s": (_DEG, 0.0), "°/s": (_DEG, 0.0), "dps": (_DEG, 0.0), "degs": (_DEG, 0.0),
            "degps": (_DEG, 0.0), "deg/sec": (_DEG, 0.0), "degree/s": (_DEG, 0.0), "degrees/s": (_DEG, 0.0),
            "mdps": (_DEG * 1e-3, 0.0), "mrad/s": (1e-3, 0.0), "rpm": (2.0 * math.pi / 60.0, 0.0)},
    "acc": {"m/s2": (1.0, 0.0), "m/s/s": (1.0, 0.0), "mps2": (1.0, 0.0), "ms2": (1.0, 0.0),
            "ms-2": (1.0, 0.0), "g": (STANDARD_GRAVITY, 0.0), "mg": (STANDARD_GRAVITY * 1e-3, 0.0)},
    "mag": {"ut": (1.0, 0.0), "µt": (1.0, 0.0), "μt": (1.0, 0.0), "microtesla": (1.0, 0.0),
            "nt": (1e-3, 0.0), "mt": (1e3, 0.0), "t": (1e6, 0.0), "tesla": (1e6, 0.0),
            "mg": (0.1, 0.0), "mgauss": (0.1, 0.0), "milligauss": (0.1, 0.0),
            "g": (100.0, 0.0), "gauss": (100.0, 0.0)},
    "t": {"s": (1.0, 0.0), "sec": (1.0, 0.0), "secs": (1.0, 0.0), "seconds": (1.0, 0.0),
          "ms": (1e-3, 0.0), "msec": (1e-3, 0.0), "milliseconds": (1e-3, 0.0),
          "us": (1e-6, 0.0), "µs": (1e-6, 0.0), "μs": (1e-6, 0.0), "microseconds": (1e-6, 0.0),
          "ns": (1e-9, 0.0), "nanoseconds": (1e-9, 0.0)},
    "temp": {"c": (1.0, 0.0), "°c": (1.0, 0.0), "degc": (1.0, 0.0), "celsius": (1.0, 0.0),
             "k": (1.0, -273.15), "kelvin": (1.0, -273.15),
             "f": (5.0 / 9.0, -32.0 * 5.0 / 9.0), "°f": (5.0 / 9.0, -32.0 * 5.0 / 9.0),
             "degf": (5.0 / 9.0, -32.0 * 5.0 / 9.0), "fahrenheit": (5.0 / 9.0, -32.0 * 5.0 / 9.0)},
}
#: quantity -> the unit names a message offers (the vocabulary has more spellings).
OFFERED = {"gyr": "rad/s, deg/s, mdps, rpm", "acc": "m/s2, g, mg", "mag": "uT, nT, mT, mG, G (gauss)",
           "t": "s, ms, us, ns, samples (a sample counter, with --rate)", "temp": "C, K, F"}
#: quantity -> an example of raw counts for messages.
COUNTS_EXAMPLE = {"gyr": "counts:0.0152587890625deg/s", "acc": "counts:0.000598755g",
                  "mag": "counts:0.15uT", "temp": "counts:0.00294118C+36.53", "t": "counts:1ms"}
#: Header units that say "raw counts" without a scale.
COUNTS_WORDS = ("counts", "count", "lsb", "raw", "adc", "digits")
_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_COUNTS = re.compile(rf"^counts:\s*(?P<lsb>{_NUMBER})(?:\s*/\s*(?P<per>{_NUMBER}))?\s*(?P<unit>.*?)"
                     rf"\s*(?:(?P<sign>[+-])\s*(?P<offset>{_NUMBER}))?$", re.IGNORECASE)


@dataclass(frozen=True)
class Conversion:
    """x_SI = x · scale + offset, from `unit` (as written) to TARGET_UNIT[quantity]."""

    quantity: str
    unit: str
    scale: float
    offset: float = 0.0

    def apply(self, x):
        """The values x (array or float, in `unit`) in the target unit."""
        return x * self.scale if self.offset == 0.0 else x * self.scale + self.offset

    @property
    def identity(self) -> bool:
        """True when the values are already in the target unit."""
        return self.scale == 1.0 and self.offset == 0.0

    def describe(self) -> str:
        """'deg/s -> rad/s (× 0.01745329)', 'm/s2 (as given)', 'F -> °C (× 0.5555556 − 17.77778)'."""
        target = TARGET_UNIT[self.quantity]
        if self.identity:
            return f"{self.unit} (as given)"
        text = f"{self.unit} -> {target} (× {self.scale:.7g}"
        if self.offset:
            text += f" {'+' if self.offset > 0 else '−'} {abs(self.offset):.7g}"
        return text + ")"


def _key(unit: str) -> str:
    """A unit name as the vocabulary stores it: lower case, without spaces, '^', '²' -> '2'."""
    return unit.strip().lower().replace(" ", "").replace("^", "").replace("²", "2").replace("**", "")


def is_counts_word(unit: str) -> bool:
    """True for a header unit that names raw counts without their scale ('LSB', 'counts', 'raw')."""
    return _key(unit) in COUNTS_WORDS


def lookup(quantity: str, unit: str) -> tuple[float, float] | None:
    """(scale, offset) from `unit` to the target unit of `quantity`, None when the name is unknown."""
    return _VOCABULARY[quantity].get(_key(unit))


def parse_unit(quantity: str, text: str, origin: str) -> Conversion:
    """The Conversion of `text` ('deg/s', 'counts:0.061deg/s', 'samples') for `quantity` ('gyr', 'acc',
    'mag', 't', 'temp'); ImuFusionError naming `origin` (e.g. "--units gyr=...") when unknown."""
    text = text.strip()
    if quantity == "t" and _key(text) in (SAMPLES, "sample", "n"):
        return Conversion(quantity, SAMPLES, 1.0)
    if _key(text).startswith("counts:"):
        return _parse_counts(quantity, text, origin)
    found = lookup(quantity, text)
    if found is None:
        hint = (f"; raw counts need their scale, e.g. {COUNTS_EXAMPLE[quantity]}" if is_counts_word(text)
                else "")
        raise ImuFusionError(f"{origin}: unknown {QUANTITY_NAME[quantity]} unit '{text}' (known: "
                             f"{OFFERED[quantity]}, or counts:LSB_VALUE UNIT){hint}")
    return Conversion(quantity, text, *found)


def _parse_counts(quantity: str, text: str, origin: str) -> Conversion:
    """The Conversion of 'counts:LSB UNIT[±OFFSET]' (LSB may be '1/SENSITIVITY')."""
    match = _COUNTS.match(text)
    usage = f"write counts:LSB_VALUE UNIT, e.g. {COUNTS_EXAMPLE[quantity]}"
    if match is None or not match["unit"]:
        raise ImuFusionError(f"{origin}: cannot read '{text}' as raw counts with a scale: {usage}")
    lsb = float(match["lsb"]) / (float(match["per"]) if match["per"] else 1.0)
    found = lookup(quantity, match["unit"])
    if found is None or not math.isfinite(lsb) or lsb <= 0.0:
        what = f"unknown unit '{match['unit']}'" if found is None else f"LSB value {lsb:g} is not positive"
        raise ImuFusionError(f"{origin}: {what} in '{text}' ({OFFERED[quantity]}): {usage}")
    scale, offset = found
    extra = float(match["offset"]) * (-1.0 if match["sign"] == "-" else 1.0) if match["offset"] else 0.0
    return Conversion(quantity, text, lsb * scale, offset + extra * scale)


def parse_units_option(texts: list[str] | None) -> dict[str, Conversion]:
    """--units 'gyr=deg/s,acc=g' (repeatable) -> {quantity: Conversion}; ImuFusionError on a bad entry."""
    out: dict[str, Conversion] = {}
    for text in texts or []:
        for entry in filter(None, (e.strip() for e in text.split(","))):
            quantity, sep, unit = entry.partition("=")
            quantity = quantity.strip().lower()
            if not sep or quantity not in TARGET_UNIT:
                raise ImuFusionError(f"--units '{entry}': expected QUANTITY=UNIT with QUANTITY one of "
                                     f"{', '.join(TARGET_UNIT)} (e.g. gyr=deg/s,acc=g,mag=uT,t=ms,temp=C)")
            out[quantity] = parse_unit(quantity, unit, f"--units {quantity}={unit.strip()}")
    return out
