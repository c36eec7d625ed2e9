"""Local optimization (Zhang et al. 2013, Sec. 4.1, after Rosenhahn/Brox and Gall et al.):
2D-3D correspondences from silhouette contours and SIFT matches become 3D point-ray pairs,
and a linearised twist update of the pose minimises their Plücker point-line distances
(Eq. 7-9). Misalignment detection decides which limbs need the global search."""
