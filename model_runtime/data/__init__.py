"""Motion data: BVH reading, rig profiles, clips at the model's rate, windows."""
