"""Measurement on top of toolkit.api: references and errors, bench, compare, the specialization
measurement, per-strategy reports, MLT's startup bias and the equal-time study."""
