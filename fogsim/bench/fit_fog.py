"""``fogsim fit-fog``: fit the scatter fog model's parameters on path-traced renders.

Reads one or more ``fogsim bench fog-physics`` folders (each: a clear run and two volumetric
runs of the same frames, see :mod:`fogsim.bench.fog_physics`) and fits, by a bounded pattern
search (Hooke–Jeeves: coordinate steps that halve when nothing improves; deterministic):

1. on the day frames, the parameters :func:`fogsim.schema.scatter.fit_space` gives for the day
   (``direct.exposure_key``, ``psf.forward``, ``psf.spread``, ``direct.illumination``, the airlight's
   ``level``, ``fade``, ``elevation``, ``sky_exponent``, ``direct.flatten``), minimising the mean over β
   of the noise-free normalised RMS
   (path-traced image scaled so its horizon is A, interior non-sky pixels,
   :mod:`fogsim.fog.physics`; pooled over frames) relative to linear Koschmieder's at that β
   (the target is a ratio per β: every β counts alike);
2. on the night frames (if any), the night's: ``glow.gain`` and ``glow.tail`` searched, ``glow.spread``
   and ``glow.max_area`` on their grids, minimising the squared log-ratio of
   the model's and the path-traced radial luminance profile around each lamp (:func:`fogsim.fog.physics.lamps`)
   plus the night images' normalised RMS relative to Koschmieder's (a halo must not brighten the whole
   night).

Writes a small versioned JSON (:class:`fogsim.schema.scatter.ScatterParamsFile`) with the
presets, seeds, frames, β and the objective before (Koschmieder: every term off) and after.

    fogsim fit-fog RUN_DIR [RUN_DIR …] [--out fogsim/fog/scatter_params.json] [--start PARAMS.json]
    fogsim fit-fog NIGHT_RUN_DIR … --glow-only [--start PARAMS.json]   # the glow alone, the rest kept
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.bench.fog_physics import committed_frames, load_frame
from fogsim.colour import linear_to_srgb, luminance
from fogsim.errors import InputError
from fogsim.fog.engine import FogSettings
from fogsim.fog.physics import horizon_radiance, interior_mask, lamps, radial_profile
from fogsim.fog.scatter import ScatterFogger, ScatterParams
from fogsim.schema.base import load_json
from fogsim.schema.documents import RenderRunFile, RenderRunParameters
from fogsim.schema.scatter import SCATTER_PARAMS_VERSION, TERMS, fit_space

#: the day parameters (path → fit record: low, high, first step, log10?) and the night ones (the lamps' gain
#: and the share of it in the wide wings searched; the core's width and the largest saturated region that
#: is a lamp on a grid): declared with the parameters (:func:`fogsim.schema.scatter.fit_space`). The day
#: bounds keep to the physical side: objects are not lit more in fog than in clear (μ ≥ 0), the airlight
#: does not grow with β (λ ≥ 0) and stays near the horizon's (a ∈ [0.5, 1.5]) — unbounded, a fit on one
#: street style (μ = −14 m: objects 5× brighter at β = 0.12) failed on the others (docs/fog-physics.md)
DAY_SPACE = fit_space("day")
NIGHT_SPACE = fit_space("night")
GLOW_BOUNDS = {path: fit for path, fit in NIGHT_SPACE.items() if "grid" not in fit}
GLOW_SPREAD, GLOW_AREA = "glow.spread", "glow.max_area"
#: the glow's day/night boundary (median linear luminance of the clear image, not fitted: between the
#: measured night streets, 0.020–0.032, and day streets, 0.071–0.20; :func:`fogsim.fog.scatter.night_weight`)
GLOW_DARK = 0.045
#: the reference RMS a ratio is taken to at least (A = 1: far below any real model's error)
RMS_FLOOR = 1e-3
MIN_STEP = 1 / 64  # stop when every step has halved this far (relative to the first step)


@dataclass
class FitFrame:
    """One frame and β, ready for the objective: the scaled path-traced renders at the counted pixels."""

    data: dict
    beta: float
    scale: float
    where: np.ndarray
    f1: np.ndarray
    f2: np.ndarray


def frame_levels(data: dict) -> list[FitFrame]:
    """One frame's β, ready for the objective (its renders scaled so the horizon is 1; levels without
    a horizon to scale by, or a frame without interior pixels, are left out)."""
    ray, mask = data["distance"], data["mask"]
    where = interior_mask(ray, mask) & ~(np.isinf(ray) & (mask == 0))
    levels = []
    for beta, (f1, f2) in sorted(data["renders"].items()):
        hz = horizon_radiance(0.5 * (f1 + f2), ray, mask)
        if hz is None or not hz["luminance"] > 0 or not where.any():
            continue
        s = 1.0 / hz["luminance"]
        levels.append(FitFrame(data, beta, s, where, s * f1[where], s * f2[where]))
    return levels


def prepare(folders: list[Path]) -> tuple[list[FitFrame], list[dict], list[FitFrame], dict]:
    """(day frames × β, night frames, night frames × β, what was read: presets, styles, dataset seeds,
    frames, β, resolution, samples)."""
    day, night, night_levels = [], [], []
    info = {"runs": [], "presets": [], "styles": [], "seeds": [], "times_of_day": [], "frames": 0, "betas": set(),
            "resolution": "", "samples": 0}
    for folder in folders:
        run_file = folder / "clear" / "render_run.json"
        given = load_json(run_file, RenderRunFile).parameters if run_file.is_file() else RenderRunParameters()
        style = given.style.get("name") if isinstance(given.style, dict) else given.style  # or the whole style
        record = {"folder": folder.name, "preset": str(given.name or ""), "style": str(style or ""),
                  "seed": given.seed, "time_of_day": "", "frames": 0, "resolution": "", "samples": 0}
        for frame in committed_frames(folder):
            data = load_frame(folder, frame)
            meta = data.pop("meta")
            data.pop("same_labels")
            run = meta.get("render", {})
            info["frames"] += 1
            record["frames"] += 1
            record["resolution"] = info["resolution"] = f"{meta['width']}x{meta['height']}"
            record["samples"] = info["samples"] = int(run.get("samples", info["samples"]) or 0)
            record["time_of_day"] = "night" if data["night"] else "day"
            info["betas"] |= set(data["renders"])
            if data["night"]:
                night.append(data)
            (night_levels if data["night"] else day).extend(frame_levels(data))
        info["runs"].append(record)
        for key, value in (("presets", record["preset"]), ("styles", record["style"]), ("seeds", record["seed"]),
                           ("times_of_day", record["time_of_day"])):
            if value not in (None, "") and value not in info[key]:
                info[key].append(value)
    info["betas"] = sorted(info["betas"])
    return day, night, night_levels, info


def day_objective(params: ScatterParams, frames: list[FitFrame], reference: dict | None = None) -> float:
    """Mean over β of the pooled noise-free normalised RMS (√mean(E₁·E₂)) of the scatter model,
    each divided by ``reference[β]`` (at least :data:`RMS_FLOOR`) when given."""
    rms = day_rms(params, frames)
    return float(np.mean([v / (max(reference[b], RMS_FLOOR) if reference else 1.0) for b, v in rms.items()]))


def fogger(params: ScatterParams, data: dict) -> ScatterFogger:
    """The scatter model on one frame's clear render, as :func:`fogsim.fog.physics.koschmieder_linear`
    blends it (linear light, A = 1, not clipped), from a 16-bit sRGB copy made once per frame: the fit
    fogs every frame hundreds of times, and decoding 16-bit codes is a table lookup."""
    if "srgb16" not in data:
        srgb = linear_to_srgb(np.clip(data["clear_linear"], 0.0, 1.0))
        data["srgb16"] = np.round(srgb * 65535.0).astype(np.uint16)
    return FogSettings("scatter", 255.0, "linear", scatter=params).fogger(data["srgb16"], data["distance"],
                                                                         data["camera"], data["up"])


def model_images(params: ScatterParams, frames: list[FitFrame]):
    """(frame-level, the model's linear image at its counted pixels) for every frame-level, one
    :class:`ScatterFogger` per frame (its set-up is shared by the frame's β)."""
    groups: dict[int, list[FitFrame]] = {}
    for fr in frames:
        groups.setdefault(id(fr.data), []).append(fr)
    for group in groups.values():
        f = fogger(params, group[0].data)
        for fr in group:
            yield fr, f.blend(fr.beta)[fr.where]


def day_rms(params: ScatterParams, frames: list[FitFrame]) -> dict[float, float]:
    """β → the pooled noise-free normalised RMS (√mean(E₁·E₂)) of the scatter model."""
    sums: dict[float, list[float]] = {}
    for fr, k in model_images(params, frames):
        acc = sums.setdefault(fr.beta, [0.0, 0])
        acc[0] += float(((fr.f1 - k) * (fr.f2 - k)).sum())
        acc[1] += k.size
    return {b: math.sqrt(max(c / n, 0.0)) for b, (c, n) in sorted(sums.items())}


def glow_objective(params: ScatterParams, frames: list[dict]) -> float | None:
    """Mean squared log10-ratio of model and path-traced ring luminance around every lamp (None: no lamp)."""
    errs = []
    for d in frames:
        found = lamps(d["clear_linear"], d["distance"])
        model = fogger(params, d)
        for beta, (f1, f2) in d["renders"].items():
            hz = horizon_radiance(0.5 * (f1 + f2), d["distance"], d["mask"])
            s = 1.0 / hz["luminance"] if hz and hz["luminance"] > 0 else 1.0
            y_pt = luminance(s * 0.5 * (f1 + f2))
            y_m = luminance(model.blend(beta))
            for lamp in found:
                for a, b in zip(radial_profile(y_m, lamp["centre"]), radial_profile(y_pt, lamp["centre"])):
                    if a is not None and b is not None:
                        errs.append((math.log10(a + 1e-3) - math.log10(b + 1e-3)) ** 2)
    return float(np.mean(errs)) if errs else None


def _set(params: ScatterParams, path: str, x: float, space: dict) -> ScatterParams:
    return params.with_values({path: 10.0 ** x if space[path].get("log") else x})


def _get(params: ScatterParams, path: str, space: dict) -> float:
    v = params.value(path)
    return math.log10(max(v, 1e-3)) if space[path].get("log") else v


def pattern_search(params: ScatterParams, space: dict, objective, log=print) -> tuple[ScatterParams, float]:
    """Hooke–Jeeves without the pattern move over ``space`` (path → ``low``, ``high``, ``step``, ``log``):
    try ±step on each parameter, keep an improvement, halve the steps when none helps; stop at
    :data:`MIN_STEP` of the first steps."""
    best = objective(params)
    steps = {n: b["step"] for n, b in space.items()}
    while any(steps[n] >= space[n]["step"] * MIN_STEP for n in space):
        improved = False
        for n, b in space.items():
            for sign in (+1, -1):
                x = min(b["high"], max(b["low"], _get(params, n, space) + sign * steps[n]))
                trial = _set(params, n, x, space)
                value = objective(trial)
                if value < best - 1e-6:
                    params, best, improved = trial, value, True
                    break
        if not improved:
            steps = {n: s / 2 for n, s in steps.items()}
        log(f"fit-fog: {best:.4f} " + " ".join(f"{n}={params.value(n):.4g}" for n in space))
    return params, best


def fit_glow(params: ScatterParams, night: list[dict], night_levels: list[FitFrame], log=print):
    """The glow's parameters fitted on the night frames, the day ones kept: (parameters, {"before",
    "after"} of the night objective, or None when there is no lamp to fit on: glow off)."""
    params = params.with_values({"glow.gain": max(params.glow.gain, 1.0),
                                 "night.luminance": params.night.luminance or GLOW_DARK})
    night_reference = day_rms(ScatterParams(), night_levels) if night_levels else None

    def night_objective(p):  # the halo's profile, and the whole night image against Koschmieder's error
        ring = glow_objective(p, night)
        if ring is None or not night_levels:
            return ring
        return ring + day_objective(p, night_levels, night_reference)
    glow_before = night_objective(params.with_values({"glow.gain": 0.0}))
    if glow_before is None:
        return params.with_values({"glow.gain": 0.0}), None
    # G and the PSF's width trade against each other (a narrower halo needs less gain): the width and
    # the lamps' largest size on a grid, the gain and its tail searched at each, the best kept
    best = None
    for area in NIGHT_SPACE[GLOW_AREA]["grid"]:
        for log_rho in NIGHT_SPACE[GLOW_SPREAD]["grid"]:
            trial = params.with_values({GLOW_SPREAD: 10.0 ** log_rho, GLOW_AREA: area, "glow.tail": 0.0})
            trial, g = pattern_search(trial, GLOW_BOUNDS, night_objective, log)
            if best is None or g < best[1]:
                best = (trial, g)
    return best[0], {"before": glow_before, "after": best[1]}


def _night_note(glow: dict | None) -> str:
    return "" if not glow else (f"; night: ring-profile log error + RMS ratio to Koschmieder {glow['before']:.3f} → "
                                f"{glow['after']:.3f}")


def fit(folders: list[Path], start: ScatterParams | None = None, log=print) -> dict:
    """Fit on the runs under ``folders``; returns the parameter document (not yet written)."""
    from fogsim._version import __version__

    day, night, night_levels, info = prepare(folders)
    if not day:
        raise InputError(folders[0], "no day frame with sky to fit on (fit-fog needs fog-physics runs; "
                         "--glow-only refits the glow on night runs alone)")
    koschmieder = ScatterParams()
    reference = day_rms(koschmieder, day)
    before = float(np.mean(list(reference.values())))
    log(f"fit-fog: {len(day)} day frame-levels, {len(night)} night frames; Koschmieder (linear) {before:.4f}")
    start = start or ScatterParams(psf={"forward": 0.5, "spread": 0.1})
    # never end worse than Koschmieder: the search only improves on its start
    if day_objective(start, day, reference) > day_objective(koschmieder, day, reference):
        start = koschmieder
    params, _ = pattern_search(start, DAY_SPACE, lambda p: day_objective(p, day, reference), log)
    fitted = day_rms(params, day)
    after = float(np.mean(list(fitted.values())))
    glow = None
    if night:
        params, glow = fit_glow(params, night, night_levels, log)
    note = ("day: mean over β of the noise-free normalised RMS (interior non-sky pixels, A = 1), fitted as its "
            "ratio to Koschmieder's per β; before = Koschmieder in linear light; per β (K → scatter): "
            + ", ".join(f"{b:g}: {reference[b]:.3f} → {fitted[b]:.3f}" for b in reference)) + _night_note(glow)
    return {"format": "fogsim-scatter-params", "version": SCATTER_PARAMS_VERSION, "parameters": params.to_dict(),
            "fitted_on": {**info, "objective": "normalised RMS (day); night: ring-profile log error + RMS ratio (glow)",
                          "before": round(before, 5), "after": round(after, 5)},
            "fogsim_version": __version__, "note": note}


def fit_glow_only(folders: list[Path], start: dict, log=print) -> dict:
    """Refit the glow on the night runs under ``folders``, every other parameter kept from the ``start``
    document (a parameter file); its record of what it was fitted on gains these runs."""
    from fogsim._version import __version__

    _, night, night_levels, info = prepare(folders)
    if not night:
        raise InputError(folders[0], "no night frame to fit the glow on")
    params, glow = fit_glow(ScatterParams.model_validate(start["parameters"]), night, night_levels, log)
    was = start.get("fitted_on", {})
    names = {r["folder"] for r in info["runs"]}
    merged = {**was, "runs": [r for r in was.get("runs", []) if r["folder"] not in names] + info["runs"]}
    for key in ("presets", "styles", "seeds", "times_of_day"):
        merged[key] = list(was.get(key, [])) + [v for v in info[key] if v not in was.get(key, [])]
    merged["betas"] = sorted(set(was.get("betas", [])) | set(info["betas"]))
    merged["frames"] = sum(r["frames"] for r in merged["runs"])
    note = start.get("note", "").split("; night:")[0] + _night_note(glow)
    return {**start, "parameters": params.to_dict(), "fitted_on": merged, "fogsim_version": __version__,
            "note": note}


def run(args) -> int:
    """``fogsim fit-fog``: fit, check the document against the schema, write it atomically."""
    from fogsim.fog.scatter import load_params, load_params_file
    from fogsim.io.documents import write_json
    from fogsim.runs import check_output
    from fogsim.schema.base import check
    from fogsim.schema.scatter import ScatterParamsFile

    log = (lambda *a: None) if args.quiet else print
    folders = [Path(f) for f in args.runs]
    check_output(args.out, [("--start", getattr(args, "start", None))] + [("RUN_DIR", f) for f in args.runs],
                 file=True)  # before the fit: never over one of its inputs
    if getattr(args, "glow_only", False):
        start = load_params_file(args.start).model_dump(mode="json")   # default: the shipped file
        doc = fit_glow_only(folders, start, log=log)
    else:
        start = load_params(args.start) if getattr(args, "start", None) else None
        doc = fit(folders, start=start, log=log)
    check(doc, ScatterParamsFile, args.out)
    write_json(args.out, doc)
    p = ScatterParams.model_validate(doc["parameters"])
    print(f"fit-fog: RMS normalised {doc['fitted_on']['before']:.3f} (Koschmieder) → {doc['fitted_on']['after']:.3f} "
          f"(scatter); " + " ".join(f"{path}={p.value(path):.3g}" for path in TERMS) + f" → {args.out}")
    return 0
