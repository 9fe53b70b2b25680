"""Evaluation: single-object OTB metrics, set distances (OSPA, OSPA²) and
multi-object CLEAR / identity / HOTA metrics."""
