"""mocap: multi-view human motion capture on a 3D morphable body model.

Packages (the layout is the architecture):
    body        PCA shape space, twist kinematic chain, linear blend skinning
    cameras     pinhole cameras, projection, rays, Plücker lines, epipolar geometry
    render      silhouette rasterizer, distance transforms, RGB rendering
    data        motion library, synthetic sequences, loaders for recordings
    energy      silhouette, smoothness and pose-prior energies
    trackers    local optimizer, annealed particle filter, hybrid and marker trackers
    eval        joint error, MMTA/MMTP
    recording   Rerun sinks (the only package that imports rerun)
"""

__version__ = "0.1.0"
