"""Observation models: appearance likelihoods (:mod:`pgm.observation.appearance`) and
detection sources (:mod:`pgm.observation.detections`)."""
