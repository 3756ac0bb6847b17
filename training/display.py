"""How each triad's values are shown to people: the display unit and the factor from the triad's SI
unit (°/s reads better than rad/s). The one table reports, notes and diagnoses share."""
import numpy as np

#: triad -> (display unit, factor from the SI unit).
DISPLAY = {"gyr": ("°/s", float(np.rad2deg(1.0))), "acc": ("m/s²", 1.0), "mag": ("µT", 1.0)}
