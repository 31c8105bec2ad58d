"""Checks of correctness: same-image comparisons, BSDF sampling tests, the Embree cross-check,
the MLT toy target and the GPU check."""
