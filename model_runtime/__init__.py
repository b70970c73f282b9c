"""Model runtime for TrajeVAE: skeleton, motion data, models, training, evaluation.

Pure numpy/torch; never imports bpy, so everything here runs and is tested
outside Blender.
"""
