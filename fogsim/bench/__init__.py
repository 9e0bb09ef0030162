"""The benchmarks behind ``fogsim bench``: experiment drivers, not library code.

Each measures a figure beside a baseline timed in the same run (:mod:`.timing`: medians of
interleaved repeats, since these machines are noisy) and prints both with their ratio: :mod:`.fog`
(fog engine speed), :mod:`.fog_physics` + :mod:`.fog_physics_report` (Koschmieder against
path-traced fog), :mod:`.depth` (depth completion against exact rendered depth), :mod:`.lidar`
(LiDAR completion speed and accuracy), :mod:`.lidar_side_by_side` (LiDAR fog beside the reference
simulator's re-implementation, the docs' table) and :mod:`.waymo_lidar` (Waymo LiDAR decode speed). The
render benchmarks import bpy and live in :mod:`fogsim.render.blender.bench`. None of them is a
test; CI times nothing.
"""
