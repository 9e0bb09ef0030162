"""fogsim's ``hahner2021`` LiDAR fog model beside the released code of Hahner et al. 2021 (MartinHahner/
LiDAR_fog_sim, its batch path ``fog_simulation.simulate_fog``), on the test fixtures' KITTI-, nuScenes- and
STF-format sweeps at β 0.03 / 0.06 / 0.09 / 0.12: per scan and β the kept / attenuated / lost / clutter shares
of both and their largest difference (target: within 0.5 percentage points of each share).

The released code is not part of fogsim (CC BY-NC 4.0) and is never copied into it: check it out yourself
into a folder outside this repository and point ``--released`` at it. It needs numpy, scipy and tqdm (the
project's development environment has them). Its integral tables are pickles: they are read here with an
unpickler that admits only numpy scalars and dtypes (what the tables hold), nothing that runs code.

    git clone https://github.com/MartinHahner/LiDAR_fog_sim /tmp/LiDAR_fog_sim
    python scripts/check_hahner_released.py --released /tmp/LiDAR_fog_sim
    python scripts/check_hahner_released.py --released /tmp/LiDAR_fog_sim --variant viewer

How the released code is run: ``simulate_fog(ParameterSet(alpha=β, gamma=1e-6), points, 10)`` (its batch
path: default 'v1' noise, no gain), fed what its documentation says — KITTI's 0–1 reflectances × 255 and
rounded, 0–255 scans as stored; its module Generator replaced by ``default_rng(seed)`` so both draw the same
range noise. A point is its ``clutter`` when the released code moved it, else ``kept`` when its intensity is
the fed one, else ``attenuated``; it never loses one. The released code reads its integral at the nearest of
its nine table α (0.09 → 0.10); fogsim computes it at β itself — the ``table α`` rows run fogsim with the
table's α for the integral too, which isolates that difference.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one core, before numpy loads
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import types  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BETAS = (0.03, 0.06, 0.09, 0.12)
OUTCOMES = ("kept", "attenuated", "lost", "clutter")
TARGET_PP = 0.5


class TableUnpickler(pickle.Unpickler):
    """Admits the globals the released integral tables use (numpy scalars and dtypes), refuses any other."""

    def find_class(self, module, name):
        if (module, name) == ("numpy", "dtype"):
            return np.dtype
        if name == "scalar" and module in ("numpy.core.multiarray", "numpy._core.multiarray"):
            for mod in ("numpy._core.multiarray", "numpy.core.multiarray"):
                try:
                    return importlib.import_module(mod).scalar
                except ImportError:
                    continue
        raise pickle.UnpicklingError(f"refused {module}.{name}: the integral tables hold numbers only")


def released_module(folder: Path):
    """The released ``fog_simulation`` module, its table reader given :class:`TableUnpickler`."""
    if not (folder / "fog_simulation.py").is_file():
        raise SystemExit(f"error: {folder}: no fog_simulation.py (check out MartinHahner/LiDAR_fog_sim there)")
    sys.path.insert(0, str(folder))
    try:
        module = importlib.import_module("fog_simulation")
    finally:
        sys.path.pop(0)
    module.pickle = types.SimpleNamespace(load=lambda handle: TableUnpickler(handle).load())
    return module


def scans(tmp: Path):
    """(label, PointCloud) of the fixture sweeps, one per format."""
    import lidar_fixtures as lf
    from fogsim.lidar.formats import read_points

    return [("KITTI street sweep (hdl64e, 0-1)", "hdl64e", lf.kitti_street_cloud(tmp)),
            ("KITTI full sweep (hdl64e, 0-1)", "hdl64e", read_points(lf.kitti_sweep(tmp), "kitti")),
            ("nuScenes sweep (hdl32e, 0-255)", "hdl32e", read_points(lf.nuscenes_sweep(tmp), "nuscenes")),
            ("STF sweep (hdl64-s3d, 0-255)", "hdl64-s3d", read_points(lf.stf_sweep(tmp), "stf"))]


def released_outcomes(module, scan, fed: np.ndarray, beta: float, seed: int, variant: str = "batch"):
    """(outcome codes, output ranges) of the released batch path on ``scan`` fed ``fed``; ``viewer``: with the
    backscatter its viewer sets for the α (β_b = 0.046/MOR(α)) instead of the frozen one."""
    pc = np.zeros((len(scan), 5), np.float32)
    pc[:, :3], pc[:, 3] = scan.xyz, fed
    module.RNG = np.random.default_rng(seed)
    params = module.ParameterSet(alpha=beta, gamma=0.000001)
    if variant == "viewer":
        params.mor = np.log(20) / beta
        params.beta = 0.046 / params.mor
    out, _, _ = module.simulate_fog(params, pc.copy(), 10)
    moved = np.any(out[:, :3] != pc[:, :3], axis=1)
    outcome = np.where(moved, 3, np.where(out[:, 3] == pc[:, 3], 0, 1))
    sign = np.sign(np.einsum("ij,ij->i", out[:, :3].astype(np.float64), pc[:, :3].astype(np.float64)))
    return outcome, sign * np.linalg.norm(out[:, :3].astype(np.float64), axis=1)


def shares(outcome: np.ndarray) -> np.ndarray:
    return 100.0 * np.bincount(outcome, minlength=4) / len(outcome)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--released", type=Path, required=True, help="a checkout of MartinHahner/LiDAR_fog_sim")
    ap.add_argument("--seed", type=int, default=0, help="range-noise seed of both (default 0)")
    ap.add_argument("--variant", choices=("batch", "viewer"), default="batch",
                    help="batch (default: the backscatter frozen at α 0.06, as the released batch path) or viewer "
                         "(the backscatter at each α, as its viewer sets it; fogsim's hahner_variant viewer)")
    args = ap.parse_args(argv)
    module = released_module(args.released.resolve())
    sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this repository's fogsim and its fixtures
    from fogsim.lidar.fog import LidarFogger
    from fogsim.lidar.hahner import TABLE_ALPHAS, HahnerParameters
    from fogsim.lidar.hahner2021 import fed_intensity

    worst, worst_table = 0.0, 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for label, sensor, scan in scans(Path(tmp)):
            fed = fed_intensity(scan)
            spec = {"model": "hahner2021", "hahner_variant": args.variant}
            exact, table = LidarFogger(scan, sensor, spec), LidarFogger(scan, sensor, spec)
            table.published.params = HahnerParameters(table_lookup=True)
            print(f"\n{label}: {len(scan)} points, {100 * float((fed == 0).mean()):.1f} % fed 0")
            print(f"  {'β':<6}{'':<18}" + "".join(f"{o:>12}" for o in OUTCOMES) + f"{'max |Δ| pp':>12}"
                  + f"{'clutter range median (m)':>26}")
            seconds = {"released": 0.0, "fogsim": 0.0}
            for k, beta in enumerate(BETAS):
                t0 = time.perf_counter()
                ref, ref_r = released_outcomes(module, scan, fed, beta, args.seed + k, args.variant)
                t1 = time.perf_counter()
                got = exact(beta, np.random.default_rng(args.seed + k))
                seconds["released"] += t1 - t0
                seconds["fogsim"] += time.perf_counter() - t1
                tab = table(beta, np.random.default_rng(args.seed + k))
                rs = shares(ref)
                ta = min(TABLE_ALPHAS, key=lambda a: abs(a - beta))
                for name, fogged in (("fogsim", got), (f"fogsim, table α {ta:g}", tab)):
                    fs = shares(fogged.outcome)
                    diff = float(np.abs(fs - rs).max())
                    if fogged is got:
                        worst = max(worst, diff)
                    else:
                        worst_table = max(worst_table, diff)
                    rows = fogged.output_index[fogged.outcome == 3]
                    ranges = np.linalg.norm(fogged.cloud.xyz[rows].astype(np.float64), axis=1)
                    med = np.median(ranges) if len(rows) else np.nan
                    if name == "fogsim":
                        ref_med = np.median(ref_r[ref == 3]) if (ref == 3).any() else np.nan
                        print(f"  {beta:<6g}{'released':<18}" + "".join(f"{v:12.2f}" for v in rs) + f"{'':>12}"
                              + f"{ref_med:26.2f}")
                    print(f"  {'':<6}{name:<18}" + "".join(f"{v:12.2f}" for v in fs) + f"{diff:12.2f}{med:26.2f}")
                same = np.array_equal(got.outcome == 3, ref == 3)
                if same and (ref == 3).any():
                    rows = got.output_index[ref == 3]
                    mine = np.linalg.norm(got.cloud.xyz[rows].astype(np.float64), axis=1)
                    theirs = np.abs(ref_r[ref == 3])
                    print(f"  {'':<6}the same points scattered, with the same draws: their ranges differ by a median "
                          f"{float(np.median(np.abs(mine - theirs))):.3f} m, 99 % of them by ≤ "
                          f"{100 * float(np.percentile(np.abs(mine - theirs) / theirs, 99)):.1f} % (its tables "
                          "step 0.1 m)")
            print(f"  time for the {len(BETAS)} levels (one run, wall clock): released code "
                  f"{seconds['released']:.2f} s, fogsim {1e3 * seconds['fogsim']:.0f} ms")
    verdict = "ok" if worst <= TARGET_PP else "MISSED"
    print(f"\nlargest share difference, fogsim hahner2021 {args.variant} (integral at β) vs the released code: "
          f"{worst:.2f} pp "
          f"[{verdict}: ≤ {TARGET_PP} pp]; with the table's α for the integral too: {worst_table:.2f} pp")
    return 0 if worst <= TARGET_PP else 1


if __name__ == "__main__":
    raise SystemExit(main())
