"""Recordings and their references: reading and writing IMU recordings (CSV, sidecars), the
`ImuData` container, reference attitude and fields, the Earth's gravity and magnetic field,
input limits and time offsets. Imports nothing above it in training/ (docs/architecture.md)."""
