"""Depth for real images and how good it is: stereo (SGBM, WLS), ILA depth completion
(``depth.ila``, the only module here that imports torch), LiDAR completion and sources, and depth
metrics and scores. The hole fill that fogging needs is :mod:`fogsim.fog.fill` (ILA registers into it)."""
