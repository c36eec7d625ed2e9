"""The marker / keypoint tracker of Canton-Ferrer, Casas & Pardàs 2010 (``tracker=marker_apf``).

- :mod:`.tracker`: :class:`MarkerAPFTracker`, the annealed particle filter and its step;
- :mod:`.startup`: start-up from one frame (robust triangulation, shape fit, neutral pose);
- :mod:`.associate`: people associated across views by whole-skeleton epipolar consistency;
- :mod:`.people`: several people tracked with identities;
- :mod:`.anneal`, :mod:`.propagation`: survival-rate annealing with crossover, truncated
  Gaussian propagation;
- :mod:`.refine`: Gauss-Newton on the reprojection error from the APF estimate;
- :mod:`.offsets`: keypoint-to-landmark offsets learned while tracking.

Elsewhere, because other packages use them too: the likelihood (an energy like the others)
in :mod:`mocap.energy.markers` with its compiled kernel :mod:`mocap.energy.marker_kernel`;
the landmark catalogue in :mod:`mocap.body.catalogue`, the bone-length model in
:mod:`mocap.body.bone_lengths`; keypoint files in :mod:`mocap.data.openpose`.
"""
