"""Comparator, accuracy report, CI error-budget gate and fits."""
