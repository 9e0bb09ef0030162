"""Every difference between the Blender versions we support (3.4 … 5.0) lives here."""
from __future__ import annotations

import bpy

VERSION = bpy.app.version

#: names of the render passes in the multilayer EXR, per Blender version (first match wins)
PASS_CHANNELS = {
    "rgb": [("ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B")],
    "depth": ["ViewLayer.Depth.Z"],
    "index": ["ViewLayer.IndexOB.X", "ViewLayer.Object Index.X"],
}


def node_tree(idblock):
    """A material's or world's node tree, switched on where this Blender needs it: before 5.0 a new one has no
    tree until ``use_nodes = True``; from 5.0 every one has its tree and ``use_nodes`` is deprecated (removed in
    6.0: reading or setting it warns), so it is left alone unless the tree is missing."""
    if VERSION < (5, 0, 0) or idblock.node_tree is None:
        idblock.use_nodes = True
    return idblock.node_tree


def node_tree_in_use(idblock):
    """The node tree a material or world renders with, or None (before 5.0 a tree can exist switched off)."""
    tree = idblock.node_tree
    if tree is None:
        return None
    return tree if VERSION >= (5, 0, 0) or idblock.use_nodes else None


def has_denoiser() -> bool:
    """True when this Cycles build has OpenImageDenoise (Debian's 3.4 has not)."""
    try:
        import _cycles
    except ImportError:
        return False
    return bool(getattr(_cycles, "with_openimagedenoise", False))


def set_multilayer_exr(image_settings) -> None:
    """Make the render output one single-part multilayer float EXR holding every pass."""
    if hasattr(image_settings, "media_type"):  # 5.0: must come before file_format
        image_settings.media_type = "MULTI_LAYER_IMAGE"
    image_settings.file_format = "OPEN_EXR_MULTILAYER"
    image_settings.color_depth = "32"
    image_settings.exr_codec = "NONE"  # a temporary file read back at once: compression only costs time
    if hasattr(image_settings, "use_exr_interleave"):  # 5.0 writes one part per pass otherwise
        image_settings.use_exr_interleave = True


def set_denoiser_speed(cycles, quality: str, prefilter: str) -> None:
    """OpenImageDenoise quality (HIGH/BALANCED/FAST, Blender 4.1+) and prefilter (ACCURATE/FAST/NONE)."""
    if hasattr(cycles, "denoising_quality"):
        cycles.denoising_quality = quality
    cycles.denoising_prefilter = prefilter


def set_mesh_polygons(mesh, loop_starts, loop_totals) -> None:
    """Fill polygon loop ranges (``loop_total`` became read-only in Blender 4.0)."""
    mesh.polygons.foreach_set("loop_start", loop_starts)
    if VERSION < (4, 0, 0):
        mesh.polygons.foreach_set("loop_total", loop_totals)


def sky_type_physical(node) -> str | None:
    """Set a physical sky model on a Sky Texture node; returns the type chosen (None if none)."""
    items = [e.identifier for e in node.bl_rna.properties["sky_type"].enum_items]
    for name in ("NISHITA", "SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "HOSEK_WILKIE", "PREETHAM"):
        if name in items:
            node.sky_type = name
            return name
    return None


def principled_inputs(node) -> dict:
    """Principled BSDF input sockets by role (names changed in 4.0)."""
    names = {s.name for s in node.inputs}
    pick = lambda *cands: next((node.inputs[c] for c in cands if c in names), None)  # noqa: E731
    return {"base": pick("Base Color"), "roughness": pick("Roughness"), "metallic": pick("Metallic"),
            "emission": pick("Emission Color", "Emission"), "emission_strength": pick("Emission Strength"),
            "transmission": pick("Transmission Weight", "Transmission"), "alpha": pick("Alpha"),
            "normal": pick("Normal")}


def cycles_preferences():
    """The Cycles add-on's preferences (devices live there, not in the scene); KeyError if Cycles is off."""
    return bpy.context.preferences.addons["cycles"].preferences


def compute_devices(prefs, kind: str) -> list | None:
    """Select the compute backend ``kind`` ("OPTIX", "CUDA", …) and return its devices (the
    preferences' entries, CPU left out); None when this Blender has no such backend.

    Differences handled: the backends a build offers (Debian's 3.4 has CUDA and HIP, no OptiX;
    assigning a missing one raises TypeError); ``refresh_devices()`` (3.0+; ``get_devices()``,
    deprecated, before) and ``get_devices_for_type`` (3.4: ``(kind)``; 5.0: ``(kind, device_list)``,
    which also appends the CPU entries when a GPU is found, hence the type filter).
    """
    try:
        prefs.compute_device_type = kind
    except TypeError:
        return None
    if hasattr(prefs, "refresh_devices"):
        prefs.refresh_devices()
    else:
        prefs.get_devices()
    found = prefs.get_devices_for_type(kind) if hasattr(prefs, "get_devices_for_type") else prefs.devices
    return [d for d in found if d.type == kind]


def has_mie_phase() -> bool:
    """True when Volume Scatter offers the Mie phase function (Blender 4.3+)."""
    prop = bpy.types.ShaderNodeVolumeScatter.bl_rna.properties.get("phase")
    return prop is not None and "MIE" in [e.identifier for e in prop.enum_items]


def set_volume_phase(node, phase: str, g: float, diameter_um: float) -> str:
    """Phase function of a Volume Scatter node: "HG" (anisotropy g, every version) or "MIE"
    (droplet diameter in µm, Blender 4.3+); returns what was set. ValueError if MIE is absent."""
    node.inputs["Anisotropy"].default_value = g
    if phase == "HG":
        if hasattr(node, "phase"):  # 4.3+: HG is the default, set it anyway
            node.phase = "HENYEY_GREENSTEIN"
        return "HG"
    items = [e.identifier for e in node.bl_rna.properties["phase"].enum_items] if hasattr(node, "phase") else []
    if "MIE" not in items:
        raise ValueError(f"the Mie phase function needs Blender 4.3 or later (this is {bpy.app.version_string}); "
                         "use phase \"HG\" with g = 0.85")
    node.phase = "MIE"
    node.inputs["Diameter"].default_value = diameter_um
    return "MIE"


def set_volume_unbiased(cycles) -> bool | None:
    """5.0's null-scattering volume integrator (``volume_biased`` = False); None where absent (3.4)."""
    if hasattr(cycles, "volume_biased"):
        cycles.volume_biased = False
        return False
    return None


def force_homogeneous(material) -> None:
    """3.4: treat the material's volume as homogeneous (analytic path); 5.0 decides by itself."""
    if hasattr(material.cycles, "homogeneous_volume"):
        material.cycles.homogeneous_volume = True


def enable_importers() -> None:
    """Make Blender's glTF and FBX importers available (add-ons shipped with 3.4 and the 5.0
    module; OBJ is built in) and let 3.4's glTF importer run on numpy ≥ 1.24, which dropped the
    ``numpy.bool`` alias it uses (numpy 2 has it again, as ``numpy.bool_``)."""
    import addon_utils
    import numpy

    if "bool" not in numpy.__dict__:
        numpy.bool = numpy.bool_
    for module in ("io_scene_gltf2", "io_scene_fbx"):
        addon_utils.enable(module, default_set=False)
