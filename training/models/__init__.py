"""The calibration models and their numpy twins of the C runtime: thermal polynomials and their
degree choice, the ELM compass and PSO-BP networks, the magnetometer particle filter and its
moments, the ellipsoid fit, the checks and fit quality of a trained model (docs/architecture.md)."""
