"""Depth for real images and how good it is: stereo (SGBM, WLS), hole filling, ILA depth
completion (``depth.ila``, the only module here that imports torch) and depth metrics."""
