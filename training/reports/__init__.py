"""Human-readable reports: the main job's report and plots, the calibration report of a trained
artefact and the one-line run summaries the CLI prints."""
