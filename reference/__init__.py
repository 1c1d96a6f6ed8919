"""Mitsuba 3 reference renderer: the ground truth."""
