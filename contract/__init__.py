"""The contract between the Python pipeline and the C runtime, at the bottom of the house: the
variable table (names, value references, types, units, defaults, ranges), the flat array layouts,
the checks of values against their declared ranges, the errors every layer raises, and our
distribution's name and version. It imports nothing from `training` or `fmu`."""

__version__ = "0.1.0"
