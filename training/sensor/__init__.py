"""The virtual sensor (issue 34, docs/virtual_sensor.md): the trained model as a sensor — build its FMU
(`build.py`) and run true motion through it (`simulate.py`)."""
