"""ImuFusion training pipeline: data, simulator, models, C-runtime bridge, reports, CLI."""
