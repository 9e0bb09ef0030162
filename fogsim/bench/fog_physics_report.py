"""The report of :class:`fogsim.fog.physics.Comparison`: a markdown table per β and model
(noise-free RMS raw / normalised / far-normalised, bias per distance bin, per-object contrast
PT/K) and the files ``fog_physics.json``, ``fog_physics.md``, ``panels_<frame>.png``. Values
are in linear light with the airlight A = white = 1.
"""
from __future__ import annotations

from pathlib import Path

from fogsim.fog.physics import BIN_NAMES, MIN_CONTRAST, SUMMARY_MIN_TRANSMISSION, Comparison

#: per-object table rows: objects that keep at least this transmission (the rest: JSON only)
TABLE_MIN_TRANSMISSION = 0.01


def _f(v, fmt: str = "{:+.3f}") -> str:
    return "—" if v is None else fmt.format(v)


def markdown(result: dict, model_names: tuple[str, ...] | None = None) -> str:
    """The table of :meth:`Comparison.result`: per β and model, noise-free RMS raw and normalised
    (non-sky interior pixels) and the normalised bias per distance bin; then per-object contrast."""
    names = model_names or tuple(result["models"])
    frac = result.get("interior_fraction")
    lines = [f"Koschmieder against path-traced fog, {len(result['frames'])} frame(s); linear light, A = white = 1; "
             f"noise-free RMS from two seeds on interior pixels ({_f(frac, '{:.0%}')} of pixels); "
             "normalised = path-traced image scaled so the horizon is A (bias columns: normalised); "
             "far-normalised = scaled so the median beyond the visibility is A.", "",
             "| β (1/m) | A_h | sky / A_h | model | RMS raw | RMS normalised | RMS far-normalised | "
             + " | ".join(f"bias {b}" for b in BIN_NAMES) + " | object contrast PT/K (median, n) |",
             "|---" * (8 + len(BIN_NAMES)) + "|"]
    for key, pb in result["per_beta"].items():
        hz = pb["horizon"]
        for name in names:
            m = pb["models"].get(name, {})
            raw, norm = m.get("raw", {}), m.get("normalised", {})
            biases = [_f(norm.get(b, {}).get("bias")) for b in BIN_NAMES]
            summ = pb.get("objects_summary", {}).get(name, {})
            objs = f"{_f(summ.get('median_ratio_pt_k'), '{:.2f}')} ({summ.get('objects', 0)})"
            lines.append(f"| {key} | {_f(hz['luminance_mean'], '{:.3f}')} | {_f(hz['mean_sky_over_horizon'], '{:.2f}')}"
                         f" | {name} | {_f(raw.get('all', {}).get('rms'), '{:.3f}')} "
                         f"| {_f(norm.get('all', {}).get('rms'), '{:.3f}')} "
                         f"| {_f(m.get('far', {}).get('all', {}).get('rms'), '{:.3f}')} | "
                         + " | ".join(biases) + f" | {objs} |")
    lines += ["", "Per object (interior pixels): contrast against the airlight, C = 1 − Y/A; "
              "C_K/C0 = t for linear Koschmieder; PT/K = C_PT / C_K (the summary column above: median over "
              f"objects with t ≥ {SUMMARY_MIN_TRANSMISSION:g}); rows with t < {TABLE_MIN_TRANSMISSION:g} are "
              "in the JSON only.", "",
              "| β | frame | object | class | d (m) | t = e^(−βd) | C0 | C_PT / C0 | "
              + " | ".join(f"PT/K {n}" for n in names) + " |", "|---" * (8 + len(names)) + "|"]
    for key, pb in result["per_beta"].items():
        for o in pb["objects"]:
            if (o["transmission"] or 0) < TABLE_MIN_TRANSMISSION:
                continue
            rel = None if o["contrast_pt"] is None or abs(o["contrast_clear"]) < MIN_CONTRAST \
                else o["contrast_pt"] / o["contrast_clear"]
            lines.append(f"| {key} | {o['frame']} | {o['id']} | {o['class'] or '—'} | {_f(o['distance_m'], '{:.1f}')} "
                         f"| {_f(o['transmission'], '{:.3f}')} | {o['contrast_clear']:.3f} | {_f(rel, '{:.3f}')} | "
                         + " | ".join(_f(o["ratio_pt_k"].get(n), "{:.2f}") for n in names) + " |")
    lines += glow_lines(result, names)
    lines += target_lines(result)
    return "\n".join(lines) + "\n"


#: issue 19's targets for the scatter model: RMS ≤ this × Koschmieder's at every β, median object
#: contrast ratio PT/model within CONTRAST_BAND
RMS_TARGET = 0.5
CONTRAST_BAND = (0.8, 1.25)


