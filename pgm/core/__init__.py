"""The core of the modelling layer: variables, the root factor class and its registry,
the factor graph, beliefs (particles, intensities, exponential families), the frame
context, numerics, boxes, errors and the random-generator helper.

Everything else in :mod:`pgm` builds on this subpackage; it imports nothing else of
``pgm`` (a test enforces the direction).
"""
