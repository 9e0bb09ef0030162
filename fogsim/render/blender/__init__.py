"""The Blender side: scene description → bpy objects, Cycles passes, the render job and the
add-on's panel. The only code in fogsim that imports bpy (Blender 3.4 binary or the 5.0 module)."""