def _rms(pb: dict, name: str, exposure: str):
    return pb["models"].get(name, {}).get(exposure, {}).get("all", {}).get("rms")


def target_summary(result: dict, koschmieder=("srgb", "linear"), model: str = "scatter") -> list[dict]:
    """Per β: the scatter model's RMS (normalised, far-normalised) over the better Koschmieder
    blend's (sRGB or linear), and its median object contrast ratio PT/model, with the targets
    (:data:`RMS_TARGET`, :data:`CONTRAST_BAND`) met or not; [] without a scatter model."""
    if model not in result.get("models", []):
        return []
    rows = []
    for key, pb in result["per_beta"].items():
        row = {"beta": pb["beta"]}
        for exposure in ("normalised", "far"):
            ks = [v for v in (_rms(pb, k, exposure) for k in koschmieder) if v is not None]
            s = _rms(pb, model, exposure)
            row[exposure] = {"koschmieder": min(ks) if ks else None, "scatter": s,
                             "ratio": s / min(ks) if ks and s is not None and min(ks) > 0 else None}
        summ = pb.get("objects_summary", {})
        row["contrast"] = {n: summ.get(n, {}).get("median_ratio_pt_k") for n in (*koschmieder, model)}
        c = row["contrast"][model]
        row["rms_met"] = row["normalised"]["ratio"] is not None and row["normalised"]["ratio"] <= RMS_TARGET
        row["contrast_met"] = c is not None and CONTRAST_BAND[0] <= c <= CONTRAST_BAND[1]
        rows.append(row)
    return rows


def target_lines(result: dict) -> list[str]:
    """The scatter model against Koschmieder and issue 19's targets, one row per β."""
    rows = target_summary(result)
    if not rows:
        return []
    lo, hi = CONTRAST_BAND
    lines = ["", f"Scatter against Koschmieder (the better of sRGB and linear blending, per β): RMS normalised and "
             f"far-normalised, scatter / Koschmieder (target ≤ {RMS_TARGET:g}), and the median object contrast "
             f"ratio PT/model (target {lo:g}–{hi:g}).", "",
             "| β | RMS norm. K → scatter | ratio | RMS far K → scatter | ratio | contrast PT/K sRGB, linear | "
             "contrast PT/scatter | targets |", "|---" * 8 + "|"]
    for r in rows:
        n, f, c = r["normalised"], r["far"], r["contrast"]
        met = ("RMS " + ("met" if r["rms_met"] else "missed") + ", contrast "
               + ("met" if r["contrast_met"] else "missed"))
        lines.append(f"| {r['beta']:g} | {_f(n['koschmieder'], '{:.3f}')} → {_f(n['scatter'], '{:.3f}')} "
                     f"| {_f(n['ratio'], '{:.2f}')} | {_f(f['koschmieder'], '{:.3f}')} → {_f(f['scatter'], '{:.3f}')} "
                     f"| {_f(f['ratio'], '{:.2f}')} | {_f(c['srgb'], '{:.2f}')}, {_f(c['linear'], '{:.2f}')} "
                     f"| {_f(c['scatter'], '{:.2f}')} | {met} |")
    return lines


def glow_lines(result: dict, names: tuple[str, ...]) -> list[str]:
    """The night glow table: per β, the median over lamps of the mean luminance (units of A, the
    path-traced image normalised) in rings around each lamp, path-traced against each model."""
    rows = [(key, pb["glow"]) for key, pb in result["per_beta"].items() if pb.get("glow")]
    if not rows:
        return []
    rings = rows[0][1]["rings_px"]
    lines = ["", "Glow around the lamps of night frames: median over lamps of the mean luminance in rings "
             "around each lamp (px), units of A (path-traced image normalised).", "",
             "| β | lamps | image | " + " | ".join(f"{lo}-{hi} px" for lo, hi in rings) + " |",
             "|---" * (3 + len(rings)) + "|"]
    for key, g in rows:
        for label, prof in (("path-traced", g["pt"]), *((n, g["models"].get(n)) for n in names)):
            if prof is None:
                continue
            lines.append(f"| {key} | {g['lamps']} | {label} | " + " | ".join(_f(v, "{:.3f}") for v in prof) + " |")
    return lines


def write_report(comparison: Comparison, out: str | Path) -> dict:
    """``fog_physics.json``, ``fog_physics.md`` and ``panels_<frame>.png`` under ``out``; returns the result."""
    from fogsim.io.atomic import atomic_write_bytes
    from fogsim.io.documents import write_json
    from fogsim.io.images import write_image

    out = Path(out)
    result = comparison.result()
    result["targets"] = target_summary(result)
    write_json(out / "fog_physics.json", result)
    atomic_write_bytes(out / "fog_physics.md", markdown(result).encode())
    for frame, panel in comparison.panels.items():
        write_image(out / f"panels_{frame}.png", panel)
    return result
