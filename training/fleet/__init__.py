"""Fleets of sensor units of one type: simulate them (`simulate-fleet`), calibrate each on Dask
(`fleet train`) and describe the population of their calibrations."""
