"""Synthetic scenes with exact ground truth: the unit tests' fixture and the demo's input."""

from pgm.synthetic.scene import (
    MAGAZINE_COLOR,
    ObjectSpec,
    ObjectTruth,
    OccluderSpec,
    Scene,
    SyntheticSequence,
    demo_scene,
    multi_target_scene,
    part_occlusion_scene,
)

__all__ = ["ObjectSpec", "OccluderSpec", "ObjectTruth", "Scene", "SyntheticSequence", "MAGAZINE_COLOR", "demo_scene", "part_occlusion_scene", "multi_target_scene"]
