"""Fog as a participating medium in Cycles: a closed box domain around camera and scene.

Facts this follows (``docs/fog-physics.md``; measured in Blender 3.4 and 5.0):

* **Never a world volume**: it makes Cycles ignore the world background and the sun (the image
  is 0.0 everywhere). The fog is a closed box mesh (the "fog layer") from 1 m below the ground
  to ``layer_height_m`` above it, ``extent_m`` to each side of the camera (R ≫ 1/β so the sides
  do not leak light), its far corners inside the camera's clip_end (2000 m).
* Its material has **no Surface**; the medium goes into the Volume output. Densities are per
  metre in world space (object scale does not change them). Three media, β in 1/m:

  - ``full``: Volume Scatter, Color white (σ_s = σ_t = β; the node's 0.8 default would give
    0.8·β), Anisotropy g (Henyey–Greenstein; Mie on Blender 4.3+ only when asked);
  - ``hybrid`` (scatter fraction w): Volume Scatter white density β·w, Volume Absorption black
    density β·(1 − w), Emission strength β·(1 − w)·L (L = ``emission``, scene-linear): in a
    uniform light field L it keeps L as the equilibrium radiance at a fraction of the cost;
  - ``ea`` (camera rays only): Volume Absorption black density IsCameraRay·β and Emission
    strength IsCameraRay·β·A: Cycles integrates it analytically, so the image is exactly
    I·t + A·(1 − t), t = e^(−βℓ) — Koschmieder in linear light (a test of units).

* Cycles settings of a fog render (:func:`fog_render_settings`, restored afterwards):
  ``volume_bounces`` (64; Cycles' default 0 is single scattering, almost black), ``max_bounces``
  = volume bounces + the quality's total, ``sample_clamp_indirect`` 0 (a clamp biases multiple
  scattering), adaptive sampling off (noise must not depend on the pixel), OIDN when this
  Blender has it, 5.0's ``volume_biased`` False where it exists, Z and object-index passes off
  (a scattering fog corrupts them on 25–30 % of pixels: labels come from the clear render),
  ``resolution_percentage`` from ``resolution_scale`` (cheap fog: :mod:`fogsim.render.fog_rebuild`),
  and ``transparent_max_bounces`` raised by 8: Blender 3.4 counts the domain boundary as a
  transparent bounce of shadow rays, so with draft's 0 the sun and sky never reach a point
  inside the fog (measured: sun-lit walls 0.10 too dark in the EA check).
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field

import bpy
import numpy as np

from fogsim.render.blender.compat import (
    force_homogeneous,
    has_denoiser,
    node_tree,
    node_tree_in_use,
    set_denoiser_speed,
    set_volume_phase,
    set_volume_unbiased,
)
from fogsim.render.quality import cycles_settings

DOMAIN_NAME = "fogsim_fog_domain"
GROUND_MARGIN_M = 1.0  # the box starts this far below the ground (z = 0)
FOG_CLIP_START_M = 1e-3  # camera clip_start of fog renders (the fog starts at the lens)
TRANSPARENT_EXTRA = 8  # transparent bounces added for fog renders (domain boundaries, 3.4)

# a unit cube, vertex i = (i & 1, i >> 1 & 1, i >> 2 & 1), triangles wound outward
_CUBE_FACES = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                        [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]], np.int32)


@dataclass
class FogDomain:
    """The fog layer of one frame: its object, mesh, material and the sockets that hold β."""

    obj: object
    mesh: object
    material: object
    medium: str
    beta: float = 0.0
    #: (socket, factor): socket.default_value = factor·β for every density-bearing input
    density_inputs: list = field(default_factory=list)
    phase: str = "HG"


def domain_box(camera_xy, height_m: float, extent_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Min and max corners (metres, world) of the fog box around the camera's ground position."""
    x, y = float(camera_xy[0]), float(camera_xy[1])
    lo = np.array([x - extent_m, y - extent_m, -GROUND_MARGIN_M])
    hi = np.array([x + extent_m, y + extent_m, height_m])
    return lo, hi


