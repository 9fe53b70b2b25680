"""pgm: visual trackers as explicit probabilistic factor graphs."""
