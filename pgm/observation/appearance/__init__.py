"""Appearance likelihood factors and the per-frame image work they share."""
