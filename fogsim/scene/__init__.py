"""Procedural street scenes as a renderer-agnostic, JSON-serialisable description.

World frame: right-handed, metres, z up (Blender's), the street runs along +y. Every asset
is built in its own local frame — origin at the centre of its ground footprint, z up,
facing +y — and placed by a 4×4 local→world matrix. Nothing here imports bpy.
"""