def _box_mesh(name: str, lo, hi):
    bits = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], np.float64)
    verts = (lo + bits * (np.asarray(hi) - lo)).astype(np.float32)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts.tolist(), [], _CUBE_FACES.tolist())
    mesh.update()
    return mesh


def _fog_material(settings: dict) -> tuple[object, list, str]:
    """The medium's material (no surface) and its (socket, factor-of-β) list."""
    medium = settings["medium"]
    mat = bpy.data.materials.new(f"fogsim_fog_{medium}")
    nt = node_tree(mat)
    for node in list(nt.nodes):
        if node.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(node)
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    force_homogeneous(mat)
    density, phase = [], "HG"

    def scatter(fraction: float):
        nonlocal phase
        node = nt.nodes.new("ShaderNodeVolumeScatter")
        node.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)  # albedo 1: σ_s = σ_t = Density
        phase = set_volume_phase(node, settings["phase"], settings["g"], settings["diameter_um"])
        density.append((node.inputs["Density"], fraction))
        return node.outputs[0]

    def absorption():
        node = nt.nodes.new("ShaderNodeVolumeAbsorption")
        node.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)  # σ_a = (1 − Color)·Density = Density
        return node

    def emission():
        node = nt.nodes.new("ShaderNodeEmission")
        node.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        return node

    def add(a, b):
        node = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(a, node.inputs[0])
        nt.links.new(b, node.inputs[1])
        return node.outputs[0]

    if medium == "full":
        shader = scatter(1.0)
    elif medium == "hybrid":
        w, L = settings["scatter_fraction"], settings["emission"]
        ab, em = absorption(), emission()
        density += [(ab.inputs["Density"], 1.0 - w), (em.inputs["Strength"], (1.0 - w) * L)]
        shader = add(add(ab.outputs[0], em.outputs[0]), scatter(w))
    elif medium == "ea":
        A = settings["emission"]
        ab, em = absorption(), emission()
        path = nt.nodes.new("ShaderNodeLightPath")
        for target, factor in ((ab.inputs["Density"], 1.0), (em.inputs["Strength"], A)):
            mul = nt.nodes.new("ShaderNodeMath")
            mul.operation = "MULTIPLY"
            nt.links.new(path.outputs["Is Camera Ray"], mul.inputs[0])
            nt.links.new(mul.outputs[0], target)
            density.append((mul.inputs[1], factor))
        shader = add(ab.outputs[0], em.outputs[0])
    else:
        raise ValueError(f"unknown fog medium {medium!r}")
    nt.links.new(shader, out.inputs["Volume"])  # the Surface output stays unlinked: no surface
    return mat, density, phase


def build_domain(built, scene, settings: dict) -> FogDomain:
    """Create the fog layer around ``scene.camera`` and record it in ``built`` (so
    :func:`fogsim.render.blender.scratch.clear` removes it). β starts at 0: call :func:`set_density`."""
    if scene.world is not None and (tree := node_tree_in_use(scene.world)) is not None:
        out = next((n for n in tree.nodes if n.type == "OUTPUT_WORLD"), None)
        if out is not None and out.inputs["Volume"].is_linked:
            raise ValueError("the world has a volume shader: it blocks all world and sun light; "
                             "fogsim's fog is a box domain, remove the world volume")
    cam = scene.camera.matrix_world.translation
    lo, hi = domain_box((cam.x, cam.y), settings["layer_height_m"], settings["extent_m"])
    if not lo[2] < cam.z < hi[2]:
        raise ValueError(f"the camera (z = {cam.z:.2f} m) is outside the fog layer "
                         f"(z {lo[2]:g}…{hi[2]:g} m): raise layer_height_m")
    mesh = _box_mesh(DOMAIN_NAME, lo, hi)
    mat, density, phase = _fog_material(settings)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(DOMAIN_NAME, mesh)
    obj.pass_index = 0
    built.collection.objects.link(obj)
    built.objects.append(obj)
    built.meshes.append(mesh)
    built.others.append(("materials", mat))
    domain = FogDomain(obj, mesh, mat, settings["medium"], density_inputs=density, phase=phase)
    set_density(domain, 0.0)
    return domain


