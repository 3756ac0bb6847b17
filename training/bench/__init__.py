"""Benchmark code: the attitude-filter comparison on BROAD, the trained-model bench and the
thermal-model comparison (docs/BENCHMARKS.md); the scripts that run them are in benchmarks/."""
