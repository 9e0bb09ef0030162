"""Rendering procedural street scenes into labeled datasets.

Renderer-agnostic: dataset presets, one frame's ground truth (labels, silhouettes) and
commit, the frame loop. ``render.blender`` is the only code in fogsim that imports bpy.
"""
