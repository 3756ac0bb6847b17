"""Diagnosis of a recording: which effects (temperature, time, motion ...) explain the residual
errors of a trained model, with the fits, readings, export and report (docs/diagnosis/)."""
