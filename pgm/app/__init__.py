"""The application layer: runners over videos and the ``pgm`` command line.

This is the only part of :mod:`pgm` that may import everything (models, inference, I/O,
evaluation, plotting).
"""
