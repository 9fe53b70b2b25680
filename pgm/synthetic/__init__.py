"""Synthetic scenes with exact ground truth: the unit tests' fixture and the demo's input.

:mod:`~pgm.synthetic.scene` (specs and the renderer), :mod:`~pgm.synthetic.sequence`
(the rendered sequence and its writers), :mod:`~pgm.synthetic.scenes` (presets).
"""

from pgm.synthetic.scene import MAGAZINE_COLOR, ObjectSpec, ObjectTruth, OccluderSpec, Scene
from pgm.synthetic.scenes import demo_scene, multi_target_scene, part_occlusion_scene
from pgm.synthetic.sequence import SyntheticSequence

__all__ = ["ObjectSpec", "OccluderSpec", "ObjectTruth", "Scene", "SyntheticSequence",
           "MAGAZINE_COLOR", "demo_scene", "part_occlusion_scene", "multi_target_scene"]