def set_density(domain: FogDomain, beta: float) -> None:
    """Set the extinction β (1/m) of the medium in place (no rebuild)."""
    for socket, factor in domain.density_inputs:
        socket.default_value = float(factor * beta)
    domain.beta = float(beta)


@contextmanager
def fog_render_settings(scene, settings: dict, quality: dict, seed: int):
    """Cycles and pass settings of a Combined-only fog render, restored on exit.

    Yields what the scene holds while inside (read back from Blender, not the requested values).
    """
    cy, layer = scene.cycles, scene.view_layers[0]
    names = ["samples", "use_adaptive_sampling", "use_denoising", "volume_bounces", "max_bounces",
             "sample_clamp_indirect", "seed", "transparent_max_bounces", "denoising_prefilter",
             "denoising_quality", "volume_biased"]
    saved = {n: getattr(cy, n) for n in names if hasattr(cy, n)}
    saved_passes = (layer.use_pass_z, layer.use_pass_object_index)
    saved_persistent = scene.render.use_persistent_data
    saved_clip = scene.camera.data.clip_start
    saved_pct = scene.render.resolution_percentage
    try:
        # cheap fog: the fog levels at a fraction of the size, rebuilt by fogsim.render.fog_rebuild
        scene.render.resolution_percentage = max(1, round(100 * float(settings.get("resolution_scale", 1.0))))
        # camera rays start at clip_start: the fog must start at the lens (0.1 m of missing fog
        # left a −0.0036 bias at 0–10 m, β = 0.12, in the EA check)
        scene.camera.data.clip_start = FOG_CLIP_START_M
        # only β changes between the fog renders: keep Cycles' scene (BVH, images) between them
        scene.render.use_persistent_data = True
        base = cycles_settings(quality)  # the clear render's settings, defaults from the schema
        cy.samples = int(settings["samples"] or base["samples"])
        cy.use_adaptive_sampling = False
        denoise = bool(settings["denoise"]) and has_denoiser()
        cy.use_denoising = denoise
        if denoise:
            set_denoiser_speed(cy, base["denoising_quality"], base["denoising_prefilter"])
        cy.volume_bounces = int(settings["volume_bounces"])
        cy.max_bounces = int(settings["volume_bounces"]) + base["max_bounces"]
        cy.sample_clamp_indirect = 0.0
        # Blender 3.4 counts the domain's boundary as a transparent bounce of shadow rays: with the
        # quality's 0 (draft) every shadow ray leaving the fog layer (sun, sky) would be blocked
        cy.transparent_max_bounces = base["transparent_max_bounces"] + TRANSPARENT_EXTRA
        cy.seed = (int(seed) + int(settings["noise_seed"])) % 2**31
        biased = set_volume_unbiased(cy)
        layer.use_pass_z = layer.use_pass_object_index = False
        yield {"samples": cy.samples, "denoise": bool(cy.use_denoising), "adaptive_sampling": cy.use_adaptive_sampling,
               "volume_bounces": cy.volume_bounces, "max_bounces": cy.max_bounces,
               "sample_clamp_indirect": cy.sample_clamp_indirect, "seed": cy.seed,
               "transparent_max_bounces": cy.transparent_max_bounces,
               "clip_start_m": scene.camera.data.clip_start,
               "volume_biased": biased, "passes": "Combined",
               "resolution_percentage": scene.render.resolution_percentage}
    finally:
        for n, v in saved.items():
            setattr(cy, n, v)
        layer.use_pass_z, layer.use_pass_object_index = saved_passes
        scene.render.use_persistent_data = saved_persistent
        scene.camera.data.clip_start = saved_clip
        scene.render.resolution_percentage = saved_pct
