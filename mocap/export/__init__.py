"""The motion out: ``motion.npz`` of every run and exports to BVH, TRC, glTF/GLB and C3D."""
