"""Benchmark sequences rendered by anny's own mesh and 104-bone skinning, not by our PCA body.

- :mod:`.procedural`: ``data/mismatch`` (three procedural motions written as anny bone
  rotations), the ground-truth joint definitions and the rendering shared by all generators.
- :mod:`.real_motion`: ``data/real_motion`` (real motion-capture clips drive anny's skeleton).
"""
