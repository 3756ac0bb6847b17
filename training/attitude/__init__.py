"""What `train` decides about the attitude filter from the data (issue 29): settings chosen by
replaying the recordings' attitude reference (replay.py), whether the magnetometer deserves to correct
the heading (magnetic_trust.py)."""
