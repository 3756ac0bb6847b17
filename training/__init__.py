"""ImuFusion training pipeline: data, simulator, models, C-runtime bridge, reports, CLI."""

__version__ = "0.1.0"
